"""Properties every kernel must have, checked on random rays against independent implicit functions.

Hypothesis draws seeds (derandomized, so runs are reproducible); each seed makes a batch of rays in
generic position, so no example sits exactly on an edge by construction.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ._cases import CASE_IDS, CASES, random_rays

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)
PROPERTY_SETTINGS = settings(max_examples=8, deadline=None, derandomize=True, database=None)
RAYS_PER_SEED = 64


def _cast(params, dtype):
    return tuple(jnp.asarray(p, dtype) for p in params)


@functools.cache
def batched_hits(case_index: int):
    case = CASES[case_index]

    @jax.jit
    def hits(params, o, d):
        return jax.vmap(lambda o_, d_: case.hits(*params, o_, d_))(o, d)

    return hits


@functools.cache
def batched_inside(case_index: int):
    case = CASES[case_index]
    return jax.jit(lambda params, p: jax.vmap(lambda q: case.inside(*params, q))(p))


def hits_in_float32(index, o, d):
    case = CASES[index]
    t, n = batched_hits(index)(
        _cast(case.params, jnp.float32), jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)
    )
    return np.asarray(t, np.float64), np.asarray(n, np.float64)


def finite_hits(index, seed):
    """Rays, and for each finite crossing: (ray index, t, hit point in float64, normal)."""
    o, d = random_rays(CASES[index], seed, RAYS_PER_SEED)
    t, n = hits_in_float32(index, o, d)
    ray, slot = np.nonzero(np.isfinite(t))
    p = o[ray] + t[ray, slot, None] * d[ray]
    return o, d, ray, t[ray, slot], p, n[ray, slot]


def resample(rows, count, seed):
    """``count`` rows drawn with replacement: fixed shapes, so the jitted kernels compile once."""
    pick = np.random.default_rng(seed).integers(0, len(rows[0]), size=count)
    return tuple(r[pick] for r in rows)


def numeric_gradient(f, p, h=1e-6):
    return np.array([(f(p + h * e) - f(p - h * e)) / (2 * h) for e in np.eye(3)])


@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
@PROPERTY_SETTINGS
@given(seed=SEEDS)
def test_every_finite_crossing_lies_on_the_surface(index, seed):
    case = CASES[index]
    o, d, ray, t, p, _ = finite_hits(index, seed)
    for i in range(len(t)):
        # float32: |p| has ~1e-7 relative rounding, t about the same; allow 20 ulps of the ray's scale.
        scale = np.linalg.norm(o[ray[i]]) + abs(t[i]) * np.linalg.norm(d[ray[i]]) + case.size
        assert abs(case.distance(p[i])) < 2e-6 * scale, (case.name, o[ray[i]], d[ray[i]], t[i])
        assert case.on_patch(p[i]), (case.name, p[i])


@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
@PROPERTY_SETTINGS
@given(seed=SEEDS)
def test_normals_are_unit_and_follow_the_implicit_gradient(index, seed):
    case = CASES[index]
    _, _, _, _, p, n = finite_hits(index, seed)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, rtol=1e-5)
    if not case.geometric_normal:
        return
    for i in range(len(p)):
        g = numeric_gradient(case.distance, p[i])
        cosine = n[i] @ g / np.linalg.norm(g)
        assert (cosine if case.signed_normal else abs(cosine)) > 1 - 1e-4, (case.name, p[i], n[i], g)


SOLID_CASES = [i for i, c in enumerate(CASES) if c.solid]


@pytest.mark.parametrize("index", SOLID_CASES, ids=[CASE_IDS[i] for i in SOLID_CASES])
@PROPERTY_SETTINGS
@given(seed=SEEDS)
def test_just_behind_the_normal_is_inside_and_just_ahead_is_outside(index, seed):
    case = CASES[index]
    _, _, _, _, p, n = finite_hits(index, seed)
    if len(p) == 0:
        return
    p, n = resample((p, n), 128, seed)
    step = 1e-4 * case.size
    params = _cast(case.params, jnp.float32)
    behind = np.asarray(batched_inside(index)(params, jnp.asarray(p - step * n, jnp.float32)))
    ahead = np.asarray(batched_inside(index)(params, jnp.asarray(p + step * n, jnp.float32)))
    assert behind.all(), (case.name, p[~behind])
    assert not ahead.any(), (case.name, p[ahead])


CONVEX_CASES = [i for i, c in enumerate(CASES) if c.convex and c.geometric_normal]


@pytest.mark.parametrize("index", CONVEX_CASES, ids=[CASE_IDS[i] for i in CONVEX_CASES])
@PROPERTY_SETTINGS
@given(seed=SEEDS)
def test_rays_spawned_outwards_never_rehit_a_convex_shape(index, seed):
    # As pbrt-v4's shapes_test: from a hit offset slightly along n, any direction in the n hemisphere
    # stays strictly beyond the supporting plane, so a convex (or planar) shape has no crossing at t > 0.
    case = CASES[index]
    _, _, _, _, p, n = finite_hits(index, seed)
    if len(p) == 0:
        return
    p, n = resample((p, n), 32, seed)
    rng = np.random.default_rng(seed)
    spawn_per_hit = 16
    w = rng.normal(size=(len(p), spawn_per_hit, 3))
    w *= np.sign(np.einsum("hsk,hk->hs", w, n))[..., None]
    # the offset is relative to the shape's size and to the hit point's own magnitude: a grazing
    # ray meets a plane thousands of units out, where float32 rounds a point by ~1e-3 (seed 69:
    # an offset of 2e-4 at |p| ≈ 1.2e4 re-hit the plane at t ≈ 1e-4, run alone)
    scale = np.maximum(case.size, np.linalg.norm(p, axis=1, keepdims=True))
    origins = np.repeat(p + 1e-4 * scale * n, spawn_per_hit, axis=0)
    t, _ = hits_in_float32(index, origins, w.reshape(-1, 3))
    assert not np.any(np.isfinite(t) & (t > 0)), (case.name, t[np.isfinite(t) & (t > 0)])


@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
def test_vmap_equals_one_ray_at_a_time(index):
    case = CASES[index]
    o, d = random_rays(case, 7, 12)
    params = _cast(case.params, jnp.float32)
    t_batch, n_batch = batched_hits(index)(params, jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    one = jax.jit(lambda params, o_, d_: case.hits(*params, o_, d_))
    singles = [
        one(params, jnp.asarray(oi, jnp.float32), jnp.asarray(di, jnp.float32))
        for oi, di in zip(o, d, strict=True)
    ]
    t_loop = np.stack([np.asarray(s[0]) for s in singles])
    n_loop = np.stack([np.asarray(s[1]) for s in singles])
    np.testing.assert_array_equal(np.isinf(t_batch), np.isinf(t_loop))
    np.testing.assert_allclose(
        np.where(np.isinf(t_loop), 0, t_batch), np.where(np.isinf(t_loop), 0, t_loop), rtol=1e-6
    )
    np.testing.assert_allclose(n_batch, n_loop, atol=1e-6)


@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
def test_float32_agrees_with_float64(index):
    case = CASES[index]
    o, d = random_rays(case, 11, 256)
    t32, n32 = hits_in_float32(index, o, d)
    with jax.enable_x64(True):
        t64, n64 = batched_hits(index)(_cast(case.params, jnp.float64), jnp.asarray(o), jnp.asarray(d))
        t64, n64 = np.asarray(t64), np.asarray(n64)
    both = np.isfinite(t32) & np.isfinite(t64)
    # Grazing rays may hit in one precision only; they must be rare.
    assert np.mean(np.isfinite(t32) != np.isfinite(t64)) < 0.01, case.name
    # Error along the ray relative to the size of the numbers involved (|o| and the hit distance).
    d_len = np.linalg.norm(d, axis=-1, keepdims=True)
    scale = (np.linalg.norm(o, axis=-1, keepdims=True) + case.size) / d_len + np.abs(np.where(both, t64, 0))
    err = np.abs(t32[both] - t64[both]) / scale[both]
    # Near-tangent crossings are ill-conditioned (error ~ eps / sqrt(discriminant)): bound the bulk
    # tightly and the worst case loosely.
    assert np.quantile(err, 0.99) < 1e-5, case.name
    assert np.max(err, initial=0) < 1e-3, case.name
    assert np.quantile(np.abs(n32 - n64)[both], 0.99) < 1e-3, case.name
