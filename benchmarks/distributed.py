"""Speed-up of one render split across processes (``raytracer.distributed``) on this machine.

    python -m benchmarks.distributed [--scene F] [--size 640x480] [--spp 1] [--processes 1,2]
                                     [--cpu-devices 1,2] [--repeats 3] [--grad] [--out DIR]

For each process count P, P worker processes on localhost (``jax.distributed``, gloo collectives
over TCP, one CPU device each) render the same scene together; each reports its compile (first
call) and the median of ``--repeats`` warm calls, wall clock around the whole call (the gather of
the parts included). ``--grad`` also times ``distributed.value_and_grad`` of the image's mean
square. P = 1 is a single process without ``jax.distributed``: ``raytracer.render``'s path.
``--cpu-devices`` also splits each process's CPU into that many JAX devices
(``--xla_force_host_platform_device_count``), over which a process shards its tiles: every
combination of the two lists is measured.
Results: ``DIR/distributed.json`` and a Markdown table on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENE = ROOT / "benchmarks" / "scenes" / "whitted.pov"


def _worker(args) -> None:
    import jax

    if args.processes > 1:
        jax.distributed.initialize(coordinator_address=args.address, num_processes=args.processes,
                                   process_id=args.rank)
    import jax.numpy as jnp

    from raytracer import distributed, load_scene

    width, height = (int(v) for v in args.size.split("x"))
    scene = load_scene(args.scene, width=width, height=height)
    out = {"rank": args.rank, "processes": args.processes, "devices": jax.device_count()}

    def timed(fn):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        first = time.perf_counter() - t0
        warm = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(fn())
            warm.append(time.perf_counter() - t0)
        return first, statistics.median(warm)

    out["render_first_s"], out["render_warm_s"] = timed(
        lambda: distributed.render(scene, width=width, height=height, spp=args.spp))
    if args.grad:
        out["grad_first_s"], out["grad_warm_s"] = timed(lambda: distributed.value_and_grad(
            lambda im: jnp.mean(im ** 2), scene, width=width, height=height, spp=args.spp)[0])
    Path(args.result).write_text(json.dumps(out))
    if args.processes > 1:
        jax.distributed.shutdown()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _run(args, processes: int, devices: int, out_dir: Path) -> list[dict]:
    address = f"127.0.0.1:{_free_port()}"
    procs, files = [], []
    for rank in range(processes):
        result = out_dir / f"p{processes}_d{devices}_r{rank}.json"
        files.append(result)
        cmd = [sys.executable, "-m", "benchmarks.distributed", "--worker", "--address", address,
               "--rank", str(rank), "--processes", str(processes), "--result", str(result),
               "--scene", str(args.scene), "--size", args.size, "--spp", str(args.spp),
               "--repeats", str(args.repeats)] + (["--grad"] if args.grad else [])
        flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={devices}".strip()
        env = {**os.environ, "JAX_PLATFORMS": "cpu", "XLA_FLAGS": flags}
        procs.append(subprocess.Popen(cmd, cwd=ROOT, env=env))
    for p in procs:
        if p.wait() != 0:
            raise SystemExit(f"a worker of the {processes}-process, {devices}-device run failed")
    return [json.loads(f.read_text()) for f in files]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(DEFAULT_SCENE))
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--processes", default="1,2")
    ap.add_argument("--cpu-devices", default="1")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--grad", action="store_true")
    ap.add_argument("--out", default="out/distributed")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--address", help=argparse.SUPPRESS)
    ap.add_argument("--rank", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--result", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        args.processes = int(args.processes)
        _worker(args)
        return
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    runs = [(p, d) for d in (int(v) for v in args.cpu_devices.split(","))
            for p in (int(v) for v in args.processes.split(","))]
    for p, d in runs:
        results = _run(args, p, d, out_dir)
        row = {"processes": p, "devices": results[0]["devices"]}
        for key in results[0]:
            if key.endswith("_s"):
                row[key] = max(r[key] for r in results)  # the image is ready when the slowest is
        rows.append(row)
    base = rows[0]
    for row in rows:
        row["render_speedup"] = base["render_warm_s"] / row["render_warm_s"]
        if args.grad:
            row["grad_speedup"] = base["grad_warm_s"] / row["grad_warm_s"]
    (out_dir / "distributed.json").write_text(json.dumps({"scene": str(args.scene), "size": args.size,
                                                          "spp": args.spp, "rows": rows}, indent=1))
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for row in rows:
        cells = (f"{row[k]:.3g}" if isinstance(row[k], float) else str(row[k]) for k in keys)
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
