"""Gradients of ``raytracer.render``: finite everywhere, equal to finite differences, and where they
are not (visibility edges) the disagreement is measured and confined to edge pixels.

Stance (docs/gradients.md): AD gives the derivative of each pixel's colour with the pixel's hit
object (and every secondary ray's hit object, shadow and TIR decision) held fixed. Finite
differences jump where an edge crosses a pixel centre within ±h. So for parameters that never move
edges (colours, finish, light colour) JVP = FD on all pixels; for geometric ones the two differ only
at pixels that are not differentiable at the current parameters, which a test detects independently
from the one-sided differences (forward and backward differences disagree there).

Everything is float64 (``jax.enable_x64``) with scenes built inside that context. Each distinct
scene structure costs one XLA compile (10–60 s), so each test module fixture compiles ONE
``jit(jvp)`` program and checks many parameters at once along random directions
(:func:`raytracer.params.random_tangent`); the JVP program also gives the primal image for the
finite differences (zero tangent), so no separate forward program is compiled.
"""

from __future__ import annotations

import dataclasses
import functools
import glob
import math
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import raytracer as rt
from raytracer import params

ROOT = Path(__file__).resolve().parent.parent
W, H = 32, 24
H_FD = 1e-6  # central-difference step (float64): truncation ~h², rounding ~1e-16/h ≈ 1e-10


@pytest.fixture(autouse=True)
def _float64():
    with jax.enable_x64(True):
        yield


def demo_scene(width: int = W, height: int = H, *, depth: int = 3) -> rt.Scene:
    """A smooth gradient wall; a phong, reflective sphere; a glass sphere (ior 1.33) and a glass
    cube turned 45° (ior 1.6: rays entering its front faces are totally internally reflected at the
    side faces, 63.8° > the 38.7° critical angle); one point light; shadows."""
    cam = rt.Camera(location=(0, 1.0, -5.0), look_at=(0, 0.8, 0), right=(width / height, 0, 0),
                    angle_degrees=45.0)
    wall = rt.Pigment.mapped("gradient", [(0.0, (0.9, 0.3, 0.1)), (0.5, (0.9, 0.85, 0.2)),
                                          (1.0, (0.1, 0.3, 0.9))], vector=(1.0, 0.6, 0.0),
                             transform=rt.Transform.scale(16.0).then(rt.Transform.translate((-8, -2, 0))))
    glass = rt.Texture.of(rt.Pigment.solid((1, 1, 1), filter=0.0, transmit=1.0),
                          rt.Finish(ambient=(0, 0, 0), diffuse=0.0, conserve_energy=True,
                                    reflection=rt.Reflection(min=(0, 0, 0), max=(1, 1, 1), fresnel=True)))
    objects = (
        rt.Object(rt.Plane((0, 0, -1), -4.0), texture=rt.Texture.of(wall, rt.Finish(ambient=(0.2,) * 3,
                                                                                     diffuse=0.7))),
        rt.Object(rt.Sphere((1.0, 0.8, 0.5), 0.8), texture=rt.Texture.of(
            rt.Pigment.solid((0.8, 0.35, 0.2)),
            rt.Finish(ambient=(0.1,) * 3, diffuse=0.6, phong=0.5, phong_size=30.0,
                      reflection=rt.Reflection(min=(0.2,) * 3, max=(0.2,) * 3)))),
        rt.Object(rt.Sphere((-1.2, 1.4, -0.8), 0.55), texture=glass, interior=rt.Interior(ior=1.33)),
        rt.Object(rt.Box((-0.45, -0.45, -0.45), (0.45, 0.45, 0.45)),
                  transform=rt.Transform.rotate((0, 45, 0)).then(rt.Transform.translate((-0.6, 0.2, -1.5))),
                  texture=glass, interior=rt.Interior(ior=1.6)),
    )
    light = rt.Light(position=(-10, 15, -12), color=(1.0, 0.95, 0.9))
    return rt.Scene(camera=cam, objects=objects, lights=(light,),
                    settings=rt.Settings(max_trace_level=depth, adc_bailout=0.0))


def is_material(name: str) -> bool:
    # reflection.exponent included: the mirror ray's colour c^(1/exponent) is continuous in
    # (c, exponent) through c = 0 (odd in c), where reflection rays see the black background
    return not params.moves_edges(name)


def is_ior(name: str) -> bool:
    return name.endswith(".ior")


def is_geometric(name: str) -> bool:
    # pattern parameters (values, vector, frequency…) move colour edges too, but of a smooth
    # gradient pattern only where it wraps; adc_bailout is a threshold (zero derivative a.e.)
    return params.moves_edges(name) and ".pigment." not in name and "adc_bailout" not in name


class Probe:
    """One compiled ``jit(jvp(render))`` program for a scene structure, and finite differences."""

    def __init__(self, scene: rt.Scene, width: int, height: int):
        self.p, rest = eqx.partition(scene, eqx.is_inexact_array)
        self.width, self.height = width, height

        def image(p):
            return rt.render(eqx.combine(p, rest), width=width, height=height)

        self._jvp = jax.jit(lambda p, t: jax.jvp(image, (p,), (t,)))
        self._zero = params.random_tangent(self.p, jax.random.PRNGKey(0), [])

    def image(self, p=None) -> np.ndarray:
        return np.asarray(self._jvp(self.p if p is None else p, self._zero)[0])

    def jvp(self, tangent) -> np.ndarray:
        return np.asarray(self._jvp(self.p, tangent)[1])

    def shifted(self, tangent, h: float):
        return jax.tree_util.tree_map(lambda a, b: a + h * b, self.p, tangent)

    def differences(self, tangent, h: float = H_FD):
        """(central, forward, backward) differences along ``tangent``, each (H, W, 3)."""
        plus, minus = self.image(self.shifted(tangent, h)), self.image(self.shifted(tangent, -h))
        mid = self.image()
        return (plus - minus) / (2 * h), (plus - mid) / h, (mid - minus) / h

    def tangent(self, seed: int, names) -> object:
        return params.random_tangent(self.p, jax.random.PRNGKey(seed), names)


@pytest.fixture(scope="module")
def demo():
    with jax.enable_x64(True):
        return Probe(demo_scene(), W, H)


def _pixel_error(a, b) -> np.ndarray:
    return np.abs(a - b).max(axis=-1)


# --------------------------------------------------------------------------------------------------
# (a) parameters that never move edges: JVP = FD on (almost) every pixel


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_jvp_matches_central_differences_for_material_parameters(demo, seed):
    """Random direction over every colour, finish coefficient, reflection amount, light colour,
    ambient light and background of the demo scene."""
    t = demo.tangent(seed, is_material)
    jvp = demo.jvp(t)
    fd, _, _ = demo.differences(t)
    assert np.isfinite(jvp).all()
    err = _pixel_error(jvp, fd)
    assert np.abs(jvp).max() > 0.1  # the direction does change the image
    assert (err <= 1e-4).mean() >= 0.99, np.sort(err.ravel())[-10:]
    assert np.median(err) <= 1e-7


@pytest.mark.slow
def test_jvp_matches_central_differences_for_ior_through_refraction_and_tir(demo):
    """ior of the glass sphere and the glass cube (whose side faces totally reflect): the outline
    seen through the glass and the TIR boundary move with ior, so a few pixels may be edge pixels;
    the rest match."""
    t = demo.tangent(2, is_ior)
    jvp = demo.jvp(t)
    fd, fwd, bwd = demo.differences(t)
    assert np.isfinite(jvp).all()
    changed = np.abs(jvp).max(axis=-1) > 1e-3
    assert changed.sum() >= 20  # pixels seen through the glass sphere and cube respond to ior
    err = _pixel_error(jvp, fd)
    assert (err <= 1e-4).mean() >= 0.99, np.sort(err.ravel())[-10:]


# --------------------------------------------------------------------------------------------------
# (b) geometric parameters: JVP = FD except at edge pixels, measured


@pytest.mark.slow
def test_geometric_jvp_disagrees_with_differences_only_at_edge_pixels(demo):
    """Random direction over shape parameters, object transforms, camera, light position.

    An edge pixel is one where the image is not differentiable at the current parameters along
    the direction: its one-sided differences disagree (an edge crossing the pixel centre within
    ±h gives |FD| ~ jump/h; a pixel grazing a silhouette has a derivative ~ 1/√(discriminant) that
    changes within ±h). That is detected from finite differences alone, independently of AD.
    Measured (32×24, seed 3, h = 1e-6): 3 pixels (0.39 %) disagree, the same 3 are edge pixels;
    the largest JVP there is ~1e6 (a grazing silhouette hit), elsewhere JVP = FD to 5e-5.
    """
    t = demo.tangent(3, is_geometric)
    jvp = demo.jvp(t)
    assert np.isfinite(jvp).all()
    fd, fwd, bwd = demo.differences(t, H_FD)
    scale = np.abs(jvp).max(axis=-1) + 1.0
    wrong = _pixel_error(jvp, fd) > 1e-4 * scale
    edge = _pixel_error(fwd, bwd) > 1e-2 * scale  # smooth pixels: |fwd − bwd| ≈ h·|f''| ≲ 1e-5
    assert wrong.mean() <= 0.01
    assert not (wrong & ~edge).any(), np.argwhere(wrong & ~edge)
    assert edge.mean() <= 0.02


# --------------------------------------------------------------------------------------------------
# closed-form geometric derivatives


def fade_sphere_scene(radius: float, fade_distance: float):
    """A white sphere of ``radius`` centred at z = 5 seen head-on from the origin through a 3×3 image
    (the centre pixel's ray is the +z axis), lit by a point light AT the camera with
    ``fade_power 2``: the centre hit is p = (0, 0, 5 − r), n·l = 1, light distance 5 − r."""
    cam = rt.Camera(location=(0, 0, 0), direction=(0, 0, 1), right=(1, 0, 0), up=(0, 1, 0),
                    angle_degrees=30.0, up_or_right_given=True)
    tex = rt.Texture.of(rt.Pigment.solid((0.9, 0.6, 0.3)), rt.Finish(ambient=(0.2, 0.2, 0.2), diffuse=0.7))
    light = rt.Light(position=(0, 0, 0), color=(1.0, 0.8, 0.6), fade_distance=fade_distance, fade_power=2.0)
    return rt.Scene(camera=cam, objects=(rt.Object(rt.Sphere((0, 0, 5), radius), texture=tex),),
                    lights=(light,), settings=rt.Settings(max_trace_level=1, adc_bailout=0.0))


def centre_colour(scene):
    return rt.render(scene, width=3, height=3)[1, 1]


def test_inflating_sphere_moves_the_centre_hit_back_along_the_ray():
    """dt/dr = −1: inflating the sphere brings the centre hit towards the camera (and the light at
    the camera). The ambient term does not depend on the hit distance, so its derivative is zero;
    the faded diffuse term ``d·P·C·2/(1 + (dist/D)²)`` with dist = 5 − r has
    d/dr = d·P·C·4·dist/D² / (1 + (dist/D)²)²."""
    r, fade_d = 1.3, 2.5
    scene = fade_sphere_scene(r, fade_d)
    p_rgb, c_rgb = np.array([0.9, 0.6, 0.3]), np.array([1.0, 0.8, 0.6])
    dist = 5.0 - r
    q = 1.0 + (dist / fade_d) ** 2
    expected_colour = 0.2 * p_rgb + 0.7 * p_rgb * c_rgb * 2.0 / q
    expected_derivative = 0.7 * p_rgb * c_rgb * 4.0 * dist / fade_d**2 / q**2

    def colour_of_radius(radius):
        return centre_colour(eqx.tree_at(lambda s: s.objects[0].shape.radius, scene, radius))

    colour, d_colour = jax.jit(lambda x: jax.jvp(colour_of_radius, (x,), (jnp.ones_like(x),)))(
        scene.objects[0].shape.radius)
    np.testing.assert_allclose(colour, expected_colour, rtol=1e-12)
    np.testing.assert_allclose(d_colour, expected_derivative, rtol=1e-9)


@pytest.mark.slow  # three compiled programs (~30 s each on 2 cores)
def test_grad_vjp_and_jvp_under_jit_agree_with_each_other():
    """``jax.grad``, ``jax.vjp`` and ``jax.jvp`` of a render, each inside ``jax.jit``, give the same
    linear map (⟨u, J v⟩ = ⟨Jᵀu, v⟩) and finite values."""
    scene = fade_sphere_scene(1.3, 2.5)
    p, rest = eqx.partition(scene, eqx.is_inexact_array)

    def image(p):
        return rt.render(eqx.combine(p, rest), width=3, height=3)

    u = jax.random.normal(jax.random.PRNGKey(1), (3, 3, 3), jnp.float64)
    v = params.random_tangent(p, jax.random.PRNGKey(2))
    g = jax.jit(jax.grad(lambda p: jnp.sum(u * image(p))))(p)
    _, pullback = jax.jit(lambda p: jax.vjp(image, p))(p)
    (g_vjp,) = jax.jit(pullback)(u)
    _, jv = jax.jit(lambda p, v: jax.jvp(image, (p,), (v,)))(p, v)

    def dot(a, b):
        return sum(jnp.vdot(x, y) for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b),
                                                   strict=True))

    for tree in (g, g_vjp):
        assert all(bool(jnp.isfinite(x).all()) for x in jax.tree_util.tree_leaves(tree))
    np.testing.assert_allclose(dot(g, v), jnp.vdot(u, jv), rtol=1e-10)
    np.testing.assert_allclose(dot(g_vjp, v), jnp.vdot(u, jv), rtol=1e-10)


@pytest.mark.slow  # a JVP and a VJP program per parameter
@pytest.mark.parametrize("name", ["lights[0].color", "objects[0].shape.radius"])
def test_check_grads_on_a_tiny_render(name):
    scene = fade_sphere_scene(1.3, 2.5)

    def image(x):
        return rt.render(params.replace(scene, {name: x}), width=3, height=3)

    check_grads(image, (params.get(scene, name),), order=1, modes=("fwd", "rev"), eps=1e-6)


def test_reflection_exponent_derivative_at_one():
    """A mirror-ish sphere reflecting a lit grey wall: the reflected colour is c^(1/exponent), whose
    derivative at exponent 1 is −c·log c ≠ 0 for 0 < c < 1."""
    cam = rt.Camera(location=(0, 0, 0), direction=(0, 0, 1), right=(1, 0, 0), up=(0, 1, 0),
                    angle_degrees=20.0, up_or_right_given=True)
    mirror = rt.Texture.of(rt.Pigment.solid((0, 0, 0)), rt.Finish(
        ambient=(0, 0, 0), diffuse=0.0, reflection=rt.Reflection(min=(0.5,) * 3, max=(0.5,) * 3)))
    wall = rt.Texture.of(rt.Pigment.solid((0.5, 0.5, 0.5)), rt.Finish(ambient=(1, 1, 1), diffuse=0.0))
    scene = rt.Scene(camera=cam, objects=(rt.Object(rt.Sphere((0, 0, 5), 1.0), texture=mirror),
                                          rt.Object(rt.Plane((0, 0, 1), -2.0), texture=wall)),
                     settings=rt.Settings(max_trace_level=2, adc_bailout=0.0))
    name = "objects[0].texture.layers[0].finish.reflection.exponent"

    def centre(e):
        return rt.render(params.replace(scene, {name: e}), width=3, height=3)[1, 1, 0]

    # closed form: 0.5 · 0.5^(1/e); d/de at e = 1: 0.5 · 0.5 · log(0.5) · (−1) = 0.1733
    value, slope = jax.jit(lambda e: jax.jvp(centre, (e,), (jnp.ones_like(e),)))(jnp.float64(1.0))
    np.testing.assert_allclose(value, 0.25, rtol=1e-12)
    np.testing.assert_allclose(slope, -0.25 * math.log(0.5), rtol=1e-9)


def test_filter_and_transmit_an_opaque_pigment_does_not_use_have_no_gradient(x64):
    """A pigment written without filter or transmit is opaque in the program's structure: its
    colours' filter and transmit channels change nothing (the image does not depend on them), so
    their gradient is exactly 0, where it was −diffuse·(n·l)·P through the attenuation 1 − f − t
    while no light passed (a colour fit drifted them negative). Written, even as 0, they are
    rendered, and their gradient is the closed form's."""
    cam = rt.Camera(location=(0, 0, -5), look_at=(0, 0, 0))
    light = rt.Light(position=(0.0, 0.0, -10.0))
    fin = rt.Finish(ambient=(0.0, 0.0, 0.0), diffuse=0.8)

    def scene(pigment):
        return rt.Scene(camera=cam, objects=(rt.Object(rt.Sphere((0, 0, 0), 1.0),
                                                       texture=rt.Texture.of(pigment, fin)),),
                        lights=(light,), settings=rt.Settings(adc_bailout=0.0))

    def grad_of(pigment):
        g = jax.grad(lambda s: rt.render(s, width=1, height=1)[0, 0].sum())(scene(pigment))
        return np.asarray(g.objects[0].texture.layers[0].pigment.colors)[0]

    opaque = grad_of(rt.Pigment.solid((0.8, 0.4, 0.2)))
    np.testing.assert_allclose(opaque[:3], 0.8, rtol=1e-12)  # d (0.8 · P · n·l) / dP, n·l = 1
    assert (opaque[3:] == 0).all()
    # written: the centre pixel is 0.8·P·(1 − f − t) + (f·P + t)·background(0): d/df = d/dt = −0.8·ΣP
    written = grad_of(rt.Pigment.solid((0.8, 0.4, 0.2), filter=0.0, transmit=0.0))
    np.testing.assert_allclose(written[3:], -0.8 * 1.4, rtol=1e-12)


# --------------------------------------------------------------------------------------------------
# every example scene: finite reverse-mode gradients


EXAMPLE_SCENES = sorted(glob.glob(str(ROOT / "examples" / "scenes" / "*.pov")))
GRAD_W, GRAD_H = 8, 6
GRAD_MAX_TRACE_LEVEL = 3  # compile time grows with depth; deeper levels repeat the same code


def _capped_example(path: str) -> rt.Scene:
    scene = rt.load_scene(path, width=GRAD_W, height=GRAD_H)
    return eqx.tree_at(lambda s: s.settings, scene, dataclasses.replace(
        scene.settings, max_trace_level=min(scene.settings.max_trace_level, GRAD_MAX_TRACE_LEVEL)))


def _shading_signature(scene: rt.Scene):
    """What the compiled program simulates besides its primitive kernels and patterns:
    ``plan(scene).effects`` without ``kinds`` and ``patterns``."""
    return dataclasses.replace(rt.plan(scene).effects, kinds=(), patterns=())


def _features(scene: rt.Scene) -> set:
    eff = rt.plan(scene).effects
    return {("kind", k) for k in eff.kinds} | {("pattern", q) for q in eff.patterns}


@functools.cache
def _differentiated_examples() -> tuple[str, ...]:
    """The example scenes whose reverse mode is compiled: one per shading signature (at the capped
    depth), together covering every pattern of the examples. Every primitive kind is differentiated
    in one scene (:func:`every_kind_scene`), so a signature's scene is the smallest (fewest kinds
    and patterns, then by name) that leaves no pattern uncovered: a lathe's example adds only a
    checker to the seed's signature, and its kernel's reverse mode cost 12 s of compile more."""
    by_signature: dict = {}
    features: dict = {}
    for path in EXAMPLE_SCENES:
        scene = _capped_example(path)
        features[path] = _features(scene)
        by_signature.setdefault(_shading_signature(scene), []).append(path)
    patterns = {f for path in EXAMPLE_SCENES for f in features[path] if f[0] == "pattern"}
    # start from the richest scene of each signature, then shrink each pick while the cover holds
    chosen = {sig: min(paths, key=lambda p: (-len(features[p]), Path(p).stem))
              for sig, paths in by_signature.items()}
    for sig, paths in by_signature.items():
        others = set().union(*(features[p] for s, p in chosen.items() if s != sig))
        chosen[sig] = min((p for p in paths if patterns <= others | features[p]),
                          key=lambda p: (len(features[p]), Path(p).stem))
    return tuple(sorted(chosen.values()))


KIND_W, KIND_H = 32, 24  # a few rays on every object


def _shape_cases():
    """The shape test cases in the order their shapes are registered (``raytracer.shapes``), so a
    new shape takes a new cell of ``every_kind_scene`` and leaves the others' cells as they were
    (each cell sees its shape from its own angle: a clipped plane's patch moved into the first
    column was seen by no ray at 32×24)."""
    from shapes._cases import CASES

    order = list(rt.shapes.REGISTRY)
    return sorted(CASES, key=lambda c: order.index(c.kind))


def every_kind_scene() -> rt.Scene:
    """One object per shape test case (every registered shape and static variant, from
    ``tests/shapes``), each moved into a cell of a 4-wide grid and scaled to it, unbounded ones
    (planes, quadrics) clipped by a sphere around their patch, with phong, a shadow-catching wall
    and a light: a new shape is differentiated here without a new example."""
    cases = _shape_cases()
    tex = rt.Texture.of(rt.Pigment.solid((0.8, 0.6, 0.4)),
                        rt.Finish(ambient=(0.1,) * 3, diffuse=0.7, phong=0.4, phong_size=20.0))
    objects = [rt.Object(rt.Plane((0, 0, -1), -3.0), texture=tex)]
    for i, case in enumerate(cases):
        cell = np.array([i % 4 - 1.5, 1.5 - i // 4, 0.0]) * 2.5
        to_unit = rt.Transform.translate(-np.asarray(case.aim, float)).then(rt.Transform.scale(1 / case.size))
        place = to_unit.then(rt.Transform.rotate((60.0, 30.0, 0.0))).then(rt.Transform.translate(cell))
        shape = case.make(*case.params)
        clip = () if shape.bounds() is not None else (rt.Object(rt.Sphere(case.aim, 1.2 * case.size)),)
        objects.append(rt.Object(shape, transform=place, texture=tex, clipped_by=clip))
    rows = -(-len(cases) // 4)
    centre = (0.0, 1.25 * (4 - rows), 0.0)
    away = 16.0 * max(1.0, 1.1 * rows / 4)  # four rows fill the frame; more, farther
    cam = rt.Camera(location=(centre[0], centre[1], -away), look_at=centre, right=(KIND_W / KIND_H, 0, 0),
                    angle_degrees=40.0)
    return rt.Scene(camera=cam, objects=tuple(objects), lights=(rt.Light(position=(-10, 15, -12)),),
                    settings=rt.Settings(max_trace_level=1, adc_bailout=0.0))


def test_differentiated_scenes_cover_every_shading_signature_kind_and_pattern():
    """The example scenes left out of the reverse-mode tests below add nothing to them: their
    shading signatures, primitive kinds and patterns are all differentiated (a kind or pattern runs
    the same code whatever the signature it appears in)."""
    chosen = _differentiated_examples()
    examples = {path: _capped_example(path) for path in EXAMPLE_SCENES}
    assert set(chosen) <= set(examples)
    every_kind = _features(every_kind_scene())
    assert {("kind", c.kind) for c in _shape_cases()} <= every_kind
    signatures = {_shading_signature(examples[p]) for p in chosen}
    features = set().union(*(_features(examples[p]) for p in chosen), every_kind)
    for path, scene in examples.items():
        assert _shading_signature(scene) in signatures, f"{Path(path).name}: signature not differentiated"
        assert _features(scene) <= features, Path(path).name


def _assert_finite_gradient(scene: rt.Scene, width: int, height: int, what: str):
    """``jax.grad`` of the image's mean square with respect to every parameter, asserted finite."""
    p, rest = eqx.partition(scene, eqx.is_inexact_array)
    g = jax.jit(jax.grad(lambda p: jnp.mean(rt.render(eqx.combine(p, rest), width=width,
                                                      height=height) ** 2)))(p)
    bad = [n for n, x in params.parameters(g).items() if not bool(jnp.isfinite(x).all())]
    assert not bad, f"{what}: non-finite gradient for {bad}"
    return g


@pytest.mark.slow  # one reverse-mode program per scene: 5–30 s of compile each
@pytest.mark.parametrize("path", _differentiated_examples(), ids=lambda p: Path(p).stem)
def test_grad_is_finite_for_every_example_scene(path):
    """Reverse mode through the whole renderer (every parameter of the scene) is finite at every
    pixel, for one example scene per shading signature (see the test above; the others run the
    same code). (Grouping several scenes into one program compiles far slower than one per scene.)
    Every example's forward render is compared with POV-Ray, so finite, by the suite's ``pov/``
    entries."""
    _assert_finite_gradient(_capped_example(path), GRAD_W, GRAD_H, Path(path).name)


@pytest.mark.slow  # one reverse-mode program with every primitive kind
def test_grad_is_finite_for_every_primitive_kind_in_one_scene():
    scene = every_kind_scene()
    g = _assert_finite_gradient(scene, KIND_W, KIND_H, "every kind")
    # every object is seen: each one's parameters move the image
    for i in range(1, len(scene.objects)):
        moved = [x for n, x in params.parameters(g).items() if n.startswith(f"objects[{i}].shape.")]
        assert any(bool(jnp.any(x != 0)) for x in moved), scene.objects[i].shape


# --------------------------------------------------------------------------------------------------
# against Mitsuba's AD


@pytest.mark.mitsuba
@pytest.mark.slow
def test_gradients_match_mitsuba_prb_at_pixel_centres():
    """dL/d(reflectance) and dL/d(irradiance) of an image MSE: ours (jax.grad) vs Mitsuba prb."""
    pytest.importorskip("mitsuba")
    vg = pytest.importorskip("validation.gradients")
    results = vg.compare("lambert_sphere", width=32, height=24)
    assert {r.parameter for r in results} == {"objects[1] reflectance", "lights[0] irradiance"}
    for r in results:
        assert r.rel_error <= vg.MAX_REL_ERROR, r.line()


# --------------------------------------------------------------------------------------------------
# the Optimistix example


@pytest.mark.slow  # ~55 s: two renders and two LM solves, compile included
def test_fit_material_example_recovers_its_parameters(tmp_path):
    import subprocess
    import sys

    out = subprocess.run([sys.executable, str(ROOT / "examples" / "fit_material.py"), "--out",
                          str(tmp_path / "fit.png")], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    last = out.stdout.strip().splitlines()[-1]
    assert last.startswith("max relative parameter error: ")
    assert float(last.split(":")[1]) <= 1e-3
    assert (tmp_path / "fit.png").is_file()


FIT_STEPS = """
import json, sys
import jax, jax.numpy as jnp
import raytracer as rt
compiles = []
def listen(name, *_, **__):
    if name == "/jax/core/compile/backend_compile_duration":
        compiles.append(1)

jax.monitoring.register_event_duration_secs_listener(listen)
scene = rt.load_scene("camera { location <0, 0, -4> look_at 0 } light_source { <2, 3, -4> rgb 1 } "
                      "sphere { 0, 1 pigment { rgb 1 } }")
full = rt.params.parameters(scene)
target = rt.render(scene, width=64, height=48, spp=4)  # (split over both devices)
name = "objects[0].shape.center"

def loss(x):
    image = rt.render(rt.params.replace(scene, {**full, name: x}), width=64, height=48, spp=4)
    return jnp.mean((image - target) ** 2)

step = jax.jit(jax.value_and_grad(loss))
x = rt.params.placed(full[name] + jnp.asarray([0.1, -0.1, 0.0]))
counts = []
for _ in range(3):
    before = len(compiles)
    value, grad = step(x)
    x = x - 0.1 * grad
    counts.append(len(compiles) - before)
json.dump({"devices": len(jax.local_devices()), "compiles": counts}, open(sys.argv[1], "w"))
"""


def test_a_fits_step_compiles_once_from_placed_values(tmp_path, two_device_env):
    """With two devices the render runs on both, so a fit's step returns gradients placed on both;
    parameters made on one device are another input to ``jit`` and the step would trace and compile
    again at its second call. Started from ``params.placed`` values (placed as the render takes
    them): three steps, one compile of the step (from unplaced values: two)."""
    import json
    import subprocess
    import sys

    env = {**two_device_env, "RAYTRACER_CACHE_DIR": "off"}
    run = subprocess.run([sys.executable, "-c", FIT_STEPS, str(tmp_path / "out.json")], env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads((tmp_path / "out.json").read_text())
    assert got["devices"] == 2
    assert got["compiles"][0] >= 1 and got["compiles"][1:] == [0, 0]
