"""POV-Ray's own sample scenes rendered by POV-Ray 3.7 and by us, side by side: how a user who tries
the scenes that come with POV-Ray will judge us.

    python -m benchmarks.sample_renders [--size 160x120] [--timeout 300] [--max-memory-mb 8000]
                                        [--scenes GLOB …] [--list FILE] [--limit N] [--seed S]
                                        [--out DIR] [--from-json F] [--repeats N] [--threads N]

Which scenes: every ``.pov`` under ``/usr/share/povray-3.7/scenes`` (396 in Debian's
``povray-examples``), or those matching ``--scenes`` globs relative to that folder
(``'advanced/*.pov'``, ``'objects/**/*.pov'``: quote them) and/or listed in ``--list FILE`` (one
relative path a line, ``#`` comments). ``--limit N`` keeps N of them chosen at random with ``--seed S``: the
candidates are shuffled with ``random.Random(S)`` and the first N kept, so the choice is
deterministic and a larger N keeps the scenes of a smaller one. Scenes run in that order.

Each scene file is read as it is, by both renderers (speed.py does the same): we do not add a
``#version``/``assumed_gamma`` header, because our renderer follows the scene's own gamma rules to
produce the linear image POV-Ray writes to a ``+FE`` EXR (semantics §3.1: ``_output_transfer``), so
the two linear images compare like with like. Includes come from the scene's folder and POV-Ray's
include folder (ours: ``load_scene``'s search path; POV-Ray: ``+L`` and its ``povray.ini``). A scene
next to a ``.ini`` of the same name that describes an animation (``Final_Frame`` ≠ ``Initial_Frame``:
the portfolio, ``animations/``, ``advanced/desk``) is rendered at the animation's first frame by both
(``benchmarks/sample_scenes.py`` loads a scene at that frame when it fails without; here every
animation is, so that both renderers see the same ``clock`` and ``frame_number``: POV-Ray gets the
animation's frame range and clocks and renders only that frame).

Every measurement is a fresh worker process (``benchmarks/_worker.py``), one at a time, with a
timeout (``--timeout`` s per renderer and scene) and a memory limit (``--max-memory-mb``: resident
memory of the worker and what it started; the machine has no swap):

* ours (``kind: ours``, spp 1, float32): parse s (``load_scene``), compile s (``compile_render``),
  warm s (median of up to ``--repeats`` runs of the compiled render), whole-process s (the worker's
  age when its first image was ready: interpreter start, imports, parse, compile, one render),
  peak MB, and the scene's warnings (features we parse but do not render: how many, per feature,
  the first few texts);
* POV-Ray (``kind: povray``, ``-A`` one ray per pixel centre as our spp 1, ``+WT<threads>``): its
  own Parse Time and Trace Time, the wall time of the whole ``povray`` process, peak MB;
* ``warm / trace``: our warm time over POV-Ray's Trace Time; ``process / process``: our whole-process
  time over POV-Ray's; PSNR of our linear image against POV-Ray's (``validation.metrics.psnr``,
  peak 1), when both finished.

Our status per scene: ``ok``, ``parse_error`` (a ``SceneError``: the scene uses something we do not
read), ``crash`` (any other failure, in parse, compile or render, or the worker died of a signal such
as SIGSEGV), ``timeout`` or ``memory`` (with the phase it was in), or ``killed`` (SIGTERM, SIGKILL…
from outside the benchmark: not the scene's doing, so a resumed run measures it again). POV-Ray's:
``ok``, ``error``, ``timeout``, ``memory``, ``killed``.

The run is resumable: each scene's record is appended to ``DIR/sample_renders.jsonl`` as it
finishes and scenes already there (at this size) are skipped, so an interrupted run (hours for all
396) goes on where it stopped. ``DIR/images/<scene>.png`` shows POV-Ray | ours | 4×|difference|
(sRGB). The report, ``DIR/sample_renders.md`` and ``.json``, covers every record of this size in
the ``.jsonl`` (not only the scenes of this invocation); ``--from-json F`` (a ``.jsonl`` or
``.json``) only rewrites it. The machine may be shared: compare ratios, not absolute times.
"""

from __future__ import annotations

import argparse
import collections
import datetime
import json
import math
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._common import JobFailed, MemoryExceeded, fmt, machine, md_table, run_job
from .sample_scenes import SCENES, animation_ini

JSONL = "sample_renders.jsonl"
TOP = 15  # rows of the worst-PSNR and slowest-compile tables
TOP_WARNINGS = 25
DIFF_GAIN = 4.0  # the difference panel of the side-by-side images


# ---------------------------------------------------------------------------------------------------
# Which scenes
# ---------------------------------------------------------------------------------------------------


def all_scenes(root: Path) -> list[str]:
    """Every ``.pov`` under ``root``, as sorted POSIX paths relative to it."""
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*.pov") if p.is_file())


def select(
    root: Path,
    globs: list[str] | None = None,
    list_file: Path | None = None,
    limit: int | None = None,
    seed: int = 0,
) -> list[str]:
    """The scenes to run, in run order, as paths relative to ``root``.

    The candidates are the ``.pov`` files matching ``globs`` (``Path.glob`` patterns relative to
    ``root``) and those listed in ``list_file``, or every scene when neither is given. With ``limit``
    they are shuffled with ``random.Random(seed)`` and the first ``limit`` kept (so a larger limit
    keeps the scenes of a smaller one); otherwise they run sorted.
    """
    if not globs and list_file is None:
        chosen = set(all_scenes(root))
    else:
        chosen = set()
        for pattern in globs or ():
            found = {
                p.relative_to(root).as_posix()
                for p in root.glob(pattern)
                if p.is_file() and p.suffix == ".pov"
            }
            if not found:
                print(f"sample_renders: no .pov file matches {pattern!r} under {root}", file=sys.stderr)
            chosen |= found
        if list_file is not None:
            for n, line in enumerate(Path(list_file).read_text().splitlines(), 1):
                name = line.split("#", 1)[0].strip()
                if not name:
                    continue
                path = Path(name)
                rel = path.relative_to(root) if path.is_absolute() else path
                if not (root / rel).is_file():
                    raise ValueError(f"{list_file}:{n}: no scene {name!r} under {root}")
                chosen.add(rel.as_posix())
    ordered = sorted(chosen)
    if limit is None:
        return ordered
    random.Random(seed).shuffle(ordered)
    return ordered[: max(0, limit)]


def parse_size(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[x×]\s*(\d+)\s*", text)
    if not m or int(m.group(1)) < 1 or int(m.group(2)) < 1:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 160x120, not {text!r}")
    return int(m.group(1)), int(m.group(2))


# ---------------------------------------------------------------------------------------------------
# Measuring one scene
# ---------------------------------------------------------------------------------------------------


def _first_lines(text: str, n: int = 3, width: int = 400) -> str:
    lines = [x.strip() for x in str(text).splitlines() if x.strip()]
    return " / ".join(lines[:n])[:width]


def _pov_message(error: dict) -> str:
    """POV-Ray's own error lines (``Parse Error: …`` and where), else the exception's first line."""
    log = error.get("log_tail", "")
    picked = [x.strip() for x in log.splitlines() if re.search(r"error", x, re.IGNORECASE)]
    return _first_lines("\n".join(picked) if picked else error.get("message", ""), n=3)


def attempt(job: dict, timeout: float, max_rss_mb: float | None) -> dict:
    """Runs ``job`` (a ``catch`` job); its result with ``status`` and, when it did not finish,
    ``message`` and ``phase``. Status: ``ok``, ``error`` (a failure the worker caught: see
    ``error``), ``timeout``, ``memory`` or ``died`` (the worker exited without a result)."""
    progress = Path(job["progress"]) if job.get("progress") else None
    if progress is not None and progress.exists():
        progress.unlink()
    t0 = time.perf_counter()

    def where() -> dict:
        try:
            return json.loads(progress.read_text()) if progress is not None else {}
        except (OSError, ValueError):
            return {}

    try:
        res = run_job(job, timeout=timeout, max_rss_mb=max_rss_mb)
    except subprocess.TimeoutExpired:
        got = where()
        return {
            **got,
            "status": "timeout",
            "message": f"no result after {timeout:g} s",
            "phase": got.pop("phase", None),
            "job_wall_s": time.perf_counter() - t0,
        }
    except MemoryExceeded as e:
        got = where()
        return {
            **got,
            "status": "memory",
            "message": str(e),
            "phase": got.pop("phase", None),
            "job_wall_s": time.perf_counter() - t0,
        }
    except JobFailed as e:
        got = where()
        head, _, stderr = str(e).partition("\n")
        m = re.search(r"job failed \((-?\d+)\)", head)
        code = int(m.group(1)) if m else None
        how = f"exit code {code}" if code is not None else "no result"
        if code is not None and code < 0:
            try:
                how += f" ({signal.Signals(-code).name})"
            except ValueError:
                pass
        tail = [x.strip() for x in stderr.splitlines() if x.strip()]
        # faulthandler's report of a fatal signal: its first line, then the innermost frame first
        fatal = next((i for i, x in enumerate(tail) if x.startswith("Fatal Python error")), None)
        if fatal is not None:
            frame = next((x for x in tail[fatal:] if x.startswith("File ")), "")
            last = f"{tail[fatal]} {frame}".strip()
        else:
            last = tail[-1] if tail else ""
        return {
            **got,
            "status": "died",
            "exit_code": code,
            "message": f"the worker died: {how}" + (f" / {last[:250]}" if last else ""),
            "detail": "\n".join(tail[-15:])[-3000:],
            "phase": got.pop("phase", None),
            "job_wall_s": time.perf_counter() - t0,
        }
    res["job_wall_s"] = time.perf_counter() - t0
    if "error" in res:
        res["status"] = "error"
        res["phase"] = res["error"].get("phase")
    else:
        res["status"] = "ok"
    return res


# a worker ended by one of these did not fail: something outside the benchmark stopped it (the
# kernel's OOM killer sends SIGKILL too); its scene is measured again when the run is resumed
KILLED = {-signal.SIGTERM, -signal.SIGKILL, -signal.SIGINT, -signal.SIGHUP}


def _died(res: dict, failed: str) -> None:
    res["status"] = "killed" if res.get("exit_code") in KILLED else failed


def _ours_status(res: dict) -> dict:
    """Our result with its status named for the report: ok, parse_error, crash, timeout, memory or
    killed (stopped from outside)."""
    if res["status"] == "died":
        _died(res, "crash")
    elif res["status"] == "error":
        err = res["error"]
        text = f"{err.get('type')}: {err.get('message')}"
        if err.get("scene_error"):
            res["status"] = "parse_error"
            res["message"] = _first_lines(err.get("message", ""), n=2)
        elif "RESOURCE_EXHAUSTED" in text or err.get("type") == "MemoryError":
            res["status"] = "memory"
            res["message"] = _first_lines(text, n=2)
        else:
            res["status"] = "crash"
            res["message"] = _first_lines(text, n=2)
    return res


def _pov_status(res: dict) -> dict:
    """POV-Ray's result with its status: ok, error, timeout, memory or killed."""
    if res["status"] == "died":
        _died(res, "error")
    elif res["status"] == "error":
        res["message"] = _pov_message(res["error"])
        if "timed out" in res["error"].get("message", ""):
            res["status"] = "timeout"
    return res


def image_name(scene: str) -> str:
    return scene.removesuffix(".pov").replace("/", "__") + ".png"


def side_by_side(pov: np.ndarray | None, ours: np.ndarray | None, height: int, width: int) -> np.ndarray:
    """POV-Ray | ours | DIFF_GAIN·|difference| as one linear image with 2-pixel white gaps (a missing
    image is black, and so is the difference then)."""
    blank = np.zeros((height, width, 3), np.float32)
    a = blank if pov is None else np.nan_to_num(np.asarray(pov, np.float32), nan=0.0, posinf=1.0)
    b = blank if ours is None else np.nan_to_num(np.asarray(ours, np.float32), nan=0.0, posinf=1.0)
    diff = blank if pov is None or ours is None else np.minimum(1.0, DIFF_GAIN * np.abs(a - b))
    gap = np.ones((height, 2, 3), np.float32)
    return np.concatenate([a, gap, b, gap, diff], axis=1)


def measure(scene: str, root: Path, opts, work: Path, images: Path, stamp: dict) -> dict:
    """Renders ``scene`` (relative to ``root``) with both renderers; its record."""
    from validation.metrics import psnr

    path = root / scene
    width, height = opts.size
    ini = animation_ini(path)
    frame, pov_args = None, []
    if ini is not None:
        from raytracer.sdl import Animation
        from validation.povray import animation_args

        anim = Animation.from_ini(ini)
        pov_args = animation_args(anim)
        frame = {"frame": anim.frame, "final_frame": anim.final_frame, "clock": anim.clock}
    common = {
        "scene": path,
        "width": width,
        "height": height,
        "repeats": opts.repeats,
        "max_total_s": opts.timeout / 4,
        "catch": True,
    }
    ours_npy, pov_npy = work / "ours.npy", work / "pov.npy"
    for f in (ours_npy, pov_npy):
        f.unlink(missing_ok=True)
    ours = _ours_status(
        attempt(
            {
                **common,
                "kind": "ours",
                "ini": ini,
                "spp": 1,
                "quiet": True,
                "image": ours_npy,
                "progress": work / "progress.json",
            },
            opts.timeout,
            opts.max_memory_mb,
        )
    )
    _log(f"  ours    {_summary(ours)}")
    pov = _pov_status(
        attempt(
            {
                **common,
                "kind": "povray",
                "extra_args": pov_args,
                "aa": None,
                "threads": opts.threads,
                "timeout": opts.timeout,
                "image": pov_npy,
            },
            opts.timeout + 30,
            opts.max_memory_mb,
        )
    )
    _log(f"  POV-Ray {_summary(pov)}")
    both = ours["status"] == "ok" and pov["status"] == "ok"
    a = np.load(ours_npy) if ours["status"] == "ok" and ours_npy.exists() else None
    b = np.load(pov_npy) if pov["status"] == "ok" and pov_npy.exists() else None
    value = None
    if a is not None and b is not None and a.shape == b.shape and np.all(np.isfinite(a)):
        value = psnr(a, b)
    image = None
    if a is not None or b is not None:
        from raytracer.imageio import write_png

        image = f"images/{image_name(scene)}"
        write_png(images / image_name(scene), side_by_side(b, a, height, width))
    return {
        "scene": scene,
        "width": width,
        "height": height,
        "ini": None if ini is None else ini.relative_to(root).as_posix(),
        "animation": frame,
        "status": ours["status"],
        "ours": ours,
        "povray": pov,
        "ratio_warm_to_trace": ours["time_s"] / pov["time_s"] if both and pov["time_s"] else None,
        "ratio_process": (ours["first_image_s"] / pov["wall_s"] if both and pov.get("wall_s") else None),
        "psnr_vs_povray": value,
        "image": image,
        **stamp,
        "finished_at": datetime.datetime.now().isoformat(timespec="seconds"),
    }


def _summary(res: dict) -> str:
    if res["status"] != "ok":
        phase = f" ({res['phase']})" if res.get("phase") else ""
        return f"{res['status']}{phase}: {res.get('message', '')[:200]}"
    if "compile_s" in res and "first_image_s" in res:
        return (
            f"parse {res['parse_s']:.2f} s, compile {res['compile_s']:.1f} s, warm {res['time_s']:.3f} s, "
            f"process {res['first_image_s']:.1f} s, {res.get('warnings', 0)} warnings, "
            f"peak {res['peak_mb']:.0f} MB"
        )
    return f"parse {res['parse_s']:.2f} s, trace {res['time_s']:.3f} s, process {res['wall_s']:.2f} s"


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------------------


def read_records(path: Path) -> list[dict]:
    """The records of a ``.jsonl`` (a line cut short by a kill is ignored) or of a report's ``.json``."""
    path = Path(path)
    if not path.exists():
        return []
    if path.suffix == ".json":
        return json.loads(path.read_text())["results"]
    out = []
    for line in path.read_text().splitlines():
        if line.strip():
            try:
                out.append(json.loads(line))
            except ValueError:
                continue
    return out


def append_record(path: Path, record: dict) -> None:
    with open(path, "a") as f:
        f.write(json.dumps(record) + "\n")
        f.flush()
        os.fsync(f.fileno())


def killed(record: dict) -> bool:
    """Whether a renderer of this record was stopped from outside (the scene is measured again)."""
    return "killed" in (record["ours"]["status"], record["povray"]["status"])


def latest(records: list[dict], size: tuple[int, int] | None = None) -> list[dict]:
    """One record per scene (the last one appended), of image ``size`` if given, sorted by scene."""
    by_scene = {}
    for r in records:
        if size is None or (r["width"], r["height"]) == tuple(size):
            by_scene[r["scene"]] = r
    return [by_scene[k] for k in sorted(by_scene)]


# ---------------------------------------------------------------------------------------------------
# Summary statistics
# ---------------------------------------------------------------------------------------------------


def quantile(values: list[float], q: float) -> float | None:
    """The ``q``-quantile by linear interpolation between order statistics (numpy's default), with
    infinite values allowed (identical images have an infinite PSNR)."""
    xs = sorted(values)
    if not xs:
        return None
    pos = q * (len(xs) - 1)
    i = math.floor(pos)
    frac = pos - i
    lo, hi = xs[i], xs[min(i + 1, len(xs) - 1)]
    return lo if frac == 0 or lo == hi else lo + (hi - lo) * frac


def quartiles(values: list[float]) -> dict:
    return {
        "n": len(values),
        "q1": quantile(values, 0.25),
        "median": quantile(values, 0.5),
        "q3": quantile(values, 0.75),
    }


def both_ok(r: dict) -> bool:
    return r["ours"]["status"] == "ok" and r["povray"]["status"] == "ok"


def main_warning(r: dict) -> tuple[str, int] | None:
    """The scene's most frequent warning feature and its count (ties: alphabetical)."""
    features = r["ours"].get("warning_features") or {}
    if not features:
        return None
    return min(features.items(), key=lambda kv: (-kv[1], kv[0]))


def summarize(records: list[dict]) -> dict:
    """Counts, quartiles, worst PSNRs, slowest compiles and warnings of a list of records."""
    finished = [r for r in records if both_ok(r)]
    scored = [r for r in finished if r.get("psnr_vs_povray") is not None]
    is_scored = {id(r) for r in scored}
    stats = {
        "psnr_db": quartiles([r["psnr_vs_povray"] for r in scored]),
        "warm_over_trace": quartiles(
            [r["ratio_warm_to_trace"] for r in finished if r.get("ratio_warm_to_trace")]
        ),
        "process_over_process": quartiles([r["ratio_process"] for r in finished if r.get("ratio_process")]),
        "ours_parse_s": quartiles(
            [r["ours"]["parse_s"] for r in records if r["ours"].get("parse_s") is not None]
        ),
        "ours_compile_s": quartiles([r["ours"]["compile_s"] for r in records if r["ours"]["status"] == "ok"]),
        "ours_warm_s": quartiles([r["ours"]["time_s"] for r in records if r["ours"]["status"] == "ok"]),
        "povray_trace_s": quartiles(
            [r["povray"]["time_s"] for r in records if r["povray"]["status"] == "ok"]
        ),
    }
    worst = sorted(scored, key=lambda r: (r["psnr_vs_povray"], r["scene"]))[:TOP]
    slowest = sorted(
        (r for r in records if r["ours"].get("compile_s") is not None),
        key=lambda r: (-r["ours"]["compile_s"], r["scene"]),
    )[:TOP]

    # warnings: in how many scenes each feature appears, and the PSNR of the scenes with and without it
    with_feature: dict[str, list[dict]] = collections.defaultdict(list)
    for r in records:
        for feature in r["ours"].get("warning_features") or {}:
            with_feature[feature].append(r)
    warnings = []
    for feature, rs in with_feature.items():
        have = [r["psnr_vs_povray"] for r in rs if id(r) in is_scored]
        lack = [
            r["psnr_vs_povray"] for r in scored if feature not in (r["ours"].get("warning_features") or {})
        ]
        alone = [
            r["psnr_vs_povray"]
            for r in rs
            if id(r) in is_scored and set(r["ours"]["warning_features"]) == {feature}
        ]
        med_have, med_lack = quantile(have, 0.5), quantile(lack, 0.5)
        example = next(
            (
                r["ours"].get("warning_examples", {}).get(feature)
                for r in rs
                if r["ours"].get("warning_examples", {}).get(feature)
            ),
            None,
        )
        warnings.append(
            {
                "feature": feature,
                "scenes": len(rs),
                "occurrences": sum(r["ours"]["warning_features"][feature] for r in rs),
                "scored": len(have),
                "median_psnr_with": med_have,
                "median_psnr_without": med_lack,
                "delta_db": (
                    med_have - med_lack
                    if med_have is not None
                    and med_lack is not None
                    and math.isfinite(med_have)
                    and math.isfinite(med_lack)
                    else None
                ),
                "alone_scored": len(alone),
                "median_psnr_alone": quantile(alone, 0.5),
                "example": example,
            }
        )
    warnings.sort(key=lambda w: (-w["scenes"], -w["occurrences"], w["feature"]))
    return {
        "tried": len(records),
        "ours": dict(collections.Counter(r["ours"]["status"] for r in records)),
        "povray": dict(collections.Counter(r["povray"]["status"] for r in records)),
        "finished_by_both": len(finished),
        "scored": len(scored),
        "with_warnings": sum(1 for r in records if r["ours"].get("warnings")),
        "stats": stats,
        "worst_psnr": [r["scene"] for r in worst],
        "slowest_compiles": [r["scene"] for r in slowest],
        "warnings": warnings,
    }


# ---------------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------------


def _reason(message: str) -> str:
    """A message without its location, names and numbers, so that equal causes count together."""
    first = (message or "").split(" / ")[0]
    first = re.sub(r"^\S+:\d+:\d+: ", "", first)
    first = re.sub(r"'[^']*'|\"[^\"]*\"|\d+(\.\d+)?", "…", first)
    return first[:140]


def _x(ratio) -> str | None:
    return None if ratio is None else f"{ratio:.1f}×"


def _cell(res: dict, key: str):
    return res.get(key) if res["status"] == "ok" else None


def _esc(text: str) -> str:
    return (text or "").replace("|", "\\|").replace("\n", " ")


def markdown(records: list[dict], info: dict | None, options: dict | None, source: str | None = None) -> str:
    s = summarize(records)
    by_scene = {r["scene"]: r for r in records}
    sizes = sorted({f"{r['width']}×{r['height']}" for r in records})
    md = ["# POV-Ray's sample scenes: POV-Ray 3.7 and ours side by side", ""]
    if info:
        load = info.get("load_average_at_start")
        md.append(
            f"{info['cpu']}, {info['cores']} cores, load average at start {fmt(load[0]) if load else '?'}; "
            f"jax {info['versions']['jax']}, {info['versions']['povray']}; commit {info['commit']}."
        )
    commits = sorted({r.get("commit") or "?" for r in records})
    if len(commits) > 1:
        md.append(f"The records were measured at commits {', '.join(commits)} (resumed runs).")
    if options:
        md.append(
            f"Size {', '.join(sizes) or '–'}; timeout {options['timeout']:g} s per renderer and scene; "
            f"memory limit {options['max_memory_mb']:g} MB; up to {options['repeats']} warm runs "
            f"(median); POV-Ray `-A +WT{options['threads']}`."
        )
    if source:
        md.append(f"Rewritten from `{source}`.")
    accel = collections.Counter(r["ours"].get("accel") for r in records if r["ours"]["status"] == "ok")
    if accel and set(accel) != {"native"}:
        reasons = sorted({r["ours"]["accel_reason"] for r in records if r["ours"].get("accel_reason")})
        parts = [f"native BVH in {accel['native']} scenes"] if accel.get("native") else []
        if accel.get("none"):
            why = f" ({'; '.join(reasons)})" if reasons else ""
            parts.append(f"none in {accel['none']} scenes{why}: every ray tested every primitive")
        if accel.get(None):
            parts.append(f"not recorded in {accel[None]} scenes")
        md.append(f"**Acceleration**: {'; '.join(parts)}.")
    md += [
        "",
        "Ours: parse = `load_scene`, compile = `compile_render`, warm = the compiled render (spp 1, "
        "float32), process = a fresh process's wait for its first image (interpreter, imports, parse, "
        "compile, render); peak MB of the worker (Python and JAX included). POV-Ray: its own Parse and "
        "Trace Time, process = the `povray` process's wall time. PSNR: our linear image against "
        "POV-Ray's `+FE` EXR (peak 1); both read the scene file as it is. Warnings: features we parse "
        "but do not render. Images "
        f"(`images/`): POV-Ray | ours | {DIFF_GAIN:g}×|difference|, sRGB.",
        "",
        "## Summary",
        "",
        f"- Scenes tried: **{s['tried']}**; finished by both renderers: **{s['finished_by_both']}** "
        f"(PSNR computed for {s['scored']}).",
        "- Ours: " + ", ".join(f"{k} {v}" for k, v in sorted(s["ours"].items(), key=lambda kv: -kv[1])) + ".",
        "- POV-Ray: "
        + ", ".join(f"{k} {v}" for k, v in sorted(s["povray"].items(), key=lambda kv: -kv[1]))
        + ".",
        f"- Scenes with at least one warning: {s['with_warnings']}.",
        "",
    ]
    names = {
        "psnr_db": "PSNR vs POV-Ray, dB",
        "warm_over_trace": "ours warm / POV trace",
        "process_over_process": "ours process / POV process",
        "ours_parse_s": "ours parse s",
        "ours_compile_s": "ours compile s",
        "ours_warm_s": "ours warm s",
        "povray_trace_s": "POV trace s",
    }
    rows = [[names[k], v["n"], v["q1"], v["median"], v["q3"]] for k, v in s["stats"].items()]
    md += [md_table(["", "scenes", "lower quartile", "median", "upper quartile"], rows), ""]

    def warn_cell(r):
        top = main_warning(r)
        if top is None:
            return "–"
        example = (r["ours"].get("warning_examples") or {}).get(top[0])
        return f"{top[0]} ×{top[1]}" + (f": {_esc(example)[:90]}" if example else "")

    def png(r):
        return f"[png]({r['image']})" if r.get("image") else None

    worst = [by_scene[k] for k in s["worst_psnr"]]
    md += _section(
        f"### The {len(worst)} worst PSNRs",
        ["scene", "PSNR dB", "warnings", "most frequent warning", "image"],
        [
            [r["scene"], r["psnr_vs_povray"], r["ours"].get("warnings", 0), warn_cell(r), png(r)]
            for r in worst
        ],
    )
    slowest = [by_scene[k] for k in s["slowest_compiles"]]
    md += _section(
        f"### The {len(slowest)} slowest compiles",
        ["scene", "ours compile s", "ours parse s", "ours warm s", "ours peak MB", "POV trace s", "status"],
        [
            [
                r["scene"],
                r["ours"].get("compile_s"),
                r["ours"].get("parse_s"),
                _cell(r["ours"], "time_s"),
                _cell(r["ours"], "peak_mb"),
                _cell(r["povray"], "time_s"),
                r["status"],
            ]
            for r in slowest
        ],
    )
    md += _section(
        "### Warnings across scenes",
        [
            "feature",
            "scenes",
            "occurrences",
            "median PSNR with (n)",
            "without",
            "Δ dB",
            "only warning: median PSNR (n)",
            "example",
        ],
        [
            [
                w["feature"],
                w["scenes"],
                w["occurrences"],
                f"{fmt(w['median_psnr_with'])} ({w['scored']})",
                w["median_psnr_without"],
                w["delta_db"],
                f"{fmt(w['median_psnr_alone'])} ({w['alone_scored']})",
                _esc(w["example"])[:100],
            ]
            for w in s["warnings"][:TOP_WARNINGS]
        ],
        "Scenes whose warnings name the feature (features we parse but do not render); the median PSNR "
        "of the scenes finished by both with it, without it, the difference, and of the scenes where it "
        "is the only feature warned about (what that missing feature costs on its own).",
    )

    # what did not finish
    md += _section(
        "### Our crashes",
        ["scene", "phase", "message"],
        [
            [r["scene"], r["ours"].get("phase"), _esc(r["ours"].get("message"))[:300]]
            for r in records
            if r["ours"]["status"] == "crash"
        ],
    )
    reasons = collections.defaultdict(list)
    for r in records:
        if r["ours"]["status"] == "parse_error":
            reasons[_reason(r["ours"].get("message", ""))].append(r["scene"])
    md += _section(
        "### Our parse errors (by reason)",
        ["reason", "scenes", "examples"],
        [[_esc(k), len(v), ", ".join(v[:3])] for k, v in sorted(reasons.items(), key=lambda kv: -len(kv[1]))],
    )
    md += _section(
        "### Our timeouts and memory limits",
        ["scene", "status", "phase", "parse s", "compile s", "message"],
        [
            [
                r["scene"],
                r["ours"]["status"],
                r["ours"].get("phase"),
                r["ours"].get("parse_s"),
                r["ours"].get("compile_s"),
                _esc(r["ours"].get("message"))[:200],
            ]
            for r in records
            if r["ours"]["status"] in ("timeout", "memory")
        ],
    )
    md += _section(
        "### Our images with NaN or infinite values (no PSNR)",
        ["scene", "non-finite values"],
        [
            [r["scene"], r["ours"]["nonfinite"]]
            for r in records
            if r["ours"]["status"] == "ok" and r["ours"].get("nonfinite")
        ],
    )
    md += _section(
        "### POV-Ray did not finish",
        ["scene", "status", "our status", "message"],
        [
            [r["scene"], r["povray"]["status"], r["ours"]["status"], _esc(r["povray"].get("message"))[:300]]
            for r in records
            if r["povray"]["status"] != "ok"
        ],
    )
    md += _section(
        "## Every scene",
        [
            "scene",
            "status",
            "ours parse s",
            "ours compile s",
            "ours warm s",
            "ours process s",
            "ours peak MB",
            "warnings",
            "POV parse s",
            "POV trace s",
            "POV process s",
            "warm / trace",
            "process / process",
            "PSNR dB",
            "image",
        ],
        [
            [
                r["scene"] + (f" (frame {r['animation']['frame']})" if r.get("animation") else ""),
                r["status"]
                if r["povray"]["status"] == "ok"
                else f"{r['status']}; POV-Ray {r['povray']['status']}",
                r["ours"].get("parse_s"),
                _cell(r["ours"], "compile_s"),
                _cell(r["ours"], "time_s"),
                _cell(r["ours"], "first_image_s"),
                _cell(r["ours"], "peak_mb"),
                r["ours"].get("warnings"),
                _cell(r["povray"], "parse_s"),
                _cell(r["povray"], "time_s"),
                _cell(r["povray"], "wall_s"),
                _x(r.get("ratio_warm_to_trace")),
                _x(r.get("ratio_process")),
                r.get("psnr_vs_povray"),
                png(r),
            ]
            for r in records
        ],
    )
    return "\n".join(md)


def _section(title: str, headers: list[str], rows: list[list], intro: str | None = None) -> list[str]:
    """A markdown section with one table, or nothing when there are no rows."""
    if not rows:
        return []
    return [title, "", *([intro, ""] if intro else []), md_table(headers, rows), ""]


def write_report(
    records: list[dict], out: Path, info: dict | None, options: dict | None, source: str | None = None
) -> str:
    text = markdown(records, info, options, source)
    doc = {"machine": info, "options": options, "summary": summarize(records), "results": records}
    (out / "sample_renders.json").write_text(json.dumps(doc, indent=1))
    (out / "sample_renders.md").write_text(text)
    return text


# ---------------------------------------------------------------------------------------------------
# Main
# ---------------------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=parse_size, default=(160, 120), help="WIDTHxHEIGHT (default 160x120)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per renderer and scene")
    ap.add_argument(
        "--max-memory-mb",
        type=float,
        default=8000.0,
        help="stop a renderer whose resident memory exceeds this (the machine is shared)",
    )
    ap.add_argument("--scenes", nargs="+", metavar="GLOB", help="globs relative to the scenes folder")
    ap.add_argument("--list", type=Path, metavar="FILE", help="a file of scene paths, one a line")
    ap.add_argument("--limit", type=int, help="this many scenes, chosen at random with --seed")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("out/benchmarks/sample_renders"))
    ap.add_argument(
        "--from-json", type=Path, metavar="F", help="only rewrite the report from this .jsonl or .json"
    )
    ap.add_argument("--repeats", type=int, default=3, help="warm runs per renderer (median; fewer when slow)")
    ap.add_argument("--threads", type=int, default=2, help="POV-Ray render threads (+WT)")
    ap.add_argument("--root", type=Path, default=SCENES, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    options = {
        "size": list(args.size),
        "timeout": args.timeout,
        "max_memory_mb": args.max_memory_mb,
        "repeats": args.repeats,
        "threads": args.threads,
    }
    if args.from_json:
        src = args.from_json
        doc = json.loads(src.read_text()) if src.suffix == ".json" else {}
        records = latest(read_records(src))
        opts = doc.get("options") or next((r["options"] for r in reversed(records) if r.get("options")), None)
        print(write_report(records, args.out, doc.get("machine"), opts, str(src)))
        return 0

    scenes = select(args.root, args.scenes, args.list, args.limit, args.seed)
    log = args.out / JSONL
    size = tuple(args.size)
    done = {r["scene"] for r in latest(read_records(log), size) if not killed(r)}
    todo = [s for s in scenes if s not in done]
    _log(
        f"sample_renders: {len(scenes)} scenes selected, {len(scenes) - len(todo)} already in {log}, "
        f"{len(todo)} to render at {size[0]}×{size[1]}"
    )
    info = machine()
    stamp = {"commit": info["commit"], "load_average": info["load_average_at_start"], "options": options}
    images = args.out / "images"
    images.mkdir(exist_ok=True)
    interrupted = False
    with tempfile.TemporaryDirectory(prefix="bench-samples-") as tmp:
        for i, scene in enumerate(todo, 1):
            _log(f"[{i}/{len(todo)}] {scene} …")
            try:
                append_record(log, measure(scene, args.root, args, Path(tmp), images, stamp))
            except KeyboardInterrupt:
                interrupted = True
                _log("interrupted: the report covers the scenes finished so far")
                break
    records = latest(read_records(log), size)
    print(write_report(records, args.out, info, options))
    return 130 if interrupted else 0


if __name__ == "__main__":
    sys.exit(main())
