"""POV-Ray's adaptive anti-aliasing, method 1 (semantics §3.3): the rule that chooses the pixels
to refine (``_rule``, ``_scan_flags``) and the one program that traces the centres, then the refined
pixels in passes until the rule flags nothing new (``_adaptive_program``); differentiated, the image
as a function of the scene with the refined pixels held fixed (``_render_adaptive``)."""

from __future__ import annotations

import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import _programs
from ._packed import Packed, _placed, _plan_of, _scene_plan, pack
from ._packing import is_traced
from ._plan import Plan
from ._tiles import (
    CHUNKS_PER_TILE,
    _background_only,
    _image_of,
    _image_placed,
    _layout,
    _output_transfer,
    _pixel_colours,
    _pixel_devices,
    _render_packed,
    _render_pixels,
    _render_tiles,
    _room_key,
    _with_room,
)
from .kernels import safe_pow
from .scene import Scene
from .shading import _accel


def _render_centres(packed: Packed, width: int, height: int, capacity: int | None, gamma):
    """The image of one ray through each pixel centre three ways: linear, as POV-Ray's adaptive
    rule compares colours (``_seen``) and after the output transfer; and the rays dropped. The two
    powers per value are taken in the tiles, on their devices (on one device after the program,
    at 384×288 they cost 1.2 ms (``_seen``) and 0.6 ms (an sRGB decode))."""
    settings = packed.rest.settings

    def post(colours, _):
        return jnp.concatenate([colours, _seen(colours, gamma), _output_transfer(colours, settings)], -1)

    nine, dropped = _render_tiles(packed, _plan_of(packed), width, height, 1, 1, 0, capacity, post)
    nine = _image_of(nine, width, height)
    return (nine[..., :3], nine[..., 3:6], nine[..., 6:]), dropped


def _seen(image, gamma):
    """Colours as POV-Ray's anti-aliasing compares them: raised to 1/``gamma`` (``Antialias_Gamma``)."""
    return safe_pow(jax.lax.stop_gradient(image), 1 / gamma)  # 0 where not positive


def _chain(at0, at1):
    """``s_x = f_x(s_{x-1})`` along the last axis from ``s_{-1} = 0``, for maps of one bit given by
    their values ``at0``, ``at1`` (booleans, …×W): cumulative operations instead of a loop."""
    index = jnp.arange(at0.shape[-1])
    constant = at0 == at1
    last = jax.lax.cummax(jnp.where(constant, index, -1), axis=at0.ndim - 1)  # -1: none yet, s = 0
    base = jnp.where(last >= 0, jnp.take_along_axis(at0, jnp.maximum(last, 0), axis=-1), False)
    flips = jnp.cumsum(at0 & ~at1, axis=-1, dtype=jnp.int32)  # negations up to and including x
    since = flips - jnp.where(last >= 0, jnp.take_along_axis(flips, jnp.maximum(last, 0), axis=-1), 0)
    return base ^ (since % 2 == 1)


@eqx.filter_jit
def _scan_flags(centre, refined, threshold, gamma=2.5, native: bool | None = None):
    """The pixels POV-Ray's method 1 refines, given the centre samples (H, W, 3) and the refined
    values (H, W, 3) of the pixels it refines. In scan order (rows top to bottom, each left to
    right) a pixel's centre is compared with its left and upper neighbours' values *as they are
    then*: refined already or not. A difference of at least ``threshold`` (the sum over R, G and
    B of the absolute differences of the colours raised to 1/``gamma``) refines the pixel and that
    neighbour. So a refined pixel can set off its right neighbour (its refined value differs from
    its centre), which can set off the next: POV-Ray's own rule, as far as its images show it
    (semantics §3.3). With every refined value a centre, these are the pixels on either side of a
    difference of centres.

    Where a refined value is not known yet (a pixel not traced on its grid), pass its centre:
    the flags are then a guess to refine and call again with, until every flagged pixel's refined
    value is known; they are then exact. ``_rule`` computes them from the colours as compared."""
    return _rule(_seen(centre, gamma), _seen(refined, gamma), threshold, native)


class _RowsState(NamedTuple):
    """The rule's repetition over rows (``_rule``)."""

    kept: jax.Array  # (H, W) bool: the pixels refined so far
    up: jax.Array  # (H, W) bool: those set off by the row above
    changed: jax.Array  # () bool: the last repetition changed something


class _PassState(NamedTuple):
    """The adaptive program's loop over passes (``_adaptive_program``)."""

    seen: jax.Array  # (H, W, 3) each pixel's value as the rule compares it, refined where known
    out: jax.Array  # (H, W, 3) the image so far
    flag: jax.Array  # (H, W) bool: the pixels the rule refines
    have: jax.Array  # (H, W) bool: the pixels refined so far
    dropped: jax.Array  # () int32: rays that found no room
    passes: jax.Array  # () int32


def _rule(c, a, threshold, native: bool | None = None):
    """``_scan_flags`` of the centres and refined values as POV-Ray compares them (``_seen``).

    On the CPU with the native library built (``native=None``: where it can), the rule is the
    plain loop over the pixels (``_native/antialias.cc``, called through XLA's FFI: ~25 µs a call
    at 128×96). Elsewhere it is this program: within a row the left-to-right dependence is a chain
    of maps of one bit (refined or not), :func:`_chain`; across rows, a repetition to a fixed
    point (~0.4 ms a call on the CPU at 128×96, a fixed cost of every adaptive pass)."""
    if native is None:
        native = jax.default_backend() == "cpu"
    if native and _accel.unavailable_reason() is None and c.dtype in (jnp.float32, jnp.float64):
        suffix = "F64" if c.dtype == jnp.float64 else "F32"
        loop = jax.ffi.ffi_call(f"raytracer_AaFlags{suffix}", jax.ShapeDtypeStruct(c.shape[:2], jnp.bool_),
                                vmap_method="sequential")
        return loop(c, a, jnp.asarray(threshold, c.dtype))

    def differs(x, y):
        return jnp.sum(jnp.abs(x - y), axis=-1) >= threshold

    none = jnp.zeros_like(c[:, :1, 0], bool)
    plain = jnp.concatenate([none, differs(c[:, 1:], c[:, :-1])], axis=1)  # the left one not refined
    fine = jnp.concatenate([none, differs(c[:, 1:], a[:, :-1])], axis=1)  # the left one refined
    right = jnp.concatenate([plain[:, 1:], none], axis=1)  # a pixel set off by its right neighbour

    def rows(kept):
        """Every row at once from the rows above as ``kept`` has them: a row depends on the one
        above only, so repeating this until nothing changes gives the scan-order result (row y is
        right from the y-th repetition on; usually a handful of repetitions, each one fused
        program over the image, where a scan over rows took ~6 µs a row)."""
        above = jnp.where(kept[:-1, :, None], a[:-1], c[:-1])
        up = jnp.concatenate([jnp.zeros_like(plain[:1]), differs(c[1:], above)])
        # refined_x = f_x(refined_{x-1}), f_x(0) = up_x | plain_x, f_x(1) = up_x | fine_x, from
        # refined_{-1} = 0: a map of one bit is a constant, the identity or a negation, so
        # refined_x is the last constant's value before it, negated once per negation since
        return _chain(up | plain, up | fine) | right, up

    def changed(state: _RowsState):
        return state.changed

    def again(state: _RowsState) -> _RowsState:
        new, up = rows(state.kept)
        return _RowsState(new, up, jnp.any(new != state.kept))

    start = jnp.zeros(c.shape[:2], bool)
    kept, up, _ = jax.lax.while_loop(changed, again, _RowsState(start, start, jnp.bool_(True)))
    # the row below may set a pixel off too, once its own row is done
    return kept | jnp.concatenate([up[1:], jnp.zeros_like(up[:1])])


class Adaptive(NamedTuple):
    """POV-Ray's adaptive anti-aliasing, method 1 (``+A threshold +R depth +AG gamma -J``): in
    scan order, a pixel whose centre differs from its left or upper neighbour's colour as it is
    then (refined or not) by at least ``threshold`` (the sum over R, G and B of the absolute
    differences of the traced colours, before the output transfer, raised to 1/``gamma``), and
    that neighbour, are replaced by ``(centre + Σ depth×depth grid) / (depth² + 1)`` (semantics
    §3.3, ``_scan_flags``)."""

    threshold: float = 0.3
    depth: int = 3
    gamma: float = 2.5  # POV-Ray's Antialias_Gamma (+AG): colours are compared raised to 1/gamma


def _pixel_bucket(m: int, least: int) -> int:
    """Refined pixels are traced in a padded batch: ``m`` rounded up to a multiple of an eighth of
    the next power of two, itself rounded up to a multiple of ``least`` (the tiles times the
    devices the batch is split into), so that a new count of refined pixels seldom compiles a new
    program and at most 1/8 of the batch is padding once it is large (the next power of two
    wasted up to half: 5,000 refined pixels traced 8,192)."""
    step = -(-max(least, (1 << max(m - 1, 0).bit_length()) // 8) // least) * least
    return -(-m // step) * step


def _render_adaptive(scene: Scene, width: int, height: int, aa: Adaptive, capacity):
    if aa.depth < 1 or type(aa.depth) is not int:
        raise ValueError(f"adaptive depth must be a positive int, got {aa.depth!r}")
    if not (isinstance(aa.gamma, (int, float)) and 0 < aa.gamma < math.inf):
        raise ValueError(f"adaptive gamma must be a positive number, got {aa.gamma!r}")
    scene_plan = _scene_plan(scene)
    if not any(prim.rendered for prim in scene_plan.prims):
        return _background_only(scene, width, height)
    packed = pack(scene, scene_plan)
    n = aa.depth
    # which pixels are refined is chosen from values, like a hit (piecewise constant, no gradient):
    # under eager grad and jvp the scene's values are known
    values = packed
    if is_traced(packed):
        arrays, static = eqx.partition(packed, eqx.is_array)
        values = eqx.combine(jax.lax.stop_gradient(arrays), static)
    if is_traced(values):
        # under jit / vmap they are known only when the program runs, and a loop over passes has
        # no reverse mode: refine every pixel and keep the refined value where POV-Ray's rule
        # flags it (the same image, no time saved)
        centre = _with_room(lambda room: _render_packed(packed, width, height, 1, room, True), capacity, None)
        grid = _with_room(lambda room: _render_packed(packed, width, height, n, room, True), capacity, None)
        refined = (centre + n * n * grid) / (n * n + 1)
        flag = _scan_flags(centre, refined, aa.threshold, aa.gamma)
        return _output_transfer(jnp.where(flag[..., None], refined, centre), scene.settings)
    key = _room_key(values, width, height)
    batch = _adaptive_batch(width, height)
    # arrays, not constants of the program: one program for every threshold and gamma
    dtype = scene.camera.location.dtype
    threshold, gamma = np.asarray(aa.threshold, dtype), np.asarray(aa.gamma, dtype)

    def run(room):
        n_dev = _adaptive_devices(scene_plan, width, height, n, batch, room)
        # (the values known: the program kept on disk by what its trace reads, as render's)
        return _programs.run("adaptive", _adaptive_program, _placed(values, n_dev), width, height, n, batch,
                             n_dev, room, threshold, gamma)

    image, flag = _with_room(run, capacity, key and key + ("adaptive", n))
    if values is packed:
        return image
    # differentiated: the same image as a function of the scene, the refined pixels held fixed (the
    # centres and, in one pass, the grids of the pixels the program refined)
    centre = _on_one_device(_with_room(lambda room: _render_packed(
        _image_placed(packed, scene_plan, width * height, 1, room), width, height, 1, room, True),
        capacity, key and key + ("centre",)))
    todo = np.flatnonzero(np.asarray(flag))
    if not todo.size:
        return _output_transfer(centre, scene.settings)
    m = _pixel_bucket(todo.size, CHUNKS_PER_TILE * len(jax.local_devices()))
    pixels = jnp.asarray(np.concatenate([todo, np.full(m - todo.size, width * height)]).astype(np.int32))
    placed = _placed(packed, _pixel_devices(m, n * n))
    dest, grid = _with_room(lambda room: _render_pixels(placed, width, height, n, pixels, room), capacity,
                            key and key + (n, m))
    return _refined_image(centre, _on_one_device(dest), _on_one_device(grid), n, scene.settings)


def _adaptive_batch(width: int, height: int) -> int:
    """Refined pixels per pass of ``_adaptive_program``: a quarter of the image (at least a tile's
    quantum per device), rounded as ``_pixel_bucket`` rounds. A pass with more pending pixels
    traces them in several passes (the same image); one with fewer traces only the tiles that hold
    them (``_deal``). Measured against half the image (two rounds, whitted.pov 96×72 and seed.pov
    128×96 at POV-Ray's six settings of docs/accuracy.md, and at three times those sizes): a
    quarter as fast or faster at all but one setting, up to 25 %."""
    least = CHUNKS_PER_TILE * len(jax.local_devices())
    return _pixel_bucket(max(-(-width * height // 4), least), least)


def _adaptive_devices(scene_plan: Plan, width: int, height: int, n: int, batch: int, room) -> int:
    """The local devices ``_adaptive_program`` runs on: those of the centre pass, or more where its
    refined pixels are split over more (what one device does is then repeated on the others)."""
    centre = _layout(scene_plan, width * height, 1, 1, room)[2]
    return max(centre, _pixel_devices(batch, n * n))


@eqx.filter_jit
def _adaptive_program(packed: Packed, width: int, height: int, n: int, batch: int, n_dev: int, capacity,
                      threshold, gamma):
    """POV-Ray's adaptive anti-aliasing (``Adaptive``) as one program on ``n_dev`` local devices: the
    centre pass; the pixels POV-Ray's rule flags with every value a centre (the pixels on either
    side of a difference of centres); then passes of at most ``batch`` pending pixels (flagged and
    not yet refined; past the first pass, also the two to the right of and the one below each:
    each can set off the next, and a chain is then not one pass per pixel), each traced on the
    ``n``×``n`` grid (``_pixel_colours``) and followed by the rule with the refined values known so
    far, until it flags nothing new. Returns (the image, the pixels refined in it) and the rays
    dropped. A render is one call, with no wait between passes: a pass of the host loop this
    replaced cost ~0.3 ms in calls, copies and waits besides its rays, and whitted.pov at 96×72
    (+A0.3 +R2) took 12.0–14.5 ms in four passes, now 7.7–8.7 ms."""
    settings = packed.rest.settings
    (centre, seen_centre, out_centre), dropped = _render_centres(packed, width, height, capacity, gamma)
    flag = _rule(seen_centre, seen_centre, threshold)
    size = width * height

    def post(grid, pixel):  # a tile's refined values as the rule compares them and after the transfer
        value = _refined(centre, pixel, grid, n)
        return jnp.concatenate([_seen(value, gamma), _output_transfer(value, settings)], -1)

    def pending(state: _PassState):
        # each pass refines at least one pending pixel: at most one pass a pixel
        return jnp.any(state.flag & ~state.have) & (state.passes < size)

    def shifted(x, down, right):  # x moved down and right, zeros shifted in, none wrapped
        return jnp.pad(x, ((down, 0), (right, 0)))[:height, :width]

    def one_pass(state: _PassState) -> _PassState:
        seen, out, flag, have, dropped, passes = state
        todo = flag & ~have
        # the two to the right of and the one below each pending pixel
        near = shifted(todo, 0, 1) | shifted(todo, 0, 2) | shifted(todo, 1, 0)
        todo = jnp.where(jnp.any(have), (todo | near) & ~have, todo)
        pixels = jnp.nonzero(todo.ravel(), size=batch, fill_value=size)[0].astype(jnp.int32)
        (dest, six), lost = _pixel_colours(packed, width, height, n, pixels, capacity, n_dev, post)
        seen, out = _put(seen, dest, six[:, :3]), _put(out, dest, six[:, 3:])
        have = have.ravel().at[dest].set(True, mode="drop").reshape(have.shape)
        return _PassState(seen, out, _rule(seen_centre, seen, threshold), have, dropped + lost, passes + 1)

    state = _PassState(seen_centre, out_centre, flag, jnp.zeros_like(flag), dropped, jnp.int32(0))
    _, out, flag, _, dropped, _ = jax.lax.while_loop(pending, one_pass, state)
    return (jnp.where(flag[..., None], out, out_centre), flag), dropped


def _refined(centre, dest, grid, n: int):
    """POV-Ray's refined value ``(centre + n² · grid) / (n² + 1)`` of the pixels ``dest`` (M,) (past
    the image: padding), their grids' means ``grid`` (M, 3), of the centres ``centre`` (H, W, 3)."""
    return (centre.reshape(-1, 3).at[dest].get(mode="fill", fill_value=0) + n * n * grid) / (n * n + 1)


def _put(image, dest, x):
    """``image`` (H, W, C) with the pixels ``dest`` (M,) set to ``x`` (M, C) (past the image: none)."""
    return image.reshape(-1, image.shape[-1]).at[dest].set(x, mode="drop").reshape(image.shape)


@eqx.filter_jit
def _refined_image(centre, dest, grid, n: int, settings):
    """The image of the centres ``centre`` with the pixels ``dest`` refined (``_refined``)."""
    value = _refined(centre, dest, grid, n)
    return _put(_output_transfer(centre, settings), dest, _output_transfer(value, settings))


def _on_one_device(x):
    """``x`` on the first local device where it is committed to several: the centres and the
    refined pixels of a differentiated render come from programs sharded over one or all local
    devices (``_placed``), and the program that combines them runs on one (a program takes
    committed arrays of one set of devices only). A replicated array's copy there is free; a
    sharded one is gathered by a copy between devices. A value being differentiated (eager
    ``grad``, ``jvp``) is copied there as a differentiable ``device_put``."""
    first = jax.local_devices()[0]
    if isinstance(x, jax.core.Tracer):
        one = len(jax.local_devices()) == 1
        return x if one else jax.device_put(x, jax.sharding.SingleDeviceSharding(first))
    if not x.committed or len(x.sharding.device_set) == 1:
        return x
    if x.sharding.is_fully_replicated:
        for shard in x.addressable_shards:
            if shard.device == first:
                return shard.data
    return jax.device_put(x, jax.sharding.SingleDeviceSharding(first))
