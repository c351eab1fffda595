"""``trace()`` and ``inside()`` at parse time, answered by the renderer (``raytracer.query``).

Scenes use them to place things on surfaces (meshcam_macros.inc builds its camera mesh with
57,600 calls of trace). An object identifier is lowered once to the scene model, and one
jit-compiled function per object answers every later call (~30 µs each once compiled).

Speed: a call costs ~13 µs with ``jax.config.update("jax_cpu_enable_async_dispatch", False)`` set
before JAX first runs anything (the CLI does), ~40 µs with JAX's default asynchronous dispatch.
"""

from __future__ import annotations

import math

import numpy as np

from ..query import compile_inside, compile_trace
from ._lower import Lowerer


class Tracer:
    """Compiled trace/inside functions per object record (the record is kept alive by the cache)."""

    def __init__(self):
        self._compiled: dict[tuple[str, int], tuple[object, object]] = {}

    def _function(self, kind: str, rec, make):
        """The compiled ``kind`` function of ``rec`` (None when nothing of it can be hit)."""
        entry = self._compiled.get((kind, id(rec)))
        if entry is None or entry[0] is not rec:
            obj = Lowerer().obj(rec, None, True)
            entry = self._compiled[(kind, id(rec))] = (rec, None if obj is None else make(obj))
        return entry[1]

    def trace(self, rec, origin, direction) -> tuple[tuple, tuple]:
        """(point, normal) of the nearest hit, both (0, 0, 0) when the ray misses."""
        fn = self._function("trace", rec, compile_trace)
        dx, dy, dz = direction
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        if fn is None or not math.isfinite(length) or length == 0.0:
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        ray = np.array((*origin, dx / length, dy / length, dz / length), dtype=np.float64)
        out = np.asarray(fn(ray)).tolist()
        if out[0] == 0.0:
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        return tuple(out[1:4]), tuple(out[4:7])

    def inside(self, rec, point) -> bool:
        fn = self._function("inside", rec, compile_inside)
        return fn is not None and bool(fn(np.asarray(point, np.float64)))
