"""Our gradients against Mitsuba 3's automatic differentiation (semantics §7).

For a Mitsuba-matchable scene (parallel lights, Lambert diffuse, spheres and planes; see
:mod:`validation.mitsuba`), both renderers evaluate the same image loss

    L = mean over pixels and channels of (image − target)²

against one fixed target image (ours, rendered with other material and light values), with one ray
through each pixel centre, and we compare

* dL/dρ for every solid-pigment object, where ρ = diffuse·P is Mitsuba's diffuse ``reflectance``
  (ours: ``jax.grad`` w.r.t. the pigment colour, divided by ``diffuse``), and
* dL/dE for every light, where E = π·C is Mitsuba's directional ``irradiance`` (ours: the gradient
  w.r.t. the light colour C, divided by π).

Mitsuba's side is the ``prb`` integrator (path replay backpropagation, ``max_depth 2`` = direct
light only) in ``llvm_ad_rgb``, with its primary rays moved to the pixel centres (``PRBCentres``
below; Mitsuba's own ``sample_rays`` jitters them over the pixel). With a directional light and no
area emitters, one sample per pixel is then deterministic. ``seed != seed_grad`` as Mitsuba requires.

``python -m validation --against gradients`` prints one line per parameter with the relative error
``|ours − mitsuba| / |mitsuba|`` (largest over RGB) and fails above :data:`MAX_REL_ERROR`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np

from . import mitsuba as vm

SCENES_DIR = Path(__file__).resolve().parent / "scenes"
# Single-light scenes without ambient: prb picks ONE emitter per sample (two lights would make one
# sample per pixel noisy), and Mitsuba's stand-in for POV's ambient is an area emitter that prb's
# second bounce would also see as indirect light.
SCENES = ("lambert_sphere", "scaled_spheres")
WIDTH, HEIGHT = 64, 48
# Measured: ≤ 2e-3 (edge pixels, where a centre ray lies within float32 precision of a silhouette
# or shadow edge, differ between float32 Mitsuba and float64 us); threshold with a margin.
MAX_REL_ERROR = 1e-2


@dataclasses.dataclass(frozen=True)
class GradientResult:
    scene: str
    parameter: str  # e.g. "objects[1] reflectance" or "lights[0] irradiance"
    ours: np.ndarray  # (3,)
    mitsuba: np.ndarray  # (3,)

    @property
    def rel_error(self) -> float:
        return float(np.max(np.abs(self.ours - self.mitsuba)) / max(np.max(np.abs(self.mitsuba)), 1e-12))

    @property
    def passed(self) -> bool:
        return self.rel_error <= MAX_REL_ERROR

    def line(self) -> str:
        fmt = lambda v: "[" + ", ".join(f"{x:+.6e}" for x in v) + "]"  # noqa: E731
        return (f"{self.scene:16s} {self.parameter:24s} ours {fmt(self.ours)}  mitsuba {fmt(self.mitsuba)}  "
                f"rel {self.rel_error:.2e}  {'ok' if self.passed else 'FAIL'}")


def _register_prb_centres(mi, dr):
    from mitsuba.ad.integrators.prb import PRBIntegrator

    class PRBCentres(PRBIntegrator):
        """``prb`` with every primary ray through its pixel centre (POV-Ray ``-A``, our ``spp=1``)."""

        def sample_rays(self, scene, sensor, sampler):
            film = sensor.film()
            size = film.crop_size()
            spp = sampler.sample_count()
            idx = dr.arange(mi.UInt32, dr.prod(size) * spp) // spp
            pos = mi.Vector2i()
            pos.y = idx // size[0]
            pos.x = idx - pos.y * size[0]
            sampler.next_2d()  # keep the sampler's dimension bookkeeping as in Mitsuba
            centre = (mi.Vector2f(pos) + 0.5) / mi.ScalarVector2f(size)
            with dr.resume_grad():
                ray, weight = sensor.sample_ray_differential(time=0.0, sample1=0.0, sample2=centre,
                                                             sample3=mi.Vector2f(0.5))
            return ray, weight, mi.Vector2f(pos)

    mi.register_integrator("prb_centres", lambda props: PRBCentres(props))


def _our_gradients(scene, target, width, height):
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    import raytracer as rt

    p, rest = eqx.partition(scene, eqx.is_inexact_array)

    def loss(p):
        return jnp.mean((rt.render(eqx.combine(p, rest), width=width, height=height) - target) ** 2)

    g = jax.jit(jax.grad(loss))(p)
    out = {}
    for i, obj in enumerate(scene.objects):
        pig, fin = obj.texture.layers[0].pigment, obj.texture.layers[0].finish
        if pig.pattern == "solid":
            out[f"objects[{i}] reflectance"] = np.asarray(
                g.objects[i].texture.layers[0].pigment.colors[0, :3]) / float(fin.diffuse)
    for k in range(len(scene.lights)):
        out[f"lights[{k}] irradiance"] = np.asarray(g.lights[k].color) / math.pi
    return out


def _mitsuba_gradients(scene, target, width, height, names):
    mi = vm.mitsuba()
    import drjit as dr

    if not mi.variant().startswith("llvm_ad") and not mi.variant().startswith("cuda_ad"):
        raise RuntimeError(f"Mitsuba variant {mi.variant()!r} has no AD (needs llvm_ad_rgb)")
    if "prb_centres" not in getattr(mi, "_raytracer_registered", set()):
        _register_prb_centres(mi, dr)
        mi._raytracer_registered = {"prb_centres"}
    d = vm.to_mitsuba(scene, width, height)
    d = dict(d)
    d["integrator"] = {"type": "prb_centres", "max_depth": 2, "hide_emitters": True}
    # the converter names shapes in scene order; find each object's reflectance key
    shape_keys = [k for k in d if k.split("_")[0] in ("sphere", "rectangle", "cube", "cylinder", "disk")]
    mi_scene = mi.load_dict(d)
    params = mi.traverse(mi_scene)
    keys = {}
    for name in names:
        m = re.match(r"objects\[(\d+)\] reflectance", name)
        if m:
            shape = shape_keys[int(m.group(1))]
            keys[name] = next(k for k in params.keys()
                              if k.startswith(shape + ".") and k.endswith("reflectance.value"))
        m = re.match(r"lights\[(\d+)\] irradiance", name)
        if m:
            keys[name] = f"light_{m.group(1)}.irradiance.value"
    for k in keys.values():
        dr.enable_grad(params[k])
    params.update()
    img = mi.render(mi_scene, params, spp=1, seed=0, seed_grad=1)
    ref = mi.TensorXf(np.asarray(target, dtype=np.float32))
    loss = dr.mean(dr.square(img - ref), axis=None)
    dr.backward(loss)
    return {name: np.array(dr.grad(params[k]), dtype=np.float64).ravel()[:3] for name, k in keys.items()}, \
        np.asarray(img, dtype=np.float64)


def target_scene(scene):
    """The scene the target image is rendered from: reflectances × (0.6, 1.1, 0.8) (capped at 0.95),
    light colours × 0.85 — far enough from ``scene`` for every gradient to be clearly non-zero."""
    import equinox as eqx
    import jax.numpy as jnp

    out = scene
    for i, obj in enumerate(scene.objects):
        pig = obj.texture.layers[0].pigment
        scaled = jnp.minimum(pig.colors[:, :3] * jnp.array([[0.6, 1.1, 0.8]]), 0.95)
        colours = jnp.asarray(pig.colors).at[:, :3].set(scaled)
        out = eqx.tree_at(lambda s, i=i: s.objects[i].texture.layers[0].pigment.colors, out, colours)
    for k, light in enumerate(scene.lights):
        out = eqx.tree_at(lambda s, k=k: s.lights[k].color, out, light.color * 0.85)
    return out


def compare(name: str, width: int = WIDTH, height: int = HEIGHT) -> list[GradientResult]:
    """Gradient comparison for the suite scene ``validation/scenes/<name>.pov``."""
    import jax

    import raytracer as rt

    with jax.enable_x64(True):
        scene = rt.load_scene(SCENES_DIR / f"{name}.pov", width=width, height=height)
        target = np.asarray(rt.render(target_scene(scene), width=width, height=height))
        ours = _our_gradients(scene, target, width, height)
    theirs, _ = _mitsuba_gradients(scene, target, width, height, list(ours))
    return [GradientResult(name, n, ours[n], theirs[n]) for n in ours]


def run(names=SCENES, on_result=None) -> list[GradientResult]:
    results = []
    for name in names:
        for r in compare(name):
            results.append(r)
            if on_result is not None:
                on_result(r)
    return results


def main() -> int:
    results = run(on_result=lambda r: print(r.line(), flush=True))
    bad = [r for r in results if not r.passed]
    print(f"gradients: {len(results) - len(bad)} of {len(results)} parameters within "
          f"{MAX_REL_ERROR:g} relative error of Mitsuba prb; {len(bad)} fail")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
