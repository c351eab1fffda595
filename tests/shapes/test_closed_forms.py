"""Hand-derived crossings for axis-aligned rays: every expected number below is worked out in a comment."""

import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shapes import Triangle

from ._case import jitted_kernels as k

O_MINUS_Z = jnp.array([0.0, 0.0, -5.0])
PLUS_Z = jnp.array([0.0, 0.0, 1.0])
X, Y, Z = jnp.eye(3)


def sorted_finite(t):
    t = np.asarray(t)
    return np.sort(t[np.isfinite(t)])


def test_sphere_unit_ray_from_minus_five_hits_at_four_and_six():
    # |(0,0,-5+t)| = 1  ->  t = 5 -+ 1, normals -z then +z.
    t, n = k.sphere_hits(jnp.zeros(3), 1.0, O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t, [4.0, 6.0], rtol=1e-6)
    np.testing.assert_allclose(n, [-Z, Z], atol=1e-6)


def test_sphere_long_direction_scales_t():
    # d = 2 ez: the same points are reached at half the parameter.
    t, _ = k.sphere_hits(jnp.zeros(3), 1.0, O_MINUS_Z, 2.0 * PLUS_Z)
    np.testing.assert_allclose(t, [2.0, 3.0], rtol=1e-6)


def test_sphere_reports_crossings_behind_the_origin():
    # From the centre: t = -1 and +1.
    t, _ = k.sphere_hits(jnp.zeros(3), 1.0, jnp.zeros(3), PLUS_Z)
    np.testing.assert_allclose(t, [-1.0, 1.0], rtol=1e-6)


def test_sphere_miss_is_inf_with_unit_normals():
    t, n = k.sphere_hits(jnp.zeros(3), 1.0, jnp.array([0.0, 2.0, -5.0]), PLUS_Z)
    assert np.all(np.isinf(t))
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, rtol=1e-6)


def test_plane_normal_is_normalised_before_the_distance():
    # plane{<0,0,2>, 1} is z = 1 (POV normalises N): from z = -5, t = 6.
    t, n = k.plane_hits(jnp.array([0.0, 0.0, 2.0]), 1.0, O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t, [6.0], rtol=1e-6)
    np.testing.assert_allclose(n, [Z], atol=1e-6)


def test_plane_parallel_ray_misses():
    t, _ = k.plane_hits(Y, 0.0, jnp.array([0.0, 1.0, 0.0]), X)
    assert np.isinf(t[0])


def test_box_with_unsorted_corners_enters_and_exits_z_faces():
    # Box [-1,1]^3 from z = -5: enter z = -1 (t = 4, normal -z), leave z = 1 (t = 6, normal +z).
    t, n = k.box_hits(jnp.ones(3), -jnp.ones(3), O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t, [4.0, 6.0], rtol=1e-6)
    np.testing.assert_allclose(n, [-Z, Z], atol=1e-6)


def test_box_diagonal_ray_enters_through_x_face():
    # Box [0,1]x[0,2]x[0,3], ray (-1, 0.5, 0.5) + t (1, 0.1, 0): x-slab [1, 2], y-slab [-5, 15] -> [1, 2].
    t, n = k.box_hits(
        jnp.zeros(3), jnp.array([1.0, 2.0, 3.0]), jnp.array([-1.0, 0.5, 0.5]), jnp.array([1.0, 0.1, 0.0])
    )
    np.testing.assert_allclose(t, [1.0, 2.0], rtol=1e-6)
    np.testing.assert_allclose(n, [-X, X], atol=1e-6)


def test_box_parallel_ray_outside_slab_misses():
    t, _ = k.box_hits(-jnp.ones(3), jnp.ones(3), jnp.array([0.0, 1.5, -5.0]), PLUS_Z)
    assert np.all(np.isinf(t))


def test_cylinder_across_its_side():
    # Cylinder along y, r = 1; ray along z through the axis: side at z = -1, 1 -> t = 4, 6.
    t, n = k.cylinder_hits(-Y, Y, 1.0, O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(sorted_finite(t), [4.0, 6.0], rtol=1e-6)
    np.testing.assert_allclose(n[:2], [-Z, Z], atol=1e-6)


def test_cylinder_along_its_axis_hits_both_caps():
    # Cylinder along z from -1 to 1: only the caps, base (z=-1, normal -z) at t=4, cap (z=1, +z) at t=6.
    t, n = k.cylinder_hits(-Z, Z, 1.0, O_MINUS_Z, PLUS_Z)
    assert np.all(np.isinf(t[:2]))
    np.testing.assert_allclose(t[2:], [4.0, 6.0], rtol=1e-6)
    np.testing.assert_allclose(n[2:], [-Z, Z], atol=1e-6)


def test_open_cylinder_has_no_caps():
    t, _ = k.cylinder_hits(-Z, Z, 1.0, O_MINUS_Z, PLUS_Z, open=True)
    assert np.all(np.isinf(t))


def test_cone_side_halfway_up():
    # Cone from y=-1 (r=1) to y=1 (apex): at y=0 the radius is 1/2 -> z = -+1/2, t = 4.5, 5.5.
    # The side rises 2 per 1 inwards, so the outward normal is (0, 1, 2)/sqrt(5) mirrored in z.
    t, n = k.cone_hits(-Y, 1.0, Y, 0.0, O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t[:2], [4.5, 5.5], rtol=1e-6)
    s5 = np.sqrt(5.0)
    np.testing.assert_allclose(n[:2], [[0, 1 / s5, -2 / s5], [0, 1 / s5, 2 / s5]], atol=1e-6)


def test_cone_along_axis_hits_base_disc_and_apex():
    # Cone along z, base z=-1 r=1, apex z=1: base cap at t=4; the apex point (t=6) is a double root.
    t, n = k.cone_hits(-Z, 1.0, Z, 0.0, O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t[2], 4.0, rtol=1e-6)
    np.testing.assert_allclose(n[2], -Z, atol=1e-6)
    assert np.isinf(t[3])  # no disc at a zero radius
    assert np.all(np.isfinite(np.asarray(n)))


def test_quadric_unit_sphere_matches_sphere():
    t, n = k.quadric_hits(jnp.array([1.0, 1, 1, 0, 0, 0, 0, 0, 0, -1]), O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t, [4.0, 6.0], rtol=1e-6)
    np.testing.assert_allclose(n, [-Z, Z], atol=1e-6)


def test_quadric_paraboloid_along_axis_is_linear():
    # y = x² + z² (A = C = 1, H = -1): the ray (0,-5... along +y from y=-5 on the axis: one root at y=0, t=5.
    t, n = k.quadric_hits(jnp.array([1.0, 0, 1, 0, 0, 0, 0, -1, 0, 0]), -5.0 * Y, Y)
    np.testing.assert_allclose(sorted_finite(t), [5.0], rtol=1e-6)
    np.testing.assert_allclose(n[0], -Y, atol=1e-6)  # gradient (2x, -1, 2z) at the vertex


def test_disc_with_hole():
    # Disc r=1, hole 0.5 in the z=0 plane: the centre ray passes through the hole, x = 0.7 hits at t = 5.
    t, _ = k.disc_hits(jnp.zeros(3), Z, 1.0, 0.5, O_MINUS_Z, PLUS_Z)
    assert np.isinf(t[0])
    t, n = k.disc_hits(jnp.zeros(3), Z, 1.0, 0.5, jnp.array([0.7, 0.0, -5.0]), PLUS_Z)
    np.testing.assert_allclose(t, [5.0], rtol=1e-6)
    np.testing.assert_allclose(n, [Z], atol=1e-6)


def test_triangle_hit_and_normal_from_winding():
    # Counter-clockwise seen from +z: (p2 - p1) x (p3 - p1) = +z.
    p1, p2, p3 = jnp.array([-1.0, -1, 0]), jnp.array([1.0, -1, 0]), jnp.array([0.0, 1, 0])
    t, n = k.triangle_hits(p1, p2, p3, O_MINUS_Z, PLUS_Z)
    np.testing.assert_allclose(t, [5.0], rtol=1e-6)
    np.testing.assert_allclose(n, [Z], atol=1e-6)
    t, _ = k.triangle_hits(p1, p2, p3, jnp.array([0.9, 0.9, -5.0]), PLUS_Z)
    assert np.isinf(t[0])


def test_smooth_triangle_normal_is_barycentric_blend():
    # Hit at (0.25, 0.25, 0) of the triangle (0,0,0), (1,0,0), (0,1,0): weights (0.5, 0.25, 0.25).
    p1, p2, p3 = jnp.zeros(3), X, Y
    n1, n2, n3 = Z, X, Y
    t, n = k.smooth_triangle_hits(p1, p2, p3, n1, n2, n3, jnp.array([0.25, 0.25, -1.0]), PLUS_Z)
    np.testing.assert_allclose(t, [1.0], rtol=1e-6)
    expected = np.array([0.25, 0.25, 0.5]) / np.linalg.norm([0.25, 0.25, 0.5])
    np.testing.assert_allclose(n[0], expected, atol=1e-6)


@pytest.mark.parametrize(
    ("inside", "args", "point", "expected"),
    [
        (k.sphere_inside, (jnp.zeros(3), 1.0), [0.0, 0.0, 0.5], True),
        (k.sphere_inside, (jnp.zeros(3), 1.0), [0.0, 0.0, 1.0], False),
        (k.plane_inside, (2.0 * Y, 1.0), [0.0, 0.5, 0.0], True),
        (k.plane_inside, (2.0 * Y, 1.0), [0.0, 1.5, 0.0], False),
        (k.box_inside, (jnp.ones(3), -jnp.ones(3)), [0.9, -0.9, 0.0], True),
        (k.box_inside, (jnp.ones(3), -jnp.ones(3)), [1.1, 0.0, 0.0], False),
        (k.cylinder_inside, (-Y, Y, 1.0), [0.5, 0.9, 0.5], True),
        (k.cylinder_inside, (-Y, Y, 1.0), [0.5, 1.1, 0.5], False),
        (k.cone_inside, (-Y, 1.0, Y, 0.0), [0.0, 0.0, 0.4], True),
        (k.cone_inside, (-Y, 1.0, Y, 0.0), [0.0, 0.0, 0.6], False),
        (k.quadric_inside, (jnp.array([1.0, 1, 1, 0, 0, 0, 0, 0, 0, -1]),), [0.5, 0.5, 0.5], True),
        (k.disc_inside, (jnp.zeros(3), Z, 1.0, 0.0), [5.0, 5.0, -0.1], True),
        (k.disc_inside, (jnp.zeros(3), Z, 1.0, 0.0), [0.0, 0.0, 0.1], False),
        (lambda *a: Triangle(*a[:3]).inside(a[3]), (jnp.zeros(3), X, Y), [0.1, 0.1, 0.0], False),
    ],
)
def test_inside_follows_pov_semantics(inside, args, point, expected):
    assert bool(inside(*args, jnp.array(point))) == expected
