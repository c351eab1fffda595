"""Whole-renderer tests against closed forms of POV-Ray's lighting model (semantics §2).

Each scene is built so that one pixel's radiance can be written down by hand: a 1×1 image's
only ray goes exactly along the camera direction, so hit points, normals and light directions
are known exactly.
"""

import os

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt

S = 1 / np.sqrt(2)


def one_pixel(scene, **kw):
    return np.asarray(rt.render(scene, width=1, height=1, **kw))[0, 0]


def sphere_scene(finish, pigment=(0.8, 0.4, 0.2), lights=None, extra=(), **kw):
    """Unit sphere at the origin, camera at z = -5 looking at it: the centre ray hits (0,0,-1)."""
    lights = lights if lights is not None else (
        rt.Light(position=(0.0, 10 * S, -10 * S), point_at=(0, 0, 0), parallel=True),)
    return rt.Scene(
        camera=rt.Camera(location=(0, 0, -5), look_at=(0, 0, 0)),
        objects=(rt.Object(rt.Sphere((0, 0, 0), 1.0),
                           texture=rt.Texture.of(rt.Pigment.solid(pigment), finish)),) + tuple(extra),
        lights=lights, **kw)


def test_ambient_and_diffuse_with_brilliance_match_the_closed_form():
    # N = (0,0,-1), L = (0, s, -s): N·L = s; colour = P (ambient + diffuse s^brilliance)
    p = np.array([0.8, 0.4, 0.2])
    fin = rt.Finish(ambient=(0.1, 0.2, 0.3), diffuse=0.7, brilliance=2.5)
    got = one_pixel(sphere_scene(fin))
    np.testing.assert_allclose(got, p * (np.array([0.1, 0.2, 0.3]) + 0.7 * S**2.5), rtol=1e-5)


def test_phong_and_specular_highlights_use_the_light_colour():
    # mirrored view ray R = (0,0,-1): R·L = s; H = normalize(L - D) = normalize((0, s, -s-1))
    light = rt.Light(position=(0.0, 10 * S, -10 * S), point_at=(0, 0, 0), parallel=True,
                     color=(0.5, 1.0, 2.0))
    fin = rt.Finish(ambient=(0, 0, 0), diffuse=0.0, phong=0.6, phong_size=7.0, specular=0.3,
                    roughness=0.1)
    got = one_pixel(sphere_scene(fin, lights=(light,)))
    n_dot_h = (S + 1) / np.sqrt(S**2 + (S + 1) ** 2)
    expected = (0.6 * S**7 + 0.3 * n_dot_h**10) * np.array([0.5, 1.0, 2.0])
    np.testing.assert_allclose(got, expected, rtol=1e-5)


def test_metallic_tints_highlights_by_the_pigment():
    fin = rt.Finish(ambient=(0, 0, 0), diffuse=0.0, phong=1.0, phong_size=1.0, metallic=0.7)
    got = one_pixel(sphere_scene(fin))
    x = np.arccos(S) / (np.pi / 2)
    f = np.clip(0.014567225 / (x - 1.12) ** 2 - 0.011612903, 0, 1)
    tint = 1 + 0.7 * (1 - f) * (np.array([0.8, 0.4, 0.2]) - 1)
    np.testing.assert_allclose(got, S * tint, rtol=1e-5)


def test_point_light_fade_follows_povs_formula_not_inverse_square():
    # point light straight in front: N·L = 1, distance 4 from the hit point
    light = rt.Light(position=(0, 0, -5), fade_distance=2.0, fade_power=2.0)
    fin = rt.Finish(ambient=(0, 0, 0), diffuse=1.0)
    got = one_pixel(sphere_scene(fin, pigment=(1, 1, 1), lights=(light,)))
    np.testing.assert_allclose(got, 2 / (1 + (4 / 2) ** 2), rtol=1e-5)


def test_opaque_object_casts_a_full_shadow_and_transparent_one_filters_it():
    blocker_pos = (0.0, 3 * S, -1 - 3 * S)  # on the segment from the hit point to the light
    light = rt.Light(position=(0.0, 10 * S, -1 - 10 * S))
    fin = rt.Finish(ambient=(0.1, 0.1, 0.1), diffuse=1.0)
    opaque = rt.Object(rt.Sphere(blocker_pos, 0.2), texture=rt.Texture.of(rt.Pigment.solid((1, 1, 1))))
    got = one_pixel(sphere_scene(fin, pigment=(1, 1, 1), lights=(light,), extra=(opaque,)))
    np.testing.assert_allclose(got, 0.1, rtol=1e-5)
    # rgbf <0.5, 1, 1, 0.6> filters (f P + t) = (0.3, 0.6, 0.6) at each of its two surfaces
    glass = rt.Object(rt.Sphere(blocker_pos, 0.2),
                      texture=rt.Texture.of(rt.Pigment.solid((0.5, 1, 1), filter=0.6)))
    got = one_pixel(sphere_scene(fin, pigment=(1, 1, 1), lights=(light,), extra=(glass,)))
    np.testing.assert_allclose(got, 0.1 + S * np.array([0.3, 0.6, 0.6]) ** 2, rtol=1e-4)


def test_a_fading_interior_attenuates_shadows_by_its_chord():
    # the shadow ray leaves the hit point (0, 0, -1) towards the light along (0, S, -S); a glass
    # sphere of radius r centred on it at distance 3 is crossed along a chord of 2r. povray 3.7
    # measured (docs in raytracer.shading.lighting.interior_fade): fade over the chord at the
    # exit crossing, nothing for the air before the entry
    blocker_pos = (0.0, 3 * S, -1 - 3 * S)
    light = rt.Light(position=(0.0, 10 * S, -1 - 10 * S))
    fin = rt.Finish(ambient=(0.1, 0.1, 0.1), diffuse=1.0)
    fc = np.array([0.2, 0.6, 0.3])
    for power, attenuation in ((2.0, lambda d: fc + (1 - fc) / (1 + (d / 0.5) ** 2)),
                               (1000.0, lambda d: np.exp(-(1 - fc) * d / 0.5))):
        glass = rt.Object(rt.Sphere(blocker_pos, 0.4),
                          texture=rt.Texture.of(rt.Pigment.solid((1, 1, 1), transmit=1.0)),
                          interior=rt.Interior(ior=1.5, fade_distance=0.5, fade_power=power,
                                               fade_color=fc))
        got = one_pixel(sphere_scene(fin, pigment=(1, 1, 1), lights=(light,), extra=(glass,)))
        np.testing.assert_allclose(got, 0.1 + S * attenuation(0.8), rtol=1e-4)


FADE_POWERS = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 1.5, -6> look_at <0, 0.4, 0> right x*image_width/image_height angle 45 }
light_source { <3, 8, -4> color rgb 1 }
plane { y, -1 pigment { rgb 1 } finish { ambient 0.1 diffuse 0.8 } }
plane { z, 4 pigment { rgb <0.9, 0.8, 0.7> } finish { ambient 1 diffuse 0 } }
#declare Glass = texture { pigment { rgbf <1, 0.9, 0.8, 0.8> } finish { ambient 0 diffuse 0.1 } }
sphere { <-1.6, 0, 0>, 0.7 texture { Glass }
         interior { ior 1.2 fade_distance 0.5 fade_power 0 fade_color <0.5, 0.2, 0> } }
sphere { 0, 0.7 texture { Glass } interior { ior 1.2 fade_distance 2 } }
sphere { <1.6, 0, 0>, 0.7 texture { Glass }
         interior { ior 1.2 fade_distance 0.8 fade_power -1 fade_color <0, 0.3, 0.6> } }
"""


@pytest.mark.povray
def test_a_fade_power_of_zero_or_below_fades_what_passes_through_but_not_shadows():
    """POV-Ray 3.7 (measured on slabs, semantics §2.7): ``fade_power 0``, its default, fades a
    transmitted ray to ``(1 + fc)/2`` at any depth, a negative power by the same formula; a shadow
    ray through such an interior is not faded. ``interior/atten1.pov`` writes ``fade_power 0``."""
    from validation.metrics import psnr
    from validation.povray import render_povray

    scene = rt.load_scene(FADE_POWERS)
    assert rt.plan(scene).effects.interior_fade
    ours = np.asarray(rt.render(scene, width=80, height=60))
    assert psnr(ours, render_povray(FADE_POWERS, 80, 60)) >= 40.0


def test_interior_fade_gradients_are_finite_in_both_forms():
    from raytracer.shading.lighting import interior_fade

    fc = jnp.array([0.2, 0.6, 0.3])
    # exponential form: d/dd sum(exp(-(1 - fc) d / fd)) = -sum((1 - fc)/fd · exp(...)); the
    # rational branch, not taken, once made this NaN (inf · 0) at depth 5, power 1000
    g = jax.grad(lambda d: interior_fade(d, 0.5, 1000.0, fc).sum())(5.0)
    np.testing.assert_allclose(g, -np.sum((1 - fc) / 0.5 * np.exp(-(1 - fc) * 10.0)), rtol=1e-5)
    # rational form: d/dd [fc + (1 - fc)/(1 + (d/fd)²)] = -(1 - fc)·2d/fd² / (1 + (d/fd)²)²
    g = jax.grad(lambda d: interior_fade(d, 0.5, 2.0, fc).sum())(5.0)
    np.testing.assert_allclose(g, -np.sum((1 - fc) * 2 * 5.0 / 0.25 / (1 + 100.0) ** 2), rtol=1e-5)


def test_a_difference_turns_the_subtracted_normals_inwards():
    from raytracer._plan import make_plan

    scene = rt.load_scene("difference { box { -1, 1 } sphere { 0, 0.5 } cylinder { -2*x, 2*x, 0.2 } "
                          "inverse }")
    # the whole difference is inverted: the box flips once, the subtracted ones twice
    assert [p.inverse for p in make_plan(scene).prims] == [True, False, False]
    scene = rt.load_scene("difference { box { -1, 1 } sphere { 0, 0.5 } }")
    assert [p.inverse for p in make_plan(scene).prims] == [False, True]


def test_constant_reflection_adds_the_mirrored_background():
    fin = rt.Finish(ambient=(0, 0, 0), diffuse=0.0,
                    reflection=rt.Reflection(min=(0.3, 0.3, 0.3), max=(0.3, 0.3, 0.3)))
    got = one_pixel(sphere_scene(fin, background=(0.2, 0.5, 1.0)))
    np.testing.assert_allclose(got, 0.3 * np.array([0.2, 0.5, 1.0]), rtol=1e-5)


def test_reflection_falloff_interpolates_between_min_and_max():
    # tilt the sphere's hit normal: look at the sphere from an angle so cos_i is known
    scene = rt.Scene(
        camera=rt.Camera(location=(0, 0, -5), look_at=(0, 0, 0)),
        objects=(rt.Object(rt.Plane((0, -S, -S), -1.0),  # plane through z=-1·... facing the camera at 45°
                           texture=rt.Texture.of(rt.Pigment.solid((1, 1, 1)), rt.Finish(
                               ambient=(0, 0, 0), diffuse=0.0,
                               reflection=rt.Reflection(min=(0.1,) * 3, max=(0.9,) * 3, falloff=2.0)))),),
        background=(1.0, 1.0, 1.0))
    got = one_pixel(scene)
    frac = (1 - S) ** 2
    np.testing.assert_allclose(got, frac * 0.9 + (1 - frac) * 0.1, rtol=1e-5)


def test_one_reflection_colour_with_fresnel_reflects_fresnel_times_that_colour():
    # POV-Ray takes the one colour as the maximum and 0 as the minimum (semantics §2.6): at normal
    # incidence on ior 1.5, F = ((1.5 - 1)/(1.5 + 1))² = 0.04 (POV-Ray 3.7.0.10: 0.032 for C = 0.8)
    scene = rt.load_scene("""#version 3.7; global_settings { assumed_gamma 1.0 }
        camera { location <0, 0, -5> look_at 0 }
        background { rgb <0.2, 0.5, 1> }
        sphere { 0, 1 pigment { rgb 1 } finish { ambient 0 diffuse 0 reflection { 0.8 fresnel on } }
                 interior { ior 1.5 } }""")
    np.testing.assert_allclose(one_pixel(scene), 0.8 * 0.04 * np.array([0.2, 0.5, 1.0]), rtol=1e-4)


def metallic_tint_at_normal_incidence(m, pigment):
    f = np.clip(0.014567225 / (0.0 - 1.12) ** 2 - 0.011612903, 0, 1)  # empirical curve at x = 0 (§2.4)
    return 1 + m * (1 - f) * (np.asarray(pigment) - 1)


def test_reflection_metallic_tints_without_a_highlight_metallic():
    fin = rt.Finish(ambient=(0, 0, 0), diffuse=0.0,
                    reflection=rt.Reflection(min=(0.8,) * 3, max=(0.8,) * 3, metallic=0.6))
    scene = sphere_scene(fin, background=(0.2, 0.5, 1.0))
    eff = rt.plan(scene).effects
    assert eff.reflection_metallic and not eff.metallic
    expected = 0.8 * metallic_tint_at_normal_incidence(0.6, (0.8, 0.4, 0.2)) * np.array([0.2, 0.5, 1.0])
    np.testing.assert_allclose(one_pixel(scene), expected, rtol=1e-5)


def test_reflection_metallic_zero_is_compiled_and_has_a_gradient():
    fin = rt.Finish(ambient=(0, 0, 0), diffuse=0.0,
                    reflection=rt.Reflection(min=(0.8,) * 3, max=(0.8,) * 3, metallic=0.0))
    scene = sphere_scene(fin, background=(0.2, 0.5, 1.0))
    assert rt.plan(scene).effects.reflection_metallic
    assert not rt.plan(sphere_scene(rt.Finish(reflection=rt.Reflection(min=(0.8,) * 3, max=(0.8,) * 3)))
                       ).effects.reflection_metallic

    def red(m):
        s = eqx.tree_at(lambda s: s.objects[0].texture.layers[0].finish.reflection.metallic, scene, m)
        return rt.render(s, width=1, height=1)[0, 0, 0]

    # d/dM of 0.8·(1 + M(1 - f)(P - 1))·bg = 0.8·(1 - f)(P - 1)·bg, red: P = 0.8, bg = 0.2
    expected = 0.8 * (metallic_tint_at_normal_incidence(1.0, 0.8) - 1) * 0.2
    np.testing.assert_allclose(jax.grad(red)(jnp.float32(0.0)), expected, rtol=1e-4)


# a sphere over a checkered plane, lit: its reflection shows the plane, the sky and its own tint
REFLECTION_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 1.5, -5> look_at <0, 0.5, 0> right x*image_width/image_height angle 40 }}
background {{ rgb <0.3, 0.5, 0.8> }}
light_source {{ <-4, 6, -5>, rgb 1 }}
plane {{ y, -1 pigment {{ checker rgb 1, rgb <0.1, 0.2, 0.1> }} finish {{ ambient 0.1 diffuse 0.7 }} }}
sphere {{ <0, 0.2, 0>, 1.2 pigment {{ rgb <0.9, 0.5, 0.2> }} finish {{ ambient 0.05 {finish} }} {extra} }}
"""


@pytest.mark.povray
@pytest.mark.parametrize("finish, extra", [
    # one colour with fresnel on glass-like ior: was a full mirror, 12.0 dB from POV-Ray
    ("diffuse 0.6 reflection { 0.8 fresnel on }", "interior { ior 1.5 }"),
    # reflection metallic with no highlight metallic in the scene: was untinted, 15.5 dB
    ("diffuse 0.3 reflection { 0.8 metallic 1 }", ""),
])
def test_reflection_forms_match_povray(finish, extra):
    from validation.metrics import psnr
    from validation.povray import render_povray

    text = REFLECTION_SCENE.format(finish=finish, extra=extra)
    ours = np.asarray(rt.render(rt.load_scene(text), width=80, height=60))
    assert psnr(ours, render_povray(text, 80, 60)) >= 40.0


def _shells(n: int, ior: bool) -> str:
    """``n`` concentric transparent spheres in front of a glowing checker wall."""
    rows = [f"sphere {{ 0, {0.3 * (i + 1):g} pigment {{ rgbf <1, {0.9 + 0.01 * i:g}, 0.95, 0.95> }} "
            "finish { ambient 0 diffuse 0.05 }" + (f" interior {{ ior 1.{i % 3 + 1} }}" if ior else "") + " }"
            for i in range(n)]
    level = 30 if ior else 2
    return (f"#version 3.7;\nglobal_settings {{ assumed_gamma 1.0 max_trace_level {level} }}\n"
            "camera { location <0, 0, -8> look_at 0 angle 45 }\nlight_source { <-5, 10, -8> color rgb 1 }\n"
            "plane { -z, -6 pigment { checker rgb <0.9,0.3,0.1>, rgb <0.1,0.3,0.9> } "
            "finish { ambient 1 diffuse 0 } }\n") + "\n".join(rows)


GLASS_BOX_45 = """#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 20 }
camera { location <0, 1.2, -4> look_at <0, 0.5, 0> right x*image_width/image_height angle 40 }
light_source { <-5, 10, -8> color rgb 1 }
plane { y, 0 pigment { checker rgb 0.9, rgb 0.1 } }
plane { z, 3 pigment { checker rgb <0.9,0.3,0.1>, rgb <0.1,0.3,0.9> scale 0.5 }
  finish { ambient 1 diffuse 0 } }
box { <-0.6, 0, -0.6>, <0.6, 1.2, 0.6> rotate <0, 45, 0>
  pigment { rgbf 1 } finish { ambient 0 diffuse 0 reflection { 0, 1 fresnel on } conserve_energy }
  interior { ior 1.6 } }
"""


@pytest.mark.povray
@pytest.mark.parametrize("text, precision, was", [
    # ten nested ior-1 shells at max_trace_level 2: 20 straight passes, which POV-Ray
    # does not count as levels (we stopped at 8: 17.7 dB)
    (_shells(10, ior=False), "float32", 17.7),
    # ten nested shells of iors 1.1–1.3: each surface refracts between the innermost two media
    # of the ray's interior list (we assumed air on the other side: 11.5 dB). float64: in float32
    # the grazing rays of ten concentric surfaces differ on 84 of 4,800 pixels (32.6 dB)
    (_shells(10, ior=True), "float64", 11.5),
    # the camera is inside plane { z, 3 }, so a ray leaving the box is inside two
    # interiors, where POV-Ray's Fresnel amount and conserve_energy factor are 0 (its quirk,
    # semantics §2.7; we reflected at the exits: 37.7 dB)
    (GLASS_BOX_45, "float32", 37.7),
])
def test_the_ray_keeps_the_list_of_interiors_it_is_inside_as_povray_does(text, precision, was):
    from validation.metrics import psnr
    from validation.povray import render_povray

    with jax.enable_x64(precision == "float64"):
        ours = np.asarray(rt.render(rt.load_scene(text), width=80, height=60))
    assert psnr(ours, render_povray(text, 80, 60)) >= 40.0


@pytest.mark.parametrize("text, slots", [
    (GLASS_BOX_45, 3 + 1),  # around the camera: at most one per primitive; then one per transparent one
    (_shells(10, ior=True), 16),  # 10 + 10, held to MEDIA_SLOTS
    (_shells(3, ior=False), 0),  # no refraction: no list
])
def test_the_interior_list_is_as_long_as_the_scene_can_fill(text, slots):
    """Each slot of the list is carried through every level of the ray tree: a scene gets as many
    as it can fill (the test above checks GLASS_BOX_45's image against POV-Ray with its 4)."""
    assert rt.plan(rt.load_scene(text)).effects.media_slots == slots


@pytest.mark.parametrize("depth, expected", [(2, 0.04), (3, 0.04 + 0.96 * 0.96)])
def test_glass_slab_at_normal_incidence_follows_fresnel_and_the_trace_level(depth, expected):
    # F = ((n-1)/(n+1))² = 0.04 at both faces for n = 1.5; conserve_energy leaves 0.96 transmitted.
    # depth 2: front reflection (background) + transmitted ray that dies at the back face.
    # depth 3: the back face passes 0.96 of the background through.
    glass = rt.Object(rt.Box((-2, -2, -1), (2, 2, 1)), interior=rt.Interior(ior=1.5),
                      texture=rt.Texture.of(rt.Pigment.solid((1, 1, 1), filter=1.0), rt.Finish(
                          ambient=(0, 0, 0), diffuse=0.0, conserve_energy=True,
                          reflection=rt.Reflection(max=(1, 1, 1), fresnel=True))))
    scene = rt.Scene(camera=rt.Camera(location=(0, 0, -5), look_at=(0, 0, 0)), objects=(glass,),
                     background=(0.5, 0.5, 0.5),
                     settings=rt.Settings(max_trace_level=depth, adc_bailout=0.0))
    np.testing.assert_allclose(one_pixel(scene), 0.5 * expected, rtol=1e-4)


def test_background_shows_where_nothing_is_hit():
    scene = rt.Scene(background=(0.1, 0.2, 0.3))
    img = np.asarray(rt.render(scene, width=4, height=3))
    np.testing.assert_allclose(img, np.broadcast_to([0.1, 0.2, 0.3], (3, 4, 3)), rtol=1e-6)


@pytest.mark.parametrize("gamma", [2.2, 1e308])
def test_assumed_gamma_output_is_the_power_held_finite(gamma):
    """value ** assumed_gamma (semantics §3.1); where that overflows (``assumed_gamma 1e308``, a fuzz
    case that made an infinite image) the largest finite value, with a finite gradient."""
    def image(bg):
        scene = rt.Scene(background=bg, settings=rt.Settings(output_transfer="gamma", assumed_gamma=gamma))
        return rt.render(scene, width=2, height=1)

    bg = jnp.asarray([0.5, 1.5, 0.0])
    img = np.asarray(image(bg))
    top = np.finfo(np.float32).max
    with np.errstate(over="ignore"):
        power = np.power([0.5, 1.5, 0.0], gamma)  # float64: 1.5 ** 1e308 is inf
    want = np.minimum(power, top)
    np.testing.assert_allclose(img, np.broadcast_to(want, (1, 2, 3)), rtol=1e-5)
    g = np.asarray(jax.grad(lambda b: image(b).sum())(bg))
    assert np.isfinite(g).all()
    with np.errstate(over="ignore", invalid="ignore"):
        slope = 2 * gamma * np.power([0.5, 1.5, 0.0], gamma - 1)
    want_g = np.where((power > 0) & (power < top), slope, 0.0)
    np.testing.assert_allclose(g, want_g, rtol=1e-4)


def test_supersampling_averages_a_regular_grid_of_subpixels():
    # a box edge through the pixel centre: half of any k×k grid (k even) sees the box
    scene = rt.Scene(
        camera=rt.Camera(location=(0, 0, 0), right=(1, 0, 0), up=(0, 1, 0)),
        objects=(rt.Object(rt.Box((0, -10, 1), (10, 10, 2)), texture=rt.Texture.of(
            rt.Pigment.solid((1, 1, 1)), rt.Finish(ambient=(1, 1, 1), diffuse=0.0))),),
        background=(0, 0, 0))
    np.testing.assert_allclose(one_pixel(scene, spp=4), 0.5, rtol=1e-6)
    np.testing.assert_allclose(one_pixel(scene, spp=16), 0.5, rtol=1e-6)


def test_render_rejects_non_square_sample_counts():
    with pytest.raises(ValueError, match="perfect square"):
        rt.render(rt.Scene(), width=2, height=2, spp=3)


# ---------------------------------------------------------------- the render plan
def test_diffuse_only_scene_compiles_without_secondary_rays():
    fin = rt.Finish(ambient=(0.1,) * 3, diffuse=0.6)
    scene = sphere_scene(fin)
    assert rt.plan(scene).effects.depth == 1
    assert not rt.plan(scene).effects.reflection and not rt.plan(scene).effects.transmission
    jaxpr = str(jax.make_jaxpr(lambda s: rt.render(s, width=2, height=2))(scene))
    assert jaxpr.count("argmin") == 1  # one closest-hit search: camera rays only
    assert "reverse=True" not in jaxpr  # no combination of secondary rays


ZERO_FILTER_SCENE = """
camera { location <0, 1.5, -4> look_at <0, 0.5, 0> }
light_source { <-4, 8, -6> color rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
sphere { <0, 0.8, 0>, 0.8
  texture { pigment { BOTTOM } }
  texture { pigment { checker rgbf <1, 1, 1, 1> rgbf <0.2, 0.5, 0.3, 0.6> scale 0.3 } } }
"""


def test_a_zero_filter_renders_as_opaque_and_leaves_transmission_out_unless_fitted():
    """A sphere whose bottom layer is written ``rgbf <…, 0>`` under a layer that filters: the same
    image as with that layer written ``rgb`` (opaque, as POV-Ray renders both), from the program
    of ``rgb`` with ``fit_zero_terms=False``; by default the written filter is compiled (the
    sphere is transparent: shadow rays filter through it, rays pass on through it without using a
    trace level) so that it can be fitted."""
    opaque = rt.load_scene(ZERO_FILTER_SCENE.replace("BOTTOM", "rgb <0.8, 0.3, 0.2>"))
    text = ZERO_FILTER_SCENE.replace("BOTTOM", "rgbf <0.8, 0.3, 0.2, 0>")
    fitted, rendered = rt.load_scene(text), rt.load_scene(text, fit_zero_terms=False)
    assert rt.plan(rendered).effects == rt.plan(opaque).effects
    assert not any(p.transparent for p in rt.plan(rendered).prims)
    assert [p.transparent for p in rt.plan(fitted).prims] == [False, True]  # the plane, the sphere
    assert rt.plan(fitted).effects.straight_passes == 2 and rt.plan(rendered).effects.straight_passes == 0
    want = np.asarray(rt.render(opaque, width=24, height=18))
    for scene in (fitted, rendered):
        np.testing.assert_allclose(np.asarray(rt.render(scene, width=24, height=18)), want, atol=1e-5)


ZERO_TERMS_SCENE = """
global_settings { max_trace_level 4 }
camera { location <0, 1.5, -4> look_at <0, 0.5, 0> }
light_source { <-4, 8, -6> color rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } finish { TERMS } }
sphere { <0, 0.8, 0>, 0.8 pigment { rgb <0.8, 0.3, 0.2> } finish { TERMS phong 0.6 } }
"""


@pytest.mark.parametrize(("terms", "reflection", "metallic"), [
    ("reflection 0", True, False), ("reflection { 0, 0 fresnel on metallic 0 }", True, False),
    ("specular 0 metallic 0", False, True), ("phong 0 reflection { 0 metallic 0.5 }", True, False)])
def test_zero_finish_terms_are_left_out_unless_fitted(terms, reflection, metallic):
    """Finish terms written as 0 that add nothing at 0: with ``fit_zero_terms=False`` the plan and
    the image are those of the scene without them (a ``reflection 0`` no longer makes a tree of
    ``max_trace_level`` levels); by default they are compiled, so they can be fitted."""
    bare = rt.load_scene(ZERO_TERMS_SCENE.replace("TERMS", ""))
    text = ZERO_TERMS_SCENE.replace("TERMS", terms)
    fitted, rendered = rt.load_scene(text), rt.load_scene(text, fit_zero_terms=False)
    assert rt.plan(rendered).effects == rt.plan(bare).effects
    eff = rt.plan(fitted).effects
    assert (eff.reflection, eff.depth, eff.metallic) == (reflection, 4 if reflection else 1, metallic)
    want = np.asarray(rt.render(bare, width=16, height=12))
    np.testing.assert_allclose(np.asarray(rt.render(rendered, width=16, height=12)), want, atol=1e-6)


def test_reflective_scene_scans_over_its_trace_levels_with_one_shading_body():
    fin = rt.Finish(reflection=rt.Reflection(min=(0.5,) * 3, max=(0.5,) * 3))
    scene = sphere_scene(fin, settings=rt.Settings(max_trace_level=3))
    eff = rt.plan(scene).effects
    assert eff.depth == 3 and eff.reflection and not eff.transmission and not eff.highlights
    jaxpr = str(jax.make_jaxpr(lambda s: rt.render(s, width=2, height=2))(scene))
    assert jaxpr.count("argmin") == 1  # the shading body is traced once …
    assert jaxpr.count("length=3") == 2 and "reverse=True" in jaxpr  # … and scanned over 3 levels, twice


def test_two_bounce_mirror_corridor_matches_the_geometric_series():
    # camera between two facing mirrors (reflection r = ½, ambient a = 0.1, no light): the centre
    # ray bounces back and forth and every segment ends on a mirror, so with max_trace_level L the
    # pixel is a·(1 + r + … + r^(L-1)).
    mirror = rt.Texture.of(rt.Pigment.solid((1, 1, 1)), rt.Finish(
        ambient=(0.1, 0.1, 0.1), diffuse=0.0, reflection=rt.Reflection(min=(0.5,) * 3, max=(0.5,) * 3)))
    for depth in (1, 2, 4):
        scene = rt.Scene(camera=rt.Camera(location=(0, 0, 0), look_at=(0, 0, 1)),
                         objects=(rt.Object(rt.Plane((0, 0, 1), 2.0), texture=mirror),
                                  rt.Object(rt.Plane((0, 0, -1), 2.0), texture=mirror)),
                         settings=rt.Settings(max_trace_level=depth, adc_bailout=0.0))
        expected = 0.1 * sum(0.5 ** k for k in range(depth))
        np.testing.assert_allclose(one_pixel(scene), expected, rtol=1e-5)


# ---------------------------------------------------------------- hard cases stay finite
def _finite_value_and_grad(scene, width=6, height=4):
    def loss(s):
        return jnp.sum(rt.render(s, width=width, height=height))

    value, grads = jax.value_and_grad(loss)(scene)
    leaves = jax.tree_util.tree_leaves(grads)
    assert np.isfinite(float(value))
    assert all(np.all(np.isfinite(np.asarray(g))) for g in leaves)
    return value, grads


@pytest.mark.slow  # a reverse-mode program through glass at depth 5: ~45 s of compile
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_camera_inside_a_glass_sphere_gives_finite_image_and_gradients(precision):
    with jax.enable_x64(precision == "float64"):
        glass = rt.Object(rt.Sphere((0, 0, 0), 3.0), interior=rt.Interior(ior=1.5),
                          texture=rt.Texture.of(rt.Pigment.solid((1, 1, 1), filter=0.9), rt.Finish(
                              reflection=rt.Reflection(max=(1, 1, 1), fresnel=True), conserve_energy=True)))
        scene = rt.Scene(camera=rt.Camera(location=(0, 0, -1), look_at=(0, 0, 0)), objects=(glass,),
                         lights=(rt.Light((5, 5, -5)),), background=(0.2, 0.4, 0.8))
        _finite_value_and_grad(scene)


@pytest.mark.slow  # two forward and two reverse-mode programs: ~30 s of compile
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_huge_and_tiny_scales_render_without_acne(precision):
    with jax.enable_x64(precision == "float64"):
        for scale in (1e5, 1e-4):
            fin = rt.Finish(ambient=(0.0,) * 3, diffuse=1.0)
            scene = rt.Scene(
                camera=rt.Camera(location=(0, 0, -5 * scale), look_at=(0, 0, 0)),
                objects=(rt.Object(rt.Sphere((0, 0, 0), scale),
                                   texture=rt.Texture.of(rt.Pigment.solid((1, 1, 1)), fin)),),
                lights=(rt.Light((0, 0, -10 * scale)),))
            # centre ray: N·L = 1 and no self-shadowing → exactly 1
            np.testing.assert_allclose(one_pixel(scene), 1.0, rtol=1e-4)
            _finite_value_and_grad(scene, 3, 3)


GROUND_SPHERE = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 1.63, -5.11> look_at <0, 0.6, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 }
sphere { GROUND pigment { checker rgb 0.9, rgb 0.2 } finish { ambient 0.1 diffuse 0.7 } }
sphere { <0, 0, 0>, 1 pigment { rgb <1, 0.3, 0.2> } finish { phong 0.5 } }
"""


@pytest.mark.povray
@pytest.mark.parametrize("ground", ["<0, -1e6-1, 0>, 1e6", "0, 1 scale 1e6 translate <0, -1e6-1, 0>"])
def test_float32_ground_sphere_matches_povray_on_its_checker(ground):
    """A radius-1e6 "ground sphere" with a checker, in float32. Its top stays within 1e-6 of the
    checker face y = -1 over a disc of radius ~1.4: POV-Ray (float64, 1e-10 nudge) puts all of it
    below the face. Three things make float32 agree: |o - c|² - r² is compensated (it cancels near
    a huge sphere: hits landed 0.02 short, shadow acne); the hit point is computed again from
    ``o + t d`` (closest_hit's refine: ``o + t d`` alone is off by eps·|o|, 1e-3 at the horizon, and
    flipped cells there); and the checker's nudge is POV-Ray's 1e-10, not an ulp, where the point is
    exact. Given by a transform, the sphere is the same: its similarity transform is folded into
    its centre and radius at load (absorb_transform), not applied to float32 ray origins."""
    from validation.metrics import psnr
    from validation.povray import render_povray

    text = GROUND_SPHERE.replace("GROUND", ground)
    ours = np.asarray(rt.render(rt.load_scene(text), width=160, height=120))
    assert ours.dtype == np.float32
    assert psnr(ours, render_povray(text, 160, 120)) >= 40.0


@pytest.mark.povray
def test_float32_checker_faces_far_from_the_camera_match_povray():
    """A checker plane 500 units away whose face z = 3 is the plane itself (``incdemo/chars.pov``),
    a floor seen from 760 units, and a rotated, scaled box whose faces lie on the checker's: float32
    hit points computed again at the surface land on the face, as POV-Ray's float64 ones do (each
    flipped 10 % or more of its cells before)."""
    from validation.metrics import psnr
    from validation.povray import render_povray

    head = "#version 3.7;\nglobal_settings { assumed_gamma 1.0 }\nlight_source { <200, 200, -500> rgb 1 }\n"
    for body in ("camera { location <0, 0, -500> right x*4/3 angle 6 look_at 0 }\n"
                 "plane { z, 3 pigment { checker rgb <1, 1, 0>, rgb 1 } }",
                 "camera { location <3, 300, -700> look_at 0 angle 20 }\n"
                 "plane { y, 0 pigment { checker rgb 1, rgb 0.2 scale 10 } }",
                 "camera { location <0.3, 30, -70> look_at 0 angle 10 }\n"
                 "box { -1, 1 pigment { checker rgb 1, rgb 0.2 scale 0.5 } rotate 30*y scale 3 }"):
        ours = np.asarray(rt.render(rt.load_scene(head + body), width=80, height=60))
        assert psnr(ours, render_povray(head + body, 80, 60)) >= 40.0, body


@pytest.mark.parametrize("max_trace_level, expected", [(1, (0.0, 0.0, 0.0)), (2, (0.8, 0.6 / 16, 0.4 / 16))])
def test_straight_transmission_does_not_use_trace_levels(max_trace_level, expected):
    # two concentric ior-1 shells with rgbf <1, ½, ½, 1>: four crossings filter by (1, ½, ½) each.
    # POV counts the camera ray as level 1 and spawns children only below max_trace_level, but a
    # straight (ior 1) pass keeps its level: level 2 is enough for all four crossings, level 1
    # shows nothing behind the first surface (both checked against povray 3.7.0.10).
    shell = rt.Texture.of(rt.Pigment.solid((1, 0.5, 0.5), filter=1.0),
                          rt.Finish(ambient=(0, 0, 0), diffuse=0.0))
    scene = rt.Scene(camera=rt.Camera(location=(0, 0, -5), look_at=(0, 0, 0)),
                     objects=(rt.Object(rt.Sphere((0, 0, 0), 1.0), texture=shell),
                              rt.Object(rt.Sphere((0, 0, 0), 2.0), texture=shell)),
                     background=(0.8, 0.6, 0.4),
                     settings=rt.Settings(max_trace_level=max_trace_level, adc_bailout=0.0))
    assert rt.plan(scene).effects.straight_passes > 0
    np.testing.assert_allclose(one_pixel(scene), expected, rtol=1e-5, atol=1e-7)


def test_look_at_parallel_to_sky_is_a_clear_error():
    with pytest.raises(ValueError, match="parallel to sky"):
        rt.Camera(location=(0, 0, 0), look_at=(0, 5, 0))
    with pytest.raises(ValueError, match="equals its location"):
        rt.Camera(location=(1, 2, 3), look_at=(1, 2, 3))
    rt.Camera(location=(0, 0, 0), look_at=(0, 5, 0), sky=(0, 0, 1))  # a different sky is fine


def test_camera_frame_follows_povs_look_at_rules():
    # semantics §1.1: |D|, |R|, |U| kept; D̂ = normalize(look_at − location); R̂ = normalize(sky × D̂);
    # Û = D̂ × R̂; angle α sets |D| = |R| / (2 tan(α/2)) before look_at
    cam = rt.Camera(location=(1, 2, -3), look_at=(0, 0, 0), right=(1.5, 0, 0), angle_degrees=60.0)
    loc, d, r, u = (np.asarray(v, np.float64) for v in cam.frame())
    d_hat = -np.array([1, 2, -3]) / np.linalg.norm([1, 2, -3])
    r_hat = np.cross([0, 1, 0], d_hat)
    r_hat /= np.linalg.norm(r_hat)
    np.testing.assert_allclose(d, d_hat * 1.5 / (2 * np.tan(np.radians(30))), rtol=1e-5)
    np.testing.assert_allclose(r, 1.5 * r_hat, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(u, np.cross(d_hat, r_hat), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(loc, [1, 2, -3])


def test_look_at_mirrors_right_where_up_lies_along_the_direction():
    """``up z`` with the default direction z (objects/prism3.inc's camera): (up × direction)·right
    is 0, and POV-Ray's image of that scene is the mirror of the one a kept right vector gives
    (measured: 16.7 dB kept, 89.9 dB mirrored); a positive product keeps it, a negative mirrors."""
    def right(up, rgt):
        cam = rt.Camera(location=(-10, 10, -10), look_at=(0, 0, 0), up=up, right=rgt)
        return np.asarray(cam.frame()[2], np.float64)

    kept = np.cross([0, 1, 0], np.array([1.0, -1, 1]) / np.sqrt(3))
    kept *= 4 / 3 / np.linalg.norm(kept)
    np.testing.assert_allclose(right((0, 0, 1), (4 / 3, 0, 0)), -kept, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(right((0, 1, 0), (4 / 3, 0, 0)), kept, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(right((0, 1, 0), (-4 / 3, 0, 0)), -kept, rtol=1e-5, atol=1e-6)


def test_the_api_turns_the_persistent_compilation_cache_on_unless_one_is_configured(tmp_path, monkeypatch):
    import importlib

    render_module = importlib.import_module("raytracer.render")  # the module (rt.render is the function)

    before = jax.config.jax_compilation_cache_dir
    monkeypatch.setattr(render_module, "_CACHE_CHECKED", [])
    monkeypatch.setenv("RAYTRACER_CACHE_DIR", str(tmp_path / "xla"))
    try:
        render_module.use_compilation_cache()  # the test run configured its own: kept
        assert jax.config.jax_compilation_cache_dir == before
        jax.config.update("jax_compilation_cache_dir", None)
        monkeypatch.setattr(render_module, "_CACHE_CHECKED", [])
        render_module.use_compilation_cache()  # nothing configured: ours
        assert jax.config.jax_compilation_cache_dir == str(tmp_path / "xla")
    finally:
        jax.config.update("jax_compilation_cache_dir", before)


def test_shadow_rays_skip_no_shadow_objects_without_their_crossings():
    """Shadow rays compute the crossings of shadow casters only (``_geometry.candidate_view``): a
    ``no_shadow`` CSG object on the shadow ray leaves the point lit (0.1 + diffuse·cos 45°), a
    casting one blocks it, and only the casting one's primitives are the shadow rays' candidates."""
    def scene(modifier):
        return rt.load_scene(f"""#version 3.7;
            global_settings {{ assumed_gamma 1.0 }}
            camera {{ location <0, 0, -5> look_at 0 }}
            light_source {{ <0, {10 * S}, {-1 - 10 * S}> color rgb 1 }}
            sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ ambient 0.1 diffuse 1 }} }}
            #declare C = <0, {3 * S}, {-1 - 3 * S}>;
            difference {{ sphere {{ C, 0.3 }} sphere {{ C, 0.1 }}
                         pigment {{ rgb 1 }} {modifier} }}""")

    np.testing.assert_allclose(one_pixel(scene("no_shadow")), 0.1 + S, rtol=1e-5)
    np.testing.assert_allclose(one_pixel(scene("")), 0.1, rtol=1e-5)

    from raytracer._plan import make_plan
    from raytracer.shading._accel import MASK_SHADOW
    from raytracer.shading._geometry import candidate_view, pack_geometry, visibility_bits

    plan = make_plan(scene("no_shadow"))
    geo = pack_geometry(plan, jnp.float32, accelerate=False)
    view = candidate_view(geo, plan, lambda i: bool(visibility_bits(plan.prims[i]) & MASK_SHADOW))
    assert set(view.cand_prim.tolist()) == {0} and set(geo.cand_prim.tolist()) == {0, 1, 2}
    assert view.conditions is None  # the big sphere has no CSG condition


def test_a_small_image_is_split_over_the_devices_only_where_its_rays_branch(monkeypatch):
    """An image of one tile is split over two devices when its scene has a ray tree and each device
    gets at least ``MIN_SHARD_RAYS`` camera rays; camera rays alone cost less than the split."""
    import importlib

    from raytracer._plan import make_plan

    tiles = importlib.import_module("raytracer._tiles")
    mirror = rt.Finish(reflection=rt.Reflection(min=(0.3, 0.3, 0.3), max=(0.3, 0.3, 0.3)))
    tree, flat = make_plan(sphere_scene(mirror)), make_plan(sphere_scene(rt.Finish()))
    assert tree.effects.depth > 1 and flat.effects.depth == 1
    monkeypatch.setattr(jax, "local_devices", lambda: [object(), object()])
    least = 2 * tiles.MIN_SHARD_RAYS
    assert tiles._layout(tree, 6912, 1, 1, 2) == (3456, 2, 2)
    assert tiles._layout(flat, 6912, 1, 1, 2) == (6912, 1, 1)
    assert tiles._layout(tree, least - 4, 1, 1, 2)[2] == 1
    assert tiles._layout(tree, least, 1, 1, 2)[2] == 2


def test_a_packed_scene_is_placed_on_the_device_once_and_its_image_stays_movable(monkeypatch):
    """``render`` keeps the packed scene's arrays on the device between calls (not copied from
    NumPy on each), and on one device they stay uncommitted as NumPy inputs were: the image
    combines with an array committed to any device. The placed copies stay within
    ``PLACED_BYTES`` in all: the oldest make room, and a larger scene is not kept."""
    import importlib

    packing = importlib.import_module("raytracer._packed")
    scene = sphere_scene(rt.Finish())
    first = np.asarray(rt.render(scene, width=4, height=3))
    packed = packing.pack(scene)
    placed = packing._placed(packed, 1)
    assert packing._placed(packed, 1) is placed
    leaves = [x for x in jax.tree.leaves(placed) if hasattr(x, "shape")]
    assert leaves and not any(isinstance(x, np.ndarray) for x in leaves)
    image = rt.render(scene, width=4, height=3)
    np.testing.assert_array_equal(np.asarray(image), first)
    assert not image.committed
    other = jax.device_put(jnp.ones((3, 4, 3)), jax.devices()[-1])
    assert np.asarray(image + other).shape == (3, 4, 3)
    # the placed arrays follow the x64 setting: a float64 scene placed with x64 off, then on (the
    # second took the first one's float32 arrays, and rendered a float32 image). Only placing is
    # switched here: JAX reuses compiled programs across such switches in one process.
    with jax.enable_x64(True):
        wide = packing.pack(sphere_scene(rt.Finish()))
        with jax.enable_x64(False):
            narrow = packing._placed(wide, 1)
        full = packing._placed(wide, 1)

    def dtypes(tree):
        return {x.dtype for x in jax.tree.leaves(tree) if hasattr(x, "dtype") and x.dtype.kind == "f"}

    assert full is not narrow and dtypes(narrow) == {np.dtype("float32")}
    assert np.dtype("float64") in dtypes(full)

    def size(p):
        return sum(x.nbytes for x in jax.tree.leaves(p) if isinstance(x, np.ndarray))

    one, two = packing.pack(sphere_scene(rt.Finish())), packing.pack(sphere_scene(rt.Finish()))
    monkeypatch.setattr(packing, "PLACED_BYTES", size(one) + size(two) // 2)  # room for one
    packing._PLACED.clear()
    kept = packing._placed(one, 1)
    assert packing._placed(two, 1) is not two
    assert packing._placed(one, 1) is not kept  # dropped to make room for two
    monkeypatch.setattr(packing, "PLACED_BYTES", size(one) - 1)
    three = packing.pack(sphere_scene(rt.Finish()))
    assert packing._placed(three, 1) is three  # too large to keep: its NumPy arrays, copied per call


def test_a_scene_with_nothing_to_render_is_its_background_through_the_output_transfer():
    """Every object left out (a bicubic patch: not rendered yet): the background, raised to
    assumed_gamma as POV-Ray writes it to a linear EXR (semantics §3.1), from render and from
    compile_render (whose program is compiled with it, not on the first call)."""
    from raytracer._plan import make_plan
    from raytracer.render import compile_render

    scene = rt.load_scene("""#version 3.7; global_settings { assumed_gamma 2.2 }
camera { location -5 * z look_at 0 }
background { rgb <0.5, 0.25, 1> }
bicubic_patch { type 1 flatness 0.1 u_steps 2 v_steps 2 """ + ", ".join(["<0, 0, 0>"] * 16) + """
  pigment { rgb 1 } }
""")
    assert not any(p.rendered for p in make_plan(scene).prims)
    want = np.broadcast_to(np.array([0.5, 0.25, 1.0]) ** 2.2, (6, 8, 3))
    np.testing.assert_allclose(np.asarray(rt.render(scene, width=8, height=6)), want, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(compile_render(scene, width=8, height=6)(scene)), want, rtol=1e-6)


@pytest.mark.parametrize("chosen", [None, "1"])
def test_the_api_splits_the_cpu_into_a_device_per_core_unless_told(chosen):
    """``import raytracer`` before JAX starts: one CPU device per core this process may use, as the
    command line does (renders shard their tiles over them); ``RAYTRACER_CPU_DEVICES`` chooses."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "RAYTRACER_CPU_DEVICES")}
    if chosen is not None:
        env["RAYTRACER_CPU_DEVICES"] = chosen
    out = subprocess.run([sys.executable, "-c", "import raytracer, jax; print(len(jax.devices()))"],
                         env=env, capture_output=True, text=True, check=True).stdout
    assert int(out) == (len(os.sched_getaffinity(0)) if chosen is None else int(chosen))
