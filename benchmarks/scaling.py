"""How our renderer scales with the scene, next to POV-Ray 3.7 on the same files.

    python -m benchmarks.scaling [--quick] [--out DIR] [--repeats N] [--timeout S]
                                 [--max-n N] [--max-triangles T] [--only FAMILY …] [--keep-scenes]

Five families of cases; each case is one ``.pov`` file that both renderers read, written with the
header ``#version 3.7; global_settings { assumed_gamma 1.0 max_trace_level L }``:

* ``spheres``: N = 1, 10, 100, 1,000, 10,000, 100,000 spheres (``--quick``: up to 1,000) on a square
  grid over a checker plane, one point light, 640×480 (``--quick``: 160×120). The radius shrinks
  with the grid spacing so that the spheres never overlap; each has its own colour. For N ≤ 100 the
  reverse mode is measured too (``ours_grad``: ``jax.grad`` of the image mean with respect to every
  inexact leaf of the scene).
* ``mesh``: a height-field-like grid written as one ``mesh2`` of 10k, 100k and 1M triangles
  (``--quick``: 1k and 10k), 640×480 (``--quick``: 160×120), and the smallest of those meshes
  ``#declare``d once and placed 100 times (``object { M scale 0.1 translate … }``).
* ``depth``: ``max_trace_level`` 1, 2, 5, 10, 20 on ``benchmarks/scenes/whitted.pov`` (a glass and a
  mirror sphere over a checker floor), 640×480 (``--quick``: 160×120), reverse mode included: its
  memory must stay bounded as the ray tree's full width grows as 2^depth.
* ``size``: the seed scene at 160×120, 640×480, 1920×1080, 3840×2160 (``--quick``: the first two).
* ``spp``: the seed scene at 160×120 with 1, 4, 16, 64, 256 samples per pixel (``--quick``: 1, 4,
  16). Ours: a k×k grid per pixel. POV-Ray: ``-A`` at spp 1, else ``+A0.0 +AM1 +R<k> -J`` (k²+1
  rays per pixel, every pixel supersampled); POV-Ray caps ``+R`` at 9, so spp 256 is compared with
  its 9×9 (82 rays).

Every measurement is a fresh worker process (``benchmarks/_worker.py``), one at a time:

* ours (``kind: ours``): parse s (``load_scene``), compile s (``compile_render``: trace and XLA
  compile of the render for this scene structure and size), compile s for another N (spheres
  with N ≥ 8: ``compile_render`` of the nearest count whose arrays pad to the same sizes, after
  the first in the same process: the rule is no compile for another object count), warm s
  (median of ``--repeats`` runs of the compiled function; fewer runs when they add up to more
  than a quarter of the timeout: ``runs`` in the JSON), peak MB (``VmHWM`` of the worker:
  interpreter and JAX included);
* ours reverse mode (``kind: ours_grad``, spheres with N ≤ 100, every depth): compile s, warm s,
  peak MB of the jitted gradient, and ``grad / fwd``: its warm time over the forward warm time;
* POV-Ray (``kind: povray``, ``+WT2``): its own Parse Time and Trace Time (median; the Trace Time's
  over its 1 ms clock, ``_worker.quantized_median``), peak MB of the
  ``povray`` process;
* ``ours / POV``: our warm time over POV-Ray's Trace Time; ``PSNR dB``: our image against POV-Ray's
  (``validation.metrics.psnr``, linear, peak 1), where both finished.

Every job has a timeout (``--timeout``, default 600 s, covering parse, compile and the runs) and a
memory limit (``--max-memory-mb``, default 8000: resident memory of the worker and its ``povray``);
a job that times out, goes over the limit or fails is recorded as ``timeout`` / ``failed`` with its
reason, and the run goes on.
The cases of a family run in increasing size, and a renderer that timed out or failed on one case is
not run on the larger cases of that family (``skipped``); the other renderer goes on.

Writes ``DIR/scaling.json``, ``DIR/scaling.md`` (one table per family) and ``DIR/scaling.png``
(log-log: our warm and compile time and POV-Ray's Trace Time against each family's size).
``--keep-scenes`` keeps the generated files in ``DIR/scenes`` (the 1M-triangle mesh is ~35 MB);
``--from-json FILE`` only rewrites the .md and .png. The machine is shared: compare ratios and
slopes, not absolute times.
"""

from __future__ import annotations

import argparse
import colorsys
import dataclasses
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ._common import SCENES, JobFailed, fmt, machine, md_table, run_job, scene_variant

FAMILIES = ("spheres", "mesh", "depth", "size", "spp")
KINDS = ("ours", "ours_grad", "povray")
GRAD_MAX_N = 100  # reverse mode is measured on the spheres family up to this N
POV_MAX_AA_DEPTH = 9  # POV-Ray clamps +R<n> to 9
MESH_COPIES = 100
LEVEL = 5  # max_trace_level of the generated scenes (nothing in them spawns secondary rays)


def header(level: int = LEVEL) -> str:
    return f"#version 3.7;\nglobal_settings {{ assumed_gamma 1.0 max_trace_level {int(level)} }}\n"


# ---------------------------------------------------------------------------------------------------
# Scene files
# ---------------------------------------------------------------------------------------------------

_GROUND = """\
camera { location <0, 9, -13> look_at <0, 0, 0.3> right x*image_width/image_height angle 50 }
background { rgb <0.45, 0.6, 0.85> }
light_source { <-12, 20, -14> color rgb 1 }
"""


def spheres_scene(n: int) -> str:
    """``n`` spheres on a ⌈√n⌉×⌈√n⌉ grid over the square |x|, |z| ≤ 5, resting on a checker plane.

    The radius is 0.35 of the grid spacing, so neighbours never touch; the hues step by the golden
    ratio so that neighbours differ.
    """
    k = math.ceil(math.sqrt(n))
    spacing = 10.0 / k
    r = 0.35 * spacing
    lines = [
        header(),
        _GROUND,
        "plane { y, 0 pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.25, 0.25, 0.3> } "
        "finish { ambient 0.1 diffuse 0.8 } }",
        "#declare Finish = finish { ambient 0.1 diffuse 0.7 phong 0.4 phong_size 40 }",
    ]
    for i in range(n):
        x = -5.0 + (i % k + 0.5) * spacing
        z = -5.0 + (i // k + 0.5) * spacing
        red, green, blue = colorsys.hsv_to_rgb((i * 0.618034) % 1.0, 0.7, 0.9)
        lines.append(
            f"sphere {{ <{x:.5f}, {r:.5f}, {z:.5f}>, {r:.5f} "
            f"pigment {{ rgb <{red:.3f}, {green:.3f}, {blue:.3f}> }} finish {{ Finish }} }}"
        )
    return "\n".join(lines) + "\n"


def grid_shape(triangles: int) -> tuple[int, int]:
    """(rows, cols) of a quad grid with exactly ``triangles`` = 2·rows·cols triangles, as square as
    the divisors of ``triangles / 2`` allow (rows ≤ cols)."""
    if triangles < 2 or triangles % 2:
        raise ValueError(f"a grid mesh has an even number of triangles, not {triangles}")
    quads = triangles // 2
    rows = max(d for d in range(1, math.isqrt(quads) + 1) if quads % d == 0)
    return rows, quads // rows


def height(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The terrain of the mesh family: gentle waves of amplitude < 1 over |x|, |z| ≤ 5."""
    return 0.6 * np.sin(0.9 * x) * np.cos(0.7 * z) + 0.25 * np.sin(2.3 * x + 1.7 * z)


def mesh2_text(triangles: int) -> str:
    """A ``mesh2`` of ``triangles`` triangles: a grid over |x|, |z| ≤ 5 displaced by :func:`height`,
    two triangles per quad, with a checker pigment."""
    rows, cols = grid_shape(triangles)
    xs, zs = np.meshgrid(np.linspace(-5, 5, cols + 1), np.linspace(-5, 5, rows + 1))
    verts = np.stack([xs, height(xs, zs), zs], axis=-1).reshape(-1, 3)
    idx = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]  # the quad's corners
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    vtext = ",\n".join(f"<{x:.5f}, {y:.5f}, {z:.5f}>" for x, y, z in verts.tolist())
    ftext = ",\n".join(f"<{i}, {j}, {k}>" for i, j, k in faces.tolist())
    return (
        f"mesh2 {{\n vertex_vectors {{ {len(verts)},\n{vtext} }}\n"
        f" face_indices {{ {len(faces)},\n{ftext} }}\n"
        " pigment { checker rgb <0.85, 0.8, 0.6>, rgb <0.3, 0.5, 0.3> }\n"
        " finish { ambient 0.1 diffuse 0.8 }\n}"
    )


def mesh_scene(triangles: int, copies: int = 1) -> str:
    """One mesh of ``triangles`` triangles, or (``copies`` = n², n > 1) that mesh ``#declare``d once
    and placed n×n times, each scaled by 1/n, over the same square."""
    lines = [header(), _GROUND]
    if copies == 1:
        lines.append(mesh2_text(triangles))
        return "\n".join(lines) + "\n"
    n = math.isqrt(copies)
    if n * n != copies:
        raise ValueError(f"copies must be a square number, not {copies}")
    lines.append("#declare M = " + mesh2_text(triangles))
    step = 10.0 / n
    for i in range(copies):
        x, z = -5.0 + (i % n + 0.5) * step, -5.0 + (i // n + 0.5) * step
        lines.append(f"object {{ M scale {1.0 / n:.6g} translate <{x:.5f}, 0, {z:.5f}> }}")
    return "\n".join(lines) + "\n"


def seed_scene() -> str:
    """The seed scene with the common header (it has none: POV-Ray would otherwise apply its 3.6-style
    gamma)."""
    return header() + SCENES["seed"].read_text()


# ---------------------------------------------------------------------------------------------------
# Cases
# ---------------------------------------------------------------------------------------------------


@dataclasses.dataclass
class Case:
    """One scene file and image, measured by both renderers.

    ``x`` is the case's size along its family's axis (spheres, triangles, level, pixels, spp);
    ``write(folder)`` writes the scene file (only when the case runs) and returns its path.
    """

    family: str
    label: str
    x: float
    width: int
    height: int
    write: Callable[[Path], Path]
    spp: int = 1
    grad: bool = False
    pov_aa: int | None = None  # +R<n>, or None for -A
    details: dict = dataclasses.field(default_factory=dict)
    # a scene of another object count in the same buckets (``_packing.bucket``): its
    # ``compile_render`` after this one's, in the same process, is the "recompile" column
    recount: Callable[[Path], Path] | None = None


def other_count(n: int) -> int | None:
    """The count nearest ``n`` (not ``n``) whose spheres scene pads to the same sizes as n's:
    ``n`` items and ``n + 1`` primitives (the plane) in the same buckets; None below the
    hierarchy's ``MIN_ITEMS``."""
    from raytracer._packing import bucket
    from raytracer.shading._accel import MIN_ITEMS

    if n < MIN_ITEMS:
        return None
    for m in sorted(range(max(MIN_ITEMS, n - 64), n + 65), key=lambda m: (abs(m - n), m)):
        if m != n and bucket(m) == bucket(n) and bucket(m + 1) == bucket(n + 1):
            return m
    return None


def _text_file(name: str, text: Callable[[], str]) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        path = folder / name
        path.write_text(text())
        return path

    return write


def _spheres_case(n: int, size: tuple[int, int]) -> Case:
    m = other_count(n)
    return Case("spheres", f"N = {n:,}", n, *size, _text_file(f"spheres_{n}.pov", lambda: spheres_scene(n)),
                grad=n <= GRAD_MAX_N, details={"spheres": n, "objects": n + 1, "recount": m},
                recount=None if m is None else _text_file(f"spheres_{m}.pov", lambda: spheres_scene(m)))


def cases(family: str, quick: bool, max_n: int | None, max_triangles: int | None) -> list[Case]:
    """The cases of ``family`` in the order they run (increasing size)."""
    big = (160, 120) if quick else (640, 480)
    if family == "spheres":
        ns = [1, 10, 100, 1_000] if quick else [1, 10, 100, 1_000, 10_000, 100_000]
        return [_spheres_case(n, big) for n in ns if max_n is None or n <= max_n]
    if family == "mesh":
        sizes = [1_000, 10_000] if quick else [10_000, 100_000, 1_000_000]
        if max_triangles is not None:
            sizes = [t for t in sizes if t <= max_triangles] or [max_triangles - max_triangles % 2]
        out = [
            Case(
                "mesh",
                f"{t:,} triangles",
                t,
                *big,
                _text_file(f"mesh_{t}.pov", lambda t=t: mesh_scene(t)),
                details={"triangles": t, "meshes": 1},
            )
            for t in sizes
        ]
        tile = sizes[0]
        total = MESH_COPIES * tile
        instanced = Case(
            "mesh",
            f"{MESH_COPIES} × {tile:,} (instanced)",
            total,
            *big,
            _text_file(f"mesh_{tile}_x{MESH_COPIES}.pov", lambda: mesh_scene(tile, MESH_COPIES)),
            details={"triangles": total, "meshes": MESH_COPIES, "instanced": True},
        )
        # before the single mesh of as many triangles: it parses one 100th of them
        at = next((i for i, c in enumerate(out) if c.x >= total), len(out))
        return out[:at] + [instanced] + out[at:]
    if family == "depth":
        return [
            Case(
                "depth",
                f"L = {level}",
                level,
                *big,
                lambda folder, level=level: scene_variant(SCENES["whitted"], folder, max_trace_level=level),
                grad=True,  # reverse mode's memory must not grow with 2^depth
                details={"max_trace_level": level},
            )
            for level in (1, 2, 5, 10, 20)
        ]
    if family == "size":
        sizes = [(160, 120), (640, 480)] if quick else [(160, 120), (640, 480), (1920, 1080), (3840, 2160)]
        return [
            Case(
                "size", f"{w}×{h}", w * h, w, h, _text_file("seed.pov", seed_scene), details={"pixels": w * h}
            )
            for w, h in sizes
        ]
    if family == "spp":
        out = []
        for spp in [1, 4, 16] if quick else [1, 4, 16, 64, 256]:
            k = math.isqrt(spp)
            aa = None if k == 1 else min(k, POV_MAX_AA_DEPTH)
            details = {"spp": spp, "povray_rays_per_pixel": 1 if aa is None else aa * aa + 1}
            out.append(
                Case(
                    "spp",
                    f"spp {spp}",
                    spp,
                    160,
                    120,
                    _text_file("seed.pov", seed_scene),
                    spp=spp,
                    pov_aa=aa,
                    details=details,
                )
            )
        return out
    raise ValueError(f"unknown family {family!r}; expected one of {FAMILIES}")


# ---------------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------------


def attempt(job: dict, timeout: float, max_rss_mb: float | None = None) -> dict:
    """Runs ``job``; its result with ``status: ok``, or ``status: timeout / failed`` and a reason."""
    t0 = time.perf_counter()
    try:
        res = run_job(job, timeout=timeout, max_rss_mb=max_rss_mb)
    except subprocess.TimeoutExpired:
        return {"status": "timeout", "reason": f"no result after {timeout:g} s", "job_wall_s": timeout}
    except JobFailed as e:
        tail = [x for x in str(e).splitlines() if x.strip()]
        return {
            "status": "failed",
            "reason": tail[-1][:300] if tail else "failed",
            "error": str(e)[-3000:],
            "job_wall_s": time.perf_counter() - t0,
        }
    return {
        "status": "ok",
        **res,
        "runs": len(res.get("times_s") or res.get("trace_times_s") or []),
        "job_wall_s": time.perf_counter() - t0,
    }


def run_case(case: Case, scene: Path, images: Path, opts, stopped: dict[str, str],
             recount: Path | None = None) -> dict:
    """Measures ``case`` with each renderer not yet ``stopped`` in its family; updates ``stopped``.
    ``recount``: the case's scene at another object count (``Case.recount``), compiled after it."""
    common = {
        "scene": scene,
        "width": case.width,
        "height": case.height,
        "repeats": opts.repeats,
        "max_total_s": opts.timeout / 4,
    }
    stem = f"{case.family}_{case.x}"
    jobs = {
        "ours": {**common, "kind": "ours", "spp": case.spp, "image": images / f"{stem}_ours.npy",
                 **({"recount_scene": recount} if recount is not None else {})},
        "ours_grad": {**common, "kind": "ours_grad", "spp": case.spp} if case.grad else None,
        "povray": {
            **common,
            "kind": "povray",
            "aa": None if case.pov_aa is None else [0.0, case.pov_aa],
            "threads": opts.threads,
            "timeout": opts.timeout + 60,
            "image": images / f"{stem}_pov.npy",
        },
    }
    out = {
        "family": case.family,
        "label": case.label,
        "x": case.x,
        "width": case.width,
        "height": case.height,
        "spp": case.spp,
        "scene": scene.name,
        "details": case.details,
    }
    for kind, job in jobs.items():
        if job is None:
            continue
        if kind in stopped:
            out[kind] = {"status": "skipped", "reason": stopped[kind]}
            continue
        res = attempt(job, opts.timeout, opts.max_memory_mb)
        out[kind] = res
        if res["status"] != "ok":
            stopped[kind] = f"{res['status']} at {case.label}"
        print(f"  {kind:9s} {_summary(res)}", file=sys.stderr, flush=True)
    ours, pov = out["ours"], out["povray"]
    both = ours["status"] == "ok" and pov["status"] == "ok"
    out["ratio_warm_to_trace"] = ours["time_s"] / pov["time_s"] if both and pov["time_s"] else None
    grad = out.get("ours_grad")
    out["ratio_grad_to_forward"] = (
        grad["time_s"] / ours["time_s"]
        if grad and grad["status"] == "ok" and ours["status"] == "ok"
        else None
    )
    if both:
        from validation.metrics import psnr

        out["psnr_vs_povray"] = psnr(np.load(jobs["ours"]["image"]), np.load(jobs["povray"]["image"]))
    else:
        out["psnr_vs_povray"] = None
    return out


def _summary(res: dict) -> str:
    if res["status"] != "ok":
        return f"{res['status']}: {res['reason']}"
    return (
        f"parse {res['parse_s']:.2f} s, compile {res.get('compile_s', 0):.2f} s, "
        f"time {res['time_s']:.3f} s, peak {res['peak_mb']:.0f} MB (job {res['job_wall_s']:.0f} s)"
    )


# ---------------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------------

AXIS = {
    "spheres": "spheres N",
    "mesh": "triangles",
    "depth": "max_trace_level",
    "size": "pixels",
    "spp": "samples per pixel",
}


def _cell(res: dict | None, key: str):
    """A measured value, or the status of a job that did not finish (``–``: not run)."""
    if res is None:
        return None
    return res.get(key) if res["status"] == "ok" else res["status"]


def family_table(rows: list[dict]) -> str:
    lines = []
    for r in rows:
        o, p = r["ours"], r["povray"]
        lines.append(
            [
                r["label"],
                f"{r['width']}×{r['height']}",
                _cell(o, "parse_s"),
                _cell(o, "compile_s"),
                _cell(o, "recompile_s") if o and "recompile_s" in o else None,
                _cell(o, "time_s"),
                _cell(o, "peak_mb"),
                _cell(p, "parse_s"),
                _cell(p, "time_s"),
                _cell(p, "peak_mb"),
                f"{r['ratio_warm_to_trace']:.1f}×" if r["ratio_warm_to_trace"] else None,
                r["psnr_vs_povray"],
            ]
        )
    return md_table(
        [
            "case",
            "size",
            "ours parse s",
            "ours compile s",
            "ours compile s, another N",
            "ours warm s (median)",
            "ours peak MB",
            "POV parse s",
            "POV trace s (median)",
            "POV peak MB",
            "ours / POV",
            "PSNR dB",
        ],
        lines,
    )


def grad_table(rows: list[dict]) -> str:
    lines = []
    for r in rows:
        g = r.get("ours_grad")
        if g is None:
            continue
        lines.append(
            [
                r["label"],
                f"{r['width']}×{r['height']}",
                _cell(g, "compile_s"),
                _cell(g, "time_s"),
                _cell(g, "peak_mb"),
                f"{r['ratio_grad_to_forward']:.1f}×" if r["ratio_grad_to_forward"] else None,
            ]
        )
    return md_table(
        ["case", "size", "grad compile s", "grad warm s (median)", "grad peak MB", "grad / fwd"], lines
    )


def _reasons(rows: list[dict]) -> list[str]:
    out = []
    for r in rows:
        for kind in KINDS:
            res = r.get(kind)
            if res and res["status"] != "ok":
                out.append(f"- {r['label']}, {kind}: {res['status']}: {res['reason']}")
    return out


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    families = [f for f in FAMILIES if any(r["family"] == f for r in rows)]
    ncol = min(3, len(families))
    nrow = math.ceil(len(families) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.2 * nrow), squeeze=False)
    series = [  # kind, key, label, colour, line style, marker of the instanced mesh
        ("ours", "time_s", "ours warm", "C0", "o-", "*"),
        ("ours", "compile_s", "ours compile", "C0", "s--", "X"),
        ("ours_grad", "time_s", "ours grad warm", "C2", "o-", "*"),
        ("ours_grad", "compile_s", "ours grad compile", "C2", "s--", "X"),
        ("povray", "time_s", "POV-Ray trace", "C1", "o-", "*"),
    ]
    for ax, family in zip(axes.flat, families, strict=False):
        fam = [r for r in rows if r["family"] == family]
        for kind, key, label, colour, style, star in series:
            for instanced in (False, True):
                pts = [
                    (r["x"], r[kind][key])
                    for r in fam
                    if r.get(kind)
                    and r[kind]["status"] == "ok"
                    and r[kind].get(key)
                    and bool(r["details"].get("instanced")) == instanced
                ]
                if not pts:
                    continue
                x, y = zip(*pts, strict=True)
                if instanced:
                    ax.plot(x, y, star, color=colour, ms=9, label=f"{label} ({MESH_COPIES} instances)")
                else:
                    ax.plot(x, y, style, color=colour, label=label, ms=5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # 2×10⁴ 3×10⁴ … overlap
        size = {f"{r['width']}×{r['height']}" for r in fam}
        ax.set_title(f"{family} ({', '.join(sorted(size)) if len(size) == 1 else 'varying size'})")
        ax.set_xlabel(AXIS[family])
        ax.set_ylabel("seconds")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(families) :]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_outputs(doc: dict, out: Path) -> str:
    """Writes scaling.json, scaling.md and scaling.png into ``out``; returns the markdown."""
    rows, info, opts = doc["cases"], doc["machine"], doc["options"]
    (out / "scaling.json").write_text(json.dumps(doc, indent=1))
    if any(r[k]["status"] == "ok" for r in rows for k in KINDS if r.get(k)):
        plot(rows, out / "scaling.png")
    load = info["load_average_at_start"]
    md = [
        "# Scaling: our renderer vs POV-Ray 3.7",
        "",
        f"{info['cpu']}, {info['cores']} cores, load average at start {fmt(load[0]) if load else '?'}; "
        f"jax {info['versions']['jax']}, {info['versions']['povray']}; commit {info['commit']}. "
        f"{'Quick' if opts['quick'] else 'Full'} run, {doc['wall_s'] / 60:.1f} min; medians of up to "
        f"{opts['repeats']} warm runs; timeout {opts['timeout']:g} s per job.",
        "",
        "Ours: parse = `load_scene`, compile = `compile_render` (trace + XLA), warm = the compiled render, "
        "float32; peak MB = `VmHWM` of a fresh worker (Python and JAX included). POV-Ray: `+WT2`, its "
        "own Parse and Trace Time, peak MB of the `povray` process. ours / POV = ours warm / POV trace. "
        "PSNR: ours against POV-Ray's image (linear, peak 1). `timeout` / `failed`: the job did not "
        "finish (reasons below the table); `skipped`: that renderer already timed out or failed on a "
        "smaller case of the family.",
        "",
    ]
    for family in FAMILIES:
        fam = [r for r in rows if r["family"] == family]
        if not fam:
            continue
        md += [f"## {family}", "", family_table(fam), ""]
        if any(r.get("ours_grad") for r in fam):
            md += [
                "Reverse mode (`jax.grad` of the image mean over every inexact scene leaf):",
                "",
                grad_table(fam),
                "",
            ]
        if family == "spp":
            md += [
                "POV-Ray: `-A` at spp 1, else `+A0.0 +AM1 +R<k> -J` (k²+1 rays per pixel; `+R` is at "
                "most 9, so spp 256 is compared with 82 rays).",
                "",
            ]
        reasons = _reasons(fam)
        if reasons:
            md += [*reasons, ""]
    text = "\n".join(md)
    (out / "scaling.md").write_text(text)
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="160×120, smaller N, sizes and spp")
    ap.add_argument("--out", type=Path, default=Path("out/benchmarks"))
    ap.add_argument("--repeats", type=int, default=3, help="warm runs per measurement (median)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per job (parse, compile and runs)")
    ap.add_argument("--max-n", type=int, default=None, help="largest number of spheres")
    ap.add_argument(
        "--max-triangles",
        type=int,
        default=None,
        help="largest mesh (the instanced case places 100 copies of the smallest mesh run)",
    )
    ap.add_argument("--only", action="append", choices=FAMILIES, help="run this family (repeatable)")
    ap.add_argument(
        "--max-memory-mb",
        type=float,
        default=8000.0,
        help="kill a job (failed) whose resident memory exceeds this (the machine is shared)",
    )
    ap.add_argument("--threads", type=int, default=2, help="POV-Ray render threads (+WT)")
    ap.add_argument("--keep-scenes", action="store_true", help="keep the scene files in DIR/scenes")
    ap.add_argument("--from-json", type=Path, help="only rewrite the .md and .png from this scaling.json")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.from_json:
        print(write_outputs(json.loads(args.from_json.read_text()), args.out))
        return 0
    t0 = time.perf_counter()
    info = machine()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-scaling-") as tmp:
        scenes, images = Path(tmp) / "scenes", Path(tmp) / "images"
        scenes.mkdir()
        images.mkdir()
        for family in args.only or FAMILIES:
            stopped: dict[str, str] = {}
            for case in cases(family, args.quick, args.max_n, args.max_triangles):
                print(
                    f"scaling: {family} {case.label} {case.width}×{case.height} …",
                    file=sys.stderr,
                    flush=True,
                )
                scene = case.write(scenes)
                recount = case.recount(scenes) if case.recount is not None else None
                rows.append(run_case(case, scene, images, args, stopped, recount))
                for npy in images.iterdir():
                    npy.unlink()
        if args.keep_scenes:
            shutil.copytree(scenes, args.out / "scenes", dirs_exist_ok=True)
    doc = {
        "machine": info,
        "options": {
            "quick": args.quick,
            "repeats": args.repeats,
            "timeout": args.timeout,
            "max_memory_mb": args.max_memory_mb,
            "max_n": args.max_n,
            "max_triangles": args.max_triangles,
            "only": args.only,
            "threads": args.threads,
        },
        "cases": rows,
        "wall_s": time.perf_counter() - t0,
    }
    print(write_outputs(doc, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
