"""Small numerically safe helpers shared by the pattern families (double where: guard the input,
then select the output)."""

from __future__ import annotations

import math

import jax.numpy as jnp


def safe_atan2(y, x):
    """atan2 with a finite gradient at the origin (where it returns 0)."""
    ok = (x * x + y * y) > 0
    return jnp.where(ok, jnp.arctan2(jnp.where(ok, y, 0.0), jnp.where(ok, x, 1.0)), 0.0)


def frac(x):
    return x - jnp.floor(x)


def cycloidal(x):
    """POV's ``cycloidal``: sin(2π·frac(x)); taking frac first keeps float32 accurate for large x."""
    return jnp.sin((2.0 * math.pi) * frac(x))
