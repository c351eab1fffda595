"""Inverse rendering of a shape with Optimistix: a sphere's centre and radius from its outline.

A lit sphere is rendered from two views (a second view separates its depth from its size), then
fitted from a start 30 % of its radius off in every coordinate and in the radius, by
Levenberg–Marquardt (``optimistix.least_squares``) on the per-pixel residuals of both views. The
outline's motion is the whole of the signal — a flat-lit sphere's interior barely changes — so
the fit needs the boundary term (``render(…, edges=True)``); it runs once with it and once
without, and prints the parameters and errors of both.

    python examples/fit_shape.py [--steps 60] [--target mitsuba]

With ``--target mitsuba`` the targets are Mitsuba 3's renders of the same sphere (``validation/
mitsuba.py``'s converted scene, box-filtered film, 1,024 samples a pixel): the sphere is then a flat
emitter over black (``ambient 1``, no light: Mitsuba's point lights fall off with distance, POV-Ray's
do not), and the fit recovers it from another renderer's image, its Monte Carlo noise included.

The last line printed is ``error with edges: X (start S)``.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import raytracer as rt

WIDTH, HEIGHT, SPP = 48, 36, 16
VIEWS = ("camera { location <0, 0.6, -4> look_at <0, 0, 0> angle 40 }",
         "camera { location <4, 0.6, 0> look_at <0, 0, 0> angle 40 }")
BODY = ("light_source { <-3, 5, -6> rgb 1 } light_source { <6, 4, 2> rgb 0.6 }\n"
        "sphere { <0.2, 0.1, 0.3>, 0.8 pigment { rgb <1, 0.6, 0.3> } }")
# for a Mitsuba target: the same sphere as a flat emitter, square pixels (the converter's condition)
FLAT_BODY = "sphere { <0.2, 0.1, 0.3>, 0.8 pigment { rgb <1, 0.6, 0.3> } finish { ambient 1 diffuse 0 } }"
MITSUBA_SPP = 1024
NAMES = ("objects[0].shape.center", "objects[0].shape.radius")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--target", choices=("ours", "mitsuba"), default="ours",
                    help="who renders the target images (default: ours)")
    args = ap.parse_args(argv)
    mitsuba = args.target == "mitsuba"
    views = [v.replace("angle 40", f"angle 40 right x*{WIDTH}/{HEIGHT}") for v in VIEWS] if mitsuba else VIEWS
    body = FLAT_BODY if mitsuba else BODY
    scenes = [rt.load_scene(f"#version 3.7; global_settings {{ assumed_gamma 1.0 }}\n{v}\n{body}",
                            width=WIDTH, height=HEIGHT) for v in views]
    full = [rt.params.parameters(s) for s in scenes]
    truth = {n: jnp.asarray(full[0][n]) for n in NAMES}
    if mitsuba:
        from validation.mitsuba import render_mitsuba_film

        targets = [jnp.asarray(render_mitsuba_film(s, WIDTH, HEIGHT, spp=MITSUBA_SPP)) for s in scenes]
    else:
        targets = [rt.render(s, width=WIDTH, height=HEIGHT, spp=SPP) for s in scenes]
    # (placed as the render takes them: the solver's step then compiles once, docs/gradients.md)
    start = rt.params.placed({NAMES[0]: truth[NAMES[0]] + 0.24, NAMES[1]: truth[NAMES[1]] * 1.3})

    def error(p):
        return float(np.sqrt(sum(float(jnp.sum((p[n] - truth[n]) ** 2)) for n in NAMES)))

    errors = {}
    for edges in (True, False):
        def residuals(p, _, edges=edges):
            out = []
            for scene, params, target in zip(scenes, full, targets, strict=True):
                image = rt.render(rt.params.replace(scene, {**params, **p}), width=WIDTH, height=HEIGHT,
                                  spp=SPP, edges=edges)
                out.append((image - target).reshape(-1))
            return jnp.concatenate(out)

        solver = optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6)
        fitted = optx.least_squares(jax.jit(residuals), solver, start, max_steps=args.steps,
                                    throw=False).value
        print(f"edges={edges}: centre {np.round(np.asarray(fitted[NAMES[0]]), 4)} (true "
              f"{np.asarray(truth[NAMES[0]])}), radius {float(fitted[NAMES[1]]):.4f} (true "
              f"{float(truth[NAMES[1]])}); error {error(fitted):.5f} (start {error(start):.4f})", flush=True)
        errors[edges] = error(fitted)
    print(f"error with edges: {errors[True]:.5f} (start {error(start):.4f})")


if __name__ == "__main__":
    main()
