"""Derivatives: finite differences at generic inputs (float64), and finite values and gradients at every
degenerate input we know of (float32 and float64)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import shapes as k

from ._cases import CASE_IDS, CASES, random_rays
from ._derivatives import assert_derivatives_match_fd


def generic_hit_ray(case, seed=3):
    """The first seeded ray whose crossings are all well inside their faces and far from grazing, so
    finite differences see a smooth function (near a tangent, derivatives grow like 1/sqrt(disc))."""
    o, d = random_rays(case, seed, 64)
    with jax.enable_x64(True):
        t, n = jax.jit(jax.vmap(lambda o_, d_: case.hits(*case.params, o_, d_)))(o, d)
    t, n = np.asarray(t), np.asarray(n)
    for i in range(len(o)):
        finite = np.isfinite(t[i])
        d_hat = d[i] / np.linalg.norm(d[i])
        steep = np.all(np.abs(n[i][finite] @ d_hat) > 0.3)
        inner = all(case.on_patch(o[i] + 0.999 * tt * d[i]) for tt in t[i][finite])
        if finite.any() and steep and inner:
            return o[i], d[i], finite
    raise AssertionError(f"no generic hit for {case.name}")


def _crossings_function(case):
    o, d, finite = generic_hit_ray(case)
    args = tuple(jnp.asarray(p, jnp.float64) for p in (*case.params, o, d))

    def crossings(*args):
        t, n = case.hits(*args)
        return jnp.concatenate([t[finite], n[finite].ravel()])

    return crossings, args


@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
def test_hits_match_finite_differences(index, x64):
    crossings, args = _crossings_function(CASES[index])
    assert_derivatives_match_fd(crossings, args, order=1)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
def test_hits_match_finite_differences_to_second_order(index, x64):
    crossings, args = _crossings_function(CASES[index])
    assert_derivatives_match_fd(crossings, args, order=2)


def test_inflating_sphere_moves_the_centre_hit_back_along_the_ray():
    # A ray aimed at the centre meets the near surface at t = (|o - c| - r) / |d|: growing the radius
    # by dr brings that point dr closer along the ray, so dt/dr = -1/|d| (and +1/|d| for the far hit).
    @functools.partial(jax.jit, static_argnums=(1,))
    def t_of_radius(r, slot, scale):
        t, _ = k.sphere_hits(
            jnp.array([0.2, -0.1, 0.3]), r, jnp.array([0.2, -0.1, -4.7]), jnp.array([0, 0, scale])
        )
        return t[slot]

    dt_dr = jax.grad(t_of_radius)
    np.testing.assert_allclose(dt_dr(1.3, 0, 1.0), -1.0, rtol=1e-6)
    np.testing.assert_allclose(dt_dr(1.3, 1, 1.0), 1.0, rtol=1e-6)
    np.testing.assert_allclose(dt_dr(1.3, 0, 2.0), -0.5, rtol=1e-6)


def test_moving_a_plane_along_its_normal_moves_the_hit_by_the_inverse_cosine():
    # t = (dist - n̂·o) / (n̂·d): dt/d(dist) = 1 / (n̂·d).
    d = jnp.array([0.6, 0.8, 0.0])
    g = jax.jit(jax.grad(lambda dist: k.plane_hits(jnp.array([0.0, 1.0, 0.0]), dist, jnp.zeros(3), d)[0][0]))(
        2.0
    )
    np.testing.assert_allclose(g, 1 / 0.8, rtol=1e-6)


Y, Z = jnp.array([0.0, 1.0, 0.0]), jnp.array([0.0, 0.0, 1.0])
ZERO = jnp.zeros(3)
O_MINUS_Z = jnp.array([0.0, 0.0, -5.0])
SQUARE = jnp.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
LOOP4 = ((0, 1), (1, 2), (2, 3), (3, 0))
SPHERE_QUADRIC = jnp.array([1.0, 1, 1, 0, 0, 0, 0, 0, 0, -1])


def square_polygon_hits(v, o, d):
    return k.polygon_hits(v, LOOP4, o, d)


# (name, kernel, args): inputs where a naive formula divides by zero, takes sqrt(0) or arccos(1).
DEGENERATE = [
    ("sphere miss", k.sphere_hits, (ZERO, 1.0, jnp.array([0.0, 3.0, -5.0]), Z)),
    ("sphere tangent, disc = 0", k.sphere_hits, (ZERO, 1.0, jnp.array([1.0, 0.0, -5.0]), Z)),
    ("sphere zero direction", k.sphere_hits, (ZERO, 1.0, O_MINUS_Z, ZERO)),
    ("sphere ray from the centre", k.sphere_hits, (ZERO, 1.0, ZERO, Z)),
    ("sphere zero radius", k.sphere_hits, (ZERO, 0.0, O_MINUS_Z, Z)),
    ("plane parallel ray", k.plane_hits, (Y, 1.0, ZERO, Z)),
    ("plane ray inside the plane", k.plane_hits, (Y, 0.0, ZERO, Z)),
    ("plane zero direction", k.plane_hits, (Y, 1.0, ZERO, ZERO)),
    ("plane zero normal", k.plane_hits, (ZERO, 1.0, ZERO, Z)),
    ("box axis-parallel ray", k.box_hits, (-jnp.ones(3), jnp.ones(3), O_MINUS_Z, Z)),
    ("box ray in a face plane", k.box_hits, (-jnp.ones(3), jnp.ones(3), jnp.array([1.0, 0.0, -5.0]), Z)),
    ("box ray along an edge", k.box_hits, (-jnp.ones(3), jnp.ones(3), jnp.array([1.0, 1.0, -5.0]), Z)),
    (
        "box through a corner",
        k.box_hits,
        (-jnp.ones(3), jnp.ones(3), jnp.array([2.0, 2.0, 2.0]), -jnp.ones(3)),
    ),
    ("box zero direction", k.box_hits, (-jnp.ones(3), jnp.ones(3), O_MINUS_Z, ZERO)),
    ("box flat", k.box_hits, (jnp.array([-1.0, -1, 0]), jnp.array([1.0, 1, 0]), O_MINUS_Z, Z)),
    ("cylinder along its axis", k.cylinder_hits, (-Z, Z, 1.0, O_MINUS_Z, Z)),
    ("cylinder tangent to the side", k.cylinder_hits, (-Y, Y, 1.0, jnp.array([1.0, 0.0, -5.0]), Z)),
    ("cylinder parallel to the caps", k.cylinder_hits, (-Y, Y, 1.0, O_MINUS_Z, Z)),
    ("cylinder zero direction", k.cylinder_hits, (-Y, Y, 1.0, O_MINUS_Z, ZERO)),
    ("cylinder zero length", k.cylinder_hits, (Y, Y, 1.0, O_MINUS_Z, Z)),
    ("cylinder zero radius", k.cylinder_hits, (-Y, Y, 0.0, O_MINUS_Z, Z)),
    ("cone through the apex along the axis", k.cone_hits, (-Z, 1.0, Z, 0.0, O_MINUS_Z, Z)),
    ("cone through the apex obliquely", k.cone_hits, (-Y, 1.0, Y, 0.0, jnp.array([0.0, -1.0, -2.0]), Y + Z)),
    # Parallel to a generator (a = 0): the side x = 1 - y... in the y-z plane of the cone r = (1 - y)/2.
    (
        "cone ray parallel to a generator",
        k.cone_hits,
        (-Y, 1.0, Y, 0.0, jnp.array([0.0, -5.0, 3.5]), Y - 0.5 * Z),
    ),
    ("cone zero direction", k.cone_hits, (-Y, 1.0, Y, 0.0, O_MINUS_Z, ZERO)),
    ("cone both radii zero", k.cone_hits, (-Y, 0.0, Y, 0.0, O_MINUS_Z, Z)),
    (
        "quadric linear case (paraboloid axis)",
        k.quadric_hits,
        (jnp.array([1.0, 0, 1, 0, 0, 0, 0, -1, 0, 0]), -5 * Y, Y),
    ),
    (
        "quadric cylinder along its axis",
        k.quadric_hits,
        (jnp.array([1.0, 1, 0, 0, 0, 0, 0, 0, 0, -1]), O_MINUS_Z, Z),
    ),
    (
        "quadric cone apex, zero gradient",
        k.quadric_hits,
        (jnp.array([1.0, 1, -1, 0, 0, 0, 0, 0, 0, 0]), O_MINUS_Z, Z),
    ),
    ("quadric all zero", k.quadric_hits, (jnp.zeros(10), O_MINUS_Z, Z)),
    ("quadric zero direction", k.quadric_hits, (SPHERE_QUADRIC, O_MINUS_Z, ZERO)),
    ("quadric tangent", k.quadric_hits, (SPHERE_QUADRIC, jnp.array([1.0, 0.0, -5.0]), Z)),
    ("torus miss", k.torus_hits, (2.0, 0.5, jnp.array([0.0, 3.0, -5.0]), Z)),
    ("torus down the axis", k.torus_hits, (2.0, 0.5, 5 * Y, -Y)),
    (
        "torus grazing the top",
        k.torus_hits,
        (2.0, 0.5, jnp.array([-5.0, 0.5, 0.0]), jnp.array([1.0, 0.0, 0.0])),
    ),
    ("torus zero direction", k.torus_hits, (2.0, 0.5, O_MINUS_Z, ZERO)),
    ("torus zero minor radius", k.torus_hits, (2.0, 0.0, jnp.array([2.0, 5.0, 0.0]), -Y)),
    ("torus from the origin", k.torus_hits, (2.0, 0.5, ZERO, jnp.array([1.0, 0.0, 0.0]))),
    ("disc parallel ray", k.disc_hits, (ZERO, Z, 1.0, 0.0, jnp.array([0.0, 0.0, 1.0]), Y)),
    ("disc through the centre", k.disc_hits, (ZERO, Z, 1.0, 0.0, O_MINUS_Z, Z)),
    ("disc zero direction", k.disc_hits, (ZERO, Z, 1.0, 0.0, O_MINUS_Z, ZERO)),
    ("disc zero normal", k.disc_hits, (ZERO, ZERO, 1.0, 0.0, O_MINUS_Z, Z)),
    ("triangle zero area", k.triangle_hits, (ZERO, Y, 2 * Y, O_MINUS_Z, Z)),
    ("triangle coincident vertices", k.triangle_hits, (ZERO, ZERO, ZERO, O_MINUS_Z, Z)),
    ("triangle parallel ray", k.triangle_hits, (ZERO, Y, Z, jnp.array([1.0, 0.0, 0.0]), Y)),
    ("triangle through a vertex", k.triangle_hits, (ZERO, jnp.array([1.0, 0, 0]), Y, O_MINUS_Z, Z)),
    ("triangle zero direction", k.triangle_hits, (ZERO, jnp.array([1.0, 0, 0]), Y, O_MINUS_Z, ZERO)),
    (
        "smooth triangle with cancelling normals",
        k.smooth_triangle_hits,
        (ZERO, jnp.array([1.0, 0, 0]), Y, Z, -Z, ZERO, jnp.array([0.5, 0.0, -5.0]), Z),
    ),
    ("smooth triangle zero area", k.smooth_triangle_hits, (ZERO, Y, 2 * Y, Z, Z, Z, O_MINUS_Z, Z)),
    (
        "polygon zero area",
        square_polygon_hits,
        (SQUARE * jnp.array([[1.0, 0, 0]]), O_MINUS_Z, Z),
    ),
    (
        "polygon parallel ray",
        square_polygon_hits,
        (SQUARE, jnp.array([0.0, 0, 1]), Y),
    ),
    (
        "polygon through a vertex",
        square_polygon_hits,
        (SQUARE, jnp.array([1.0, 1, -5]), Z),
    ),
    ("polygon zero direction", square_polygon_hits, (SQUARE, O_MINUS_Z, ZERO)),
]


def isosurface_ball_hits(radius, half, o, d):
    """A ball of ``radius`` (its distance function as an isosurface) in the box of ``half`` size."""
    from raytracer.shapes._isosurface import Isosurface

    ball = ("-", ("call", "sqrt", ("+", ("+", ("pow", ("arg", 0), 2), ("pow", ("arg", 1), 2)),
                                   ("pow", ("arg", 2), 2))), ("const", 0))
    return Isosurface(constants=radius[None], threshold=0.0, container=jnp.stack([-half, half]),
                      expression=ball).hits(o, d)


DEGENERATE += [
    ("isosurface zero direction", isosurface_ball_hits, (0.8, 0.6 * jnp.ones(3), O_MINUS_Z, ZERO)),
    ("isosurface tangent to the ball", isosurface_ball_hits,
     (0.5, jnp.ones(3), jnp.array([0.5, 0.0, -5.0]), Z)),
    ("isosurface along a wall of its box", isosurface_ball_hits,
     (0.8, 0.6 * jnp.ones(3), jnp.array([0.6, 0.0, -5.0]), Z)),
    ("isosurface from the ball's centre", isosurface_ball_hits, (0.8, jnp.ones(3), ZERO, Z)),
    ("isosurface zero radius", isosurface_ball_hits, (0.0, jnp.ones(3), O_MINUS_Z, Z)),
    ("isosurface zero box", isosurface_ball_hits, (0.8, jnp.zeros(3), O_MINUS_Z, Z)),
]


def blob_hits(radius, strength, o, d):
    """A blob of a sphere (``radius``, ``strength``) at the origin and a cylinder along y."""
    from raytracer.shapes import Blob

    ends = jnp.stack([jnp.zeros((2, 3)), jnp.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])])
    return Blob(strength=jnp.stack([strength, jnp.ones_like(strength)]),
                radius=jnp.stack([radius, 0.5 * jnp.ones_like(radius)]), ends=ends,
                placement=jnp.broadcast_to(jnp.eye(4)[:3], (2, 3, 4)), threshold=0.5,
                cylinders=True).hits(o, d)


DEGENERATE += [
    ("blob zero direction", blob_hits, (1.0, 2.0, O_MINUS_Z, ZERO)),
    ("blob along the cylinder's axis", blob_hits, (1.0, 2.0, 5 * Y, -Y)),
    ("blob across the cylinder's axis", blob_hits, (1.0, 2.0, jnp.array([0.0, 0.5, -5.0]), Z)),
    ("blob tangent to the sphere", blob_hits,
     (1.0, 0.5 / (1 - 0.64) ** 2, jnp.array([0.8, 0.0, -5.0]), Z)),
    ("blob from the centre", blob_hits, (1.0, 2.0, ZERO, Z)),
    ("blob zero radius", blob_hits, (0.0, 2.0, O_MINUS_Z, Z)),
    ("blob zero strength", blob_hits, (1.0, 0.0, O_MINUS_Z, Z)),
]


def _degenerate_groups():
    """The degenerate cases grouped by kernel, so each kernel compiles once per dtype (vmapped)."""
    groups: dict = {}
    for name, kernel, args in DEGENERATE:
        groups.setdefault(id(kernel), (kernel, []))[1].append((name, args))
    return list(groups.values())


DEGENERATE_GROUPS = _degenerate_groups()


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64], ids=["float32", "float64"])
@pytest.mark.parametrize(
    ("kernel", "cases"), DEGENERATE_GROUPS, ids=[cases[0][0].split(" ")[0] for _, cases in DEGENERATE_GROUPS]
)
def test_degenerate_inputs_give_finite_values_and_gradients(kernel, cases, dtype):
    with jax.enable_x64(dtype == jnp.float64):
        names = [name for name, _ in cases]
        stacked = tuple(
            jnp.stack([jnp.asarray(args[i], dtype) for _, args in cases]) for i in range(len(cases[0][1]))
        )

        def loss(*args):
            t, n = kernel(*args)
            weights = jnp.arange(1.0, 4.0, dtype=dtype)[None, :]
            return jnp.sum(jnp.where(jnp.isfinite(t), t, 0.0)) + jnp.sum(n * weights), (t, n)

        value_and_grads = jax.value_and_grad(loss, argnums=tuple(range(len(stacked))), has_aux=True)
        (_, (t, n)), grads = jax.jit(jax.vmap(value_and_grads))(*stacked)
        for j, name in enumerate(names):
            assert not np.any(np.isnan(np.asarray(t[j]))), name
            assert np.all(np.isfinite(np.asarray(n[j]))), name
            np.testing.assert_allclose(
                np.linalg.norm(np.asarray(n[j]), axis=-1), 1.0, rtol=1e-5, err_msg=name
            )
            for i, g in enumerate(grads):
                assert np.all(np.isfinite(np.asarray(g[j]))), (name, i, g[j])
