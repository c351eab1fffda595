"""XLA's CPU flags that this renderer's programs were measured with, set before the CPU backend starts.

XLA reads ``XLA_FLAGS`` once, when JAX creates its first backend (the first computation, not the
import of ``jax``), and aborts on a flag it does not know. So ``tune_xla_flags`` adds its flags
only for a jaxlib they were verified with, only while no backend exists, and never a flag that
``XLA_FLAGS`` already names (the user's setting wins). ``import raytracer`` calls it;
``RAYTRACER_TUNE_XLA=0`` leaves ``XLA_FLAGS`` alone.

Measured on the 2-core machine (jaxlib 0.10.2, 640×480, two devices, medians of 7 warm renders in
one run each; ``docs/performance.md``, "XLA's CPU flags"):

* ``--xla_cpu_experimental_ynn_fusion_type=`` (no YNNPACK library fusions). XLA 0.10 hands small
  reductions and elementwise chains to YNNPACK, whose per-call cost dominates on a tile's arrays of
  a few thousand rays: the checker pattern's three-term floor sum took 0.3 ms per 2,022 rays. Off:
  the seed scene 0.16 → 0.05 s, 1,000 spheres 0.19 → 0.145 s, ``whitted.pov`` 1.56 → 1.24 s,
  ``glass.pov`` 3.3 → 2.6–3.0 s; compile within noise. Other JAX projects turn these fusions off for
  wrong results on CPU too.
* ``--xla_cpu_use_fusion_emitters=false``: cold compiles 25–40 % shorter at the same warm time
  (seed.pov 3.1–4.0 → 2.4–2.6 s, whitted.pov 7.5–9.2 → 5.5 s when the flag was chosen).
* ``--xla_disable_hlo_passes=while-loop-invariant-code-motion``: a render's shading
  body sits in nested ``while`` loops (tiles, levels, chunks), and this pass spent 0.6 s of
  ``advanced/pawns``' 5 s XLA compile on them. Without it (two alternating rounds, 160×120 and
  640×480–1024×768): pawns compiles in 6.2 / 6.0 s instead of 6.9 / 6.8, lamppost 6.2 / 6.7
  instead of 6.6 / 6.8, the other nine scenes within ±0.2 s, and the warm renders are the same
  within noise (pawns 0.28 / 0.30 against 0.28 / 0.27 s, whitted 0.25 / 0.24 against 0.25 /
  0.24 s); reverse-mode compiles of the example scenes moved by at most 0.2 s.
"""

from __future__ import annotations

import os
import warnings

# flag name → value, for the jaxlib (major, minor) versions in TUNED_JAXLIB
TUNED_FLAGS = {
    "xla_cpu_experimental_ynn_fusion_type": "",
    "xla_cpu_use_fusion_emitters": "false",
    "xla_disable_hlo_passes": "while-loop-invariant-code-motion",
}
TUNED_JAXLIB = ((0, 10),)
OPT_OUT_ENV = "RAYTRACER_TUNE_XLA"


def _jaxlib_version() -> tuple[int, int] | None:
    from importlib.metadata import PackageNotFoundError, version

    try:
        major, minor = (int(x) for x in version("jaxlib").split(".")[:2])
    except (PackageNotFoundError, ValueError):
        return None
    return major, minor


def _backends_started() -> bool:
    import sys

    bridge = sys.modules.get("jax._src.xla_bridge")
    if bridge is None:
        return False
    started = getattr(bridge, "backends_are_initialized", None)
    return bool(started()) if started is not None else True  # unknown JAX: assume too late


def tuned_flags(flags: str) -> str:
    """``flags`` with every flag of ``TUNED_FLAGS`` it does not name appended (for a verified
    jaxlib; otherwise ``flags`` unchanged)."""
    if _jaxlib_version() not in TUNED_JAXLIB:
        return flags
    extra = [f"--{name}={value}" for name, value in TUNED_FLAGS.items() if name not in flags]
    return " ".join([flags.strip(), *extra]).strip()


def tune_xla_flags() -> None:
    """Adds the tuned flags to ``$XLA_FLAGS``, and one CPU device per core (``split_cpu``), if JAX
    has no backend yet and the user did not opt out (``RAYTRACER_TUNE_XLA=0``); once a backend
    exists, setting them would change nothing."""
    if os.environ.get(OPT_OUT_ENV, "1").strip().lower() in ("0", "false", "no", "off"):
        return
    if _backends_started():
        return
    flags = os.environ.get("XLA_FLAGS", "")
    tuned = tuned_flags(flags)
    if tuned != flags:
        os.environ["XLA_FLAGS"] = tuned
    split_cpu()


DEVICES_ENV = "RAYTRACER_CPU_DEVICES"
_COUNT_FLAG = "xla_force_host_platform_device_count"


def default_cpu_devices() -> int:
    """``$RAYTRACER_CPU_DEVICES`` if it is a positive count, else the cores this process may use."""
    try:
        chosen = int(os.environ.get(DEVICES_ENV, ""))
        if chosen >= 1:
            return chosen
    except ValueError:
        pass
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def split_cpu(devices: int | None = None) -> None:
    """Splits the CPU into ``devices`` JAX devices (default ``default_cpu_devices()``) before JAX's
    backend starts, so that renders shard their tiles over every core, from the Python API as from
    the command line (the Whitted scene at 1024×768 from ``rt.render``, median of 5 warm renders:
    1.61 s on one device, 0.72 s on two; 2 cores, one run).
    ``XLA_FLAGS`` naming a device count wins over the default; a count given here replaces it."""
    if _backends_started():
        return
    flags = os.environ.get("XLA_FLAGS", "")
    if devices is None:
        if _COUNT_FLAG in flags:
            return
        devices = default_cpu_devices()
    kept = [f for f in flags.split() if not f.lstrip("-").startswith(_COUNT_FLAG)]
    os.environ["XLA_FLAGS"] = " ".join([*kept, f"--{_COUNT_FLAG}={devices}"])


_WARNED: list[bool] = []


def warn_if_untuned() -> None:
    """Warns once per process when a verified jaxlib runs without the tuned flags: JAX's backend
    started before ``import raytracer`` (renders are then up to 3× slower), unless the user opted
    out or set the flags' values themselves."""
    if _WARNED or os.environ.get(OPT_OUT_ENV, "1").strip().lower() in ("0", "false", "no", "off"):
        return
    if _jaxlib_version() not in TUNED_JAXLIB:
        return
    flags = os.environ.get("XLA_FLAGS", "")
    missing = [f"--{name}={value}" for name, value in TUNED_FLAGS.items() if name not in flags]
    if missing:
        _WARNED.append(True)
        warnings.warn(
            "JAX started before `import raytracer`, without the XLA flags this renderer is tuned for "
            f"(renders up to 3x slower): import raytracer first, or set XLA_FLAGS=\"{' '.join(missing)}\" "
            f"before JAX starts ({OPT_OUT_ENV}=0 silences this)", RuntimeWarning, stacklevel=3)
