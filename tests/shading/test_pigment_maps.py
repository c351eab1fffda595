"""Pigment maps (``pigment_map``, a discrete pattern's pigment list): the pigments at the map's
positions, each evaluated at the point and blended as a colour map blends colours (semantics §5.2).

Held against: colours worked out by hand from each entry's own pattern, central differences in
float64, and POV-Ray's images (``examples/scenes/pigment_maps.pov`` is in the validation suite).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.sdl import SceneError, load_scene
from raytracer.shading._materials import pack_pigments, pigment_at

RED, BLUE = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)


def _stripes(c0, c1):
    """gradient x mapped black-body from c0 at 0 to c1 at 1 (no wave, no transform)."""
    return rt.Pigment.mapped("gradient", [(0.0, c0), (1.0, c1)], vector=(1.0, 0.0, 0.0))


def _packed(pigment):
    return jax.tree_util.tree_map(jnp.asarray, pack_pigments([pigment], jnp.float64))


def _at(pigment, points):
    evaluate = jax.jit(jax.vmap(lambda m, q: pigment_at(m, 0, q), in_axes=(None, 0)))
    return np.asarray(evaluate(_packed(pigment), jnp.asarray(points, jnp.float64)))


def test_a_pigment_map_blends_the_pigments_around_the_value_each_at_the_point(x64):
    # gradient y chooses: below 0.3 solid red; 0.3–0.7 red → stripes blended by (y − 0.3)/0.4;
    # above 0.7 the stripes (gradient x from blue to white), evaluated at the point's own x
    stripes = _stripes(BLUE, (1.0, 1.0, 1.0))
    mapped = rt.Pigment.of_map("gradient", [(0.3, rt.Pigment.solid(RED)), (0.7, stripes)],
                               vector=(0.0, 1.0, 0.0))
    points = [(0.25, 0.1, 0.0), (0.25, 0.5, 0.0), (0.6, 0.9, 0.0), (0.8, 0.6, 0.0)]
    got = _at(mapped, points)[:, :3]
    blue_white = lambda x: np.array(BLUE) * (1 - x) + x  # noqa: E731
    want = [RED, 0.5 * np.array(RED) + 0.5 * blue_white(0.25), blue_white(0.6),
            0.25 * np.array(RED) + 0.75 * blue_white(0.8)]
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_a_checker_of_pigments_shows_each_cells_pigment_and_nested_maps_recurse(x64):
    inner = rt.Pigment.of_map("gradient", [(0.0, rt.Pigment.solid(BLUE)), (1.0, _stripes(RED, BLUE))],
                              vector=(0.0, 0.0, 1.0))
    checker = rt.Pigment.of_map("checker", [(0.0, rt.Pigment.solid((0.0, 1.0, 0.0))), (1.0, inner)],
                                frequency=0.0)
    got = _at(checker, [(0.5, 0.5, 0.5), (1.5, 0.5, 0.25)])[:, :3]
    # cell (0,0,0) lists entry 0; cell (1,0,0) entry 1: at z = 0.25 a quarter of the stripes at x = 1.5
    stripes = np.array(RED) * 0.5 + np.array(BLUE) * 0.5
    np.testing.assert_allclose(got, [(0.0, 1.0, 0.0), 0.75 * np.array(BLUE) + 0.25 * stripes], atol=1e-12)


def test_the_sdl_reads_pigment_maps_declared_nested_and_listed():
    s = load_scene("""
        #declare M = pigment_map { [0 rgb 1] [1 gradient x color_map { [0 rgb 0] [1 rgbf 1] } scale 2] }
        sphere { 0, 1 pigment { bozo pigment_map { M } scale 3 } }
        sphere { 0, 1 pigment { brick pigment { rgb 1 } pigment { agate } } }
    """)
    assert s.warnings == ()
    bozo, brick = (o.texture.layers[0].pigment for o in s.objects)
    assert bozo.pattern == "bozo" and [e.pattern for e in bozo.entries] == ["solid", "gradient"]
    assert bozo.transparent  # an entry carries filter
    # the entry's own scale, then the outer pigment's
    np.testing.assert_allclose(np.asarray(bozo.entries[1].transform.matrix)[:3, :3], 6 * np.eye(3))
    assert [e.pattern for e in brick.entries] == ["solid", "agate"] and not brick.transparent
    with pytest.raises(SceneError) as e:
        load_scene("#declare P = pigment { rgb 1 }\nsphere { 0, 1 pigment { bozo pigment_map {\n P } } }")
    assert e.value.location.line == 3 and "expected a pigment_map" in str(e.value)


def test_the_gradient_reaches_a_map_entrys_colour_and_its_transform(x64):
    def colour(params):
        c, scale = params[:3], params[3]
        colors = jnp.stack([jnp.concatenate([c, jnp.zeros(2)]), jnp.array([1.0, 1.0, 1.0, 0.0, 0.0])])
        stripes = rt.Pigment("gradient", values=jnp.array([0.0, 1.0]), colors=colors, vector=(1.0, 0.0, 0.0),
                             transform=rt.Transform(jnp.diag(jnp.array([scale, 1.0, 1.0, 1.0]))))
        mapped = rt.Pigment.of_map("gradient", [(0.2, rt.Pigment.solid(RED)), (0.8, stripes)],
                                   vector=(0.0, 1.0, 0.0))
        mats = _packed(mapped)
        return pigment_at(mats, 0, jnp.array([0.7, 0.45, 0.0]))[:3]

    colour = jax.jit(colour)
    params = jnp.array([0.2, 0.4, 0.6, 1.3])
    jac = jax.jit(jax.jacfwd(colour))(params)
    assert np.all(np.isfinite(jac)) and np.all(np.abs(jac[:, 3]) > 0)
    step = 1e-6
    for i in range(4):
        e = jnp.zeros(4).at[i].set(step)
        np.testing.assert_allclose(jac[:, i], (colour(params + e) - colour(params - e)) / (2 * step),
                                   rtol=1e-6, atol=1e-9)


def test_average_is_the_mean_of_its_pigments_weighted_by_their_positions(x64):
    averaged = rt.Pigment.of_map("average", [(1.0, rt.Pigment.solid(RED)), (3.0, _stripes(BLUE, RED))])
    got = _at(averaged, [(0.25, 0.0, 0.0)])[0, :3]
    np.testing.assert_allclose(got, (np.array(RED) + 3 * (0.75 * np.array(BLUE) + 0.25 * np.array(RED))) / 4,
                               atol=1e-12)
    s = load_scene("sphere { 0, 1 pigment { average pigment_map { [2 rgb 1] [bozo] } } }")
    assert [float(v) for v in s.objects[0].texture.layers[0].pigment.values] == [2.0, 1.0]  # unwritten: 1


@pytest.mark.parametrize("modifiers, index_values", [
    ("", (0.0, 1.0, 2.0)),  # the index itself
    ("phase 0.3", (0.0, 1.0, 2.0)),  # phase alone changes nothing
    ("frequency 1", (0.0, 1.0, 2.0 - 2 * 1.00001 + 1.00001)),  # written: fmod(2, 1.00001), ≈ entry 1
    ("frequency 0.5 phase 0.25", (0.25, 0.75, 1.25 - 1.00001)),
], ids=["plain", "phase", "frequency-1", "frequency-and-phase"])
def test_a_discrete_pattern_wraps_its_index_only_where_a_frequency_is_written(x64, modifiers, index_values):
    # measured with povray (hexagon red, green, blue on a plane): without `frequency` the cell shows
    # its colour whatever the phase; with it, fmod(index·frequency + phase, 1.00001) picks the colours
    # as a colour map at 0, 1, 2 would (`frequency 1`: the third cell shows green, not blue)
    hexagon = "hexagon rgb <1, 0, 0>, rgb <0, 1, 0>, rgb <0, 0, 1>"
    s = load_scene(f"plane {{ y, 0 pigment {{ {hexagon} {modifiers} }} }}")
    pigment = s.objects[0].texture.layers[0].pigment
    got = _at(pigment, [(0.0, 0.0, 0.0), (0.5, 0.0, 1.2), (0.9, 0.0, 1.2)])[:, :3]
    colours = np.eye(3)

    def entry(v):
        i = min(int(np.floor(v)), 1)
        return colours[i] * (1 - (v - i)) + colours[i + 1] * (v - i) if v < 2 else colours[2]

    np.testing.assert_allclose(got, [entry(v) for v in index_values], atol=1e-9)
