"""Floating-point precision of scene parameters: float32 unless ``jax_enable_x64`` is on."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

_FLOAT32_MAX = float(np.finfo(np.float32).max)


class OutOfPrecision(ValueError):
    """A finite parameter that the working precision cannot hold (it would become infinite)."""


def default_float():
    """The float dtype parameters are created in (float64 when ``jax_enable_x64`` is on)."""
    return jnp.float64 if jax.config.jax_enable_x64 else jnp.float32


_CONSTANTS: dict = {}  # read-only arrays of Python numbers and tuples of them, by value and sign
_CONSTANTS_MAX = 4096
_BIG_INT = 1 << 63  # larger Python ints take the plain path (and its errors)


def _constant_key(x):
    """A key for a Python number or a short tuple of them (None otherwise); it tells -0.0 from 0.0."""
    tx = type(x)
    if tx is float or (tx is int and -_BIG_INT < x < _BIG_INT):
        return (x, math.copysign(1.0, x), jax.config.jax_enable_x64)
    if tx is tuple and len(x) <= 5 and all(type(e) is float or (type(e) is int and -_BIG_INT < e < _BIG_INT)
                                           for e in x):
        return (x, tuple(math.copysign(1.0, e) for e in x), jax.config.jax_enable_x64)
    return None


def as_float(x) -> jax.Array | np.ndarray:
    """Converts numbers, lists or arrays to an array of the default float dtype.

    JAX arrays (including tracers) that are already floating point keep their type and dtype, so
    values flowing through ``jax.grad`` or ``eqx.tree_at`` are never cast. Everything else becomes
    a read-only numpy array: a valid JAX leaf (``jit``/``grad`` take it like a JAX array) that
    costs ~1 µs to make, where a JAX array costs ~30-60 µs — the difference between 1 s and 20 s
    for a scene of 10^5 primitives. Read-only keeps the scene model immutable, as JAX arrays are,
    so the arrays of Python numbers (defaults, repeated finish values) are made once and shared.
    """
    key = _constant_key(x)
    if key is not None:
        a = _CONSTANTS.get(key)
        if a is None:
            a = _as_float(x)
            if len(_CONSTANTS) >= _CONSTANTS_MAX:
                _CONSTANTS.clear()
            _CONSTANTS[key] = a
        return a
    return _as_float(x)


_EXACT_INT = 1 << 53  # ints a float64 holds exactly


def _exact_number(e) -> bool:
    return type(e) is float or (type(e) is int and -_EXACT_INT < e < _EXACT_INT)


def _numbers(x) -> tuple | None:
    """The numbers of ``x`` when it is a Python number, a tuple of them or a tuple of equal-length
    tuples of them (a colour map), each exact in float64; None for anything else."""
    if type(x) is not tuple:
        flat = (x,)
    elif x and type(x[0]) is tuple:
        if not all(type(row) is tuple and len(row) == len(x[0]) for row in x):
            return None
        flat = tuple(e for row in x for e in row)
    else:
        flat = x
    return flat if all(map(_exact_number, flat)) else None


def _as_float(x) -> jax.Array | np.ndarray:
    """``as_float`` without the cache of constants. Python numbers (and tuples of them, see
    ``_numbers``) are checked in Python: a scene's colours and centres are mostly distinct
    values, and numpy's array checks below cost ~8 µs a value (10^5 spheres: ~3 values each)."""
    numbers = _numbers(x)
    if numbers is not None:
        return _from_numbers(x, numbers)
    if isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jnp.floating):
        return x
    src = np.asarray(x, dtype=np.float64)
    dtype = default_float()
    if dtype == jnp.float32:
        big = np.abs(src) > _FLOAT32_MAX
        if big.any() and np.isfinite(src[big]).any():
            v = src[big & np.isfinite(src)].flat[0]
            raise OutOfPrecision(f"expected a value within float32's range (±3.4e38), found {v:g}: load "
                                 "the scene in float64 (jax_enable_x64, --x64)")
    a = np.array(src, dtype=dtype)
    a.flags.writeable = False
    return a


def _from_numbers(x, numbers: tuple) -> np.ndarray:
    """``_as_float`` of ``x`` whose numbers are ``numbers`` (``_numbers(x)``)."""
    dtype = default_float()
    if dtype == jnp.float32:
        for v in numbers:
            if not -_FLOAT32_MAX <= v <= _FLOAT32_MAX and math.isfinite(v):
                raise OutOfPrecision(f"expected a value within float32's range (±3.4e38), found {v:g}: "
                                     "load the scene in float64 (jax_enable_x64, --x64)")
    a = np.array(x, dtype=dtype)
    a.flags.writeable = False
    return a


def as_float_or_none(x):
    """``as_float`` that lets ``None`` (an absent optional parameter) through."""
    return None if x is None else as_float(x)
