"""Kernels that describe the same surface must agree: the quadric reproduces the sphere and the
cylinder, the cone with equal radii is the cylinder, the smooth triangle with equal normals the flat one."""

import jax
import jax.numpy as jnp
import numpy as np

from ._case import jitted_kernels as k


def _rays(seed, count, spread=2.0):
    rng = np.random.default_rng(seed)
    o = rng.normal(size=(count, 3)) * 4.0
    d = rng.uniform(-spread, spread, size=(count, 3)) - o
    return jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)


def _assert_same_hits(t_a, n_a, t_b, n_b, normal_atol=1e-4):
    t_a, t_b, n_a, n_b = map(np.asarray, (t_a, t_b, n_a, n_b))
    np.testing.assert_array_equal(np.isfinite(t_a), np.isfinite(t_b))
    finite = np.isfinite(t_a)
    np.testing.assert_allclose(t_a[finite], t_b[finite], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(n_a[finite], n_b[finite], atol=normal_atol)


def test_quadric_reproduces_the_sphere():
    # (x-1)² + y² + (z+0.5)² - 4 = x² + y² + z² - 2x + z - 2.75.
    o, d = _rays(0, 200)
    coeffs = jnp.array([1.0, 1, 1, 0, 0, 0, -2, 0, 1, -2.75])
    t_q, n_q = jax.vmap(lambda o_, d_: k.quadric_hits(coeffs, o_, d_))(o, d)
    t_s, n_s = jax.vmap(lambda o_, d_: k.sphere_hits(jnp.array([1.0, 0.0, -0.5]), 2.0, o_, d_))(o, d)
    _assert_same_hits(t_q, n_q, t_s, n_s)


def test_quadric_reproduces_the_cylinder_side():
    # x² + z² - 1 = 0 is the infinite cylinder around y; a very tall finite cylinder has the same side.
    o, d = _rays(1, 200)
    t_q, n_q = jax.vmap(lambda o_, d_: k.quadric_hits(jnp.array([1.0, 0, 1, 0, 0, 0, 0, 0, 0, -1]), o_, d_))(
        o, d
    )
    tall = jnp.array([0.0, 1e3, 0.0])
    t_c, n_c = jax.vmap(lambda o_, d_: k.cylinder_hits(-tall, tall, 1.0, o_, d_, open=True))(o, d)
    # the cylinder's axis is 2,000 long: its float32 unit vector, computed in the program, is 1 to
    # an ulp (6e-8), which leaves up to 1,000·6e-8·2 = 1.2e-4 of the axis in a side normal (seen on
    # an Intel Xeon's XLA; 0 where the normalisation rounds to exactly 1)
    _assert_same_hits(t_q, n_q, t_c[:, :2], n_c[:, :2], normal_atol=3e-4)


def test_cone_with_equal_radii_is_the_cylinder():
    o, d = _rays(2, 200)
    base, cap = jnp.array([0.1, -1.0, 0.2]), jnp.array([0.3, 1.2, -0.1])
    t_a, n_a = jax.vmap(lambda o_, d_: k.cone_hits(base, 0.8, cap, 0.8, o_, d_))(o, d)
    t_b, n_b = jax.vmap(lambda o_, d_: k.cylinder_hits(base, cap, 0.8, o_, d_))(o, d)
    _assert_same_hits(t_a, n_a, t_b, n_b)


def test_smooth_triangle_with_equal_vertex_normals_is_the_flat_triangle():
    o, d = _rays(3, 200, spread=1.0)
    p1, p2, p3 = jnp.array([0.0, 0, 0.2]), jnp.array([1.5, 0.1, 0]), jnp.array([0.2, 1.3, -0.3])
    n = jnp.cross(p2 - p1, p3 - p1) * 3.0  # any length: the blend is normalised
    t_a, n_a = jax.vmap(lambda o_, d_: k.smooth_triangle_hits(p1, p2, p3, n, n, n, o_, d_))(o, d)
    t_b, n_b = jax.vmap(lambda o_, d_: k.triangle_hits(p1, p2, p3, o_, d_))(o, d)
    _assert_same_hits(t_a, n_a, t_b, n_b)


def test_polygon_triangle_matches_the_triangle():
    o, d = _rays(4, 200, spread=1.0)
    verts = jnp.array([[0.0, 0, 0.2], [1.5, 0.1, 0], [0.2, 1.3, -0.3]])
    edges = ((0, 1), (1, 2), (2, 0))
    t_a, n_a = jax.vmap(lambda o_, d_: k.polygon_hits(verts, edges, o_, d_))(o, d)
    t_b, n_b = jax.vmap(lambda o_, d_: k.triangle_hits(verts[0], verts[1], verts[2], o_, d_))(o, d)
    _assert_same_hits(t_a, n_a, t_b, n_b)
