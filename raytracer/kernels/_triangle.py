"""Flat and smooth triangles (Möller & Trumbore 1997, "Fast, minimum storage ray/triangle intersection").

Barycentric convention: the hit is ``(1 - u - v) p1 + u p2 + v p3``, so the weights of
``(p1, p2, p3)`` are ``(1 - u - v, u, v)``. POV-Ray writes the smooth normal as
``(1-u')N1 + u'(1-v')N2 + u'v'N3`` in its own parametrisation; both are the unique barycentric weights
of the hit point, so the interpolated normals agree.
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from ._numerics import as_float_arrays, eps_of, safe_mask, safe_normalize

TRIANGLE_K = 1
SMOOTH_TRIANGLE_K = 1


def _barycentric_hit(p1, p2, p3, o, d):
    """``(t, u, v, hit, geometric normal)``; t, u, v are finite (but meaningless) where not ``hit``."""
    e1, e2, s = p2 - p1, p3 - p1, o - p1
    area = jnp.cross(e1, e2)  # twice the area, along the geometric normal
    pvec = jnp.cross(d, e2)
    det = jnp.dot(e1, pvec)  # = -d · area
    eps = eps_of(det)
    area_sq = jnp.dot(area, area)
    # A sliver whose sine of angle is below eps is degenerate (zero area); a line within eps of the
    # plane's direction is parallel. Both scale-free, both a miss.
    proper = area_sq > (eps * eps) * jnp.dot(e1, e1) * jnp.dot(e2, e2)
    ok = proper & (det * det > (eps * eps) * jnp.dot(d, d) * area_sq)
    inv_det = safe_mask(ok, lambda x: 1.0 / x, det)
    qvec = jnp.cross(s, e1)
    u = jnp.dot(s, pvec) * inv_det
    v = jnp.dot(d, qvec) * inv_det
    t = jnp.dot(e2, qvec) * inv_det
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1)
    return t, u, v, hit, safe_normalize(area)


def triangle_hits(
    p1: Float[ArrayLike, "3"],
    p2: Float[ArrayLike, "3"],
    p3: Float[ArrayLike, "3"],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the triangle (edges included).

    Args:
        p1, p2, p3: (3,) vertices; a zero-area triangle never hits.
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss; n (1, 3) = ``normalize((p2 - p1) × (p3 - p1))``, which
        may face either way (triangles have no inside; shading flips it towards the ray).
    """
    p1, p2, p3, o, d = as_float_arrays(p1, p2, p3, o, d)
    t, _, _, hit, n = _barycentric_hit(p1, p2, p3, o, d)
    up = jnp.zeros_like(n).at[2].set(1.0)
    return jnp.where(hit, t, jnp.inf)[None], jnp.where(hit, n, up)[None]


def triangle_inside(
    p1: Float[ArrayLike, "3"], p2: Float[ArrayLike, "3"], p3: Float[ArrayLike, "3"], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """Always False: a triangle has no inside."""
    return jnp.zeros((), bool)


def smooth_triangle_hits(
    p1: Float[ArrayLike, "3"],
    p2: Float[ArrayLike, "3"],
    p3: Float[ArrayLike, "3"],
    n1: Float[ArrayLike, "3"],
    n2: Float[ArrayLike, "3"],
    n3: Float[ArrayLike, "3"],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing with a triangle whose normal is interpolated from vertex normals.

    Args:
        p1, p2, p3: (3,) vertices.
        n1, n2, n3: (3,) vertex normals, any lengths (used as given, then the blend is normalised).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss; n (1, 3) = ``normalize((1-u-v) n1 + u n2 + v n3)``
        (the geometric normal if that blend vanishes); it may face either way.
    """
    p1, p2, p3, n1, n2, n3, o, d = as_float_arrays(p1, p2, p3, n1, n2, n3, o, d)
    t, u, v, hit, n_geo = _barycentric_hit(p1, p2, p3, o, d)
    n = safe_normalize((1.0 - u - v) * n1 + u * n2 + v * n3, fallback=n_geo)
    up = jnp.zeros_like(n).at[2].set(1.0)
    return jnp.where(hit, t, jnp.inf)[None], jnp.where(hit, n, up)[None]


def smooth_triangle_inside(
    p1: Float[ArrayLike, "3"],
    p2: Float[ArrayLike, "3"],
    p3: Float[ArrayLike, "3"],
    n1: Float[ArrayLike, "3"],
    n2: Float[ArrayLike, "3"],
    n3: Float[ArrayLike, "3"],
    p: Float[ArrayLike, "3"],
) -> Bool[Array, ""]:
    """Always False: a triangle has no inside."""
    return jnp.zeros((), bool)
