"""What accuracy costs in time, for our renderer and its peers (POV-Ray 3.7, Mitsuba 3).

    python -m benchmarks.accuracy [--quick] [--out DIR] [--repeats 3] [--scenes seed whitted …]

Four scenes (``benchmarks._common.SCENES``): the seed scene (with a ``#version 3.7`` /
``assumed_gamma 1.0`` header so that POV-Ray writes the same linear values we do), a Whitted scene
(glass and mirror spheres over a checker floor), a Lambert scene that Mitsuba matches exactly, and a
soft-shadow area-light scene (POV-Ray only: Mitsuba has no equivalent of POV's area lights).

Sweeps, for our renderer (each setting in a fresh process: compile time, median warm time of
``--repeats`` runs, CPU seconds, peak memory ``VmHWM``):

* samples per pixel (1, 4, 16, 64: a deterministic k×k grid), float32;
* ``max_trace_level`` (Whitted scene: 1 … 8), spp 1;
* area-light samples (``area_light … n, n``), spp 1;
* float64 (``jax_enable_x64`` set before the scene exists, in its own process) at some spp;
* resolution, spp 1 (error against POV-Ray's ``-A`` render of the same size: same sampling).

Peers on the same files and sizes: POV-Ray ``-A`` and ``+A0.0 +AM1 +R<n> -J`` (n²+1 rays per pixel),
``+WT2``, its own Trace Time (printed in whole milliseconds: the median of the readings as durations on
that clock, ``_worker.quantized_median``; its process wall time is kept too); the same depth and area-light
sweeps with ``-A``; and Mitsuba ``llvm_ad_rgb`` (Lambert scene, box-filtered film, 1 … 1024 spp;
first call with a cold kernel cache, then warm median).

References, per scene: ``converged`` = ours, float64, a 16×16 (8×8 for Whitted) grid per pixel at
the deepest setting (the primary error of every row unless the row says otherwise);
``centres`` = ours, float64, spp 1, deepest setting (isolates depth/area/precision from
anti-aliasing); ``povray_aa65`` = POV-Ray ``+A0.0 +AM1 +R8 -J`` at the deepest setting;
``mitsuba_4096`` (Lambert) = Mitsuba at 4096 spp. Every row carries its error against each.

Writes ``DIR/accuracy.json`` (rows: renderer, scene, setting, compile_s, time_s, peak_mb, rmse,
max_err, plus details), ``DIR/accuracy.md`` and ``DIR/accuracy.png``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._common import SCENES, JobFailed, fmt, machine, md_table, run_job, scene_variant

SEED_HEADER = "#version 3.7;\nglobal_settings { assumed_gamma 1.0 }\n"


@dataclasses.dataclass
class SceneSweep:
    """What to measure on one scene (sizes in pixels; ``None`` = not swept)."""

    name: str
    size: tuple[int, int]
    spp: list[int]
    x64_spp: list[int]
    resolutions: list[tuple[int, int]] = dataclasses.field(default_factory=list)
    levels: list[int] = dataclasses.field(default_factory=list)  # max_trace_level sweep
    default_level: int | None = None  # level of the non-depth sweeps (None: as in the file)
    deep_level: int | None = None  # level of the references
    ref_level: int | None = None  # level of the 'converged' reference if not deep_level (cost)
    ref_area: int | None = None  # area n of the 'converged' reference if not deep_area (compile cost)
    area: list[int] = dataclasses.field(default_factory=list)  # area_light n×n sweep
    default_area: int | None = None
    pov_area: list[int] = dataclasses.field(default_factory=list)  # POV's area sweep, if wider than ours
    deep_area: int | None = None
    pov_aa: list[int] = dataclasses.field(default_factory=lambda: [2, 3, 4, 8])  # +R<n>; -A always
    # adaptive anti-aliasing (threshold, depth): ours (render(adaptive=)) and POV-Ray's +A +AM1 +R -J
    adaptive: list[tuple[float, int]] = dataclasses.field(
        default_factory=lambda: [(0.3, 2), (0.3, 3), (0.1, 3), (0.1, 4), (0.03, 4), (0.03, 6)])
    mitsuba_spp: list[int] = dataclasses.field(default_factory=list)
    mitsuba_ref_spp: int | None = None
    ref_spp: int = 256


def sweeps(quick: bool) -> list[SceneSweep]:
    # The 'converged' grids are k×k with k prime to 2, 3, 4 and 8, so that no swept grid (ours or POV-Ray's
    # +R<n>) shares sub-pixel positions with the reference (it would look better than it is).
    if quick:
        return [
            SceneSweep(
                "seed",
                (128, 96),
                spp=[1, 4, 16],
                x64_spp=[],
                resolutions=[(256, 192)],
                ref_spp=49,
                pov_aa=[2, 4, 8],
            ),
            SceneSweep(
                "whitted",
                (96, 72),
                spp=[1, 4],
                x64_spp=[],
                levels=[1, 3, 5],
                default_level=5,
                deep_level=5,
                ref_spp=25,
                pov_aa=[2, 4, 8],
            ),
            SceneSweep(
                "lambert",
                (128, 96),
                spp=[1, 4, 16],
                x64_spp=[1],
                mitsuba_spp=[1, 4, 16, 64, 256],
                mitsuba_ref_spp=4096,
                ref_spp=49,
                pov_aa=[2, 4, 8],
            ),
            SceneSweep(
                "area",
                (96, 72),
                spp=[1, 4],
                x64_spp=[],
                area=[1, 2, 3],
                default_area=3,
                deep_area=9,
                ref_area=3,
                pov_area=[1, 2, 3, 5, 9],
                ref_spp=25,
                pov_aa=[2, 4, 8],
            ),
        ]
    # the full run: as large as fits in about half an hour on 2 shared cores (compile time dominates)
    return [
        SceneSweep(
            "seed",
            (160, 120),
            spp=[1, 4, 16, 64],
            x64_spp=[1, 16],
            resolutions=[(320, 240), (640, 480)],
            ref_spp=169,
        ),
        SceneSweep(
            "whitted",
            (128, 96),
            spp=[1, 4, 16],
            x64_spp=[1],
            levels=[1, 2, 3, 4, 5, 6, 8],
            default_level=5,
            deep_level=8,
            ref_level=6,
            ref_spp=49,
        ),
        SceneSweep(
            "lambert",
            (160, 120),
            spp=[1, 4, 16, 64],
            x64_spp=[1],
            resolutions=[(320, 240)],
            mitsuba_spp=[1, 4, 16, 64, 256, 1024],
            mitsuba_ref_spp=4096,
            ref_spp=169,
        ),
        SceneSweep(
            "area",
            (120, 90),
            spp=[1, 4, 16],
            x64_spp=[],
            area=[1, 2, 3, 5],
            default_area=5,
            deep_area=17,
            ref_area=5,
            pov_area=[1, 2, 3, 5, 9, 17],
            ref_spp=49,
        ),
    ]


@dataclasses.dataclass
class Runner:
    work: Path
    repeats: int
    cache: dict = dataclasses.field(default_factory=dict)

    def file(self, sw: SceneSweep, *, level=None, area=None) -> Path:
        src = SCENES[sw.name]
        if sw.name == "seed":
            dst = self.work / "seed_v37.pov"
            if not dst.exists():
                dst.write_text(SEED_HEADER + src.read_text())
            src = dst
        return scene_variant(src, self.work, max_trace_level=level, area_samples=area)

    def job(self, job: dict) -> tuple[dict, np.ndarray]:
        key = json.dumps(job, sort_keys=True, default=str)
        if key not in self.cache:
            image = self.work / f"img{len(self.cache)}.npy"
            t0 = time.perf_counter()
            res = run_job({**job, "image": image, "repeats": job.get("repeats", self.repeats)})
            res["job_wall_s"] = time.perf_counter() - t0
            self.cache[key] = (res, np.load(image).astype(np.float64))
            print(
                f"  {job['kind']:8s} {Path(str(job['scene'])).name:22s} "
                + " ".join(f"{k}={v}" for k, v in job.items() if k not in ("kind", "scene", "max_total_s"))
                + f": compile {res.get('compile_s', 0):.2f} s, time {res['time_s']:.3f} s "
                f"(job {res['job_wall_s']:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
        return self.cache[key]


def _err(a: np.ndarray, b: np.ndarray) -> dict:
    d = a - b
    return {"rmse": float(np.sqrt(np.mean(d * d))), "max_err": float(np.max(np.abs(d)))}


def measure_scene(sw: SceneSweep, r: Runner) -> list[dict]:
    w, h = sw.size
    deep = {"level": sw.deep_level, "area": sw.deep_area}
    default = {"level": sw.default_level, "area": sw.default_area}
    deep_file = r.file(sw, **deep)
    default_file = r.file(sw, **default)
    refs: dict[str, np.ndarray] = {}
    print(f"accuracy: {sw.name} {w}×{h}: references", file=sys.stderr, flush=True)
    ref_file = r.file(sw, level=sw.ref_level or sw.deep_level, area=sw.ref_area or sw.deep_area)
    _, refs["converged"] = r.job(
        {
            "kind": "ours",
            "scene": ref_file,
            "width": w,
            "height": h,
            "spp": sw.ref_spp,
            "x64": True,
            "repeats": 1,
        }
    )
    _, refs["povray_centres"] = r.job(
        {
            "kind": "povray",
            "scene": deep_file,
            "width": w,
            "height": h,
            "aa": None,
            "threads": 2,
            "repeats": 1,
        }
    )
    _, refs["povray_aa65"] = r.job(
        {
            "kind": "povray",
            "scene": deep_file,
            "width": w,
            "height": h,
            "aa": [0.0, 8],
            "threads": 2,
            "repeats": 1,
        }
    )
    if sw.mitsuba_ref_spp:
        _, refs[f"mitsuba_{sw.mitsuba_ref_spp}"] = r.job(
            {
                "kind": "mitsuba",
                "scene": default_file,
                "width": w,
                "height": h,
                "spp": sw.mitsuba_ref_spp,
                "repeats": 1,
            }
        )
    ref_info = {name: _err(img, refs["converged"]) for name, img in refs.items()}
    rows: list[dict] = []

    def add(renderer, setting, params, res, img, *, reference="converged", extra_refs=None):
        errors = {name: _err(img, ref) for name, ref in refs.items() if ref.shape == img.shape}
        errors.update(extra_refs or {})
        row = {
            "renderer": renderer,
            "scene": sw.name,
            "setting": setting,
            "params": params,
            "width": img.shape[1],
            "height": img.shape[0],
            "compile_s": res.get("compile_s", 0.0),
            "time_s": res["time_s"],
            "peak_mb": res["peak_mb"],
            "reference": reference,
            "rmse": errors[reference]["rmse"],
            "max_err": errors[reference]["max_err"],
            "errors": errors,
            "cpu_s": float(np.median(res["cpu_s"])) if res.get("cpu_s") else None,
            "runs": len(res.get("times_s") or res.get("trace_times_s") or [1]),
        }
        for k in ("first_s", "wall_s", "parse_s", "base_mb", "first_cpu_s", "compile_cpu_s", "trace_times_s",
                  "trace_median_s"):
            if k in res:
                row[k] = res[k]
        rows.append(row)
        return row

    print(f"accuracy: {sw.name}: our renderer", file=sys.stderr, flush=True)
    f32 = {}
    for spp in sw.spp:
        res, img = r.job({"kind": "ours", "scene": default_file, "width": w, "height": h, "spp": spp})
        f32[spp] = img
        add("ours", f"spp {spp}", {"spp": spp, "x64": False, **default}, res, img)
    for spp in sw.x64_spp:
        res, img = r.job(
            {"kind": "ours", "scene": default_file, "width": w, "height": h, "spp": spp, "x64": True}
        )
        extra = {"float32_same_setting": _err(f32[spp], img)} if spp in f32 else {}
        add(
            "ours-f64", f"spp {spp} float64", {"spp": spp, "x64": True, **default}, res, img, extra_refs=extra
        )
    for level in sw.levels:
        res, img = r.job(
            {
                "kind": "ours",
                "scene": r.file(sw, level=level, area=sw.default_area),
                "width": w,
                "height": h,
                "spp": 1,
            }
        )
        add(
            "ours-depth",
            f"max_trace_level {level}",
            {"spp": 1, "level": level},
            res,
            img,
            reference="povray_centres",
        )
    for n in sw.area:
        res, img = r.job(
            {
                "kind": "ours",
                "scene": r.file(sw, level=sw.default_level, area=n),
                "width": w,
                "height": h,
                "spp": 1,
            }
        )
        add("ours-area", f"area {n}×{n}", {"spp": 1, "area": n}, res, img, reference="povray_centres")

    for threshold, depth in sw.adaptive:
        res, img = r.job({"kind": "ours", "scene": default_file, "width": w, "height": h,
                          "adaptive": [threshold, depth]})
        add("ours-adaptive", f"+A{threshold} +R{depth}", {"adaptive": [threshold, depth], **default},
            res, img)

    print(f"accuracy: {sw.name}: POV-Ray", file=sys.stderr, flush=True)
    pov = {"kind": "povray", "width": w, "height": h, "threads": 2}
    for threshold, depth in sw.adaptive:
        res, img = r.job({**pov, "scene": default_file, "aa": [threshold, depth]})
        add("povray-adaptive", f"+A{threshold} +R{depth}", {"aa": [threshold, depth], **default}, res, img)
    for aa in [None, *sw.pov_aa]:
        res, img = r.job({**pov, "scene": default_file, "aa": [0.0, aa] if aa else None})
        add(
            "povray",
            "-A" if aa is None else f"+A0.0 +AM1 +R{aa} -J ({aa * aa + 1} rays/px)",
            {"aa": aa, **default},
            res,
            img,
        )
    for level in sw.levels:
        res, img = r.job({**pov, "scene": r.file(sw, level=level, area=sw.default_area), "aa": None})
        add(
            "povray-depth",
            f"max_trace_level {level}",
            {"aa": None, "level": level},
            res,
            img,
            reference="povray_centres",
        )
    for n in sw.pov_area or sw.area:
        res, img = r.job({**pov, "scene": r.file(sw, level=sw.default_level, area=n), "aa": None})
        add("povray-area", f"area {n}×{n}", {"aa": None, "area": n}, res, img, reference="povray_centres")

    if sw.mitsuba_spp:
        print(f"accuracy: {sw.name}: Mitsuba", file=sys.stderr, flush=True)
        for spp in sw.mitsuba_spp:
            res, img = r.job({"kind": "mitsuba", "scene": default_file, "width": w, "height": h, "spp": spp})
            add("mitsuba", f"spp {spp}", {"spp": spp}, res, img)

    if sw.resolutions:
        print(f"accuracy: {sw.name}: resolution", file=sys.stderr, flush=True)
    for rw, rh in sorted({*sw.resolutions, (w, h)}):
        pov_res, pov_img = r.job({**pov, "scene": default_file, "width": rw, "height": rh, "aa": None})
        res, img = r.job({"kind": "ours", "scene": default_file, "width": rw, "height": rh, "spp": 1})
        same = {"povray_centres": _err(img, pov_img)}
        add(
            "ours-res",
            f"{rw}×{rh}",
            {"spp": 1, "width": rw, "height": rh},
            res,
            img,
            reference="povray_centres",
            extra_refs=same,
        )
        add(
            "povray-res",
            f"{rw}×{rh}",
            {"aa": None, "width": rw, "height": rh},
            pov_res,
            pov_img,
            reference="povray_centres",
            extra_refs={"povray_centres": _err(pov_img, pov_img)},
        )
    for row in rows:
        row["reference_floor"] = ref_info
    return rows


# ------------------------------------------------------------------------------------------ output
LABELS = {
    "ours": "ours (spp, float32)",
    "ours-f64": "ours float64",
    "ours-depth": "ours max_trace_level (spp 1)",
    "ours-area": "ours area n×n (spp 1)",
    "ours-adaptive": "ours adaptive (+A threshold +R depth)",
    "povray": "POV-Ray AA",
    "povray-adaptive": "POV-Ray adaptive (+A threshold +AM1 +R depth -J)",
    "povray-depth": "POV-Ray max_trace_level (-A)",
    "povray-area": "POV-Ray area n×n (-A)",
    "mitsuba": "Mitsuba llvm_ad_rgb (spp)",
}
STYLE = {
    "ours": ("C0", "o-"),
    "ours-f64": ("C0", "s--"),
    "ours-depth": ("C2", "^-"),
    "ours-area": ("C4", "v-"),
    "ours-adaptive": ("C0", "*:"),
    "povray": ("C1", "o-"),
    "povray-adaptive": ("C1", "*:"),
    "povray-depth": ("C3", "^--"),
    "povray-area": ("C5", "v--"),
    "mitsuba": ("C7", "D-"),
}
FLOOR = 1e-7  # errors of exactly 0 are drawn here on the log axis
TIME_FLOOR = 5e-4  # POV-Ray prints its Trace Time in milliseconds: 0.000 s is drawn here


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    ncol = 2
    nrow = math.ceil(len(scenes) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.2 * ncol, 4.6 * nrow), squeeze=False)
    for ax, scene in zip(axes.flat, scenes, strict=False):
        for renderer, (colour, style) in STYLE.items():
            pts = [r for r in rows if r["scene"] == scene and r["renderer"] == renderer]
            if not pts:
                continue
            pts.sort(key=lambda r: r["time_s"])
            x = [max(r["time_s"], TIME_FLOOR) for r in pts]
            y = [max(r["errors"]["converged"]["rmse"], FLOOR) for r in pts]  # one reference per panel
            ax.plot(x, y, style, color=colour, label=LABELS[renderer], ms=5)
            for r, xi, yi in zip(pts, x, y, strict=True):
                label = (
                    r["setting"].split(" (")[0].replace("max_trace_level ", "L").replace("+A0.0 +AM1 ", "")
                )
                ax.annotate(
                    label.replace(" -J", "").replace("spp ", "").replace(" float64", ""),
                    (xi, yi),
                    fontsize=6,
                    xytext=(3, 3),
                    textcoords="offset points",
                    color=colour,
                )
        ref = next(r for r in rows if r["scene"] == scene)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{scene} ({ref['width']}×{ref['height']})")
        ax.set_xlabel("render time, s (ours: warm; POV-Ray: Trace Time; Mitsuba: warm)")
        ax.set_ylabel("RMSE vs converged reference (linear)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(scenes) :]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


MAIN = ("ours", "ours-f64", "ours-adaptive", "povray", "povray-adaptive", "mitsuba")


def main_table(rows: list[dict]) -> str:
    """One table over all scenes: the sample-count sweeps of each renderer (error vs 'converged')."""
    body = [
        [
            r["scene"],
            r["renderer"],
            r["setting"],
            r["compile_s"],
            r["time_s"],
            r["peak_mb"],
            r["rmse"],
            r["max_err"],
        ]
        for r in rows
        if r["renderer"] in MAIN
    ]
    return md_table(
        ["scene", "renderer", "setting", "compile s", "time s", "peak MB", "RMSE", "max err"], body
    )


def tables(rows: list[dict]) -> str:
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        srows = [r for r in rows if r["scene"] == scene and not r["renderer"].endswith("-res")]
        refs = [k for k in srows[0]["errors"] if k not in ("float32_same_setting",)]
        out += [f"### {scene} ({srows[0]['width']}×{srows[0]['height']})", ""]
        headers = ["renderer", "setting", "compile s", "time s", "CPU s", "peak MB", "RMSE", "max err"]
        headers += [f"RMSE vs {k}" for k in refs if k != "converged"]
        body = []
        for r in srows:
            body.append(
                [
                    r["renderer"],
                    r["setting"],
                    r["compile_s"],
                    r["time_s"],
                    r["cpu_s"],
                    r["peak_mb"],
                    r["rmse"],
                    r["max_err"],
                    *[r["errors"].get(k, {}).get("rmse") for k in refs if k != "converged"],
                ]
            )
        out += [md_table(headers, body), ""]
        f64 = [r for r in srows if "float32_same_setting" in r["errors"]]
        if f64:
            out += [
                "float32 vs float64 at the same setting: "
                + ", ".join(
                    f"{r['setting'].replace(' float64', '')}: "
                    f"RMSE {fmt(r['errors']['float32_same_setting']['rmse'])}, "
                    f"max {fmt(r['errors']['float32_same_setting']['max_err'])}"
                    for r in f64
                ),
                "",
            ]
        floor = srows[0]["reference_floor"]
        out += [
            "References against the converged one (the floor of every error above): "
            + ", ".join(
                f"{k}: RMSE {fmt(v['rmse'])}, max {fmt(v['max_err'])}"
                for k, v in floor.items()
                if k != "converged"
            ),
            "",
        ]
        res = [r for r in rows if r["scene"] == scene and r["renderer"].endswith("-res")]
        if res:
            out += [
                "Resolution (spp 1 / `-A`; error = ours vs POV-Ray at the same size):",
                "",
                md_table(
                    ["renderer", "size", "compile s", "time s", "CPU s", "peak MB", "RMSE", "max err"],
                    [
                        [
                            r["renderer"],
                            r["setting"],
                            r["compile_s"],
                            r["time_s"],
                            r["cpu_s"],
                            r["peak_mb"],
                            r["rmse"] if r["renderer"] == "ours-res" else None,
                            r["max_err"] if r["renderer"] == "ours-res" else None,
                        ]
                        for r in res
                    ],
                ),
                "",
            ]
    return "\n".join(out)


def write_outputs(doc: dict, out: Path) -> None:
    """Writes accuracy.json, accuracy.png and accuracy.md into ``out`` from a results document."""
    rows, info, failures, wall = doc["rows"], doc["machine"], doc["failures"], doc["wall_s"]
    (out / "accuracy.json").write_text(json.dumps(doc, indent=1))
    if rows:
        plot(rows, out / "accuracy.png")
    load = info["load_average_at_start"]
    md = [
        "# Accuracy vs time",
        "",
        f"{info['cpu']}, {info['cores']} cores, load average at start {fmt(load[0]) if load else '?'}; "
        f"{'quick' if doc['quick'] else 'full'} run, {wall / 60:.1f} min; "
        f"medians of {doc['repeats']} warm runs "
        "(fewer when a setting's runs exceed the time cap: see `runs` in the JSON).",
        "",
        "time: ours and Mitsuba = warm render (compile/JIT excluded, shown separately); POV-Ray = its "
        "Trace Time with 2 threads, printed in whole ms (the median of the readings as durations on "
        "that clock: `benchmarks._worker.quantized_median`). RMSE / max err: linear units, against ours "
        "in float64 at high spp and the deepest setting ('converged'); the other columns use the other "
        "references.",
        "",
        "## Main table",
        "",
        main_table(rows),
        "",
        "## Per scene",
        "",
        tables(rows),
    ]
    if failures:
        md += ["## Failures", "", *[f"- {f.splitlines()[0]}" for f in failures]]
    (out / "accuracy.md").write_text("\n".join(md) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer settings, smaller images (< 15 minutes)")
    ap.add_argument("--out", type=Path, default=Path("out/benchmarks"))
    ap.add_argument("--repeats", type=int, default=3, help="warm runs per setting (median)")
    ap.add_argument("--scenes", nargs="*", default=None, help="subset of: seed whitted lambert area")
    ap.add_argument("--tiny", action="store_true", help=argparse.SUPPRESS)  # smoke test: minimal sweep
    ap.add_argument("--from-json", type=Path, help="only rewrite the .md and .png from this accuracy.json")
    ap.add_argument("--size-scale", type=float, default=None,
                    help="every scene's image size times this (no resolution sweep): the same curves where "
                    "a render's fixed costs weigh less than on the panels' small images")
    args = ap.parse_args(argv)
    if args.from_json:
        args.out.mkdir(parents=True, exist_ok=True)
        write_outputs(json.loads(args.from_json.read_text()), args.out)
        return 0
    plan = sweeps(args.quick or args.tiny)
    if args.tiny:
        plan = [
            SceneSweep(
                s.name,
                (16, 12),
                spp=[1],
                x64_spp=[1] if s.name == "lambert" else [],
                levels=[1, 2] if s.levels else [],
                default_level=s.default_level,
                deep_level=2 if s.levels else None,
                area=[2] if s.area else [],
                default_area=s.default_area,
                deep_area=3 if s.area else None,
                pov_aa=[2],
                adaptive=s.adaptive[:1],  # one setting each: the rows and the plot, not the curve
                mitsuba_spp=[1] if s.mitsuba_spp else [],
                mitsuba_ref_spp=16 if s.mitsuba_spp else None,
                ref_area=2 if s.area else None,
                ref_spp=4,
            )
            for s in plan
        ]
    if args.scenes:
        plan = [s for s in plan if s.name in args.scenes]
    if args.size_scale:
        f = args.size_scale
        plan = [dataclasses.replace(s, size=(round(s.size[0] * f), round(s.size[1] * f)), resolutions=[])
                for s in plan]
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    info = machine()
    rows: list[dict] = []
    failures = []
    with tempfile.TemporaryDirectory(prefix="bench-accuracy-") as tmp:
        runner = Runner(Path(tmp), args.repeats)
        for sw in plan:
            try:
                rows += measure_scene(sw, runner)
            except JobFailed as e:
                failures.append(f"{sw.name}: {e}")
                print(f"accuracy: {sw.name} FAILED: {e}", file=sys.stderr)
    wall = time.perf_counter() - t0
    doc = {
        "machine": info,
        "quick": args.quick,
        "size_scale": args.size_scale,
        "repeats": args.repeats,
        "wall_s": wall,
        "failures": failures,
        "columns": {
            "compile_s": "ours: compile_render (trace + XLA); Mitsuba: first call minus warm median "
            "(Dr.Jit kernel JIT, cold cache); POV-Ray: 0 (it has no compile step)",
            "time_s": "ours/Mitsuba: median warm render wall time; POV-Ray: median of its Trace Times read "
                      "as durations on a 1 ms clock (benchmarks._worker.quantized_median; trace_times_s: "
                      "the readings)",
            "peak_mb": "VmHWM of a fresh process per row (POV-Ray: ru_maxrss of the povray process alone)",
            "rmse/max_err": "linear units, all pixels and channels, vs the row's 'reference'",
        },
        "rows": rows,
    }
    write_outputs(doc, args.out)
    print(f"accuracy: wrote {args.out}/accuracy.{{json,md,png}} in {wall / 60:.1f} min", file=sys.stderr)
    return 1 if failures and not rows else 0


if __name__ == "__main__":
    sys.exit(main())
