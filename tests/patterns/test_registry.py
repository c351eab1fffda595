"""The pattern registry is the single source: every registered pattern parses, lowers, plans and
evaluates (or, if parsed only, warns where it is written); the scene model, the plan, the shader and
the parser hold no list of their own; an unregistered name is an error, not a silent default."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
import raytracer.patterns as P
from raytracer import _plan
from raytracer.sdl import SceneError, load_scene
from raytracer.sdl import _textures as sdl_textures


def _sdl_pigment(record: P.Pattern) -> str:
    """The pigment block of a scene that uses ``record``'s keyword with arguments of its kind."""
    argument = {None: "", "vector": " <1, 2, 0.5>", "values": " 3", "file": ' df3 "none.df3"'}
    colours = "".join(f" rgb {i / max(1, record.colours - 1)}," for i in range(record.colours))
    return f"pigment {{ {record.name}{argument[record.argument]}{colours.rstrip(',')} }}"


def _load(pigment: str):
    return load_scene("camera { location <0, 0, -3> look_at 0 }\n"
                      "light_source { <0, 5, -5> rgb 1 }\n"
                      f"plane {{ z, 0 {pigment} }}\n")


KEYWORDS = sorted(P.SDL_KEYWORDS)


def test_every_table_is_derived_from_the_registry():
    assert rt.PATTERNS == rt.scene.PATTERNS == P.NAMES == tuple(P.REGISTRY)
    assert rt.WAVES == P.WAVES
    assert _plan.SUPPORTED_PATTERNS == P.RENDERED
    assert set(sdl_textures.WAVE_KEYWORDS.values()) == set(P.WAVES)
    assert P.SDL_KEYWORDS <= sdl_textures.TEXTURE_PATTERNS
    assert P.SDL_KEYWORDS == set(P.NAMES) - {"solid"}
    assert {"checker", "hexagon", "brick"} == P.DISCRETE
    # the discrete patterns' colour lists, as the POV-Ray manual gives them
    assert {n: P.REGISTRY[n].colours for n in P.DISCRETE} == {"checker": 2, "hexagon": 3, "brick": 2}


# (image_map reads a file: tests/test_image_map.py)
@pytest.mark.parametrize("name", [n for n in KEYWORDS if P.REGISTRY[n].rendered and not P.REGISTRY[n].imaged])
def test_every_rendered_pattern_parses_lowers_plans_and_evaluates(name):
    record = P.REGISTRY[name]
    scene = _load(_sdl_pigment(record))
    assert scene.warnings == ()
    pigment = scene.objects[0].texture.layers[0].pigment
    assert pigment.pattern == name
    assert pigment.wave == record.default_wave
    plan = rt.plan(scene)
    assert name in plan.effects.patterns and plan.warnings == ()
    if record.discrete:  # the listed colours sit at the indices the pattern evaluates to
        np.testing.assert_array_equal(pigment.values, np.arange(record.colours))
        np.testing.assert_allclose(pigment.colors[:, 0], np.linspace(0.0, 1.0, record.colours))
        assert float(pigment.frequency) == 0.0
    if record.argument == "vector":
        np.testing.assert_array_equal(pigment.vector, [1.0, 2.0, 0.5])
    values = [float(P.pattern_value(name, jnp.asarray(q, jnp.float32), pigment.vector, None))
              for q in ((0.3, 0.2, 0.1), (-1.7, 2.4, 0.9), (0.0, 0.0, 0.0))]
    assert np.all(np.isfinite(values))
    if record.discrete:
        assert set(values) <= set(range(record.colours))


@pytest.mark.parametrize("name", [n for n in KEYWORDS if not P.REGISTRY[n].rendered])
def test_a_parsed_only_pattern_warns_where_it_is_written_and_renders_a_neutral_colour(name):
    scene = _load(_sdl_pigment(P.REGISTRY[name]))
    (warning,) = scene.warnings
    assert warning.feature == name and warning.location.line == 3
    pigment = scene.objects[0].texture.layers[0].pigment
    assert pigment.pattern == "solid"
    np.testing.assert_allclose(pigment.colors, [[0.5, 0.5, 0.5, 0.0, 0.0]])


def test_strict_loading_turns_a_parsed_only_pattern_into_an_error():
    with pytest.raises(SceneError, match="quilted"):
        load_scene("plane { y, 0 pigment { quilted } }", strict=True)


def test_a_parsed_only_pattern_built_through_the_api_is_a_plan_warning_and_its_first_colour():
    pigment = rt.Pigment.mapped("spiral1", [(0.0, (0.2, 0.4, 0.6)), (1.0, (1.0, 1.0, 1.0))])
    texture = rt.Texture.of(pigment, rt.Finish(ambient=1.0, diffuse=0.0))
    scene = rt.Scene(camera=rt.Camera(location=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0)),
                     objects=(rt.Object(rt.Plane((0.0, 0.0, 1.0), 0.0), texture=texture),))
    (warning,) = rt.plan(scene).warnings
    assert warning.feature == "spiral1" and "not rendered" in warning.message
    image = np.asarray(rt.render(scene, width=4, height=3))
    np.testing.assert_allclose(image, np.broadcast_to([0.2, 0.4, 0.6], image.shape), atol=1e-6)


def test_an_unregistered_pattern_is_an_error_in_the_model_the_evaluator_and_the_parser():
    with pytest.raises(ValueError, match="unknown pattern 'swirl'"):
        rt.Pigment.mapped("swirl", [(0.0, (0.0, 0.0, 0.0))])
    with pytest.raises(ValueError, match="unknown pattern 'swirl'"):
        P.pattern_value("swirl", jnp.zeros(3), jnp.ones(3), None)
    with pytest.raises(ValueError, match="not rendered"):
        P.pattern_value("quilted", jnp.zeros(3), jnp.ones(3), None)
    with pytest.raises(SceneError, match="swirl"):
        load_scene("plane { y, 0 pigment { swirl } }")


def test_pattern_modifiers_default_to_povray_values_and_reach_the_evaluator():
    assert dict(P.REGISTRY["brick"].modifiers) == {"brick_size": (8.0, 3.0, 4.5), "mortar": 0.5}
    assert dict(P.REGISTRY["agate"].modifiers) == {"agate_turb": 1.0}
    # (1, 1, 1) is inside a default brick (z + 2.25 = 3.25 < 4.5 - 0.5); a 3-unit mortar covers it
    p = jnp.array([1.0, 1.0, 1.0])
    assert float(P.pattern_value("brick", p, jnp.ones(3), None)) == 1.0
    assert float(P.pattern_value("brick", p, jnp.ones(3), None, mortar=3.0)) == 0.0
    with pytest.raises(ValueError, match="no modifier mortar"):
        P.pattern_value("checker", p, jnp.ones(3), None, mortar=3.0)


def test_a_pattern_modifier_in_sdl_is_parsed_and_reported_as_ignored():
    scene = _load("pigment { brick rgb 0, rgb 1 brick_size <2, 1, 1> mortar 0.1 }")
    assert [w.feature for w in scene.warnings] == ["brick_size", "mortar"]
    assert scene.objects[0].texture.layers[0].pigment.pattern == "brick"


def test_the_registry_refuses_a_discrete_pattern_whose_map_is_not_at_its_indices():
    with pytest.raises(ValueError, match="indices"):
        P.Pattern("tri", lambda p, inputs: p[0], colours=2,
                  default_map=((0.0, (0.0,) * 5), (0.5, (1.0,) * 5)))
