"""``raytracer compare SCENE``: one's own scene rendered by us and by POV-Ray (or Mitsuba 3), at the
same pixel centres, side by side.

    raytracer compare scene.pov [-W 160] [-H 120] [--against povray|mitsuba] [-o compare.png]
                                [-L DIR …] [--mitsuba-spp N]

Both images are linear: ours at one ray through each pixel centre (``spp 1``), POV-Ray's ``-A`` EXR
of the scene file as it is (our renderer follows the scene's gamma rules to the same linear image:
``benchmarks/sample_renders.py``), Mitsuba's the converted scene (``validation.mitsuba.to_mitsuba``,
which refuses what has no exact equivalent) with every ray through a pixel centre. Writes
``ours | reference | 4×|difference|`` (sRGB PNG), prints PSNR, RMSE, the largest difference, the
fraction of pixels within 0.01, and the worst region (the 8×8-pixel block of largest mean
difference), with both renderers' times. Exit status 0, or 2 for a scene or option error.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

BLOCK = 8  # pixels a side of the regions the worst one is chosen from


def worst_region(ours: np.ndarray, reference: np.ndarray, block: int = BLOCK):
    """``(x0, x1, y0, y1, mean |difference|)`` of the ``block``-pixel square (the last ones may be
    smaller) whose mean absolute difference over its pixels and channels is the largest."""
    diff = np.abs(np.asarray(ours, np.float64) - np.asarray(reference, np.float64)).mean(-1)
    h, w = diff.shape
    best = (0, 0, 0.0)
    for y in range(0, h, block):
        for x in range(0, w, block):
            m = float(diff[y:y + block, x:x + block].mean())
            if m > best[2]:
                best = (x, y, m)
    x, y, m = best
    return x, min(x + block, w) - 1, y, min(y + block, h) - 1, m


def side_by_side(ours: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(H, 3W + 2, 3) linear: ours | reference | 4×|difference|, two black columns between."""
    gap = np.zeros((ours.shape[0], 1, 3), np.float32)
    diff = np.clip(4.0 * np.abs(ours - reference), 0.0, 1.0)
    return np.concatenate([ours, gap, reference, gap, diff], axis=1).astype(np.float32)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="raytracer compare", description=__doc__.splitlines()[0])
    p.add_argument("scene", help="the .pov file")
    p.add_argument("-W", "--width", type=int, default=160, help="image width (default 160)")
    p.add_argument("-H", "--height", type=int, default=120, help="image height (default 120)")
    p.add_argument("--against", choices=("povray", "mitsuba"), default="povray",
                   help="the reference renderer (default povray)")
    p.add_argument("-o", "--output", default="compare.png",
                   help="the side-by-side PNG: ours | reference | 4×|difference| (default compare.png)")
    p.add_argument("-L", "--include-path", action="append", default=[], metavar="DIR",
                   help="extra folder to search for #include files (repeatable)")
    p.add_argument("--mitsuba-spp", type=int, default=16, metavar="N",
                   help="Mitsuba's estimates along each pixel-centre ray (glass is Monte Carlo there; "
                        "default 16)")
    return p


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    import raytracer as rt
    from raytracer.errors import SceneError

    from . import metrics

    if not (args.width > 0 and args.height > 0):
        print("raytracer compare: -W and -H must be positive", file=sys.stderr)
        return 2
    out = Path(args.output)
    if out.suffix.lower() != ".png" or not out.parent.is_dir():
        print(f"raytracer compare: cannot write {str(out)!r}: name a .png in an existing folder",
              file=sys.stderr)
        return 2
    try:
        t0 = time.perf_counter()
        scene = rt.load_scene(args.scene, include_paths=tuple(args.include_path), width=args.width,
                              height=args.height, fit_zero_terms=False)
        t1 = time.perf_counter()
        ours = np.asarray(rt.render(scene, width=args.width, height=args.height), np.float32)
        t2 = time.perf_counter()
    except SceneError as e:
        print(f"raytracer compare: {e}", file=sys.stderr)
        return 2
    timing = f"ours: parse {t1 - t0:.2f} s, compile and render {t2 - t1:.2f} s"
    if args.against == "povray":
        from .povray import PovrayError, PovrayUnavailable, run_povray

        try:
            run = run_povray(args.scene, args.width, args.height, include_paths=args.include_path)
        except (PovrayUnavailable, PovrayError) as e:
            print(f"raytracer compare: {e}", file=sys.stderr)
            return 2
        reference = run.image
        timing += (f"; POV-Ray: parse {run.parse_seconds or 0:.2f} s, trace {run.trace_seconds or 0:.2f} s "
                   "(its own report)")
    else:
        from .mitsuba import NotMatchable, render_mitsuba_centres

        try:
            t3 = time.perf_counter()
            reference = render_mitsuba_centres(scene, args.width, args.height, spp=args.mitsuba_spp)
            timing += f"; Mitsuba: {time.perf_counter() - t3:.2f} s ({args.mitsuba_spp} estimates a pixel)"
        except NotMatchable as e:
            print(f"raytracer compare: the scene has no exact Mitsuba equivalent: {e}", file=sys.stderr)
            return 2
    m = metrics.compare(ours, reference)
    x0, x1, y0, y1, worst = worst_region(ours, reference)
    rt.write_image(out, side_by_side(ours, reference))
    print(f"{args.scene} against {args.against} at {args.width}x{args.height}, pixel centres")
    print(f"PSNR {m.psnr:.1f} dB, RMSE {m.rmse:.4g}, max |difference| {m.max_abs:.4g}, "
          f"{100 * m.frac_within:.1f} % of pixels within {m.tol:g}")
    print(f"worst region: x {x0}–{x1}, y {y0}–{y1} (mean |difference| {worst:.4g})")
    for w in scene.warnings[:8]:
        print(f"  {w}")
    if len(scene.warnings) > 8:
        print(f"  … {len(scene.warnings) - 8} more warnings")
    print(f"times: {timing}")
    print(f"wrote {out} (ours | {args.against} | 4×|difference|)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
