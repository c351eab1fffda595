"""POV-Ray's 396 sample scenes (Debian ``povray-examples``) loaded as the ``raytracer`` command loads
them, and the regression guard built on that: a committed baseline of what each scene gives.

    python -m benchmarks.sample_scenes [--jobs 2] [--timeout 120] [--verbose]   # the load report
    python -m benchmarks.sample_scenes --check [--jobs 2]    # every scene against the baseline
    python -m benchmarks.sample_scenes --write [--jobs 2]    # the baseline, measured again

Each scene is loaded with ``load_scene(…, fit_zero_terms=False)`` (as the command line does), with
its own folder and POV-Ray's include folder on the include path; a scene next to a ``.ini`` of the
same name that describes an animation (the portfolio, ``animations/``) is loaded at the animation's
first frame, as POV-Ray renders it from that ``.ini`` (``benchmarks.sample_renders`` does the same).
Each load runs in a worker process with a time limit, so one hang cannot stall the run.

A scene's record (``record``): its status (``ok``, ``scene_error``, ``crash``, ``timeout``), the
first line of its error without the location, its warnings counted by feature (the interpreter's and
the plan's), its *plan* (primitive, light and layer counts and ``Effects.describe()``: what the
compiled program simulates) and its load time. The baseline (``BASELINE``) holds every scene's
record at one commit. ``compare`` sorts the differences from it into **regressions** — a scene that
loaded no longer does, a warning count grows or a new one appears — and **changes** (a scene loads
that did not, fewer warnings, another plan). Both fail the check: a change that is meant is written
into the baseline with ``--write`` in the same commit, so the baseline always says what main does.

The test suite runs the check on the scenes whose baseline load took under ``SUITE_SECONDS``
in-process (``tests/test_sample_scenes.py``: 344 scenes, about 15 s of CPU over the workers);
``--check`` covers all of them, the slow ones (``language/tracevines.pov``: 180,000 ``trace()``
calls, ~45 s) included. PSNR against POV-Ray's images is a benchmark, not a check
(``benchmarks.coverage``, ``docs/coverage.md``).
"""

from __future__ import annotations

import argparse
import collections
import concurrent.futures as cf
import json
import multiprocessing as mp
import re
import sys
import time
from pathlib import Path

SCENES = Path("/usr/share/povray-3.7/scenes")
INCLUDE = Path("/usr/share/povray-3.7/include")
BASELINE = Path(__file__).resolve().parent.parent / "tests" / "data" / "sample_scenes.json"
# scenes whose baseline load is faster than this are checked by the test suite itself
SUITE_SECONDS = 0.2
# POV-Ray 3.7.0.10 itself stops on these (Debian's package, measured): not ours to load. We load the
# first two (we read image_map and text as warned, not rendered, and never open their files)
POVRAY_REJECTS = {
    "advanced/cliche/cliche.pov": "its image_map file 'sign' is not in the package",
    "incdemo/sort.pov": "its text font 'arial.ttf' is not in the package",
    "portfolio/__empty.pov": "a template: its #include names the file '... .inc'",
}


def animation_ini(scene: Path) -> Path | None:
    """The ``.ini`` of the same name next to ``scene`` if it describes an animation (``Final_Frame`` ≠
    ``Initial_Frame``), whose first frame both renderers then render; else None."""
    ini = scene.with_suffix(".ini")
    if not ini.is_file():
        return None
    from raytracer.sdl import Animation

    anim = Animation.from_ini(ini)
    return ini if anim.final_frame != anim.initial_frame else None


def _reason(message: str) -> str:
    """An error's first line without its location (the file's lines move; the cause does not)."""
    return re.sub(r"^\S+:\d+:\d+: ", "", message.splitlines()[0])[:200]


def record(path: Path) -> dict:
    """What loading ``path`` gives, in this process (see the module's docstring)."""
    import logging

    logging.getLogger("raytracer.sdl").setLevel(logging.ERROR)
    from raytracer._plan import make_plan
    from raytracer.sdl import Animation, SceneError, load_scene

    ini = animation_ini(path)
    t0 = time.perf_counter()
    try:
        scene = load_scene(str(path), include_paths=[str(path.parent), str(INCLUDE)],
                           animation=None if ini is None else Animation.from_ini(ini),
                           fit_zero_terms=False)
        plan = make_plan(scene)
    except SceneError as e:
        return {"status": "scene_error", "error": _reason(str(e)), "load_s": time.perf_counter() - t0}
    except Exception as e:  # noqa: BLE001 - an internal error is what the guard is for
        return {"status": "crash", "error": f"{type(e).__name__}: {_reason(str(e))}",
                "load_s": time.perf_counter() - t0}
    seconds = time.perf_counter() - t0
    warnings = collections.Counter(w.feature for w in plan.warnings)  # the scene's, then the plan's
    layers = max((len(p.texture.layers) for p in plan.prims), default=0)
    return {"status": "ok", "warnings": dict(sorted(warnings.items())),
            "plan": f"{len(plan.prims)} primitives, {len(plan.lights)} lights, {layers} layers; "
                    f"{plan.effects.describe()}",
            "load_s": seconds}


def _record_into(path: str, queue) -> None:
    import jax

    jax.config.update("jax_cpu_enable_async_dispatch", False)  # as the command line does
    queue.put(record(Path(path)))


def record_with_timeout(path: Path, timeout: float) -> dict:
    """``record(path)`` in a forked worker; a worker still running after ``timeout`` s is killed."""
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    proc = ctx.Process(target=_record_into, args=(str(path), queue))
    t0 = time.perf_counter()
    proc.start()
    try:
        return queue.get(timeout=timeout)
    except Exception:  # noqa: BLE001 - the queue's Empty: a hang, or a worker that died
        alive = proc.is_alive()
        return {"status": "timeout" if alive else "crash",
                "error": f"more than {timeout:g} s" if alive else f"worker exit code {proc.exitcode}",
                "load_s": time.perf_counter() - t0}
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()


def scene_names(root: Path = SCENES) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*.pov"))


def measure(names, root: Path = SCENES, jobs: int = 2, timeout: float = 120.0) -> dict[str, dict]:
    with cf.ThreadPoolExecutor(jobs) as pool:
        futures = {pool.submit(record_with_timeout, root / n, timeout): n for n in names}
        return {futures[f]: f.result() for f in cf.as_completed(futures)}


def load_baseline(path: Path = BASELINE) -> dict:
    return json.loads(path.read_text())


def write_baseline(records: dict[str, dict], path: Path = BASELINE) -> None:
    import subprocess

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).parent).stdout.strip()
    out = {"commit": commit, "scenes": {n: {k: (round(v, 3) if k == "load_s" else v) for k, v in r.items()}
                                        for n, r in sorted(records.items())}}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1, ensure_ascii=False) + "\n")


def compare(records: dict[str, dict], baseline: dict[str, dict]) -> tuple[list[str], list[str]]:
    """``(regressions, changes)`` of ``records`` against the baseline's records of the same scenes,
    one line each (the module's docstring says which is which)."""
    regressions, changes = [], []
    for name in sorted(records):
        new, old = records[name], baseline.get(name)
        if old is None:
            changes.append(f"{name}: not in the baseline")
            continue
        if old["status"] == "ok" and new["status"] != "ok":
            regressions.append(f"{name}: loaded, now {new['status']}: {new.get('error', '')}")
            continue
        if new["status"] != "ok":
            if new["status"] != old["status"] or new.get("error") != old.get("error"):
                changes.append(f"{name}: {old['status']} ({old.get('error', '')}) -> {new['status']} "
                               f"({new.get('error', '')})")
            continue
        if old["status"] != "ok":
            changes.append(f"{name}: {old['status']} -> loads")
            continue
        before, after = old["warnings"], new["warnings"]
        for feature in sorted(set(before) | set(after)):
            b, a = before.get(feature, 0), after.get(feature, 0)
            if a > b:
                regressions.append(f"{name}: {a} warnings about {feature!r}, {b} in the baseline")
            elif a < b:
                changes.append(f"{name}: {a} warnings about {feature!r}, {b} in the baseline")
        if new["plan"] != old["plan"]:
            changes.append(f"{name}: plan {new['plan']!r}, in the baseline {old['plan']!r}")
    return regressions, changes


def report(regressions: list[str], changes: list[str]) -> str:
    """The check's message: what differs, and how to make an intended change the baseline."""
    lines = []
    if regressions:
        lines += [f"{len(regressions)} regressions against {BASELINE.name}:",
                  *("  " + r for r in regressions)]
    if changes:
        lines += [f"{len(changes)} changes against {BASELINE.name} (write them into it if they are "
                  "meant: python -m benchmarks.sample_scenes --write):", *("  " + c for c in changes)]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--scenes", type=Path, default=SCENES)
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true", help="compare every scene with the baseline")
    mode.add_argument("--write", action="store_true", help="measure every scene into the baseline")
    ap.add_argument("--verbose", action="store_true", help="print every failure")
    args = ap.parse_args(argv)
    names = scene_names(args.scenes)
    if not names:
        print(f"no .pov files under {args.scenes}", file=sys.stderr)
        return 1
    t0 = time.perf_counter()
    records = measure(names, args.scenes, args.jobs, args.timeout)
    wall = time.perf_counter() - t0
    counts = collections.Counter(r["status"] for r in records.values())
    ok = counts.get("ok", 0)
    print(f"{len(names)} scenes in {wall:.0f} s: {ok} loaded ({100 * ok / len(names):.1f}%), "
          f"{counts.get('scene_error', 0)} SceneError, {counts.get('crash', 0)} other exceptions, "
          f"{counts.get('timeout', 0)} timeouts")
    refused = {n: r for n, r in records.items() if r["status"] != "ok"}
    for n, r in sorted(refused.items()):
        if args.verbose or n not in POVRAY_REJECTS:
            why = f" (POV-Ray refuses it too: {POVRAY_REJECTS[n]})" if n in POVRAY_REJECTS else ""
            print(f"  {n}: {r['status']}: {r.get('error', '')}{why}")
    print("\nslowest:")
    for n, r in sorted(records.items(), key=lambda kv: -kv[1]["load_s"])[:10]:
        print(f"  {r['load_s']:6.2f} s  {r['status']:11s} {n}")
    if args.write:
        write_baseline(records)
        print(f"\nwrote {BASELINE}")
        return 0
    if args.check:
        regressions, changes = compare(records, load_baseline()["scenes"])
        if regressions or changes:
            print("\n" + report(regressions, changes))
            return 1
        print(f"\nevery scene as in {BASELINE.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
