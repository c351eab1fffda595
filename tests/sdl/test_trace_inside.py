"""trace() and inside() at parse time, against closed forms (values povray 3.7 prints agree)."""

import numpy as np
import pytest

from raytracer.errors import SceneError

from .conftest import run_sdl


def vec(p, name):
    return np.asarray(p.lookup(name).c[:3])


def test_trace_returns_the_nearest_hit_and_its_normal():
    # a sphere of radius 2 centred at x = 1: the ray x = 1, y = 0 along +z enters at z = -2
    p = run_sdl("""#declare S = sphere { 0, 1 scale 2 translate x }
        #declare N = <9, 9, 9>;
        #declare P = trace(S, <1, 0, -10>, <0, 0, 3>, N);
        #declare Q = trace(S, <1, 1, -10>, z);""")
    np.testing.assert_allclose(vec(p, "P"), [1, 0, -2], atol=1e-5)
    np.testing.assert_allclose(vec(p, "N"), [0, 0, -1], atol=1e-5)
    np.testing.assert_allclose(vec(p, "Q"), [1, 1, -np.sqrt(3)], atol=1e-5)


def test_a_miss_returns_zero_and_resets_the_normal():
    p = run_sdl("""#declare S = sphere { 0, 1 }
        #declare N = <9, 9, 9>;
        #declare P = trace(S, <5, 5, -10>, z, N);
        #declare B = trace(S, <0, 0, -10>, -z, N);""")
    assert vec(p, "P").tolist() == [0, 0, 0] and vec(p, "N").tolist() == [0, 0, 0]
    assert vec(p, "B").tolist() == [0, 0, 0]  # behind the start: no hit


def test_trace_sees_csg_and_the_cavity_of_a_difference_faces_inwards():
    p = run_sdl("""#declare D = difference { box { -1, 1 } sphere { 0, 0.5 } }
        #declare N1 = 0; #declare N2 = 0;
        #declare A = trace(D, <0, 0, -5>, z, N1);
        #declare B = trace(D, <0, 0, -0.75>, z, N2);
        #declare C = trace(D, <0, 0.9, -5>, z);""")
    np.testing.assert_allclose(vec(p, "A"), [0, 0, -1], atol=1e-5)
    np.testing.assert_allclose(vec(p, "N1"), [0, 0, -1], atol=1e-5)
    # from inside the solid into the cavity: the cavity wall's normal points into the cavity
    np.testing.assert_allclose(vec(p, "B"), [0, 0, -0.5], atol=1e-5)
    np.testing.assert_allclose(vec(p, "N2"), [0, 0, 1], atol=1e-5)
    np.testing.assert_allclose(vec(p, "C"), [0, 0.9, -1], atol=1e-5)


def test_trace_through_a_union_of_several_bounding_units():
    # a union is split into its members for POV-Ray's tie rule (semantics §4.4); trace() must see
    # every member (a fuzz case crashed here: the units' boxes were indexed by a traced value)
    p = run_sdl("""#declare U = union { sphere { 0, 1 } sphere { <0, 0, -3>, 0.5 } box { -1, <1, 1, 3> } }
        #declare N = 0;
        #declare A = trace(U, <0, 0, -10>, z, N);
        #declare B = trace(U, <0, 0.9, -10>, z);""")
    np.testing.assert_allclose(vec(p, "A"), [0, 0, -3.5], atol=1e-5)
    np.testing.assert_allclose(vec(p, "N"), [0, 0, -1], atol=1e-5)
    np.testing.assert_allclose(vec(p, "B"), [0, 0.9, -1], atol=1e-5)  # the box's face


@pytest.mark.parametrize("obj, point, expected", [
    ("difference { box { -1, 1 } sphere { 0, 0.5 } }", "<0.8, 0, 0>", 1.0),
    ("difference { box { -1, 1 } sphere { 0, 0.5 } }", "<0.1, 0, 0>", 0.0),
    ("difference { box { -1, 1 } sphere { 0, 0.5 } }", "<2, 0, 0>", 0.0),
    ("union { sphere { 0, 1 } sphere { 3*x, 1 } translate y }", "<3, 1.5, 0>", 1.0),
    ("intersection { sphere { 0, 1 } sphere { x, 1 } }", "<0.5, 0, 0>", 1.0),
    ("intersection { sphere { 0, 1 } sphere { x, 1 } }", "<-0.5, 0, 0>", 0.0),
    ("sphere { 0, 1 inverse }", "<0, 0, 0>", 0.0),
    ("sphere { 0, 1 clipped_by { plane { y, 0 } } }", "<0, 0.5, 0>", 0.0),
    ("sphere { 0, 1 clipped_by { plane { y, 0 } } }", "<0, -0.5, 0>", 1.0),
    ("box { 0, 1 scale 2 rotate 45*z }", "<0, 1.5, 0.5>", 1.0),
    ("box { 0, 1 scale 2 rotate 45*z }", "<1.5, 0, 0.5>", 0.0),
    ("triangle { 0, x, y }", "<0.1, 0.1, 0>", 0.0),  # no inside
])
def test_inside(obj, point, expected):
    p = run_sdl(f"#declare O = {obj}\n#declare R = inside(O, {point});")
    assert p.lookup("R") == expected


def test_trace_needs_an_object_identifier():
    with pytest.raises(SceneError, match="expected an object identifier in trace"):
        run_sdl("#declare P = trace(1, 0, z);")


def test_trace_and_inside_say_at_the_call_that_they_cannot_see_an_unrendered_part():
    """The answer of a call that cannot see a part already shaped the scene (``#if``s, placements),
    so it is said at once, once per call site, even inside a value that is never used; the part's
    own warning comes where the object is placed."""
    from raytracer.sdl import load_scene

    s = load_scene("""#declare Land = union { ovus { 1, 0.5 } sphere { 0, 1 } }
        #declare I = 0;
        #while (I < 3)
          #declare P = trace(Land, <0, 5, 0>, -y);
          #declare Q = inside(Land, <0, 0, 0>);
          #declare I = I + 1;
        #end
        object { Land }""")
    found = [(w.feature, w.location.line, w.location.col) for w in s.warnings]
    assert found == [("ovus", 4, 24), ("ovus", 5, 24), ("ovus", 1, 25)]
    assert "trace() cannot see the ovus" in s.warnings[0].message
    s = load_scene("#declare S = sphere { 0, 1 } #declare P = trace(S, <0, 5, 0>, -y);")
    assert s.warnings == ()


def test_min_and_max_extent_are_the_boxes_povray_prints():
    """The corners povray 3.7 prints for these objects (``#debug vstr(min_extent(…))``): a rotated
    sphere's own box, a difference's first child's, an intersection's common part, the text's
    glyph box, ±1e10 for anything unbounded."""
    p = run_sdl("""#declare S = sphere { <1,2,3>, 0.5 scale 2 rotate 30*y }
        #declare D = difference { box { -1, 1 } sphere { 0, 1.2 } translate x }
        #declare I = intersection { box { -1, 1 } sphere { <1,0,0>, 1.2 } }
        #declare U = union { sphere { 0, 1 } plane { y, 0 } }
        #declare T = text { ttf "timrom.ttf" "AV" 0.3, 0 }
        #declare S0 = min_extent(S); #declare S1 = max_extent(S);
        #declare D0 = min_extent(D); #declare D1 = max_extent(D);
        #declare I0 = min_extent(I); #declare I1 = max_extent(I);
        #declare U0 = min_extent(U); #declare U1 = max_extent(U);
        #declare T0 = min_extent(T); #declare T1 = max_extent(T);""")
    povray = {"S": ([3.732051, 3.0, 3.196152], [5.732051, 5.0, 5.196153]),
              "D": ([0, -1, -1], [2, 1, 1]), "I": ([-0.2, -1, -1], [1, 1, 1]),
              "U": ([-1e10] * 3, [1e10] * 3),
              # povray pads a text's box by ~1e-5: -0.000012,-0.016005,-0.000024 / 1.278005,0.696022,0.300013
              "T": ([0, -0.016, 0], [1.278, 0.696, 0.3])}
    for name, (lo, hi) in povray.items():
        np.testing.assert_allclose(vec(p, f"{name}0"), lo, atol=3e-5, err_msg=name)
        np.testing.assert_allclose(vec(p, f"{name}1"), hi, atol=3e-5, err_msg=name)
