"""Run the real POV-Ray 3.7 binary and read its output back as a linear float image.

POV-Ray is the reference for what a ``.pov`` file means (semantics §3.5): we render with
``-D -A +FE`` (one ray through each pixel centre, written as a half-float linear OpenEXR) or, for
comparisons with box-filtered films, ``+A0.0 +AM1 +R<n> -J`` (every pixel supersampled on a
deterministic n×n grid plus the centre). Debian's ``povray.conf`` restricts file I/O to the
temporary folder and ``.``, so each render runs with its working folder set to a fresh temporary
folder, writes its output there, and reads includes from the folders passed as ``+L``.

Nothing is cached: every call runs ``povray``.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["PovrayError", "PovrayRender", "PovrayUnavailable", "animation_args", "povray_executable",
           "read_exr", "render_povray", "run_povray"]


class PovrayUnavailable(RuntimeError):
    """The ``povray`` binary is not installed (tests skip on this)."""


class PovrayError(RuntimeError):
    """``povray`` ran but failed (parse error, timeout, no output); carries its stderr."""

    def __init__(self, message: str, stderr: str = ""):
        self.stderr = stderr
        tail = "\n".join(stderr.strip().splitlines()[-25:])
        super().__init__(f"{message}\n--- povray output (last lines) ---\n{tail}" if tail else message)


@dataclasses.dataclass(frozen=True)
class PovrayRender:
    """One POV-Ray render.

    Attributes:
        image:         (H, W, 3) float32 linear RGB, row 0 at the top.
        trace_seconds: POV-Ray's own "Trace Time" (wall clock of the render phase), or None.
        parse_seconds: POV-Ray's "Parse Time", or None.
        command:       the argument list that was run.
        log:           POV-Ray's console output (it writes everything to stderr).
    """

    image: np.ndarray
    trace_seconds: float | None
    parse_seconds: float | None
    command: tuple[str, ...]
    log: str


def povray_executable() -> str | None:
    """Path of the ``povray`` binary (``$POVRAY`` overrides the search), or None."""
    override = os.environ.get("POVRAY")
    if override:
        return override if Path(override).exists() else shutil.which(override)
    return shutil.which("povray")


def read_exr(path) -> np.ndarray:
    """Reads an RGB OpenEXR file as (H, W, 3) float32 (POV writes half floats)."""
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        channels = f.channels()
        if "RGB" in channels:
            pixels = channels["RGB"].pixels
        else:
            pixels = np.stack([channels[c].pixels for c in ("R", "G", "B")], axis=-1)
    return np.ascontiguousarray(pixels, dtype=np.float32)


_TIME = r"{}:\s+\d+ hours?\s+\d+ minutes?\s+\d+ seconds?\s+\(([0-9.]+) seconds\)"


def _parse_seconds(log: str, label: str) -> float | None:
    m = re.search(_TIME.format(label), log)
    return float(m.group(1)) if m else None


def animation_args(animation) -> list[str]:
    """Options that make POV-Ray render one frame of an animation: the frame range, clocks and
    cyclic flag of ``animation`` (a :class:`raytracer.sdl.Animation`), with the subset of frames
    (``+SF``/``+EF``) set to its ``frame`` alone, so that ``clock``, ``clock_delta``,
    ``frame_number`` and ``final_frame`` are those of that frame of the whole animation. POV-Ray
    then names the output file after the frame (``out01.exr``); :func:`run_povray` finds it.
    """
    a = animation
    return [f"+KFI{int(a.initial_frame)}", f"+KFF{int(a.final_frame)}", f"+KI{float(a.initial_clock):.17g}",
            f"+KF{float(a.final_clock):.17g}", "+KC" if a.cyclic else "-KC", f"+SF{int(a.frame)}",
            f"+EF{int(a.frame)}"]


def _is_scene_path(scene) -> bool:
    if isinstance(scene, os.PathLike):
        return True
    return isinstance(scene, str) and "\n" not in scene and "{" not in scene and len(scene) < 4096


def run_povray(scene, width: int, height: int, *, antialias: tuple[float, int] | None = None,
               include_paths=(), timeout: float = 300.0, threads: int | None = None,
               extra_args=()) -> PovrayRender:
    """Renders a POV-Ray scene with the real binary.

    Args:
        scene:         a path to a ``.pov`` file, or the scene text itself.
        width, height: image size in pixels (``+W``/``+H``; ``image_width``/``image_height``).
        antialias:     None for ``-A`` (one ray through each pixel centre), or ``(threshold, depth)``
                       for ``+A<threshold> +AM1 +R<depth> -J`` (method 1, deterministic grid; a
                       threshold of 0 supersamples every pixel with ``depth²+1`` rays).
        include_paths: extra folders searched by ``#include`` (``+L``). A scene file's own folder is
                       always searched.
        timeout:       seconds before the render is killed (raises :class:`PovrayError`).
        threads:       render threads (``+WT``); None uses POV-Ray's default (all cores).
        extra_args:    further command-line options, appended last.

    Returns:
        A :class:`PovrayRender` whose ``image`` is (height, width, 3) float32 linear RGB.

    Raises:
        PovrayUnavailable: ``povray`` is not installed.
        PovrayError: the render failed or timed out.
    """
    exe = povray_executable()
    if exe is None:
        raise PovrayUnavailable("POV-Ray is not installed (no `povray` on PATH; set $POVRAY to its path)")
    libs = [Path(p).resolve() for p in include_paths]
    with tempfile.TemporaryDirectory(prefix="povray-") as tmp:
        tmp_path = Path(tmp)
        scene_file = tmp_path / "scene.pov"
        if _is_scene_path(scene):
            src = Path(scene)
            if not src.is_file():
                raise FileNotFoundError(f"no POV-Ray scene at {src}")
            shutil.copyfile(src, scene_file)
            libs.insert(0, src.resolve().parent)
        else:
            scene_file.write_text(str(scene))
        aa = ["-A"] if antialias is None else [
            f"+A{float(antialias[0]):.4f}", "+AM1", f"+R{int(antialias[1])}", "-J"]
        cmd = [exe, "-D", *aa, f"+W{int(width)}", f"+H{int(height)}", "+FE",
               "+I" + scene_file.name, "+Oout.exr", *(f"+L{p}" for p in libs)]
        if threads is not None:
            cmd.append(f"+WT{int(threads)}")
        cmd.extend(str(a) for a in extra_args)
        try:
            proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=timeout,
                                  stdin=subprocess.DEVNULL, errors="replace")
        except subprocess.TimeoutExpired as e:
            log = e.stderr.decode(errors="replace") if isinstance(e.stderr, bytes) else (e.stderr or "")
            raise PovrayError(f"povray timed out after {timeout:g} s", log) from None
        log = proc.stdout + proc.stderr
        out = tmp_path / "out.exr"
        frames = sorted(tmp_path.glob("out*.exr"))
        if not out.is_file() and len(frames) == 1:  # one frame of an animation: out<frame>.exr
            out = frames[0]
        if proc.returncode != 0 or not out.is_file():
            raise PovrayError(f"povray failed (exit code {proc.returncode})", log)
        image = read_exr(out)
    if image.shape != (height, width, 3):
        raise PovrayError(f"povray wrote a {image.shape} image, expected {(height, width, 3)}", log)
    return PovrayRender(image=image, trace_seconds=_parse_seconds(log, "Trace Time"),
                        parse_seconds=_parse_seconds(log, "Parse Time"), command=tuple(cmd), log=log)


def render_povray(scene, width: int, height: int, *, antialias: tuple[float, int] | None = None,
                  include_paths=(), timeout: float = 300.0, threads: int | None = None) -> np.ndarray:
    """The image of :func:`run_povray`: (height, width, 3) float32 linear RGB, row 0 at the top."""
    return run_povray(scene, width, height, antialias=antialias, include_paths=include_paths,
                      timeout=timeout, threads=threads).image
