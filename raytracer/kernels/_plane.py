"""Plane ``n̂ · p = distance`` with ``n̂ = normal / |normal|`` (POV-Ray normalises at parse time)."""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from ._common import masked_hits
from ._numerics import as_float_arrays, safe_normalize, solve_linear

PLANE_K = 1


def plane_hits(
    normal: Float[ArrayLike, "3"],
    distance: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the plane.

    Args:
        normal: (3,) plane normal, any nonzero length; it points to the outside.
        distance: () offset along the unit normal.
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` when the line is parallel to the plane; n (1, 3) = n̂.
    """
    normal, distance, o, d = as_float_arrays(normal, distance, o, d)
    n_hat = safe_normalize(normal)
    t, ok = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, o) - distance)
    return masked_hits(t[None], n_hat[None], ok[None])


def plane_inside(
    normal: Float[ArrayLike, "3"], distance: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside (below) the plane: ``n̂ · p < distance``."""
    normal, distance, p = as_float_arrays(normal, distance, p)
    return jnp.dot(safe_normalize(normal), p) < distance
