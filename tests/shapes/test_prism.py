"""The prism: POV-Ray's splines as Bernstein segments, crossings against a box and by hand, the fill
and its sides, bounds, the SDL, and its test cases (a quadratic-spline frame, a conic pyramid)
with implicit functions of their own (numpy's polynomial roots, float64)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shapes import Prism
from raytracer.shapes._prism import prism_from_segments, segment_senses, spline_segments

from ._case import Case, assert_refined_crossing_is_the_kernels


def _bernstein(c, s):
    b = list(c)
    while len(b) > 1:
        b = [b[i] + s * (b[i + 1] - b[i]) for i in range(len(b) - 1)]
    return b[0]


# ---------------------------------------------------------------- an implicit function of an outline
def _power(c):
    """numpy.polynomial coefficients (lowest first) of a Bernstein segment's x and z."""
    n = len(c) - 1
    from math import comb

    out = np.zeros((n + 1, 2))
    for k_ in range(n + 1):  # B_k = C(n,k) s^k (1-s)^(n-k), expanded
        for j in range(n - k_ + 1):
            out[k_ + j] += comb(n, k_) * comb(n - k_, j) * (-1) ** j * c[k_]
    return out


def outline_distance(segments, x, z):
    """Signed distance of (x, z) to the outline (negative where filled, even-odd): the nearest
    point of each segment by the roots of the derivative of the squared distance, the fill by the
    crossings of a half-line towards +x (numpy's roots, float64)."""
    best, crossings = np.inf, 0
    for c in segments:
        p = _power(np.asarray(c, np.float64))
        px = np.polynomial.Polynomial(p[:, 0]) - x
        pz = np.polynomial.Polynomial(p[:, 1]) - z
        d2 = px * px + pz * pz
        cands = [0.0, 1.0] + [r.real for r in d2.deriv().roots() if abs(r.imag) < 1e-9 and 0 < r.real < 1]
        best = min(best, min(np.sqrt(max(d2(s), 0.0)) for s in cands))
        for r in pz.roots():
            if abs(r.imag) < 1e-9 and 0 <= r.real < 1 and px(r.real) > 0:
                crossings += 1
    return -best if crossings % 2 else best


# A frame: a quadratic-spline square with rounded sides and a hole of the same kind.
FRAME_POINTS = [(1, -1), (0, 0), (2, 0), (2, 2), (0, 2), (0, 0), (0.7, 0.3), (0.4, 0.4), (1.6, 0.4),
                (1.6, 1.6), (0.4, 1.6), (0.4, 0.4)]


def _frame_case():
    segments = spline_segments("quadratic_spline", np.array(FRAME_POINTS, float) - 1.0)
    shape = prism_from_segments(segments, -0.4, 0.6)
    sense = np.asarray(shape.sense)

    def distance(p):
        return max(abs(p[1] - 0.1) - 0.5, outline_distance(segments, p[0], p[2]))

    def make(c, h1, h2):
        return Prism(controls=c, sense=sense, height1=h1, height2=h2)

    return Case("prism quadratic frame", make,
                (np.asarray(shape.controls, np.float64), np.float64(-0.4), np.float64(0.6)), distance,
                np.array([0.0, 0.1, 0.0]), 1.3, convex=False)


def _pyramid_case():
    # conic_sweep: the square outline scaled by the height, between 0.5 and 1.5
    segments = spline_segments("linear_spline", [(1, 1), (-1, 1), (-1, -1), (1, -1), (1, 1)])
    shape = prism_from_segments(segments, 0.5, 1.5, conic=True)
    sense = np.asarray(shape.sense)

    def distance(p):
        section = outline_distance(segments, p[0] / p[1], p[2] / p[1])
        return max(abs(p[1] - 1.0) - 0.5, p[1] * section)

    def make(c, h1, h2):
        return Prism(controls=c, sense=sense, height1=h1, height2=h2, conic=True)

    return Case("prism conic", make,
                (np.asarray(shape.controls, np.float64), np.float64(0.5), np.float64(1.5)), distance,
                np.array([0.0, 1.0, 0.0]), 1.2)


CASES = [_frame_case(), _pyramid_case()]


# ---------------------------------------------------------------- closed forms
def test_pov_splines_become_their_bernstein_segments():
    """Linear: the points (the last outline closed); quadratic: the parabola through each point's
    neighbours (value and slope by hand); cubic: Catmull–Rom; Bézier: four points a segment."""
    lin = spline_segments("linear_spline", [(0, 0), (1, 0), (1, 1), (0, 0), (2, 2), (3, 2), (3, 3)])
    assert lin.shape == (6, 2, 2)  # 3 closed by repetition, 3 closed automatically
    np.testing.assert_array_equal(lin[-1], [[3, 3], [2, 2]])
    # quadratic: the segment (1,0) -> (1,1) after (0,0): P(s) = P1 + (P2 - P0) s/2 + (P2 - 2P1 + P0) s²/2
    quad = spline_segments("quadratic_spline", [(0, -1), (0, 0), (1, 0), (1, 1), (0, 1), (0, 0)])
    assert quad.shape == (4, 3, 2)
    for s in (0.0, 0.3, 1.0):
        p0, p1, p2 = np.array([0.0, 0]), np.array([1.0, 0]), np.array([1.0, 1])
        expected = p1 + (p2 - p0) * s / 2 + (p2 - 2 * p1 + p0) * s * s / 2
        np.testing.assert_allclose(_bernstein(quad[1], s), expected)
    # cubic: the segment P1 -> P2 has tangents (P2 - P0)/2 and (P3 - P1)/2
    pts = np.array([(0, -1), (0, 0), (2, 0), (2, 2), (0, 2), (0, 0), (2, 0)], float)
    cub = spline_segments("cubic_spline", pts)
    assert cub.shape == (4, 4, 2)
    h = 1e-6
    slope0 = (_bernstein(cub[0], h) - _bernstein(cub[0], 0.0)) / h
    slope1 = (_bernstein(cub[0], 1.0) - _bernstein(cub[0], 1 - h)) / h
    np.testing.assert_allclose(slope0, (pts[2] - pts[0]) / 2, atol=1e-4)
    np.testing.assert_allclose(slope1, (pts[3] - pts[1]) / 2, atol=1e-4)
    bez = spline_segments("bezier_spline", [(0, 0), (1, 1), (2, 1), (3, 0), (3, 0), (2, -1), (1, -1), (0, 0)])
    np.testing.assert_array_equal(bez[1], [[3, 0], [2, -1], [1, -1], [0, 0]])


def test_a_square_prism_crosses_lines_where_its_box_does():
    """A linear square from (0,0) to (1,1), heights −0.5 … 0.5: every crossing and outward normal
    of 200 random lines is the box's (worked by the slab method)."""
    segments = spline_segments("linear_spline", [(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)])
    shape = prism_from_segments(segments, 0.5, -0.5)
    rng = np.random.default_rng(0)
    o = rng.normal(size=(200, 3)) * 3
    d = rng.normal(size=(200, 3))
    t, n = jax.jit(jax.vmap(shape.hits))(jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    t, n = np.asarray(t, np.float64), np.asarray(n, np.float64)
    lo, hi = np.array([0.0, -0.5, 0.0]), np.array([1.0, 0.5, 1.0])
    for i in range(len(o)):
        with np.errstate(divide="ignore", invalid="ignore"):
            a, b = (lo - o[i]) / d[i], (hi - o[i]) / d[i]
        near, far = np.nanmax(np.minimum(a, b)), np.nanmin(np.maximum(a, b))
        found = np.sort(t[i][np.isfinite(t[i])])
        expected = [near, far] if near <= far else []
        np.testing.assert_allclose(found, expected, rtol=1e-5, atol=1e-5)
        for slot in np.nonzero(np.isfinite(t[i]))[0]:
            p = o[i] + t[i, slot] * d[i]
            axis = np.argmin(np.minimum(np.abs(p - lo), np.abs(p - hi)))
            expect = np.zeros(3)
            expect[axis] = 1.0 if abs(p[axis] - hi[axis]) < abs(p[axis] - lo[axis]) else -1.0
            np.testing.assert_allclose(n[i, slot], expect, atol=1e-5)


def test_a_line_through_a_joint_crosses_once_and_holes_are_empty():
    """The half-open rule at joints: a line along z = 0 through the frame's corner joints crosses
    each wall once; a point in the hole or between two nested outlines' overlap is not filled."""
    segments = spline_segments("linear_spline", [(0, 0), (2, 0), (2, 2), (0, 2), (0, 0),
                                                 (0.5, 0.5), (1.5, 0.5), (1.5, 1.5), (0.5, 1.5), (0.5, 0.5)])
    shape = prism_from_segments(segments, 0.0, 1.0)
    # along x at z = 0 (the bottom wall itself is hit edge-on: no crossing of the walls x = 0, 2)
    t, _ = jax.jit(shape.hits)(jnp.array([-1.0, 0.5, 0.5]), jnp.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(np.sort(np.asarray(t)[np.isfinite(t)]), [1.0, 1.5, 2.5, 3.0], atol=1e-6)
    inside = jax.jit(jax.vmap(shape.inside))
    pts = jnp.array([[0.25, 0.5, 1.0], [1.0, 0.5, 1.0], [1.0, 1.5, 1.0], [1.0, 0.5, 2.5]])
    np.testing.assert_array_equal(np.asarray(inside(pts)), [True, False, False, False])


def test_fill_sides_follow_the_even_odd_rule_whatever_the_winding():
    outer = [(0, 0), (2, 0), (2, 2), (0, 2), (0, 0)]
    hole = [(0.5, 0.5), (0.5, 1.5), (1.5, 1.5), (1.5, 0.5), (0.5, 0.5)]  # wound the other way
    for pts in (outer + hole, outer[::-1] + hole, outer + hole[::-1]):
        segs = spline_segments("linear_spline", pts)
        sense = segment_senses(segs)
        for c, s in zip(segs, sense, strict=True):
            mid, tangent = c.mean(0), c[1] - c[0]
            left = np.array([-tangent[1], tangent[0]])
            inward = np.array([1.0, 1.0]) - mid  # the centre (1, 1) is in the hole
            in_hole_side = np.dot(left, inward) > 0
            is_hole_edge = np.all((c > 0.4) & (c < 1.6))
            # the fill lies towards the centre on the outer square, away from it on the hole's
            assert s == (1 if in_hole_side != is_hole_edge else -1)


def test_padding_makes_outlines_of_similar_size_one_variant():
    a = prism_from_segments(spline_segments("linear_spline", [(0, 0), (1, 0), (0, 1)]), 0, 1)
    b = prism_from_segments(spline_segments("linear_spline", [(0, 0), (1, 0), (1, 1), (0, 1)]), 0, 1)
    assert a.controls.shape == b.controls.shape == (4, 2, 2)
    assert list(np.asarray(a.sense)) == [1, 1, 1, 0] or list(np.asarray(a.sense)) == [-1, -1, -1, 0]
    lo, hi = a.bounds()
    np.testing.assert_allclose(lo, [0, 0, 0])
    np.testing.assert_allclose(hi, [1, 1, 1])


def test_a_cubic_prisms_crossings_have_the_implicit_functions_derivatives(x64):
    """The bisected roots of a Bézier outline carry the implicit function theorem's
    derivatives: d t / d(controls) against central differences (float64)."""
    points = [(0, 0), (1, -1), (2, 1), (2, 2), (2, 2), (1, 3), (-1, 1), (0, 0)]
    segs = spline_segments("bezier_spline", points)
    shape = prism_from_segments(segs, 0.0, 1.0)
    o, d = jnp.array([-2.0, 0.5, 0.7]), jnp.array([1.0, 0.05, 0.1])

    def first(c):
        t, _ = Prism(controls=c, sense=shape.sense, height1=0.0, height2=1.0).hits(o, d)
        return jnp.min(t)

    c0 = jnp.asarray(shape.controls)
    g = np.asarray(jax.jit(jax.grad(first))(c0))
    rng = np.random.default_rng(1)
    f = jax.jit(first)
    for _ in range(3):
        v = rng.normal(size=c0.shape) * (np.asarray(shape.sense) != 0)[:, None, None]
        h = 1e-6
        fd = (float(f(c0 + h * v)) - float(f(c0 - h * v))) / (2 * h)
        np.testing.assert_allclose(np.sum(g * v), fd, rtol=1e-6, atol=1e-9)


# ---------------------------------------------------------------- the SDL
def test_the_sdl_reads_every_spline_and_sweep_and_refuses_too_few_points(tmp_path):
    from raytracer.sdl import SceneError, load_scene

    head = "camera { location <0, 5, -5> look_at 0 } light_source { <0, 9, -9> rgb 1 }\n"
    body = ("prism { linear_spline 0, 1, 4, <0,0>, <1,0>, <0,1>, <0,0> }\n"
            "prism { conic_sweep quadratic_spline 0.5, 1, 6,\n"
            "  <1,-1>, <0,0>, <2,0>, <2,2>, <0,2>, <0,0> open }\n"
            "prism { bezier_spline 0, 1, 4, <0,0>, <1,1>, <2,1>, <0,0> }\n"
            "prism { cubic_spline 0, 1, 7, <0,-1>, <0,0>, <2,0>, <2,2>, <0,2>, <0,0>, <2,0> sturm }\n")
    path = tmp_path / "p.pov"
    path.write_text(head + body)
    scene = load_scene(path)
    shapes = [o.shape for o in scene.objects]
    assert [type(s).__name__ for s in shapes] == ["Prism"] * 4
    assert [s.conic for s in shapes] == [False, True, False, False]
    assert [s.open for s in shapes] == [False, True, False, False]
    assert [s.controls.shape[1] for s in shapes] == [2, 3, 4, 4]
    path.write_text(head + "prism { quadratic_spline 0, 1, 2, <0,0>, <1,0> }\n")
    with pytest.raises(SceneError, match=r"p\.pov:2:\d+: expected at least 4 points"):
        load_scene(path)


def test_an_open_prism_has_no_caps_and_no_inside():
    segs = spline_segments("linear_spline", [(0, 0), (1, 0), (0, 1)])
    open_prism = prism_from_segments(segs, 0, 1, open_=True)
    t, _ = jax.jit(open_prism.hits)(jnp.array([0.2, 3.0, 0.2]), jnp.array([0.0, -1.0, 0.0]))
    assert not np.isfinite(np.asarray(t)).any()  # straight down through the open caps
    assert not bool(jax.jit(open_prism.inside)(jnp.array([0.2, 0.5, 0.2])))
    # the hierarchy's refinement never answers with a cap it does not have (t0 on the top plane)
    t, n = jax.jit(open_prism.near_hit)(jnp.array([0.2, 3.0, 0.2]), jnp.array([0.0, -1.0, 0.0]), 2.0)
    assert not (np.isclose(float(t[0]), 2.0) and abs(float(n[0, 1])) == 1.0)


def test_the_hierarchys_crossing_refined_is_the_kernels_with_its_derivatives(x64):
    """``near_hit`` (the native hierarchy's crossing t0, its segment found among the nearest
    boxes) gives the first crossing the whole kernel finds, its normal and its derivatives along
    the controls, for lines through walls and caps of a frame with a hole (float64)."""
    segments = spline_segments("quadratic_spline", np.array(FRAME_POINTS, float) - 1.0)
    shape = prism_from_segments(segments, -0.4, 0.6)
    rng = np.random.default_rng(3)
    o = rng.normal(size=(64, 3)) * 2.5
    d = rng.uniform(-1, 1, size=(64, 3)) * 0.3 - o / 2.5
    assert_refined_crossing_is_the_kernels(
        lambda c: Prism(controls=c, sense=shape.sense, height1=-0.4, height2=0.6), shape.controls, o, d)
