"""Noise patterns: built on OUR lattice noise (``_noise.py``), so they match POV-Ray in look and
statistics, not pixel for pixel (the measured numbers are in ``tests/shading/test_patterns.py``)."""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..kernels import safe_sqrt
from ._common import cycloidal, frac
from ._noise import WAVE_CENTRES, WAVE_FREQUENCIES, dturbulence, noise, turbulence
from ._record import BLACK, BLUE, GREEN, RED, WHITE, Pattern, rgb


def bozo(p, inputs):
    return noise(p)


def dents(p, inputs):
    return noise(p) ** 3


def granite(p, inputs):
    # Σ_{i=0..5} min(|1 - 2N(4·2ⁱ p)|, 0.5) / 2ⁱ  (semantics §5.3, generator 2)
    value = jnp.zeros((), p.dtype)
    for i in range(6):
        n = noise((4.0 * 2.0**i) * p)
        value = value + jnp.minimum(jnp.abs(1.0 - 2.0 * n), 0.5) / 2.0**i
    return value


# Wrinkles: our own 1/f sum of signed noise (ten octaves, ω = ½, λ = 2), affinely calibrated to POV's
# measured mean 0.51 and std 0.134; its autocorrelation (0.82/0.43/0.07 at ¼/½/1) then matches too.
_WRINKLES_OCTAVES = 10
_WRINKLES_SCALE = 0.50
_WRINKLES_OFFSET = 0.50


def wrinkles(p, inputs):
    value = jnp.zeros((), p.dtype)
    for i in range(_WRINKLES_OCTAVES):
        value = value + (2.0 * noise((2.0**i) * p) - 1.0) / 2.0**i
    return jnp.clip(_WRINKLES_OFFSET + _WRINKLES_SCALE * value, 0.0, 1.0)


_RIPPLE_GAIN = {"ripples": 0.0613, "waves": 0.0556}  # calibrated to POV's standard deviation


def _superposed(p, kind):
    """Superposed circular waves from NUMBER_OF_WAVES centres (our own points in the unit cube).

    ripples: sin(2π d) per centre (crests 1 unit apart); waves: cos(2π f d) with our own per-centre
    spatial frequency f in [0.1, 0.5] (broader, rounder swells).
    """
    value = jnp.zeros((), p.dtype)
    for c, f in zip(WAVE_CENTRES, WAVE_FREQUENCIES, strict=True):
        d = safe_sqrt(jnp.sum((p - jnp.asarray(c, p.dtype)) ** 2))
        if kind == "ripples":
            value = value + jnp.sin((2.0 * math.pi) * frac(d))
        else:
            value = value + jnp.cos((2.0 * math.pi) * frac(float(f) * d))
    return jnp.clip(0.5 + _RIPPLE_GAIN[kind] * value, 0.0, 1.0)


def ripples(p, inputs):
    return _superposed(p, "ripples")


def waves(p, inputs):
    return _superposed(p, "waves")


# marble, wood and agate use their turbulence themselves instead of warping the point (semantics §5.3)
def marble(p, inputs):
    if inputs.turbulence is None:
        return p[0]
    return p[0] + inputs.turbulence[0] * turbulence(p, inputs.octaves, inputs.omega, inputs.lambda_)


def wood(p, inputs):
    turb = inputs.turbulence
    if turb is None:
        qx, qy = p[0], p[1]
    else:
        w = dturbulence(p, inputs.octaves, inputs.omega, inputs.lambda_)
        qx = p[0] + cycloidal((p[0] + w[0]) * turb[0])
        qy = p[1] + cycloidal((p[1] + w[1]) * turb[1])
    return safe_sqrt(qx * qx + qy * qy)


def agate(p, inputs, *, agate_turb):
    t = turbulence(p, inputs.octaves, inputs.omega, inputs.lambda_)
    n = 0.5 * (cycloidal(1.3 * agate_turb * t + 1.1 * p[2]) + 1.0)
    n = jnp.clip(n, 0.0, 1.0)
    ok = n > 0
    return jnp.where(ok, jnp.power(jnp.where(ok, n, 1.0), 0.77), 0.0)


_BOZO_MAP = ((0.0, WHITE), (0.4, WHITE), (0.4, GREEN), (0.6, GREEN), (0.6, BLUE), (0.8, BLUE),
             (0.8, RED), (1.0, RED))
# POV-Ray's built-in maps of marble, wood and agate, measured (povray's pigment without a map beside
# one with a black-to-white map on the same plane: pairs of value and colour, their breaks found)
_MARBLE_MAP = ((0.0, rgb(0.9, 0.8, 0.8)), (0.9, rgb(0.9, 0.08, 0.08)), (0.9, BLACK), (1.0, BLACK))
_WOOD_MAP = ((0.0, rgb(0.666, 0.312, 0.2)), (0.6, rgb(0.666, 0.312, 0.2)), (0.6, rgb(0.4, 0.133, 0.066)),
             (1.0, rgb(0.4, 0.133, 0.066)))
_AGATE_MAP = ((0.0, rgb(1, 1, 1)), (0.5, rgb(0.95, 0.75, 0.5)), (0.5, rgb(0.9, 0.7, 0.5)),
              (0.6, rgb(0.9, 0.7, 0.4)), (0.6, rgb(1.0, 0.7, 0.4)), (1.0, rgb(0.6, 0.3, 0.0)))

# POV-Ray's own normal patterns: the gain on our perturbation (shading/_normals.py) that gives the
# standard deviation of POV-Ray's, measured on planes of each at 320×240 (the mean ratio of POV-Ray's
# to ours over the plane's two tangent directions in three orientations; tests/test_normals.py
# checks the result); POV-Ray's wrinkles also tilt every point by 0.444·amount along (1, 1, 1)
NORMAL_GAIN = {"bumps": 7.27, "dents": 1.68, "wrinkles": 2.17, "ripples": 2.35, "waves": 17.4}
WRINKLES_BIAS = 0.444

PATTERNS = (
    Pattern("bozo", bozo, default_map=_BOZO_MAP, noise=True),
    Pattern("spotted", bozo, noise=True),
    Pattern("bumps", bozo, noise=True, normal_gain=NORMAL_GAIN["bumps"]),
    Pattern("dents", dents, noise=True, normal_gain=NORMAL_GAIN["dents"]),
    Pattern("granite", granite, noise=True),
    Pattern("wrinkles", wrinkles, noise=True, normal_gain=NORMAL_GAIN["wrinkles"], normal_bias=WRINKLES_BIAS),
    Pattern("ripples", ripples, normal_gain=NORMAL_GAIN["ripples"]),
    Pattern("waves", waves, normal_gain=NORMAL_GAIN["waves"]),
    Pattern("marble", marble, default_wave="triangle", turbulence="internal", default_map=_MARBLE_MAP),
    Pattern("wood", wood, default_wave="triangle", turbulence="internal", default_map=_WOOD_MAP),
    Pattern("agate", agate, turbulence="internal", modifiers={"agate_turb": 1.0}, noise=True,
            default_map=_AGATE_MAP),
)
