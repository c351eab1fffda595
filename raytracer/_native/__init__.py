"""The native library (``_bvh*.so``, built from this folder's C++ at install by ``setup.py``): the
hierarchy's queries (``bvh.cc``), POV-Ray's anti-aliasing rule (``antialias.cc``), compaction
(``compact.cc``) and the run-time warnings of compiled programs (``notice.cc``), each an XLA FFI
target ``raytracer_<name>``.

``library()`` loads it once and registers every target, or says why it cannot (the package installs
and renders without it: see ``shading/_accel.py``)."""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path

TARGETS = tuple(name + suffix for name in ("BvhBuild", "BvhClosest", "BvhAny", "BvhAll", "AaFlags")
                for suffix in ("F32", "F64")) + ("Compact", "StableOrder", "Notice")


@functools.cache
def library() -> tuple[ctypes.CDLL | None, str | None]:
    """(the loaded library, None) with its FFI targets registered, or (None, the reason it failed)."""
    import jax

    folder = Path(__file__).resolve().parent
    found = sorted(folder.glob("_bvh*.so"))
    if not found:
        return None, (f"the native BVH library is not built (no _bvh*.so in {folder}; reinstall with a "
                      "C++ compiler)")
    try:
        lib = ctypes.cdll.LoadLibrary(str(found[0]))
    except OSError as e:
        return None, f"the native BVH library does not load: {e}"
    missing = [name for name in TARGETS + ("SetNoticeSink",) if not hasattr(lib, name)]
    if missing:  # a library built from older sources (an editable install not rebuilt)
        return None, (f"the native library {found[0].name} lacks {', '.join(missing)}: it was built from "
                      "older sources (reinstall: pip install -e .)")
    for name in TARGETS:
        capsule = jax.ffi.pycapsule(getattr(lib, name))
        jax.ffi.register_ffi_target(f"raytracer_{name}", capsule, platform="cpu")
    return lib, None
