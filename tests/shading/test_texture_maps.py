"""Patterned textures (``texture_map``, a block pattern's textures, ``tiles``): a pattern chooses
whole textures, each shaded in full, and their colours are blended (semantics §5.7).

Held against: weights worked out by hand from each pattern's value, the blend rule of POV-Ray's
manual (3.4.6.5.1: both textures computed in their entirety, reflection and refraction included,
then their colours interpolated) checked pixel by pixel, central differences in float64, and
POV-Ray's images (``examples/scenes/texture_map.pov`` is in the validation suite).
"""

import types

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.sdl import SceneError, load_scene
from raytracer.shading._materials import pack_textures, texture_choice

RED, GREEN, BLUE = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _plain(rgb):
    return rt.Texture.of(rt.Pigment.solid(rgb))


def _choices(texture, points):
    packed = jax.tree_util.tree_map(jnp.asarray, pack_textures([types.SimpleNamespace(texture=texture)],
                                                               jnp.float64))
    choose = jax.jit(jax.vmap(lambda q: texture_choice(packed, 0, q)))
    leaves, weights = choose(jnp.asarray(points, jnp.float64))
    return np.asarray(leaves), np.asarray(weights)


def test_a_texture_map_weighs_the_two_textures_around_the_value_and_nests(x64):
    # hexagon (in x-z) lists: entry 0 red; entry 1 a gradient-x map [0.2 green][0.8 blue]. At the
    # origin hexagon's value is 0; at (0.5, 0, 1.2) and (0.3, 0, 1.2) it is 1 (the cell above),
    # where gradient x is 0.5 (half green, half blue) and 0.3 (5/6 green). The leaves are numbered in
    # the tree's depth-first order: red 0, green 1, blue 2.
    inner = rt.Texture.of_map("gradient", [(0.2, _plain(GREEN)), (0.8, _plain(BLUE))], vector=(1.0, 0.0, 0.0))
    outer = rt.Texture.of_map("hexagon", [(0.0, _plain(RED)), (1.0, inner), (2.0, _plain(RED))])
    leaves, weights = _choices(outer, [(0.0, 0.0, 0.0), (0.5, 0.0, 1.2), (0.3, 0.0, 1.2)])
    assert leaves.shape == (3, 4) and outer.depth == 2
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=1e-12)

    def weight_of(k, leaf):
        return weights[k][leaves[k] == leaf].sum()

    assert weight_of(0, 0) == 1.0
    np.testing.assert_allclose([weight_of(1, 1), weight_of(1, 2)], [0.5, 0.5], rtol=1e-12)
    np.testing.assert_allclose([weight_of(2, 1), weight_of(2, 2)], [5 / 6, 1 / 6], rtol=1e-12)


# a plane facing the camera, seen orthographically over x in [0, 1]; the texture map blends by x
_SCENE = """
#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
background {{ rgb <0.2, 0.4, 0.6> }}
camera {{ orthographic location <0.5, 0.5, -5> look_at <0.5, 0.5, 0> right x up 0.25*y }}
light_source {{ <-1, 2, -10> rgb 1 }}
plane {{ -z, 0 texture {{ gradient x texture_map {{ [0.2 {a}] [0.8 {b}] }} }} }}
"""
# one reflects the background, the other lets it through: both are written with every term, so
# the three scenes below are one program with other values
_MIRROR = "pigment { rgbf <0.9, 0.3, 0.2, 0> } finish { phong 0.7 reflection 0.3 diffuse 0.5 }"
_CLEAR = "pigment { rgbf <0.3, 0.9, 0.5, 0.6> } finish { phong 0 reflection 0 diffuse 0.4 }"


def _render(a, b):
    text = _SCENE.format(a=a, b=b)
    return np.asarray(rt.render(load_scene(text, width=16, height=4), width=16, height=4))


@pytest.mark.slow  # three renders of one program
def test_each_texture_is_shaded_in_full_and_the_colours_blend(x64):
    # POV-Ray's rule (manual 3.4.6.5.1): the colour is (1 - s)·C_a + s·C_b with C each texture's own
    # colour there, its reflected and transmitted light included; s = (x - 0.2)/0.6 clipped
    mixed, only_a, only_b = _render(_MIRROR, _CLEAR), _render(_MIRROR, _MIRROR), _render(_CLEAR, _CLEAR)
    x = (np.arange(16) + 0.5) / 16
    s = np.clip((x - 0.2) / 0.6, 0.0, 1.0)[None, :, None]
    np.testing.assert_allclose(mixed, (1 - s) * only_a + s * only_b, rtol=1e-10, atol=1e-12)
    assert np.ptp(only_a - only_b) > 0.1  # (the two textures do differ)


@pytest.mark.slow  # compiles a forward-mode render
def test_the_gradient_reaches_an_entrys_finish_and_the_patterns_space(x64):
    scene = load_scene(_SCENE.format(a=_MIRROR, b=_CLEAR), width=8, height=2)
    diffuse = "objects[0].texture.entries[1].layers[0].finish.diffuse"
    matrix = "objects[0].texture.pattern.transform.matrix"
    assert matrix not in rt.params.parameters(scene)  # (no transform written: give it one)
    scene = eqx.tree_at(lambda s: s.objects[0].texture.pattern.transform, scene, rt.Transform(np.eye(4)),
                        is_leaf=lambda x: x is None)

    def image(params):
        m = jnp.eye(4).at[0, 0].set(params[1])
        return rt.render(rt.params.replace(scene, {diffuse: params[0], matrix: m}), width=8, height=2)

    params = jnp.array([0.4, 1.1])
    for i in range(2):
        t = jnp.zeros(2).at[i].set(1.0)
        _, jvp = jax.jvp(image, (params,), (t,))
        h = 1e-6
        fd = (image(params + h * t) - image(params - h * t)) / (2 * h)
        assert np.all(np.isfinite(jvp)) and np.max(np.abs(jvp)) > 1e-3
        np.testing.assert_allclose(jvp, fd, rtol=1e-5, atol=1e-8)


def test_the_sdl_reads_texture_maps_block_lists_and_tiles():
    s = load_scene("""
        #declare T = texture { pigment { rgb 1 } finish { phong 1 } }
        #declare M = texture_map { [0.1 T] [0.9 pigment { rgb <1, 0, 0> }] }
        plane { y, 0 texture { bozo texture_map { M } scale 2 } }
        box { 0, 1 texture { checker texture { T }, texture { pigment { rgb 0.5 } } scale 3 } }
        sphere { 0, 1 texture { tiles { texture { T } tile2 texture { pigment { rgb 0 } } } } }
        sphere { 0, 1 texture { brick texture { T } } }
    """)
    assert s.warnings == ()
    bozo, checker, tiles, brick = (o.texture for o in s.objects)
    assert bozo.pattern.pattern == "bozo" and np.allclose(bozo.pattern.values, [0.1, 0.9])
    assert bozo.entries[0].layers[0].finish.phong is not None  # T, by its identifier
    # the texture's scale moves its pattern and the textures read before it
    np.testing.assert_allclose(np.asarray(checker.pattern.transform.matrix)[:3, :3], 3 * np.eye(3))
    assert checker.pattern.frequency == 0 and len(checker.entries) == 2
    # tiles' texture sits where a checker's second does (measured with povray)
    assert tiles.pattern.pattern == "checker" and tiles.entries[1].layers[0].finish.phong is not None
    assert len(brick.entries) == 2  # the list filled with the default texture
    # the first plain texture is what the layers hold (shadow rays and other readers)
    assert checker.layers is checker.entries[0].layers


def test_an_average_weighs_every_texture_by_its_position(x64):
    # average texture_map [1 red] [3 green] [(1) blue]: 1/5, 3/5, 1/5 wherever the point is
    s = load_scene("""sphere { 0, 1 texture { average texture_map {
        [1 pigment { rgb <1, 0, 0> }] [3 pigment { rgb <0, 1, 0> }] [pigment { rgb <0, 0, 1> }] } } }""")
    tex = s.objects[0].texture
    assert s.warnings == () and [float(v) for v in tex.pattern.values] == [1.0, 3.0, 1.0]
    leaves, weights = _choices(tex, [(0.3, -2.0, 7.0)])
    assert leaves.shape == (1, 3)
    got = [weights[0][leaves[0] == k].sum() for k in range(3)]
    np.testing.assert_allclose(got, [0.2, 0.6, 0.2], rtol=1e-12)


def test_what_is_approximated_is_warned_and_a_patterned_texture_needs_its_textures():
    s = load_scene("""
        #declare O = sphere { 0, 1 }
        sphere { 0, 1 texture { object { O texture { pigment { rgb <1, 0, 0> } },
                                         texture { pigment { rgb 0 } } } } }
        sphere { 0, 1 texture { material_map { png "none.png" texture { pigment { rgb <1, 0, 0> } } } } }
    """)
    assert [w.feature for w in s.warnings] == ["object", "material_map"]
    assert not any(o.texture.patterned for o in s.objects)
    for o in s.objects:
        np.testing.assert_allclose(np.asarray(o.texture.layers[0].pigment.colors)[0, :3], RED)
    with pytest.raises(SceneError) as e:
        load_scene("sphere { 0, 1 texture {\n checker scale 2 } }")
    assert e.value.location.line == 2 and "textures of patterned texture 'checker'" in str(e.value)


@pytest.mark.parametrize("scene, message", [
    ("sphere { 0, 1 texture { C }\n texture { pigment { rgbt 1 } } }", "cannot layer over a patterned"),
    ("sphere { 0, 1 texture { pigment { rgbt 1 } }\n texture { C } }", "cannot layer a patterned texture"),
    ("#declare L = texture { pigment { rgbt 1 } }\n texture { C }", "cannot layer a patterned texture over"),
    ("#default {\n texture { C } }", "a default texture cannot be a patterned texture"),
    ("sphere { 0, 1 material { texture { C }\n texture { pigment { rgbt 1 } } } }", "cannot layer over"),
], ids=["over", "under", "declared", "default", "material"])
def test_a_patterned_texture_is_no_layer_and_no_default_as_in_povray(scene, message):
    checker = "#declare C = texture { checker texture { pigment { rgb 1 } } texture { pigment { rgb 0 } } }\n"
    with pytest.raises(SceneError) as e:
        load_scene(checker + scene)
    assert e.value.location.line == 3 and message in str(e.value)
