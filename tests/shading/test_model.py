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


@pytest.mark.slow  # five programs in float64
def test_pigments_by_pattern_are_every_patterns_pigments_with_their_derivatives(x64):
    """``pigments_at`` groups the needed entries by pattern and computes each group's pattern only;
    each needed entry's RGBFT and its derivatives with respect to the points and the pigments'
    parameters are those of ``pigment_at`` (which computes every pattern of the scene), whatever
    the order and mix of patterns, solid rows, a pattern we do not render (its value 0 still
    takes the row's phase) and entries not needed (float64: the same sums in another order)."""
    from raytracer import load_scene
    from raytracer._packing import with_field
    from raytracer._plan import make_plan
    from raytracer.shading import _materials
    from raytracer.shading._materials import pack_materials, pigment_at, pigments_at

    text = """
camera { location <0, 0, -5> look_at 0 }
sphere { 0, 1 pigment { granite turbulence 0.3 color_map { [0 rgbf <1, 0.2, 0.1, 0.6>] [1 rgbt 0.9] } } }
sphere { 1, 1 pigment { marble turbulence 0.8 } }
sphere { 2, 1 texture { pigment { bozo scale 0.3 } } texture { pigment { checker rgbf 1 rgb 0 } } }
sphere { 3, 1 pigment { rgbf <0.2, 0.4, 0.6, 0.5> } }
sphere { 4, 1 pigment { bozo phase 0.5 color_map { [0 rgb 1] [1 rgb <0, 0.5, 1>] } } }
"""
    scene = load_scene(text)
    # the last pigment's pattern one we parse but do not render (possible only through the API:
    # the plan warns, and its value is 0)
    obj = scene.objects[4]
    layer = obj.texture.layers[0]
    layer = with_field(layer, "pigment", with_field(layer.pigment, "pattern", "quilted"))
    obj = with_field(obj, "texture", with_field(obj.texture, "layers", (layer,)))
    scene = with_field(scene, "objects", (*scene.objects[:4], obj))
    plan = make_plan(scene)
    assert "quilted" in [w.feature for w in plan.warnings]
    mats = jax.tree_util.tree_map(jnp.asarray, pack_materials(plan, jnp.float64))
    assert _materials.costly_patterns(mats)
    rng = np.random.default_rng(3)
    m = 3 * _materials.PIGMENT_BLOCK + 77  # blocks that mix patterns, and a partial last block
    rows = jnp.asarray(rng.integers(0, len(plan.prims) * mats.n_layers, m), jnp.int32)
    points = jnp.asarray(rng.normal(size=(m, 3)) * 2, jnp.float64)
    needed = jnp.asarray(rng.random(m) < 0.6)

    @jax.jit
    def every_pattern(pts, ms):
        return jax.vmap(lambda r, p: pigment_at(ms, r, p))(rows, pts)

    @jax.jit
    def by_pattern(pts, ms):
        return pigments_at(ms, rows, pts, needed)

    want, got = every_pattern(points, mats), by_pattern(points, mats)
    keep = np.asarray(needed)
    np.testing.assert_allclose(np.asarray(got)[keep], np.asarray(want)[keep], rtol=1e-12, atol=1e-12)
    # only the unrendered pattern's entries needed: blocks of nothing else are computed too
    quilted = np.asarray(rows) // mats.n_layers == 4
    alone = np.asarray(pigments_at(mats, rows, points, jnp.asarray(quilted)))
    np.testing.assert_allclose(alone[quilted], np.asarray(want)[quilted], rtol=1e-12, atol=1e-12)
    tangents = (jnp.asarray(rng.normal(size=(m, 3)), jnp.float64),
                jax.tree_util.tree_map(lambda x: jnp.asarray(rng.normal(size=x.shape), x.dtype)
                                       if jnp.issubdtype(x.dtype, jnp.floating)
                                       else np.zeros(x.shape, jax.dtypes.float0), mats))  # (tables)
    _, d_want = jax.jit(lambda p, t: jax.jvp(every_pattern, p, t))((points, mats), tangents)
    _, d_got = jax.jit(lambda p, t: jax.jvp(by_pattern, p, t))((points, mats), tangents)
    assert np.abs(np.asarray(d_want)[keep]).max() > 0.1
    np.testing.assert_allclose(np.asarray(d_got)[keep], np.asarray(d_want)[keep], rtol=1e-9, atol=1e-9)

    def grad_of(fn):
        return jax.jit(jax.grad(lambda p: jnp.sum(jnp.where(needed[:, None], fn(p, mats), 0.0) ** 2)))(points)

    g_want, g_got = grad_of(every_pattern), grad_of(by_pattern)
    np.testing.assert_allclose(np.asarray(g_got), np.asarray(g_want), rtol=1e-9, atol=1e-9)


# transparent shadow casters with noise patterns: in the hierarchy (more than MIN_FILTER_ITEMS) and
# candidates (an intersection), lit by two point lights of one structure, an area light, an
# adaptive one and a spotlight; a floor of two texture layers (the top one a noise pattern), so the
# others' second layer is absent
SHADOWS = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 5, -8> look_at <0, 0.5, 0> angle 55 }
light_source { <-6, 10, -5> color rgb 0.7 }
light_source { <5, 8, -3> color rgb 0.5 }
light_source { <0, 9, 4> color rgb 0.4 area_light x, z, 3, 3 }
light_source { <-3, 8, 5> color rgb 0.3 area_light 2 * x, 2 * z, 3, 3 adaptive 0 }
light_source { <2, 7, -6> color rgb 0.6 spotlight point_at <0, 0.5, 0> radius 12 falloff 20 }
plane { y, 0 texture { pigment { rgb 0.8 } }
  texture { pigment { bozo scale 0.7 color_map { [0 rgbt 1] [1 rgbf <0.2, 0.5, 0.9, 0.5>] } } } }
#declare R = seed(5);
#for (i, 0, 19)
  sphere { <rand(R) * 6 - 3, 0.4 + rand(R), rand(R) * 5 - 2>, 0.3 + 0.2 * rand(R)
           pigment { #if (mod(i, 2)) granite turbulence 0.4 #else bozo scale 0.4 #end
                     color_map { [0 rgbf <1, 0.4, 0.2, 0.8>] [1 rgbt <0.3, 0.8, 1, 0.7>] } } }
#end
intersection { sphere { 0, 1 } box { -0.7, 0.7 } translate <1.5, 1.2, -1>
               pigment { marble turbulence 0.6 color_map { [0 rgbf 0.9] [1 rgb <0.5, 0.2, 0.1>] } } }
"""


@pytest.mark.slow  # two programs
def test_batch_shadows_through_noise_patterns_are_the_per_ray_shadows(monkeypatch):
    """Where transparent shadow casters have noise patterns, ``shade_batch`` computes the shadows of
    a chunk's rays together, each crossing's pattern only where the crossing is
    (``_batch_shadows``; an adaptive area light's samples likewise, chunk by chunk of (point,
    sample) pairs), and in the same call the pigments of the hits' texture layers. The image
    is that of the per-ray shadows and surfaces, which compute every pattern at every slot of
    crossings and at every hit. (The derivatives of the pigments so computed are held to the per-ray
    ones above; the rest of the batch path is products and sums.)"""
    from raytracer import load_scene, render
    from raytracer.shading import _model

    scene = load_scene(SHADOWS)
    # 16×12: the per-ray reference computes every pattern at every slot of every shadow ray (~20 ms
    # a pixel under the suite's unoptimised XLA: 18 s at 32×24)
    ours = np.asarray(render(scene, width=16, height=12))
    monkeypatch.setattr(_model, "costly_patterns", lambda mats: False)
    jax.clear_caches()
    reference = np.asarray(render(scene, width=16, height=12))
    assert np.isfinite(ours).all()
    np.testing.assert_allclose(ours, reference, atol=2e-5)
