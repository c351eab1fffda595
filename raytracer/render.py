"""The jit boundary: scene → plan → packed arrays → tiles of camera rays → Whitted tracer → image.

``render`` is one ``eqx.filter_jit``-compiled function of the scene: changing a parameter value
never recompiles; changing the structure (objects, kinds, optional effects) does. Tiles are mapped
with ``lax.map`` and each tile is rematerialised (``jax.checkpoint``) in reverse mode, so neither
the forward render nor its gradient holds more than one tile's rays at a time.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._packing import Frozen, is_traced, skeleton, with_field
from ._plan import Plan, make_plan
from .scene import Scene
from .shading import _accel
from .shading._geometry import PackedGeometry, pack_geometry
from .shading._materials import PackedMaterials, pack_materials
from .shading.camera import camera_rays, image_coords
from .shading.whitted import make_context, slots_per_camera_ray, trace

RAYS_PER_TILE = 1 << 18  # ray slots in the widest level of one tile's Whitted tree (memory bound)
MAX_TILE = 1 << 13  # camera rays per tile
CHUNKS_PER_TILE = 4  # secondary rays are shaded in chunks of tile/4 rays; chunks with no live ray are skipped
# a tile's pool of at most this many slots is shaded in one vmap, unchunked: skipping its empty
# chunks saves less than their branches cost (two ``lax.cond`` levels, linearized in reverse mode:
# the chunked reverse program of an 8×6 glass scene took 56 s to trace and compile, unchunked 31 s)
UNCHUNKED_POOL = 4096
FORWARD_CAPACITY = 4  # live-ray slots per camera ray and level when rendering values (grown if short)
PROGRESS_PARTS = 16  # a render with a progress bar runs as this many calls of one compiled program


def plan(scene: Scene) -> Plan:
    """The static render plan of ``scene`` (primitives, effects, depth, warnings)."""
    return make_plan(scene)


def _tile_size(scene_plan: Plan, n_rays: int, capacity: int | None = None) -> int:
    """Camera rays per tile: the pool of the widest tree level stays within ``RAYS_PER_TILE``."""
    width = slots_per_camera_ray(scene_plan.effects, capacity)
    size = max(64, min(MAX_TILE, RAYS_PER_TILE // width)) // CHUNKS_PER_TILE * CHUNKS_PER_TILE
    return min(size, -(-n_rays // CHUNKS_PER_TILE) * CHUNKS_PER_TILE)


def _output_transfer(img, settings):
    if settings.output_transfer == "linear":
        return img
    if settings.output_transfer == "gamma":
        return jnp.where(img > 0, jnp.abs(img) ** settings.assumed_gamma, 0.0)
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


_PACKED: dict[tuple, tuple[Scene, Packed]] = {}  # the last few concrete scenes packed (by identity)


def pack(scene: Scene, scene_plan: Plan | None = None) -> Packed:
    """``scene`` packed for the compiled program (values stay differentiable: under ``jax.grad``
    the packing is traced with the rest). A concrete scene is immutable (read-only arrays), so the
    last few packed are kept: rendering one scene again does not pack it again."""
    key = (id(scene), _accel.mode())
    cached = _PACKED.get(key)
    if cached is not None and cached[0] is scene:
        return cached[1]
    scene_plan = make_plan(scene) if scene_plan is None else scene_plan
    dtype = scene.camera.location.dtype
    packed = Packed(with_field(scene, "objects", ()), skeleton(scene.objects),
                    pack_geometry(scene_plan, dtype), pack_materials(scene_plan, dtype))
    if not is_traced(scene) and all(isinstance(x, np.ndarray) and not x.flags.writeable
                                    for x in jax.tree_util.tree_leaves(scene.objects)):
        while len(_PACKED) >= 4:
            _PACKED.pop(next(iter(_PACKED)))
        _PACKED[key] = (scene, packed)
    return packed


def _trace_tiles(packed: Packed, scene_plan: Plan, origins, dirs, tile: int, capacity: int | None):
    """Colours of a stack of tiles (T, tile, 3), one tile at a time, and the dropped-ray count.
    ``scene_plan`` is ``make_plan(packed.scene)``."""
    scene = packed.rest
    ctx = make_context(scene_plan, packed.geo, packed.mats, scene.lights, scene.settings, scene.background,
                       scene.camera.location.dtype)
    pool = tile * slots_per_camera_ray(scene_plan.effects, capacity)
    chunk = pool if pool <= UNCHUNKED_POOL else tile // CHUNKS_PER_TILE

    def one_tile(args):
        o, d = args
        return trace(ctx, o, d, chunk=chunk, capacity=capacity)

    if origins.shape[0] == 1:
        # one tile: nothing to bound by rematerialising it, and reverse mode then keeps the tile's
        # residuals instead of tracing (and compiling) its forward pass a second time
        colours, dropped = one_tile((origins[0], dirs[0]))
        return colours[None], jnp.sum(dropped)[None]
    colours, dropped = jax.lax.map(jax.checkpoint(one_tile), (origins, dirs))
    return colours, jnp.sum(dropped)[None]


def _layout(scene_plan: Plan, n: int, n_parts: int, capacity: int | None) -> tuple[int, int, int]:
    """``(tile, tiles per part, devices)`` for ``n`` camera rays split into ``n_parts`` parts."""
    tile = _tile_size(scene_plan, n, capacity)
    n_dev = len(jax.devices()) if math.ceil(n / tile) >= len(jax.devices()) * n_parts else 1
    per_part = -(-math.ceil(n / tile) // (n_dev * n_parts)) * n_dev
    return tile, per_part, n_dev


@eqx.filter_jit
def _render_part(packed: Packed, width: int, height: int, k: int, n_parts: int, part,
                 capacity: int | None = None):
    """Colours (tiles, tile, 3) of part ``part`` (traced) of the image's tiles, in ``n_parts`` parts,
    and the number of rays dropped for lack of ``capacity`` (see ``whitted.trace``)."""
    return _render_tiles(packed, make_plan(packed.scene), width, height, k, n_parts, part, capacity)


def _render_tiles(packed: Packed, scene_plan: Plan, width: int, height: int, k: int, n_parts: int, part,
                  capacity: int | None):
    """``_render_part`` inside a trace that has already made ``scene_plan = make_plan(packed.scene)``."""
    scene = packed.rest
    dtype = scene.camera.location.dtype
    x0, y0 = image_coords(width, height, k, dtype)
    origins, dirs = camera_rays(scene.camera, x0, y0)
    n = width * height * k * k
    tile, per_part, n_dev = _layout(scene_plan, n, n_parts, capacity)
    total = per_part * n_parts * tile
    origins = jnp.concatenate([origins.reshape(n, 3), jnp.zeros((total - n, 3), dtype)])
    dirs = jnp.concatenate([dirs.reshape(n, 3), jnp.broadcast_to(jnp.asarray([0, 0, 1], dtype),
                                                                 (total - n, 3))])
    origins = jax.lax.dynamic_slice_in_dim(origins.reshape(-1, tile, 3), part * per_part, per_part)
    dirs = jax.lax.dynamic_slice_in_dim(dirs.reshape(-1, tile, 3), part * per_part, per_part)
    if n_dev > 1:
        # tiles are independent: shard them over the devices (CPU devices with
        # --xla_force_host_platform_device_count, or GPUs); the packed scene is replicated
        def trace_shard(p, o, d):
            return _trace_tiles(p, scene_plan, o, d, tile=tile, capacity=capacity)

        mesh = jax.make_mesh((n_dev,), ("tiles",), devices=jax.devices(),
                             axis_types=(jax.sharding.AxisType.Auto,))
        spec, replicated = jax.sharding.PartitionSpec("tiles"), jax.sharding.PartitionSpec()
        colours, dropped = jax.shard_map(trace_shard, mesh=mesh, in_specs=(replicated, spec, spec),
                                         out_specs=(spec, spec), check_vma=False)(packed, origins, dirs)
        return colours, jnp.sum(dropped)
    colours, dropped = _trace_tiles(packed, scene_plan, origins, dirs, tile=tile, capacity=capacity)
    return colours, jnp.sum(dropped)


@eqx.filter_jit
def _assemble(settings, parts, width: int, height: int, k: int):
    n = width * height * k * k
    colours = jnp.concatenate([c.reshape(-1, 3) for c in parts])[:n]
    img = colours.reshape(height, width, k * k, 3).mean(axis=2)
    return _output_transfer(img, settings)


def _background_only(scene: Scene, width: int, height: int):
    dtype = scene.camera.location.dtype
    img = jnp.broadcast_to(scene.background.astype(dtype), (height, width, 3))
    return _output_transfer(img, scene.settings)


@eqx.filter_jit
def _render_packed(packed: Packed, width: int, height: int, k: int, capacity: int | None = None):
    """The image and the number of rays dropped for lack of ``capacity`` (0 when None)."""
    colours, dropped = _render_tiles(packed, make_plan(packed.scene), width, height, k, 1, 0, capacity)
    return _assemble(packed.rest.settings, [colours], width, height, k), dropped


def _render(scene: Scene, width: int, height: int, k: int, capacity: int | None = None):
    """The image and the number of rays dropped for lack of ``capacity`` (0 when None)."""
    scene_plan = make_plan(scene)
    if not any(prim.rendered for prim in scene_plan.prims):  # every ray sees the background
        return _background_only(scene, width, height), jnp.zeros((), jnp.int32)
    return _render_packed(pack(scene, scene_plan), width, height, k, capacity)


def _check(width: int, height: int, spp: int) -> int:
    k = math.isqrt(spp)
    if k * k != spp or spp < 1:
        raise ValueError(f"spp must be a perfect square (1, 4, 9, 16, …), got {spp}")
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width}×{height}")
    return k


def render(scene: Scene, *, width: int, height: int, spp: int = 1) -> jax.Array:
    """Renders ``scene`` to a linear RGB image of shape (height, width, 3), row 0 at the top.

    One jit-compiled program (cached per scene structure, image size and spp); differentiable in
    every inexact array leaf of ``scene`` with ``jax.grad``, ``jax.jvp`` and ``jax.vjp``. Called on
    a traced scene it renders the full-width Whitted tree; called on values it compacts live rays
    between trace levels (recompiling with more room if a level did not fit): the same image.

    Args:
        scene:  the scene.
        width, height: image size in pixels.
        spp:    samples per pixel: 1 = one ray through each pixel centre (POV-Ray ``-A``);
                k² = a deterministic k×k grid of sub-pixel centres, averaged (box filter).
    """
    k = _check(width, height, spp)
    if any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(scene)):
        # under jit / grad / vmap: the exact full-width tree in one program
        return _render(scene, width, height, k)[0]
    # called with values: compact live rays between levels, and grow the room until nothing is
    # dropped (same image, far less work in deep reflective/refractive trees)
    capacity = FORWARD_CAPACITY
    while True:
        image, dropped = _render(scene, width, height, k, capacity)
        if int(dropped) == 0:
            return image
        capacity *= 4



def compile_render(scene: Scene, *, width: int, height: int, spp: int = 1, progress=None,
                   capacity: int | None = FORWARD_CAPACITY):
    """Compiles the render of ``scene``'s structure ahead of time (for the CLI and benchmarks).

    Returns ``f(scene) -> image`` that runs the compiled program for any scene of the same
    structure without recompiling. With ``progress`` (a callable ``(parts_done, parts_total)``),
    the image is rendered in ``PROGRESS_PARTS`` calls of one compiled part program, reporting after
    each; the program has no host callback, so JAX's persistent compilation cache can keep it.

    ``capacity`` compacts the live rays of each trace level into ``capacity`` slots per camera ray
    (``None``: the exact full-width tree, as ``render`` uses). If a render drops rays for lack of
    room, it is recompiled with four times the capacity and rendered again, so the image is exact.
    """
    k = _check(width, height, spp)
    if not any(prim.rendered for prim in make_plan(scene).prims):
        return lambda s: _background_only(s, width, height)
    n_parts = 1 if progress is None else PROGRESS_PARTS
    state = {"capacity": capacity}

    def build():
        return _render_part.lower(pack(scene), width, height, k, n_parts, jnp.asarray(0),
                                  state["capacity"]).compile()

    state["compiled"] = build()

    def run(s: Scene) -> jax.Array:
        packed = pack(s)
        while True:
            parts, dropped = [], 0
            for i in range(n_parts):
                colours, lost = state["compiled"](packed, width, height, k, n_parts, jnp.asarray(i),
                                                  state["capacity"])
                parts.append(colours)
                dropped += int(lost)
                if progress is not None:
                    progress(i + 1, n_parts)
            if dropped == 0 or state["capacity"] is None:
                return _assemble(s.settings, parts, width, height, k)
            state["capacity"] *= 4  # some tree level was wider: exact re-render with more room
            state["compiled"] = build()

    return run
