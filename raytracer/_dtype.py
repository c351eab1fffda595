"""Floating-point precision of scene parameters: float32 unless ``jax_enable_x64`` is on."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def default_float():
    """The float dtype parameters are created in (float64 when ``jax_enable_x64`` is on)."""
    return jnp.float64 if jax.config.jax_enable_x64 else jnp.float32


def as_float(x) -> jax.Array:
    """Converts numbers, lists, numpy or JAX arrays to a JAX array of the default float dtype.

    JAX arrays (including tracers) that are already floating point keep their dtype, so values
    flowing through ``jax.grad`` or ``eqx.tree_at`` are never cast.
    """
    if isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jnp.floating):
        return x
    return jnp.asarray(np.asarray(x, dtype=np.float64), dtype=default_float())


def as_float_or_none(x):
    """``as_float`` that lets ``None`` (an absent optional parameter) through."""
    return None if x is None else as_float(x)
