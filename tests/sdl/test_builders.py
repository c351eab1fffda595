"""Builders and lowering: what each construct becomes in the scene model."""

from pathlib import Path

import jax
import numpy as np
import pytest

from raytracer import scene as S
from raytracer.sdl import SceneError, load_scene

SEED = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "seed.pov"


def same_pytree(a, b) -> bool:
    la, ta = jax.tree_util.tree_flatten(a)
    lb, tb = jax.tree_util.tree_flatten(b)
    return ta == tb and all(np.allclose(x, y) for x, y in zip(la, lb, strict=True))


def only_object(text):
    s = load_scene(text)
    assert len(s.objects) == 1
    return s.objects[0]


def rgbft(obj):
    return np.asarray(obj.texture.layers[0].pigment.colors[0])


def test_seed_scene_objects():
    s = load_scene(SEED)
    sphere, box = s.objects
    assert isinstance(sphere.shape, S.Sphere) and float(sphere.shape.radius) == 2.0
    np.testing.assert_allclose(rgbft(sphere), [1, 0, 0, 0, 0])
    fin = sphere.texture.layers[0].finish
    assert (float(fin.ambient[0]), float(fin.diffuse), float(fin.phong)) == pytest.approx((0.2, 0.8, 1))
    assert box.texture.layers[0].finish.phong is None
    np.testing.assert_allclose(box.shape.corner1, [-2, -0.2, -2])
    # rotate <-20, 30, 0>: Ry(30) @ Rx(-20) (semantics §4.3)
    a, b = np.radians(-20), np.radians(30)
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    np.testing.assert_allclose(box.transform.matrix[:3, :3], ry @ rx, atol=1e-6)
    assert not box.texture.layers[0].pigment.transparent
    (light,) = s.lights
    np.testing.assert_allclose(light.position, [-10, 3, -20])
    np.testing.assert_allclose(light.color, [1, 1, 1])
    np.testing.assert_allclose(s.camera.location, [0, 0, -8])
    np.testing.assert_allclose(s.camera.look_at, [0, 0, 0])
    # no #version and no assumed_gamma: POV-Ray 3.7 turns gamma handling off (its parse warning
    # says so) and writes sRGB⁻¹(value) to EXR
    assert s.settings.output_transfer == "srgb_decode"


@pytest.mark.parametrize("a, b", [
    ("sphere { <0,0,0>, 1 pigment { color red 1 } }", "sphere { 0 1 pigment { rgb x } }"),
    ("sphere { 0, 1 rotate <10, 20, 30> }", "sphere { 0, 1 rotate 10*x rotate 20*y rotate 30*z }"),
    ("box { 0, 1 translate <1,2,3> scale 2 }",
     "box { 0, 1 transform { translate <1,2,3> scale 2 } }"),
    ("#declare T = transform { scale 2 translate x }\nbox { 0, 1 transform T }",
     "box { 0, 1 scale 2 translate x }"),
    ("box { 0, 1 transform { translate x inverse } }", "box { 0, 1 translate -x }"),
    ("#declare B = box { 0, 1 }\nobject { B pigment { rgb 1 } }", "box { 0, 1 pigment { rgb 1 } }"),
    ("sphere { 0, 1 matrix <1,0,0, 0,1,0, 0,0,1, 1,2,3> }", "sphere { 0, 1 translate <1,2,3> }"),
    ("sphere { 0, 1 finish { phong 0.5 } }", "sphere { 0, 1 texture { finish { phong 0.5 } } }"),
    ("plane { <0, 2, 0>, 1 }", "plane { y, 1 }"),
    ("sphere { 0, 1 pigment { checker } }",
     "sphere { 0, 1 pigment { checker color blue 1, color green 1 } }"),
])
def test_two_spellings_give_equal_pytrees(a, b):
    assert same_pytree(load_scene(a), load_scene(b))


def test_camera_records_modifiers_and_transform():
    s = load_scene("camera { orthographic location <0,1,-5> look_at 0 angle 40 up y right 2*x "
                   "sky <0,1,1> rotate 90*y }")
    c = s.camera
    assert c.projection == "orthographic" and c.up_or_right_given
    assert float(c.angle_degrees) == 40.0
    np.testing.assert_allclose(c.right, [2, 0, 0])
    np.testing.assert_allclose(c.sky, [0, 1, 1])
    np.testing.assert_allclose(np.asarray(c.transform.matrix)[:3, :3] @ np.array([1, 0, 0]), [0, 0, -1],
                               atol=1e-6)


def test_textures_before_a_transform_move_with_the_object():
    before = only_object("sphere { 0, 1 pigment { checker } scale 2 }")
    after = only_object("sphere { 0, 1 scale 2 pigment { checker } }")
    np.testing.assert_allclose(np.diag(before.texture.layers[0].pigment.transform.matrix), [2, 2, 2, 1])
    assert after.texture.layers[0].pigment.transform is None


def test_csg_children_keep_their_textures_and_pigment_only_child_gets_default_finish():
    u = only_object("""difference {
        box { -1, 1 pigment { rgb <1,0,0> } }
        sphere { 0, 1.2 }
        pigment { rgb <0,0,1> } finish { ambient 1 } }""")
    box, sphere = u.children
    np.testing.assert_allclose(rgbft(box), [1, 0, 0, 0, 0])
    assert float(box.texture.layers[0].finish.ambient[0]) == pytest.approx(0.1)
    assert sphere.texture is None
    assert float(u.texture.layers[0].finish.ambient[0]) == 1.0


def test_csg_transform_moves_child_pattern_textures():
    u = only_object("union { sphere { 0, 1 pigment { checker } } scale 3 }")
    (child,) = u.children
    assert child.transform is None
    np.testing.assert_allclose(np.diag(child.texture.layers[0].pigment.transform.matrix), [3, 3, 3, 1])
    np.testing.assert_allclose(np.diag(u.transform.matrix), [3, 3, 3, 1])


def test_a_texture_map_of_bare_entries_is_approximated_by_its_first_entry():
    """``texture_map { [0.05, pigment {…} finish {…}] … }`` (advanced/grenadine/lemon.inc's peel):
    the entries' items are textures, as POV-Ray reads them; the approximation takes the first (it
    took the default black texture)."""
    o = only_object("sphere { 0, 1 texture { cylindrical texture_map {\n"
                    " [0.05, pigment { rgb <1, 0.8, 0> } finish { phong 0.8 } ]\n"
                    " [0.06, pigment { rgb <1, 0.9, 0.7> } ] } } }")
    np.testing.assert_allclose(rgbft(o), [1, 0.8, 0, 0, 0])
    assert float(o.texture.layers[0].finish.phong) == pytest.approx(0.8)


def test_object_without_texture_gets_the_default():
    o = only_object("sphere { 0, 1 }")
    np.testing.assert_allclose(rgbft(o), [0, 0, 0, 0, 0])
    assert float(o.texture.layers[0].finish.diffuse) == pytest.approx(0.6)


@pytest.mark.parametrize("pigment, transparent", [
    ("rgb 1", False), ("rgbf <1,1,1,0>", True), ("color 0.5", True), ("color red 1 filter 0", True),
    ("rgbt 0.2", True),
])
def test_pigment_transparency_follows_the_colour_expression(pigment, transparent):
    o = only_object(f"sphere {{ 0, 1 pigment {{ {pigment} }} }}")
    assert o.texture.layers[0].pigment.transparent is transparent


@pytest.mark.parametrize("pigment", [
    "rgbf <1,1,1,0>", "color red 1 filter 0", "rgbt <0.2, 0.3, 0.4, 0>",
    "gradient x color_map { [0 rgbf <1,0,0,0>] [1 rgbft <0,0,1,0,0>] }",
])
def test_a_filter_written_as_zero_is_transparent_only_where_it_is_to_be_fitted(pigment):
    """``fit_zero_terms`` (default True): a written 0 filter or transmit makes the pigment
    transparent, so it can be fitted; False (the command line's): only a value that is not 0 does,
    as POV-Ray renders it. A non-zero value is transparent either way."""
    text = f"sphere {{ 0, 1 pigment {{ {pigment} }} }}"
    assert load_scene(text).objects[0].texture.layers[0].pigment.transparent
    assert not load_scene(text, fit_zero_terms=False).objects[0].texture.layers[0].pigment.transparent
    clear = text.replace("0>", "0.5>").replace("filter 0", "filter 0.5")
    assert load_scene(clear, fit_zero_terms=False).objects[0].texture.layers[0].pigment.transparent


def test_finish_keywords():
    f = only_object("""sphere { 0, 1 finish { ambient rgb <0.1,0.2,0.3> emission 0.5 diffuse 0.7
        brilliance 2 phong 0 phong_size 20 specular 0.3 roughness 0.01 metallic
        reflection { 0.1, 0.9 fresnel falloff 2 exponent 0.5 metallic 0.3 } conserve_energy } }"""
                    ).texture.layers[0].finish
    np.testing.assert_allclose(f.ambient, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(f.emission, [0.5, 0.5, 0.5])
    assert float(f.phong) == 0.0 and float(f.phong_size) == 20
    assert float(f.metallic) == 1.0 and f.conserve_energy
    r = f.reflection
    np.testing.assert_allclose(r.min, [0.1] * 3)
    np.testing.assert_allclose(r.max, [0.9] * 3)
    assert r.fresnel and float(r.falloff) == 2 and float(r.exponent) == 0.5


def reflection_of(finish):
    return only_object(f"sphere {{ 0, 1 finish {{ {finish} }} }}").texture.layers[0].finish.reflection


# (min, max, fresnel) as POV-Ray 3.7.0.10 renders them on a sphere with ior 1.5 that only reflects a
# white background: 0.8·0.04 = 0.032 facing the camera for `{ 0.8 fresnel on }`, 0.2 + 0.6·0.04 for
# two colours with fresnel, a constant 0.8 for the forms without it (semantics §2.6)
@pytest.mark.parametrize("finish, rmin, rmax, fresnel", [
    ("reflection { 0.8 fresnel on }", 0.0, 0.8, True),  # one colour with fresnel: the maximum, min 0
    ("reflection { 0.8, fresnel }", 0.0, 0.8, True),
    ("reflection { 0.8 fresnel on fresnel off }", 0.0, 0.8, False),  # (1 - cos)·0.8 at the rim
    ("reflection { 0.8 fresnel off }", 0.8, 0.8, False),
    ("reflection { 0.8 }", 0.8, 0.8, False),
    ("reflection { 0.2, 0.8 fresnel on }", 0.2, 0.8, True),
    ("reflection 0.8", 0.8, 0.8, False),
    ("reflection { 0.2, 0.8 } reflection { fresnel on }", 0.0, 0.0, True),  # a block's colours are its own
    ("reflection { 0.2, 0.8 fresnel on } reflection { 0.2, 0.8 }", 0.2, 0.8, True),  # fresnel carries over
    ("reflection { 0.2, 0.8 fresnel on } reflection 0.5", 0.5, 0.5, False),  # the old form turns it off
    ("reflection { fresnel on } reflection { 0.8 }", 0.8, 0.8, True),  # one colour, no fresnel keyword
])
def test_reflection_colours_and_fresnel_follow_povray(finish, rmin, rmax, fresnel):
    r = reflection_of(finish)
    np.testing.assert_allclose(r.min, [rmin] * 3)
    np.testing.assert_allclose(r.max, [rmax] * 3)
    assert r.fresnel is fresnel


def test_legacy_reflection_colour_is_both_minimum_and_maximum():
    r = reflection_of("reflection rgb <0.8, 0.5, 0.2>")
    np.testing.assert_allclose(r.min, [0.8, 0.5, 0.2])
    np.testing.assert_allclose(r.max, [0.8, 0.5, 0.2])


def test_reflection_falloff_exponent_and_metallic_carry_over_to_later_statements():
    # POV-Ray 3.7.0.10: `reflection { 0.2, 0.8 falloff 3 } reflection { 0.2, 0.8 }` renders as the first
    r = reflection_of("reflection { 0.2, 0.8 falloff 3 exponent 2 metallic 0.5 } reflection 0.4")
    assert (float(r.falloff), float(r.exponent), float(r.metallic)) == (3.0, 2.0, 0.5)


def test_reflection_metallic_is_absent_unless_given_and_zero_stays_a_parameter():
    assert reflection_of("reflection { 0.8 }").metallic is None
    assert float(reflection_of("reflection { 0.8 metallic }").metallic) == 1.0
    assert float(reflection_of("reflection { 0.8 metallic 0 }").metallic) == 0.0


def test_interior_and_legacy_finish_ior():
    o = only_object("sphere { 0, 1 interior { ior 1.5 fade_distance 2 fade_power 1 fade_color rgb x } }")
    assert float(o.interior.ior) == 1.5
    np.testing.assert_allclose(o.interior.fade_color, [1, 0, 0])
    legacy = only_object("sphere { 0, 1 finish { refraction 1 ior 1.33 } }")
    assert float(legacy.interior.ior) == pytest.approx(1.33)


def test_lights():
    s = load_scene("""light_source { <0,10,0> rgb 2 spotlight point_at 0 radius 10 falloff 20
                                     tightness 5 fade_distance 3 fade_power 2 }
        light_source { 0, 1 parallel shadowless translate y*5 }
        light_source { 0, 1 area_light x, z, 3, 4 circular orient translate x }""")
    spot, par, area = s.lights
    np.testing.assert_allclose(spot.color, [2, 2, 2])
    assert float(spot.spot.radius_degrees) == 10 and float(spot.spot.tightness) == 5
    assert float(spot.fade_power) == 2
    assert par.parallel and par.shadowless
    np.testing.assert_allclose(par.position, [0, 5, 0])
    np.testing.assert_allclose(par.point_at, [0, 5, 1])
    assert (area.area.size1, area.area.size2, area.area.circular) == (3, 4, True)
    np.testing.assert_allclose(area.position, [1, 0, 0])


def test_light_inside_a_union_moves_with_it():
    s = load_scene("union { sphere { 0, 1 } light_source { <1,0,0> rgb 1 } translate y }")
    np.testing.assert_allclose(s.lights[0].position, [1, 1, 0])


def test_shapes():
    s = load_scene("""cylinder { 0, y, 1 open } cone { 0, 1, y, 0.5 } torus { 2, 0.5 }
        disc { 0, y, 2, 1 } quadric { <1,1,1>, <0,0,0>, <0,0,0>, -1 }
        polygon { 4, <0,0>, <1,0>, <1,1>, <0,0> } triangle { 0, x, y }
        smooth_triangle { 0, z, x, z, y, z }
        mesh { triangle { 0, x, y } triangle { 0, y, z } }
        mesh2 { vertex_vectors { 3, 0, x, y } face_indices { 1, <0, 1, 2> } }""")
    kinds = [type(o.shape).__name__ for o in s.objects]
    assert kinds == ["Cylinder", "Cone", "Torus", "Disc", "Quadric", "Polygon", "Triangle",
                     "SmoothTriangle", "Mesh", "Mesh"]
    assert s.objects[0].shape.open
    assert s.objects[8].shape.triangles.shape == (2, 3, 3)
    np.testing.assert_allclose(s.objects[9].shape.triangles[0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_unsupported_objects_are_parsed_and_left_out():
    s = load_scene("sor { 4, <0,0>, <1,1>, <1,2>, <0,3> } sphere { 0, 1 } "
                   "union { bicubic_patch { type 1 flatness 0.1 u_steps 2 v_steps 2 "
                   + ", ".join(["<0,0,0>"] * 16) + " } box { 0, 1 } }")
    assert [w.feature for w in s.warnings] == ["sor", "bicubic_patch"]
    assert len(s.objects) == 2 and len(s.objects[1].children) == 1


@pytest.mark.parametrize("header, transfer, gamma", [
    ("#version 3.7; global_settings { assumed_gamma 1 }", "linear", 1.0),
    ("#version 3.7;", "linear", 1.0),
    ("#version 3.6;", "srgb_decode", 1.0),
    ("#version 3.6; global_settings { assumed_gamma 2.2 }", "gamma", 2.2),
    ("", "srgb_decode", 1.0),  # no #version: gamma handling off, as povray 3.7.0.10 does
    ("global_settings { assumed_gamma 1.0 }", "linear", 1.0),
])
def test_gamma_and_version(header, transfer, gamma):
    st = load_scene(header).settings
    assert (st.output_transfer, st.assumed_gamma) == (transfer, pytest.approx(gamma))


def test_background_is_premultiplied_by_one_minus_transmit():
    np.testing.assert_allclose(load_scene("background { color 0.5 }").background, [0.25] * 3)
    np.testing.assert_allclose(load_scene("background { rgb <1, 0.5, 0> }").background, [1, 0.5, 0])


def test_global_settings():
    st = load_scene("global_settings { max_trace_level 300 adc_bailout 0.01 ambient_light rgb 2 }"
                    ).settings
    assert st.max_trace_level == 256
    assert float(st.adc_bailout) == pytest.approx(0.01)
    np.testing.assert_allclose(st.ambient_light, [2, 2, 2])


def test_pattern_pigment_fields():
    pig = only_object("""sphere { 0, 1 pigment { marble turbulence 0.5 octaves 3 omega 0.4
        lambda 3 frequency 2 phase 0.1 color_map { [0 rgb 0] [0.5 0.7 color rgb 1 color rgbt 0.5] } } }"""
                      ).texture.layers[0].pigment
    assert pig.pattern == "marble" and pig.wave == "triangle" and pig.octaves == 3
    np.testing.assert_allclose(pig.turbulence, [0.5] * 3)
    np.testing.assert_allclose(pig.values, [0, 0.5, 0.7])
    assert pig.transparent
    grad = only_object("sphere { 0, 1 pigment { gradient y sine_wave } }").texture.layers[0].pigment
    assert grad.wave == "sine"
    np.testing.assert_allclose(grad.vector, [0, 1, 0])
    np.testing.assert_allclose(grad.colors[:, :3], [[0, 0, 0], [1, 1, 1]])


def test_width_and_height_feed_image_size():
    s = load_scene("camera { right x*image_width/image_height }", width=300, height=100)
    np.testing.assert_allclose(s.camera.right, [3, 0, 0])


@pytest.mark.slow
def test_standard_include_files_load():
    s = load_scene('\n'.join(f'#include "{n}.inc"' for n in
                             ("colors", "textures", "shapes", "metals", "glass", "woods", "stones"))
                   + "\nsphere { 0, 1 texture { T_Stone1 } }")
    assert len(s.objects) == 1


def test_look_at_along_sky_keeps_the_right_vector_with_a_warning():
    s = load_scene("camera { location <0, 5, 0> look_at 0 right x }")
    _, d, r, u = s.camera.frame()
    np.testing.assert_allclose(r, [1, 0, 0], atol=1e-6)  # POV keeps the old right (semantics §1.1)
    np.testing.assert_allclose(u, [0, 0, 1], atol=1e-6)  # up = D̂ × R̂
    assert [w.feature for w in s.warnings] == ["camera sky"]


def test_checker_colours_need_no_comma():
    # valid POV: a second rgb… starts the second colour (POV-Ray renders both)
    s = load_scene("sphere { 0, 1 pigment { checker rgb <.8,.8,.75> rgb <.2,.3,.2> } }")
    np.testing.assert_allclose(s.objects[0].texture.layers[0].pigment.colors[:, :3],
                               [[0.8, 0.8, 0.75], [0.2, 0.3, 0.2]], rtol=1e-6)


def test_an_object_identifier_first_in_braces_copies_that_object():
    # povray 3.7 renders 'mesh { S }' as S (a sphere) and 'sphere { B }' as B (a box)
    s = load_scene("""#declare S = sphere { 0, 1 pigment { rgb <1,0,0> } }
        #declare B = box { -0.5, 0.5 pigment { rgb <0,1,0> } }
        mesh { S translate <-1.5,0,0> }
        sphere { B translate <1.5,0,0> }
        union { S scale 2 }""")
    a, b, c = s.objects
    assert isinstance(a.shape, S.Sphere) and isinstance(b.shape, S.Box) and isinstance(c.shape, S.Sphere)
    # a sphere's similarity transforms are folded into its centre and radius (absorb_transform)
    assert a.transform is None and c.transform is None
    np.testing.assert_allclose(a.shape.center, [-1.5, 0, 0])
    np.testing.assert_allclose(rgbft(b), [0, 1, 0, 0, 0])
    np.testing.assert_allclose(c.shape.radius, 2.0)


def test_a_spheres_similarity_transform_is_folded_into_it_and_an_ellipsoid_keeps_its_own():
    s = load_scene("sphere { <1, 0, 0>, 0.5 scale 2 rotate 90*z translate <0, 0, 1e6> }\n"
                   "sphere { <1, 0, 0>, 0.5 scale <1, 2, 1> }")
    folded, ellipsoid = s.objects
    assert folded.transform is None
    np.testing.assert_allclose(folded.shape.center, [0, 2, 1e6], atol=1e-12)
    np.testing.assert_allclose(folded.shape.radius, 1.0)
    np.testing.assert_allclose(np.asarray(ellipsoid.transform.matrix)[:3, :3], np.diag([1, 2, 1]))
    np.testing.assert_allclose(ellipsoid.shape.center, [1, 0, 0])


def test_only_modifiers_may_follow_an_object_identifier():
    with pytest.raises(SceneError) as e:  # povray: "No matching } in 'union', sphere found instead"
        load_scene("#declare S = sphere { 0, 1 }\nunion { S sphere { x, 0.5 } }")
    assert e.value.location.line == 2 and e.value.location.col == 11


def test_povray_syntax_that_loads_with_a_warning():
    """Valid POV-Ray 3.7 (it parses each) that we read and do not render yet: a mesh triangle's
    per-vertex ``texture_list`` (identifiers only, as POV-Ray) and the short form ``slope y``."""
    text = ("#declare T1 = texture { pigment { rgb 1 } } #declare T2 = texture { pigment { rgb 0 } }\n"
            "mesh { triangle { <0,0,0>, <1,0,0>, <0,1,0> texture_list { T1 T2 T1 } } }\n"
            "sphere { 0, 1 pigment { slope y } }")
    s = load_scene(text)
    assert [w.feature for w in s.warnings] == ["mesh texture", "slope"]
    with pytest.raises(SceneError, match="expected a texture identifier in texture_list, found 'texture'"):
        load_scene("mesh { triangle { 0, x, y texture_list { texture { pigment { rgb 1 } } } } }")


def test_modifiers_that_change_the_image_are_warned_where_they_are_ignored():
    """``uv_mapping`` (object, texture, pigment), ``cutaway_textures`` and a ``noise_generator``
    other than POV-Ray's default 2 change POV-Ray's image; we read them, say so at their place."""
    s = load_scene("global_settings { noise_generator 1 } global_settings { noise_generator 2 }\n"
                   "sphere { 0, 1 pigment { bozo noise_generator 3 uv_mapping } uv_mapping }\n"
                   "sphere { 0, 1 texture { uv_mapping pigment { rgb 1 } } }\n"
                   "difference { sphere { 0, 1 } box { 0, 1 } cutaway_textures }\n"
                   "sphere { 0, 1 hollow sturm uv_mapping off }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [
        ("noise_generator", 1), ("noise_generator", 2), ("uv_mapping", 2), ("uv_mapping", 2),
        ("uv_mapping", 3), ("cutaway_textures", 4)]
