"""Running a batched function over only the live items of a batch: the live items are moved to the
front (a stable partition, no sort) and cut into chunks. A render loops over the chunks up to the
last live one (``lax.while_loop``: the dead chunks behind it cost nothing); differentiated, the
loop is a ``lax.scan`` over every chunk that skips those without a live item with ``lax.cond``
(which runs only the taken branch and differentiates like any branch).

The scheduler shades its pools of rays this way, and the shading model traces an adaptive area
light's full grid only for the points in a penumbra.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero


def partition(alive):
    """A permutation putting live items first (stable), and its inverse, in O(n) (no sort)."""
    n = alive.shape[0]
    before = jnp.cumsum(alive.astype(jnp.int32))  # live items up to and including each
    index = jnp.arange(n, dtype=jnp.int32)
    # a dead item's place: after every live item, then the dead ones before it (index + 1 - before)
    pos = jnp.where(alive, before - 1, before[-1] + index - before)
    order = jnp.zeros(n, jnp.int32).at[pos].set(index)
    return order, pos


def _native() -> bool:
    """Whether the native compaction (``_native/compact.cc``) serves this process: the CPU backend
    with the library built."""
    from . import _accel

    return jax.default_backend() == "cpu" and _accel.unavailable_reason() is None


def nonzero(mask, size: int):
    """``(index, count)``: the flat positions (``size``,) int32 of the first ``size`` true entries of
    ``mask`` in order (then zeros), and how many there are (may exceed ``size``). On the CPU the
    plain loop (``_native/compact.cc``): XLA's ``jnp.nonzero`` is a cumulative sum and a scatter
    over the whole mask (17.5 ms for 1.7M entries on a 2-core Xeon, where the loop takes ~1 ms)."""
    flat = mask.reshape(-1)
    if _native():
        shapes = (jax.ShapeDtypeStruct((size,), jnp.int32), jax.ShapeDtypeStruct((), jnp.int32))
        return jax.ffi.ffi_call("raytracer_Compact", shapes, vmap_method="sequential")(flat)
    count = jnp.sum(flat, dtype=jnp.int32)
    return jnp.nonzero(flat, size=size, fill_value=0)[0].astype(jnp.int32), count


def stable_order(key, bound: int):
    """The permutation (n,) int32 that sorts ``key`` (n,) of integers in [0, ``bound``), ties in
    index order. On the CPU a counting sort (``_native/compact.cc``; XLA's stable argsort of 43k
    keys takes 5.4 ms); elsewhere ``jnp.argsort``."""
    key = jnp.clip(key.astype(jnp.int32), 0, bound - 1)
    if _native():
        return jax.ffi.ffi_call("raytracer_StableOrder", jax.ShapeDtypeStruct(key.shape, jnp.int32),
                                vmap_method="sequential")(key)
    return jnp.argsort(key, stable=True).astype(jnp.int32)


def divisor_near(n: int, target: int) -> int:
    """The divisor of ``n`` closest to ``target`` (at least 1)."""
    divisors = [k for k in range(1, n + 1) if n % k == 0]
    return min(divisors, key=lambda k: abs(k - max(1, target)))


def zeros_like_shapes(shapes, lead=()):
    """Zeros shaped as ``shapes`` (a tree of ``ShapeDtypeStruct``), with ``lead`` axes in front."""
    return jax.tree.map(lambda x: jnp.zeros(lead + x.shape, x.dtype), shapes)


def _blocked_map(fn: Callable[[Any], Any], items, live_chunk, n: int, chunk: int, blocks: bool):
    """``fn`` over the chunks of ``items`` (a tree of arrays with a leading axis ``n``) whose
    ``live_chunk`` (n/chunk,) bool is set, zeros for the others, stacked back to ``n`` items.
    With ``blocks``, chunks are grouped into about √(n/chunk) blocks that are skipped first."""
    n_chunks = n // chunk
    per_block = divisor_near(n_chunks, int(n_chunks ** 0.5)) if blocks else n_chunks
    lead = (n_chunks // per_block, per_block)
    blocked = jax.tree.map(lambda a: a.reshape(lead + (chunk,) + a.shape[1:]), items)
    # fn behind a jit boundary: the two nested conds would otherwise linearise it four times in
    # reverse mode (JAX linearises a cond's branches twice; a jaxpr's linearisation is cached).
    # Reverse mode runs each chunk (and block) again instead of storing what it computed
    # (``jax.checkpoint``): a loop step's residuals are otherwise every intermediate of the shading,
    # each written into a stacked buffer and read back one small copy at a time, and the scene's
    # arrays with them (a cond's residuals are its outputs, stacked per step). The demo scene of
    # examples/fit_material.py, 40×30: forward + backward 17.3 → 3.0× its forward (float32),
    # 21.3 → 3.4× (float64); at 320×240, 17 → 4.8×, its compile 32 → 18 s (docs/gradients.md).
    # The checkpoint inside the cond keeps the backward pass's own cond from carrying the
    # shading's residuals. Forward renders are unchanged (a checkpoint acts only under
    # differentiation).
    fn_jit = jax.jit(jax.checkpoint(fn))
    shapes = jax.eval_shape(fn_jit, jax.tree.map(lambda a: a[0, 0], blocked))

    @jax.checkpoint
    def one_chunk(x):
        it, live = x
        return jax.lax.cond(live, lambda: fn_jit(it), lambda: zeros_like_shapes(shapes))

    @jax.checkpoint
    def one_block(x):
        it, live = x
        return jax.lax.cond(jnp.any(live), lambda: jax.lax.map(one_chunk, (it, live)),
                            lambda: zeros_like_shapes(shapes, (per_block,)))

    out = jax.lax.map(one_block, (blocked, live_chunk.reshape(lead)))
    return jax.tree.map(lambda x: x.reshape((n,) + x.shape[3:]), out)


def map_in_place(fn: Callable[[Any], Any], items, alive, chunk: int):
    """:func:`map_live` without moving anything: chunks of ``items`` in their order, those without a
    live item skipped, one chunk per loop step (blocks would copy every block in and out once
    more). For a batch whose live items are already together (a compacted pool's are its first
    slots), where ``map_live``'s partition and its two gathers of every field would only copy
    them."""
    n = alive.shape[0]
    if n % chunk:
        raise ValueError(f"{n} items do not split into chunks of {chunk}")
    live_chunk = jnp.any(alive.reshape(n // chunk, chunk), axis=1)
    return _live_map(fn, items, live_chunk, n, chunk, blocks=False)


def _live_map(fn: Callable[[Any], Any], items, live_chunk, n: int, chunk: int, blocks: bool):
    """``_blocked_map``'s result. Not differentiated, a ``while_loop`` runs ``fn`` over the chunks
    up to the last live one and writes them into zeros: the dead chunks behind it (most of a
    compacted pool's deep levels) cost no loop step, where the scan sliced each one's items and
    wrote its zeros (the Whitted scene at 1024×768: 0.325 → 0.30 s). A ``while_loop`` has no
    reverse mode, so its derivative (``custom_jvp``) is that of ``_blocked_map``'s scan: forward
    and reverse mode run today's differentiated program, the same values."""
    body, consts, shapes = closure(fn, items, chunk)

    @jax.custom_jvp
    def run(items, live_chunk, consts):
        n_chunks = n // chunk
        blocked = jax.tree.map(lambda a: a.reshape((n_chunks, chunk) + a.shape[1:]), items)
        end = last_live_end(live_chunk)

        def step(state):
            i, out = state
            it = jax.tree.map(lambda a: jax.lax.dynamic_index_in_dim(a, i, keepdims=False), blocked)
            res = jax.lax.cond(live_chunk[i], lambda: body(it, *consts), lambda: zeros_like_shapes(shapes))
            out = jax.tree.map(lambda o, r: jax.lax.dynamic_update_index_in_dim(o, r, i, 0), out, res)
            return i + 1, out

        _, out = jax.lax.while_loop(lambda state: state[0] < end, step,
                                    (jnp.int32(0), zeros_like_shapes(shapes, (n_chunks,))))
        return jax.tree.map(lambda x: x.reshape((n,) + x.shape[2:]), out)

    @partial(run.defjvp, symbolic_zeros=True)
    def _(primals, tangents):
        return jvp_of_moving(
            lambda items, live_chunk, consts: _blocked_map(lambda it: body(it, *consts), items, live_chunk, n,
                                                           chunk, blocks), primals, tangents)

    return run(items, live_chunk, consts)


def last_live_end(live_chunk):
    """One past the last chunk with a live item (0 if none): the chunks a loop must run (a
    compacted pool's live chunks are its first ones)."""
    n_chunks = live_chunk.shape[0]
    return jnp.max(jnp.where(live_chunk, jnp.arange(1, n_chunks + 1, dtype=jnp.int32), 0))


def closure(fn: Callable[[Any], Any], items, chunk: int):
    """``fn`` of one chunk of ``items`` (a tree of arrays with a leading item axis) as
    ``body(x, *consts)`` with every array it closes over (the scene's, and the tracers of an
    enclosing trace) an argument, ``consts``, and the shapes of its result: a ``custom_jvp`` must take
    them as arguments to differentiate with respect to them (``jax.closure_convert`` hoists only the
    perturbed ones, and the others then leak out of the trace that made them)."""
    example = jax.tree.map(lambda a: jax.ShapeDtypeStruct((chunk,) + a.shape[1:], a.dtype), items)
    closed, shapes = jax.make_jaxpr(fn, return_shape=True)(example)
    out_tree = jax.tree.structure(shapes)

    @jax.jit
    def body(x, *consts):
        return jax.tree.unflatten(out_tree, jax.core.eval_jaxpr(closed.jaxpr, consts, *jax.tree.leaves(x)))

    return body, tuple(closed.consts), shapes


def resized(fn: Callable[[Any], Any], items, chunk: int, consts: tuple):
    """``fn`` of ``chunk`` items as ``body(x, *consts)`` with the ``consts`` of another
    :func:`closure` of ``fn`` (a jaxpr is traced for one size): the arrays it closes over are
    matched to those by identity. None if it closes over a tracer that ``consts`` lacks."""
    body, mine, _ = closure(fn, items, chunk)
    where = {id(c): i for i, c in enumerate(consts)}
    picks = [where.get(id(c)) for c in mine]
    if any(i is None and isinstance(c, jax.core.Tracer) for i, c in zip(picks, mine, strict=True)):
        return None

    def other(x, *given):
        return body(x, *(c if i is None else given[i] for i, c in zip(picks, mine, strict=True)))

    return other


def jvp_of_moving(fn: Callable[..., Any], primals, tangents):
    """A ``custom_jvp`` rule with symbolic zeros: ``jax.jvp`` of ``fn`` with respect to the inputs
    whose tangent is not a ``SymbolicZero``, the others held as constants (instantiated zero
    tangents would compute, and compile, every derivative no one asked for)."""
    flat, tree = jax.tree.flatten(primals)
    flat_t = jax.tree.leaves(tangents)
    moving = [not isinstance(t, SymbolicZero) for t in flat_t]

    def of_moving(*xs):
        it = iter(xs)
        args = [next(it) if m else p for p, m in zip(flat, moving, strict=True)]
        return fn(*jax.tree.unflatten(tree, args))

    return jax.jvp(of_moving, [p for p, m in zip(flat, moving, strict=True) if m],
                   [t for t, m in zip(flat_t, moving, strict=True) if m])


def map_live(fn: Callable[[Any], Any], items, alive, chunk: int, blocks: bool = True):
    """``fn`` (batched: a leading axis of ``chunk``) over ``items`` (a tree of arrays with a leading
    axis ``n``, a multiple of ``chunk``), where ``alive`` (n,) says which items matter. The result is
    ``fn``'s for live items and zeros for the items of skipped chunks, in the items' order.

    With ``blocks``, chunks are grouped into about √(n/chunk) blocks that are skipped first, so a
    sparse batch costs O(blocks + chunks of one block) loop steps rather than O(chunks).
    """
    n = alive.shape[0]
    if n % chunk:
        raise ValueError(f"{n} items do not split into chunks of {chunk}")
    order, inverse = partition(alive)
    sorted_items, sorted_alive = jax.tree.map(lambda a: a[order], (items, alive))
    live_chunk = jnp.any(sorted_alive.reshape(n // chunk, chunk), axis=1)
    out = _live_map(fn, sorted_items, live_chunk, n, chunk, blocks)
    return jax.tree.map(lambda x: x[inverse], out)


def intermediate_bytes(jaxpr) -> int:
    """Bytes of every value a (closed) jaxpr computes, nested jaxprs included (a scan's body once per
    step, the larger branch of a cond), without what runs inside a ``jax.checkpoint`` (its residuals
    are its inputs). An upper bound of what reverse mode would keep of it: a linearisation keeps a
    subset of these values as residuals."""
    from jax.extend import core

    inner = jaxpr.jaxpr if isinstance(jaxpr, core.ClosedJaxpr) else jaxpr
    total = 0
    for eqn in inner.eqns:
        total += sum(v.aval.size * v.aval.dtype.itemsize for v in eqn.outvars
                     if hasattr(v.aval, "dtype") and hasattr(v.aval, "size"))
        name = eqn.primitive.name
        if name in ("checkpoint", "remat", "remat2"):
            continue
        subs = [intermediate_bytes(j) for j in core.jaxprs_in_params(eqn.params)]
        if not subs:
            continue
        if name == "cond":
            total += max(subs)
        elif name == "scan":
            total += eqn.params["length"] * sum(subs)
        else:
            total += sum(subs)
    return total
