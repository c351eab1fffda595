"""``image_map``: an image wrapped over pattern space (semantics §5.6).

Held against: the pixel each point takes worked out by hand (POV-Ray's rules, measured with
``povray``), bilinear weights by hand, central differences, and POV-Ray's images
(``examples/scenes/image_map.pov`` is in the validation suite).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from PIL import Image

import raytracer as rt
from raytracer.imageio import srgb_decode
from raytracer.sdl import SceneError, load_scene
from raytracer.shading._materials import pack_pigments, pigment_at

# a 4 × 3 image, top row first; its pixel (row r, column c) is PIXELS[r, c]
PIXELS = np.arange(12 * 5, dtype=np.float64).reshape(3, 4, 5) / 60.0


def _image_pigment(pixels=PIXELS, **kwargs):
    return rt.Pigment("image_map", values=[0.0], colors=np.zeros((1, 5)), transparent=True,
                      image=rt.ImageMap(pixels, **kwargs))


def _at(pigment, points):
    mats = jax.tree_util.tree_map(jnp.asarray, pack_pigments([pigment], jnp.float64))
    evaluate = jax.jit(jax.vmap(lambda m, q: pigment_at(m, 0, q), in_axes=(None, 0)))
    return np.asarray(evaluate(mats, jnp.asarray(points, jnp.float64)))


def test_a_planar_image_tiles_the_xy_plane_from_its_top_row_down(x64):
    # u = frac(x), v = frac(y); column floor(4u), row floor(3(1 − v)) from the top; z plays no part
    got = _at(_image_pigment(), [(0.1, 0.9, 5.0), (0.6, 0.5, 0.0), (-0.1, -0.2, 0.0), (2.99, 1.01, 0.0)])
    np.testing.assert_allclose(got, PIXELS[[0, 1, 0, 2], [0, 2, 3, 3]])


def test_bilinear_blends_the_four_pixel_centres_around_the_point_wrapping_at_the_edges(x64):
    # x = 0.05: 0.2 − 0.5 = −0.3 pixels: 0.3 of column 3 (wrapped), 0.7 of column 0; y = 0.9: row
    # 3·0.1 − 0.5 = −0.2: 0.2 of row 2 (wrapped), 0.8 of row 0
    got = _at(_image_pigment(interpolate=2), [(0.05, 0.9, 0.0)])[0]
    top = 0.3 * PIXELS[0, 3] + 0.7 * PIXELS[0, 0]
    bottom = 0.3 * PIXELS[2, 3] + 0.7 * PIXELS[2, 0]
    np.testing.assert_allclose(got, 0.8 * top + 0.2 * bottom, rtol=1e-12)


def test_spherical_and_cylindrical_maps_wrap_around_y_from_plus_x_and_once_clears_the_rest(x64):
    # spherical: u = atan2(z, x)/2π, v = latitude/π + ½; cylindrical: the same u, v = frac(y)
    s = 1 / np.sqrt(2)
    sphere = _at(_image_pigment(map_type=1), [(s, 0.0, s), (0.0, 1.0, 0.0), (-1.0, -0.3, 0.0)])
    # (⅛ turn, equator): column 0, row 1; the north pole: row 0; −x, below: column 2, row 1
    np.testing.assert_allclose(sphere, PIXELS[[1, 0, 1], [0, 0, 2]])
    cylinder = _at(_image_pigment(map_type=2, once=True), [(0.0, 0.5, -2.0), (1.0, 1.5, 0.0)])
    # −z is ¾ turn: column 3, row 1; above the unit height with once: clear
    np.testing.assert_allclose(cylinder, [PIXELS[1, 3], (0, 0, 0, 0, 1)])


def test_the_sdl_reads_an_image_as_povray_decodes_it(tmp_path):
    rgba = np.array([[[255, 128, 0, 255], [10, 20, 30, 64]]], np.uint8)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "i.png")
    scene = tmp_path / "s.pov"
    scene.write_text('sphere { 0, 1 pigment { image_map { png "i.png" once interpolate 2 } } }\n'
                     'sphere { 0, 1 pigment { image_map { "i.png" gamma 1.0 transmit all 0.25 } } }\n')
    a, b = (o.texture.layers[0].pigment for o in load_scene(scene).objects)
    assert a.pattern == "image_map" and a.image.once and a.image.interpolate == 2 and a.transparent
    # 8-bit files are sRGB-decoded unless a gamma is given; alpha is transmit 1 − alpha
    np.testing.assert_allclose(np.asarray(a.image.pixels)[0, :, :3], srgb_decode(rgba[0, :, :3] / 255.0),
                               rtol=1e-6)
    np.testing.assert_allclose(np.asarray(a.image.pixels)[0, :, 4], [0.0, 1 - 64 / 255], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(b.image.pixels)[0, :, :3], rgba[0, :, :3] / 255.0, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(b.image.pixels)[0, :, 4], [0.25, 1.25 - 64 / 255], rtol=1e-6)
    scene.write_text('sphere { 0, 1 pigment {\n image_map { png "missing.png" } } }')
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    assert e.value.location.line == 2 and 'expected an image file, found no "missing.png"' in str(e.value)


def test_the_gradient_reaches_every_pixel_an_interpolated_point_reads(x64):
    # inverse texturing: the colour is linear in the four pixels around the point
    point = jnp.array([0.3, 0.4, 0.0])

    def colour(pixels):
        return pigment_at(jax.tree_util.tree_map(jnp.asarray, pack_pigments(
            [_image_pigment(pixels, interpolate=2)], jnp.float64)), 0, point)[:3]

    jac = np.asarray(jax.jacrev(colour)(jnp.asarray(PIXELS)))  # (3, 3, 4, 5)
    assert np.all(np.isfinite(jac))
    touched = np.argwhere(np.abs(jac[0, :, :, 0]) > 0)
    assert len(touched) == 4  # x = 0.7 pixel (columns 0, 1), y = 1.3 (rows 1, 2)
    assert {tuple(t) for t in touched} == {(1, 0), (1, 1), (2, 0), (2, 1)}
    np.testing.assert_allclose(jac[0, :, :, 0].sum(), 1.0, rtol=1e-12)
