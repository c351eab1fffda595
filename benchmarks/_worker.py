"""One measurement in a fresh process: ``python -m benchmarks._worker`` reads a job (JSON) on stdin and
prints its result (JSON) as the last line of stdout.

A fresh process per measurement makes the peak memory mean something: ``VmHWM`` is the
high-water mark of resident memory of *this* process (our renderer, Mitsuba; ``ru_maxrss`` would
carry the parent's across ``exec``), ``ru_maxrss`` that of its only child (POV-Ray,
``RUSAGE_CHILDREN``). It includes the Python interpreter and the imported libraries;
``base_mb`` is the high-water mark just before the measured work started.

Jobs (all take ``scene`` (a .pov path), ``width``, ``height``, ``repeats`` and optionally ``image``,
a ``.npy`` path to write the last image to):

* ``{"kind": "ours", "spp": k², "x64": bool}``: parse, compile (``compile_render``), one first render
  (``first_render_s``: where the compiled room is too small for the ray tree, ``compile_render``
  compiles again inside it), unmeasured warm renders (``_warm_up``), then ``repeats`` warm renders.
  ``x64`` turns ``jax_enable_x64`` on before anything is created. With ``"adaptive": [threshold,
  depth]``, ``render(…, adaptive=)`` instead (its first call, compile and one render, is the compile
  time). The scene is loaded as the ``raytracer`` command loads it (``fit_zero_terms=False``: a
  filter written as 0 is opaque).
* ``{"kind": "ours_grad", "spp": k², "x64": bool}``: parse, then compile and time (``repeats`` warm
  runs) ``jax.jit(jax.grad(loss))`` with ``loss = mean(render(scene))`` differentiated with respect to
  every inexact array leaf of the scene (``eqx.partition(scene, eqx.is_inexact_array)``, as
  ``benchmarks/gradients.py``): reverse mode through the full-width ray tree. ``image`` is not written.
* ``{"kind": "povray", "aa": null | [threshold, depth], "threads": 2}``: ``repeats`` runs of the
  ``povray`` binary through :func:`validation.povray.run_povray`; POV-Ray's own Parse and Trace Time
  and its CPU seconds are read from its log. Its ``time_s`` is the median of the Trace Times read as
  durations on a clock of 1 ms ticks (:func:`quantized_median`; ``trace_median_s`` is their plain
  median, ``trace_times_s`` the readings).
* ``{"kind": "mitsuba", "spp": n, "seed": 0}``: the scene converted with
  :func:`validation.mitsuba.to_mitsuba`, loaded once, then rendered to a box-filtered film: the first
  call JIT-compiles Dr.Jit's kernels (``first_s``; run with an empty ``$HOME`` so that Dr.Jit's
  on-disk kernel cache is cold), then unmeasured warm renders (``_warm_up``) and ``repeats`` warm
  ones.

Optional keys of the ``ours`` and ``povray`` jobs (``benchmarks/sample_renders.py`` uses them):

* ``include_paths``: further ``#include`` folders (ours: ``load_scene(include_paths=)``; POV-Ray: ``+L``).
* ``ini`` (ours): a POV-Ray ``.ini`` whose animation's first frame is loaded
  (``Animation.from_ini``); the result's ``animation`` says which frame. ``extra_args`` (POV-Ray):
  further command-line options, such as :func:`validation.povray.animation_args` of that frame. (The
  POV-Ray worker does not read the .ini itself: importing ``raytracer`` there would make a child of
  the size of a JAX process, and ``RUSAGE_CHILDREN`` would count it as POV-Ray's peak memory.)
* ``catch``: report a failure as the result ``{"error": {"type", "message", "phase", …}, …}`` (with
  what was measured before it) instead of exiting non-zero; ``phase`` is ``parse``, ``compile`` or
  ``render`` (ours) or ``povray``.
* ``progress``: a file path; ours writes the phase it is in and what it has measured so far there
  (JSON), so a caller that kills the worker on a timeout knows where it was.
* ``quiet``: silence the scene's warnings on stderr (ours; they are counted in the result anyway).
* ``cpu_devices`` (ours): JAX devices to split the CPU into (default: one per core, as the
  ``raytracer`` command; tiles are sharded over them). The result's ``devices`` says how many.

Ours also reports ``warnings`` (how many the scene has), ``warning_features`` (their count per
feature), ``warning_examples`` (the first message of each feature), ``warning_texts`` (the first
few), ``first_image_s`` (the age of the worker process when the first image was ready: interpreter
start, imports, parse, compile and one render, as a user of a fresh ``raytracer`` process waits),
``nonfinite`` (NaN or infinite values in the image) and ``accel`` (``native``: the renders used the
native bounding volume hierarchy; ``none``: every ray tested every primitive, ``accel_reason`` says
why). POV-Ray's result has ``wall_s``, the wall
time of the whole ``povray`` process (median over the runs).
"""

from __future__ import annotations

import json
import os
import re
import resource
import statistics
import sys
import time

_T0 = time.perf_counter()  # as early as this process measures anything (see _process_age_s)
WARNING_TEXTS = 5  # ours: how many warning texts the result carries


def _process_age_s() -> float:
    """Seconds since this process started (the interpreter's start included, from /proc on Linux;
    elsewhere since this module was imported)."""
    try:
        start_ticks = int(open("/proc/self/stat").read().rsplit(")", 1)[1].split()[19])  # field 22
        uptime = float(open("/proc/uptime").read().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return time.perf_counter() - _T0


def _stage(job: dict, phase: str, **measured) -> None:
    """Notes that ``job`` has reached ``phase`` with ``measured`` so far (for ``catch`` and ``progress``)."""
    job["_phase"] = phase
    job.setdefault("_partial", {}).update(measured)
    if job.get("progress"):
        with open(job["progress"], "w") as f:
            json.dump({"phase": phase, **job["_partial"]}, f)


def _animation(job: dict):
    """The first frame of the animation ``job["ini"]`` describes, or None (no .ini)."""
    if not job.get("ini"):
        return None
    from raytracer.sdl import Animation

    return Animation.from_ini(job["ini"])


def _animation_info(anim) -> dict | None:
    if anim is None:
        return None
    return {
        "frame": anim.frame,
        "initial_frame": anim.initial_frame,
        "final_frame": anim.final_frame,
        "clock": anim.clock,
        "cyclic": anim.cyclic,
    }


def _rss_mb(who=resource.RUSAGE_SELF) -> float:
    """High-water mark of resident memory, MB. For this process, Linux's ``VmHWM`` (of this
    program's memory since it started): ``ru_maxrss`` survives ``exec``, so a worker started by a
    parent that had grown reported the parent's mark (979 MB for a 160×120 render, started after
    the scaling benchmark had read 3840×2160 images). For the children (POV-Ray), ``ru_maxrss``."""
    if who == resource.RUSAGE_SELF:
        try:
            with open("/proc/self/status") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1]) / 1024.0  # kB
        except OSError:
            pass
    return resource.getrusage(who).ru_maxrss / 1024.0  # Linux: kilobytes


def _save(path, image) -> None:
    if path:
        import numpy as np

        np.save(path, np.asarray(image))


# unmeasured warm runs before the measured ones (ours and Mitsuba; each POV-Ray run is a process of
# its own): up to this many, within this many seconds. A process's first warm renders are slower
# until the OS has spread XLA's two worker threads over the two cores: seed.pov 128×96 adaptive took
# 3.1–3.5 ms a render for its first 5–20 renders, 2.0–2.3 ms after (2.0–2.4 ms from the first with the
# threads pinned to a core each), so a median of three such renders measured the placement
WARM_UP_RUNS = 20
WARM_UP_S = 1.0


def _warm_up(fn) -> None:
    t0 = time.perf_counter()
    for _ in range(WARM_UP_RUNS):
        fn()
        if time.perf_counter() - t0 > WARM_UP_S:
            return


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

    if job.get("quiet"):
        import logging

        logging.getLogger("raytracer").setLevel(logging.ERROR)
    if job.get("x64"):
        jax.config.update("jax_enable_x64", True)  # before the scene (and its arrays) exist
    from raytracer import load_scene
    from raytracer.render import compile_render

    _stage(job, "parse")
    anim = _animation(job)
    t0 = time.perf_counter()
    scene = load_scene(
        job["scene"],
        width=job["width"],
        height=job["height"],
        include_paths=job.get("include_paths", ()),
        animation=anim,
        fit_zero_terms=False,  # an image, as the command line renders it
    )
    parse_s = time.perf_counter() - t0
    features: dict[str, int] = {}
    examples: dict[str, str] = {}
    for w in scene.warnings:
        features[w.feature] = features.get(w.feature, 0) + 1
        examples.setdefault(w.feature, w.message)
    _stage(
        job,
        "compile",
        parse_s=parse_s,
        animation=_animation_info(anim),
        warnings=len(scene.warnings),
        warning_features=features,
        warning_examples=examples,
        warning_texts=[str(w) for w in scene.warnings[:WARNING_TEXTS]],
    )
    base_mb = _rss_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    if job.get("adaptive"):
        # two passes (centres, then the refined pixels): ``render`` compiles both on the first call,
        # which "compile" then includes (one render of it too)
        from raytracer.render import render

        adaptive = tuple(job["adaptive"])

        def run(s):
            return render(s, width=job["width"], height=job["height"], adaptive=adaptive)

        jax.block_until_ready(run(scene))
    else:
        run = compile_render(scene, width=job["width"], height=job["height"], spp=job.get("spp", 1))
    compile_s = time.perf_counter() - t0
    compile_cpu_s = time.process_time() - c0
    _stage(job, "render", compile_s=compile_s, compile_cpu_s=compile_cpu_s)
    first = []

    def once():
        image = jax.block_until_ready(run(scene))
        if not first:
            first.append(_process_age_s())
        return image

    # the first render apart: it may compile again (a ray tree wider than the first room), and with
    # two repeats the median was the mean of it and a warm run (incdemo/glasses/glass: 3.05 s
    # "warm" for renders of ~1 s)
    t0 = time.perf_counter()
    once()
    first_render_s = time.perf_counter() - t0
    _warm_up(once)
    walls, cpus, image = _timed_runs(once, job.get("repeats", 3), job.get("max_total_s", 120.0))
    _save(job.get("image"), image)
    import numpy as np

    recount = {}
    if job.get("recount_scene"):
        # the same scene at another object count, in this process after the first: what a
        # sequence of scenes (an animation, an optimisation that adds objects) pays for each
        other = load_scene(job["recount_scene"], width=job["width"], height=job["height"],
                           fit_zero_terms=False)
        t0 = time.perf_counter()
        compile_render(other, width=job["width"], height=job["height"], spp=job.get("spp", 1))
        recount = {"recompile_s": time.perf_counter() - t0}

    return {
        **job["_partial"],
        "parse_s": parse_s,
        "compile_s": compile_s,
        "compile_cpu_s": compile_cpu_s,
        "times_s": walls,
        "cpu_s": cpus,
        "time_s": statistics.median(walls),
        "first_image_s": first[0],
        "first_render_s": first_render_s,
        "peak_mb": _rss_mb(),
        "base_mb": base_mb,
        "nonfinite": int(np.sum(~np.isfinite(np.asarray(image)))),
        "dtype": str(image.dtype),
        "devices": len(jax.devices()),
        **_acceleration(),
        **recount,
    }


def _acceleration() -> dict:
    """Whether renders used the native hierarchy (``accel``: native or none) and, if not, why (asked
    after the measured work, so that it adds nothing to it)."""
    from raytracer.shading import _accel

    mode = _accel.mode()
    return {"accel": mode, "accel_reason": _accel.unavailable_reason() if mode == "none" else None}


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
CLOCK_STEP_S = 1e-3  # POV-Ray prints its Trace Time in whole milliseconds


def quantized_median(readings, step: float = CLOCK_STEP_S) -> float:
    """The median duration behind ``readings`` taken on a clock that ticks every ``step`` seconds:
    the median of grouped data, each reading k·step standing for the durations of
    [(k − ½)·step, (k + ½)·step), interpolated within the class that holds the middle. A reading is
    the difference of two clock readings, so a duration d reads ⌊d/step⌋ or ⌈d/step⌉ steps as the
    render starts early or late in a tick, and the mean of the readings is d; their plain median
    is a whole number of steps, off by up to half a step (POV-Ray's renders of a few milliseconds:
    readings of 2 and 3 ms in the proportion 7 : 4 have the median 2 ms, their mean is 2.36 and
    this 2.29 ms; for a constant duration it is within 0.09 of a step). Readings off the grid (a
    finer clock) give their plain median."""
    values = [float(r) for r in readings]
    ticks = [round(v / step) for v in values]
    if not values or any(abs(v - t * step) > 1e-9 for v, t in zip(values, ticks, strict=True)):
        return statistics.median(values)
    half, below = len(ticks) / 2, 0
    for tick in sorted(set(ticks)):
        count = ticks.count(tick)
        if below + count >= half:
            return max(0.0, (tick - 0.5 + (half - below) / count) * step)
        below += count
    raise AssertionError("unreachable: the classes hold every reading")


def run_povray(job: dict) -> dict:
    from validation.povray import run_povray as run

    aa = job.get("aa")
    results = []
    _stage(job, "povray")

    def once():
        t0 = time.perf_counter()
        r = run(
            job["scene"],
            job["width"],
            job["height"],
            antialias=tuple(aa) if aa else None,
            threads=job.get("threads", 2),
            timeout=job.get("timeout", 900.0),
            include_paths=job.get("include_paths", ()),
            extra_args=job.get("extra_args", ()),
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
        "time_s": quantized_median(traces),  # POV-Ray's clock ticks in milliseconds
        "trace_median_s": statistics.median(traces),
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
    _warm_up(once)
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


def _error(e: BaseException, phase: str | None) -> dict:
    """What the caller needs of a failure: its type and message, where it happened and, for a failure
    that is not a scene error, the last lines of its traceback."""
    import traceback

    from raytracer.errors import SceneError

    out = {
        "type": type(e).__name__,
        "message": str(e),
        "phase": phase,
        "scene_error": isinstance(e, SceneError),
    }
    stderr = getattr(e, "stderr", None)  # validation.povray.PovrayError: POV-Ray's own messages
    if stderr:
        out["log_tail"] = "\n".join(stderr.strip().splitlines()[-40:])
    if not out["scene_error"] and stderr is None:
        out["traceback"] = "".join(traceback.format_exception(e)[-12:])[-4000:]
    return out


def main() -> int:
    job = json.loads(sys.stdin.read())
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    kind = job["kind"]
    if kind in ("ours", "ours_grad"):
        # one JAX device per core unless the job says otherwise, as the raytracer command does
        # (POV-Ray renders with +WT2 on these 2-core machines)
        from raytracer.cli import _split_cpu

        _split_cpu(job.get("cpu_devices"))
    jobs = {"ours": run_ours, "ours_grad": run_ours_grad, "povray": run_povray, "mitsuba": run_mitsuba}
    if not job.get("catch"):
        result = jobs[kind](job)
    else:
        import faulthandler

        faulthandler.enable()  # a fatal signal (a native crash) prints the Python stack on stderr
        try:
            result = jobs[kind](job)
        except Exception as e:  # noqa: BLE001 - reported to the caller, who classifies it
            result = {**job.get("_partial", {}), "error": _error(e, job.get("_phase"))}
    if kind in ("ours", "ours_grad"):
        import jax

        result["devices"] = jax.device_count()
    sys.stdout.write("\n" + json.dumps(result) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
