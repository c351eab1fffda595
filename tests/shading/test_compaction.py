"""Compaction (``shading/_chunks.nonzero``) and the stable order of small keys
(``shading/_chunks.stable_order``): the native loops (``_native/compact.cc``) and the JAX programs
used where the library is not built, against NumPy."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import _native
from raytracer.shading import _accel, _chunks


@pytest.mark.parametrize("native", [True, False])
def test_compaction_and_stable_order_are_numpys(native, monkeypatch):
    if native and _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    monkeypatch.setattr(_chunks, "_native", lambda: native)
    rng = np.random.default_rng(7)
    mask = rng.random((37, 41, 3)) < 0.05
    flat = np.flatnonzero(mask)
    for size in (flat.size + 9, flat.size - 5):  # room to spare, and too little (the count says so)
        index, count = jax.jit(lambda m, s=size: _chunks.nonzero(m, s))(jnp.asarray(mask))
        assert int(count) == flat.size
        kept = min(size, flat.size)
        np.testing.assert_array_equal(np.asarray(index)[:kept], flat[:kept])
        assert np.all(np.asarray(index)[kept:] == 0)
    # batched (one compaction per row of the batch)
    rows = rng.random((3, 50)) < 0.3
    index, count = jax.vmap(lambda m: _chunks.nonzero(m, 50))(jnp.asarray(rows))
    for r in range(3):
        want = np.flatnonzero(rows[r])
        assert int(count[r]) == want.size
        np.testing.assert_array_equal(np.asarray(index[r])[:want.size], want)
    key = rng.integers(0, 5, 1000)
    order = jax.jit(lambda k: _chunks.stable_order(k, 5))(jnp.asarray(key, jnp.int32))
    np.testing.assert_array_equal(np.asarray(order), np.argsort(key, kind="stable"))


def test_a_library_built_from_older_sources_is_a_reason_not_a_crash(monkeypatch):
    """An editable install whose native library predates ``compact.cc``: the library is reported
    unavailable, naming what it lacks (the renderer then takes the JAX paths), not an AttributeError."""
    import ctypes
    import types

    if _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    real = ctypes.cdll.LoadLibrary
    monkeypatch.setattr(ctypes.cdll, "LoadLibrary", lambda path: types.SimpleNamespace(
        **{n: getattr(real(path), n) for n in ("BvhBuildF32", "BvhBuildF64", "BvhClosestF32", "BvhClosestF64",
                                                "BvhAnyF32", "BvhAnyF64", "BvhAllF32", "BvhAllF64",
                                                "AaFlagsF32", "AaFlagsF64")}))
    lib, reason = _native.library.__wrapped__()
    assert lib is None and "Compact" in reason and "StableOrder" in reason and "Notice" in reason
