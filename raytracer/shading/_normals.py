"""``normal { }``: the perturbed shading normal of a texture layer (semantics §5.5).

POV-Ray's rule, measured (``tests/test_normals.py`` holds it against ``povray``): the surface
normal, already turned to face the incoming ray, is taken into the pattern's space as a normal
(``W^T n`` for ``W`` the linear part of world_from_pattern) and normalised; the pattern's value
``w`` (after frequency, phase and wave, as a pigment's colour map would see it) is sampled at the
four corners ``q + h V_i`` of a regular tetrahedron around the pattern-space point ``q``; the
perturbation ::

    P = -(amount / (10 h)) Σ_i w(q + h V_i) V_i

is added, and the sum goes back to world space as a normal (``A^T`` for ``A = W^{-1}``) and is
normalised. For a value of gradient ``g``, ``P ≈ -(4/30)·amount·g``: ``normal { gradient x 1 }``
tilts a plane by atan(2/15). ``h`` is the normal's ``accuracy``; the tetrahedron's corners are
POV-Ray's (found from where ``gradient x``'s wrap crosses them). Scaling a normal's space
non-uniformly changes the depth of its bumps as POV-Ray's does; a uniform scale does not.

``bumps``, ``dents``, ``wrinkles``, ``ripples`` and ``waves`` are POV-Ray's own normal patterns,
built on its noise and wave sources, which ours match in statistics, not pixels
(``raytracer/patterns/_noisy.py``). Their perturbation is the same tetrahedron on our pattern
value at a fixed spacing, times a gain per pattern that gives the standard deviation of the
perturbation POV-Ray's renders show (``Pattern.normal_gain``; POV-Ray's ``accuracy`` does not reach them).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from .. import patterns
from ..kernels import safe_normalize
from ._materials import (
    PackedNormals,
    _evaluated_patterns,
    _pattern_point,
    _raw_value,
    map_bracket,
    waved_value,
)

# the tetrahedron's corners (unit vectors, summing to 0; Σ V Vᵀ = 4/3 I)
TETRAHEDRON = np.array([[math.sqrt(8 / 9), -1 / 3, 0.0],
                        [-math.sqrt(2 / 9), -1 / 3, math.sqrt(2 / 3)],
                        [-math.sqrt(2 / 9), -1 / 3, -math.sqrt(2 / 3)],
                        [0.0, 1.0, 0.0]])

# POV-Ray's own normal patterns (``Pattern.normal_gain``): the spacing their value is sampled at
SPECIAL_SPACING = 0.02


def _slope_height(table, size, w):
    """The height a slope map ``table`` (K, 3: value, height, slope; ``size`` entries, padded by
    the last) gives value ``w``: the cubic Hermite curve of the segment around ``w`` in its own
    parameter t, with the entries' slopes as its tangents; the end heights beyond the ends."""
    i0, i1, t = map_bracket(table[:, 0], w, size)  # (t 0 and 1 past the ends: the end heights)
    h0, s0, h1, s1 = table[i0, 1], table[i0, 2], table[i1, 1], table[i1, 2]
    t2, t3 = t * t, t * t * t
    return (2 * t3 - 3 * t2 + 1) * h0 + (t3 - 2 * t2 + t) * s0 + (3 * t2 - 2 * t3) * h1 + (t3 - t2) * s1


def perturbed(nm: PackedNormals, row, p, n):
    """The unit shading normal of material row ``row`` at world point ``p`` whose surface normal
    ``n`` (unit, facing the incoming ray): ``n`` itself where the row has no normal."""
    pats = nm.patterns
    own_gain = nm.gain[row]
    own = own_gain > 0  # one of POV-Ray's own normal patterns
    h = jnp.where(own, jnp.asarray(SPECIAL_SPACING, p.dtype), nm.accuracy[row])
    corners = jnp.asarray(TETRAHEDRON, p.dtype)
    q = _pattern_point(pats, row, p)
    pid = jnp.asarray(pats.tables["pattern_id"])[row]
    v = jnp.zeros((4,), p.dtype)
    for k in _evaluated_patterns(pats):
        centre = q
        if pats.turbulent[k] and patterns.REGISTRY[pats.pattern_names[k]].turbulence == "warp":
            # the turbulence moves the tetrahedron's centre, not its corners one by one (POV-Ray's
            # measured: gradient x with turbulence tilts by the closed form away from its wraps)
            centre = q + patterns.dturbulence(q, pats.octaves[pats.pattern_names[k]], pats.omega[row],
                                              pats.lambda_[row]) * pats.turbulence[row]
        points = centre[None, :] + h * corners
        values = jax.vmap(lambda x, k=k: _raw_value(pats, k, row, x, warp=False))(points)
        v = jnp.where(pid == k, values, v)
    w = jax.vmap(lambda x: waved_value(pats, row, x))(v)
    if nm.slope is not None:  # the slope map's height of each value
        heights = jax.vmap(lambda x: _slope_height(nm.slope[row], nm.slope_size[row], x))(w)
        w = jnp.where(nm.slope_size[row] > 0, heights, w)
    gain = jnp.where(own, own_gain, 1.0) * nm.amount[row] / (10.0 * h)
    perturbation = -gain * jnp.sum(w[:, None] * corners, axis=0) + nm.bias[row] * nm.amount[row]
    a = pats.pattern_from_world[row][:3, :3]
    n_p = safe_normalize(jnp.sum(nm.world_from_pattern[row] * n[:, None], axis=0), n)  # Wᵀ n
    bent = safe_normalize(jnp.sum(a * (n_p + perturbation)[:, None], axis=0), n)  # Aᵀ (n_p + P)
    return jnp.where(nm.amount[row] != 0, bent, n)

