"""Shared pieces of the benchmarks: scene files and their variants, running one measurement in a
fresh worker process, and markdown tables."""

from __future__ import annotations

import json
import os
import platform
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENES = {
    "seed": ROOT / "examples" / "scenes" / "seed.pov",
    "whitted": ROOT / "benchmarks" / "scenes" / "whitted.pov",
    "whitted_lights": ROOT / "benchmarks" / "scenes" / "whitted_lights.pov",
    "lambert": ROOT / "benchmarks" / "scenes" / "lambert.pov",
    "area": ROOT / "benchmarks" / "scenes" / "area.pov",
}


class JobFailed(RuntimeError):
    pass


class MemoryExceeded(JobFailed):
    """A worker (with what it started) held more resident memory than the job allowed; it was killed."""


def scene_variant(
    src: Path, folder: Path, *, max_trace_level: int | None = None, area_samples: int | None = None
) -> Path:
    """A copy of scene ``src`` in ``folder`` with ``max_trace_level`` and/or the area-light sample counts
    (``area_light <a>, <b>, n, n``) rewritten; both renderers read the same file."""
    text = src.read_text()
    tag = []
    if max_trace_level is not None:
        text, n = re.subn(r"max_trace_level\s+\d+", f"max_trace_level {int(max_trace_level)}", text)
        if n != 1:
            raise ValueError(f"{src}: expected one max_trace_level in global_settings")
        tag.append(f"L{max_trace_level}")
    if area_samples is not None:
        text, n = re.subn(
            r"(area_light\s*<[^>]*>\s*,\s*<[^>]*>\s*,)\s*\d+\s*,\s*\d+",
            rf"\g<1> {int(area_samples)}, {int(area_samples)}",
            text,
        )
        if n != 1:
            raise ValueError(f"{src}: expected one area_light")
        tag.append(f"A{area_samples}")
    if not tag:
        return src
    out = folder / f"{src.stem}_{'_'.join(tag)}.pov"
    out.write_text(text)
    return out


def run_job(job: dict, *, timeout: float = 1800.0, max_rss_mb: float | None = None) -> dict:
    """Runs one measurement (see :mod:`benchmarks._worker`) in a fresh Python process.

    Raises :class:`JobFailed` if the worker fails, :class:`subprocess.TimeoutExpired` after
    ``timeout`` seconds, and :class:`MemoryExceeded` once the worker's process group holds more than
    ``max_rss_mb`` of resident memory (polled every :data:`POLL_S` seconds on Linux; the machine is
    shared and has no swap). The worker runs in its own process group, killed whole on any of
    these (or an interrupt), so that a ``povray`` it started does not outlive it.
    """
    env = dict(os.environ)
    env.setdefault("JAX_PLATFORMS", "cpu")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    job = {k: (str(v) if isinstance(v, Path) else v) for k, v in job.items()}
    with tempfile.TemporaryDirectory(prefix="bench-home-") as home:
        if job["kind"] == "mitsuba":
            env["HOME"] = home  # Dr.Jit caches compiled kernels under ~/.drjit: start cold
        # ours starts cold too: a program an earlier run left in the persistent cache would be
        # loaded, not compiled, and the compile columns would measure a cache load; a
        # RAYTRACER_CACHE_DIR of the caller's is kept
        env.setdefault("RAYTRACER_CACHE_DIR", str(Path(home) / "xla"))
        proc = subprocess.Popen(
            [sys.executable, "-m", "benchmarks._worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=ROOT,
            start_new_session=True,
        )
        try:
            stdout, stderr = _communicate(proc, json.dumps(job), timeout, max_rss_mb)
        except BaseException:
            _kill_group(proc)
            raise
    lines = stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        raise JobFailed(f"{job['kind']} job failed ({proc.returncode}): {job}\n{stderr[-3000:]}")
    return json.loads(lines[-1])


POLL_S = 0.5


def _communicate(proc: subprocess.Popen, text: str, timeout: float, max_rss_mb: float | None):
    """``proc.communicate(text)`` within ``timeout`` seconds, checking the group's memory meanwhile."""
    if max_rss_mb is None:
        return proc.communicate(text, timeout=timeout)
    deadline = time.monotonic() + timeout
    pending = text
    while True:
        try:  # a retried communicate() loses no output; the input is sent by the first call only
            return proc.communicate(pending, timeout=max(0.0, min(POLL_S, deadline - time.monotonic())))
        except subprocess.TimeoutExpired:
            pending = None
        if time.monotonic() >= deadline:
            raise subprocess.TimeoutExpired(proc.args, timeout)
        rss = _group_rss_mb(proc.pid)
        if rss > max_rss_mb:
            raise MemoryExceeded(f"used {rss:.0f} MB of resident memory, over the limit of {max_rss_mb:g} MB")


def _group_rss_mb(pgid: int) -> float:
    """Resident memory of the processes in group ``pgid``, from /proc (0 where there is no /proc)."""
    total = 0
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()  # from field 3 (state) on
        except (OSError, IndexError):
            continue  # the process has gone
        if int(fields[2]) == pgid:  # field 5: pgrp
            total += int(fields[21])  # field 24: rss, in pages
    return total * os.sysconf("SC_PAGE_SIZE") / 2**20


def _kill_group(proc: subprocess.Popen) -> None:
    """Kills a worker started with ``start_new_session`` and everything it started, and reaps it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.communicate()


def machine() -> dict:
    """What the numbers were measured on."""
    try:
        model = next(
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        )
    except (OSError, StopIteration):
        model = platform.processor()
    try:
        load = os.getloadavg()
    except OSError:
        load = None
    versions = {}
    for mod in ("jax", "mitsuba", "numpy"):
        try:
            versions[mod] = __import__(mod).__version__
        except Exception:  # noqa: BLE001 - optional
            versions[mod] = None
    try:
        pov = subprocess.run(["povray", "--version"], capture_output=True, text=True, timeout=30)
        versions["povray"] = next(x.strip() for x in (pov.stdout + pov.stderr).splitlines() if "POV-Ray" in x)
    except (OSError, StopIteration, subprocess.SubprocessError):
        versions["povray"] = None
    try:
        git = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT, timeout=30
        )
        commit = git.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {
        "commit": commit,
        "cpu": model,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "load_average_at_start": load,
        "versions": versions,
    }


def fmt(x, digits: int = 3) -> str:
    if x is None:
        return "–"
    if isinstance(x, str):
        return x
    if x == 0:
        return "0"
    if abs(x) >= 100:
        return f"{x:.0f}"
    return f"{x:.{digits}g}"


def md_table(headers: list[str], rows: list[list]) -> str:
    out = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    out += ["| " + " | ".join(fmt(c) for c in row) + " |" for row in rows]
    return "\n".join(out)
