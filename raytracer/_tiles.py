"""Tiles of camera rays: how an image is cut into tiles (``_layout``), each traced by the Whitted
tracer with its rays made in the tile (``_trace_tiles``), sharded over the local devices
(``_sharded``) and assembled into the image; the room a tile's ray tree gets (``_with_room``), and
the images of scenes without objects."""

from __future__ import annotations

import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._notice import DROPPED_RAYS, notice, on
from ._packed import Packed, _placed, _plan_of
from ._plan import Plan
from .scene import SEES_EVERYWHERE, Scene, environment_of
from .shading._model import pack_environment, segment_factors, unlit_colour
from .shading.camera import camera_rays, camera_sees, sample_coords
from .shading.whitted import initial_media, make_context, slots_per_camera_ray, trace

RAYS_PER_TILE = 1 << 18  # ray slots in the widest level of one tile's Whitted tree (memory bound)


TREE_SLOTS_PER_TILE = 1 << 22  # ray slots over all levels of one tile's tree (deep straight-pass trees)


MAX_TILE = 1 << 13  # camera rays per tile


CHUNKS_PER_TILE = 4  # a tile's rays are a multiple of 4 (× samples): its pools split into chunks


# rays per chunk of a pool, at least (tile/4, tile/8, … whichever is the smallest still this large):
# chunks past a pool's last live one cost nothing (``_chunks._live_map``), so small chunks waste
# little on a deep level's few live rays. Whitted scene, 1024×768 (tiles of 8,192 rays), warm:
# chunks of 2,048 / 512 / 256 / 128 rays 0.31 / 0.28 / 0.28 / 0.30 s; advanced/pawns at 160×120
# (tiles of 4,800): chunks of 1,200 / 300 / 150 rays 0.37 / 0.34–0.35 / 0.33 s
CHUNK_RAYS = 256


# and where a tile's tree has one level (no reflected or refracted rays): its pool is the camera rays,
# all live but a batch's padding, so a chunk's fixed cost (a loop step, a branch) is paid for fewer
# rays. seed.pov, three alternating rounds (256 → 512): 640×480 16.5–20.1 → 16.3–16.7 ms, 128×96
# adaptive +A0.3 +R2 2.51–2.85 → 2.26–2.41 ms, +A0.03 +R6 5.0–5.6 → 4.4–4.8 ms; 1,024 no better.
# Trees stay at 256: whitted.pov 96×72 adaptive was 1–9 % slower at 512
FLAT_CHUNK_RAYS = 512


# differentiated, a tile's pool of at most this many slots is shaded in one vmap, unchunked:
# skipping its empty chunks saves less than their branches cost (two ``lax.cond`` levels,
# linearized in reverse mode: the chunked reverse program of an 8×6 glass scene took 56 s to trace
# and compile, unchunked 31 s). Forward, pools of any size are shaded in chunks (the live tree
# skips dead chunks without a branch): whitted.pov at 48×36 3.2 → 1.5 ms, 24×18 1.1 → 0.7 ms
UNCHUNKED_POOL = 4096


# camera rays per device, at least, for an image of fewer tiles than devices to be split over them
# (a program sharded over two CPU devices costs ~0.5–1 ms more per call: whitted.pov at 16×12 /
# 48×36 / 64×48 took 1.6 / 2.1 / 2.8 ms split, 0.5 / 1.5 / 2.1 ms on one device)
MIN_SHARD_RAYS = 2048


# live-ray slots per camera ray and level of a tile's ray tree (``capacity="auto"``):
FIRST_CAPACITY = 2  # where a drop is seen (values, eager grad): grown fourfold if short, and remembered


FORWARD_CAPACITY = 4  # under jit/vmap, where a drop is only warned of at run time


def _mesh(n_dev: int):
    return jax.make_mesh((n_dev,), ("tiles",), devices=jax.local_devices()[:n_dev],
                         axis_types=(jax.sharding.AxisType.Auto,))


def _replicated(x, n_dev: int):
    """``x`` (arrays inside a program sharded over ``n_dev`` local devices) whole on every device.
    Left to XLA's partitioner, what a program did with a sharded trace's colours next was split
    over the devices too, each piece gathered on its own: an adaptive pass's update waited on six
    gathers (~45 µs each at 128×96, each a wait for every device) instead of one."""
    if n_dev == 1:
        return x
    everywhere = jax.sharding.NamedSharding(_mesh(n_dev), jax.sharding.PartitionSpec())
    return jax.lax.with_sharding_constraint(x, everywhere)


def _tile_size(scene_plan: Plan, n_rays: int, samples: int, capacity: int | None = None) -> int:
    """Camera rays per tile: the pool of the widest tree level stays within ``RAYS_PER_TILE`` and
    the pools of all levels (kept for the combine) within ``TREE_SLOTS_PER_TILE``, and a tile holds
    whole pixels (a multiple of ``samples`` rays, so its samples average in the tile)."""
    width = slots_per_camera_ray(scene_plan.effects, capacity)
    quantum = samples * CHUNKS_PER_TILE
    fits = min(MAX_TILE, RAYS_PER_TILE // width, TREE_SLOTS_PER_TILE // (width * scene_plan.effects.depth))
    size = max(quantum, max(64, fits) // quantum * quantum)
    return min(size, -(-n_rays // quantum) * quantum)


def _chunk_size(tile: int, depth: int = 2) -> int:
    """Rays per chunk of a tile's pools: ``tile/c`` for the largest ``c`` of 4, 8, 16, … that divides
    ``tile`` and leaves at least ``CHUNK_RAYS`` rays (``FLAT_CHUNK_RAYS`` for a tree of ``depth``
    1; ``tile/4`` if none does)."""
    least = CHUNK_RAYS if depth > 1 else FLAT_CHUNK_RAYS
    c = CHUNKS_PER_TILE
    while tile % (2 * c) == 0 and tile // (2 * c) >= least:
        c *= 2
    return tile // c


def _output_transfer(img, settings):
    if settings.output_transfer == "linear":
        return img
    if settings.output_transfer == "gamma":
        # value ** assumed_gamma, held at the dtype's largest finite value where it would overflow
        # and 0 where it would underflow (assumed_gamma 1e308 made an infinite image, found by
        # benchmarks/fuzz.py); those values and non-positive ones stay out of the power, so no
        # gradient meets inf·0
        info = jnp.finfo(img.dtype)
        g = min(settings.assumed_gamma, float(info.max))  # (1e308 in float32: the same image)
        positive = img > 0
        exponent = jnp.log(jnp.where(positive, img, 1.0)) * g
        over = positive & (exponent > math.log(float(info.max)))
        under = positive & (exponent < math.log(float(info.tiny)))
        safe = jnp.where(positive & ~over & ~under, img, 1.0)
        return jnp.where(positive & ~over & ~under, safe ** g, jnp.where(over, float(info.max), 0.0))
    # pre-3.7 scenes: POV writes sRGB⁻¹(value) to EXR (semantics §3.1)
    x = jnp.clip(img, 0.0, None)
    return jnp.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _trace_tiles(packed: Packed, scene_plan: Plan, tiles, width: int, height: int, k: int, tile: int,
                 stride: int, capacity: int | None, post=None):
    """Pixel colours (T, tile/k², 3) of the tiles numbered ``tiles`` (T,) of ``stride`` tiles in
    all, one tile at a time, and the dropped-ray count. A tile's camera rays are made in the tile,
    so no image-sized array of rays exists; its k² samples per pixel are averaged in it, so
    supersampling widens nothing. ``tiles`` may instead be (T, tile/k²) pixel indices: each row is
    a tile of those pixels (the refined pixels of adaptive anti-aliasing), where an index past the
    image is padding (dead rays, colour 0). ``post`` (None: none) maps a tile's colours
    (pixels, 3) and its pixels' indices (pixels,) to the array returned in their place ((T,
    tile/k², …)): work per pixel done where the tile is, on its device, and one array for a
    program sharded over devices to gather (each gathered array is a wait for every device).
    ``scene_plan`` is ``make_plan(packed.scene)``."""
    scene = packed.rest
    dtype = scene.camera.location.dtype
    ctx = make_context(scene_plan, packed.geo, packed.mats, scene.lights, scene.settings, scene.background,
                       dtype, environment_of(scene))
    pool = tile * slots_per_camera_ray(scene_plan.effects, capacity)
    chunk = _chunk_size(tile, scene_plan.effects.depth)
    grad_chunk = pool if pool <= UNCHUNKED_POOL else chunk
    samples = k * k
    pixels = tile // samples
    media = initial_media(ctx, scene.camera.frame()[0])  # the interiors around the camera

    def one_tile(t):
        # tile t holds pixels t, t + stride, t + 2·stride, …: spread over the whole image, so its
        # live secondary rays are the image's average (a compacted pool sized by that average
        # fits), not those of one glass-covered patch; a pixel's samples stay together
        pixel = t if t.ndim else t + stride * jnp.arange(pixels)

        def traced(pixel):
            colours, dropped = shaded(pixel)
            return (colours if post is None else post(colours, pixel)), dropped

        def shaded(pixel):
            ray = (pixel[:, None] * samples + jnp.arange(samples)[None, :]).reshape(tile)
            coords = sample_coords(ray, width, height, k, dtype)
            o, d = camera_rays(scene.camera, *coords)
            # a row of pixel indices: those past the image are padding, dead rays (a plain
            # render's tail past the image is traced: its tiles are not padded at their ends)
            alive = jnp.repeat(pixel < width * height, samples) if t.ndim else None
            seen = camera_sees(scene.camera, *coords)  # a fisheye's corners: black, not traced
            if seen is not None:
                alive = seen if alive is None else alive & seen
            colours, dropped = trace(ctx, o, d, chunk=chunk, capacity=capacity, media=media,
                                     grad_chunk=grad_chunk, alive=alive)
            if seen is not None:
                colours = jnp.where(seen[:, None], colours, 0.0)
            return colours.reshape(pixels, samples, 3).mean(axis=1), dropped

        def blank(pixel):  # ``traced``'s outputs for a tile of padding (the trace's count is int32)
            colours = jnp.zeros((pixels, 3), dtype)
            if post is not None:
                shape = jax.eval_shape(post, colours, pixel)  # traces ``post`` alone, not the shading
                colours = jnp.zeros(shape.shape, shape.dtype)
            return colours, jnp.zeros((), jnp.int32)

        if not t.ndim:
            return traced(pixel)
        # a tile of padding alone (``_deal``) is not traced, nor its camera rays made
        return jax.lax.cond(jnp.any(pixel < width * height), traced, blank, pixel)

    if tiles.shape[0] == 1:
        # one tile: nothing to bound by rematerialising it, and reverse mode then keeps the tile's
        # residuals instead of tracing (and compiling) its forward pass a second time
        colours, dropped = one_tile(tiles[0])
        return jax.tree.map(lambda x: x[None], colours), jnp.sum(dropped)[None]
    colours, dropped = jax.lax.map(jax.checkpoint(one_tile), tiles)
    return colours, jnp.sum(dropped)[None]


def _layout(scene_plan: Plan, n: int, samples: int, n_parts: int,
            capacity: int | None) -> tuple[int, int, int]:
    """``(tile, tiles per part, devices)`` for ``n`` camera rays split into ``n_parts`` parts.

    The number of tiles is a multiple of parts × devices, and the tiles are then made just large
    enough to cover the image: rounding the count of the largest tiles up instead would trace up
    to a part's worth of rays past the image (16 progress parts × 2 devices: 64 tiles of 8,192
    rays for the 38 a 640×480 image needs)."""
    tile = _tile_size(scene_plan, -(-n // n_parts), samples, capacity)  # a small image: small tiles
    devices = len(jax.local_devices())  # a process's own (raytracer.distributed splits across processes)
    # an image of fewer tiles than devices is split over them too where each gets enough work: a
    # ray tree (whitted.pov at 80×60 / 96×72, one tile: 3.0 / 4.1 ms on one device, 2.6–2.9 / 3.0–3.3
    # ms on two); camera rays alone cost less than the split (seed.pov 96×72: 1.0 → 1.5 ms)
    enough = math.ceil(n / tile) >= devices * n_parts or (
        scene_plan.effects.depth > 1 and n >= devices * n_parts * MIN_SHARD_RAYS)
    n_dev = devices if enough else 1
    group = n_dev * n_parts
    tiles = -(-math.ceil(n / tile) // group) * group
    quantum = samples * CHUNKS_PER_TILE
    tile = -(-math.ceil(n / tiles) // quantum) * quantum
    return tile, tiles // n_parts, n_dev


@eqx.filter_jit
def _render_part(packed: Packed, width: int, height: int, k: int, n_parts: int, part,
                 capacity: int | None = None):
    """Pixel colours (tiles, pixels per tile, 3) of part ``part`` (traced) of the image's tiles, in
    ``n_parts`` parts, and the number of rays dropped for lack of ``capacity`` (``whitted.trace``)."""
    return _render_tiles(packed, _plan_of(packed), width, height, k, n_parts, part, capacity)


def _render_tiles(packed: Packed, scene_plan: Plan, width: int, height: int, k: int, n_parts: int, part,
                  capacity: int | None, post=None):
    """``_render_part`` inside a trace that has already made ``scene_plan = make_plan(packed.scene)``
    (``post``: as ``_trace_tiles``). Rays beyond the image (the last tile's tail) are traced and
    cut off by ``_assemble``."""
    tile, per_part, n_dev = _layout(scene_plan, width * height * k * k, k * k, n_parts, capacity)
    tiles = part * per_part + jnp.arange(per_part)
    stride = per_part * n_parts
    return _sharded(packed, tiles, n_dev, lambda p, t: _trace_tiles(
        p, scene_plan, t, width, height, k, tile=tile, stride=stride, capacity=capacity, post=post))


def _sharded(packed: Packed, tiles, n_dev: int, trace):
    """``trace(packed, tiles)`` → (colours, dropped) with the leading axis of ``tiles`` (a multiple
    of ``n_dev``) sharded over ``n_dev`` local devices: tiles are independent (CPU devices with
    --xla_force_host_platform_device_count, or GPUs). Returns the colours and the total dropped."""
    if n_dev > 1:
        # the packed scene is replicated; only its arrays cross the shard_map boundary, its
        # static half (the skeleton, static tables) is closed over
        arrays, static = eqx.partition(packed, eqx.is_array)
        spec, replicated = jax.sharding.PartitionSpec("tiles"), jax.sharding.PartitionSpec()
        colours, dropped = jax.shard_map(lambda a, t: trace(eqx.combine(a, static), t), mesh=_mesh(n_dev),
                                         in_specs=(replicated, spec), out_specs=(spec, spec),
                                         check_vma=False)(_replicated(arrays, n_dev), tiles)
        return _replicated((colours, jnp.sum(dropped)), n_dev)
    colours, dropped = trace(packed, tiles)
    return colours, jnp.sum(dropped)


@eqx.filter_jit
def _assemble(settings, parts, width: int, height: int, k: int, linear: bool = False):
    # parts: (tiles, pixels per tile, 3); tile t holds pixels t, t + tiles, … (``_trace_tiles``)
    image = _image_of(jnp.concatenate(parts), width, height)
    return image if linear else _output_transfer(image, settings)


def _image_of(colours, width: int, height: int):
    """The (H, W, C) image of tiles' colours (tiles, pixels per tile, C) (``_trace_tiles``)."""
    c = colours.shape[-1]
    return jnp.swapaxes(colours, 0, 1).reshape(-1, c)[:width * height].reshape(height, width, c)


def _background_only(scene: Scene, width: int, height: int, k: int = 1):
    """The image of a scene without a rendered object: every ray sees the background, or what the
    environment effects make of it (a sky, through fogs)."""
    environment = environment_of(scene)
    if environment or scene.camera.projection not in SEES_EVERYWHERE:  # a colour (or none) per ray
        return _unlit_image(scene.camera, environment, scene.background, scene.settings, width, height, k)
    return _background_image(scene.background.astype(scene.camera.location.dtype), scene.settings,
                             width, height)


@eqx.filter_jit
def _unlit_image(camera, environment, background, settings, width: int, height: int, k: int):
    """The image every ray of which hits nothing: the background under the environment effects
    ``environment`` (``environment_of``'s; the shading model's functions, k×k samples a pixel)."""
    dtype = camera.location.dtype
    coords = sample_coords(jnp.arange(width * height * k * k), width, height, k, dtype)
    o, d = camera_rays(camera, *coords)
    background = background.astype(dtype)
    packed = pack_environment(environment, dtype)

    def one(o_, d_):
        scale, add = segment_factors(packed, o_, d_ / jnp.linalg.norm(d_), None)
        return unlit_colour(packed, background, d_) * scale + add

    colours = jax.vmap(one)(o, d)
    seen = camera_sees(camera, *coords)
    if seen is not None:
        colours = jnp.where(seen[:, None], colours, 0.0)
    image = colours.reshape(height * width, k * k, 3).mean(axis=1).reshape(height, width, 3)
    return _output_transfer(image, settings)


@eqx.filter_jit
def _background_image(background, settings, width: int, height: int):
    """The image of a scene whose every ray sees the background, as one program (op by op, each
    call of a new size compiled its operations: incdemo/i_internal.pov, whose objects are all
    left out, took 0.39 s at 160×120)."""
    return _output_transfer(jnp.broadcast_to(background, (height, width, 3)), settings)


@eqx.filter_jit
def _render_packed(packed: Packed, width: int, height: int, k: int, capacity: int | None = None,
                   linear: bool = False):
    """The image (``linear``: before the output transfer) and the number of rays dropped for lack of
    ``capacity`` (0 when None)."""
    colours, dropped = _render_tiles(packed, _plan_of(packed), width, height, k, 1, 0, capacity)
    return _assemble(packed.rest.settings, [colours], width, height, k, linear), dropped


def _pixel_devices(m: int, samples: int = 1) -> int:
    """The local devices ``_render_pixels`` shards ``m`` pixels of ``samples`` rays over: all where
    ``m`` splits into their tiles and each gets ``MIN_SHARD_RAYS``, else one."""
    devices = len(jax.local_devices())
    split = m % (devices * CHUNKS_PER_TILE) == 0 and m * samples >= devices * MIN_SHARD_RAYS
    return devices if split else 1


@eqx.filter_jit
def _render_pixels(packed: Packed, width: int, height: int, k: int, pixels, capacity: int | None = None):
    """``_pixel_colours`` as a program of its own."""
    return _pixel_colours(packed, width, height, k, pixels, capacity)


def _pixel_colours(packed: Packed, width: int, height: int, k: int, pixels, capacity: int | None = None,
                   most_devices: int | None = None, post=None):
    """Linear colours of the pixels ``pixels`` (M,) int, each the mean of its k×k grid: (the pixel
    of each colour (M,), the colours (M, 3)), in the order they were traced; and the rays dropped.
    Indices past the image are padding (colour 0, its index kept), all after the live ones; M is a
    multiple of ``CHUNKS_PER_TILE`` × the devices (``_pixel_bucket``), which the tiles are sharded
    over where M allows (``_pixel_devices``; at most ``most_devices``). The live pixels fill the
    first tiles, as few as hold them, at least one a device (``_deal``), and a tile of padding alone
    is skipped: a batch of 16,384 pixels of which 500 are live took 9.9 ms (whitted.pov, 288×216,
    3×3), as long as 6,000 live ones, when every tile held a few. ``post``: as ``_trace_tiles``
    (the colours returned are then its arrays)."""
    scene_plan = _plan_of(packed)
    m = pixels.shape[0]
    n_dev = min(_pixel_devices(m, k * k), most_devices or m)
    share = m // n_dev
    most = _tile_size(scene_plan, share * k * k, k * k, capacity) // (k * k)
    # the largest tile that divides a device's share: a few large tiles shade a level's live rays in
    # chunks, where tiles of a pool of at most UNCHUNKED_POOL slots shade every slot of every level
    # (whitted.pov, +A0.3 +R2 at 96×72, per device: tiles of 512 pixels took 12 ms, one of 1,536 7 ms)
    per_tile = next(d for d in range(min(share, most) // CHUNKS_PER_TILE * CHUNKS_PER_TILE, 0,
                                     -CHUNKS_PER_TILE) if share % d == 0)
    rows = _replicated(_deal(pixels, width * height, per_tile, n_dev), n_dev)
    colours, dropped = _sharded(packed, rows, n_dev, lambda p, r: _trace_tiles(
        p, scene_plan, r, width, height, k, tile=per_tile * k * k, stride=0, capacity=capacity, post=post))
    return (rows.reshape(-1), colours.reshape(m, -1)), dropped


def _deal(pixels, size: int, per_tile: int, n_dev: int):
    """The tiles (M / ``per_tile``, ``per_tile``) of the pixels ``pixels`` (M,): its L live ones (the
    indices below ``size``, first) dealt in turn to the first T' tiles of devices in turn, T' the
    fewest of ``per_tile`` pixels that hold them, a multiple of ``n_dev``; the rest ``size``
    (padding). So live tile j holds live pixels j, j + T', j + 2T', … (a tile spread over the
    batch, as a plain render's over the image: one device does not get a glass sphere's edges and
    the other the floor's) and is the (j // n_dev)-th tile of device j mod ``n_dev`` (each device
    holding M / n_dev consecutive tiles)."""
    m = pixels.shape[0]
    tiles = m // per_tile
    live = jnp.sum(pixels < size)
    used = jnp.clip(-(-live // (per_tile * n_dev)) * n_dev, n_dev, tiles)
    slot = jnp.arange(tiles)
    j = slot % (tiles // n_dev) * n_dev + slot // (tiles // n_dev)  # the live tile each slot holds
    i = jnp.arange(per_tile)[None, :] * used + j[:, None]  # and the live pixel at each position
    return jnp.where((j[:, None] < used) & (i < live), pixels[jnp.minimum(i, m - 1)], size)


@on(DROPPED_RAYS)
def _warn_dropped(dropped, capacity: int) -> None:
    if int(dropped) > 0:
        warnings.warn(
            f"{int(dropped)} rays of the ray tree did not fit the compiled room of {capacity} slots per "
            "camera ray and were left out of this image and its gradient: pass a larger capacity= to "
            "render (or capacity=None, the exact full-width tree), or call it outside jit/vmap, where "
            "the room grows until every ray fits", RuntimeWarning, stacklevel=2)


def _image_placed(packed: Packed, scene_plan: Plan, pixels: int, k: int, room) -> Packed:
    """``_placed`` for ``_render_packed`` of ``pixels`` pixels of k×k samples with ``room``."""
    return _placed(packed, _layout(scene_plan, pixels * k * k, k * k, 1, room)[2])


# the room that rendered each packed scene structure (treedef, leaf shapes) and sampling without a
# drop, so that a loop of eager renders (an optimisation) grows the room once, not on every call
_ROOM: dict = {}


def _room_key(packed: Packed, *rest):
    """A key of the packed scene's structure and ``rest`` for ``_ROOM``, or None when the room
    cannot grow (under jit/vmap: the drop count exists only at run time). The packed scene has a
    handful of arrays whatever the number of objects (the scene itself: ~16 per object)."""
    leaves, treedef = jax.tree.flatten(packed)
    arrays = [x for x in leaves if isinstance(x, (jax.Array, np.ndarray))]
    if any(isinstance(x, jax.core.Tracer) for x in arrays):
        return None
    key = treedef, tuple((np.shape(x), np.result_type(x).str) for x in arrays), rest
    try:
        hash(key)
    except TypeError:  # a static field that cannot be hashed: the room grows, nothing is remembered
        return (_UNKEPT,) + rest
    return key


_UNKEPT = "not remembered"  # first entry of a key whose room is not kept (a new entry each call)


def _with_room(fn, capacity, key):
    """``fn(room)`` → (value, dropped rays), with ``capacity`` handled as ``render`` says; ``key``
    (``_room_key``): where the room that suffices is remembered (None: under jit/vmap)."""
    grow = capacity == "auto"
    if grow:
        capacity = FORWARD_CAPACITY if key is None else _ROOM.get(key, FIRST_CAPACITY)
    keep = grow and key is not None and key[0] is not _UNKEPT
    while True:
        value, dropped = fn(capacity)
        if capacity is None:
            return value
        if isinstance(dropped, jax.core.Tracer):
            # under jit / vmap the count is known only when the program runs
            notice(DROPPED_RAYS, (dropped,), (capacity,))
            return value
        # with values, and under eager jax.grad / jvp / vjp too (an integer output carries no
        # tangent: its value is known here), a tree level wider than the room renders again with
        # four times the room: the same image, exact
        if int(dropped) == 0 or not grow:
            _warn_dropped(dropped, capacity)
            if keep:
                _ROOM[key] = capacity
            return value
        capacity *= 4
