"""``trace()`` and ``inside()`` at parse time, with the renderer's own intersection code.

Scenes use them to place things on surfaces (meshcam_macros.inc builds its camera mesh with
57,600 calls of trace). An object identifier is lowered once to the scene model, and one
jit-compiled function per object answers every later call (~30 µs each once compiled), so the
answers are exactly what the renderer would hit: same kernels, transforms, CSG and clipping.

POV-Ray's definitions (manual, "Functions"): ``trace(OBJECT, A, B [, N])`` shoots a ray from
``A`` along ``B`` and returns the nearest intersection with OBJECT, or <0,0,0> when there is none;
``N`` receives the surface normal there (<0,0,0> when nothing was hit — the only reliable way to
tell). ``inside(OBJECT, P)`` is 1 when P is inside the object's solid and 0 otherwise; a clipped
object is inside where its shape and every clipping object are.

Speed: a call costs ~13 µs with ``jax.config.update("jax_cpu_enable_async_dispatch", False)`` set
before JAX first runs anything (the CLI does), ~40 µs with JAX's default asynchronous dispatch.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from .. import scene as S
from .._plan import make_plan
from ..shading._geometry import KINDS, _inside_fn, closest_hit, pack_geometry, static_prim_mask
from ._lower import Lowerer

# crossings closer to the ray's start than this (in units of the normalised direction) are
# ignored, as POV-Ray ignores depths below its own small tolerance
_T_MIN = 1e-6


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
        fn = self._function("trace", rec, _trace_function)
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
        fn = self._function("inside", rec, lambda obj: jax.jit(functools.partial(_inside, obj, None)))
        return fn is not None and bool(fn(np.asarray(point, np.float64)))


def _trace_function(obj):
    scene = S.Scene(camera=S.Camera(), objects=(obj,))
    plan = make_plan(scene)
    if not plan.prims:
        return None
    dtype = S.Sphere((0.0, 0.0, 0.0), 1.0).radius.dtype
    # packed once, outside the program: the inverse transforms (LAPACK calls) and stacking are
    # then constants, and each call runs only the intersection (~80 -> ~15 µs per call)
    geo = pack_geometry(plan, dtype)
    visible = jnp.asarray(static_prim_mask(geo, lambda i: plan.prims[i].rendered))
    sign = np.where(static_prim_mask(geo, lambda i: plan.prims[i].inverse), -1.0, 1.0)

    @jax.jit
    def fn(ray):  # one (6,) argument: origin and unit direction (one argument dispatches faster)
        o, d = ray[:3].astype(dtype), ray[3:].astype(dtype)
        hit = closest_hit(geo, plan, o, d, _T_MIN, visible, sign)
        # one array: a single device-to-host copy per call
        return jnp.concatenate([hit.found.astype(dtype)[None], o + hit.t * d, hit.normal])

    return fn


def _inside(obj, object_from_world, p):
    """Whether world point ``p`` is inside ``obj`` (traced into one jit program per object)."""
    if obj.transform is not None:  # concrete: inverted here, a constant of the program
        m = np.linalg.inv(np.asarray(obj.transform.matrix, np.float64))
        object_from_world = m if object_from_world is None else m @ object_from_world
    if isinstance(obj, S.CSG):
        kids = [_inside(c, object_from_world, p) for c in obj.children]
        if obj.operation == "intersection":
            v = functools.reduce(jnp.logical_and, kids)
        elif obj.operation == "difference":
            v = kids[0]
            for k in kids[1:]:
                v = v & ~k
        else:  # union, merge
            v = functools.reduce(jnp.logical_or, kids)
    else:
        kind = obj.shape.kind
        fn = _inside_fn(kind, KINDS[kind].static(obj.shape))
        if fn is None:  # triangles, polygons, meshes have no inside
            v = jnp.asarray(False)
        else:
            m = None if object_from_world is None else jnp.asarray(object_from_world, p.dtype)
            q = p if m is None else m[:3, :3] @ p + m[:3, 3]
            v = jnp.asarray(fn(*KINDS[kind].params(obj.shape), q))
    for clip in obj.clipped_by:
        v = v & _inside(clip, object_from_world, p)
    return v != obj.inverse
