"""Speed benchmark: our renderer next to POV-Ray on the seed scene (640×480), a Whitted scene with
a glass and a mirror sphere over a checker floor, and a Whitted scene with three lights and four
phong spheres over a checker box (tinyraytracer's; both 1024×768, ``max_trace_level 5``).

    python -m benchmarks.speed [--quick] [--out DIR] [--repeats 3]

For each scene, in a fresh process per measurement (so the peak memory is that measurement's):

* ours: parse time, compile time (``raytracer.render.compile_render``: trace + XLA compile of the
  whole render for this scene structure and image size), warm render time (median of ``--repeats``
  runs of the compiled function) and its CPU seconds, peak resident memory (``ru_maxrss`` of the
  worker process, interpreter and libraries included; ``base_mb`` is the high-water mark before
  compiling);
* POV-Ray 3.7, same file and size, ``-A`` (one ray per pixel, as our ``spp=1``), ``+WT2``: its own
  Parse Time and Trace Time (median of ``--repeats``), its CPU seconds, the wall time of the whole
  ``povray`` process, and its peak memory (``RUSAGE_CHILDREN`` of a worker whose only child is povray);
* the ratio of our warm time to POV-Ray's Trace Time, and the PSNR of our image against POV-Ray's.

Writes ``DIR/speed.json`` and ``DIR/speed.md``. ``--quick`` renders a quarter of the pixels.
The machine is shared: compare ratios and CPU seconds, not absolute wall-clock times.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._common import SCENES, fmt, machine, md_table, run_job

CASES = [("seed", 640, 480), ("whitted", 1024, 768), ("whitted_lights", 1024, 768)]


def measure(name: str, width: int, height: int, repeats: int, work: Path) -> dict:
    scene = SCENES[name]
    ours = run_job(
        {
            "kind": "ours",
            "scene": scene,
            "width": width,
            "height": height,
            "spp": 1,
            "repeats": repeats,
            "max_total_s": 1e9,
            "image": work / f"{name}_ours.npy",
        }
    )
    pov = run_job(
        {
            "kind": "povray",
            "scene": scene,
            "width": width,
            "height": height,
            "aa": None,
            "threads": 2,
            "repeats": repeats,
            "max_total_s": 1e9,
            "image": work / f"{name}_pov.npy",
        }
    )
    a = np.load(work / f"{name}_ours.npy").astype(np.float64)
    b = np.load(work / f"{name}_pov.npy").astype(np.float64)
    rmse = float(np.sqrt(np.mean((a - b) ** 2)))
    return {
        "scene": name,
        "file": str(scene.relative_to(SCENES["seed"].parents[2])),
        "width": width,
        "height": height,
        "ours": ours,
        "povray": pov,
        "ratio_warm_to_trace": ours["time_s"] / pov["time_s"] if pov["time_s"] else None,
        "ratio_cpu": (
            float(np.median(ours["cpu_s"]) / np.median(pov["cpu_s"]))
            if pov["cpu_s"] and np.median(pov["cpu_s"]) > 0
            else None
        ),
        "rmse_vs_povray": rmse,
        "psnr_vs_povray": math.inf if rmse == 0 else -20 * math.log10(rmse),
    }


def table(results: list[dict]) -> str:
    rows = []
    for r in results:
        o, p = r["ours"], r["povray"]
        rows.append(
            [
                r["scene"],
                f"{r['width']}×{r['height']}",
                o["parse_s"],
                o["compile_s"],
                o["time_s"],
                float(np.median(o["cpu_s"])),
                o["peak_mb"],
                p["parse_s"],
                p["time_s"],
                float(np.median(p["cpu_s"])) if p["cpu_s"] else None,
                p["wall_s"],
                p["peak_mb"],
                f"{r['ratio_warm_to_trace']:.1f}×" if r["ratio_warm_to_trace"] else "–",
                f"{r['ratio_cpu']:.1f}×" if r.get("ratio_cpu") else "–",
                r["psnr_vs_povray"],
            ]
        )
    return md_table(
        [
            "scene",
            "size",
            "ours parse s",
            "ours compile s",
            "ours warm s (median)",
            "ours warm CPU s",
            "ours peak MB",
            "POV parse s",
            "POV Trace Time s (median)",
            "POV CPU s",
            "POV process wall s",
            "POV peak MB",
            "ours warm / POV trace",
            "ours CPU / POV CPU",
            "PSNR vs POV dB",
        ],
        rows,
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="half the width and height")
    ap.add_argument("--out", type=Path, default=Path("out/benchmarks"))
    ap.add_argument("--repeats", type=int, default=3, help="warm runs per measurement (median)")
    ap.add_argument("--scenes", nargs="*", default=[c[0] for c in CASES], help=argparse.SUPPRESS)
    ap.add_argument("--scale", type=float, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    scale = args.scale or (0.5 if args.quick else 1.0)
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    info = machine()
    results = []
    with tempfile.TemporaryDirectory(prefix="bench-speed-") as tmp:
        for name, w, h in CASES:
            if name not in args.scenes:
                continue
            w, h = max(8, round(w * scale)), max(6, round(h * scale))
            print(f"speed: {name} {w}×{h} …", file=sys.stderr, flush=True)
            results.append(measure(name, w, h, args.repeats, Path(tmp)))
            print(
                f"  ours compile {results[-1]['ours']['compile_s']:.1f} s, "
                f"warm {results[-1]['ours']['time_s']:.2f} s;"
                f" POV trace {results[-1]['povray']['time_s']:.2f} s",
                file=sys.stderr,
                flush=True,
            )
    doc = {
        "machine": info,
        "quick": args.quick,
        "repeats": args.repeats,
        "results": results,
        "wall_s": time.perf_counter() - t0,
        "notes": {
            "peak_mb": "ru_maxrss of a fresh worker process (ours: the process itself, interpreter and "
            "JAX included; POV-Ray: RUSAGE_CHILDREN of a worker whose only child is povray)",
            "povray": "-A (one ray per pixel centre), +WT2, +FE; Trace Time as printed by POV-Ray",
            "ours": "spp 1 (pixel centres), float32, raytracer.render.compile_render then warm runs",
        },
    }
    (args.out / "speed.json").write_text(json.dumps(doc, indent=1))
    load = info["load_average_at_start"]
    md = [
        "# Speed: our renderer vs POV-Ray 3.7",
        "",
        f"Machine: {info['cpu']}, {info['cores']} cores, load average at start "
        f"{fmt(load[0]) if load else '?'}; jax {info['versions']['jax']}, {info['versions']['povray']}. "
        f"Medians of {args.repeats} runs{' (quick: half size)' if args.quick else ''}.",
        "",
        table(results),
        "",
        "Peak MB: `ru_maxrss` of a fresh process per measurement (ours includes the Python interpreter "
        "and JAX; POV-Ray's is the `povray` process alone). POV-Ray: `-A +WT2`, its own Trace Time. "
        "Ours: float32, 1 ray per pixel centre, compile = `compile_render` (trace + XLA), warm = the "
        "compiled function's run time.",
        "",
    ]
    (args.out / "speed.md").write_text("\n".join(md))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
