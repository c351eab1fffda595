"""Where a warm render's time goes, by raytracer source function.

    python scripts/profile_render.py SCENE.pov WIDTH HEIGHT [--out DIR] [--top N] [--by func|line]

Compiles the scene (``compile_render``, the CLI's path), dumps the optimised HLO, times three warm
renders, records one with ``jax.profiler``, then prints each XLA operation's own time (nested
events subtracted) grouped by how often it ran (per chunk, per tree level, per tile), and that time
attributed to the innermost raytracer frame of each fused instruction (the HLO text's stack-frame
tables). A fusion's time is split evenly over its instructions, so the attribution is a guide, not
a measurement.
"""

from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import os
import re
import statistics
import sys
import tempfile
import time


def _self_times(trace_dir: str):
    path = glob.glob(os.path.join(trace_dir, "**", "*.trace.json.gz"), recursive=True)[-1]
    events = [e for e in json.load(gzip.open(path))["traceEvents"] if e.get("ph") == "X"]
    by_thread = collections.defaultdict(list)
    for e in events:
        by_thread[(e["pid"], e["tid"])].append(e)
    own, count = collections.Counter(), collections.Counter()
    for evs in by_thread.values():
        evs.sort(key=lambda e: (e["ts"], -e["dur"]))
        stack = []
        for e in evs:
            while stack and stack[-1]["ts"] + stack[-1]["dur"] <= e["ts"]:
                stack.pop()
            if stack:
                own[stack[-1]["name"]] -= e["dur"]
            own[e["name"]] += e["dur"]
            count[e["name"]] += 1
            stack.append(e)
    skip = ("$", "np.", "ThunkExecutor")
    return {n: (d, count[n]) for n, d in own.items() if not n.startswith(skip)}


def _hlo_sources(hlo_path: str, by: str):
    """name of each HLO instruction → the raytracer source keys of what it computes."""
    tables = {"FileNames": {}, "FunctionNames": {}, "FileLocations": {}, "StackFrames": {}}
    section, body = None, []
    for line in open(hlo_path).read().split("\n"):
        if line in tables:
            section = line
            continue
        if section and re.match(r"^\d+ ", line):
            i, rest = line.split(" ", 1)
            if section in ("FileNames", "FunctionNames"):
                tables[section][int(i)] = rest.strip('"')
            else:
                tables[section][int(i)] = {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", rest)}
            continue
        section = None
        body.append(line)

    def key(line):
        m = re.search(r"stack_frame_id=(\d+)", line)
        frame, seen = int(m.group(1)) if m else None, set()
        while frame in tables["StackFrames"] and frame not in seen:
            seen.add(frame)
            entry = tables["StackFrames"][frame]
            loc = tables["FileLocations"][entry["file_location_id"]]
            file = tables["FileNames"][loc["file_name_id"]]
            if "/raytracer/" in file:
                func = tables["FunctionNames"][loc["function_name_id"]]
                short = file.split("/raytracer/")[-1]
                return f"{short}:{loc['line']} {func}" if by == "line" else f"{short}:{func}"
            frame = entry["parent_frame_id"]
        return None

    comps, current = {}, None
    for line in body:
        m = re.match(r"^(?:ENTRY )?%?([\w.\-]+) .*\{$", line)
        if m and not line.startswith(" "):
            current = comps.setdefault(m.group(1), [])
        elif current is not None and line.startswith("  "):
            current.append(line)
    instr = {}
    for lines in comps.values():
        for line in lines:
            m = re.match(r"\s+(?:ROOT )?%?([\w.\-]+) = ", line)
            if m:
                instr[m.group(1)] = line

    def sources(name):
        line = instr.get(name)
        if line is None:
            return ["?"]
        m = re.search(r"calls=%?([\w.\-]+)", line)
        keys = []
        if m and "fusion(" in line:
            for inner in comps.get(m.group(1), []):
                if not re.search(r"= \S+ (parameter|bitcast|constant|get-tuple-element)\(", inner):
                    keys += [k for k in [key(inner)] if k]
        return keys or [key(line) or "?"]

    return sources


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("width", type=int)
    ap.add_argument("height", type=int)
    ap.add_argument("--out", default=None, help="folder for the HLO dump and the trace (default: temporary)")
    ap.add_argument("--top", type=int, default=40)
    ap.add_argument("--by", choices=("func", "line"), default="func")
    args = ap.parse_args(argv)
    out = args.out or tempfile.mkdtemp(prefix="profile-render-")
    os.environ["RAYTRACER_CACHE_DIR"] = "off"  # a cached program would not be dumped
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + f" --xla_dump_to={out}/hlo "
                               "--xla_dump_hlo_as_text --xla_dump_hlo_pass_re=NONE").strip()
    import jax

    from raytracer import load_scene
    from raytracer.render import compile_render

    scene = load_scene(args.scene, width=args.width, height=args.height)
    t0 = time.perf_counter()
    run = compile_render(scene, width=args.width, height=args.height)
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(run(scene))
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        jax.block_until_ready(run(scene))
        times.append(time.perf_counter() - t0)
    print(f"compile {compile_s:.2f} s, warm {statistics.median(times):.3f} s (median of 3)")
    jax.profiler.start_trace(f"{out}/trace", create_perfetto_trace=True)
    jax.block_until_ready(run(scene))
    jax.profiler.stop_trace()
    own = _self_times(f"{out}/trace")
    total = sum(d for d, _ in own.values())
    print(f"operation time {total / 1e3:.1f} ms (all threads)\n\nby call count:")
    groups = collections.Counter()
    for d, c in own.values():
        groups[c] += d
    for c, d in groups.most_common(10):
        print(f"  {c:7d} calls: {d / 1e3:8.1f} ms")
    hlo = sorted(glob.glob(f"{out}/hlo/*_render_part.cpu_after_optimizations.txt"))
    if not hlo:
        print("no HLO dump of _render_part found", file=sys.stderr)
        return 1
    sources = _hlo_sources(hlo[-1], args.by)
    by_source = collections.Counter()
    for name, (d, _) in own.items():
        keys = sources(name)
        for k in keys:
            by_source[k] += d / len(keys)
    print("\nby source:")
    for k, d in by_source.most_common(args.top):
        print(f"  {d / 1e3:8.1f} ms {100 * d / total:5.1f} %  {k}")
    print(f"\n(trace and HLO in {out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
