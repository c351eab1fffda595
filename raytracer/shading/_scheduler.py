"""The ray scheduler: a tree of rays traced level by level, as one ``lax.scan``, then combined.

It knows rays only as :class:`~._model.Rays` and hits only through one function,
``shade_rays(rays) -> Shading`` (for each ray of a batch, the local colour it sees and the
children it spawns, each with the ``coef`` and ``power`` its colour comes back with). It knows
nothing of lights, textures or surfaces. What it does:

  * levels: each level of the ray tree lives in a pool of ray slots; one ``lax.scan`` step shades
    the whole pool and writes the children into the next level's pool, so the shading body is
    traced once and compile time does not grow with the depth;
  * chunks: a pool is shaded in chunks, and chunks with no live ray are skipped with
    ``lax.cond``, so the empty slots of the tree cost almost nothing. A compacted pool's live rays
    are its first slots, so it is shaded where it is; the exact layout's are first moved to the
    front;
  * pools: either as wide as the tree's widest level (exact), or ``capacity`` slots per camera
    ray with the live children compacted into them (children that do not fit are counted);
  * the combine: a reverse scan computes ``colour = local + Σ coef · colour(child)^power`` from
    the deepest level up.

Scan and cond differentiate like any JAX function (reverse mode included); nothing here is a
``while_loop``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..kernels import safe_pow
from ._chunks import intermediate_bytes, map_in_place, map_live, zeros_like_shapes
from ._model import Rays, Shading, dead_rays


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


def _compacted(children: tuple, live: list, size: int):
    """The next pool with the live children packed, in slot order, into its first slots; where
    each child went; whether it fit; and how many did not."""
    every = jnp.concatenate(live)
    count = jnp.cumsum(every.astype(jnp.int32))  # live children up to and including each
    pos = count - 1
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
            # c^power written as c · c^(power-1): exact at power 1 (the default), where
            # d/dpower = c·log c must survive (a where(power == 1, c, …) shortcut would drop it)
            c = c * safe_pow(c, link.power[:, None] - 1.0)
        out = out + jnp.where(link.alive[:, None], link.coef * c, 0.0)
    return out, None


def trace_tree(shade_rays: Callable[[Rays], Shading], rays: Rays, *, depth: int, branch: int, chunk: int,
               capacity: int | None = None) -> tuple[jax.Array, jax.Array]:
    """Colours (N, 3) of the trees of N root rays, ``depth`` levels deep, one scan step per level.

    Args:
        shade_rays: a batch of rays → their :class:`Shading`, ``branch`` children each (a static
                   count); it sees a chunk of a pool at a time.
        rays:      the N root rays.
        depth:     levels of the tree (1: only the root rays are shaded).
        branch:    child slots per ray.
        chunk:     rays shaded per ``shade_rays`` call; chunks without a live ray are skipped.
        capacity:  ``None`` (exact): the pool is as wide as the tree's widest level
                   (``N·branch^(depth-1)``) and the children of slot i go to slots i + width·s.
                   ``c``: the pool has ``N·c`` slots and the live children are compacted into it,
                   far cheaper for deep trees where few of the ``branch^k`` slots hold a ray;
                   children beyond the capacity are dropped and counted.

    Returns:
        ``(colours (N, 3), dropped)``: ``dropped`` counts children that did not fit (always 0
        without a capacity); a caller that needs the exact image re-renders with more capacity.
    """
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
            nxt, dest, live, dropped = _compacted(children, live, size)
        else:
            width = n * jnp.power(len(children), k)  # slots this level uses: [0, width)
            nxt, dest = _full_width(children, live, width, has_next)
            dropped = jnp.zeros((), jnp.int32)
        links = tuple(Link(coef=c.coef, power=c.power, alive=a, dest=jnp.minimum(d, size - 1))
                      for c, a, d in zip(children, live, dest, strict=True))
        return nxt, (LevelRecord(local=shading.local, links=links), dropped)

    _, (records, dropped) = jax.lax.scan(level, pool, jnp.arange(depth))
    colour, _ = jax.lax.scan(_combine, jnp.zeros((size, 3), rays.origin.dtype), records, reverse=True)
    return colour[:n], jnp.sum(dropped)
