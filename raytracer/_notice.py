"""Warnings that a compiled program raises when it runs: counts known only then (rays that did not
fit the ray tree's room, crossings the boundary term had no room for).

``notice(code, counts, info)`` inside a traced function warns, each time the compiled program runs,
when any of ``counts`` (integer scalars, traced) is positive; ``info`` holds static integers the
message needs. The warning is the function registered for ``code`` (``on``), called with the counts
then the static values.

With the native library (``raytracer/_native/notice.cc``) this is a custom call that returns at once
while every count is zero, and a program holding it is kept by JAX's persistent compilation cache
and serialised by ``_programs`` like any other: a JAX host callback (``jax.debug.callback``) would
make every such program compile again in every process (a sphere fit's first call with the
boundary term: 19.6 s in every process, 5.1 s once the cache holds it; ``benchmarks.inverse
--new-processes``). Without the library (or off the CPU) the warning falls back to
``jax.debug.callback``, called only when a count is positive.

What the call returns is unused, so the primitive is an effect: it carries
``jax.debug.callback``'s unordered effect, which JAX keeps under ``jit``, ``vmap`` (the counts
summed over the batch), ``grad``, ``cond``/``while``/``scan``, ``checkpoint`` and custom
derivatives. XLA's partitioner wants a sharding on every side-effecting instruction and keeps
one only on its own custom calls, so in a program over several devices the call runs in a fully
manual region on each, the counts on the first and zeros on the others: one warning a run, the
whole program's count (inside the caller's own ``shard_map``, each device reports its own).
"""

from __future__ import annotations

import ctypes
import dataclasses
import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax._src import core, sharding_impls
from jax._src import debugging as _debugging
from jax._src.interpreters import ad, batching, mlir

from . import _native

DROPPED_RAYS = 0  # counts (rays dropped,), info (the room in slots per camera ray,)
EDGES_LEFT_OUT = 1  # counts (crossings without room, rays dropped from the jumps' trees), info (room,)

_WARNINGS: dict[int, Callable[..., None]] = {}


def on(code: int):
    """Registers the function that warns for ``code``: called with the counts, then ``info``."""
    def register(fn):
        _WARNINGS[code] = fn
        return fn
    return register


def notice(code: int, counts, info: tuple[int, ...] = ()) -> None:
    """Warns through ``on(code)``'s function when the program runs and a count is positive."""
    counts = jnp.stack([jnp.asarray(c, jnp.int32).reshape(()) for c in counts])
    info = tuple(int(i) for i in info)
    if _native_sink() and jax.default_backend() == "cpu":
        notice_p.bind(counts, code=code, info=info)
        return
    jax.lax.cond(jnp.any(counts > 0),
                 lambda c: jax.debug.callback(lambda v: _warn(code, tuple(int(x) for x in v) + info), c),
                 lambda c: None, counts)


def _warn(code: int, values: tuple[int, ...]) -> None:
    _WARNINGS[code](*values)


# ---------------------------------------------------------------- the native sink
_FAILED = [ctypes.create_string_buffer(1)]  # the last failure's message (read by notice.cc)
_SINK_TYPE = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64, ctypes.POINTER(ctypes.c_int64))


def _sink(code, n, values):
    try:
        _warn(int(code), tuple(int(values[i]) for i in range(n)))
        return None
    except BaseException as e:  # a warning filter made it an error: the program fails with it
        _FAILED[0] = ctypes.create_string_buffer(f"{type(e).__name__}: {e}".encode(errors="replace"))
        return ctypes.addressof(_FAILED[0])


_SINK = _SINK_TYPE(_sink)  # kept alive for the library's pointer


@functools.cache
def _native_sink() -> bool:
    """Whether the native library is loaded and its sink is this module's."""
    lib, _ = _native.library()
    if lib is None:
        return False
    lib.SetNoticeSink.argtypes = [_SINK_TYPE]
    lib.SetNoticeSink.restype = None
    lib.SetNoticeSink(_SINK)
    return True


# ---------------------------------------------------------------- the primitive
notice_p = core.Primitive("raytracer_notice")
notice_p.multiple_results = True


@notice_p.def_impl
def _notice_impl(counts, *, code, info):
    values = tuple(int(x) for x in np.asarray(counts))
    if any(v > 0 for v in values):
        _warn(code, values + info)
    return []


@notice_p.def_effectful_abstract_eval
def _notice_abstract_eval(counts, *, code, info):
    return [], {_debugging.debug_effect}


def _notice_batch(args, dims, *, code, info):
    (counts,), (dim,) = args, dims
    return notice_p.bind(jnp.sum(counts, axis=dim, dtype=jnp.int32), code=code, info=info), []


batching.primitive_batchers[notice_p] = _notice_batch


def _notice_jvp(primals, tangents, **params):  # integer counts: no tangent
    return notice_p.bind(*primals, **params), []


ad.primitive_jvps[notice_p] = _notice_jvp


def _notice_lowering(ctx, counts, *, code, info):
    axis_context = ctx.module_context.axis_context
    if isinstance(axis_context, sharding_impls.ShardingContext) and axis_context.num_devices > 1:
        # XLA's partitioner wants a sharding on every side-effecting instruction and keeps one only
        # on its own custom calls (host callbacks among them): the call runs in a manual region
        # on every device of the program, with the counts on the first and zeros on the others
        mesh = jax.sharding.AbstractMesh((axis_context.num_devices,), ("notice",))

        def on_each_device(c):
            first = jax.lax.axis_index("notice") == 0
            notice_p.bind(jnp.where(first, c, 0), code=code, info=info)
            return []

        manual = jax.shard_map(on_each_device, mesh=mesh, in_specs=jax.sharding.PartitionSpec(),
                               out_specs=[], check_vma=False)
        return mlir.lower_fun(manual, multiple_results=True)(ctx, counts)
    if isinstance(axis_context, sharding_impls.SPMDAxisContext) and \
            set(axis_context.manual_axes) != set(axis_context.mesh.axis_names):
        raise NotImplementedError("raytracer's run-time warnings in a partly manual shard_map")
    # one unused scalar result: the FFI handler's signature (a call without results has nothing
    # a partitioner could annotate)
    ctx = dataclasses.replace(ctx, avals_out=[core.ShapedArray((), np.int32)])
    lower = jax.ffi.build_ffi_lowering_function("raytracer_Notice", has_side_effect=True)
    lower(ctx, counts, code=np.int64(code), info=np.asarray(info, np.int64))
    return []


mlir.register_lowering(notice_p, _notice_lowering, platform="cpu")
