"""The ray scheduler: a tree of rays traced level by level, then combined.

It knows rays only as :class:`~._model.Rays` and hits only through one function,
``shade_rays(rays) -> Shading`` (for each ray of a batch, the local colour it sees and the
children it spawns, each with the ``coef`` and ``power`` its colour comes back with). It knows
nothing of lights, textures or surfaces. What it does:

  * levels: each level of the ray tree lives in a pool of ray slots; one loop step shades the
    pool and writes the children into the next level's pool, so the shading body is traced once
    and compile time does not grow with the depth;
  * chunks: a pool is shaded in chunks, and chunks with no live ray are skipped, so the empty
    slots of the tree cost almost nothing. A compacted pool's live rays are its first slots, so it
    is shaded where it is; the exact layout's are first moved to the front;
  * pools: either as wide as the tree's widest level (exact), or ``capacity`` slots per camera
    ray with the live children compacted into them (children that do not fit are counted);
  * the combine: from the deepest level up, ``colour = local + Σ coef · colour(child)^power``.

Two programs compute the same colours. :func:`_trace_scan` is a ``lax.scan`` over every level
(each pool shaded, compacted and recorded whole, ``lax.cond`` skipping dead chunks) and a reverse
scan for the combine: scan and cond differentiate like any JAX function, reverse mode included.
:func:`_live_tree`, for a compacted tree shaded in chunks, is ``while_loop`` s whose work follows
the live rays (the levels that hold one, the chunks up to the last live one, children appended
chunk by chunk); a ``while_loop`` has no reverse mode, so it is what a render runs where nothing
differentiates it, and its derivatives (``custom_jvp``) are those of the scan.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..kernels import safe_pow
from ._chunks import (
    closure,
    intermediate_bytes,
    jvp_of_moving,
    last_live_end,
    map_in_place,
    map_live,
    partition,
    resized,
    zeros_like_shapes,
)
from ._model import Rays, Shading, dead_rays


class _LevelState(NamedTuple):
    """The live tree's loop over levels (``_live_tree``)."""

    level: jax.Array  # () int32: the level being shaded
    pool: Rays  # its rays, the live ones first
    chunks: jax.Array  # () int32: its chunks up to the last live one
    spare: Rays  # the buffer the next level's rays are written into
    records: "LevelRecord"  # every level's local colours and links
    dropped: jax.Array  # () int32: children that found no room


class _ChunkState(NamedTuple):
    """One level's loop over its chunks (``_live_tree``)."""

    chunk: jax.Array  # () int32: the next chunk
    pool: Rays  # the next level's rays so far
    count: jax.Array  # () int32: children written so far (some past the room: dropped)
    records: "LevelRecord"


class Link(NamedTuple):
    """How one child slot of a pool comes back to its parents: ``coef · colour[dest]^power``.

    coef:  (P, 3) colour coefficient.
    power: (P,) exponent, or None (no exponent; static).
    alive: (P,) bool: the child was traced (it exists and it found room in the next pool).
    dest:  (P,) int32 the child's slot in the next level's pool.
    """

    coef: jax.Array
    power: jax.Array | None
    alive: jax.Array
    dest: jax.Array


class LevelRecord(NamedTuple):
    """What the reverse combine needs from one level: the local colours (P, 3) of its pool and one
    :class:`Link` per child slot (``lax.scan`` stacks these over the levels)."""

    local: jax.Array
    links: tuple[Link, ...]


MAX_FULL_WIDTH = 1 << 20  # slots per camera ray of the exact full-width tree


def slots_per_ray(branch: int, depth: int, capacity: int | None = None) -> int:
    """Pool slots per camera ray: the widest level of a tree of ``depth`` levels where each ray has
    ``branch`` child slots, ``branch^(depth-1)``, or ``capacity`` when live rays are compacted
    (never more than the full width)."""
    full = branch ** (depth - 1) if branch > 1 else 1
    if capacity is None and full > MAX_FULL_WIDTH:
        raise ValueError(f"the exact full-width ray tree of this scene ({branch}^{depth - 1} slots per "
                         "camera ray) cannot be held: render with a capacity (the default)")
    return full if capacity is None else min(full, capacity)


# Reverse mode keeps, for every level of the scan, what the pool's shading computed (its residuals),
# unless the shading is rematerialised. Above this many bytes over the levels (an upper bound,
# ``_chunks.intermediate_bytes``), a pool shaded in one call runs again in the backward pass instead.
# The filtered-shadow scene of tests/shading/test_model.py at 16×12 (49 levels through 20 noise-
# textured glass spheres, ~1 GB a level by that bound) kept 9.8 GB of XLA temporaries; an 8×6
# glass scene (10 levels of ~3 MB) stays below it and keeps its faster program.
LEVEL_RESIDUAL_BUDGET = 1 << 30


def _shade_pool(shade_rays: Callable[[Rays], Shading], rays: Rays, chunk: int, in_place: bool,
                levels: int = 1) -> Shading:
    """``shade_rays`` over a pool, in chunks of ``chunk`` rays with the live rays moved to the front;
    chunks with no live ray are skipped (``_chunks.map_live``), so the empty slots of the tree cost
    almost nothing. With ``in_place`` nothing is moved (``_chunks.map_in_place``): a compacted
    pool's live rays are already its first slots, and a renderer's camera rays are all live.
    ``levels``: how many pools like this one reverse mode keeps at once (the scan's levels)."""
    n = rays.origin.shape[0]
    if chunk >= n:  # one call over the pool, skipped when the pool is empty (deep levels)
        # a jit boundary: JAX linearises each branch of a cond twice (once to find which outputs
        # have tangents), and the inner jaxpr's linearisation is cached, so reverse mode traces the
        # shading once, not twice (glass.pov's reverse-mode trace: 8.7 → 5.4 s); this trace is
        # reused by the branch
        shade = jax.jit(shade_rays)
        traced = shade.trace(rays)
        shapes = traced.out_info
        if levels > 1 and levels * intermediate_bytes(traced.jaxpr) > LEVEL_RESIDUAL_BUDGET:
            # rematerialised as the chunks are (``_chunks._blocked_map``): the level's residuals are
            # its rays; the checkpoint outside the cond keeps the backward cond from carrying them
            # (the jit's trace above is reused inside the checkpoint: nothing is traced again)
            remat = jax.checkpoint(shade)
            return jax.checkpoint(lambda r: jax.lax.cond(jnp.any(r.alive), lambda: remat(r),
                                                         lambda: zeros_like_shapes(shapes)))(rays)
        return jax.lax.cond(jnp.any(rays.alive), lambda: shade(rays), lambda: zeros_like_shapes(shapes))
    if in_place:
        return map_in_place(shade_rays, rays, rays.alive, chunk)
    return map_live(shade_rays, rays, rays.alive, chunk)


def _pad(rays: Rays, size: int) -> Rays:
    """``rays`` followed by dead slots up to ``size``."""
    dead = dead_rays(size - rays.origin.shape[0], rays.origin.dtype, rays.media.shape[-1])
    return jax.tree.map(lambda a, b: jnp.concatenate([a, b]), rays, dead)


def _compacted(children: tuple, live: list, size: int, chunk: int):
    """The next pool with the live children packed into its first slots; where each child went;
    whether it fit; and how many did not. The order is :func:`_live_tree`'s, chunk by chunk of
    ``chunk`` parents, and in a chunk every first child before any second: where children are
    dropped, both keep the same ones (unchunked, ``chunk`` = ``size``: every first child first)."""
    every = jnp.concatenate(live)
    b, chunks = len(live), max(1, size // chunk)  # a pool shaded in one call (chunk ≥ size): one chunk
    # live children up to and including each, counted in that order, laid out slot-major
    major = every.reshape(b, chunks, -1).transpose(1, 0, 2).reshape(-1)
    count = jnp.cumsum(major.astype(jnp.int32))
    pos = (count - 1).reshape(chunks, b, -1).transpose(1, 0, 2).reshape(-1)
    keep = every & (pos < size)
    dest_all = jnp.where(keep, pos, size)  # size: out of range, the slot holds no child
    # where each slot's child comes from: one scatter of indices, then a gather per field (XLA's
    # CPU scatter is a serial loop: seven of them, one per field, were ~10 % of the Whitted
    # scene's render). Empty slots copy the first child, a finite ray, marked dead.
    slot = jnp.arange(size, dtype=jnp.int32)
    src = jnp.zeros(size, jnp.int32).at[dest_all].set(jnp.arange(every.shape[0], dtype=jnp.int32),
                                                      mode="drop")
    nxt = jax.tree.map(lambda *xs: jnp.concatenate(xs)[src], *(c.ray for c in children))
    nxt = nxt._replace(alive=slot < count[-1])
    dest = [dest_all[i * size:(i + 1) * size] for i in range(len(children))]
    fits = [keep[i * size:(i + 1) * size] for i in range(len(children))]
    return nxt, dest, fits, jnp.sum(every) - jnp.sum(keep)


def _full_width(children: tuple, live: list, width, has_next):
    """The next pool of the exact layout: the children of slot i go to slots i + width·s (s = the
    child slot), where ``width`` is the number of slots the current level uses."""
    index = jnp.arange(children[0].ray.alive.shape[0])
    dest = [index + width * i for i in range(len(children))]
    if len(children) == 1:
        return children[0].ray._replace(alive=live[0]), dest
    if len(children) != 2:
        raise NotImplementedError("the exact pool layout handles one or two child slots")
    second = index >= width
    src = jnp.where(second, index - width, index)

    def pick(a, b):
        sel = second.reshape(second.shape + (1,) * (a.ndim - 1))
        return jnp.where(sel, b[src], a[src])

    nxt = jax.tree.map(pick, children[0].ray, children[1].ray)
    return nxt._replace(alive=nxt.alive & (index < 2 * width) & has_next), dest


def _combine(colour_next, rec: LevelRecord):
    """One level of the reverse combine: ``local + Σ coef · colour(child)^power``."""
    out = rec.local
    for link in rec.links:
        c = colour_next[link.dest]
        if link.power is not None:
            # c^power written as c · |c|^(power-1): exact at power 1 (the default), where
            # d/dpower = c·log c must survive (a where(power == 1, c, …) shortcut would drop it).
            # Odd in c, so continuous in (c, power) through c = 0: a colour a perturbation makes
            # negative (a mirror seeing black) stays c at power 1 and near it, where c·c^(power-1)
            # jumped from c (power 1) to 0 (any other power): finite differences moving power and
            # a black colour together disagreed with the derivative on 23 % of the demo's pixels
            c = c * safe_pow(jnp.abs(c), link.power[:, None] - 1.0)
        out = out + jnp.where(link.alive[:, None], link.coef * c, 0.0)
    return out, None


def trace_tree(shade_rays: Callable[[Rays], Shading], rays: Rays, *, depth: int, branch: int, chunk: int,
               capacity: int | None = None, grad_chunk: int | None = None) -> tuple[jax.Array, jax.Array]:
    """Colours (N, 3) of the trees of N root rays, ``depth`` levels deep, one loop step per level.

    Args:
        shade_rays: a batch of rays → their :class:`Shading`, ``branch`` children each (a static
                   count); it sees a chunk of a pool at a time.
        rays:      the N root rays.
        depth:     levels of the tree (1: only the root rays are shaded).
        branch:    child slots per ray.
        chunk:     rays shaded per ``shade_rays`` call; chunks without a live ray are skipped.
        grad_chunk: rays per call of the program derivatives are taken through, if not ``chunk``
                   (a small pool shaded in one call compiles faster in reverse mode; forward, its
                   dead chunks cost nothing).
        capacity:  ``None`` (exact): the pool is as wide as the tree's widest level
                   (``N·branch^(depth-1)``) and the children of slot i go to slots i + width·s.
                   ``c``: the pool has ``N·c`` slots and the live children are compacted into it,
                   far cheaper for deep trees where few of the ``branch^k`` slots hold a ray;
                   children beyond the capacity are dropped and counted.

    Returns:
        ``(colours (N, 3), dropped)``: ``dropped`` counts children that did not fit (always 0
        without a capacity); a caller that needs the exact image re-renders with more capacity.

    A compacted tree shaded in chunks is traced, where nothing differentiates it, by
    :func:`_live_tree`, whose work follows the live rays; its derivatives are this scan's.
    """
    n = rays.origin.shape[0]
    size = n * slots_per_ray(branch, depth, capacity)
    full = branch ** (depth - 1) if branch > 1 else 1
    grad_chunk = min(chunk if grad_chunk is None else grad_chunk, size)  # a pool at most
    if capacity is not None and size < n * full and chunk < size and depth > 1:
        return _live_tree(shade_rays, rays, depth=depth, branch=branch, chunk=chunk, capacity=capacity,
                          grad_chunk=grad_chunk)
    return _trace_scan(shade_rays, rays, depth=depth, branch=branch, chunk=grad_chunk, capacity=capacity)


def _trace_scan(shade_rays: Callable[[Rays], Shading], rays: Rays, *, depth: int, branch: int, chunk: int,
                capacity: int | None = None, order: int | None = None) -> tuple[jax.Array, jax.Array]:
    """:func:`trace_tree` as a ``lax.scan`` over every level, each shading its whole pool (dead
    chunks skipped), compacting it and keeping its records: JAX differentiates it in both modes.
    ``order``: the chunk of :func:`_compacted`'s order (default ``chunk``), that of the live tree
    this scan is the derivative of."""
    n = rays.origin.shape[0]
    size = n * slots_per_ray(branch, depth, capacity)
    # the full width is only compared here, never allocated (a 111-level tree's is 2^110 slots:
    # slots_per_ray without a capacity refuses it, which crashed advanced/pawns.pov at compile)
    full = branch ** (depth - 1) if branch > 1 else 1
    compact = capacity is not None and size < n * full
    pool = _pad(rays, size)
    if depth == 1:
        return _shade_pool(shade_rays, pool, chunk, True).local[:n], jnp.zeros((), jnp.int32)

    def level(pool: Rays, k):
        shading = _shade_pool(shade_rays, pool, chunk, compact, levels=depth)
        children = shading.children
        has_next = k + 1 < depth
        live = [c.ray.alive & has_next for c in children]
        if compact:
            nxt, dest, live, dropped = _compacted(children, live, size, order or chunk)
        else:
            width = n * jnp.power(len(children), k)  # slots this level uses: [0, width)
            nxt, dest = _full_width(children, live, width, has_next)
            dropped = jnp.zeros((), jnp.int32)
        links = tuple(Link(coef=c.coef, power=c.power, alive=a, dest=jnp.minimum(d, size - 1))
                      for c, a, d in zip(children, live, dest, strict=True))
        return nxt, (LevelRecord(local=shading.local, links=links), dropped)

    _, (records, dropped) = jax.lax.scan(level, pool, jnp.arange(depth))
    colour, _ = jax.lax.scan(_combine, jnp.zeros((size, 3), rays.origin.dtype), records, reverse=True)
    return colour[:n], jnp.sum(dropped, dtype=jnp.int32)  # the live tree's int32 (float64 included)


def _live_tree(shade_rays: Callable[[Rays], Shading], rays: Rays, *, depth: int, branch: int, chunk: int,
               capacity: int, grad_chunk: int) -> tuple[jax.Array, jax.Array]:
    """:func:`trace_tree` of a compacted tree whose work follows its live rays: a ``while_loop``
    over the levels that stops at the first without a live ray, in each a ``while_loop`` over the
    chunks up to the last live one, each chunk appending its live children to the next pool and
    writing its records where they go; then the combine over the levels it traced. The scan shades
    every level, and compacts, records and combines every pool slot of it, live or not (the
    Whitted scene at 1024×768: a pool of 2 slots per camera ray, 0.45 live rays per camera ray
    and level). A ``while_loop`` has no reverse mode: the derivatives (``custom_jvp``) are those
    of :func:`_trace_scan`, the same values. Both fill a pool in one order (a chunk's children
    after those of the chunks before it, in a chunk every first child before any second:
    ``_compacted``), so where the capacity is too small they keep the same children and drop the
    same: the forward image under ``jit`` (a drop warned of) is the one the derivatives are of."""
    n = rays.origin.shape[0]
    size = n * slots_per_ray(branch, depth, capacity)
    spare = size + branch * chunk  # room for a chunk's whole block of children past the last slot
    pool = _pad(rays, spare)
    body, consts, shapes = closure(shade_rays, pool, chunk)

    def record(shape, dtype=None):
        return jnp.zeros((depth, size) + shape.shape[1:], dtype or shape.dtype)

    @jax.custom_jvp
    def run(pool, consts):
        records = LevelRecord(local=record(shapes.local), links=tuple(
            Link(coef=record(c.coef), power=None if c.power is None else record(c.power),
                 alive=record(c.ray.alive), dest=record(c.ray.level, jnp.int32)) for c in shapes.children))
        first_end = last_live_end(jnp.any(pool.alive[:size].reshape(size // chunk, chunk), axis=1))

        def level(state: _LevelState) -> _LevelState:
            k, cur, end, nxt, records, dropped = state
            has_next = k + 1 < depth

            def step(cs: _ChunkState) -> _ChunkState:
                j, nxt, count, records = cs
                at = j * chunk
                it = jax.tree.map(lambda a: jax.lax.dynamic_slice_in_dim(a, at, chunk), cur)
                sh = jax.lax.cond(jnp.any(it.alive), lambda: body(it, *consts),
                                  lambda: zeros_like_shapes(shapes))
                every = jnp.concatenate([c.ray.alive & has_next for c in sh.children])
                pos = count + jnp.cumsum(every, dtype=jnp.int32) - 1
                keep = every & (pos < size)
                dest = jnp.where(keep, pos, size - 1)
                order, _ = partition(every)  # the chunk's live children first, in order
                block = jax.tree.map(lambda *xs: jnp.concatenate(xs)[order], *(c.ray for c in sh.children))
                start = jnp.minimum(count, size)
                nxt = jax.tree.map(lambda b, x: jax.lax.dynamic_update_slice_in_dim(b, x, start, 0), nxt,
                                   block)

                def put(buf, x):
                    zeros = (jnp.int32(0),) * (x.ndim - 1)
                    return jax.lax.dynamic_update_slice(buf, x[None], (k, at) + zeros)

                links = []
                for s, (c, link) in enumerate(zip(sh.children, records.links, strict=True)):
                    part = slice(s * chunk, (s + 1) * chunk)
                    links.append(Link(coef=put(link.coef, c.coef),
                                      power=None if c.power is None else put(link.power, c.power),
                                      alive=put(link.alive, keep[part]), dest=put(link.dest, dest[part])))
                records = LevelRecord(local=put(records.local, sh.local), links=tuple(links))
                return _ChunkState(j + 1, nxt, count + jnp.sum(every, dtype=jnp.int32), records)

            _, nxt, count, records = jax.lax.while_loop(
                lambda cs: cs.chunk < end, step, _ChunkState(jnp.int32(0), nxt, jnp.int32(0), records))
            kept = jnp.minimum(count, size)
            nxt = nxt._replace(alive=jnp.arange(spare) < kept)
            return _LevelState(k + 1, nxt, (kept + chunk - 1) // chunk, cur, records, dropped + count - kept)

        def more(state: _LevelState):  # a level with a live ray, and not past the depth
            return (state.chunks > 0) & (state.level < depth)

        state = _LevelState(jnp.int32(0), pool, first_end, pool, records, jnp.int32(0))
        used, _, _, _, records, dropped = jax.lax.while_loop(more, level, state)

        def combine(i, colour):
            level_ = used - 1 - i
            rec = jax.tree.map(lambda a: jax.lax.dynamic_index_in_dim(a, level_, keepdims=False), records)
            return _combine(colour, rec)[0]

        colour = jax.lax.fori_loop(0, used, combine, jnp.zeros((size, 3), pool.origin.dtype))
        return colour[:n], dropped

    @partial(run.defjvp, symbolic_zeros=True)
    def _(primals, tangents):
        # the body is a jaxpr of ``chunk`` rays: shading ``grad_chunk`` at a time needs another,
        # traced only here, where something differentiates (None: it closes over other arrays)
        other = None if grad_chunk == chunk else resized(shade_rays, pool, grad_chunk, consts)
        shade, every = (body, chunk) if other is None else (other, grad_chunk)
        return jvp_of_moving(
            lambda pool, consts: _trace_scan(lambda r: shade(r, *consts), jax.tree.map(lambda a: a[:n], pool),
                                             depth=depth, branch=branch, chunk=every, capacity=capacity,
                                             order=chunk),
            primals, tangents)

    return run(pool, consts)
