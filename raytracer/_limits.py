"""The memory a render needs, estimated from its image before anything is allocated, against the
bound: ``$RAYTRACER_MAX_MEMORY_MB`` if set, else what the machine has available (``MemAvailable``,
and the room left under ``ulimit -v``).

The estimate is a base (the JAX runtime, the compiled program, one tile's working set: tiles bound
the ray tree whatever the image) plus copies of the image. Measured with ``/usr/bin/time -v
raytracer render examples/scenes/seed.pov -W n -H n`` (2-core Xeon, n = 500 … 5,000): peak resident
memory grows by 72 bytes a pixel in float32 writing EXR, 86 writing PNG, 133 in float64, about six
copies of the image's three channels, whatever the samples per pixel; 7 copies are counted.
"""

from __future__ import annotations

import os
import resource

from .errors import LimitError

IMAGE_COPIES = 7
BASE_MB = 512


def render_memory(width: int, height: int, itemsize: int) -> int:
    """Bytes a render of a ``width`` × ``height`` image in floats of ``itemsize`` bytes needs, at most."""
    return BASE_MB * (1 << 20) + IMAGE_COPIES * 3 * itemsize * width * height


def _status_kb(key: str, path: str) -> int | None:
    try:
        with open(path) as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return None


def memory_bound() -> tuple[int | None, str]:
    """``(bytes, where the bound comes from)``; None where nothing is known (not Linux)."""
    given = os.environ.get("RAYTRACER_MAX_MEMORY_MB")
    if given:
        try:
            return int(float(given) * (1 << 20)), "$RAYTRACER_MAX_MEMORY_MB"
        except ValueError:
            raise LimitError(f"$RAYTRACER_MAX_MEMORY_MB: expected a number of MB, found {given!r}") from None
    bounds = []
    available = _status_kb("MemAvailable", "/proc/meminfo")
    if available is not None:
        bounds.append((available * 1024, "the memory this machine has available"))
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    size = _status_kb("VmSize", "/proc/self/status")
    if soft != resource.RLIM_INFINITY and size is not None:
        bounds.append((max(soft - size * 1024, 0), "the room left under ulimit -v"))
    if not bounds:
        return None, ""
    return min(bounds)


def check_render_memory(width: int, height: int, itemsize: int) -> None:
    """Raises :class:`LimitError` when the render's estimate exceeds the bound."""
    bound, source = memory_bound()
    need = render_memory(width, height, itemsize)
    if bound is not None and need > bound:
        gb = 1 << 30
        raise LimitError(
            f"a {width}×{height} render needs about {need / gb:.1f} GB ({IMAGE_COPIES} copies of the "
            f"image in float{8 * itemsize} while it is rendered and written), more than "
            f"{bound / gb:.1f} GB ({source}): render a smaller image (-W/-H), or set "
            "RAYTRACER_MAX_MEMORY_MB if the estimate is wrong for this scene")
