"""``normal { }``: the perturbed shading normal (semantics §5.5, ``raytracer/shading/_normals.py``).

Held against: the closed form of POV-Ray's rule (measured with ``povray`` on planes lit by three
coloured parallel lights, whose channels give the perturbed normal of every pixel), POV-Ray's
images (``examples/scenes/normals.pov`` is in the validation suite), POV-Ray's statistics for its
own normal patterns, and central differences in float64.
"""

import subprocess

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.imageio import read_image
from raytracer.scene import rotation_matrix, scale_matrix, translation_matrix
from raytracer.sdl import load_scene
from validation.povray import povray_executable

S = 1 / np.sqrt(2)


def _bumped_plane(normal, light_direction, camera_z=-5.0):
    """The plane z = 0 facing a camera on −z, lit by one parallel light from ``light_direction``;
    white, no ambient, diffuse 1: a pixel is the perturbed normal's cosine to the light."""
    layer = rt.Layer(rt.Pigment.solid((1.0, 1.0, 1.0)), rt.Finish(ambient=(0, 0, 0), diffuse=1.0), normal)
    return rt.Scene(camera=rt.Camera(location=(0, 0, camera_z), look_at=(0, 0, 0)),
                    objects=(rt.Object(rt.Plane((0.0, 0.0, -1.0), 0.0), texture=rt.Texture((layer,))),),
                    lights=(rt.Light(position=10 * np.asarray(light_direction), point_at=(0, 0, 0),
                                     parallel=True),))


def test_a_gradient_normal_tilts_a_plane_as_povrays_rule_in_closed_form(x64):
    # gradient x's value rises by 1 per unit of pattern x, so on the tetrahedron the perturbation
    # is exactly -(2/15)·amount·x̂ in pattern space, for any accuracy, and with turbulence too (it
    # moves the tetrahedron's centre, here by less than the 0.3 to the nearest wrap); the normal
    # goes there by Wᵀ (normalised) and back by Aᵀ, A = W⁻¹ — so a non-uniform scale changes the depth
    world_from_pattern = rotation_matrix((0, 0, 20)) @ scale_matrix((2.0, 1.0, 0.5)) @ translation_matrix(
        (0.3, 0, 0))
    amount = 2.0
    light = np.array([0.8, -0.3, -1.0]) / np.linalg.norm([0.8, -0.3, -1.0])
    for accuracy, turbulence in ((0.02, None), (0.1, (0.1, 0.1, 0.1))):
        normal = rt.Normal.of("gradient", amount, vector=(1.0, 0.0, 0.0), accuracy=accuracy,
                              turbulence=turbulence, transform=rt.Transform(world_from_pattern))
        got = np.asarray(rt.render(_bumped_plane(normal, light), width=1, height=1))[0, 0]
        w = world_from_pattern[:3, :3]
        n_p = w.T @ np.array([0.0, 0.0, -1.0])
        n_p /= np.linalg.norm(n_p)
        bent = np.linalg.inv(w).T @ (n_p - 2 / 15 * amount * np.array([1.0, 0.0, 0.0]))
        expected = max(0.0, bent @ light / np.linalg.norm(bent))
        np.testing.assert_allclose(got, expected, rtol=1e-9)
        assert abs(expected - light @ np.array([0.0, 0.0, -1.0])) > 0.02  # the normal did move


def test_a_slope_map_is_a_hermite_curve_in_each_segments_own_parameter(x64):
    # POV-Ray's, measured: the manual's triangle wave ([0 <0,1>] [0.5 <1,1>] [0.5 <1,-1>] [1 <0,-1>])
    # is straight (its slopes are tangents in t, not per unit of value); [0 <0,0>] [1 <1,0>] is
    # 3t² − 2t³; past the ends, the end heights
    from raytracer.shading._normals import _slope_height

    def height(rows, w):
        return float(_slope_height(jnp.asarray(rows, jnp.float64), len(rows), jnp.asarray(w)))

    triangle = [[0, 0, 1], [0.5, 1, 1], [0.5, 1, -1], [1, 0, -1]]
    for w, h in ((0.1, 0.2), (0.4, 0.8), (0.6, 0.8), (0.95, 0.1)):
        assert height(triangle, w) == pytest.approx(h, abs=1e-12)
    for t in (0.0, 0.3, 0.5, 1.0):
        assert height([[0, 0, 0], [1, 1, 0]], t) == pytest.approx(3 * t**2 - 2 * t**3, abs=1e-12)
    ends = [[0.2, 0.3, 1], [0.8, 0.7, 1]]
    assert height(ends, 0.1) == 0.3 and height(ends, 0.9) == 0.7
    s = load_scene("#declare S = slope_map { [0 <0, 1>] [1, <1, 0>] }\n"
                   "sphere { 0, 1 normal { gradient x slope_map { S } } }")
    np.testing.assert_allclose(s.objects[0].texture.layers[0].normal.slope_map, [[0, 0, 1], [1, 1, 0]])


def test_a_layer_without_a_normal_compiles_no_normal_code():
    plain = load_scene("camera { location -5*z look_at 0 } sphere { 0, 1 pigment { rgb 1 } }")
    bumped = load_scene("camera { location -5*z look_at 0 } sphere { 0, 1 pigment { rgb 1 } "
                        "normal { onion 0.5 } }")
    assert rt.plan(plain).effects.normals == ()
    assert rt.plan(bumped).effects.normals == ("onion",)


def test_the_sdl_reads_normals_as_povray_writes_them():
    s = load_scene("""
        #declare N = normal { gradient x 1 scale 2 }
        #default { normal { bozo } }
        sphere { 0, 1 normal { N bump_size 3 accuracy 0.05 } }
        sphere { 0, 1 texture { pigment { rgb 1 } normal { bumps 0.2 } } scale 0.5 }
        sphere { 0, 1 }
    """)
    a, b, c = (o.texture.layers[0].normal for o in s.objects)
    assert a.pattern.pattern == "gradient" and float(a.amount) == 3.0
    assert float(a.accuracy) == pytest.approx(0.05)
    np.testing.assert_allclose(np.asarray(a.pattern.transform.matrix)[:3, :3], 2 * np.eye(3))
    np.testing.assert_allclose(np.asarray(a.pattern.vector), (1, 0, 0))
    # an object's scale reaches its texture's normal, as its pigment
    assert b.pattern.pattern == "bumps" and float(b.amount) == pytest.approx(0.2)
    np.testing.assert_allclose(np.asarray(b.pattern.transform.matrix)[:3, :3], 0.5 * np.eye(3))
    assert c.pattern.pattern == "bozo" and float(c.amount) == 0.5  # the default and POV's amount
    assert s.warnings == ()


def test_normals_we_do_not_render_are_warned_at_their_place_and_perturb_nothing():
    s = load_scene("sphere { 0, 1 normal { checker normal { bumps } normal { dents } } }\n"
                   "sphere { 0, 1 normal { quilted 0.5 } }\n"
                   "sphere { 0, 1 normal { gradient x normal_map { [0 bumps] [1 dents] } } }\n"
                   "camera { location -5*z look_at 0 normal { bumps 0.5 } }\n")
    assert [(w.feature, w.location.line) for w in s.warnings] == [
        ("checker", 1), ("quilted", 2), ("normal_map", 3), ("camera normal", 4)]
    assert s.objects[0].texture.layers[0].normal is None
    assert s.objects[1].texture.layers[0].normal is None
    assert s.objects[2].texture.layers[0].normal is None


def test_a_normal_that_is_not_one_is_an_error_at_its_place():
    from raytracer.sdl import SceneError
    with pytest.raises(SceneError) as e:
        load_scene("#declare P = pigment { rgb 1 }\nsphere { 0, 1 normal {\n  P } }")
    assert e.value.location.line == 3 and "expected a normal" in str(e.value)
    with pytest.raises(SceneError) as e:
        load_scene("sphere { 0, 1 normal { bumps 0.5\n  <1, 2, 3> } }")
    assert e.value.location.line == 2 and "expected a normal item" in str(e.value)


def test_the_gradient_of_a_bumped_image_is_finite_and_matches_central_differences(x64):
    # the normal's amount and the scale of its space move the shading smoothly (onion has no
    # wrap in the image below, bumps is smooth noise)
    light = np.array([0.4, 0.3, -1.0]) / np.linalg.norm([0.4, 0.3, -1.0])

    def image(params):
        amount, scale = params
        normals = (rt.Normal.of("onion", amount, transform=rt.Transform(
                       jnp.diag(jnp.array([scale, scale, scale, 1.0])) @ translation_matrix((3.0, 2.0, 0)))),
                   rt.Normal.of("bumps", amount, transform=rt.Transform(
                       jnp.diag(jnp.array([scale, 1.0, scale, 1.0])))))
        return jnp.stack([rt.render(_bumped_plane(n, light, camera_z=-3.0), width=6, height=4)
                          for n in normals])

    params = jnp.array([0.6, 0.8])
    loss = lambda p: jnp.sum(image(p) ** 2)  # noqa: E731
    grad = jax.grad(loss)(params)
    assert np.all(np.isfinite(grad)) and np.all(np.abs(grad) > 1e-6)
    step = 1e-5
    for i in range(2):
        e = jnp.zeros(2).at[i].set(step)
        fd = (loss(params + e) - loss(params - e)) / (2 * step)
        np.testing.assert_allclose(grad[i], fd, rtol=1e-5)


# the three-light rig: a plane facing −z under red, green and blue parallel lights from
# (1, 0, −1), (0, 0, −1) and (0, 1, −1): a pixel's channels give its perturbed normal
_RIG = """#version 3.7;
global_settings {{ assumed_gamma 1.0 ambient_light 0 }}
camera {{ orthographic location <0,0,-10> look_at <0,0,0> right x*4 up y*3 }}
light_source {{ <10,0,-10> rgb <1,0,0> parallel point_at <0,0,0> }}
light_source {{ <0,0,-10> rgb <0,1,0> parallel point_at <0,0,0> }}
light_source {{ <0,10,-10> rgb <0,0,1> parallel point_at <0,0,0> }}
plane {{ -z, 0 pigment {{ rgb 1 }} finish {{ ambient 0 diffuse 1 }} normal {{ {normal} }} }}
"""


def _tilts(rgb):
    """(H, W, 2) the perturbed normal's tangent components over its component along the surface's
    normal −z, from the rig's channels."""
    r, g, b = (rgb[..., i].astype(np.float64) for i in range(3))
    return np.stack([np.sqrt(2) * r - g, np.sqrt(2) * b - g], -1) / g[..., None]


@pytest.mark.povray
@pytest.mark.slow  # POV-Ray and our renders of five patterns
def test_povrays_own_normal_patterns_have_povrays_statistics(tmp_path):
    # bumps, dents, wrinkles, ripples and waves rest on POV-Ray's noise and wave sources, which
    # ours match in statistics: the perturbation's standard deviation in both tangent directions,
    # and wrinkles' tilt of every point, within 15 % of POV-Ray's (measured: within 11 %)
    for normal in ("bumps 0.2 scale 0.1", "dents 0.2 scale 0.1", "wrinkles 0.1 scale 0.1",
                   "ripples 0.2 scale 0.1", "waves 0.2 scale 0.1"):
        scene = tmp_path / "rig.pov"
        scene.write_text(_RIG.format(normal=normal))
        subprocess.run([povray_executable(), "-D", "-A", f"+I{scene}", f"+O{tmp_path / 'p.exr'}", "+FE",
                        "+W160", "+H120"], capture_output=True, check=True)
        theirs = _tilts(read_image(tmp_path / "p.exr")[..., :3])
        ours = _tilts(np.asarray(rt.render(load_scene(scene), width=160, height=120)))
        np.testing.assert_allclose(ours.std(axis=(0, 1)), theirs.std(axis=(0, 1)), rtol=0.15, err_msg=normal)
        if normal.startswith("wrinkles"):
            np.testing.assert_allclose(ours.mean(axis=(0, 1)), theirs.mean(axis=(0, 1)), rtol=0.1)
