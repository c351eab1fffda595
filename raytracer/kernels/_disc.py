"""Disc: the part of a plane through ``center`` with ``hole_radius <= |p - center| <= radius``."""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from ._common import masked_hits, points_at
from ._numerics import as_float_arrays, safe_normalize, solve_linear

DISC_K = 1


def disc_hits(
    center: Float[ArrayLike, "3"],
    normal: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    hole_radius: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the disc (an annulus when ``hole_radius > 0``).

    Args:
        center: (3,) centre.
        normal: (3,) normal, any nonzero length; it points to the outside half-space.
        radius: () outer radius.
        hole_radius: () inner radius (0 for no hole).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss or a parallel ray; n (1, 3) = unit ``normal``.
    """
    center, normal, radius, hole_radius, o, d = as_float_arrays(center, normal, radius, hole_radius, o, d)
    n_hat = safe_normalize(normal)
    l = o - center
    t, ok = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, l))
    r = points_at(l, d, t[None])[0]
    rho_sq = jnp.dot(r, r)
    hit = ok & (rho_sq <= radius * radius) & (rho_sq >= hole_radius * hole_radius)
    return masked_hits(t[None], n_hat[None], hit[None])


def disc_inside(
    center: Float[ArrayLike, "3"],
    normal: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    hole_radius: Float[ArrayLike, ""],
    p: Float[ArrayLike, "3"],
) -> Bool[Array, ""]:
    """POV-Ray's disc inside: the half-space behind the disc's plane, ``n̂ · (p - center) < 0``."""
    center, normal, radius, hole_radius, p = as_float_arrays(center, normal, radius, hole_radius, p)
    return jnp.dot(safe_normalize(normal), p - center) < 0
