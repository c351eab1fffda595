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


def checker_face(q_a, q_b):
    """The face between the unit cells of ``q_a`` and ``q_b``: the integer plane of the axis along
    which their cells differ most (neighbouring cells: the one axis they differ along)."""
    step = jnp.floor(q_b) - jnp.floor(q_a)
    axis = jnp.argmax(jnp.abs(step))
    sign = jnp.where(step[axis] < 0, -1.0, 1.0).astype(q_a.dtype)
    normal = jnp.where(jnp.arange(3) == axis, sign, 0.0).astype(q_a.dtype)
    return normal, sign * jnp.maximum(jnp.floor(q_a), jnp.floor(q_b))[axis]


def checker_cell(q):
    """The unit cell of ``q`` as one int32: its integer coordinates hashed (neighbours always differ)."""
    n = jnp.floor(q + 1e-10).astype(jnp.int32)
    return n[0] * 73856093 ^ n[1] * 19349663 ^ n[2] * 83492791


def hexagon(p, inputs):
    """Hexagonal rods along y, side 1, vertices on ±x, tiled in the x-z plane.

    Centres are c(i, j) = (1.5 i, √3 (j + i/2)); the value is (j - i) mod 3: 0 = COLOR_1 (the hexagon at
    the origin), 1 = COLOR_2 (the neighbour in +z), 2 = COLOR_3 (the neighbours at (1.5, ±√3/2)
    alternate 2 and 1 going round; POV-Ray's "COLOR_3 to either side").
    """
    x, z = p[0], p[2]
    i0 = jnp.floor(x / 1.5)
    best_d2, best_colour = None, None
    for di in (0.0, 1.0):  # the nearest centre lies in one of the two bracketing columns
        i = i0 + di
        j = jnp.round(z / _SQRT3 - 0.5 * i)
        d2 = (x - 1.5 * i) ** 2 + (z - _SQRT3 * (j + 0.5 * i)) ** 2
        colour = jnp.mod(j - i, 3.0)
        if best_d2 is None:
            best_d2, best_colour = d2, colour
        else:
            closer = d2 < best_d2
            best_colour = jnp.where(closer, colour, best_colour)
            best_d2 = jnp.where(closer, d2, best_d2)
    return best_colour


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


PATTERNS = (
    Pattern("checker", checker, colours=2, default_map=((0.0, BLUE), (1.0, GREEN)), face=checker_face,
            cell=checker_cell),
    Pattern("hexagon", hexagon, colours=3, default_map=((0.0, BLUE), (1.0, GREEN), (2.0, RED))),
    Pattern("brick", brick, colours=2, default_map=((0.0, WHITE), (1.0, RED)),
            # POV-Ray's defaults: brick + mortar per axis, and the mortar's width
            modifiers={"brick_size": (8.0, 3.0, 4.5), "mortar": 0.5}),
)
