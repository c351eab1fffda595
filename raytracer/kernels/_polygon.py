"""Planar polygon with any number of sub-polygons, filled by the even-odd (Jordan) rule, so overlaps
and nested loops make holes, as POV-Ray's ``polygon``.

The plane comes from Newell's normal (the vector area ``Σ a × b`` over the edges, taken about the
centroid to avoid cancellation), which is robust to nearly collinear vertices. The point-in-polygon
test counts crossings of a ray in the plane with the (static) edge list, all edges at once.
"""

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from ._common import masked_hits, points_at
from ._numerics import as_float_arrays, eps_of, safe_div, safe_normalize, solve_linear

POLYGON_K = 1


def _plane_basis(n: Float[Array, "3"]) -> tuple[Float[Array, "3"], Float[Array, "3"]]:
    """Two unit vectors spanning the plane of unit ``n``, branch-free.

    Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (JCGT 6(1)).
    """
    sign = jnp.copysign(1.0, n[2]).astype(n.dtype)
    a = -1.0 / (sign + n[2])  # |sign + n_z| >= 1
    b = n[0] * n[1] * a
    u = jnp.stack([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    w = jnp.stack([b, sign + n[1] * n[1] * a, -n[1]])
    return u, w


def _even_odd(px, py, ax, ay, bx, by) -> Array:
    """Parity of the crossings of the ray from (px, py) towards +x with the edges a -> b (2-D)."""
    # Half-open straddle test: a vertex exactly at height py counts for one of its two edges only.
    straddle = (ay > py) != (by > py)
    x_at_py = ax + safe_div((py - ay) * (bx - ax), by - ay)
    crossings = jnp.sum(straddle & (px < x_at_py))
    return crossings % 2 == 1


def polygon_hits(
    vertices: Float[ArrayLike, "V 3"],
    edges: Sequence[tuple[int, int]],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the filled polygon.

    Args:
        vertices: (V, 3) coplanar points.
        edges: static sequence of ``(i, j)`` vertex index pairs; each sub-polygon is a closed loop of
            edges (orientation of each loop is free, the fill is even-odd).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss, a parallel ray or a degenerate (zero-area) polygon;
        n (1, 3) the unit Newell normal (its sign follows the winding of the loops; may face either way).
    """
    vertices, o, d = as_float_arrays(vertices, o, d)
    index = np.asarray(edges, dtype=np.int32).reshape(-1, 2)
    centroid = jnp.mean(vertices, axis=0)
    a = vertices[index[:, 0]] - centroid[None, :]
    b = vertices[index[:, 1]] - centroid[None, :]
    area = jnp.sum(jnp.cross(a, b), axis=0)  # Newell: twice the vector area
    scale = jnp.sum(a * a) + jnp.sum(b * b)
    eps = eps_of(scale)
    proper = jnp.dot(area, area) > (eps * scale) ** 2
    n_hat = safe_normalize(area)
    l = o - centroid
    t, ok = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, l))
    q = points_at(l, d, t[None])[0]
    u, w = _plane_basis(n_hat)
    inside = _even_odd(jnp.dot(q, u), jnp.dot(q, w), a @ u, a @ w, b @ u, b @ w)
    return masked_hits(t[None], n_hat[None], (ok & proper & inside)[None])


def polygon_inside(
    vertices: Float[ArrayLike, "V 3"], edges: Sequence[tuple[int, int]], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """Always False: a polygon has no inside."""
    return jnp.zeros((), bool)
