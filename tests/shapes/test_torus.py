"""Torus crossings against numpy's companion-matrix roots of the same quartic, in float64."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shapes import Torus

from ._case import Case
from ._case import jitted_kernels as k


def numpy_torus_roots(major, minor, o, d):
    """Real roots of the torus quartic along o + t d, from ``np.roots`` in float64.

    Returns (roots, well_conditioned): the second is False when two real roots nearly coincide or a
    complex pair is nearly real (grazing rays), where no float32 solver can be held to a tight tolerance.
    """
    o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
    norm_sq = np.array([d @ d, 2 * o @ d, o @ o])  # |o + t d|² as a polynomial in t
    planar = np.array([d[0] ** 2 + d[2] ** 2, 2 * (o[0] * d[0] + o[2] * d[2]), o[0] ** 2 + o[2] ** 2])
    shifted = norm_sq + np.array([0.0, 0.0, major**2 - minor**2])
    quartic = np.polysub(np.polymul(shifted, shifted), 4 * major**2 * planar)
    roots = np.roots(quartic)
    real = np.sort(roots[np.abs(roots.imag) < 1e-7].real)
    complex_ok = np.all(np.abs(roots.imag[np.abs(roots.imag) >= 1e-7]) > 1e-2)
    separated = len(real) < 2 or np.min(np.diff(real)) > 1e-2
    return real, bool(complex_ok and separated)


def random_torus_rays(seed, count):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        major = rng.uniform(1.0, 3.0)
        minor = rng.uniform(0.1, 0.9) * major
        o = rng.normal(size=3) * 4 * major
        target = rng.uniform(-1, 1, size=3) * (major + minor)
        d = (target - o) * rng.uniform(0.2, 3.0)  # not unit length on purpose
        yield major, minor, o, d


def finite_sorted(t):
    t = np.asarray(t, np.float64)
    return np.sort(t[np.isfinite(t)])


def test_torus_axis_ray_crosses_the_tube_twice_on_each_side():
    # R = 2, r = 0.5 along x from x = -5: tube walls at x = -2.5, -1.5, 1.5, 2.5 -> t = 2.5, 3.5, 6.5, 7.5.
    t, n = k.torus_hits(2.0, 0.5, jnp.array([-5.0, 0.0, 0.0]), jnp.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(t, [2.5, 3.5, 6.5, 7.5], rtol=1e-6)
    x = np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(n, [-x, x, -x, x], atol=1e-6)


def test_torus_ray_down_the_hole_misses():
    t, _ = k.torus_hits(2.0, 0.5, jnp.array([0.0, 5.0, 0.0]), jnp.array([0.0, -1.0, 0.0]))
    assert np.all(np.isinf(t))


def test_torus_vertical_ray_through_the_tube_centre():
    # Down through (2, y, 0): the tube spans y in [-0.5, 0.5] -> t = 4.5, 5.5, normals +y then -y.
    t, n = k.torus_hits(2.0, 0.5, jnp.array([2.0, 5.0, 0.0]), jnp.array([0.0, -1.0, 0.0]))
    np.testing.assert_allclose(finite_sorted(t), [4.5, 5.5], rtol=1e-6)
    finite = np.isfinite(np.asarray(t))
    np.testing.assert_allclose(np.asarray(n)[finite], [[0, 1, 0], [0, -1, 0]], atol=1e-6)


def _compare_with_numpy(dtype, rtol_scale, seed, count):
    checked = 0
    hits = jax.jit(k.torus_hits)
    for major, minor, o, d in random_torus_rays(seed, count):
        expected, well_conditioned = numpy_torus_roots(major, minor, o, d)
        if not well_conditioned:
            continue
        t, _ = hits(
            jnp.asarray(major, dtype), jnp.asarray(minor, dtype), jnp.asarray(o, dtype), jnp.asarray(d, dtype)
        )
        got = finite_sorted(t)
        assert len(got) == len(expected), (major, minor, o, d, got, expected)
        # Absolute position error along the ray, relative to the torus size.
        err = np.abs(got - expected) * np.linalg.norm(d) / (major + minor)
        assert np.all(err < rtol_scale), (err, major, minor, o, d)
        checked += 1
    assert checked > count // 2


def test_torus_matches_numpy_roots_in_float64(x64):
    _compare_with_numpy(jnp.float64, 1e-10, seed=1, count=200)


def test_torus_matches_numpy_roots_in_float32():
    # float32 positions far from the torus (|o| up to ~12 (R + r)) lose ~eps |o| to rounding alone.
    _compare_with_numpy(jnp.float32, 2e-5, seed=2, count=200)


def test_torus_inside_the_tube_and_in_the_hole():
    assert bool(k.torus_inside(2.0, 0.5, jnp.array([2.2, 0.1, 0.0])))
    assert not bool(k.torus_inside(2.0, 0.5, jnp.array([0.0, 0.0, 0.0])))
    assert not bool(k.torus_inside(2.0, 0.5, jnp.array([0.0, 0.0, 2.6])))


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_torus_zero_direction_is_a_finite_miss(dtype):
    with jax.enable_x64(dtype == jnp.float64):
        t, n = k.torus_hits(jnp.asarray(2.0, dtype), 0.5, jnp.ones(3, dtype), jnp.zeros(3, dtype))
        assert np.all(np.isinf(t)) and np.all(np.isfinite(np.asarray(n)))


# ---------------------------------------------------------------- the generic test case
def _torus_case():
    major, minor = 1.5, 0.4

    def distance(p):
        return np.hypot(np.hypot(p[0], p[2]) - major, p[1]) - minor

    return Case(
        "torus", Torus, (major, minor), distance, np.zeros(3), 1.9, convex=False
    )


CASES = [_torus_case()]
