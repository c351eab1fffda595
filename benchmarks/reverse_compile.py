"""Cold cost of a reverse-mode program for each example scene: trace and XLA compile.

    python -m benchmarks.reverse_compile [--size W H] [--out FILE] [scene.pov ...]

For each scene (default: every ``examples/scenes/*.pov``), ``jax.jit(jax.grad(loss))`` of the
image MSE ``mean(render(scene)²)`` at 8×6 is lowered (trace, linearise, transpose: ``lower_s``) and
compiled by XLA (``compile_s``), in this process, with JAX's caches cleared between scenes and
the persistent cache off (the target: reverse-mode compile ≤ 10 s for every example scene).
XLA's flags are raytracer's defaults (``raytracer/_xla.py``), as a user gets them.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def measure(path: Path, width: int, height: int) -> tuple[float, float]:
    import jax
    import jax.numpy as jnp

    from raytracer import load_scene, render

    scene = load_scene(path, width=width, height=height)

    def loss(s):
        return jnp.mean(render(s, width=width, height=height) ** 2)

    jax.clear_caches()
    t0 = time.perf_counter()
    lowered = jax.jit(jax.grad(loss)).lower(scene)
    t1 = time.perf_counter()
    lowered.compile()
    return t1 - t0, time.perf_counter() - t1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", type=Path)
    ap.add_argument("--size", nargs=2, type=int, default=(8, 6), metavar=("W", "H"))
    ap.add_argument("--out", type=Path, help="also write the table to this file")
    args = ap.parse_args(argv)
    import raytracer  # noqa: F401, I001  (its XLA flags before JAX starts)
    import jax

    scenes = args.scenes or sorted((ROOT / "examples" / "scenes").glob("*.pov"))
    lines = ["| scene | lower s | compile s | total s |", "|---|---|---|---|"]
    totals = []
    cached = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)  # cold compiles
    try:
        for path in scenes:
            lower_s, compile_s = measure(path, *args.size)
            totals.append(lower_s + compile_s)
            lines.append(f"| {path.stem} | {lower_s:.1f} | {compile_s:.1f} | {lower_s + compile_s:.1f} |")
            print(lines[-1], flush=True)
    finally:
        jax.config.update("jax_enable_compilation_cache", cached)
    summary = (f"median {statistics.median(totals):.1f} s, max {max(totals):.1f} s, "
               f"{sum(t > 10 for t in totals)} of {len(totals)} over 10 s")
    print(summary)
    if args.out:
        args.out.write_text("\n".join(lines + ["", summary]) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
