"""The shared numerics: safe functions at their singular points, the stable quadratic, the quartic and
the implicit-function derivative of a root found without gradients."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.kernels import (
    differentiable_root,
    offset_sq_minus,
    safe_arccos,
    safe_div,
    safe_mask,
    safe_normalize,
    safe_pow,
    safe_sqrt,
    solve_linear,
    solve_quadratic,
    solve_quartic,
)

DTYPES = pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64], ids=["float32", "float64"])


def _all_finite(*xs):
    return all(np.all(np.isfinite(np.asarray(x))) for x in xs)


@DTYPES
@pytest.mark.parametrize(
    ("fn", "points"),
    [
        (safe_sqrt, [0.0, -1.0, 4.0]),
        (lambda x: safe_div(1.0, x), [0.0, 2.0]),
        (safe_arccos, [1.0, -1.0, 1.5, -2.0, 0.3]),
        (lambda x: safe_pow(x, 0.5), [0.0, -1.0, 4.0]),
        (lambda x: safe_pow(2.0, x), [0.0, 3.0]),
        (lambda x: safe_mask(x > 0, jnp.log, x), [0.0, -1.0, 1.0]),
        (lambda x: jnp.sum(safe_normalize(jnp.stack([x, 0.0 * x, 0.0 * x]))), [0.0, 1e-30, 2.0]),
    ],
)
def test_safe_functions_have_finite_gradients_at_their_singular_points(fn, points, dtype):
    with jax.enable_x64(dtype == jnp.float64):
        for x in points:
            x = jnp.asarray(x, dtype)
            value, grad = jax.value_and_grad(fn)(x)
            assert _all_finite(value, grad), (x, value, grad)
            assert value.dtype == dtype


def test_safe_functions_agree_with_numpy_inside_their_domains():
    np.testing.assert_allclose(safe_sqrt(4.0), 2.0)
    np.testing.assert_allclose(safe_div(1.0, 4.0), 0.25)
    np.testing.assert_allclose(safe_arccos(0.5), np.arccos(0.5), rtol=1e-6)
    np.testing.assert_allclose(safe_arccos(1.5), 0.0)
    np.testing.assert_allclose(safe_arccos(-1.5), np.pi, rtol=1e-6)
    np.testing.assert_allclose(safe_pow(4.0, 0.5), 2.0)
    np.testing.assert_allclose(safe_normalize(jnp.array([3.0, 0.0, 4.0])), [0.6, 0.0, 0.8], rtol=1e-6)
    np.testing.assert_allclose(safe_normalize(jnp.zeros(3)), [0.0, 0.0, 1.0])


def test_quadratic_keeps_the_small_root_in_float32():
    # t² - (1e4 + 1e-4) t + 1 = (t - 1e4)(t - 1e-4): the naive formula returns 0 for the small root.
    t0, t1, ok = solve_quadratic(jnp.float32(1.0), jnp.float32(-(1e4 + 1e-4)), jnp.float32(1.0))
    assert bool(ok)
    np.testing.assert_allclose([t0, t1], [1e-4, 1e4], rtol=1e-6)


def test_offset_sq_minus_is_exact_to_float32_near_a_huge_sphere():
    # |o - c|² - r² for points a few units above a radius-1e6 "ground sphere": ~2e6, while each term
    # is ~1e12 (float32 rounding ~6e4). Against float64; its gradient is the plain formula's.
    rng = np.random.default_rng(0)
    o = rng.uniform(-5, 5, (64, 3)).astype(np.float32)
    c, r = np.float32([0.3, -1e6 - 1, 0.7]), np.float32(1e6)
    exact = np.sum((o.astype(np.float64) - c.astype(np.float64)) ** 2, axis=1) - np.float64(r) ** 2
    ours = jax.vmap(lambda p: offset_sq_minus(p, jnp.asarray(c), r))(jnp.asarray(o))
    np.testing.assert_allclose(ours, exact, rtol=4 * np.finfo(np.float32).eps)
    naive = np.sum((o - c) ** 2, axis=1) - r * r
    assert np.max(np.abs(naive - exact) / np.abs(exact)) > 1e-3  # what the plain formula gives
    g = jax.grad(lambda p: offset_sq_minus(p, jnp.asarray(c), r))(jnp.asarray(o[0]))
    np.testing.assert_allclose(g, 2 * (o[0].astype(np.float64) - c), rtol=1e-6)


@pytest.mark.parametrize(
    ("a", "b", "c", "expected"),
    [
        (1.0, -3.0, 2.0, [1.0, 2.0]),  # two roots, ascending
        (1.0, 0.0, 1.0, [np.inf, np.inf]),  # none
        (1.0, -2.0, 1.0, [1.0, 1.0]),  # tangent: double root
        (1.0, 0.0, 0.0, [0.0, 0.0]),  # double root at 0 (q = 0)
        (0.0, 2.0, -4.0, [2.0, np.inf]),  # linear
        (0.0, 0.0, 1.0, [np.inf, np.inf]),  # constant, no root
        (0.0, 0.0, 0.0, [np.inf, np.inf]),  # identically zero: no isolated root
        (-2.0, 0.0, 8.0, [-2.0, 2.0]),  # negative leading coefficient
    ],
)
def test_quadratic_cases(a, b, c, expected):
    t0, t1, ok = solve_quadratic(a, b, c)
    np.testing.assert_allclose([t0, t1], expected, rtol=1e-6)
    assert bool(ok) == bool(np.isfinite(expected[0]))


@pytest.mark.parametrize(
    ("a", "b", "c"), [(1.0, -2.0, 1.0), (0.0, 0.0, 1.0), (0.0, 2.0, -4.0), (1e-30, 1.0, -1.0)]
)
def test_quadratic_gradients_are_finite_at_degenerate_coefficients(a, b, c):
    def finite_roots_sum(a, b, c):
        t0, t1, _ = solve_quadratic(a, b, c)
        roots = jnp.stack([t0, t1])
        return jnp.sum(jnp.where(jnp.isfinite(roots), roots, 0.0))

    grads = jax.jit(jax.grad(finite_roots_sum, argnums=(0, 1, 2)))(a, b, c)
    assert _all_finite(*grads)


def test_linear_root_beyond_one_over_eps_counts_as_parallel():
    t, ok = solve_linear(jnp.float32(1e-9), jnp.float32(-1.0))
    assert not bool(ok) and np.isinf(t)
    t, ok = solve_linear(jnp.float32(0.5), jnp.float32(-1.0))
    assert bool(ok) and float(t) == 2.0


def test_quartic_matches_numpy_roots_on_polynomials_with_known_roots(x64):
    rng = np.random.default_rng(0)
    solve = jax.jit(solve_quartic)
    for _ in range(50):
        roots = np.sort(rng.uniform(-1, 1, size=rng.integers(0, 5)))
        if len(roots) > 1 and np.min(np.diff(roots)) < 1e-2:
            continue
        poly = np.atleast_1d(np.poly(roots)) * rng.uniform(0.5, 2.0)
        # Pad to degree 4 with a positive quadratic factor (no real roots) where needed.
        while len(poly) < 5:
            poly = np.polymul(poly, [1.0, 0.0, 1.5]) if len(poly) <= 3 else np.concatenate([[0.0], poly])
        got, ok = solve(jnp.asarray(poly), -2.0, 2.0)
        got = np.sort(np.asarray(got)[np.asarray(ok)])
        np.testing.assert_allclose(got, roots, atol=1e-10)


def test_differentiable_root_has_the_implicit_derivative():
    # Root of f(t) = t² - θ is sqrt(θ): dt/dθ = 1 / (2 sqrt θ), d²t/dθ² = -1 / (4 θ^1.5).
    def root(theta):
        return differentiable_root(lambda t: t * t - theta, jnp.sqrt(jax.lax.stop_gradient(theta)))

    theta = 2.0
    np.testing.assert_allclose(root(theta), np.sqrt(theta), rtol=1e-6)
    np.testing.assert_allclose(jax.grad(root)(theta), 0.5 / np.sqrt(theta), rtol=1e-5)
    np.testing.assert_allclose(jax.grad(jax.grad(root))(theta), -0.25 * theta**-1.5, rtol=1e-4)


def test_differentiable_root_at_a_double_root_stays_finite():
    g = jax.grad(lambda theta: differentiable_root(lambda t: (t - theta) ** 2, theta))(1.0)
    assert np.isfinite(g)


def test_matvec_and_vecmat_are_the_matrix_products_for_any_leading_axes():
    """The fused 3×3 products the renderer transforms rays, points and normals with, against numpy's
    float64 products (one vector, and a batch)."""
    from raytracer.kernels import matvec, vecmat

    rng = np.random.default_rng(7)
    a = rng.normal(size=(3, 3))
    for v in (rng.normal(size=3), rng.normal(size=(5, 3))):
        np.testing.assert_allclose(np.asarray(matvec(jnp.asarray(a), jnp.asarray(v))), v @ a.T, rtol=1e-5,
                                   atol=1e-6)
        np.testing.assert_allclose(np.asarray(vecmat(jnp.asarray(v), jnp.asarray(a))), v @ a, rtol=1e-5,
                                   atol=1e-6)


def test_bisection_answers_a_root_at_either_end_with_that_end():
    """A bracket whose end is a root (a curve's joint: a prism's or a lathe's line through it) gives
    that end, not the point the halvings moved to."""
    from raytracer.kernels._numerics import _bisect

    lo, hi = jnp.array([0.0, 0.0, 0.0]), jnp.array([1.0, 1.0, 1.0])
    root, has = _bisect(lambda s: jnp.stack([s[0], s[1] - 1.0, s[2] - 0.3]), lo, hi, 30)
    np.testing.assert_allclose(np.asarray(root), [0.0, 1.0, 0.3], atol=1e-7)
    assert np.asarray(has).all()
