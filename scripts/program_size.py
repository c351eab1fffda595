"""How big a scene's render program is, and which raytracer functions make it so (compile time).

    python scripts/program_size.py SCENE.pov [WIDTH HEIGHT] [--top N] [--paths FUNCTION [--depth D]]
                                                        [--compile]

Traces the program ``render`` compiles for the scene (one part, ``FIRST_CAPACITY``) to a jaxpr and
counts its equations, those of nested bodies (scan, while, cond, inner jits) included, by the
innermost raytracer function of each equation's traceback; an equation of an inner jit (a jnp
function's body) counts for the function that called it. ``--paths F`` instead counts the
equations made under function ``F`` by the chain of raytracer callers above it: where a kernel is
traced more than once (a shape's ``hits`` for camera rays, for shadow rays, in the hierarchy's
leaves). ``--compile`` also lowers and compiles it and reports the times and XLA's optimised
instruction and fusion counts.

The jaxpr's size is a guide to XLA's compile time, not a measure of it: XLA's CPU compile is mostly
LLVM's code generation of the fusions (measured: 2.2 s of the seed scene's 3.3 s under the
profiler, split over 32 modules that compile in parallel).
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import time


def _frame_key(frames) -> str | None:
    frame = next((f for f in frames if f"{os.sep}raytracer{os.sep}" in f.file_name), None)
    return None if frame is None else f"{os.path.basename(frame.file_name)}:{frame.function_name}"


def _path_key(frames, function: str, depth: int = 5) -> str | None:
    ours = [f for f in frames if f"{os.sep}raytracer{os.sep}" in f.file_name]
    at = next((i for i, f in enumerate(ours) if f.function_name == function), None)
    if at is None:
        return None
    return " < ".join(f"{f.function_name}:{f.line_num}" for f in ours[at + 1:at + 1 + depth]) or "(top)"


def count(jaxpr, key_of, parent=None, counts=None) -> collections.Counter:
    """Equations of ``jaxpr`` and its nested bodies by ``key_of(traceback frames)``; an equation
    without a key counts for the equation whose body holds it."""
    import jax

    counts = collections.Counter() if counts is None else counts
    for eqn in jaxpr.eqns:
        frames = eqn.source_info.traceback.frames if eqn.source_info.traceback else []
        key = key_of(frames) or parent
        if key is not None:
            counts[key] += 1
        for value in eqn.params.values():
            for sub in value if isinstance(value, (tuple, list)) else (value,):
                if isinstance(sub, jax.extend.core.ClosedJaxpr):
                    count(sub.jaxpr, key_of, key, counts)
                elif isinstance(sub, jax.extend.core.Jaxpr):
                    count(sub, key_of, key, counts)
    return counts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("size", nargs="*", type=int, default=[160, 120], help="WIDTH HEIGHT (160 120)")
    parser.add_argument("--top", type=int, default=30)
    parser.add_argument("--paths", metavar="FUNCTION", help="count FUNCTION's equations by its callers")
    parser.add_argument("--depth", type=int, default=5, help="callers shown per path (--paths)")
    parser.add_argument("--compile", action="store_true", help="also lower and compile, and time both")
    args = parser.parse_args(argv)
    if len(args.size) != 2:
        parser.error("give both WIDTH and HEIGHT, or neither")
    width, height = args.size

    import importlib

    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from raytracer import SceneError, load_scene

    packing = importlib.import_module("raytracer._packed")
    tiles = importlib.import_module("raytracer._tiles")
    folder = os.path.dirname(os.path.abspath(args.scene))
    try:
        scene = load_scene(args.scene, include_paths=[folder, "/usr/share/povray-3.7/include"])
    except (SceneError, OSError) as e:
        print(f"program_size: {e}", file=sys.stderr)
        return 2
    packed = packing.pack(scene)
    arrays, static = eqx.partition(packed, eqx.is_array)

    def program(a):
        p = eqx.combine(a, static)
        return tiles._render_tiles(p, packing._plan_of(p), width, height, 1, 1, jnp.asarray(0),
                                   tiles.FIRST_CAPACITY)

    start = time.perf_counter()
    closed = jax.make_jaxpr(program)(arrays)
    traced = time.perf_counter() - start
    if args.paths:
        counts = count(closed.jaxpr, lambda frames: _path_key(frames, args.paths, args.depth))
        print(f"{args.scene}: {sum(counts.values())} equations under {args.paths}, by caller")
    else:
        counts = count(closed.jaxpr, _frame_key)
        print(f"{args.scene} at {width}x{height}: {sum(counts.values())} equations "
              f"(traced in {traced:.2f} s)")
    for key, n in counts.most_common(args.top):
        print(f"{n:8d}  {key}")
    if args.compile:
        start = time.perf_counter()
        lowered = tiles._render_part.lower(packed, width, height, 1, 1, jnp.asarray(0),
                                           tiles.FIRST_CAPACITY)
        middle = time.perf_counter()
        compiled = lowered.compile()
        end = time.perf_counter()
        hlo = compiled.compiled.as_text()
        instructions = sum(1 for line in hlo.splitlines()
                           if " = " in line and not line.lstrip().startswith("//"))
        print(f"trace + lower {middle - start:.2f} s, XLA compile {end - middle:.2f} s "
              f"(persistent cache: {jax.config.jax_compilation_cache_dir or 'off'}); optimised HLO: "
              f"{instructions} instructions, {hlo.count('fusion(')} fusion calls")
    return 0


if __name__ == "__main__":
    sys.exit(main())
