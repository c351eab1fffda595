"""The fisheye, spherical and cylindrical cameras against POV-Ray: every pixel's ray direction read
from POV-Ray's render of a sky_sphere that colours each direction (its x, y, z in the red, green
and blue of three gradients), the moving eyes of cylinders 3 and 4 from a plane that colours each
place; a fisheye's corners black; their errors and their refusal of the boundary term."""

import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.shading.camera import camera_rays, camera_sees, sample_coords

W, H = 32, 24
HEAD = "#version 3.7; global_settings { assumed_gamma 1.0 }\n"
# (x + 1)/2, (y + 1)/2, (z + 1)/2 of a ray's unit direction as its colour (three gradients averaged)
DIRECTIONS = """sky_sphere { pigment { average pigment_map {
  [1 gradient x color_map { [0 rgb 0] [1 rgb <3,0,0>] } scale 2.00001 translate -1.000005*x]
  [1 gradient y color_map { [0 rgb 0] [1 rgb <0,3,0>] } scale 2.00001 translate -1.000005*y]
  [1 gradient z color_map { [0 rgb 0] [1 rgb <0,0,3>] } scale 2.00001 translate -1.000005*z] } } }"""
# (x + 20)/40 and (y + 20)/40 of the point where a ray meets the plane z = 10, in red and green
PLACES = """plane { z, 10 finish { ambient 1 diffuse 0 } pigment { average pigment_map {
  [1 gradient x color_map { [0 rgb 0] [1 rgb <2,0,0>] } scale 40.0001 translate -20.00005*x]
  [1 gradient y color_map { [0 rgb 0] [1 rgb <0,2,0>] } scale 40.0001 translate -20.00005*y] } } }"""
LOOK = "location <1, 2, -3> look_at <0, 2.5, 1>"
CAMERAS = [
    f"fisheye angle 180 {LOOK}",
    f"fisheye angle 270 up 0.8*y right 1.2*x {LOOK}",
    f"fisheye {LOOK}",
    f"spherical {LOOK}",
    f"spherical angle 200, 70 {LOOK}",
    f"cylinder 1 angle 120 up 2*y {LOOK}",
    f"cylinder 2 angle 100 right 2*x {LOOK}",
    f"cylinder 3 angle 200 up 4*y {LOOK}",
    f"cylinder 4 angle 90 right 3*x direction 2*z {LOOK}",
]


def _ours(camera_text):
    scene = rt.load_scene(HEAD + f"camera {{ {camera_text} }}\n" + DIRECTIONS, width=W, height=H)
    coords = sample_coords(jnp.arange(W * H), W, H)
    o, d = camera_rays(scene.camera, *coords)
    seen = camera_sees(scene.camera, *coords)
    seen = np.ones(W * H, bool) if seen is None else np.asarray(seen)
    return scene, np.asarray(o).reshape(H, W, 3), np.asarray(d).reshape(H, W, 3), seen.reshape(H, W)


@pytest.mark.povray
@pytest.mark.parametrize("camera_text", CAMERAS)
def test_every_pixels_ray_is_the_one_povray_traces(camera_text):
    from validation.povray import render_povray

    pov = render_povray(HEAD + f"camera {{ {camera_text} }}\n" + DIRECTIONS, W, H).astype(np.float64)
    _, _, d, seen = _ours(camera_text)
    black = np.all(pov == 0, axis=-1)  # a pixel POV-Ray traces no ray for
    np.testing.assert_array_equal(~seen, black)
    np.testing.assert_allclose(d[seen], 2 * pov[seen] - 1, atol=4e-3)
    if camera_text.startswith(("cylinder 3", "cylinder 4")):
        pov = render_povray(HEAD + f"camera {{ {camera_text} }}\n" + PLACES, W, H).astype(np.float64)
        _, o, d, _ = _ours(camera_text)
        t = (10 - o[..., 2]) / d[..., 2]
        hit = o + t[..., None] * d
        near = (t > 0) & np.all(np.abs(hit[..., :2]) < 19.5, axis=-1)  # the gradients repeat past ±20
        assert near.sum() > W * H // 4
        np.testing.assert_allclose(hit[near][:, :2], 40 * pov[near][:, :2] - 20, atol=0.03)


def test_a_fisheyes_corners_are_black_and_its_centre_looks_ahead():
    text = HEAD + "camera { fisheye angle 180 location 0 look_at z }\nbackground { rgb 1 }"
    image = np.asarray(rt.render(rt.load_scene(text), width=W, height=H))
    assert np.all(image[0, 0] == 0) and np.all(image[H // 2, W // 2] == 1)
    _, _, d, _ = _ours("fisheye angle 180 location 0 look_at z")
    # θ = ρ · angle, ρ = |x0 right + y0 up| (right 1.33, up 1): 90° off the axis at the disc's edge
    x0, y0 = (W // 2 + 0.5) / W - 0.5, 0.5 - 0.5 / H
    rho = np.hypot(1.33 * x0, y0)
    assert np.degrees(np.arccos(d[0, W // 2, 2])) == pytest.approx(180 * rho, abs=0.01)


def test_a_cylinder_type_out_of_range_is_an_error_and_edges_refuse_a_curved_camera():
    with pytest.raises(rt.SceneError, match="cylinder camera type from 1 to 4") as e:
        rt.load_scene("camera {\n  cylinder 5 }")
    assert (e.value.location.line, e.value.location.col) == (2, 12)
    scene = rt.load_scene("camera { spherical } sphere { z, 1 }")
    with pytest.raises(ValueError, match="perspective or orthographic camera"):
        rt.render(scene, width=4, height=3, edges=True)
