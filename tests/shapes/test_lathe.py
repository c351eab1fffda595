"""The lathe: POV-Ray's splines as Bernstein segments of a curve (r, y), crossings against a tube
worked by hand (two cylinders and two planes), lines along the axis and across it, the SDL, and
its test cases (a tube, a rounded ring) with an implicit function of their own: the distance of the
meridian point (√(x² + z²), y) to the curve (numpy's polynomial roots, float64)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shapes import Lathe
from raytracer.shapes._lathe import MAX_CROSSINGS, lathe_from_segments, lathe_segments

from ._case import Case, assert_refined_crossing_is_the_kernels
from .test_prism import outline_distance

TUBE = [(1.0, 0.0), (1.5, 0.0), (1.5, 2.0), (1.0, 2.0), (1.0, 0.0)]  # r 1 to 1.5, y 0 to 2
# a closed ring of four Bézier arcs around (1.5, 0.5), radius about 0.5: a rounded torus
RING = [(2.0, 0.5), (2.0, 0.78), (1.78, 1.0), (1.5, 1.0), (1.5, 1.0), (1.22, 1.0), (1.0, 0.78), (1.0, 0.5),
        (1.0, 0.5), (1.0, 0.22), (1.22, 0.0), (1.5, 0.0), (1.5, 0.0), (1.78, 0.0), (2.0, 0.22), (2.0, 0.5)]


def _case(name, spline, points, aim, size):
    segments = lathe_segments(spline, points)
    shape = lathe_from_segments(segments)
    sense = np.asarray(shape.sense)

    def distance(p):
        return outline_distance(segments, np.hypot(p[0], p[2]), p[1])

    def make(c):
        return Lathe(controls=c, sense=sense)

    return Case(name, make, (np.asarray(shape.controls, np.float64),), distance, np.asarray(aim, float), size,
                convex=False)


CASES = [_case("lathe linear tube", "linear_spline", TUBE, (0.0, 1.0, 0.0), 1.6),
         _case("lathe bezier ring", "bezier_spline", RING, (0.0, 0.5, 0.0), 2.0)]


def test_pov_splines_become_their_segments():
    """Linear: N − 1 segments; quadratic: N − 2 (the first point sets the slope); cubic: N − 3;
    Bézier: N / 4 (manual 3.4.5.1.8); the curve is not closed for the lathe."""
    pts = [(0, 0), (1, 0), (1.2, 1), (0.5, 2), (0.8, 2.5), (0, 3)]
    assert lathe_segments("linear_spline", pts).shape == (5, 2, 2)
    quad = lathe_segments("quadratic_spline", pts)
    assert quad.shape == (4, 3, 2)
    # the segment (1, 0) -> (1.2, 1) after (0, 0): the prism's rule, P1 + (P2 − P0)/4 in the middle
    np.testing.assert_allclose(quad[0], [(1, 0), (1 + 1.2 / 4, 0.25), (1.2, 1)])
    assert lathe_segments("cubic_spline", pts).shape == (3, 4, 2)
    assert lathe_segments("bezier_spline", RING).shape == (4, 4, 2)


def test_a_tube_crosses_lines_where_its_cylinders_and_planes_do():
    """The linear tube (r from 1 to 1.5, y from 0 to 2): the crossings of 300 random lines are
    those of the solid between the two cylinders and the two planes, worked in closed form."""
    shape = lathe_from_segments(lathe_segments("linear_spline", TUBE))
    rng = np.random.default_rng(0)
    o = rng.normal(size=(300, 3)) * 3
    d = rng.normal(size=(300, 3))
    t, _ = jax.jit(jax.vmap(shape.hits))(jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    t = np.asarray(t, np.float64)
    for i in range(len(o)):
        expected = _tube_crossings(o[i], d[i])
        found = np.sort(t[i][np.isfinite(t[i])])
        np.testing.assert_allclose(found, expected, rtol=2e-4, atol=2e-4)


def _tube_crossings(o, d):
    """Where the line enters or leaves {1 ≤ ρ ≤ 1.5, 0 ≤ y ≤ 2}: the candidates of each surface,
    kept where the points beside them differ in being inside."""
    cands = []
    a, b, c = d[0] ** 2 + d[2] ** 2, o[0] * d[0] + o[2] * d[2], o[0] ** 2 + o[2] ** 2
    for r in (1.0, 1.5):
        disc = b * b - a * (c - r * r)
        if a > 0 and disc > 0:
            cands += [(-b - np.sqrt(disc)) / a, (-b + np.sqrt(disc)) / a]
    if d[1] != 0:
        cands += [(0.0 - o[1]) / d[1], (2.0 - o[1]) / d[1]]

    def inside(t):
        p = o + t * d
        rho = np.hypot(p[0], p[2])
        return 1.0 <= rho <= 1.5 and 0.0 <= p[1] <= 2.0

    h = 1e-7 * (1 + np.abs(np.array(cands)).max()) if cands else 0
    return sorted(t for t in cands if inside(t - h) != inside(t + h))


def test_lines_along_and_across_the_axis():
    """A line down the axis meets the ring's holes' floor nowhere and a line down beside it the
    ring twice; a horizontal line through the tube's middle meets its four walls."""
    tube = lathe_from_segments(lathe_segments("linear_spline", TUBE))
    lines = jax.jit(jax.vmap(tube.hits))(jnp.array([[-3.0, 1.0, 0.0], [0.0, 5.0, 0.0], [1.25, 5.0, 0.0]]),
                                         jnp.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, -1.0, 0.0]]))
    t, n = (x[0] for x in lines)
    hit = np.isfinite(np.asarray(t))
    np.testing.assert_allclose(np.sort(np.asarray(t)[hit]), [1.5, 2.0, 4.0, 4.5], atol=1e-5)
    # outward: away from the tube's wall solid (−x at x = −1.5, +x at x = −1, …)
    by_t = dict(zip(np.asarray(t)[hit].round(4), np.asarray(n)[hit, 0].round(4), strict=True))
    assert by_t == {1.5: -1.0, 2.0: 1.0, 4.0: -1.0, 4.5: 1.0}
    t = lines[0][1]  # down the axis: the hole
    assert not np.isfinite(np.asarray(t)).any()
    t, n = (x[2] for x in lines)  # down inside the wall
    hit = np.isfinite(np.asarray(t))
    np.testing.assert_allclose(np.sort(np.asarray(t)[hit]), [3.0, 5.0], atol=1e-5)
    np.testing.assert_allclose(np.asarray(n)[hit][np.argsort(np.asarray(t)[hit])], [(0, 1, 0), (0, -1, 0)],
                               atol=1e-5)


def test_the_inside_is_the_meridian_fill_and_the_crossings_are_few():
    ring = lathe_from_segments(lathe_segments("bezier_spline", RING))
    inside = jax.jit(jax.vmap(ring.inside))(jnp.array([[1.5, 0.5, 0.0], [0.0, 0.5, -1.5], [0.0, 0.5, 0.0],
                                              [2.5, 0.5, 0.0], [1.5, 1.2, 0.0]]))
    np.testing.assert_array_equal(np.asarray(inside), [True, True, False, False, False])
    assert ring.n_crossings() == min(2 * 3 * ring.controls.shape[0], MAX_CROSSINGS)


def test_the_sdl_reads_every_spline_and_refuses_too_few_points(tmp_path):
    from raytracer.sdl import SceneError, load_scene

    head = "camera { location <0, 5, -5> look_at 0 } light_source { <0, 9, -9> rgb 1 }\n"
    body = ("lathe { 5, <1, 0>, <1.5, 0>, <1.5, 2>, <1, 2>, <1, 0> }\n"
            "lathe { quadratic_spline 4, <0, 0>, <1, 0>, <1, 1>, <0, 2> }\n"
            "lathe { cubic_spline 5, <0, 0>, <1, 0>, <1, 1>, <0.5, 2>, <0, 3> sturm }\n"
            "lathe { bezier_spline 4, <0, 0>, <1, 0>, <1, 1>, <0, 1> }\n")
    path = tmp_path / "l.pov"
    path.write_text(head + body)
    scene = load_scene(path)
    assert scene.warnings == ()
    shapes = [o.shape for o in scene.objects]
    assert [type(s).__name__ for s in shapes] == ["Lathe"] * 4
    assert [s.controls.shape[1] for s in shapes] == [2, 3, 4, 4]
    assert [int(np.count_nonzero(np.asarray(s.sense))) for s in shapes] == [4, 2, 2, 1]
    path.write_text(head + "lathe { bezier_spline 6,\n <0,0>, <1,0>, <1,1>, <0,1>, <0,2>, <1,2> }\n")
    with pytest.raises(SceneError, match=r"l\.pov:2:\d+: expected at least 4 points for a bezier_spline"):
        load_scene(path)


def test_the_hierarchys_crossing_refined_is_the_kernels_with_its_derivatives(x64):
    """``near_hit`` (the native hierarchy's crossing t0, its curve parameter the point's nearest on
    the nearest segments) gives the first crossing the whole kernel finds, its normal and its
    derivatives along the controls, for lines through the ring (float64)."""
    shape = lathe_from_segments(lathe_segments("bezier_spline", RING))
    rng = np.random.default_rng(3)
    o = rng.normal(size=(64, 3)) * 3.0
    d = rng.uniform(-1, 1, size=(64, 3)) * 0.5 - o / 3.0
    assert_refined_crossing_is_the_kernels(lambda c: Lathe(controls=c, sense=shape.sense), shape.controls,
                                           o, d)
