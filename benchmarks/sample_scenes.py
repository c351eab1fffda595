"""Load rate of POV-Ray's 396 sample scenes (Debian ``povray-examples``) with ``load_scene``.

Each scene loads in a worker process with a time limit, so one hang cannot stall the run. Prints
the counts, the slowest scenes and the most common failure reasons; failures that come with a
POV-Ray .ini (the portfolio's animations) are retried at the INI's first frame and counted apart.

    python -m benchmarks.sample_scenes [--jobs 2] [--timeout 30] [--scenes DIR] [--verbose]
"""

from __future__ import annotations

import argparse
import collections
import concurrent.futures as cf
import multiprocessing as mp
import re
import sys
import time
from pathlib import Path

SCENES = Path("/usr/share/povray-3.7/scenes")
INCLUDE = Path("/usr/share/povray-3.7/include")


def _load_one(path: str, queue, ini: str | None = None) -> None:
    import logging

    logging.getLogger("raytracer.sdl").setLevel(logging.ERROR)
    import jax

    jax.config.update("jax_cpu_enable_async_dispatch", False)  # as the CLI does (see cli.py)
    from raytracer.sdl import Animation, SceneError, load_scene

    t0 = time.perf_counter()
    try:
        animation = None if ini is None else Animation.from_ini(ini)
        scene = load_scene(path, include_paths=[str(Path(path).parent), str(INCLUDE)],
                           animation=animation)
        queue.put(("ok", f"{len(scene.objects)} objects, {len(scene.warnings)} warnings",
                   time.perf_counter() - t0))
    except SceneError as e:
        queue.put(("scene_error", str(e), time.perf_counter() - t0))
    except BaseException as e:  # noqa: BLE001 - the point is to catch what should never escape
        queue.put(("crash", f"{type(e).__name__}: {e}", time.perf_counter() - t0))


def load_with_timeout(path: str, timeout: float, ini: str | None = None) -> tuple[str, str, float]:
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    proc = ctx.Process(target=_load_one, args=(path, queue, ini))
    t0 = time.perf_counter()
    proc.start()
    proc.join(timeout)
    if proc.is_alive():
        proc.kill()
        proc.join()
        return "timeout", f"more than {timeout:g} s", time.perf_counter() - t0
    try:
        return queue.get(timeout=5)
    except Exception:  # noqa: BLE001
        return "crash", f"worker exited with code {proc.exitcode}", time.perf_counter() - t0


def _reason(status: str, message: str) -> str:
    """The message without its location, so equal causes count together."""
    first = message.splitlines()[0]
    first = re.sub(r"^\S+:\d+:\d+: ", "", first)
    first = re.sub(r"'[^']*'|\"[^\"]*\"|\d+(\.\d+)?", "…", first)
    return f"{status}: {first[:110]}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=30.0)
    ap.add_argument("--scenes", type=Path, default=SCENES)
    ap.add_argument("--verbose", action="store_true", help="print every failure")
    args = ap.parse_args(argv)
    files = sorted(str(p) for p in args.scenes.rglob("*.pov"))
    if not files:
        print(f"no .pov files under {args.scenes}", file=sys.stderr)
        return 1
    results = {}
    t0 = time.perf_counter()
    with cf.ThreadPoolExecutor(args.jobs) as pool:
        futs = {pool.submit(load_with_timeout, f, args.timeout): f for f in files}
        for fut in cf.as_completed(futs):
            results[futs[fut]] = fut.result()
    wall = time.perf_counter() - t0
    counts = collections.Counter(status for status, _, _ in results.values())
    n = len(files)
    ok = counts.get("ok", 0)
    print(f"{n} scenes in {wall:.0f} s: {ok} loaded ({100 * ok / n:.1f}%), "
          f"{counts.get('scene_error', 0)} SceneError, {counts.get('crash', 0)} other exceptions, "
          f"{counts.get('timeout', 0)} timeouts")
    print("\nslowest:")
    for f, (status, _, dt) in sorted(results.items(), key=lambda kv: -kv[1][2])[:10]:
        print(f"  {dt:6.2f} s  {status:11s} {Path(f).relative_to(args.scenes)}")
    reasons = collections.Counter(_reason(s, m) for s, m, _ in results.values() if s != "ok")
    if reasons:
        print("\nmost common failure reasons:")
        for reason, k in reasons.most_common(15):
            print(f"  {k:4d}  {reason}")
    # POV-Ray renders the portfolio scenes as animations from their .ini files (frame_number
    # indexes arrays there); load each failure that has one at its first frame, as povray would
    retry = {f: str(Path(f).with_suffix(".ini")) for f, (s, _, _) in results.items()
             if s != "ok" and Path(f).with_suffix(".ini").is_file()}
    if retry:
        with cf.ThreadPoolExecutor(args.jobs) as pool:
            again = dict(zip(retry, pool.map(lambda f: load_with_timeout(f, args.timeout, retry[f]),
                                              retry), strict=True))
        more = sum(1 for status, _, _ in again.values() if status == "ok")
        print(f"\nwith their .ini's animation settings (first frame): {more} of the {len(retry)} "
              f"failures that have one load too: {ok + more} of {n} ({100 * (ok + more) / n:.1f}%)")
    if args.verbose:
        print("\nfailures:")
        for f, (status, msg, _) in sorted(results.items()):
            if status != "ok":
                print(f"  {Path(f).relative_to(args.scenes)}: {status}: {msg.splitlines()[0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
