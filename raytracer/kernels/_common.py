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


def matvec(a: Float[Array, "3 3"], v: Float[Array, "... 3"]) -> Float[Array, "... 3"]:
    """``a @ v`` (for each leading index of ``v``) as products and a sum of three terms, which XLA
    fuses with what surrounds it. As a ``dot``, each of a ray's 3×3 transforms was a library call
    of its own per batch: ``whitted.pov``'s four per-chunk dots took 80 ms of a 1.2 s render."""
    return jnp.sum(_lead(a, v) * v[..., None, :], axis=-1)


def vecmat(v: Float[Array, "... 3"], a: Float[Array, "3 3"]) -> Float[Array, "... 3"]:
    """``v @ a`` (for each leading index of ``v``), fused as :func:`matvec`."""
    return jnp.sum(v[..., :, None] * _lead(a, v), axis=-2)


def _lead(a, v):
    """``a`` with a unit axis for each leading axis of ``v`` (no implicit rank promotion)."""
    return a.reshape((1,) * (v.ndim - 1) + a.shape)
