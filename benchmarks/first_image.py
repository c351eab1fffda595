"""The first image as a user meets it: ``raytracer render`` and ``povray`` as whole processes, side by
side, on a fixed set of POV-Ray's sample scenes — with an empty cache, with a warm one, and a
re-render inside a running process.

    python -m benchmarks.first_image [--size 160x120] [--repeats 3] [--scenes A.pov …] [--out DIR]

For each scene (relative to ``/usr/share/povray-3.7/scenes``), one after the other:

* POV-Ray: ``povray -D -A +W +H`` (one ray per pixel centre, every core), PNG output; the wall time
  of the process, median of ``--repeats``.
* ours, **cold**: ``python -m raytracer.cli render`` (PNG) with ``$RAYTRACER_CACHE_DIR`` a new empty
  folder: no kept program, no XLA cache. One run.
* ours, **warm**: the same command ``--repeats`` times more, the folder now holding the scene's
  program (``raytracer/_programs.py``): median wall time, and the stages the command prints
  (parse, compile — on a warm cache, loading the kept program —, render); "start" is the rest
  (interpreter, imports, the backend's start, writing the image).
* ours, **in process**: one process loads and compiles the scene, then renders it ``--repeats``
  times more, each time reading the scene again (the edit–render loop): the median of a re-render
  (``load_scene`` + the compiled render), next to POV-Ray's whole process.

Writes ``DIR/first-image.json`` and ``DIR/first-image.md`` (default ``benchmarks/results``). The
machine may be shared: the ratios come from one run, scene by scene.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks._common import fmt, machine, md_table

ROOT = Path("/usr/share/povray-3.7/scenes")
INCLUDE = Path("/usr/share/povray-3.7/include")
# six scenes whose first image was slowest, and ten from a seeded random sample of the 396 that both render
SCENES = [
    "advanced/lamppost.pov", "interior/ballbox1.pov", "lights/glassthing.pov", "incdemo/screen.pov",
    "incdemo/texture1.pov", "advanced/isocacti.pov", "lights/projected_through.pov",
    "textures/pigments/txtravg.pov", "interior/fog_ft.pov", "objects/blob1b.pov",
    "advanced/bwstripe.pov", "textures/finishes/cluster.pov", "incdemo/glasses/samp_demo.pov",
    "objects/quartic/quarcyl.pov", "objects/superel1.pov", "advanced/drums2/drums.pov",
]
TIMES = re.compile(r"times: parse ([\d.]+) s, compile ([\d.]+) s, render ([\d.]+) s")

IN_PROCESS = """
import json, statistics, sys, time
import jax
from raytracer.render import compile_render
from raytracer.sdl import load_scene
path, width, height, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
load = lambda: load_scene(path, width=width, height=height, fit_zero_terms=False)
run = compile_render(load(), width=width, height=height)
jax.block_until_ready(run(load()))
times = []
for _ in range(repeats):
    t0 = time.perf_counter()
    jax.block_until_ready(run(load()))
    times.append(time.perf_counter() - t0)
print(json.dumps({"rerender_s": statistics.median(times)}))
"""


def _timed(cmd: list[str], cwd: Path, env: dict | None = None, timeout: float = 600) -> tuple[float, str]:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr[-500:]}")
    return wall, proc.stdout


def povray(scene: Path, out: Path, width: int, height: int) -> float:
    return _timed(["povray", "-D", "-A", f"+I{scene.name}", f"+O{out}", f"+W{width}", f"+H{height}",
                   f"+L{scene.parent}", f"+L{INCLUDE}"], scene.parent)[0]


def ours(scene: Path, out: Path, width: int, height: int, cache: Path) -> dict:
    env = {**os.environ, "RAYTRACER_CACHE_DIR": str(cache)}
    wall, stdout = _timed([sys.executable, "-m", "raytracer.cli", "render", str(scene), "-o", str(out),
                           "-W", str(width), "-H", str(height)], scene.parent, env)
    m = TIMES.search(stdout)
    parse, compile_, render = (float(x) for x in m.groups()) if m else (None, None, None)
    start = None if m is None else wall - parse - compile_ - render
    return {"wall_s": wall, "parse_s": parse, "compile_s": compile_, "render_s": render, "start_s": start}


def in_process(scene: Path, width: int, height: int, repeats: int, cache: Path) -> float:
    env = {**os.environ, "RAYTRACER_CACHE_DIR": str(cache)}
    _, stdout = _timed([sys.executable, "-c", IN_PROCESS, str(scene), str(width), str(height), str(repeats)],
                       scene.parent, env)
    return json.loads(stdout.strip().splitlines()[-1])["rerender_s"]


def measure(name: str, width: int, height: int, repeats: int, work: Path) -> dict:
    scene = ROOT / name
    out = work / "image.png"
    pov = statistics.median(povray(scene, out, width, height) for _ in range(repeats))
    cache = Path(tempfile.mkdtemp(dir=work, prefix="cache-"))
    cold = ours(scene, out, width, height, cache)
    warm_runs = [ours(scene, out, width, height, cache) for _ in range(repeats)]
    warm = {k: statistics.median(r[k] for r in warm_runs) if warm_runs[0][k] is not None else None
            for k in warm_runs[0]}
    rerender = in_process(scene, width, height, repeats, cache)
    return {"scene": name, "povray_s": pov, "cold": cold, "warm": warm, "rerender_s": rerender,
            "cold_ratio": cold["wall_s"] / pov, "warm_ratio": warm["wall_s"] / pov,
            "rerender_ratio": rerender / pov}


def markdown(records: list[dict], info: dict, size: tuple[int, int], repeats: int) -> str:
    rows = [[r["scene"], r["povray_s"], r["cold"]["wall_s"], r["cold_ratio"], r["warm"]["wall_s"],
             r["warm_ratio"], r["warm"]["start_s"], r["warm"]["parse_s"], r["warm"]["compile_s"],
             r["warm"]["render_s"], r["rerender_s"], r["rerender_ratio"]] for r in records]
    med = {k: statistics.median(r[k] for r in records)
           for k in ("cold_ratio", "warm_ratio", "rerender_ratio")}
    return "\n".join([
        f"# First image: whole processes at {size[0]}×{size[1]}, ours beside POV-Ray",
        "",
        f"Commit {info['commit']}, {info['cpu']} ({info['cores']} cores), POV-Ray "
        f"`{info['versions'].get('povray')}`; medians of {repeats} (cold: one run). Regenerate: "
        f"`python -m benchmarks.first_image`.",
        "",
        f"Median ratio to POV-Ray's process: cold **{med['cold_ratio']:.2f}×**, warm cache "
        f"**{med['warm_ratio']:.2f}×**, re-render in a running process **{med['rerender_ratio']:.2f}×**.",
        "",
        md_table(["scene", "POV-Ray s", "cold s", "cold ×", "warm s", "warm ×", "start s", "parse s",
                  "load s", "render s", "re-render s", "re-render ×"], rows),
        "",
        "warm: start = interpreter, imports, backend, image written; load = the kept program read "
        "(`raytracer/_programs.py`); re-render = `load_scene` + the compiled render in a live process.",
        "",
    ])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenes", nargs="*", default=SCENES)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    args = ap.parse_args(argv)
    width, height = (int(x) for x in args.size.split("x"))
    info = machine()
    records = []
    with tempfile.TemporaryDirectory(prefix="first-image-") as work:
        for name in args.scenes:
            try:
                r = measure(name, width, height, args.repeats, Path(work))
            except (RuntimeError, subprocess.TimeoutExpired) as e:
                print(f"{name}: {e}", file=sys.stderr)
                continue
            records.append(r)
            print(f"{name}: POV-Ray {fmt(r['povray_s'])} s; ours cold {fmt(r['cold']['wall_s'])} s "
                  f"({r['cold_ratio']:.1f}×), warm {fmt(r['warm']['wall_s'])} s ({r['warm_ratio']:.1f}×), "
                  f"re-render {fmt(r['rerender_s'])} s ({r['rerender_ratio']:.2f}×)", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    report = {"machine": info, "size": [width, height], "repeats": args.repeats, "scenes": records}
    (args.out / "first-image.json").write_text(json.dumps(report, indent=1))
    (args.out / "first-image.md").write_text(markdown(records, info, (width, height), args.repeats))
    return 0


if __name__ == "__main__":
    sys.exit(main())
