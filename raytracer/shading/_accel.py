"""The acceleration structure: a bounding volume hierarchy that *chooses* which primitive a ray hits.

A ray used to be tested against every primitive (``_geometry.all_crossings``). Primitives whose
shape names a native kernel (spheres, boxes, triangles, cylinders, cones, discs, tori,
superellipsoids, meshes: ``AbstractShape.native_kernel``) and that need nothing but their own
surface — no CSG or clipping condition — are instead *items* of a hierarchy built and traversed
by native code
(``raytracer/_native/bvh.cc``) called through XLA's FFI:

* ``closest``: the item a ray hits first, then its distance and normal computed again by the
  primitive's own JAX kernel (``sub_hits``; a superellipsoid refines the query's crossing with two
  Newton steps, ``near_hit``, where its own search costs ~400 evaluations of its norm): the
  choice is piecewise constant (made on ``stop_gradient`` values), the hit is differentiable
  exactly as before — Mitsuba's split of a preliminary intersection from a differentiable surface
  interaction;
* ``blocked``: whether any opaque item (``MASK_SHADOW``) lies on a shadow segment (an any-hit
  query that stops at the first);
* ``filtering``: the transparent shadow-casting items (``MASK_FILTER``) a shadow segment crosses,
  the nearest ``FILTER_ITEMS`` of them, each with all its crossings computed again by its kernel
  (the shading model multiplies their pigments' filter); a transparent CSG object gives one entry
  per crossing of a member that it counts. A fading interior attenuates the shadow at each exit
  crossing over the depth since the previous crossing, taken over these crossings and the
  candidates' together (``_model._shadow_fade``). With the pure-JAX twin, which has no such
  query, transparent shadow casters stay candidates, and so do a few (``MIN_FILTER_ITEMS``).

The hierarchy is rebuilt by every call of the compiled program from the scene's current values
(binned SAH, native), so it is right under ``jit``, ``grad`` and ``vmap`` and for traced geometry.
The other primitives (planes and other unbounded shapes, CSG objects it cannot hold, shapes
without a native kernel) keep the candidate path of ``_geometry``; a scene with fewer than
``MIN_ITEMS`` items is not accelerated at all, unless one of them is a CSG object, a shape whose
hit the hierarchy's solver finds (``near_hit``) or one whose kernel is costly (a torus): each pays
for the query alone.
``RAYTRACER_ACCEL=none`` turns the native path off (``native`` requires it); without the compiled
library the renderer falls back to the candidate path, and ``raytracer info`` says which one a render
uses.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_batching import custom_vmap

from .. import _native
from .._packing import any_traced, bucket, is_traced, pad_rows, register_packed
from ..kernels import matvec, world_normal
from ..shapes._base import AbstractShape, native_kinds

ITEM_PARAMS = 24  # object_from_world (12) + the shape's parameters (12): see bvh.cc
MIN_ITEMS = 8  # fewer items: every primitive is a candidate (measured: no faster either way at 10)
T_MAX = 1e7  # crossings beyond are ignored (the hierarchy's queries and ``_geometry.closest_hit``)
# item visibility bits (bvh.cc's ``want``): seen by camera rays, by reflected and transmitted rays;
# blocks shadow rays (opaque), filters them (transparent: every crossing multiplies the light)
MASK_CAMERA, MASK_REFLECT, MASK_SHADOW, MASK_FILTER = 1, 2, 4, 8
JAX_TWIN_KERNELS = frozenset(range(5))  # the kernels ``_accel_jax`` has (sphere … disc: no torus)
KIND_CSG = native_kinds()["CSG"]  # an item that is a CSG object (bvh.cc's CSG units: its members and program)
KIND_NONE = native_kinds()["NONE"]  # a row that continues the item before it (a prism's outline)
MEMBER_INTS = 4  # a CSG member's entry in its object's program (bvh.cc's CSG units)
# the box of a CSG object without one (``_geometry.csg_units``): holds every point within T_MAX of
# a ray's origin in any scene of sizes below ~1e7 (the build's centroids and areas stay finite)
UNBOUNDED = 1e8
MAX_PROGRAM = 1 << 24  # the program's offsets travel in the items' parameters: exact in float32
FILTER_ITEMS = 16  # transparent items a filtered shadow segment keeps (the nearest; see ``filtering``)
# transparent shadow casters of fewer items than this stay candidates (with the CSG objects they are
# part of): ``filtering`` evaluates FILTER_ITEMS entries of every shadow ray whatever it crosses,
# which costs more than testing a few candidates (advanced/diffract, 8 transparent primitives:
# 0.31 -> 2.4 s warm through the hierarchy; incdemo/glasses/glass, 75: 6.4 -> 0.8 s)
MIN_FILTER_ITEMS = FILTER_ITEMS + 1


class AccelUnavailable(RuntimeError):
    pass


def _library() -> str | None:
    """Loads the native library and registers its FFI targets (``raytracer/_native``: the
    hierarchy's, POV-Ray's anti-aliasing rule, compaction, run-time warnings); the reason it failed
    otherwise."""
    return _native.library()[1]


def mode() -> str:
    """``"native"`` when renders use the native hierarchy, ``"none"`` when they test every primitive,
    ``"jax"`` when they use its pure-JAX twin (``_accel_jax``).

    ``$RAYTRACER_ACCEL``: ``auto`` (default: native when the library is built and the default device
    is a CPU; the pure-JAX twin when the default device is not a CPU — the native code runs on the
    host only; every primitive tested when the library is missing on a CPU), ``native`` (an error
    when unavailable), ``none`` or ``jax``."""
    want = os.environ.get("RAYTRACER_ACCEL", "auto").strip().lower() or "auto"
    if want not in ("auto", "native", "none", "jax"):
        raise ValueError(f"RAYTRACER_ACCEL must be auto, native, none or jax, not {want!r}")
    if want in ("none", "jax"):
        return want
    problem = _library()
    if jax.default_backend() != "cpu":
        if want == "auto":
            return "jax"  # the portable path: a GPU or TPU traverses the tables itself
        problem = f"the native BVH runs on the CPU and the default device is {jax.default_backend()}"
    if problem is not None:
        if want == "native":
            raise AccelUnavailable(problem)
        return "none"
    return "native"


def unavailable_reason() -> str | None:
    return _library()


# ---------------------------------------------------------------- the FFI calls
def _suffix(dtype) -> str:
    return "F64" if jnp.dtype(dtype) == jnp.float64 else "F32"


def _build(boxes):
    """The hierarchy of ``boxes`` (n, 6): (node_box (2n-1, 6), node_info (2n-1, 4), order (n,))."""
    n = boxes.shape[0]
    m = max(2 * n - 1, 1)
    out = (jax.ShapeDtypeStruct((m, 6), boxes.dtype), jax.ShapeDtypeStruct((m, 4), jnp.int32),
           jax.ShapeDtypeStruct((n,), jnp.int32))
    call = jax.ffi.ffi_call(f"raytracer_BvhBuild{_suffix(boxes.dtype)}", out)
    return tuple(call(boxes))


def _native_query(name: str, outputs):
    """A native query over rays of any leading shape ``S`` (``o``, ``d``: S + (3,)); ``outputs(S,
    dtype)`` gives its results' shapes. Under ``vmap`` the rays of every batch (the ray pool,
    area-light samples, …) become one call; the hierarchy is the scene's and is never batched."""

    @custom_vmap
    def query(tables, o, d, tmin, tmax, want):
        call = jax.ffi.ffi_call(f"raytracer_{name}{_suffix(o.dtype)}", outputs(tmin.shape, o.dtype))
        return tuple(call(*tables, o.reshape(-1, 3), d.reshape(-1, 3), tmin.reshape(-1), tmax.reshape(-1),
                          want.reshape(-1)))

    @query.def_vmap
    def _batched(axis_size, in_batched, tables, o, d, tmin, tmax, want):
        if any(jax.tree_util.tree_leaves(in_batched[0])):
            raise NotImplementedError("the native BVH does not batch over scenes: vmap over scenes with "
                                      "RAYTRACER_ACCEL=none")
        rays = [x if b else jnp.broadcast_to(x, (axis_size, *x.shape))
                for x, b in zip((o, d, tmin, tmax, want), in_batched[1:], strict=True)]
        out = query(tables, *rays)
        return out, (True,) * len(out)

    return query


def _hit(shape, dtype):
    """(item S int32, -1 for none; t S)"""
    return jax.ShapeDtypeStruct(shape, jnp.int32), jax.ShapeDtypeStruct(shape, dtype)


def _crossed(shape, dtype):
    """(the ``FILTER_ITEMS`` nearest items crossed, S + (k,) int32 ascending, -1 after the last; how
    many were crossed, S int32, may exceed k; each one's crossing, S + (k,): its first, or for a
    CSG member the one its object counts, +inf after the last)"""
    return (jax.ShapeDtypeStruct((*shape, FILTER_ITEMS), jnp.int32), jax.ShapeDtypeStruct(shape, jnp.int32),
            jax.ShapeDtypeStruct((*shape, FILTER_ITEMS), dtype))


_closest_query = _native_query("BvhClosest", _hit)
_any_query = _native_query("BvhAny", _hit)
_all_query = _native_query("BvhAll", _crossed)


# ---------------------------------------------------------------- the packed hierarchy
@dataclasses.dataclass(frozen=True)
class AccelGroup:
    """Static description of the items of one accelerated group (``_geometry.Group``)."""

    group: int  # index into PackedGeometry.groups
    per_member: int  # items per primitive (1, or a mesh's triangles)
    csg: bool = False  # members of CSG objects (``CsgUnits``): the query names the crossing it counts
    filters: bool = True  # some item is a transparent shadow caster (``MASK_FILTER``): ``filtering`` asks it


@dataclasses.dataclass
class Accel:
    """The items of every accelerated primitive and their hierarchy (arrays of this trace)."""

    groups: tuple[AccelGroup, ...]
    item_prim: jax.Array  # (n,) int32 primitive of each item
    # the query's scene operands: node_box, node_info, order, kind, mask, params, unit, unit_box, program
    tables: tuple
    n_items: int  # items (the tables' rows past them are padding: ``pack_accel``)
    # (G, 2) int32: each group's first item and number of items (arrays, not constants of the
    # program: scenes that differ only in their numbers of items share one program)
    ranges: jax.Array | None = None


register_packed(Accel, ("item_prim", "tables", "ranges"))


@jax.jit
def _group_items(shape, ofw, wfo):
    """World boxes (n·k, 6) and parameters (n·k, ITEM_PARAMS) of the items of one stacked group: one
    compiled program per group signature (op by op, a cold start compiled every operation)."""
    p, hull = jax.vmap(lambda s: type(s).native_items(s))(shape)  # (n, k, 12 r - 12), (n, k, V, 3)
    n, k = p.shape[:2]
    world = jnp.einsum("nij,nkvj->nkvi", wfo[:, :3, :3], hull) + wfo[:, None, None, :3, 3]
    boxes = jnp.concatenate([world.min(axis=2), world.max(axis=2)], axis=-1).reshape(n * k, 6)
    m = jnp.broadcast_to(ofw[:, None, :3, :].reshape(n, 1, 12), (n, k, 12))
    # an item of r rows (``native_rows``) continues its parameters on the next rows
    params = jnp.concatenate([m, p.astype(ofw.dtype)], axis=-1).reshape(-1, ITEM_PARAMS)
    return boxes, params


ITEMS_CHUNK = 256  # one-item shapes' items are computed in chunks of this many shapes (``_items``)
# concrete groups of one-item shapes up to this size: numpy, shape by shape (a compiled program per
# shape variant cost ~60 ms each of a cold start: advanced/lamppost's eight, 0.5 s of its packing)
NUMPY_ITEMS_MAX = 256


def _host_items(shape, ofw, wfo):
    """``_group_items`` of a concrete group of one-item shapes on the host, shape by shape."""
    n = ofw.shape[0]
    items = [type(shape).native_items(jax.tree_util.tree_map(lambda a, j=j: a[j], shape)) for j in range(n)]
    p = np.concatenate([np.asarray(q) for q, _ in items])  # (n, 12)
    hull = np.concatenate([np.asarray(h) for _, h in items])  # (n, V, 3)
    world = np.einsum("nij,nvj->nvi", wfo[:, :3, :3], hull.astype(wfo.dtype)) + wfo[:, None, :3, 3]
    boxes = np.concatenate([world.min(axis=1), world.max(axis=1)], axis=-1)
    params = np.concatenate([ofw[:, :3, :].reshape(n, 12), p.astype(ofw.dtype)], axis=-1)
    return boxes, params.reshape(-1, ITEM_PARAMS)  # (an item of r rows continues on the next rows)


def _items(shape, ofw, wfo):
    """``_group_items`` of one stacked group, under ``stop_gradient``. A concrete group of one-item
    shapes (every kind but the mesh) goes in chunks of ``ITEMS_CHUNK`` shapes, its last chunk
    padded with copies of its last shape, so that a shape variant compiles one program whatever
    its group's size: each size compiled its own, ~0.1-0.2 s a group on a cold start
    (``advanced/lamppost``: nine groups, 1.1-1.3 s of its packing)."""
    sg = jax.lax.stop_gradient
    one_item = type(shape).n_native_items is AbstractShape.n_native_items
    if not one_item or is_traced(shape, ofw, wfo):
        return _group_items(jax.tree_util.tree_map(sg, shape), sg(ofw), sg(wfo))
    host = jax.tree_util.tree_map(np.asarray, (shape, ofw, wfo))
    n = host[1].shape[0]
    if n <= NUMPY_ITEMS_MAX:
        return _host_items(*host)
    total = -(-n // ITEMS_CHUNK) * ITEMS_CHUNK
    host = jax.tree_util.tree_map(lambda x: pad_rows(x, total), host)
    parts = [_group_items(*jax.tree_util.tree_map(lambda x, s=start: x[s:s + ITEMS_CHUNK], host))
             for start in range(0, total, ITEMS_CHUNK)]
    return (np.concatenate([np.asarray(b) for b, _ in parts])[:n],
            np.concatenate([np.asarray(p) for _, p in parts])[:n * shape.n_native_rows()])


def _joined(parts, dtype) -> jax.Array:
    """``jnp.concatenate(parts).astype(dtype)``, joined on the host when no part is traced (a
    jnp concatenate of host arrays compiles a conversion for every new shape of a part)."""
    if any_traced(parts):
        return jnp.concatenate(parts).astype(dtype)
    return np.concatenate([np.asarray(x) for x in parts]).astype(dtype)


def one_unit(n: int, dtype):
    """The unit tables of ``n`` items in one bounding unit (no tie between units to decide), and an
    empty CSG program."""
    return np.zeros(n, np.int32), np.zeros((1, 6), dtype), np.zeros(1, np.int32)


@dataclasses.dataclass(frozen=True)
class CsgUnits:
    """CSG objects the hierarchy holds as one item each (``_geometry.csg_units``): the native query
    finds the crossing of a member that the object's conditions count (bvh.cc, CSG units).

    units:   (U',) the bounding unit of each (an index into the plan's units and ``unit_boxes``).
    program: the programs, bvh.cc's layout, with member items numbered from the first member item.
    offsets: (U',) where each unit's program starts.
    masks:   (U',) the OR of its members' visibility bits.
    """

    units: np.ndarray
    program: np.ndarray
    offsets: np.ndarray
    masks: np.ndarray


def pack_accel(shapes, object_from_world, world_from_object, groups, prim_mask, dtype, prim_unit=None,
               unit_boxes=None, csg: CsgUnits | None = None, csg_groups=()) -> Accel:
    """Items and hierarchy of the accelerated groups. ``groups``: (group index, prim indices) pairs,
    ``shapes[g]`` / ``*_from_*[g]`` that group's stacked shapes and (n, 4, 4) maps; ``prim_mask`` (P,)
    int: each primitive's visibility bits; ``prim_unit`` (P,) and ``unit_boxes`` ((U, 3), (U, 3)):
    each primitive's bounding unit and the units' world boxes, which decide ties between coincident
    surfaces (``_geometry.unit_boxes``; None: one unit). ``csg``: the CSG objects held as items, whose
    members are the primitives of ``csg_groups`` (pairs as ``groups``'), in that order.

    The items are the groups' (in the hierarchy), then one per CSG object (in the hierarchy, its box
    its unit's), then the CSG members' (not in the hierarchy: their objects' programs name them)."""
    sg = jax.lax.stop_gradient
    prim_mask = np.asarray(prim_mask, np.int32)
    boxes, kinds, params, prims, accel_groups, ranges = [], [], [], [], [], []
    first = 0

    def add(g, prim_ids, is_csg):
        nonlocal first
        b, p = _items(shapes[g], object_from_world[g], world_from_object[g])
        n = len(prim_ids)
        k = p.shape[0] // n  # rows of a member: its items', each of ``n_native_rows`` rows
        r = shapes[g].n_native_rows()
        kind = np.full(n * k, type(shapes[g]).native_kernel, np.int32)
        if r > 1:  # the rows after an item's first continue it: never hit, never inside
            kind.reshape(-1, r)[:, 1:] = KIND_NONE
        if not is_csg:
            if r > 1:  # each continuation row an item of its own with a point box (never crossed)
                xp = jnp if any_traced([b]) else np
                point = xp.concatenate([b[:, :3], b[:, :3]], axis=-1)
                rest = xp.repeat(point[:, None], r - 1, axis=1)
                b = xp.concatenate([b[:, None], rest], axis=1).reshape(-1, 6)
            boxes.append(b)
        params.append(p)
        kinds.append(kind)
        prims.append(np.repeat(np.asarray(prim_ids, np.int32), k))
        filters = bool(np.any(prim_mask[np.asarray(prim_ids, np.int64)] & MASK_FILTER))
        accel_groups.append(AccelGroup(g, k, is_csg, filters))
        ranges.append((first, n * k))
        first += n * k

    for g, prim_ids in groups:
        add(g, prim_ids, False)
    held = np.concatenate(prims) if prims else np.zeros(0, np.int32)
    masks = prim_mask[held]
    units = np.asarray(prim_unit, np.int32)[held] if unit_boxes is not None else None
    program = np.zeros(1, np.int32)
    if csg is not None:
        n_csg = len(csg.units)
        # (an object without a box: a box of everything, ``UNBOUNDED``)
        if any_traced(unit_boxes):
            lo, hi = (sg(b)[csg.units] for b in unit_boxes)
            boxes.append(jnp.clip(jnp.concatenate([lo, hi], axis=-1), -UNBOUNDED, UNBOUNDED))
        else:  # on the host: each jnp operation compiled a program on a cold start
            boxes.append(np.clip(np.concatenate([np.asarray(b)[csg.units] for b in unit_boxes], axis=-1),
                                 -UNBOUNDED, UNBOUNDED))
        offsets = np.zeros((n_csg, ITEM_PARAMS), dtype)
        offsets[:, 0] = csg.offsets
        params.append(offsets)
        kinds.append(np.full(n_csg, KIND_CSG, np.int32))
        prims.append(np.zeros(n_csg, np.int32))  # (never named by a query: it names the member)
        masks = np.concatenate([masks, csg.masks])
        units = np.concatenate([units, csg.units])
        first += n_csg
        member_base = first  # the members' items follow the objects'
        for g, prim_ids in csg_groups:
            add(g, prim_ids, True)
        rows = [shapes[g].n_native_rows() for g, _ in csg_groups]
        member_prims = np.concatenate([np.repeat(np.asarray(ids, np.int32), r)
                                       for (_, ids), r in zip(csg_groups, rows, strict=True)])
        masks = np.concatenate([masks, prim_mask[member_prims]])
        units = np.concatenate([units, np.asarray(prim_unit, np.int32)[member_prims]])
        program = _relocate(csg, member_base)
        if program.size >= MAX_PROGRAM:
            raise ValueError(f"the CSG programs hold {program.size} numbers, more than {MAX_PROGRAM}")
    boxes = _joined(boxes, dtype)
    item_prim = np.concatenate(prims)
    node_box, node_info, order = _hierarchy()[0](boxes)
    if unit_boxes is None:
        item_unit, unit_box, _ = one_unit(len(item_prim), dtype)
    else:
        item_unit = units
        unit_box = (jnp.concatenate([sg(unit_boxes[0]), sg(unit_boxes[1])], axis=-1).astype(dtype)
                    if any_traced(unit_boxes) else np.concatenate(unit_boxes, axis=-1).astype(dtype))
    tables = (node_box, node_info, order, np.concatenate(kinds), masks, _joined(params, dtype), item_unit,
              unit_box, program)
    if _hierarchy()[0] is _build:
        # the rows past the hierarchy's nodes and items are padding (zeros: no item, mask 0), which
        # no node names: the query reads only what the root reaches
        held, items = bucket(order.shape[0]), bucket(first)
        tables = (tuple(pad_rows(x, 2 * held - 1, 0) for x in tables[:2]) + (pad_rows(order, held, 0),)
                  + tuple(pad_rows(x, items, 0) for x in tables[3:7]) + tables[7:8]
                  + (pad_rows(program, bucket(program.shape[0]), 0),))
        item_prim = pad_rows(item_prim, items, 0)
    tables = tuple(map(_array, tables))
    return Accel(tuple(accel_groups), _array(item_prim), tables, first,
                 np.asarray(ranges, np.int32).reshape(-1, 2))


def _array(x):
    """``x`` as the program takes it: a traced value as a JAX array, a concrete one as it is (a
    NumPy array; ``jnp.asarray`` compiled a staging program for each new shape and dtype on a cold
    start, ~10-20 ms each, 8-10 per sample scene's packing)."""
    return jnp.asarray(x) if any_traced([x]) else np.asarray(x)


def _relocate(csg: CsgUnits, member_base: int) -> np.ndarray:
    """``csg.program`` with its member items (written as ``-1 - member``) numbered from
    ``member_base``, the first member item."""
    program = csg.program.copy()
    members = program < 0
    program[members] = member_base + (-1 - program[members])
    return program


def _alike(accel: Accel, shapes, groups) -> list[tuple[object, list[int]]]:
    """The hierarchy's groups ``groups`` (indices into ``accel.groups``) in sets whose kernels'
    arrays stack alike, each with its kernel (None: the class's own ``sub_hits``; else a kernel
    several classes share: ``AbstractShape.kernel_form``): one kernel, pytree structure and static
    fields, leaf shapes past the leading axis, and items per member. One kernel evaluation serves
    a set: an item lies in one group, whose member's arrays are selected before the kernel rather
    than its results after (``advanced/lamppost``'s cylinders, cones and open cones, items and CSG
    members, were five evaluations)."""
    sets: dict = {}
    for g in groups:
        ag = accel.groups[g]
        kernel, arrays = shapes[ag.group].kernel_form()
        leaves, treedef = jax.tree_util.tree_flatten(arrays)
        key = (kernel, treedef, tuple((np.shape(x)[1:], jnp.result_type(x)) for x in leaves), ag.per_member)
        sets.setdefault(key, (kernel, []))[1].append(g)
    return list(sets.values())


def _chosen_members(accel: Accel, alike: list[int], shapes, object_from_world, item):
    """For items ``item`` (any shape; < 0: none) of the groups ``alike`` (one of ``_alike``'s sets):
    whether each is one, whether it is a CSG member, its member's kernel arrays (the shape, or its
    form's arrays), object-from-world map and sub-item (leaves of ``item``'s shape in front; a first
    member's where it is none). The set's groups' arrays are concatenated and gathered once by one
    index (a gather and a select per group and leaf made ~15 % of a scene's program: lamppost)."""
    chosen = jnp.maximum(item, 0)
    index = jnp.zeros_like(chosen)
    sub = jnp.zeros_like(chosen)
    found = is_csg = jnp.zeros(jnp.shape(item), bool)
    offset = 0
    arrays, maps = [], []
    for g in alike:
        ag = accel.groups[g]
        local = chosen - accel.ranges[g, 0]
        mine = (item >= 0) & (local >= 0) & (local < accel.ranges[g, 1])
        if ag.per_member == 1:
            member = local
        else:
            member, part = local // ag.per_member, local % ag.per_member
            sub = jnp.where(mine, part, sub)
        index = jnp.where(mine, offset + member, index)
        found = found | mine
        if ag.csg:
            is_csg = is_csg | mine
        arrays.append(shapes[ag.group].kernel_form()[1])
        maps.append(object_from_world[ag.group])
        offset += maps[-1].shape[0]
    if len(alike) > 1:
        arrays = [jax.tree_util.tree_map(lambda *xs: jnp.concatenate(xs), *arrays)]
        maps = [jnp.concatenate(maps)]
    picked = jax.tree_util.tree_map(lambda a: a[index], arrays[0])
    return found, is_csg, picked, maps[0][index], sub


def _kernel_hits(kernel, arrays, o, d, sub):
    """The crossings of one member's kernel ``arrays`` (``_alike``'s ``kernel``: None, its shape's own)."""
    return arrays.sub_hits(o, d, sub) if kernel is None else kernel(arrays, o, d)


def closest(accel: Accel, shapes, object_from_world, o, d, t_min, want: int | jax.Array):
    """The closest item hit beyond ``t_min`` by rays whose visibility bit is ``want``, computed
    again by its primitive's kernel: ``(found, t, prim, unit world normal, sub)`` (``inverse`` not
    applied; ``sub`` the item's index within its primitive: a mesh's triangle, else 0); ``t`` is
    +inf where nothing is found. A member of a CSG object answers with its
    crossing nearest the one the query counted (its others may lie where the object is not)."""
    sg = jax.lax.stop_gradient
    want = jnp.asarray(want, jnp.int32)
    item, t_chosen = _hierarchy()[1](accel.tables, sg(o), sg(d), sg(t_min), jnp.asarray(T_MAX, o.dtype), want)
    chosen = jnp.maximum(item, 0)
    best_t, best_n = jnp.asarray(jnp.inf, o.dtype), jnp.zeros(3, o.dtype).at[2].set(1.0)
    best_sub = jnp.zeros((), jnp.int32)
    for kernel, alike in _alike(accel, shapes, range(len(accel.groups))):
        mine, csg, arrays, m, sub = _chosen_members(accel, alike, shapes, object_from_world, item)
        o_obj, d_obj = matvec(m[:3, :3], o) + m[:3, 3], matvec(m[:3, :3], d)  # the same t
        # a shape that refines the query's crossing instead of finding all of its own again (the
        # query's t where it found one, else a finite stand-in: no inf in the gradient's path)
        near = None if kernel is not None else arrays.near_hit(
            o_obj, d_obj, jnp.where(mine & jnp.isfinite(t_chosen), t_chosen, 0).astype(o.dtype))
        t, n = _kernel_hits(kernel, arrays, o_obj, d_obj, sub) if near is None else near
        ok = mine & (t > t_min) & jnp.isfinite(t) & (t < T_MAX)
        tt = jnp.where(ok, t, jnp.inf)
        c = jnp.argmin(tt)
        if any(accel.groups[g].csg for g in alike):
            c = jnp.where(csg, jnp.argmin(jnp.where(ok, jnp.abs(sg(t) - t_chosen), jnp.inf)), c)
        closer = tt[c] < best_t
        best_t = jnp.where(closer, tt[c], best_t)
        best_n = jnp.where(closer, world_normal(n[c], m), best_n)
        best_sub = jnp.where(closer, sub, best_sub).astype(jnp.int32)
    return jnp.isfinite(best_t), best_t, accel.item_prim[chosen], best_n, best_sub


def blocked(accel: Accel, o, d, t_min, t_max):
    """Whether a shadow-casting item lies on the segment ``t_min < t < t_max`` of the ray."""
    sg = jax.lax.stop_gradient
    want = jnp.asarray(MASK_SHADOW, jnp.int32)
    item, _ = _hierarchy()[2](accel.tables, sg(o), sg(d), sg(t_min), sg(t_max), want)
    return item >= 0


class Crossed(NamedTuple):
    """The transparent items a shadow segment crosses, each with every crossing of its kernel."""

    t: jax.Array  # (k, J) crossings of each kept item (+inf where none, or the slot is empty)
    prim: jax.Array  # (k,) int32 primitive of each kept item (0 for empty slots)
    normal: jax.Array  # (k, J, 3) unit world normals (``inverse`` not applied)
    overflow: jax.Array  # () bool: more than k items were crossed (the farthest were dropped)


def _line_crossings(shapes, slots: int) -> int:
    """The most crossings a line can have with a shape of the stacked group ``shapes``: its class's
    ``line_crossings`` where that is a number for the class (a convex frustum's 2), else ``slots``."""
    bound = getattr(type(shapes), "line_crossings", None)
    return min(bound, slots) if isinstance(bound, int) else slots


def filtering(accel: Accel, shapes, object_from_world, o, d, t_min, t_max) -> Crossed:
    """The nearest ``FILTER_ITEMS`` transparent shadow-casting items (``MASK_FILTER``) with a
    crossing on the segment ``t_min < t < t_max``, and every crossing of each, computed again by its
    primitive's kernel (a sphere filters twice if the segment crosses it twice; crossings outside the
    segment are +inf)."""
    sg = jax.lax.stop_gradient
    want = jnp.asarray(MASK_FILTER, jnp.int32)
    item, count, t_native = _all_query(accel.tables, sg(o), sg(d), sg(t_min), sg(t_max), want)
    ts = []
    # (the query names only items of groups with transparent shadow casters)
    for kernel, alike in _alike(accel, shapes, [g for g, ag in enumerate(accel.groups) if ag.filters]):
        members = _chosen_members(accel, alike, shapes, object_from_world, item)
        any_csg = any(accel.groups[g].csg for g in alike)
        all_csg = all(accel.groups[g].csg for g in alike)

        def one(mine, csg, arrays, m, sub, t_counted, any_csg=any_csg, all_csg=all_csg, kernel=kernel):
            o_obj, d_obj = matvec(m[:3, :3], o) + m[:3, 3], matvec(m[:3, :3], d)
            # CSG members only, of a shape that refines the query's crossing (a polynomial's
            # search, ~4 brackets of 50 halvings, on every entry of every shadow ray: pawns.pov
            # 1.2 -> 3.5 s): the counted crossing itself
            near = None if kernel is not None or not all_csg else arrays.near_hit(
                o_obj, d_obj, jnp.where(mine & jnp.isfinite(t_counted), t_counted, 0).astype(o.dtype))
            if near is not None:
                t, n = near
                ok = mine & (t > t_min) & (t < t_max) & jnp.isfinite(t)
                return jnp.where(ok, t, jnp.inf), world_normal(n[0], m)[None]
            t, n = _kernel_hits(kernel, arrays, o_obj, d_obj, sub)
            ok = mine & (t > t_min) & (t < t_max) & jnp.isfinite(t)
            n = jax.vmap(lambda v: world_normal(v, m))(n)
            t = jnp.where(ok, t, jnp.inf)
            if not any_csg:
                return t, n
            # an entry per crossing its object counts: the member's crossing nearest it
            c = jnp.argmin(jnp.where(ok, jnp.abs(sg(t) - t_counted), jnp.inf))
            nearest = jnp.full_like(t, jnp.inf).at[0].set(t[c])
            return jnp.where(csg, nearest, t), jnp.where(csg, n.at[0].set(n[c]), n)

        t, n = jax.vmap(one)(*members, t_native)
        if all_csg:
            t, n = t[:, :1], n[:, :1]
        else:
            # no more than a line can cross (a cylinder's kernel has 4 slots, a line crosses it
            # twice): every slot is a pigment request of every shadow ray downstream
            most = max(_line_crossings(shapes[accel.groups[g].group], t.shape[1]) for g in alike)
            if most < t.shape[1]:
                keep = jnp.argsort(sg(t), axis=1)[:, :most]
                t, n = jnp.take_along_axis(t, keep, axis=1), jnp.take_along_axis(n, keep[..., None], axis=1)
        ts.append((t, n))
    width = max(t.shape[1] for t, _ in ts)

    def widen(x, fill):
        pad = [(0, 0)] * x.ndim
        pad[1] = (0, width - x.shape[1])
        return jnp.pad(x, pad, constant_values=fill)

    t = functools.reduce(jnp.minimum, [widen(t, jnp.inf) for t, _ in ts])
    n = sum(jnp.where(jnp.isfinite(widen(ti, jnp.inf))[..., None], widen(ni, 0.0), 0.0) for ti, ni in ts)
    return Crossed(t, accel.item_prim[jnp.maximum(item, 0)], n, count > FILTER_ITEMS)


# ---------------------------------------------------------------- RAYTRACER_ACCEL=jax
def _hierarchy():
    """(build, closest query, any query) of the renders: the native ones, or with
    ``RAYTRACER_ACCEL=jax`` their pure-JAX twins (``_accel_jax``: the same tables, any device)."""
    if mode() == "jax":
        from . import _accel_jax

        return _accel_jax.build, _accel_jax.closest_query, _accel_jax.any_query
    return _build, _closest_query, _any_query
