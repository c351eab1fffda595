"""The jit boundary: scene → plan → packed arrays → tiles of camera rays → Whitted tracer → image.

``render`` is one ``eqx.filter_jit``-compiled function of the scene: changing a parameter value
never recompiles; changing the structure (objects, kinds, optional effects) does. Tiles are mapped
with ``lax.map`` and each tile is rematerialised (``jax.checkpoint``) in reverse mode, so neither
the forward render nor its gradient holds more than one tile's rays at a time.
"""

from __future__ import annotations

import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp

from ._plan import Plan, make_plan
from .scene import Scene
from .shading._geometry import pack_geometry
from .shading._materials import pack_materials
from .shading.camera import camera_rays, image_coords
from .shading.whitted import make_context, trace

RAYS_PER_TILE = 1 << 18  # ray slots in the widest level of one tile's Whitted tree (memory bound)
MAX_TILE = 1 << 13  # camera rays per tile
CHUNKS_PER_TILE = 4  # secondary rays are shaded in chunks of tile/4 rays; chunks with no live ray are skipped


def plan(scene: Scene) -> Plan:
    """The static render plan of ``scene`` (primitives, effects, depth, warnings)."""
    return make_plan(scene)


def _tile_size(p: Plan, n_rays: int) -> int:
    """Camera rays per tile: the pool of the widest tree level stays within ``RAYS_PER_TILE``."""
    eff = p.effects
    branch = int(eff.reflection) + int(eff.transmission)
    width = branch ** (eff.depth - 1) if branch > 1 else 1
    size = max(64, min(MAX_TILE, RAYS_PER_TILE // width)) // CHUNKS_PER_TILE * CHUNKS_PER_TILE
    return min(size, -(-n_rays // CHUNKS_PER_TILE) * CHUNKS_PER_TILE)


def _output_transfer(img, settings):
    if settings.output_transfer == "linear":
        return img
    if settings.output_transfer == "gamma":
        return jnp.where(img > 0, jnp.abs(img) ** settings.assumed_gamma, 0.0)
    # pre-3.7 scenes: POV writes sRGB⁻¹(value) to EXR (§3.1)
    x = jnp.clip(img, 0.0, None)
    return jnp.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _context(scene: Scene):
    p = make_plan(scene)
    dtype = scene.camera.location.dtype
    geo = pack_geometry(p, dtype)
    mats = pack_materials(p, dtype)
    return make_context(p, geo, mats, scene.lights, scene.settings, scene.background, dtype)


def _trace_tiles(scene: Scene, origins, dirs, index, tile: int, n_tiles: int, progress: bool):
    """Colours of a stack of tiles (T, tile, 3), one tile at a time."""
    ctx = _context(scene)

    @jax.checkpoint
    def one_tile(args):
        o, d, i = args
        colour = trace(ctx, o, d, chunk=tile // CHUNKS_PER_TILE)
        if progress:
            jax.debug.callback(_report_progress, i, n_tiles)
        return colour

    return jax.lax.map(one_tile, (origins, dirs, index))


@functools.partial(eqx.filter_jit)
def _render(scene: Scene, width: int, height: int, k: int, progress: bool):
    p = make_plan(scene)
    dtype = scene.camera.location.dtype
    if not any(prim.rendered for prim in p.prims):  # nothing to hit: every ray sees the background
        img = jnp.broadcast_to(scene.background.astype(dtype), (height, width, 3))
        return _output_transfer(img, scene.settings)
    x0, y0 = image_coords(width, height, k, dtype)
    origins, dirs = camera_rays(scene.camera, x0, y0)
    n = width * height * k * k
    origins, dirs = origins.reshape(n, 3), dirs.reshape(n, 3)
    tile = _tile_size(p, n)
    devices = jax.devices()
    n_dev = len(devices) if math.ceil(n / tile) >= len(devices) else 1
    n_tiles = -(-math.ceil(n / tile) // n_dev) * n_dev
    pad = n_tiles * tile - n
    origins = jnp.concatenate([origins, jnp.broadcast_to(origins[:1], (pad, 3))]).reshape(n_tiles, tile, 3)
    dirs = jnp.concatenate([dirs, jnp.broadcast_to(dirs[:1], (pad, 3))]).reshape(n_tiles, tile, 3)
    index = jnp.arange(n_tiles)
    trace_tiles = functools.partial(_trace_tiles, tile=tile, n_tiles=n_tiles, progress=progress)
    if n_dev > 1:
        # tiles are independent: shard them over the devices (CPU devices with
        # --xla_force_host_platform_device_count, or GPUs); the scene is replicated
        mesh = jax.make_mesh((n_dev,), ("tiles",), devices=devices,
                             axis_types=(jax.sharding.AxisType.Auto,))
        spec, replicated = jax.sharding.PartitionSpec("tiles"), jax.sharding.PartitionSpec()
        colours = jax.shard_map(trace_tiles, mesh=mesh, in_specs=(replicated, spec, spec, spec),
                                out_specs=spec, check_vma=False)(scene, origins, dirs, index)
    else:
        colours = trace_tiles(scene, origins, dirs, index)
    img = colours.reshape(-1, 3)[:n].reshape(height, width, k * k, 3).mean(axis=2)
    return _output_transfer(img, scene.settings)


_progress_state = {"bar": None}


def _report_progress(index, total):
    bar = _progress_state["bar"]
    if bar is not None:
        bar(int(index) + 1, int(total))


def render(scene: Scene, *, width: int, height: int, spp: int = 1, progress=None) -> jax.Array:
    """Renders ``scene`` to a linear RGB image of shape (height, width, 3), row 0 at the top.

    Args:
        scene:  the scene; differentiable in every inexact array leaf.
        width, height: image size in pixels.
        spp:    samples per pixel: 1 = one ray through each pixel centre (POV-Ray ``-A``);
                k² = a deterministic k×k grid of sub-pixel centres, averaged (box filter).
        progress: optional callable ``(tiles_done, tiles_total)`` called as tiles finish.
    """
    k = math.isqrt(spp)
    if k * k != spp or spp < 1:
        raise ValueError(f"spp must be a perfect square (1, 4, 9, 16, …), got {spp}")
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width}×{height}")
    _progress_state["bar"] = progress
    try:
        return _render(scene, width, height, k, progress is not None)
    finally:
        _progress_state["bar"] = None


def compile_render(scene: Scene, *, width: int, height: int, spp: int = 1, progress=None):
    """Compiles the render of ``scene``'s structure ahead of time (for timing and benchmarks).

    Returns a function ``f(scene) -> image`` that runs the compiled program for any scene of the
    same structure (values may differ) without recompiling.
    """
    k = math.isqrt(spp)
    if k * k != spp or spp < 1:
        raise ValueError(f"spp must be a perfect square (1, 4, 9, 16, …), got {spp}")
    compiled = _render.lower(scene, width, height, k, progress is not None).compile()

    def run(s: Scene) -> jax.Array:
        _progress_state["bar"] = progress
        try:
            return compiled(s, width, height, k, progress is not None)
        finally:
            _progress_state["bar"] = None

    return run
