"""The jit boundary: scene → plan → packed arrays → tiles of camera rays → Whitted tracer → image.

``render`` is one ``eqx.filter_jit``-compiled function of the scene: changing a parameter value
never recompiles; changing the structure (objects, kinds, optional effects) does. Tiles are mapped
with ``lax.map`` and each tile is rematerialised (``jax.checkpoint``) in reverse mode, so neither
the forward render nor its gradient holds more than one tile's rays at a time.
"""

from __future__ import annotations

import functools
import math
import operator
import os
import pickle
import warnings
import weakref
from pathlib import Path
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._gc import paused, without_collections
from ._packing import Frozen, is_traced, keyed, skeleton, with_field
from ._plan import InPrim, Plan, leaf_prims, make_plan
from ._xla import warn_if_untuned
from .kernels import safe_pow
from .scene import Scene, environment_of
from .shading import _accel
from .shading._geometry import PackedGeometry, hierarchy_filters, pack_geometry, prim_bits
from .shading._materials import PackedMaterials, pack_materials
from .shading._model import pack_environment, segment_factors, unlit_colour
from .shading.camera import camera_rays, sample_coords
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
PROGRESS_PARTS = 16  # a render with a progress bar runs as this many calls of one compiled program


_CACHE_CHECKED = []


def use_compilation_cache() -> None:
    """Turns JAX's persistent compilation cache on, once per process, unless the user configured one:
    ``$RAYTRACER_CACHE_DIR`` (default ``~/.cache/raytracer/xla``; ``off`` leaves it off). A second
    process rendering a scene of the same structure, image size and spp then loads the compiled
    program from disk instead of compiling it (``whitted.pov`` at 1024×768: 6.0 s of tracing and
    compiling became 2.0 s of tracing and loading). Programs that compile in under a second are not
    stored. JAX reads the
    setting at its first compilation, so a process that compiled something before its first render
    keeps what it had. Also warns, once, if JAX started without ``raytracer/_xla.py``'s flags."""
    if _CACHE_CHECKED:
        return
    _CACHE_CHECKED.append(True)
    warn_if_untuned()
    if jax.config.jax_compilation_cache_dir is not None:
        return  # the user's (or the test suite's) choice
    cache = os.environ.get("RAYTRACER_CACHE_DIR", str(Path.home() / ".cache" / "raytracer" / "xla"))
    if cache and cache.lower() != "off":
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


def plan(scene: Scene) -> Plan:
    """The static render plan of ``scene`` (primitives, effects, depth, warnings)."""
    return make_plan(scene)


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


class Packed(NamedTuple):
    """The scene as the compiled program receives it (see ``raytracer/_packing.py``): its skeleton
    (objects without their arrays; camera, lights and settings as they are) and its objects packed
    into struct-of-arrays. Packing runs before the program, so neither the program's size nor its
    compile time grows with the number of objects' leaves."""

    rest: Scene  # the scene without its objects (camera, lights, settings: arrays)
    objects: Frozen  # the objects' skeleton: one static argument, hashed once
    geo: PackedGeometry
    mats: PackedMaterials

    @property
    def scene(self) -> Scene:
        """The scene's skeleton: the objects with placeholders for their arrays."""
        return with_field(self.rest, "objects", self.objects.value)


_WRITEABLE = operator.attrgetter("flags.writeable")
_PACKED: dict[tuple, tuple[Scene, Packed, Plan]] = {}  # the last few concrete scenes packed (by identity)


@without_collections  # packing makes no cycles (raytracer/_gc.py)
def pack(scene: Scene, scene_plan: Plan | None = None) -> Packed:
    """``scene`` packed for the compiled program (values stay differentiable: under ``jax.grad``
    the packing is traced with the rest). A concrete scene is immutable (read-only arrays), so the
    last few packed are kept: rendering one scene again does not pack it again."""
    cached = _kept(scene)
    if cached is not None:
        return cached[1]
    leaves, treedef = jax.tree_util.tree_flatten(scene.objects)  # one walk of the objects
    types = set(map(type, leaves))
    if any(issubclass(t, jax.core.Tracer) for t in types):
        return _pack_traced(scene, _accel.mode())
    scene_plan = make_plan(scene) if scene_plan is None else scene_plan
    packed = _pack(scene, scene_plan, (leaves, treedef))
    rest = packed.rest
    if not is_traced(rest) and types <= {np.ndarray} and not any(map(_WRITEABLE, leaves)):
        while len(_PACKED) >= 4:
            _PACKED.pop(next(iter(_PACKED)))
        _PACKED[(id(scene), _accel.mode())] = (scene, packed, scene_plan)
    return packed


def _kept(scene: Scene) -> tuple[Scene, Packed, Plan] | None:
    """What ``pack`` keeps of this concrete scene (the scene, packed, its plan), or None."""
    cached = _PACKED.get((id(scene), _accel.mode()))
    return cached if cached is not None and cached[0] is scene else None


def _scene_plan(scene: Scene) -> Plan:
    """``make_plan(scene)``, kept with the packed scene where ``pack`` keeps it: each render of
    the same scene made its plan again (0.25 ms for seed.pov, 0.4 ms for whitted.pov: an adaptive
    render at 128×96 takes a few ms)."""
    cached = _kept(scene)
    return make_plan(scene) if cached is None else cached[2]


_PLACED: dict[tuple, tuple[Packed, Packed, int]] = {}  # the last few packed scenes placed on devices
# the bytes the placed copies may take in all (a copy per device): the oldest are dropped to make
# room, and a packed scene larger than this is copied to the devices by every call instead. A 1M-
# triangle mesh (242 MB packed, two devices) copied per call spent 0.1 s of a 0.42 s render at
# 640×480 on it (kept: 0.32 s, the process's peak memory unchanged: its parse's is higher)
PLACED_BYTES = 1 << 30


def _placed(packed: Packed, n_dev: int) -> Packed:
    """``packed`` with its NumPy arrays on the device(s) a program sharded over ``n_dev`` local
    devices reads them from (replicated over them): each call would otherwise copy them there
    again. An adaptive render calls three or four programs with the same scene; its ~95 copies
    were ~1.4 ms of a 7 ms render (seed.pov at 128×96). Kept for the last few packed scenes."""
    if is_traced(packed):  # inside a trace: the program's inputs are the trace's
        return packed
    key = (id(packed), n_dev, jax.config.jax_enable_x64)  # placed arrays take the x64 setting's dtypes
    hit = _PLACED.get(key)
    if hit is not None and hit[0] is packed:
        return hit[1]
    arrays, static = eqx.partition(packed, lambda x: isinstance(x, np.ndarray))
    size = n_dev * sum(x.nbytes for x in jax.tree.leaves(arrays))
    if size > PLACED_BYTES:
        return packed  # copied by each call: no second copy kept
    # room first, so that the copies never take more than the budget
    while _PLACED and (len(_PLACED) >= 4 or size + sum(e[2] for e in _PLACED.values()) > PLACED_BYTES):
        _PLACED.pop(next(iter(_PLACED)))
    if n_dev > 1:
        mesh = jax.make_mesh((n_dev,), ("tiles",), devices=jax.local_devices()[:n_dev],
                             axis_types=(jax.sharding.AxisType.Auto,))
        placed = jax.device_put(arrays, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec()))
    else:  # uncommitted, as NumPy arrays are: the image may then be combined with any other
        placed = jax.device_put(arrays)
    placed = eqx.combine(placed, static)
    _PLACED[key] = (packed, placed, size)
    return placed


def _pack(scene: Scene, scene_plan: Plan, flat=None) -> Packed:
    dtype = scene.camera.location.dtype
    rest = with_field(scene, "objects", ())
    geo, mats = pack_geometry(scene_plan, dtype), pack_materials(scene_plan, dtype)
    signature = _signature(scene_plan, geo, mats)
    if signature is None:
        objects = skeleton(scene.objects, flat)
    else:
        # the program is keyed by the signature: the skeleton is built only if asked for (a weak
        # reference: a compiled program's cache keeps its key, which must not keep the scene)
        key = hash(signature), signature
        objects = Frozen(key=("objects", key), make=functools.partial(_skeleton_of, weakref.ref(scene)))
        keyed(geo, ("geometry", key))
        keyed(mats, ("materials", key))
        keyed(geo.accel, ("hierarchy", key))
    packed = Packed(rest, objects, geo, mats)
    # the compiled program's trace takes its plan from here (``_plan_of``) instead of making it
    # again from the skeleton: for 100,000 spheres that was 3 s of ``make_plan`` and 1.3 s of
    # building the skeleton's objects
    packed.objects.memo = (_rest_signature(rest), scene_plan)
    return packed


def _skeleton_of(scene_ref):
    scene = scene_ref()
    if scene is None:
        raise RuntimeError("the scene this value was packed from no longer exists: pack the scene again")
    return skeleton(scene.objects).value


def _signature(scene_plan: Plan, geo: PackedGeometry, mats: PackedMaterials) -> bytes | None:
    """What the render program's trace reads of the packed objects beyond their arrays' shapes,
    for a scene whose objects vary only in the hierarchy's groups of one-item shapes: then scenes
    that differ only in how many objects those groups hold (in one ``_packing.bucket``) share one
    compiled program, without a trace. None for any other scene, whose program is keyed by its
    whole skeleton.

    The trace reads (``shading/_model.make_context``, ``_geometry``, ``_materials``): the effects;
    the candidates (their groups, slots, CSG conditions and the ``where`` of every primitive
    their inside trees name) and of each candidate primitive its visibility bits, transparency,
    fade, ``inverse`` and material rows' static tables; the hierarchy's groups and whether its
    items filter or fade shadows; the materials' patterns, layers and waves; whether the scene is
    one bounding unit; the roots ``initial_media`` sends through the inside circuit (those of the
    candidates' objects, in the candidates). Everything else it looks up at a traced primitive,
    from arrays (the CSG objects the hierarchy holds are its items and programs: arrays). A
    scene without a hierarchy falls back."""
    accel = geo.accel
    if accel is None or _accel.mode() != "native":
        return None
    prims = scene_plan.prims
    bits = prim_bits(scene_plan)
    named = set(geo.cand_prim.tolist())
    if geo.conditions is not None:
        named.update(geo.conditions.circuit.leaf_prim.tolist())
    circuit_roots = ()
    if scene_plan.effects.media_slots:  # the objects ``initial_media`` sends through the circuit
        padded = {i for g, members in enumerate(geo.member_prims) if members is not None
                  for i in geo.groups[g].prims}  # (of which initial_media tests the objects' own)
        circuit_roots = tuple(tree for tree in scene_plan.roots
                              if not (isinstance(tree, InPrim) and tree.prim in padded))
        named.update(i for tree in circuit_roots for i in leaf_prims(tree))
    layers = mats.n_layers

    def rows(i):
        return slice(i * layers, (i + 1) * layers)

    candidates = [(i, int(bits[i]), prims[i].transparent, prims[i].fades, prims[i].inverse, geo.where[i],
                   mats.layer_present[i].tobytes(), mats.pattern_id[rows(i)].tobytes(),
                   mats.waves[rows(i)].tobytes(), mats.fresnel[rows(i)].tobytes(),
                   mats.conserve_energy[rows(i)].tobytes()) for i in sorted(named)]
    groups = [(g.kind, g.solid, g.accelerated, g.csg_member, None if g.accelerated else g.prims)
              for g in geo.groups]
    return pickle.dumps((
        scene_plan.effects, candidates, groups, circuit_roots, geo.cand_prim.tobytes(), geo.n_candidates,
        geo.conditions, geo.unit_boxes is None, accel.groups, hierarchy_filters(geo, scene_plan)[1:], layers,
        mats.pattern_names, mats.turbulent, mats.octaves, bool(np.any(mats.waves != 0))),
        protocol=pickle.HIGHEST_PROTOCOL)


def _rest_signature(rest: Scene):
    """What a plan may depend on in the scene without its objects: its structure (static fields
    included), its arrays' shapes and dtypes, its other leaves (never array values: a plan is made
    inside traces too)."""
    leaves, treedef = jax.tree_util.tree_flatten(rest)
    return treedef, tuple((tuple(x.shape), str(x.dtype)) if eqx.is_array(x) else x for x in leaves)


def _plan_of(packed: Packed) -> Plan:
    """``make_plan(packed.scene)``: the plan its objects' skeleton was packed with, for the same
    rest of the scene, or a new one."""
    known = packed.objects.memo
    try:
        if known is not None and known[0] == _rest_signature(packed.rest):
            return known[1]
    except (TypeError, ValueError):  # a leaf that does not compare to a bool: make the plan
        pass
    return make_plan(packed.scene)


@eqx.filter_jit
def _pack_traced(scene: Scene, mode: str) -> Packed:
    """``pack`` of a scene whose objects are traced, as one compiled program. Under an eager
    transformation (``jax.grad(loss)(scene)`` without ``jit``) packing op by op linearised and
    compiled every small operation on its own (6 s of tiny programs for a ten-kind scene, each
    new shape again); as one call the transformation sees one primitive. Inside the user's ``jit``
    it is inlined. ``mode`` (``_accel.mode()``) keys the cache: it decides what is packed."""
    del mode
    return _pack(scene, make_plan(scene))


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
            o, d = camera_rays(scene.camera, *sample_coords(ray, width, height, k, dtype))
            # a row of pixel indices: those past the image are padding, dead rays (a plain
            # render's tail past the image is traced: its tiles are not padded at their ends)
            alive = jnp.repeat(pixel < width * height, samples) if t.ndim else None
            colours, dropped = trace(ctx, o, d, chunk=chunk, capacity=capacity, media=media,
                                     grad_chunk=grad_chunk, alive=alive)
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
    if environment:  # a colour per ray
        return _unlit_image(scene.camera, environment, scene.background, scene.settings, width, height, k)
    return _background_image(scene.background.astype(scene.camera.location.dtype), scene.settings,
                             width, height)


@eqx.filter_jit
def _unlit_image(camera, environment, background, settings, width: int, height: int, k: int):
    """The image every ray of which hits nothing: the background under the environment effects
    ``environment`` (``environment_of``'s; the shading model's functions, k×k samples a pixel)."""
    dtype = camera.location.dtype
    o, d = camera_rays(camera, *sample_coords(jnp.arange(width * height * k * k), width, height, k, dtype))
    background = background.astype(dtype)
    packed = pack_environment(environment, dtype)

    def one(o_, d_):
        scale, add = segment_factors(packed, o_, d_ / jnp.linalg.norm(d_), None)
        return unlit_colour(packed, background, d_) * scale + add

    colours = jax.vmap(one)(o, d)
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


def _check(width: int, height: int, spp: int) -> int:
    k = math.isqrt(spp)
    if k * k != spp or spp < 1:
        raise ValueError(f"spp must be a perfect square (1, 4, 9, 16, …), got {spp}")
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width}×{height}")
    return k


def _warn_dropped(dropped, capacity: int) -> None:
    if int(dropped) > 0:
        warnings.warn(
            f"{int(dropped)} rays of the ray tree did not fit the compiled room of {capacity} slots per "
            "camera ray and were left out of this image and its gradient: pass a larger capacity= to "
            "render (or capacity=None, the exact full-width tree), or call it outside jit/vmap, where "
            "the room grows until every ray fits", RuntimeWarning, stacklevel=2)


@without_collections  # a trace makes few cycles (a reverse-mode one of glass.pov: 139 objects)
def render(scene: Scene, *, width: int, height: int, spp: int = 1,
           capacity: int | None | str = "auto", adaptive: tuple | None = None) -> jax.Array:
    """Renders ``scene`` to a linear RGB image of shape (height, width, 3), row 0 at the top.

    One jit-compiled program (cached per scene structure, image size, spp and capacity);
    differentiable in every inexact array leaf of ``scene`` with ``jax.grad``, ``jax.jvp`` and
    ``jax.vjp``.

    The ray tree (reflected and refracted children, level by level) is held in pools of
    ``capacity`` slots per camera ray, the live rays of each level compacted into them, so memory
    is bounded by a tile of camera rays times ``capacity`` times the depth, forward and reverse,
    whatever the scene's ``max_trace_level``.

    Args:
        scene:  the scene.
        width, height: image size in pixels.
        spp:    samples per pixel: 1 = one ray through each pixel centre (POV-Ray ``-A``);
                k² = a deterministic k×k grid of sub-pixel centres, averaged (box filter).
        capacity: ``"auto"``: with values and under eager ``jax.grad``, ``jvp`` and ``vjp``,
                ``FIRST_CAPACITY``, grown fourfold (and compiled again) until no ray is left out,
                so the image is exact; the room that sufficed is kept for the next render of a
                scene of the same structure. Under ``jit`` or ``vmap`` the count is known only
                when the program runs: it keeps ``FORWARD_CAPACITY`` and warns
                (``RuntimeWarning``) if a tree level was wider. ``int``: that room (warns
                likewise). ``None``: the exact full-width tree (``branch^(depth-1)`` slots per
                camera ray: only for shallow trees).
        adaptive: ``(threshold, depth[, gamma])`` (``Adaptive``): POV-Ray's adaptive
                anti-aliasing, method 1 (``+A threshold +R depth +AG gamma -J``; gamma 2.5 as
                POV-Ray's). A first pass traces pixel centres; the pixels POV-Ray's rule refines
                (a colour difference of at least ``threshold`` with the left or upper neighbour,
                in scan order, of colours raised to 1/gamma) get ``depth²`` more
                rays on a grid. Deterministic; differentiable (which pixels are refined is chosen
                from values, like a hit: piecewise constant). Under ``jit`` or ``vmap`` that choice
                is known only at run time, so every pixel is refined and the flagged ones kept:
                the same image, without the saving.
    """
    k = _check(width, height, spp)
    use_compilation_cache()
    if capacity != "auto" and capacity is not None and (type(capacity) is not int or capacity < 1):
        raise ValueError(f"capacity must be a positive int, None or 'auto', got {capacity!r}")
    if adaptive is not None:
        if spp != 1:
            raise ValueError("adaptive anti-aliasing starts from one ray per pixel centre: leave spp at 1")
        return _render_adaptive(scene, width, height, Adaptive(*adaptive), capacity)
    scene_plan = _scene_plan(scene)
    if not any(prim.rendered for prim in scene_plan.prims):  # every ray sees the background or sky
        return _background_only(scene, width, height, math.isqrt(spp))
    packed = pack(scene, scene_plan)
    return _with_room(lambda room: _render_packed(_image_placed(packed, scene_plan, width * height, k, room),
                                                  width, height, k, room),
                      capacity, _room_key(packed, width, height, k))


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
    if not all(jax.core.is_concrete(x) for x in arrays if isinstance(x, jax.Array)):
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
            # under jit / vmap the count is known only when the program runs; the host callback
            # only when rays were dropped (a callback costs ~0.5 ms a call: a small render's time)
            jax.lax.cond(dropped > 0, lambda d, c=capacity: jax.debug.callback(_warn_dropped, d, c),
                         lambda d: None, dropped)
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
        return _adaptive_program(_placed(values, n_dev), width, height, n, batch, n_dev, room, threshold,
                                 gamma)

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


def compile_render(scene: Scene, *, width: int, height: int, spp: int = 1, progress=None,
                   capacity: int | None = FIRST_CAPACITY):
    """Compiles the render of ``scene``'s structure ahead of time (for the CLI and benchmarks).

    Returns ``f(scene) -> image`` that runs the compiled program for any scene of the same
    structure without recompiling. With ``progress`` (a callable ``(parts_done, parts_total)``),
    the image is rendered in ``PROGRESS_PARTS`` calls of one compiled part program, reporting after
    each; the program has no host callback, so JAX's persistent compilation cache can keep it.

    ``capacity`` compacts the live rays of each trace level into ``capacity`` slots per camera ray
    (``None``: the exact full-width tree). If a render drops rays for lack of
    room, it is recompiled with four times the capacity and that part rendered again, so the image
    is exact.
    """
    k = _check(width, height, spp)
    use_compilation_cache()
    scene_plan = make_plan(scene)  # once: packing takes it (a plan of 100,000 spheres takes 3 s)
    if not any(prim.rendered for prim in scene_plan.prims):
        _background_only(scene, width, height, k)  # its program compiled here, as a render's would be
        return lambda s: _background_only(s, width, height, k)
    n_parts = 1 if progress is None else PROGRESS_PARTS
    state = {"capacity": capacity}

    def placed(packed: Packed, scene_plan: Plan) -> Packed:
        # the scene's arrays on the devices once, not copied there by every call (33 arrays of
        # seed.pov, replicated on two devices: ~0.4 ms of a 3 ms render at 160×120)
        n_dev = _layout(scene_plan, width * height * k * k, k * k, n_parts, state["capacity"])[2]
        return _placed(packed, n_dev)

    def build():
        # tracing a large scene's program with the collector on: each full collection walks the
        # scene's objects (for 100,000 spheres ~2.5 s of collections in a 1.5 s trace)
        with paused():
            if n_parts == 1:
                # the image in one program, render's own: assembling the parts in another program
                # compiled it on the first call (~20 ms: the first "warm" render of a 160×120
                # sample scene took 24 ms, the next ones 3–4 ms)
                return _render_packed.lower(placed(pack(scene, scene_plan), scene_plan), width, height, k,
                                            state["capacity"]).compile()
            return _render_part.lower(placed(pack(scene, scene_plan), scene_plan), width, height, k, n_parts,
                                      jnp.asarray(0), state["capacity"]).compile()

    state["compiled"] = build()

    def run(s: Scene) -> jax.Array:
        packed = pack(s)
        packed = placed(packed, _plan_of(packed))
        while n_parts == 1:
            image, lost = state["compiled"](packed, width, height, k, state["capacity"])
            if state["capacity"] is None or int(lost) == 0:
                return image
            state["capacity"] *= 4  # as below: more room, compiled again
            state["compiled"] = build()
        parts = []
        while len(parts) < n_parts:
            colours, lost = state["compiled"](packed, width, height, k, n_parts, jnp.asarray(len(parts)),
                                              state["capacity"])
            if state["capacity"] is not None and int(lost) > 0:
                # a tree level of this part was wider than the room: recompile with four times
                # the room and render this part again (the parts done are exact: they dropped
                # nothing, and more room changes nothing where nothing was dropped)
                state["capacity"] *= 4
                state["compiled"] = build()
                continue
            parts.append(colours)
            if progress is not None:
                progress(len(parts), n_parts)
        return _assemble(s.settings, parts, width, height, k)

    return run
