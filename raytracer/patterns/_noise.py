"""Our lattice noise and turbulence: the machinery of the noise patterns (bozo, granite, marble …).

Not POV-Ray's noise: POV-Ray is AGPL-3 and its noise is driven by a table of random constants that is
part of its code, so by project rule we do not port it. Ours has the same *structure* (a hashed
integer lattice, per corner a small linear function of the offset, blended with the s-curve
``f²(3 - 2f)``), the same range ([0, 1], generator-2 style clamp) and is calibrated to POV-Ray's
measured statistics (mean, standard deviation, autocorrelation at lags ¼-2 units), checked in
``tests/shading/test_patterns.py``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

_TABLE_BITS = 12
_TABLE_MASK = (1 << _TABLE_BITS) - 1
# Per lattice corner: a constant and a gradient (scalar noise), and three such sets (vector noise).
# Our own random numbers from a fixed seed; uniform in [-1, 1].
_RNG = np.random.default_rng(0x5EED_F00D)
_SCALAR_TABLE = _RNG.uniform(-1.0, 1.0, size=(1 << _TABLE_BITS, 4))
_VECTOR_TABLE = _RNG.uniform(-1.0, 1.0, size=(1 << _TABLE_BITS, 3, 4))
# Ripple/wave centres: 10 (POV's default number_of_waves) of our own points in the unit cube.
NUMBER_OF_WAVES = 10
WAVE_CENTRES = _RNG.uniform(0.0, 1.0, size=(NUMBER_OF_WAVES, 3))
WAVE_FREQUENCIES = _RNG.uniform(0.1, 0.5, size=NUMBER_OF_WAVES)

# Weight of the per-corner constant relative to the per-corner gradient, and the affine map of the raw
# lattice sum onto [0, 1]. Calibrated (tests/shading/test_patterns.py) so that bozo = noise has POV-Ray
# 3.7's measured mean 0.506, standard deviation 0.117 and autocorrelation 0.92/0.58/0.10 at lags
# 0.25/0.5/1 (POV's generator 2 maps its own sum with clamp((s + 1.05242)·0.48985582, 0, 1)).
_CONSTANT_WEIGHT = 0.55
_NOISE_SCALE = 0.44
_NOISE_OFFSET = 0.506
# Vector noise: each component calibrated to POV's measured DNoise standard deviation 0.242.
_DNOISE_SCALE = 0.92

# Corners of the unit cell, (8, 3).
_CORNERS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=np.int32)
# The lattice repeats with this period (so integer cell indices never overflow int32).
_LATTICE_PERIOD = 1 << 16


def _lowbias32(h):
    """A 32-bit integer mixing function (C. Wellons' "lowbias32"), uint32 in and out."""
    h = h ^ (h >> 16)
    h = h * jnp.uint32(0x7FEB352D)
    h = h ^ (h >> 15)
    h = h * jnp.uint32(0x846CA68B)
    return h ^ (h >> 16)


def _lattice(p):
    """Cell corners of ``p``: (table index (8,), offset of p from each corner (8, 3), weight (8,))."""
    cell = jnp.floor(p)
    f = p - cell  # in [0, 1)
    cell_i = jnp.mod(cell, _LATTICE_PERIOD).astype(jnp.int32)
    # corner (i, j, k)'s hash is lowbias(lowbias(lowbias(z_k ^ C) ^ y_j) ^ x_i): the first round
    # has 2 distinct inputs and the second 4, so 14 rounds give the 8 corners' hashes, not 24.
    # The corner's index wraps after the offset is added: cell -1's upper corner is cell 0's lower
    # one (index 0, not the period), so the noise is continuous across the coordinate planes.
    mask = jnp.uint32(_LATTICE_PERIOD - 1)
    x, y, z = (((cell_i[a] + jnp.arange(2, dtype=jnp.int32)).astype(jnp.uint32) & mask) for a in range(3))
    h_z = _lowbias32(z ^ jnp.uint32(0x9E3779B9))  # (2,) over k
    h_yz = _lowbias32(h_z[None, :] ^ y[:, None])  # (2, 2) over j, k
    h = _lowbias32(h_yz[None, :, :] ^ x[:, None, None]).reshape(8)  # over i, j, k: _CORNERS' order
    index = (h & jnp.uint32(_TABLE_MASK)).astype(jnp.int32)
    offset = f[None, :] - _CORNERS.astype(p.dtype)  # (8, 3)
    s = f * f * (3.0 - 2.0 * f)  # s-curve, C1 across cell faces
    w = jnp.where(_CORNERS == 1, s[None, :], 1.0 - s[None, :])  # (8, 3)
    return index, offset, jnp.prod(w, axis=1)


def _noise_raw(p):
    index, offset, weight = _lattice(p)
    rows = jnp.asarray(_SCALAR_TABLE, dtype=p.dtype)[index]  # (8, 4)
    corner = _CONSTANT_WEIGHT * rows[:, 0] + jnp.sum(rows[:, 1:] * offset, axis=1)
    return jnp.sum(weight * corner)


def noise(p):
    """Our scalar lattice noise at one point.

    Args:
        p: (3,) point.

    Returns:
        Scalar in [0, 1] (clamped, as POV's generator 2), mean ≈ 0.506, std ≈ 0.117, correlation length
        ≈ ½ unit; C1-smooth inside the clamp. Not POV-Ray's values (see the module docstring).
    """
    p = jnp.asarray(p)
    return jnp.clip(_NOISE_OFFSET + _NOISE_SCALE * _noise_raw(p), 0.0, 1.0)


def dnoise(p):
    """Our vector lattice noise (three independent components) at one point, for turbulence warps.

    Args:
        p: (3,) point.

    Returns:
        (3,) vector, each component mean ≈ 0, std ≈ 0.24, |component| ≲ 1, like POV's DNoise.
    """
    p = jnp.asarray(p)
    index, offset, weight = _lattice(p)
    rows = jnp.asarray(_VECTOR_TABLE, dtype=p.dtype)[index]  # (8, 3, 4)
    corner = _CONSTANT_WEIGHT * rows[..., 0] + jnp.sum(rows[..., 1:] * offset[:, None, :], axis=-1)
    return _DNOISE_SCALE * jnp.sum(weight[:, None] * corner, axis=0)


def _octaves(p, octaves, omega, lambda_):
    """The octaves' amplitudes ``ωⁱ`` and their points ``λⁱ p`` stacked (octaves, 3), each a
    running product as the sums below have always taken them."""
    amplitudes, points = [1.0], [p]
    amplitude, scale = 1.0, 1.0
    for _ in range(1, int(octaves)):
        amplitude = amplitude * omega
        scale = scale * lambda_
        amplitudes.append(amplitude)
        points.append(scale * p)
    return amplitudes, jnp.stack(points)


# Every octave's noise is one vmapped evaluation over the stacked points, not one traced copy per
# octave: POV-Ray's 6 octaves made 6 copies of the lattice in the program (a third of
# advanced/pawns' equations), the sums below still run octave by octave in the same order.


def turbulence(p, octaves: int = 6, omega=0.5, lambda_=2.0):
    """Scalar turbulence, POV's generator-2 formula (semantics §5.3) on our noise.

    ``clamp(2N(p) - 0.5, 0, 1) + Σ_{i=1}^{octaves-1} ωⁱ (2N(λⁱ p) - 0.5)``; ``octaves`` is static.
    """
    p = jnp.asarray(p)
    amplitudes, points = _octaves(p, octaves, omega, lambda_)
    n = jax.vmap(noise)(points)
    value = jnp.clip(2.0 * n[0] - 0.5, 0.0, 1.0)
    for i in range(1, len(amplitudes)):
        value = value + amplitudes[i] * (2.0 * n[i] - 0.5)
    return value


def dturbulence(p, octaves: int = 6, omega=0.5, lambda_=2.0):
    """Vector turbulence ``Σ_{i=0}^{octaves-1} ωⁱ DNoise(λⁱ p)`` (semantics §5.3); (3,)."""
    p = jnp.asarray(p)
    amplitudes, points = _octaves(p, octaves, omega, lambda_)
    d = jax.vmap(dnoise)(points)
    value = d[0]
    for i in range(1, len(amplitudes)):
        value = value + amplitudes[i] * d[i]
    return value
