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
    # issue 13 item 5, measured with povray 3.7 (semantics §4.4): an exact tie goes to the object
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
