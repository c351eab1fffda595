"""Small helpers shared by the kernels: points along a ray and the masked (t, n) result."""

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float


def points_at(o: Float[Array, "3"], d: Float[Array, "3"], t: Float[Array, " K"]) -> Float[Array, "K 3"]:
    """``o + t d`` for each slot, with ``t = +inf`` (no crossing) replaced by 0 so the point is finite.

    Replacing ``t`` *before* the product keeps normals computed from these points finite, and their
    gradients too (``inf * 0`` never occurs).
    """
    t_safe = jnp.where(jnp.isfinite(t), t, 0.0)
    return o[None, :] + t_safe[:, None] * d[None, :]


def masked_hits(
    t: Float[Array, " K"], n: Float[Array, "K 3"], hit: Bool[Array, " K"]
) -> tuple[Float[Array, " K"], Float[Array, "K 3"]]:
    """The kernel result: ``t = +inf`` and ``n = +z`` in the slots that are not hits."""
    up = jnp.zeros_like(n).at[:, 2].set(1.0)
    return jnp.where(hit, t, jnp.inf), jnp.where(hit[:, None], n, up)
