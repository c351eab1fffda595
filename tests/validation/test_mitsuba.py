"""Scene → Mitsuba conversion: analytic pixel values, built-in integrators, and NotMatchable."""

import math

import numpy as np
import pytest

from raytracer.scene import (
    CSG,
    Camera,
    Cone,
    Finish,
    Interior,
    Light,
    Object,
    Pigment,
    Plane,
    Reflection,
    Scene,
    Settings,
    Sphere,
    Texture,
    Transform,
)

pytestmark = pytest.mark.mitsuba
vm = pytest.importorskip("validation.mitsuba")
pytest.importorskip("mitsuba")

W, H = 32, 24
RHO, LIGHT = np.array([0.8, 0.5, 0.25]), np.array([1.0, 0.75, 0.5])


@pytest.fixture(scope="module")
def mi():
    return vm.mitsuba()


def lambert_scene(**finish) -> Scene:
    """Unit sphere at z = 5 seen from the origin, lit along the view axis by a parallel light."""
    cam = Camera(location=(0, 0, 0), direction=(0, 0, 1), right=(W / H, 0, 0), up=(0, 1, 0),
                 angle_degrees=40.0, up_or_right_given=True)
    tex = Texture.of(Pigment.solid(RHO), Finish(ambient=(0, 0, 0), diffuse=0.6, **finish))
    light = Light(position=(0, 0, -100), color=LIGHT, point_at=(0, 0, 0), parallel=True)
    return Scene(camera=cam, objects=(Object(Sphere((0, 0, 5), 1.0), texture=tex),), lights=(light,),
                 settings=Settings(adc_bailout=0.0))


def analytic_lambert(i: int, j: int) -> np.ndarray:
    """POV's value at pixel (i, j) of ``lambert_scene``: diffuse·P·C·(N·L), semantics §1.2, §2.4."""
    r_len = W / H
    d_len = r_len / (2 * math.tan(math.radians(20)))
    x0, y0 = (i + 0.5) / W - 0.5, 0.5 - (j + 0.5) / H
    d = np.array([x0 * r_len, y0 * 1.0, d_len])
    d /= np.linalg.norm(d)
    c = np.array([0.0, 0.0, 5.0])
    b = d @ c
    disc = b * b - (c @ c - 1.0)
    if disc < 0:
        return np.zeros(3)
    p = (b - math.sqrt(disc)) * d
    n = p - c
    return 0.6 * RHO * LIGHT * max(0.0, float(n @ np.array([0.0, 0.0, -1.0])))


def test_lambert_sphere_matches_the_analytic_value_at_pixel_centres(mi):
    img = vm.render_mitsuba_centres(vm.to_mitsuba(lambert_scene(), W, H))
    assert img.shape == (H, W, 3)
    for i, j in [(16, 12), (15, 11), (19, 9), (12, 14), (0, 0)]:
        np.testing.assert_allclose(img[j, i], analytic_lambert(i, j), atol=2e-5, rtol=1e-4)


def test_image_is_not_mirrored(mi):
    # a sphere on the +x side (POV: right) must appear in the right half of the image
    s = lambert_scene()
    s = Scene(camera=s.camera, lights=s.lights, settings=s.settings,
              objects=(Object(Sphere((1.2, 0, 5), 0.5), texture=s.objects[0].texture),))
    img = vm.render_mitsuba_centres(vm.to_mitsuba(s, W, H))
    lum = img.sum(axis=(0, 2))
    assert lum[W // 2:].sum() > 0 and lum[: W // 2].sum() == 0


def test_whitted_integrator_equals_mitsuba_direct_on_a_lambert_scene(mi):
    d = vm.to_mitsuba(lambert_scene(), W, H)
    ours = vm.render_mitsuba_centres(d)
    direct = vm.render_mitsuba_centres(d, integrator={"type": "direct", "hide_emitters": True})
    np.testing.assert_allclose(ours, direct, atol=1e-6)


def test_whitted_integrator_equals_mitsuba_path_for_a_mirror_and_emissive_surfaces(mi):
    s = lambert_scene()
    glow = Texture.of(Pigment.checker((0.9, 0.2, 0.1), (0.1, 0.3, 0.9)),
                      Finish(ambient=(1, 1, 1), diffuse=0.0))
    chrome = Reflection(min=(0.8,) * 3, max=(0.8,) * 3)
    mirror = Texture.of(Pigment.solid((0, 0, 0)), Finish(ambient=(0, 0, 0), diffuse=0.0, reflection=chrome))
    s = Scene(camera=s.camera, settings=Settings(adc_bailout=0.0, max_trace_level=6),
              objects=(Object(Sphere((0, 0, 5), 1.0), texture=mirror),
                       Object(Plane((0, 1, 0), -1.5), texture=glow),
                       Object(Plane((0, 0, 1), -3.0), texture=glow)))
    d = vm.to_mitsuba(s, W, H)
    ours = vm.render_mitsuba_centres(d)
    path = vm.render_mitsuba_centres(d, integrator={"type": "path", "max_depth": 6, "hide_emitters": False})
    np.testing.assert_allclose(ours, path, atol=1e-5)
    assert ours.max() > 0.5


def test_film_render_averages_the_pixel_area(mi):
    d = vm.to_mitsuba(lambert_scene(), W, H)
    film = vm.render_mitsuba_film(d, spp=64)
    centres = vm.render_mitsuba_centres(d)
    assert film.shape == (H, W, 3)
    # interior pixel: the pixel average of a smooth shading is close to its centre value
    np.testing.assert_allclose(film[12, 16], centres[12, 16], rtol=2e-2)


def _only(s, *objects, camera=None, lights=None):
    return Scene(camera=camera or s.camera, lights=s.lights if lights is None else lights,
                 settings=s.settings, objects=objects)


ELLIPSOID = Transform.scale((1, 2, 1)).then(Transform.translate((0, 0, 5)))
GLASS_NO_FRESNEL = Texture.of(Pigment.solid((1, 1, 1), filter=1.0), Finish(diffuse=0.0))


@pytest.mark.parametrize("change, feature", [
    (lambda s: _only(s, *s.objects, lights=(Light(position=(0, 5, -5)),)), "point light"),
    (lambda s: lambert_scene(phong=0.5), "phong"),
    (lambda s: lambert_scene(brilliance=2.0), "brilliance ≠ 1"),
    (lambda s: _only(s, Object(Cone((0, 0, 5), 1.0, (0, 1, 5), 0.2))), "cone"),
    (lambda s: _only(s, CSG("difference", (s.objects[0], Object(Sphere((0, 0, 4), 0.5))))), "CSG difference"),
    (lambda s: _only(s, Object(Sphere((0, 0, 0), 1.0), transform=ELLIPSOID)), "ellipsoid"),
    (lambda s: _only(s, *s.objects, camera=Camera(right=(1.33, 0, 0))), "non-square pixels"),
    (lambda s: _only(s, Object(Sphere((0, 0, 5), 1.0), interior=Interior(ior=1.5), texture=GLASS_NO_FRESNEL)),
     "refraction without reflection{0, 1 fresnel on}"),
])
def test_features_without_an_exact_equivalent_raise_not_matchable(mi, change, feature):
    with pytest.raises(vm.NotMatchable) as e:
        vm.to_mitsuba(change(lambert_scene()), W, H)
    assert e.value.feature == feature


def test_glass_is_a_dielectric_and_marked_stochastic(mi):
    s = lambert_scene()
    glass = Texture.of(Pigment.solid((1, 1, 1), transmit=1.0),
                       Finish(ambient=(0, 0, 0), diffuse=0.0, conserve_energy=True,
                              reflection=Reflection(min=(0, 0, 0), max=(1, 1, 1), fresnel=True)))
    s = Scene(camera=s.camera, lights=s.lights, settings=s.settings,
              objects=(Object(Sphere((0, 0, 5), 1.0), texture=glass, interior=Interior(ior=1.5)),))
    d = vm.to_mitsuba(s, W, H)
    assert d.stochastic
    assert [v["bsdf"] for k, v in d.items() if k.startswith("sphere")] == [
        {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0}]
