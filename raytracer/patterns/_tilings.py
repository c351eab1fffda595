"""Discrete patterns: each point chooses one entry of a list (exact POV-Ray 3.7: the manual's
definitions and, where it is silent — orientation of hexagon, where brick mortar sits — what POV-Ray
3.7.0.10 renders; ``tests/shading/test_patterns.py`` compares with POV-Ray renders)."""

from __future__ import annotations

import math

import jax.numpy as jnp

from ._common import frac
from ._record import BLUE, GREEN, RED, WHITE, Pattern

_SQRT3 = math.sqrt(3.0)


def checker(p, inputs):
    """0 = first colour, 1 = second colour: the parity of the cell's integer coordinates.

    POV-Ray adds 1e-10 to each coordinate, so that a face at an integer coordinate belongs to the
    cell above it (``inputs.face_nudge``). So do we in float32 where the pattern space keeps the
    surface's point exact (float32 points of discrete patterns are computed at the surface,
    ``shading._geometry.closest_hit``'s refine): any nudge of an ulp or more would move the points of
    a surface that only approaches a face (the top of a radius-1e6 ground sphere resting on y = -1,
    x²/2e6 below it) into the wrong cell. Elsewhere the shader nudges by a few ulps."""
    k = jnp.sum(jnp.floor(p + inputs.face_nudge))
    return k - 2.0 * jnp.floor(0.5 * k)


def checker_face(q_a, q_b, value):
    """The face between the unit cells of ``q_a`` and ``q_b``: the integer plane of the axis along
    which their cells differ most (neighbouring cells: the one axis they differ along)."""
    step = jnp.floor(q_b) - jnp.floor(q_a)
    axis = jnp.argmax(jnp.abs(step))
    sign = jnp.where(step[axis] < 0, -1.0, 1.0).astype(q_a.dtype)
    normal = jnp.where(jnp.arange(3) == axis, sign, 0.0).astype(q_a.dtype)
    return normal, sign * jnp.maximum(jnp.floor(q_a), jnp.floor(q_b))[axis], jnp.asarray(True)


def checker_cell(q):
    """The unit cell of ``q`` as one int32: its integer coordinates hashed (neighbours always differ)."""
    n = jnp.floor(q + 1e-10).astype(jnp.int32)
    return n[0] * 73856093 ^ n[1] * 19349663 ^ n[2] * 83492791


def _hexagon_cell(p):
    """``(centre x, centre z, value)`` of the hexagon holding ``p`` (see :func:`hexagon`): the
    nearest of the centres c(i, j) = (1.5 i, √3 (j + i/2)), which lies in one of the two columns
    bracketing x."""
    x, z = p[0], p[2]
    i0 = jnp.floor(x / 1.5)
    best = None
    for di in (0.0, 1.0):
        i = i0 + di
        j = jnp.round(z / _SQRT3 - 0.5 * i)
        cx, cz = 1.5 * i, _SQRT3 * (j + 0.5 * i)
        d2 = (x - cx) ** 2 + (z - cz) ** 2
        here = (d2, cx, cz, jnp.mod(j - i, 3.0))
        if best is not None:
            here = tuple(jnp.where(d2 < best[0], a, b) for a, b in zip(here, best, strict=True))
        best = here
    return best[1], best[2], best[3]


def hexagon(p, inputs):
    """Hexagonal rods along y, side 1, vertices on ±x, tiled in the x-z plane.

    Centres are c(i, j) = (1.5 i, √3 (j + i/2)); the value is (j - i) mod 3: 0 = COLOR_1 (the hexagon at
    the origin), 1 = COLOR_2 (the neighbour in +z), 2 = COLOR_3 (the neighbours at (1.5, ±√3/2)
    alternate 2 and 1 going round; POV-Ray's "COLOR_3 to either side").
    """
    return _hexagon_cell(p)[2]


def hexagon_cell(q):
    """The hexagon of ``q`` as one int32: its centre's indices (i, j) hashed."""
    cx, cz, _ = _hexagon_cell(q)
    i = jnp.round(cx / 1.5)
    j = jnp.round(cz / _SQRT3 - 0.5 * i)
    return i.astype(jnp.int32) * 73856093 ^ j.astype(jnp.int32) * 19349663


def hexagon_face(q_a, q_b, value):
    """The face between the hexagons of ``q_a`` and ``q_b``: each point lies in the cell of its
    nearest centre, so the face is the plane halfway between the two centres, square to the line
    joining them (normal from ``q_a``'s cell to ``q_b``'s)."""
    ax, az, _ = _hexagon_cell(q_a)
    bx, bz, _ = _hexagon_cell(q_b)
    zero = jnp.zeros((), q_a.dtype)
    step = jnp.stack([bx - ax, zero, bz - az]).astype(q_a.dtype)
    normal = step / jnp.sqrt(jnp.maximum(jnp.sum(step * step), jnp.finfo(q_a.dtype).tiny))
    offset = jnp.dot(normal, jnp.stack([0.5 * (ax + bx), zero, 0.5 * (az + bz)]).astype(q_a.dtype))
    return normal, offset, jnp.asarray(True)


def brick(p, inputs, *, brick_size, mortar):
    """1 = brick (COLOR_2), 0 = mortar (COLOR_1).

    Rows of height size.y; odd rows are shifted by half a brick in x, even rows by half a brick in z;
    the mortar occupies the last ``mortar`` of each cell along every axis (as POV-Ray 3.7 renders it).
    """
    bx, by, bz = brick_size
    row = jnp.floor(p[1] / by)
    odd = (row - 2.0 * jnp.floor(0.5 * row)) > 0.5
    fx = frac((p[0] + jnp.where(odd, 0.5 * bx, 0.0)) / bx) * bx
    fy = frac(p[1] / by) * by
    fz = frac((p[2] + jnp.where(odd, 0.0, 0.5 * bz)) / bz) * bz
    inside = (fx < bx - mortar) & (fy < by - mortar) & (fz < bz - mortar)
    return inside.astype(p.dtype)


# bisection steps that find an axis-square face between two pattern-space points a hair apart
_AXIS_BISECTIONS = 40


def axis_face(q_a, q_b, value):
    """``(normal, offset, found)``: the face between the cells of ``q_a`` and ``q_b`` for a pattern
    whose faces are planes square to its axes (brick), found by probing its ``value`` (q → value):
    the axis along which moving ``q_a`` to ``q_b``'s coordinate changes the value is the face's
    normal, and bisection along it finds the face (``found`` False where no single axis does:
    a corner between the two points)."""
    v_a = value(q_a)
    changes = jnp.stack([value(q_a.at[k].set(q_b[k])) != v_a for k in range(3)])
    axis = jnp.argmax(changes)
    lo, hi = q_a[axis], q_b[axis]
    for _ in range(_AXIS_BISECTIONS):
        mid = 0.5 * (lo + hi)
        same = value(q_a.at[axis].set(mid)) == v_a
        lo, hi = jnp.where(same, mid, lo), jnp.where(same, hi, mid)
    sign = jnp.where(q_b[axis] > q_a[axis], 1.0, -1.0).astype(q_a.dtype)
    normal = jnp.where(jnp.arange(3) == axis, sign, 0.0).astype(q_a.dtype)
    return normal, sign * 0.5 * (lo + hi), jnp.sum(changes) == 1


PATTERNS = (
    Pattern("checker", checker, colours=2, default_map=((0.0, BLUE), (1.0, GREEN)), face=checker_face,
            cell=checker_cell),
    Pattern("hexagon", hexagon, colours=3, default_map=((0.0, BLUE), (1.0, GREEN), (2.0, RED)),
            face=hexagon_face, cell=hexagon_cell),
    Pattern("brick", brick, colours=2, default_map=((0.0, WHITE), (1.0, RED)), face=axis_face,
            # POV-Ray's defaults: brick + mortar per axis, and the mortar's width
            modifiers={"brick_size": (8.0, 3.0, 4.5), "mortar": 0.5}),
)
