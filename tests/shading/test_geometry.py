"""Scene-level geometry against POV-Ray: which of two coincident surfaces a ray sees."""

from __future__ import annotations

import numpy as np
import pytest

_HEAD = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -6> look_at 0 right x*4/3 }
light_source { <2, 4, -5> rgb 1 }
background { rgb <0.1, 0.2, 0.3> }
#declare R = pigment { rgb <1, 0.2, 0.1> };
#declare G = pigment { rgb <0.1, 1, 0.2> };
"""

# Four columns, each a red box and, later in the file, a green surface on its front face (z = -1):
# equal boxes (the first shows); a difference whose bounding box starts at z = -3 (it shows); a
# union of a box and a sphere at z = -3, bounded part by part (the first shows); a polygon, whose
# box POV-Ray grows by ~1e-3 (it shows; at 160×120 POV-Ray lets ~1 % of its pixels show the box,
# where its float64 box and polygon kernels differ by an ulp)
BOUNDED = _HEAD + """
box { <-3.2, -1, -1>, <-1.8, 1, 1> pigment { R } }
box { <-3.2, -1, -1>, <-1.8, 1, 1> pigment { G } }
box { <-1.5, -1, -1>, <-0.1, 1, 1> pigment { R } }
difference { box { <-1.5, -1, -3>, <-0.1, 1, 1> } box { <-5, -5, -5>, <5, 5, -1> } pigment { G } }
box { <0.2, -1, -1>, <1.6, 1, 1> pigment { R } }
union { box { <0.2, -1, -1>, <1.6, 1, 1> } sphere { <0.9, 2, -3>, 0.1 } pigment { G } }
box { <1.9, -1, -1>, <3.2, 1, 1> pigment { R } }
polygon { 4, <1.9, -1, -1>, <3.2, -1, -1>, <3.2, 1, -1>, <1.9, 1, -1> pigment { G } }
"""

# an unbounded plane shows over the box face it touches, although the box comes first
PLANE = _HEAD + """
box { <-2, -1, -1>, <2, 1, 1> rotate 30*z pigment { R } }
plane { z, -1 pigment { G } }
"""


@pytest.mark.povray
@pytest.mark.parametrize("text", [BOUNDED, PLANE], ids=["bounded-objects", "plane"])
def test_coincident_surfaces_show_the_one_povray_tests_first(tmp_path, text):
    # measured with povray 3.7 (semantics §4.4): an exact tie goes to the object
    # whose bounding box the ray enters first, else to the earlier one in the file
    import raytracer as rt
    from validation import metrics
    from validation.povray import render_povray

    path = tmp_path / "coincident.pov"
    path.write_text(text)
    ours = np.asarray(rt.render(rt.load_scene(path), width=32, height=24))
    # measured 86 dB (bounded objects) and 84 dB (plane); 17 and 15 dB before
    assert metrics.psnr(ours, render_povray(path, 32, 24)) >= 40.0


def test_an_intersection_is_bounded_by_its_parts_that_are_not_inverted():
    """POV-Ray's box of ``intersection { A B { inverse } }`` (the idiom for A minus B) is A's: an
    inverted part bounds nothing. Were it the overlap of both boxes, the object's box would not hold
    it, and the hierarchy, which culls by the box, would cut the ring below out of the image."""
    import jax.numpy as jnp

    import raytracer as rt
    from raytracer._plan import make_plan
    from raytracer.shading._geometry import csg_units, pack_geometry, prim_bits, unit_boxes

    scene = rt.load_scene(_HEAD + """
intersection { box { <-1, -0.1, -1>, <1, 0.1, 1> } box { -0.7, 0.7 inverse } pigment { R } }
intersection { sphere { 0, 0.5 } sphere { <0.3, 0, 0>, 0.4 inverse } pigment { R } translate 3 * x }
difference { box { -1, 1 } sphere { 0, 1.5 } pigment { G } translate -3 * x }
intersection { box { -1, 1 } sphere { 0, 0.5 } inverse pigment { G } translate 3 * y }
merge { sphere { 0, 0.5 } sphere { <1, 0, 0>, 0.5 inverse } pigment { G } translate -3 * y }
intersection { plane { y, 0 } plane { x, 0 inverse } pigment { G } }
""")
    plan = make_plan(scene)
    geo = pack_geometry(plan, jnp.float64, accelerate=False)
    lo, hi = unit_boxes(plan, geo, [np.linalg.inv(np.asarray(m)) for m in geo.object_from_world])
    np.testing.assert_allclose(lo[:5], [[-1, -0.1, -1], [2.5, -0.5, -0.5], [-4, -1, -1], [-0.5, 2.5, -0.5],
                                        [-0.5, -3.5, -0.5]], atol=1e-12)
    np.testing.assert_allclose(hi[:5], [[1, 0.1, 1], [3.5, 0.5, 0.5], [-2, 1, 1], [0.5, 3.5, 0.5],
                                        [1.5, -2.5, 0.5]], atol=1e-12)
    assert np.isinf(lo[5]).all() and np.isinf(hi[5]).all()  # a plane, and an inverted one: unbounded
    # the hierarchy holds the five bounded ones (the inverted intersection too: its surface is the
    # intersection's, inside its box), not the unbounded one
    assert csg_units(plan, prim_bits(plan)) == (0, 1, 2, 3, 4)


def test_bounded_by_bounds_an_object_without_a_box_of_its_own(monkeypatch):
    """An intersection of planes (shapes2.inc's tetrahedron) has no box; its ``bounded_by``
    sphere's box becomes its box, so the native hierarchy holds it (tested for the rays that enter
    the box, as POV-Ray tests it for those that meet the sphere) with the image of the unbounded
    one, tested by every ray. An object with a box of its own keeps it: the hint is ignored."""
    import jax.numpy as jnp

    import raytracer as rt
    from raytracer._plan import make_plan
    from raytracer.shading import _accel
    from raytracer.shading._geometry import csg_units, pack_geometry, prim_bits, unit_boxes

    tetra = """intersection { plane { -y, 1 } plane { -z, 1 rotate <19.47, 0, 0> }
        plane { -z, 1 rotate <19.47, -120, 0> } plane { -z, 1 rotate <19.47, 120, 0> } %s
        pigment { G } rotate <20, 30, 0> translate <-1, 0, 1> }"""
    text = _HEAD + tetra + "\nsphere { <2, 0, 0>, 0.5 %s pigment { R } }\n"
    bounded = rt.load_scene(text % ("bounded_by { sphere { 0, 3 } }", "bounded_by { box { -9, 9 } }"))
    plain = rt.load_scene(text % ("", ""))
    plan = make_plan(bounded)
    # the tetrahedron's four planes and its bound (not rendered); the sphere, whose box is its own
    assert [p.kind for p in plan.prims] == ["plane"] * 4 + ["sphere"] * 2
    assert [p.rendered for p in plan.prims] == [True] * 4 + [False, True]
    geo = pack_geometry(plan, jnp.float64, accelerate=False)
    lo, hi = unit_boxes(plan, geo, [np.linalg.inv(np.asarray(m)) for m in geo.object_from_world])
    # the sphere's box, turned and moved with the tetrahedron: its corners' hull
    corners = np.array([[(-3, 3)[(k >> a) & 1] for a in range(3)] for k in range(8)], float)
    m = np.asarray(rt.load_scene(_HEAD + "box { -3, 3 rotate <20, 30, 0> translate <-1, 0, 1> }")
                   .objects[0].transform.matrix)
    world = corners @ m[:3, :3].T + m[:3, 3]
    np.testing.assert_allclose(lo[0], world.min(0), atol=1e-9)
    np.testing.assert_allclose(hi[0], world.max(0), atol=1e-9)
    np.testing.assert_allclose(lo[1], [1.5, -0.5, -0.5], atol=1e-9)  # the sphere's own box
    assert csg_units(plan, prim_bits(plan)) == (0,) and csg_units(make_plan(plain), prim_bits(plan)) == ()
    monkeypatch.setattr(_accel, "MIN_ITEMS", 1)
    images = [np.asarray(rt.render(s, width=48, height=36)) for s in (bounded, plain)]
    assert (images[0] != images[0][0, 0]).any(axis=-1).mean() > 0.05  # the tetrahedron and the sphere
    np.testing.assert_allclose(images[0], images[1], atol=1e-5)


@pytest.mark.parametrize("held", [False, True], ids=["candidate", "hierarchy"])
def test_bounded_by_shows_an_unbounded_object_to_the_rays_that_cross_its_bound(held, monkeypatch):
    """POV-Ray's ``bounded_by`` on an object without a box: a ray that crosses the bound sees all of
    the object, also where it lies outside the bound, and a ray that does not sees none of it
    (neither a clip nor a box). An orthographic camera looks along +z at a white wall (z = 3) through
    a red plane z = 0 bounded by a sphere of radius 1.2 at z = -3: the plane is seen exactly where
    the camera's ray crosses the sphere, x² + y² < 1.2², though the plane lies 3 from the sphere.
    Made invisible to the camera (``no_image``), the same plane shades the wall from a light at
    z = -10 where the shadow ray crosses the sphere: inside the cone from the light tangent to it.
    Both as a candidate of every ray and as a CSG object of the native hierarchy (its box the
    sphere's; bvh.cc's bounds' node)."""
    import jax.numpy as jnp

    import raytracer as rt
    from raytracer._plan import make_plan
    from raytracer.shading import _accel
    from raytracer.shading._geometry import pack_geometry

    if held:
        if _accel.unavailable_reason() is not None:
            pytest.skip(str(_accel.unavailable_reason()))
        monkeypatch.setenv("RAYTRACER_ACCEL", "native")
        monkeypatch.setattr(_accel, "MIN_ITEMS", 1)
    else:
        monkeypatch.setenv("RAYTRACER_ACCEL", "none")

    head = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -5> look_at <0, 0, 0> right 8*x up 6*y }
light_source { <0, 0, -10> color rgb 1 }
plane { z, 3 pigment { rgb 1 } finish { ambient 0 diffuse 1 } }
"""
    bounded = "plane { z, 0 %s bounded_by { sphere { <0, 0, -3>, 1.2 } } pigment { rgb <1, 0, 0> } " \
              "finish { ambient 1 diffuse 0 } }\n"
    w, h = 32, 24
    x = (np.arange(w) + 0.5) / w * 8 - 4
    y = 3 - (np.arange(h) + 0.5) / h * 6
    r = np.hypot(*np.meshgrid(x, y))  # (h, w) distance from the axis
    edge = 0.25 * np.sqrt(2)  # a pixel's diagonal: pixels this close to a circle are not asked about

    scene = rt.load_scene(head + bounded % "")
    geo = pack_geometry(make_plan(scene), jnp.float32)
    assert [g.kind for g in geo.groups if g.accelerated] == (["plane", "sphere"] if held else [])
    seen = np.asarray(rt.render(scene, width=w, height=h))
    red = (seen[..., 0] > 0.5) & (seen[..., 1] < 0.1)
    inside, outside = r < 1.2 - edge, r > 1.2 + edge
    assert inside.sum() > 20 and red[inside].all() and not red[outside].any()

    lit = np.asarray(rt.render(rt.load_scene(head + bounded % "no_image"), width=w, height=h))[..., 1]
    shadow = 13 * 1.2 / np.sqrt(7**2 - 1.2**2)  # the tangent cone's radius on the wall
    inside, outside = r < shadow - edge, r > shadow + edge
    assert inside.sum() > 50 and (lit[inside] < 1e-6).all() and (lit[outside] > 0.05).all()


@pytest.mark.parametrize("obj, band", [
    # transforms before clipped_by do not move the clipping plane: the box [-2, 2]³ is cut at y = 0.5
    ("box { -1, 1 rotate 90*x scale 2 clipped_by { plane { y, 0.5 } } }", (-2.0, 0.5)),
    # transforms after it do, also for a sphere that folds its transform into its centre and radius
    ("sphere { 0, 1 clipped_by { plane { y, 0.5 } } translate <0, 1, 0> }", (0.0, 1.5)),
])
def test_clipping_objects_move_with_the_transforms_given_after_them(obj, band):
    """POV-Ray moves a ``clipped_by`` (and ``bounded_by``) object with the transforms its object is
    given after it only (measured with POV-Ray 3.7). An orthographic view along +z of a white
    object: it covers exactly the rows of the band of heights ``band``."""
    import raytracer as rt

    text = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -10> look_at 0 right 8*x up 8*y }
light_source { <0, 0, -20> color rgb 1 }
""" + obj[:-1] + "pigment { rgb 1 } finish { ambient 1 diffuse 0 } }\n"
    image = np.asarray(rt.render(rt.load_scene(text), width=40, height=40))[..., 0]
    y = 4 - (np.arange(40) + 0.5) / 5  # the rows' heights
    seen = (image > 0.5).any(axis=1)
    lo, hi = band
    np.testing.assert_array_equal(seen[(y > lo + 0.2) & (y < hi - 0.2)], True)
    np.testing.assert_array_equal(seen[(y < lo - 0.2) | (y > hi + 0.2)], False)
