"""One measurement in a fresh process: ``python -m benchmarks._worker`` reads a job (JSON) on stdin and
prints its result (JSON) as the last line of stdout.

A fresh process per measurement makes the peak memory mean something: ``ru_maxrss`` is the
high-water mark of resident memory of *this* process (our renderer, Mitsuba), or of its only child
(POV-Ray, ``RUSAGE_CHILDREN``). It includes the Python interpreter and the imported libraries;
``base_mb`` is the high-water mark just before the measured work started.

Jobs (all take ``scene`` (a .pov path), ``width``, ``height``, ``repeats`` and optionally ``image``,
a ``.npy`` path to write the last image to):

* ``{"kind": "ours", "spp": k², "x64": bool}``: parse, compile (``compile_render``), then ``repeats``
  warm renders. ``x64`` turns ``jax_enable_x64`` on before anything is created.
* ``{"kind": "ours_grad", "spp": k², "x64": bool}``: parse, then compile and time (``repeats`` warm
  runs) ``jax.jit(jax.grad(loss))`` with ``loss = mean(render(scene))`` differentiated with respect to
  every inexact array leaf of the scene (``eqx.partition(scene, eqx.is_inexact_array)``, as
  ``benchmarks/gradients.py``): reverse mode through the full-width ray tree. ``image`` is not written.
* ``{"kind": "povray", "aa": null | [threshold, depth], "threads": 2}``: ``repeats`` runs of the
  ``povray`` binary through :func:`validation.povray.run_povray`; POV-Ray's own Parse and Trace Time
  and its CPU seconds are read from its log.
* ``{"kind": "mitsuba", "spp": n, "seed": 0}``: the scene converted with
  :func:`validation.mitsuba.to_mitsuba`, loaded once, then rendered ``repeats + 1`` times to a
  box-filtered film: the first call JIT-compiles Dr.Jit's kernels (``first_s``; run with an empty
  ``$HOME`` so that Dr.Jit's on-disk kernel cache is cold), the others are warm.
"""

from __future__ import annotations

import json
import os
import re
import resource
import statistics
import sys
import time


def _rss_mb(who=resource.RUSAGE_SELF) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0  # Linux: kilobytes


def _save(path, image) -> None:
    if path:
        import numpy as np

        np.save(path, np.asarray(image))


def _timed_runs(fn, repeats: int, max_total_s: float):
    """Runs ``fn`` ``repeats`` times (fewer if the runs together exceed ``max_total_s``, at least one);
    returns (wall seconds, CPU seconds of this process, last result)."""
    walls, cpus, out = [], [], None
    for _ in range(max(1, repeats)):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        if sum(walls) > max_total_s:
            break
    return walls, cpus, out


def run_ours(job: dict) -> dict:
    import jax

    if job.get("x64"):
        jax.config.update("jax_enable_x64", True)  # before the scene (and its arrays) exist
    from raytracer import load_scene
    from raytracer.render import compile_render

    t0 = time.perf_counter()
    scene = load_scene(job["scene"], width=job["width"], height=job["height"])
    parse_s = time.perf_counter() - t0
    base_mb = _rss_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    run = compile_render(scene, width=job["width"], height=job["height"], spp=job.get("spp", 1))
    compile_s = time.perf_counter() - t0
    compile_cpu_s = time.process_time() - c0
    walls, cpus, image = _timed_runs(
        lambda: jax.block_until_ready(run(scene)), job.get("repeats", 3), job.get("max_total_s", 120.0)
    )
    _save(job.get("image"), image)
    return {
        "parse_s": parse_s,
        "compile_s": compile_s,
        "compile_cpu_s": compile_cpu_s,
        "times_s": walls,
        "cpu_s": cpus,
        "time_s": statistics.median(walls),
        "peak_mb": _rss_mb(),
        "base_mb": base_mb,
        "dtype": str(image.dtype),
        "devices": len(jax.devices()),
    }


def run_ours_grad(job: dict) -> dict:
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    if job.get("x64"):
        jax.config.update("jax_enable_x64", True)
    from raytracer import load_scene, render

    width, height, spp = job["width"], job["height"], job.get("spp", 1)
    t0 = time.perf_counter()
    scene = load_scene(job["scene"], width=width, height=height)
    parse_s = time.perf_counter() - t0
    params, rest = eqx.partition(scene, eqx.is_inexact_array)

    def loss(p):
        return jnp.mean(render(eqx.combine(p, rest), width=width, height=height, spp=spp))

    base_mb = _rss_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    grad = jax.jit(jax.grad(loss)).lower(params).compile()
    compile_s = time.perf_counter() - t0
    compile_cpu_s = time.process_time() - c0
    walls, cpus, g = _timed_runs(
        lambda: jax.block_until_ready(grad(params)), job.get("repeats", 3), job.get("max_total_s", 120.0)
    )
    leaves = jax.tree_util.tree_leaves(g)
    return {
        "parse_s": parse_s,
        "compile_s": compile_s,
        "compile_cpu_s": compile_cpu_s,
        "times_s": walls,
        "cpu_s": cpus,
        "time_s": statistics.median(walls),
        "peak_mb": _rss_mb(),
        "base_mb": base_mb,
        "parameters": int(sum(x.size for x in leaves)),
        "finite": bool(all(bool(jnp.all(jnp.isfinite(x))) for x in leaves)),
        "devices": len(jax.devices()),
    }


_CPU = re.compile(r"Trace Time:.*?\n\s*using (\d+) thread\(s\) with ([0-9.]+) CPU-seconds total")


def run_povray(job: dict) -> dict:
    from validation.povray import run_povray as run

    aa = job.get("aa")
    results = []

    def once():
        t0 = time.perf_counter()
        r = run(
            job["scene"],
            job["width"],
            job["height"],
            antialias=tuple(aa) if aa else None,
            threads=job.get("threads", 2),
            timeout=job.get("timeout", 900.0),
        )
        results.append((r, time.perf_counter() - t0))
        return r

    walls, _, r = _timed_runs(once, job.get("repeats", 3), job.get("max_total_s", 120.0))
    traces = [x.trace_seconds for x, _ in results]
    cpu = [float(m.group(2)) for x, _ in results if (m := _CPU.search(x.log))]
    threads = [int(m.group(1)) for x, _ in results if (m := _CPU.search(x.log))]
    _save(job.get("image"), r.image)
    return {
        "parse_s": statistics.median(x.parse_seconds or 0.0 for x, _ in results),
        "compile_s": 0.0,
        "trace_times_s": traces,
        "time_s": statistics.median(traces),
        "wall_times_s": walls,
        "wall_s": statistics.median(walls),
        "cpu_s": cpu,
        "threads": threads[-1] if threads else None,
        "peak_mb": _rss_mb(resource.RUSAGE_CHILDREN),
        "command": " ".join(r.command[:-1]),
    }


def run_mitsuba(job: dict) -> dict:
    import numpy as np

    from raytracer import load_scene
    from validation.mitsuba import load, mitsuba, to_mitsuba

    mi = mitsuba()
    scene = load_scene(job["scene"], width=job["width"], height=job["height"])
    t0 = time.perf_counter()
    mi_scene = load(to_mitsuba(scene, job["width"], job["height"]))
    load_s = time.perf_counter() - t0
    base_mb = _rss_mb()
    spp, seed = int(job["spp"]), int(job.get("seed", 0))

    def once():
        return np.asarray(mi.render(mi_scene, spp=spp, seed=seed), dtype=np.float32)[..., :3]

    c0, t0 = time.process_time(), time.perf_counter()
    once()
    first_s, first_cpu = time.perf_counter() - t0, time.process_time() - c0
    walls, cpus, image = _timed_runs(once, job.get("repeats", 3), job.get("max_total_s", 120.0))
    _save(job.get("image"), image)
    return {
        "parse_s": load_s,
        "compile_s": max(0.0, first_s - statistics.median(walls)),
        "first_s": first_s,
        "first_cpu_s": first_cpu,
        "times_s": walls,
        "cpu_s": cpus,
        "time_s": statistics.median(walls),
        "peak_mb": _rss_mb(),
        "base_mb": base_mb,
        "variant": mi.variant(),
    }


def main() -> int:
    job = json.loads(sys.stdin.read())
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    kind = job["kind"]
    jobs = {"ours": run_ours, "ours_grad": run_ours_grad, "povray": run_povray, "mitsuba": run_mitsuba}
    result = jobs[kind](job)
    sys.stdout.write("\n" + json.dumps(result) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
