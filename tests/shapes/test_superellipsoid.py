"""Superellipsoid crossings against closed forms (the sphere, the box, points on the axes and diagonals, a
line through two spikes of a non-convex one) and against dense sampling of the manual's equation in numpy."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.shapes import REGISTRY, Superellipsoid, box_hits, sphere_hits
from raytracer.shapes._superellipsoid import superellipsoid_hits, superellipsoid_inside

from ._case import Case


def manual_value(p, e, n):
    """POV-Ray's left side, ``(|x|^(2/e) + |y|^(2/e))^(e/n) + |z|^(2/n)`` (1 on the surface), float64."""
    p = np.abs(np.asarray(p, np.float64))
    return (p[..., 0] ** (2 / e) + p[..., 1] ** (2 / e)) ** (e / n) + p[..., 2] ** (2 / n)


BATCH = 256  # every batch is padded to this, so each dtype compiles the kernel once


@functools.cache
def _batched(dtype):
    return jax.jit(jax.vmap(superellipsoid_hits, in_axes=(None, None, 0, 0)))


def _hits(e, n, o, d, dtype=jnp.float64):
    """Batched crossings (rays along the first axis of o, d; at most BATCH) as float64 numpy arrays."""
    count = len(o)
    pad = ((0, BATCH - count), (0, 0))
    o, d = np.pad(np.asarray(o, np.float64), pad), np.pad(np.asarray(d, np.float64), pad)
    with jax.enable_x64(dtype == jnp.float64):
        t, normal = _batched(dtype)(
            jnp.asarray(e, dtype), jnp.asarray(n, dtype), jnp.asarray(o, dtype), jnp.asarray(d, dtype)
        )
        return np.asarray(t, np.float64)[:count], np.asarray(normal, np.float64)[:count]


def _rays(seed, count, radius=3.0, spread=1.0):
    rng = np.random.default_rng(seed)
    o = rng.normal(size=(count, 3))
    o *= radius / np.linalg.norm(o, axis=1, keepdims=True)
    d = (rng.uniform(-spread, spread, size=(count, 3)) - o) * rng.uniform(0.3, 3.0, size=(count, 1))
    return o, d


def test_e_n_one_is_the_unit_sphere(x64):
    o, d = _rays(0, 256, spread=1.2)
    t, normal = _hits(1.0, 1.0, o, d)
    with jax.enable_x64(True):
        t_s, n_s = jax.jit(jax.vmap(lambda o_, d_: sphere_hits(jnp.zeros(3), 1.0, o_, d_)))(o, d)
    t_s, n_s = np.asarray(t_s), np.asarray(n_s)
    assert np.isfinite(t_s[:, 0]).sum() > 100
    np.testing.assert_array_equal(np.isfinite(t[:, :2]), np.isfinite(t_s))
    assert np.all(np.isinf(t[:, 2:]))
    finite = np.isfinite(t_s)
    np.testing.assert_allclose(t[:, :2][finite], t_s[finite], rtol=1e-9)
    np.testing.assert_allclose(normal[:, :2][finite], n_s[finite], atol=1e-9)


def test_small_exponents_fill_the_unit_box(x64):
    # With e = n = ε the shape lies between the box [-1, 1]^3 and the box shrunk by 2^-ε (the nested
    # p-norms with p = 2/ε exceed the largest coordinate by at most 2^(ε/2) each): its crossings are
    # sandwiched between those of the two boxes, and its normals are the box's face normals.
    eps = 0.01
    o, d = _rays(1, 256, spread=1.2)
    shrink = 2.0**-eps
    with jax.enable_x64(True):
        boxes = jax.jit(jax.vmap(lambda o_, d_, s: box_hits(-s * jnp.ones(3), s * jnp.ones(3), o_, d_),
                                 in_axes=(0, 0, None)))
        t_big, n_box = (np.asarray(a) for a in boxes(o, d, 1.0))
        t_small = np.asarray(boxes(o, d, shrink)[0])
    t, normal = _hits(eps, eps, o, d)
    both = np.isfinite(t_small[:, 0])
    assert both.sum() > 100
    assert np.all(np.isfinite(t[both, :2])) and np.all(np.isinf(t[both, 2:]))
    assert np.all(np.isinf(t[np.isinf(t_big[:, 0])]))
    tol = 1e-9
    assert np.all((t_big[both, 0] - tol <= t[both, 0]) & (t[both, 0] <= t_small[both, 0] + tol))
    assert np.all((t_small[both, 1] - tol <= t[both, 1]) & (t[both, 1] <= t_big[both, 1] + tol))
    # Away from the edges (second largest coordinate < 0.9) the normal is the face normal.
    p = o[both, None, :] + t[both, :2, None] * d[both, None, :]
    second = np.sort(np.abs(p), axis=-1)[..., 1]
    flat = second < 0.9
    np.testing.assert_allclose(normal[both, :2][flat], n_box[both][flat], atol=1e-3)


@pytest.mark.parametrize(("e", "n"), [(0.3, 0.7), (1.0, 1.0), (2.5, 0.5), (3.0, 4.0)])
def test_points_on_the_axes_and_diagonals(e, n, x64):
    # From the origin: along an axis the surface is at 1; along (1, 1, 0) at x = y = 2^(-e/2); along
    # (1, 0, 1) at x = z = 2^(-n/2); along (1, 1, 1) at (2^(e/n) + 1)^(-n/2).
    dirs = np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, 1], [1, 1, 0], [-1, 0, 1], [1, 1, -1]])
    expected = [1.0, 1.0, 1.0, 2 ** (-e / 2), 2 ** (-n / 2), (2 ** (e / n) + 1) ** (-n / 2)]
    t, normal = _hits(e, n, np.zeros((6, 3)), dirs)
    np.testing.assert_allclose(t[:, 0], -np.asarray(expected), rtol=1e-10)
    np.testing.assert_allclose(t[:, 1], expected, rtol=1e-10)
    assert np.all(np.isinf(t[:, 2:]))
    # On the axes the normal is the axis (by symmetry), for every e and n.
    np.testing.assert_allclose(normal[:3, 1], dirs[:3], atol=1e-12)


def test_a_line_through_two_spikes_of_a_star_crosses_four_times(x64):
    # e = n = 4, in the plane z = 0: √|x| + √|y| = 1. The line x + y = 0.9 runs through the spike
    # along y (√x + √(x + 0.9) = 1 at x = -0.0025; √x + √(0.9 - x) = 1 at x = ((1 ∓ √0.8) / 2)²)
    # and the spike along x (x = 0.9025): four crossings, two solid intervals.
    o, d = np.array([[-1.0, 1.9, 0.0]]), np.array([[1.0, -1.0, 0.0]])
    roots = [-0.0025, ((1 - np.sqrt(0.8)) / 2) ** 2, ((1 + np.sqrt(0.8)) / 2) ** 2, 0.9025]
    t, _ = _hits(4.0, 4.0, o, d)
    np.testing.assert_allclose(t[0, :4], np.asarray(roots) + 1.0, rtol=1e-10)
    assert np.all(np.isinf(t[0, 4:]))


def dense_crossings(o, d, e, n, samples=200_001):
    """Sign changes of the manual's equation on a dense grid of the ray's passage through the box."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-1 - o) / d, (1 - o) / d
    t_in, t_out = np.max(np.minimum(t1, t2)), np.min(np.maximum(t1, t2))
    if not t_in < t_out:
        return np.zeros(0), 0.0
    t = np.linspace(t_in - 1e-3, t_out + 1e-3, samples)
    inside = manual_value(o + t[:, None] * d, e, n) < 1
    i = np.nonzero(inside[1:] != inside[:-1])[0]
    return 0.5 * (t[i] + t[i + 1]), t[1] - t[0]


@pytest.mark.parametrize(("e", "n"), [(0.4, 3.0), (3.0, 0.5), (2.5, 2.5), (0.2, 0.2)])
def test_crossings_match_dense_sampling_of_the_manual_equation(e, n, x64):
    # Mixed exponents (one below 2, the other above) are the cases without a convexity argument.
    o, d = _rays(2, 100, spread=1.0)
    t, _ = _hits(e, n, o, d)
    agree = 0
    for i in range(len(o)):
        expected, step = dense_crossings(o[i], d[i], e, n)
        got = t[i][np.isfinite(t[i])]
        assert np.all(np.diff(got) > 0)
        if len(got) == len(expected):
            np.testing.assert_allclose(got, expected, atol=step)
            agree += 1
        else:  # a pair of crossings missed by one side must be a sliver the other side sees
            assert abs(len(got) - len(expected)) == 2
    assert agree >= 0.98 * len(o)


def test_float32_crossings_lie_on_the_surface_of_a_mixed_instance():
    o, d = _rays(3, BATCH)
    t, _ = _hits(3.0, 0.5, o, d, dtype=jnp.float32)
    ray, slot = np.nonzero(np.isfinite(t))
    assert ray.size > 150
    p = o[ray] + t[ray, slot, None] * d[ray]
    n_over_2 = 0.25  # the manual's left side to the power n/2 is homogeneous: distance-like
    level = manual_value(p, 3.0, 0.5) ** n_over_2 - 1
    assert np.max(np.abs(level)) < 1e-5


def test_inside_is_where_the_manual_equation_is_below_one():
    rng = np.random.default_rng(4)
    p = rng.uniform(-1.1, 1.1, size=(2000, 3))
    inside = jax.jit(jax.vmap(superellipsoid_inside, in_axes=(None, None, 0)))
    for e, n in [(0.5, 0.8), (3.0, 0.5), (4.0, 4.0)]:
        got = np.asarray(inside(e, n, jnp.asarray(p)))
        value = manual_value(p, e, n)
        clear = np.abs(value - 1) > 1e-4
        np.testing.assert_array_equal(got[clear], (value < 1)[clear])
        assert got.any() and not got.all()


Z = np.array([0.0, 0.0, 1.0])
# Inputs where a naive formula takes 0^p with p < 1, 0/0 or a power of an overflowing sum.
DEGENERATE = [
    ("zero direction", 1.0, 1.0, [0.0, 0.0, -5.0], [0.0, 0.0, 0.0]),
    ("down the z axis, pole of a star", 4.0, 4.0, [0.0, 0.0, -5.0], Z),
    ("down the z axis, rounded box", 0.2, 0.2, [0.0, 0.0, -5.0], Z),
    ("along the x axis from the centre", 3.0, 0.5, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
    ("close to a rounded edge", 0.3, 0.3, [-5.0, 0.88, 0.88], [1.0, 0.0, 0.0]),
    ("in the plane z = 0 along a diagonal", 2.0, 3.0, [-2.0, -2.0, 0.0], [1.0, 1.0, 0.0]),
    ("tiny exponents", 1e-6, 1e-6, [0.3, 0.2, -5.0], Z),
    ("zero exponents", 0.0, 0.0, [0.3, 0.2, -5.0], Z),
    ("large e, on the plane y = 0", 40.0, 1.0, [0.3, 0.0, -5.0], Z),
    ("e much larger than n", 30.0, 0.05, [0.5, 0.0, -5.0], Z),
    ("miss", 1.0, 1.0, [0.0, 3.0, -5.0], Z),
]


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64], ids=["float32", "float64"])
def test_degenerate_inputs_give_finite_values_and_gradients(dtype):
    with jax.enable_x64(dtype == jnp.float64):
        names = [c[0] for c in DEGENERATE]
        e, n, o, d = (jnp.asarray([c[i] for c in DEGENERATE], dtype) for i in range(1, 5))

        def loss(*args):
            t, normal = superellipsoid_hits(*args)
            weights = jnp.arange(1.0, 4.0, dtype=dtype)[None, :]
            return jnp.sum(jnp.where(jnp.isfinite(t), t, 0.0)) + jnp.sum(normal * weights), (t, normal)

        value_and_grads = jax.value_and_grad(loss, argnums=(0, 1, 2, 3), has_aux=True)
        (_, (t, normal)), grads = jax.jit(jax.vmap(value_and_grads))(e, n, o, d)
        for j, name in enumerate(names):
            assert not np.any(np.isnan(np.asarray(t[j]))), name
            np.testing.assert_allclose(np.linalg.norm(np.asarray(normal[j]), axis=-1), 1.0, rtol=1e-5,
                                       err_msg=name)
            for g in grads:
                assert np.all(np.isfinite(np.asarray(g[j]))), (name, g[j])
        hit = np.isfinite(np.asarray(t)).any(axis=1)
        assert hit.tolist() == [False] + [True] * (len(names) - 2) + [False]


def test_sdl_superellipsoid_parses_its_exponents():
    scene = rt.load_scene("camera { location <0, 0, -5> look_at 0 }\n"
                          "superellipsoid { <0.5, 0.8> scale 2 pigment { rgb 1 } }")
    (obj,) = scene.objects
    assert isinstance(obj.shape, Superellipsoid) and REGISTRY["superellipsoid"] is Superellipsoid
    np.testing.assert_allclose([obj.shape.e, obj.shape.n], [0.5, 0.8], rtol=1e-7)


def test_line_crossings_is_two_for_convex_instances_only():
    assert Superellipsoid(0.5, 2.0).line_crossings == 2
    assert Superellipsoid(2.5, 1.0).line_crossings == Superellipsoid.crossings == 8


# ---------------------------------------------------------------- the generic test cases
def _case(name, e, n, convex):
    def distance(p):
        # The manual's left side to the power n/2 (homogeneous of degree 1), minus 1.
        return manual_value(p, e, n) ** (n / 2) - 1

    return Case(name, Superellipsoid, (e, n), distance, np.zeros(3), 1.0, convex=convex)


# One generic case: the non-convex star takes every branch of the kernel (critical-point splits,
# several crossings per octant); each case costs a compile of the kernel (~10-25 s) per generic
# test. The convex shape is checked by the closed forms and sampling tests of this module.
CASES = [_case("superellipsoid star", 3.0, 2.5, convex=False)]
