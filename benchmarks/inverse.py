"""Inverse rendering of geometry: fits that need the boundary term (``render(…, edges=True)``).

Each fit renders a target, starts the parameters away from it and runs Adam on the mean squared
image difference over its views (float32, 64×48, 16 samples a pixel), once with the boundary term
and once without. It reports, per fit and mode: converged (the parameter error cut tenfold or
more), the start and final errors, the steps taken, the warm time of one forward + backward pass
and the first call's time (trace and compile).

    python -m benchmarks.inverse [--steps 150] [--json benchmarks/results/inverse.json]

Fits:

* ``sphere``: a lit sphere's centre and radius from its outline in two views (a second view
  separates depth from size), started 30 % of the radius off in each.
* ``box``: a box's two corners from two views, started 0.3 units off.
* ``camera``: a camera's place over a checker floor (its look_at fixed), started 0.3 units off in
  each coordinate: the checker's cell edges are the signal.
* ``light``: a point light's place from the shadow a sphere casts on a plain floor, started 0.3
  units off in each coordinate (the floor's shading moves with it too).
* ``shadow``: the centre of a sphere the camera does not see (``no_image``) from the shadows it
  casts on a plain floor in two lights, started 30 % of its radius off in each axis: the shadows'
  outlines are the only signal.
* ``penumbra``: the same unseen sphere from the penumbra it casts in an area light of 4×4
  samples (each sample's shadow outline is an edge of the term's), started as ``shadow``.

* ``ior``: the index of refraction of a glass sphere in front of a checker wall, started 0.15 low:
  the cell edges seen through the glass move with it.
* ``mesh``: the eight vertices of a box-shaped flat mesh of twelve triangles (24 numbers; the
  triangles take them by index, so the mesh stays closed) from two views from opposite corners,
  which between them see every face, each coordinate started 0.1–0.2 units off (fixed seed): its
  outline and its creases are the signal.

``--new-processes``: each fit's first call (trace, lowering and compile of its step) in a new
process with an empty JAX persistent compilation cache, then in another with the cache it filled
(``benchmarks/results/inverse-first-calls.json``).

``--batched``: the warm forward + backward time and the first call of one loss over five views
of a sphere on a floor (its centre the parameter), the views as a Python loop in one program,
``jax.vmap`` and ``jax.lax.map``, with the term and without.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

import raytracer as rt

WIDTH, HEIGHT, SPP = 64, 48, 16

VIEWS = ("camera { location <0, 0.6, -4> look_at <0, 0, 0> angle 40 }",
         "camera { location <4, 0.6, 0> look_at <0, 0, 0> angle 40 }")
LIGHT = "light_source { <-3, 5, -6> rgb 1 } light_source { <6, 4, 2> rgb 0.6 }"
CHECKER = ("plane { y, -0.8 pigment { checker rgb <0.9, 0.85, 0.7> rgb <0.15, 0.2, 0.3> scale 0.9 "
           "translate <0.3, 0, 0.2> } }")
FLOOR_VIEW = ("camera { location <0.5, 2.5, -3.5> look_at <0, -0.8, 0> angle 50 }",)
# a box's six faces by the index 4x + 2y + z of the corner each takes
_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))
FITS = {  # name: (objects, offsets of the parameters from the truth, views, lights[, Derived])
    "sphere": ("sphere { <0.2, 0.1, 0.3>, 0.8 pigment { rgb <1, 0.6, 0.3> } }",
               {"objects[0].shape.center": np.array([0.24, -0.24, 0.24]),  # 0.3·r off in each axis
                "objects[0].shape.radius": np.array(0.24)}, VIEWS, LIGHT),
    "box": ("box { <-0.7, -0.5, -0.6>, <0.6, 0.4, 0.5> pigment { rgb <0.3, 0.6, 1> } }",
            {"objects[0].shape.corner1": np.array([0.3, -0.3, 0.3]),
             "objects[0].shape.corner2": np.array([-0.3, 0.3, 0.3])}, VIEWS, LIGHT),
    "camera": (CHECKER, {"camera.location": np.array([0.3, -0.3, 0.3])}, FLOOR_VIEW, LIGHT),
    "light": ("plane { y, -0.8 pigment { rgb 0.8 } }\n"
              "sphere { <0, 0.1, 0.3>, 0.5 pigment { rgb <1, 0.6, 0.3> } }",
              {"lights[0].position": np.array([0.3, -0.3, 0.3])}, FLOOR_VIEW,
              "light_source { <-1.5, 3, -2> rgb 1 }"),
    "shadow": ("plane { y, -0.8 pigment { rgb 0.8 } }\n"
               "sphere { <0, 0.1, 0.3>, 0.5 pigment { rgb 1 } no_image }",
               {"objects[1].shape.center": np.array([0.15, -0.15, 0.15])}, FLOOR_VIEW, LIGHT),
    "penumbra": ("plane { y, -0.8 pigment { rgb 0.8 } }\n"
                 "sphere { <0, 0.1, 0.3>, 0.5 pigment { rgb 1 } no_image }",
                 {"objects[1].shape.center": np.array([0.15, -0.15, 0.15])}, FLOOR_VIEW,
                 "light_source { <-1.5, 3, -2> rgb 1 area_light <1.5, 0, 0>, <0, 0, 1.5>, 4, 4 }"),
    "ior": ("plane { z, 3 pigment { checker rgb <0.9, 0.85, 0.7> rgb <0.15, 0.2, 0.3> scale 0.5 } }\n"
            "sphere { 0, 1 pigment { rgbf <1, 1, 1, 0.95> } finish { ambient 0 diffuse 0 } "
            "interior { ior 1.5 } }",
            {"objects[1].interior.ior": np.array(-0.15)}, VIEWS[:1], LIGHT),
}


class Derived(NamedTuple):
    """Fitted values that are not the scene's own parameters: their truth, and the scene's
    parameters they make."""

    truth: dict
    scene_params: Callable[[dict], dict]


MESH_FACES = np.array([(q[0], q[1], q[2]) for q in _QUADS] + [(q[0], q[2], q[3]) for q in _QUADS])
MESH_VERTICES = np.array([[x, y, z] for x in (-0.7, 0.6) for y in (-0.5, 0.4) for z in (-0.6, 0.5)])
_rng = np.random.default_rng(7)
_offsets = _rng.uniform(0.1, 0.2, (8, 3)) * _rng.choice([-1.0, 1.0], (8, 3))
FITS["mesh"] = (
    "mesh { " + " ".join("triangle { " + ", ".join("<{}, {}, {}>".format(*MESH_VERTICES[i]) for i in f) + " }"
                         for f in MESH_FACES) + " pigment { rgb <0.3, 0.6, 1> } }",
    {"vertices": _offsets},
    ("camera { location <-3, 2.5, -3> look_at <0, 0, 0> angle 40 }",
     "camera { location <3, -2.5, 3> look_at <0, 0, 0> angle 40 }"), LIGHT,
    Derived({"vertices": jnp.asarray(MESH_VERTICES, jnp.float32)},
            lambda p: {"objects[0].shape.triangles": p["vertices"][jnp.asarray(MESH_FACES)]}))


def _scenes(body: str, views, lights: str):
    return [rt.load_scene(f"#version 3.7; global_settings {{ assumed_gamma 1.0 }}\n{view}\n{lights}\n{body}",
                          width=WIDTH, height=HEIGHT) for view in views]


def fit(name: str, edges: bool, steps: int, rate: float = 0.02) -> dict:
    """Adam on the views' mean squared difference; the record of the fit."""
    body, offsets, views, lights, *derived = FITS[name]
    derived = derived[0] if derived else Derived({}, lambda p: p)
    scenes = _scenes(body, views, lights)
    params = [rt.params.parameters(s) for s in scenes]
    # (placed as the render takes them, as params.parameters' are: the step then compiles once)
    truth = rt.params.placed({n: jnp.asarray(derived.truth[n] if n in derived.truth else params[0][n])
                              for n in offsets})
    targets = [rt.render(s, width=WIDTH, height=HEIGHT, spp=SPP) for s in scenes]

    def loss(p):
        total = 0.0
        for scene, full, target in zip(scenes, params, targets, strict=True):
            image = rt.render(rt.params.replace(scene, {**full, **derived.scene_params(p)}), width=WIDTH,
                              height=HEIGHT, spp=SPP, edges=edges)
            total = total + jnp.mean((image - target) ** 2)
        return total / len(scenes)

    step = jax.jit(jax.value_and_grad(loss))
    x = {n: truth[n] + jnp.asarray(offsets[n], truth[n].dtype) for n in offsets}

    def error(p):
        return float(np.sqrt(sum(float(jnp.sum((p[n] - truth[n]) ** 2)) for n in p)))

    start_error = error(x)
    t0 = time.perf_counter()
    jax.block_until_ready(step(x))
    first = time.perf_counter() - t0
    m = {n: jnp.zeros_like(v) for n, v in x.items()}
    v = {n: jnp.zeros_like(v) for n, v in x.items()}
    times, taken = [], 0
    for i in range(1, steps + 1):
        t0 = time.perf_counter()
        value, grad = jax.block_until_ready(step(x))
        times.append(time.perf_counter() - t0)
        for n in x:  # Adam
            m[n] = 0.9 * m[n] + 0.1 * grad[n]
            v[n] = 0.999 * v[n] + 0.001 * grad[n] ** 2
            x[n] = x[n] - rate * (m[n] / (1 - 0.9 ** i)) / (jnp.sqrt(v[n] / (1 - 0.999 ** i)) + 1e-12)
        taken = i
        if error(x) < start_error / 100:
            break
    if steps == 0:
        return {"fit": name, "edges": edges, "first_call_s": first}
    final = error(x)
    return {"fit": name, "edges": edges, "converged": final <= start_error / 10, "start_error": start_error,
            "final_error": final, "steps": taken, "warm_fwd_bwd_s": float(np.median(times)),
            "first_call_s": first, "final_loss": float(value)}


def new_process_first_calls(name: str, edges: bool) -> dict:
    """The first call of a fit's step in a new process: with an empty persistent compilation cache
    (a temporary one), then in another new process with the cache the first one filled."""
    import os
    import subprocess
    import sys
    import tempfile

    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "JAX_COMPILATION_CACHE_DIR": cache,
               "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0",
               "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "0"}
        for key in ("empty_cache_s", "warm_cache_s"):
            run = subprocess.run([sys.executable, "-m", "benchmarks.inverse", "--first-call", name,
                                  *(["--no-edges"] if not edges else [])],
                                 env=env, capture_output=True, text=True, check=True)
            out[key] = json.loads(run.stdout.strip().splitlines()[-1])["first_call_s"]
    return {"fit": name, "edges": edges, **out}


BATCH = ("plane { y, -0.8 pigment { rgb 0.8 } }\n"
         "sphere { <0.2, 0.1, 0.3>, 0.8 pigment { rgb <1, 0.6, 0.3> } }")


def batched(mode: str, edges: bool, repeats: int = 10) -> dict:
    """One loss over five views (``mode``: "loop", "vmap" or "map"): warm fwd+bwd and first call."""
    scene = _scenes(BATCH, VIEWS[:1], LIGHT)[0]
    params = rt.params.parameters(scene)
    angles = np.linspace(0.0, 1.2, 5)
    places = np.stack([4 * np.sin(angles), np.full(5, 0.6), -4 * np.cos(angles)], -1)
    places = jnp.asarray(places, jnp.float32)

    def image(place, centre):
        moved = rt.params.replace(scene, {**params, "camera.location": place,
                                          "objects[1].shape.center": centre})
        return rt.render(moved, width=WIDTH, height=HEIGHT, spp=SPP, edges=edges)

    def loss(centre):
        if mode == "vmap":
            images = jax.vmap(image, in_axes=(0, None))(places, centre)
        elif mode == "map":
            images = jax.lax.map(lambda place: image(place, centre), places)
        else:
            images = jnp.stack([image(place, centre) for place in places])
        return jnp.mean(images ** 2)

    step = jax.jit(jax.value_and_grad(loss))
    centre = params["objects[1].shape.center"]
    t0 = time.perf_counter()
    jax.block_until_ready(step(centre))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(step(centre))
        times.append(time.perf_counter() - t0)
    return {"views": mode, "edges": edges, "warm_fwd_bwd_s": float(np.median(times)), "first_call_s": first}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--fits", nargs="*", default=list(FITS))
    ap.add_argument("--json", type=Path)
    ap.add_argument("--batched", action="store_true", help="five views as a loop, vmap and lax.map")
    ap.add_argument("--new-processes", action="store_true",
                    help="each fit's first call in a new process, with an empty and a warm compilation cache")
    # one first call, for --new-processes
    ap.add_argument("--first-call", metavar="FIT", help=argparse.SUPPRESS)
    ap.add_argument("--no-edges", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.first_call:
        print(json.dumps(fit(args.first_call, not args.no_edges, 0)))
        return
    if args.new_processes:
        print(f"{'fit':8} {'edges':6} {'empty cache s':>13} {'warm cache s':>12}")
        firsts = []
        for name in args.fits:
            for edges in (True, False):
                r = new_process_first_calls(name, edges)
                firsts.append(r)
                print(f"{name:8} {edges!s:6} {r['empty_cache_s']:13.1f} {r['warm_cache_s']:12.1f}",
                      flush=True)
        if args.json:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps({"width": WIDTH, "height": HEIGHT, "spp": SPP,
                                             "new_process_first_calls": firsts}, indent=1))
        return
    rows = []
    print(f"{'fit':8} {'edges':6} {'conv':5} {'start':>8} {'final':>9} {'steps':>5} {'fwd+bwd ms':>10} "
          f"{'first s':>8}")
    for name in args.fits:
        for edges in (True, False):
            r = fit(name, edges, args.steps)
            rows.append(r)
            print(f"{name:8} {edges!s:6} {r['converged']!s:5} {r['start_error']:8.4f} "
                  f"{r['final_error']:9.5f} "
                  f"{r['steps']:5d} {1e3 * r['warm_fwd_bwd_s']:10.1f} {r['first_call_s']:8.1f}", flush=True)
    views = []
    if args.batched:
        print(f"{'views':8} {'edges':6} {'fwd+bwd ms':>10} {'first s':>8}")
        for mode in ("loop", "vmap", "map"):
            for edges in (True, False):
                r = batched(mode, edges)
                views.append(r)
                print(f"{mode:8} {edges!s:6} {1e3 * r['warm_fwd_bwd_s']:10.1f} {r['first_call_s']:8.1f}",
                      flush=True)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        record = {"width": WIDTH, "height": HEIGHT, "spp": SPP, "fits": rows, "batched": views}
        args.json.write_text(json.dumps(record, indent=1))


if __name__ == "__main__":
    main()
