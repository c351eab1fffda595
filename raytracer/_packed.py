"""The scene packed for the compiled program: its skeleton and its objects as struct-of-arrays
(``Packed``), kept by identity for the next render of the same scene, placed on the devices once,
and keyed by what the program's trace reads of them (``_signature``), so that scenes differing only
in how many objects the hierarchy holds share one program."""

from __future__ import annotations

import functools
import operator
import pickle
import weakref
from typing import NamedTuple

import equinox as eqx
import jax
import numpy as np

from ._gc import without_collections
from ._packing import Frozen, is_traced, keyed, skeleton, with_field
from ._plan import InPrim, Plan, leaf_prims, make_plan
from .scene import Scene
from .shading import _accel
from .shading._geometry import PackedGeometry, hierarchy_filters, pack_geometry, prim_bits
from .shading._materials import PackedMaterials, pack_materials


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
        # reference: a compiled program's cache keeps its key, which must not keep the scene); the
        # key is the same in every process (``_programs`` keeps programs on disk by it)
        key = signature
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
