"""Cellular patterns on OUR random points (one per unit cube of pattern space, from our own hash and
table): ``crackle`` (a Voronoi diagram's distances) and ``cells`` (a random value per unit cube).

POV-Ray's are built on random tables that are part of its code, which we do not port (the rule of
``_noise.py``), so these match POV-Ray in look and statistics, not pixel for pixel: the value's
mean, spread and autocorrelation, measured with ``povray`` and checked in
``tests/patterns/test_cellular.py``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..kernels import safe_sqrt
from ._noise import _lowbias32, noise
from ._record import Pattern

_TABLE_BITS = 12
_RNG = np.random.default_rng(0xC5AC_71E5)
_POINTS = _RNG.uniform(0.0, 1.0, size=(1 << _TABLE_BITS, 3))  # a cube's point, from its corner
_VALUES = _RNG.uniform(0.0, 1.0, size=1 << _TABLE_BITS)  # a cube's value (cells)
_PERIOD = 1 << 16
# the 27 cubes around a point's own, whose points can be its three nearest
_NEIGHBOURS = np.array([[i, j, k] for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], np.int32)


def _cube_index(cube):
    """Table index of integer cubes ``cube`` (..., 3) int32."""
    c = (jnp.mod(cube, _PERIOD)).astype(jnp.uint32)
    h = _lowbias32(c[..., 2] ^ jnp.uint32(0x2545F491))
    h = _lowbias32(h ^ c[..., 1])
    h = _lowbias32(h ^ c[..., 0])
    return (h & jnp.uint32((1 << _TABLE_BITS) - 1)).astype(jnp.int32)


def _nearest(p, metric=2.0):
    """The distances of the three points nearest ``p`` (ascending) and the nearest point."""
    cube = jnp.floor(p)
    cubes = cube.astype(jnp.int32)[None, :] + _NEIGHBOURS  # (27, 3)
    points = cubes.astype(p.dtype) + jnp.asarray(_POINTS, p.dtype)[_cube_index(cubes)]
    d = p[None, :] - points
    if metric == 2.0:
        dist = safe_sqrt(jnp.sum(d * d, axis=1))
    elif metric == 1.0:
        dist = jnp.sum(jnp.abs(d), axis=1)
    else:
        dist = jnp.sum(jnp.abs(d) ** metric, axis=1) ** (1.0 / metric)
    negated, order = jax.lax.top_k(-dist, 3)
    return -negated, points[order[0]]


def crackle(p, inputs, form=(-1.0, 1.0, 0.0), metric=2.0, offset=0.0, solid=False):
    """``form · (d₁, d₂, d₃) + offset`` for the distances to the three nearest points (POV-Ray's
    default form: the distance to the Voronoi diagram's walls, 0 on them); ``solid``: our noise at
    the nearest point, one value a cell."""
    dist, nearest = _nearest(p, float(metric))
    if solid:
        return noise(nearest)
    return jnp.dot(jnp.asarray(form, p.dtype), dist) + offset


def cells(p, inputs):
    """A random value in [0, 1) per unit cube."""
    return jnp.asarray(_VALUES, p.dtype)[_cube_index(jnp.floor(p).astype(jnp.int32))]


PATTERNS = (
    Pattern("crackle", crackle, noise=True,
            modifiers={"form": (-1.0, 1.0, 0.0), "metric": 2.0, "offset": 0.0, "solid": False}),
    Pattern("cells", cells),
)
