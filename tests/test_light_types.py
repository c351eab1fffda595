"""The light-type list is the single source of the render plan's light effects and of the defaults:
each type (and modifier) turns on exactly the effects it declares, and the parser, the scene model
and the spotlight cone share POV-Ray's defaults."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import raytracer as rt
from raytracer._plan import Effects
from raytracer.scene._lights import LIGHT_EFFECTS, LIGHT_SDL_KEYWORDS, LIGHT_TYPES, light_effects
from raytracer.sdl import load_scene

# One SDL light per entry of LIGHT_TYPES (a new light type adds its line here).
SDL_LIGHT = {
    "point": "light_source { <0, 5, -5> rgb 1 }",
    "spotlight": "light_source { <0, 5, -5> rgb 1 spotlight point_at 0 }",
    "cylinder": "light_source { <0, 5, -5> rgb 1 cylinder point_at 0 }",
    "parallel": "light_source { <0, 5, -5> rgb 1 parallel point_at 0 }",
    "area_light": "light_source { <0, 5, -5> rgb 1 area_light x, z, 2, 2 }",
    "fade": "light_source { <0, 5, -5> rgb 1 fade_distance 3 fade_power 2 }",
    "shadowless": "light_source { <0, 5, -5> rgb 1 shadowless }",
}


def _scene(light: str):
    return load_scene(f"camera {{ location <0, 1, -4> look_at 0 }}\n{light}\n"
                      "sphere { 0, 1 pigment { rgb 1 } }\nplane { y, -1 pigment { rgb 1 } }\n")


def test_every_light_type_has_a_scene_and_every_light_effect_a_type():
    assert set(SDL_LIGHT) == {t.name for t in LIGHT_TYPES}
    effect_fields = {f.name for f in dataclasses.fields(Effects)}
    assert set(LIGHT_EFFECTS) == {"fade", "spotlights", "area_lights", "parallel_lights"} <= effect_fields


@pytest.mark.parametrize("light_type", LIGHT_TYPES, ids=lambda t: t.name)
def test_a_light_turns_on_exactly_the_effects_its_type_declares(light_type):
    scene = _scene(SDL_LIGHT[light_type.name])
    (light,) = scene.lights
    assert light_type.present(light)
    effects = rt.plan(scene).effects
    assert {e for e in LIGHT_EFFECTS if getattr(effects, e)} == set(light_type.effects)
    assert light_effects(scene.lights) == {e: e in light_type.effects for e in LIGHT_EFFECTS}
    if light_type.rendered_as is not None:
        assert [w.feature for w in scene.warnings] == [f"{light_type.name} light"]


def test_a_shadowless_area_light_needs_no_area_sampling():
    scene = _scene("light_source { <0, 5, -5> rgb 1 area_light x, z, 2, 2 shadowless }")
    assert light_effects(scene.lights)["area_lights"] is False


def test_effects_of_several_lights_are_the_union_of_their_types():
    lights = (_scene(SDL_LIGHT["spotlight"]).lights + _scene(SDL_LIGHT["fade"]).lights)
    assert light_effects(lights) == {"fade": True, "spotlights": True, "area_lights": False,
                                     "parallel_lights": False}
    assert light_effects(()) == dict.fromkeys(LIGHT_EFFECTS, False)


def test_defaults_are_povray_s_in_the_parser_and_the_scene_model():
    # POV-Ray 3.7 manual, "Spotlights" and "Point Lights": radius 30, falloff 45, tightness 0 (degrees);
    # white; point_at <0, 0, 1>
    (spot,) = _scene("light_source { <0, 5, -5> spotlight }").lights
    for light in (spot, rt.Light(position=(0.0, 5.0, -5.0), spot=rt.Spot())):
        np.testing.assert_array_equal(light.color, [1.0, 1.0, 1.0])
        np.testing.assert_array_equal(light.point_at, [0.0, 0.0, 1.0])
        assert (float(light.spot.radius_degrees), float(light.spot.falloff_degrees),
                float(light.spot.tightness)) == (30.0, 45.0, 0.0)


def test_every_light_keyword_comes_from_one_type_and_parses():
    # LIGHT_SDL_KEYWORDS is derived from LIGHT_TYPES: each item below is read by the parser through
    # its type's declaration, and lands on the Light field the type lowers it to.
    assert set(LIGHT_SDL_KEYWORDS) == {k for t in LIGHT_TYPES for k in t.sdl_keywords}
    (light,) = _scene("light_source { <0, 5, -5> rgb 1 spotlight radius 10 falloff 20 tightness 5 "
                      "fade_distance 3 fade_power 2 area_light x, 2*z, 3, 2 circular orient adaptive 1 "
                      "jitter area_illumination on parallel shadowless point_at <0, 0, 1> }").lights
    assert (float(light.spot.radius_degrees), float(light.spot.falloff_degrees),
            float(light.spot.tightness)) == (10.0, 20.0, 5.0)
    assert (float(light.fade_distance), float(light.fade_power)) == (3.0, 2.0)
    assert (light.area.size1, light.area.size2, light.area.circular, light.area.orient) == (3, 2, True, True)
    assert light.parallel and light.shadowless


def test_area_light_options_without_area_light_leave_a_point_light():
    # POV-Ray's advanced/diffract.pov gives adaptive and jitter outside its #if (Area_Light)
    (light,) = _scene("light_source { <0, 5, -5> rgb 1 adaptive 1 jitter circular orient }").lights
    assert light.area is None and light.spot is None and not light.parallel


def test_area_light_axes_and_position_follow_the_light_transform():
    # rotate 90*y (left-handed, POV-Ray): x -> -z, z -> x
    (light,) = _scene("light_source { <0, 5, -5> rgb 1 area_light x, 2*z, 3, 2 rotate 90*y }").lights
    np.testing.assert_allclose(light.area.axis1, [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(light.area.axis2, [2, 0, 0], atol=1e-12)
    np.testing.assert_allclose(light.position, [-5, 5, 0], atol=1e-12)


def test_light_items_that_change_nothing_are_warned():
    scene = _scene("light_source { <0, 5, -5> rgb 1 area_light x, z, 3, 3 adaptive 1 jitter orient "
                   "area_illumination on }")
    warned = " ".join(str(w) for w in scene.warnings)
    assert all(f"[{kw}]" in warned for kw in ("jitter", "orient", "area_illumination")), warned
    assert len(scene.warnings) == 3  # adaptive and the grid are simulated
    quiet = _scene("light_source { <0, 5, -5> rgb 1 area_light x, z, 3, 3 circular area_illumination off }")
    assert not quiet.warnings


def test_an_area_grid_too_large_to_hold_is_a_located_error():
    """An area light's penumbra points trace their whole grid at once, so a grid the renderer
    cannot hold (1024×1024 ran out of memory) is refused where it is written, in the SDL and in
    the Python API, and the largest grid it holds loads."""
    from raytracer.scene._lights import MAX_AREA_SAMPLES
    from raytracer.sdl import SceneError

    with pytest.raises(SceneError, match=r"^<string>:3:20: an area_light grid of 512×300 = 153,600"):
        _scene("light_source { <0, 5, -5> rgb 1\n  area_light x, z, 512, 300 adaptive 1 }")
    assert _scene("light_source { <0, 5, -5> rgb 1 area_light x, z, 256, 256 adaptive 1 }").lights
    assert 256 * 256 == MAX_AREA_SAMPLES
    with pytest.raises(ValueError, match="300×512"):
        rt.AreaLight((1.0, 0, 0), (0, 0, 1.0), 300, 512)
