"""Inverse rendering with Optimistix: recover material parameters from an image.

Part one renders a target image of a small scene (a smooth gradient wall, a phong + reflective
sphere, a glass sphere in front of the wall), perturbs the sphere's pigment colour, diffuse,
phong and reflection and the glass sphere's ior, and recovers them with Levenberg–Marquardt
(``optimistix.least_squares``) on the per-pixel residuals. The parameters are picked by name with
``raytracer.params.split``. It prints a table (parameter, true, start, recovered, relative error) and
saves a plot: the loss per LM step, and the target / start / fitted images.

Part two fits the Lambert reflectance ρ = diffuse·P of a Mitsuba-matchable scene to a target that
Mitsuba 3 rendered (rays through pixel centres) and compares the result with the ρ Mitsuba used.
It is skipped, with a message, when Mitsuba is not installed.

    python examples/fit_material.py [--out PATH.png] [--no-mitsuba]

The last line printed is ``max relative parameter error: X`` for part one.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import raytracer as rt
from raytracer import params

jax.config.update("jax_enable_x64", True)

WIDTH, HEIGHT, DEPTH = 40, 30, 3

SPHERE = "objects[1].texture.layers[0]"
FIT = {  # name: perturbed start value
    f"{SPHERE}.pigment.colors": None,  # set below: rgb scaled, filter/transmit kept
    f"{SPHERE}.finish.diffuse": 0.45,
    f"{SPHERE}.finish.phong": 0.8,
    f"{SPHERE}.finish.reflection.max": (0.35, 0.3, 0.25),
    "objects[2].interior.ior": 1.4,
}


def demo_scene(width: int = WIDTH, height: int = HEIGHT, depth: int = DEPTH) -> rt.Scene:
    cam = rt.Camera(location=(0, 1.0, -5.0), look_at=(0, 0.8, 0), right=(width / height, 0, 0),
                    angle_degrees=45.0)
    # a gradient wall with a periodic colour map (first entry = last): continuous everywhere, even
    # where the pattern wraps, so no colour edge moves when refraction through the glass changes
    wall = rt.Pigment.mapped("gradient", [(0.0, (0.9, 0.35, 0.1)), (0.5, (0.2, 0.45, 0.9)),
                                          (1.0, (0.9, 0.35, 0.1))], vector=(1.0, 0.6, 0.0),
                             transform=rt.Transform.scale(9.0).then(rt.Transform.translate((-4, -2, 0))))
    glass = rt.Texture.of(rt.Pigment.solid((1, 1, 1), filter=0.0, transmit=1.0),
                          rt.Finish(ambient=(0, 0, 0), diffuse=0.0, conserve_energy=True,
                                    reflection=rt.Reflection(min=(0, 0, 0), max=(1, 1, 1), fresnel=True)))
    objects = (
        rt.Object(rt.Plane((0, 0, -1), -4.0), texture=rt.Texture.of(wall, rt.Finish(ambient=(0.2,) * 3,
                                                                                     diffuse=0.7))),
        rt.Object(rt.Sphere((1.0, 0.7, -1.2), 0.7), texture=rt.Texture.of(
            rt.Pigment.solid((0.8, 0.35, 0.2)),
            # ambient 0.3 (the ambient term sees P without diffuse) separates P from diffuse·P
            rt.Finish(ambient=(0.3,) * 3, diffuse=0.6, phong=0.5, phong_size=30.0,
                      reflection=rt.Reflection(min=(0.2,) * 3, max=(0.2,) * 3)))),
        rt.Object(rt.Sphere((-0.9, 0.9, 0.6), 0.7), texture=glass, interior=rt.Interior(ior=1.5)),
    )
    light = rt.Light(position=(-10, 15, -12), color=(1.0, 0.95, 0.9))
    return rt.Scene(camera=cam, objects=objects, lights=(light,),
                    settings=rt.Settings(max_trace_level=depth, adc_bailout=0.0))


def fit(scene_true: rt.Scene, start: dict, target, width: int, height: int, *, max_steps: int = 40):
    """Levenberg–Marquardt on the residuals ``render(scene) − target`` over the named parameters.

    Returns (fitted scene, loss per residual evaluation, wall time including compile)."""
    scene0 = params.replace(scene_true, start)
    y0, rest = params.split(scene0, list(start))
    losses: list[float] = []

    def record(loss):
        losses.append(float(loss))

    # a colour's filter and transmit channels are held at their start values: an opaque pigment
    # does not use them (zero gradient, docs/gradients.md), and a glass's are not fitted here
    colours = {n: params.get(y0, n) for n in start if n.endswith(".colors")}

    def residuals(y, args):
        y = params.replace(y, {n: params.get(y, n).at[:, 3:].set(c[:, 3:]) for n, c in colours.items()})
        img = rt.render(eqx.combine(y, rest), width=width, height=height)
        r = (img - target).reshape(-1)
        jax.debug.callback(record, jnp.mean(r * r))
        return r

    solver = optx.LevenbergMarquardt(rtol=1e-10, atol=1e-10)
    t0 = time.perf_counter()
    sol = optx.least_squares(residuals, solver, y0, max_steps=max_steps, throw=False)
    jax.block_until_ready(sol.value)
    y = params.replace(sol.value, {n: params.get(sol.value, n).at[:, 3:].set(c[:, 3:])
                                   for n, c in colours.items()})
    return eqx.combine(y, rest), losses, time.perf_counter() - t0


def table(scene_true, start: dict, fitted) -> float:
    """Prints one row per scalar parameter; returns the largest relative error."""
    print(f"{'parameter':52s} {'true':>9s} {'start':>9s} {'recovered':>11s} {'rel. error':>10s}")
    worst = 0.0
    for name in start:
        true = np.ravel(params.get(scene_true, name))
        s = np.ravel(np.asarray(start[name], dtype=np.float64))
        got = np.ravel(params.get(fitted, name))
        for i in range(true.size):
            if true.size > 1 and name.endswith(".colors") and i >= 3:
                continue  # filter and transmit are held at their true values
            label = name if true.size == 1 else f"{name}[{i}]"
            rel = abs(got[i] - true[i]) / max(abs(true[i]), 1e-12)
            worst = max(worst, rel)
            print(f"{label:52s} {true[i]:9.5f} {s[i]:9.5f} {got[i]:11.7f} {rel:10.2e}")
    return worst


def plot(path: Path, losses, images, titles):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 1 + len(images), figsize=(4 * (1 + len(images)), 3.4))
    axes[0].semilogy(np.arange(1, len(losses) + 1), losses, "o-", ms=3)
    axes[0].set_xlabel("residual evaluation (LM step)")
    axes[0].set_ylabel("mean squared residual")
    axes[0].set_title("loss")
    for ax, img, title in zip(axes[1:], images, titles, strict=True):
        ax.imshow(np.clip(np.asarray(img), 0, 1) ** (1 / 2.2))
        ax.set_title(title)
        ax.axis("off")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def part_one(out: Path) -> float:
    print(f"== part one: own target, {WIDTH}×{HEIGHT}, max_trace_level {DEPTH}, float64")
    scene = demo_scene()
    start = dict(FIT)
    colours = np.asarray(params.get(scene, f"{SPHERE}.pigment.colors")).copy()
    colours[0, :3] = (0.55, 0.5, 0.35)
    start[f"{SPHERE}.pigment.colors"] = colours
    t0 = time.perf_counter()
    target = rt.render(scene, width=WIDTH, height=HEIGHT)
    start_img = rt.render(params.replace(scene, start), width=WIDTH, height=HEIGHT)
    print(f"target and start images: {time.perf_counter() - t0:.1f} s (compile included)")
    fitted, losses, seconds = fit(scene, start, target, WIDTH, HEIGHT)
    print(f"Levenberg–Marquardt: {len(losses)} residual evaluations, {seconds:.1f} s (compile included); "
          f"loss {losses[0]:.3e} → {losses[-1]:.3e}")
    worst = table(scene, start, fitted)
    fitted_img = rt.render(fitted, width=WIDTH, height=HEIGHT)
    plot(out, losses, [target, start_img, fitted_img], ["target", "start", "fitted"])
    print(f"plot: {out}")
    return worst


def lambert_scene(width: int, height: int, rho) -> rt.Scene:
    """A Lambert sphere on a grey ground under one parallel light: Mitsuba-matchable (semantics §6)."""
    cam = rt.Camera(location=(0.13, 1.63, -5.11), look_at=(0.02, 0.61, 0.0), right=(width / height, 0, 0),
                    angle_degrees=50.0)
    diffuse = 0.9
    sphere = rt.Object(rt.Sphere((0, 0.8, 0), 0.8), texture=rt.Texture.of(
        rt.Pigment.solid(np.asarray(rho) / diffuse), rt.Finish(ambient=(0, 0, 0), diffuse=diffuse)))
    ground = rt.Object(rt.Plane((0, 1, 0), 0.0), texture=rt.Texture.of(
        rt.Pigment.solid((0.8, 0.8, 0.75)), rt.Finish(ambient=(0, 0, 0), diffuse=0.6)))
    light = rt.Light(position=(-30, 50, -20), point_at=(0, 0, 0), parallel=True)
    return rt.Scene(camera=cam, objects=(ground, sphere), lights=(light,),
                    settings=rt.Settings(max_trace_level=1, adc_bailout=0.0))


def part_two():
    print("== part two: Lambert reflectance ρ = diffuse·P against a Mitsuba target")
    try:
        from validation import mitsuba as vm

        vm.mitsuba()
    except Exception as e:  # noqa: BLE001 - any import/LLVM failure means "no Mitsuba here"
        print(f"skipped: Mitsuba is unavailable ({type(e).__name__}: {e})")
        return
    w, h = 24, 18
    rho_true = np.array([0.72, 0.27, 0.18])
    truth = lambert_scene(w, h, rho_true)
    t0 = time.perf_counter()
    target = vm.render_mitsuba_centres(truth, w, h, spp=1).astype(np.float64)
    print(f"Mitsuba target ({vm.variant()}, pixel centres): {time.perf_counter() - t0:.1f} s")
    name = "objects[1].texture.layers[0].pigment.colors"
    colours = np.asarray(params.get(truth, name)).copy()
    colours[0, :3] = 0.5
    fitted, losses, seconds = fit(truth, {name: colours}, jnp.asarray(target), w, h, max_steps=20)
    rho_fit = 0.9 * np.asarray(params.get(fitted, name))[0, :3]
    rel = np.abs(rho_fit - rho_true) / rho_true
    print(f"LM: {len(losses)} evaluations, {seconds:.1f} s; loss {losses[0]:.3e} → {losses[-1]:.3e}")
    print(f"{'channel':8s} {'Mitsuba ρ':>10s} {'recovered ρ':>12s} {'rel. error':>10s}")
    for c, name_c in enumerate("rgb"):
        print(f"{name_c:8s} {rho_true[c]:10.5f} {rho_fit[c]:12.7f} {rel[c]:10.2e}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default_out = Path(tempfile.gettempdir()) / "raytracer" / "fit_material.png"
    ap.add_argument("--out", type=Path, default=default_out,
                    help="where to save the plot (default: %(default)s)")
    ap.add_argument("--no-mitsuba", action="store_true", help="skip part two")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    worst = part_one(args.out)
    if args.no_mitsuba:
        print("== part two: skipped (--no-mitsuba)")
    else:
        part_two()
    print(f"total: {time.perf_counter() - t0:.1f} s")
    print(f"max relative parameter error: {worst:.3e}")
    return 0 if worst <= 1e-3 else 1


if __name__ == "__main__":
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    sys.exit(main())
