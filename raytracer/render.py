"""The jit boundary: scene → plan → packed arrays → tiles of camera rays → Whitted tracer → image.

``render`` is one ``eqx.filter_jit``-compiled function of the scene: changing a parameter value
never recompiles; changing the structure (objects, kinds, optional effects) does. Tiles are mapped
with ``lax.map`` and each tile is rematerialised (``jax.checkpoint``) in reverse mode, so neither
the forward render nor its gradient holds more than one tile's rays at a time.
"""

from __future__ import annotations

import functools
import math
import numbers
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp

from . import _programs
from ._adaptive import Adaptive, _render_adaptive
from ._edges import EDGE_LATTICE, boundary_term
from ._gc import paused, without_collections
from ._limits import check_render_memory
from ._notice import EDGES_LEFT_OUT, notice, on
from ._packed import Packed, _placed, _plan_of, _scene_plan, pack
from ._plan import Plan, make_plan
from ._tiles import (
    FIRST_CAPACITY,
    FORWARD_CAPACITY,
    _assemble,
    _background_only,
    _image_placed,
    _layout,
    _output_transfer,
    _render_packed,
    _render_part,
    _room_key,
    _warn_dropped,
    _with_room,
)
from ._xla import warn_if_untuned
from .scene import PINHOLE, Scene

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
    cache = _programs.cache_root()
    if cache is not None:
        jax.config.update("jax_compilation_cache_dir", str(cache))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


def plan(scene: Scene) -> Plan:
    """The static render plan of ``scene`` (primitives, effects, depth, warnings)."""
    return make_plan(scene)


# a size that fitted is not checked again by the calls of a fit's loop (a failure is not cached)
_fits_memory = functools.lru_cache(maxsize=64)(check_render_memory)


def _check(width: int, height: int, spp: int) -> int:
    for name, value in (("width", width), ("height", height), ("spp", spp)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise ValueError(f"{name} must be a positive int, got {value!r}")
    k = math.isqrt(spp)
    if k * k != spp or spp < 1:
        raise ValueError(f"spp must be a perfect square (1, 4, 9, 16, …), got {spp}")
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width}×{height}")
    _fits_memory(width, height, 8 if jax.config.jax_enable_x64 else 4)  # LimitError, before anything
    return k


@without_collections  # a trace makes few cycles (a reverse-mode one of glass.pov: 139 objects)
def render(scene: Scene, *, width: int, height: int, spp: int = 1,
           capacity: int | None | str = "auto", adaptive: tuple | None = None,
           edges: bool = False) -> jax.Array:
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
        edges:  derivatives see the edges of what camera rays see (``raytracer/_edges.py``): where a
                parameter moves an object's outline or the seam of two surfaces, the pixels it
                crosses get the boundary term of their box-filtered integral, computed on the k×k
                lattice (deterministic; the image is unchanged). Without it a derivative holds the
                primitive each ray sees fixed: an outline's motion is invisible to it.
    """
    k = _check(width, height, spp)
    use_compilation_cache()
    if capacity != "auto" and capacity is not None and (type(capacity) is not int or capacity < 1):
        raise ValueError(f"capacity must be a positive int, None or 'auto', got {capacity!r}")
    if edges:
        if adaptive is not None:
            raise ValueError("edges=True takes a lattice of spp samples; adaptive anti-aliasing has none")
        if scene.camera.projection not in PINHOLE:
            raise ValueError(f"edges=True needs a perspective or orthographic camera; the boundary term "
                             f"has no outline for a {scene.camera.projection} camera's rays")
        return _render_with_edges(scene, width, height, k, capacity)
    if adaptive is not None:
        if spp != 1:
            raise ValueError("adaptive anti-aliasing starts from one ray per pixel centre: leave spp at 1")
        return _render_adaptive(scene, width, height, Adaptive(*adaptive), capacity)
    scene_plan = _scene_plan(scene)
    if not any(prim.rendered for prim in scene_plan.prims):  # every ray sees the background or sky
        return _background_only(scene, width, height, math.isqrt(spp))
    return _image(scene, scene_plan, width, height, k, capacity)


def _image(scene: Scene, scene_plan: Plan, width: int, height: int, k: int, capacity, linear: bool = False):
    """The image of a scene with something rendered (``linear``: before the output transfer)."""
    packed = pack(scene, scene_plan)

    def run(room):
        args = (_image_placed(packed, scene_plan, width * height, k, room), width, height, k, room)
        args += (True,) if linear else ()  # (as ``compile_render`` asks: the two share kept programs)
        # with values, the program kept on disk by what its trace reads, loaded where a process
        # compiled this structure before, as the command line's is (``raytracer/_programs.py``)
        return _programs.run("render", _render_packed, *args)

    return _with_room(run, capacity, _room_key(packed, width, height, k, linear))


@on(EDGES_LEFT_OUT)
def _warn_edges_left_out(overflow, dropped, tree_room: int) -> None:
    """What the boundary term left out: crossings past its room, rays of the jumps' ray trees."""
    if int(overflow) > 0:
        warnings.warn(f"{int(overflow)} crossings of edges found no room (raytracer/_edges.py, _room): their "
                      "boundary term is left out of this derivative", RuntimeWarning, stacklevel=2)
    _warn_dropped(dropped, tree_room)


def _render_with_edges(scene: Scene, width: int, height: int, k: int, capacity):
    """``render`` whose derivatives add the boundary term (``_edges.boundary_term``): a
    ``jax.custom_jvp`` of the linear image in the scene's inexact arrays, its tangent the render's
    own plus the boundary term's (linear in the tangent, so reverse mode transposes it)."""
    scene_plan = _scene_plan(scene)
    if not any(prim.rendered for prim in scene_plan.prims):  # nothing rendered: no edge
        return _background_only(scene, width, height, k)
    dynamic, static = eqx.partition(scene, eqx.is_inexact_array)

    def linear_image(dyn):
        s = eqx.combine(dyn, static)
        return _image(s, _scene_plan(s), width, height, k, capacity, linear=True)

    @jax.custom_jvp
    def image(dyn):
        return linear_image(dyn)

    @image.defjvp
    def _image_jvp(primals, tangents):
        (dyn,), (dyn_dot,) = primals, tangents
        value, value_dot = jax.jvp(linear_image, (dyn,), (dyn_dot,))
        tree_room = FORWARD_CAPACITY if capacity in ("auto", None) else capacity
        edges = boundary_term(dyn, dyn_dot, static, width, height, max(k, EDGE_LATTICE), tree_room)
        counts = (edges.overflow, edges.dropped)
        if isinstance(edges.overflow, jax.core.Tracer):  # known when the program runs
            notice(EDGES_LEFT_OUT, counts, (tree_room,))
        else:
            _warn_edges_left_out(*counts, tree_room)
        return value, value_dot + edges.tangent

    return _output_transfer(image(dynamic), scene.settings)


def compile_render(scene: Scene, *, width: int, height: int, spp: int = 1, progress=None,
                   capacity: int | None = FIRST_CAPACITY):
    """Compiles the render of ``scene``'s structure ahead of time (for the CLI and benchmarks).

    Returns ``f(scene) -> image`` that runs the compiled program for any scene of the same
    structure without recompiling. With ``progress`` (a callable ``(parts_done, parts_total)``),
    the image is rendered in ``PROGRESS_PARTS`` calls of one compiled part program, reporting after
    each. The program is kept on disk by what its trace reads (``raytracer/_programs.py``): a later
    process compiling a scene of the same structure, size and spp loads it without a trace.

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
            packed = placed(pack(scene, scene_plan), scene_plan)
            if n_parts == 1:
                # the image in one program, render's own: assembling the parts in another program
                # compiled it on the first call (~20 ms: the first "warm" render of a 160×120
                # sample scene took 24 ms, the next ones 3–4 ms)
                return _programs.compiled("render", _render_packed, packed, width, height, k,
                                          state["capacity"])
            return _programs.compiled("render part", _render_part, packed, width, height, k, n_parts,
                                      jnp.asarray(0), state["capacity"])

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
