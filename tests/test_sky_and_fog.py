"""``sky_sphere`` and constant ``fog`` (semantics §2.8): what rays that hit nothing see and what
they pass through, against POV-Ray's images, their derivatives against central differences, and
their syntax."""

import equinox as eqx
import jax
import numpy as np
import pytest

import raytracer as rt
from raytracer.errors import SceneError

HEAD = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0.5, -4> look_at <0, 0.6, 0> right x*image_width/image_height angle 70 }
"""

# the sky alone: layers over the background (filter, transmit), emission (not of what a filter passes),
# the sky's transformations written before and after its pigments, a pigment's own transformation
LAYERED = HEAD + """
background { rgb <0, 0.2, 1> }
sky_sphere {
  rotate 20 * z
  pigment { gradient y color_map { [0 rgb <1, 0.5, 0>] [0.5 rgb <0.2, 0.3, 1>] [1 rgbt <1, 1, 1, 0.6>] } }
  pigment { gradient x color_map { [0 rgbf <0.2, 1, 0.4, 0.7>] [1 rgbt <0, 0, 1, 0.8>] } scale 0.7 }
  translate <0, 0.2, 0>
  emission <1.5, 1, 0.8>
}
"""

# a declared sky used and added to, after a first sky that the later one replaces
DECLARED = HEAD + """
sky_sphere { pigment { rgb <1, 0, 0> } }
#declare Sky = sky_sphere { pigment { gradient z color_map { [0 rgb 0.1] [1 rgb <0.5, 0.8, 1>] } } }
sky_sphere { Sky pigment { rgbf <1, 0.6, 0.6, 0.5> } scale <1, 2, 1> }
"""

# rays that hit nothing after reflection and refraction see the sky too
UNDER_THE_SKY = HEAD + """
global_settings { max_trace_level 6 }
light_source { <-5, 8, -6> rgb 1 }
sky_sphere { pigment { gradient y color_map { [0 rgb <0.9, 0.6, 0.3>] [1 rgb <0.1, 0.3, 0.9>] } }
             rotate <10, 0, 30> }
sphere { <-1.1, 0.6, 0>, 0.9 pigment { rgb 0.2 } finish { reflection 0.8 } }
sphere { <1.1, 0.6, 0>, 0.9 pigment { rgbf <1, 1, 1, 0.9> } interior { ior 1.5 } }
"""


# two fogs (one with filter and transmit) over a sky, a mirror, a glass sphere and a transparent
# triangle seen from behind in front of the glass: rays inside the sphere, and past the triangle,
# have no fog (where a ray past such a triangle meets a mirror, POV-Ray fogs more than we do:
# semantics §2.8)
FOGGY = UNDER_THE_SKY + """
fog { distance 4 color rgbft <0.6, 0.7, 0.8, 0.3, 0.1> }
#declare Haze = fog { rgb <0.9, 0.5, 0.3> distance 12 }
fog { Haze }
plane { y, -0.3 pigment { checker rgb 1 rgb 0.2 } }
triangle { <2.4, -0.3, -1.5>, <0.2, -0.3, -1.5>, <1.3, 1.2, -1.8> pigment { rgbf <1, 1, 0.9, 0.8> } }
"""

# fog over the background alone: every ray sees it from infinitely far (its transmit lets some
# through); a ground fog, whose rays that climb out of it see through it
FOG_ONLY = HEAD + """background { rgb <0, 1, 0> } fog { distance 3 color rgbt <0, 0, 1, 0.4> }
fog { fog_type 2 distance 2 color rgbt <1, 0.5, 0, 0.1> fog_offset 0.6 fog_alt 0.4 up <0.2, 1, 0> }"""

# a ground fog over a floor, a mirror and glass, with a constant fog
GROUND = UNDER_THE_SKY + """
plane { y, -0.3 pigment { checker rgb 1 rgb 0.2 } }
fog { fog_type 2 distance 1.5 color rgbf <0.8, 0.8, 0.9, 0.3> fog_offset 0.2 fog_alt 0.5 }
fog { distance 30 color rgb <0.5, 0.5, 0.6> }
"""


@pytest.mark.povray
@pytest.mark.parametrize("text", [LAYERED, DECLARED, UNDER_THE_SKY, FOGGY, FOG_ONLY, GROUND],
                         ids=["layered", "declared", "under", "foggy", "fog-only", "ground"])
def test_sky_and_fog_match_povray(text):
    """Every pixel within POV-Ray's half-float EXR (the first two scenes have nothing but the sky:
    the program of camera rays alone)."""
    from validation.povray import render_povray

    ours = np.asarray(rt.render(rt.load_scene(text, width=40, height=30), width=40, height=30))
    theirs = render_povray(text, 40, 30)
    assert np.abs(ours).max() > 0.1
    np.testing.assert_allclose(ours, theirs, atol=2e-3)


def test_sky_and_fog_parameters_have_the_derivatives_of_finite_differences(x64):
    """d image / d (the sky's colour map and emission, the fog's distance and colour) along a
    random direction, forward mode, against central differences (float64), where the camera sees
    the sky directly, in a mirror and through glass, through a fog."""
    text = UNDER_THE_SKY + (
        "background { rgb <0.2, 0, 0.1> } sky_sphere { pigment { gradient y color_map "
        "{ [0 rgb <0.9, 0.6, 0.3>] [1 rgbt <0.1, 0.3, 0.9, 0.3>] } } emission <1.2, 1, 0.9> }"
        "fog { distance 5 color rgbft <0.6, 0.7, 0.8, 0.3, 0.2> }"
        "fog { fog_type 2 distance 2 color rgb <0.3, 0.4, 0.5> fog_offset 0.4 fog_alt 0.6 }")
    scene = rt.load_scene(text, width=8, height=6)  # (the second sky replaces the first)
    params = {name: x for name, x in rt.params.parameters(scene).items() if name.startswith("environment[")}
    # the environment's values in the order of ``scene.ENVIRONMENT``: the sky, then the fogs as written
    assert {"environment[0].emission", "environment[0].pigments[0].colors", "environment[1].distance",
            "environment[1].color", "environment[2].offset", "environment[2].alt"} <= set(params)
    rng = np.random.default_rng(2)
    tangent = {name: rng.normal(size=np.shape(x)) for name, x in params.items()}

    def image(p):
        return rt.render(rt.params.replace(scene, p), width=8, height=6)

    _, d_image = jax.jvp(image, (params,), (tangent,))
    h = 1e-6
    step = {name: np.asarray(x) + h * tangent[name] for name, x in params.items()}
    back = {name: np.asarray(x) - h * tangent[name] for name, x in params.items()}
    central = (np.asarray(image(step)) - np.asarray(image(back))) / (2 * h)
    assert np.abs(central).max() > 0.1  # the sky moves the image
    np.testing.assert_allclose(np.asarray(d_image), central, atol=1e-6)


def test_a_sky_without_pigment_shows_the_background_and_a_stray_item_is_an_error():
    scene = rt.load_scene("background { rgb <0, 0, 1> } sky_sphere { scale 2 }")
    assert scene.environment == ()
    with pytest.raises(SceneError, match=r"<string>:1:32: expected pigment, a transformation or emission"):
        rt.load_scene("sky_sphere { pigment { rgb 1 } phong 1 }")
    with pytest.raises(SceneError, match="in sky_sphere, found float 'S'"):
        rt.load_scene("#declare S = 1; sky_sphere { S }")
    with pytest.raises(SceneError, match=r"<string>:2:7: expected a fog, found sky_sphere 'S'"):
        rt.load_scene("#declare S = sky_sphere { pigment { rgb 1 } }\nfog { S }")


def test_fogs_povray_does_not_render_are_left_out_with_a_warning():
    """A ground fog without ``fog_alt`` (POV-Ray's image is NaN), a fog of distance 0 and an
    unknown type are left out; a turbulent fog is rendered smooth. Each says so at its line."""
    scene = rt.load_scene("fog { fog_type 2 distance 3 rgb 1 fog_offset 0.5 up y }\n"
                          "fog { distance 0 rgb 1 }\n"
                          "fog { distance 3 rgb 0.5 turbulence 0.4 octaves 3 scale 2 }\n"
                          "fog { fog_type 3 distance 3 rgb 1 }\n"
                          "fog { fog_type 2 distance 3 rgb 1 fog_alt 0.5 }")
    fogs = [v for v in scene.environment if isinstance(v, rt.Fog)]
    assert len(fogs) == 2 and [f.ground for f in fogs] == [False, True]
    messages = [(w.location.line, w.message) for w in scene.warnings if w.feature == "fog"]
    assert [line for line, _ in messages] == [1, 2, 3, 4]
    assert "fog_alt > 0" in messages[0][1] and "turbulence" in messages[2][1]
    with pytest.raises(SceneError, match=r"<string>:1:32: expected a fog item"):
        rt.load_scene("fog { distance 3 rgb 1 } fog { phong 1 }")


def test_a_fogs_colour_is_any_colour_expression():
    """POV-Ray reads a fog's colour as an expression: an identifier, arithmetic on one, a vector
    (``lights/circular.pov``'s ``fog { distance 200 Wheat*.5 }``); a fog identifier still starts a
    fog, and its items may follow."""
    written = rt.load_scene("fog { distance 200 color rgb <0.4, 0.3, 0.2> }")
    for text in ("#declare W = rgb <0.8, 0.6, 0.4>; fog { distance 200 W*.5 }",
                 "#declare W = rgb <0.4, 0.3, 0.2>; fog { W distance 200 }",
                 "fog { distance 200 <0.4, 0.3, 0.2> }",
                 "#declare F = fog { distance 5 rgb 1 }; fog { F distance 200 rgb <0.4, 0.3, 0.2> }"):
        scene = rt.load_scene(text)
        assert scene.environment == written.environment, text
    with pytest.raises(SceneError, match=r"<string>:1:36: expected a fog item"):
        rt.load_scene("#declare S = 1; fog { S distance 3 phong 1 }")


def test_a_scene_holds_its_environment_effects_as_records_of_the_environment_record():
    """The Python API: ``Scene.environment`` holds the effects' records in any order (a fog before a
    sky renders as the SDL scene does); an effect that does not add up appears once, and what is
    not an environment effect is refused."""
    text = ("sky_sphere { pigment { gradient y color_map { [0 rgb 0.2] [1 rgb <0.3, 0.5, 0.9>] } } }"
            "fog { distance 4 rgb <0.6, 0.6, 0.7> }")
    loaded = rt.load_scene(UNDER_THE_SKY + text, width=8, height=6)
    sky, fog = loaded.environment
    assert isinstance(sky, rt.SkySphere) and isinstance(fog, rt.Fog)
    built = eqx.tree_at(lambda s: s.environment, loaded, (fog, sky))
    np.testing.assert_array_equal(np.asarray(rt.render(built, width=8, height=6)),
                                  np.asarray(rt.render(loaded, width=8, height=6)))
    with pytest.raises(ValueError, match="more than one SkySphere"):
        rt.Scene(environment=(sky, fog, sky))
    with pytest.raises(TypeError, match="not an environment effect"):
        rt.Scene(environment=(rt.Settings(),))
