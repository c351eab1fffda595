"""The shading model's plumbing that is not POV-Ray's formulas (those are held to POV-Ray's images
elsewhere): here, the fusion boundary around a hit's layers."""

from __future__ import annotations

import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shading._model import _materialised


@pytest.mark.parametrize("adc_bailout", [0.0, 1 / 255, 5.0])
def test_materialised_layers_are_the_layers_whichever_branch_runs(adc_bailout):
    """The shading model materialises a hit's layers behind a conditional on a scene value (a
    fusion boundary for XLA's CPU): both branches give the values unchanged, bools and ints
    included, under vmap and under differentiation, whatever the value (an adc_bailout of 5 takes
    the other branch)."""
    ctx = types.SimpleNamespace(settings=types.SimpleNamespace(adc_bailout=jnp.asarray(adc_bailout)))
    tree = (jnp.linspace(0.0, 1.0, 12).reshape(4, 3), jnp.arange(4) > 1, jnp.arange(4, dtype=jnp.int32))
    out = jax.jit(jax.vmap(lambda t: _materialised(ctx, t)))(tree)
    for got, want in zip(out, tree, strict=True):
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    grad = jax.grad(lambda x: jnp.sum(_materialised(ctx, (x,))[0] ** 2))(tree[0])
    np.testing.assert_allclose(np.asarray(grad), 2 * np.asarray(tree[0]), rtol=1e-6)
