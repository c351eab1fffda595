"""Scene-level geometry: every primitive of the plan packed by kind, closest hits, CSG visibility,
and shadow transmittance — all for ONE ray (the caller vmaps over rays).

Primitives of one shape class and one static variant (its pytree structure and leaf shapes: an open
cylinder, a polygon's edge list) are stacked into *groups*; a ray is inverse-transformed into each
instance's object space and the shape's own ``hits`` is vmapped over the group. Every shape reports
all ``K`` crossings of the line, so CSG (keep a crossing only where it lies inside/outside the other
operands, semantics §4.2), ``clipped_by`` and filtered shadows (multiply the filter of every crossing,
semantics §2.5) are masks over the same candidates. Every inside question — hit conditions here,
``raytracer.query`` and the SDL's ``inside()`` — is answered by one circuit (``evaluate_inside``).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._packing import EYE4, bucket, inverse_affines, pad_rows, register_packed, stack
from .._plan import InAll, InAny, InDiff, InPrim, InsideTree, Plan, has_box
from ..kernels import matvec, world_normal
from ..shapes import AbstractShape, world_bounds
from ..shapes._base import UNBOUNDED_KERNELS
from . import _accel
from ._accel import Accel


@dataclasses.dataclass(frozen=True)
class Group:
    """Static description of one stacked group of primitives: one shape class and one static
    variant (the shape's pytree structure and leaf shapes), so one ``vmap`` of its kernel."""

    kind: str
    prims: tuple[int, ...]  # indices into plan.prims
    solid: bool  # has an inside test
    accelerated: bool = False  # chosen by the hierarchy (``_accel``), not a candidate of every ray
    csg_member: bool = False  # (accelerated) members of CSG objects the hierarchy holds (``csg_units``)


@dataclasses.dataclass
class PackedGeometry:
    """Arrays of every group (built inside the jit trace from the scene's leaves)."""

    groups: tuple[Group, ...]
    shapes: tuple[AbstractShape, ...]  # per group: the group's shapes stacked along a leading axis
    object_from_world: tuple[jax.Array, ...]  # per group: (n, 4, 4)
    where: dict[int, tuple[int, int]]  # prim -> (group, index in group)
    cand_prim: np.ndarray  # (C,) prim index of every flat candidate (groups not accelerated)
    n_candidates: int
    conditions: CSGConditions | None = None  # None when no hit has CSG / clipping conditions
    bounds: "BoundChecks | None" = None  # None when no candidate has a bound to cross (``bounded_by``)
    accel: Accel | None = None  # the hierarchy of the accelerated groups
    prim_sign: np.ndarray | None = None  # (P,) -1.0 where a primitive's normals are inverted
    # ties between coincident surfaces (semantics §4.4): the bounding unit of every primitive and
    # the world boxes (lo, hi) of the units, (U, 3) each; None when the scene is one unit
    prim_unit: np.ndarray | None = None
    unit_boxes: tuple | None = None
    # what the program looks up at a traced primitive, as arrays of ``bucket(P)`` entries (not
    # constants: a program per object count): "sign" (``prim_sign``), "unit" (``prim_unit``, 0
    # when None), "medium" (``medium_ids``) and "solid" (the primitive's shape has an inside)
    prim_table: dict | None = None
    # per group: the primitive of each member of a padded group (``_padded_to_bucket``) that is an
    # object of its own (``solo_prims``; -1 for the others and past its members), as an array;
    # None for other groups
    member_prims: tuple | None = None


register_packed(PackedGeometry, ("shapes", "object_from_world", "accel", "unit_boxes", "prim_table",
                                 "member_prims"))


# the leaf types of a shape's array fields (tracers are jax.Array instances too; a number set by
# ``eqx.tree_at`` is a leaf as well)
_LEAVES = (np.ndarray, jax.Array, np.generic, float, int)


@functools.cache
def _field_split(cls) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """A shape class's field names: (array fields, static fields)."""
    fields = dataclasses.fields(cls)
    return (tuple(f.name for f in fields if not f.metadata.get("static", False)),
            tuple(f.name for f in fields if f.metadata.get("static", False)))


def _stack(trees, plain: bool = False):
    """The shapes ``trees`` (one variant) stacked along a new leading axis. ``plain``: their
    variant key is a plain one (``_variant``): each array field is stacked as it is, without a
    pytree walk (the flatten of an Equinox module is Python code: 100,000 spheres took it twice,
    1.7 s)."""
    if not plain:
        return jax.tree_util.tree_map(lambda *xs: stack(xs), *trees)
    first = trees[0]
    arrays, _ = _field_split(type(first))
    out = object.__new__(type(first))  # as Equinox's unflatten makes a module: its fields, set
    for name, value in vars(first).items():
        if name in arrays and value is not None:
            value = stack([vars(t)[name] for t in trees])
        object.__setattr__(out, name, value)
    return out


def _variant(shape: AbstractShape) -> tuple:
    """Shapes with equal keys stack into one group: same class, static fields and leaf shapes.
    A shape whose array fields are all arrays or None has a *plain* key, read from its fields:
    ``(class, static values, array shapes)``; any other (a nested pytree) ``(treedef, leaf
    shapes)``."""
    cls = type(shape)
    arrays, static = _field_split(cls)
    values = vars(shape)
    shapes = []
    for name in arrays:
        value = values[name]
        if value is None:
            shapes.append(None)
        elif isinstance(value, _LEAVES):
            shapes.append(np.shape(value))
        else:
            return _walked_variant(shape)
    key = cls, tuple(values[n] for n in static), tuple(shapes)
    try:
        hash(key)
    except TypeError:  # a static value that does not hash (a polygon's edges given as lists)
        return _walked_variant(shape)
    return key


def _walked_variant(shape: AbstractShape) -> tuple:
    leaves, treedef = jax.tree_util.tree_flatten(shape)
    return treedef, tuple(np.shape(x) for x in leaves)


def _accelerable(prim, filter_query: bool, kernels=None) -> bool:
    """Whether the hierarchy may choose this primitive: a native kernel (one of ``kernels`` when
    given: the pure-JAX twin has fewer), bounded, rendered, no CSG or clipping condition. A
    transparent primitive that casts shadows also needs the hierarchy's all-crossings query
    (``filter_query``: the native one); its interior's fade on shadow rays is computed over the
    query's crossings and the candidates' together (``_model._shadow_fade``)."""
    kernel = type(prim.obj.shape).native_kernel
    if kernel is None or kernel in UNBOUNDED_KERNELS or (kernels is not None and kernel not in kernels):
        return False
    if not prim.rendered or prim.conditions or prim.bounds:
        return False
    if prim.transparent and "no_shadow" not in prim.flags:
        return filter_query
    return True


def medium_ids(prims) -> np.ndarray:
    """Primitives whose interior is one record (the children of a CSG given one ``interior``) are
    one medium, named by the first of them: a ray that enters a hollow glass ``difference``
    through its outer sphere leaves it through its inner one. A primitive without an interior is
    a medium of its own (ior 1)."""
    first: dict[int, int] = {}
    return np.array([i if p.interior is None else first.setdefault(id(p.interior), i)
                     for i, p in enumerate(prims)], np.int32)


def visibility_bits(prim) -> int:
    """The ``_accel.MASK_*`` bits of a primitive: seen by camera / reflected rays, blocks (opaque)
    or filters (transparent) shadow rays."""
    if not prim.rendered:
        return 0
    shadow = _accel.MASK_FILTER if prim.transparent else _accel.MASK_SHADOW
    return ((_accel.MASK_CAMERA if "no_image" not in prim.flags else 0)
            | (_accel.MASK_REFLECT if "no_reflection" not in prim.flags else 0)
            | (shadow if "no_shadow" not in prim.flags else 0))


def native_items(shape: AbstractShape) -> int:
    """``shape.n_native_items()`` through the class: a method looked up on an Equinox module
    instance is wrapped in a new module each time (~0.2 ms), which a loop over 10^5 objects feels."""
    return type(shape).n_native_items(shape)


def accelerated_prims(plan: Plan, accelerate: bool | None = None) -> list[bool]:
    """Which primitives the native hierarchy chooses among, as items of their own (see
    ``pack_geometry``)."""
    return hierarchy_choice(plan, accelerate)[0]


def hierarchy_choice(plan: Plan, accelerate: bool | None = None,
                     bits: np.ndarray | None = None) -> tuple[list[bool], tuple[int, ...]]:
    """What the native hierarchy holds: which primitives are items of their own, and which bounding
    units are CSG objects it evaluates (``csg_units``); nothing when they make fewer than
    ``_accel.MIN_ITEMS`` items. ``bits``: ``prim_bits(plan)``, when the caller has them."""
    if accelerate is None:
        accelerate = _accel.mode() != "none"  # native, or its JAX twin (RAYTRACER_ACCEL=jax)
    twin = _accel.mode() == "jax"  # the pure-JAX twin: no all-crossings query, no torus kernel, no CSG
    kernels = _accel.JAX_TWIN_KERNELS if twin else None
    bits = prim_bits(plan) if bits is None else bits
    held = [accelerate and _accelerable(p, not twin, kernels) for p in plan.prims]
    csg = csg_units(plan, bits) if accelerate and not twin else ()
    if csg:
        # a CSG object left with one part and no condition (``difference { A B }`` whose B is
        # left out) is a plain primitive: an item of its own, not a CSG object
        members = _unit_members(plan)
        csg = tuple(u for u in csg if not any(held[i] for i in members[u]))
    in_csg = set(csg)
    filters = [i for i in np.flatnonzero(bits & _accel.MASK_FILTER) if held[i] or plan.prim_unit[i] in in_csg]
    if 0 < sum(native_items(plan.prims[i].obj.shape) for i in filters) < _accel.MIN_FILTER_ITEMS:
        # a few transparent shadow casters: cheaper as candidates than through the all-crossings
        # query, unless their objects have a part the hierarchy's solver finds (``_refines``)
        members = _unit_members(plan)
        costly = {u for u in csg if any(_refines(plan.prims[i].obj.shape) for i in members[u])}
        for i in filters:
            held[i] = held[i] and _refines(plan.prims[i].obj.shape)
        dropped = {plan.prim_unit[i] for i in filters} - costly
        csg = tuple(u for u in csg if u not in dropped)
    items = sum(native_items(p.obj.shape) for p, ok in zip(plan.prims, held, strict=True) if ok) + len(csg)
    # A CSG object pays for the query alone: as candidates, every ray computes each member's
    # crossings and the inside tests of the others at each (a difference of a box and n - 1
    # cylinders on a plane, 160x120: n = 2 / 4 / 12 took 6.4 / 13 / 101 ms warm as candidates, 4.0 /
    # 5.2 / 8.3 ms held, and compiled 0.6-0.8 s faster; incdemo/sundial.pov, 35 members: 0.85 s ->
    # 12 ms). So does a shape whose hit the hierarchy's solver finds (``near_hit``): its JAX search
    # costs every ray ~400 evaluations of a superellipsoid's norm or a polynomial's four brackets;
    # and one whose kernel is costly (a torus's quartic).
    if items < _accel.MIN_ITEMS and not csg and not any(
            _refines(plan.prims[i].obj.shape) or plan.prims[i].obj.shape.costly_kernel
            for i, ok in enumerate(held) if ok):
        return [False] * len(plan.prims), ()
    return held, csg


def _refines(shape: AbstractShape) -> bool:
    """Whether the hierarchy's choice of ``shape`` is refined (``near_hit``) rather than searched
    again by its own kernel."""
    return type(shape).near_hit is not AbstractShape.near_hit


MAX_CSG_HEIGHT = 64  # deeper CSG trees stay candidates (bvh.cc evaluates a tree by recursion)


def _height(tree: InsideTree) -> int:
    return 0 if isinstance(tree, InPrim) else 1 + max(map(_height, tree.terms))


def prim_bits(plan: Plan) -> np.ndarray:
    """(P,) int32: ``visibility_bits`` of every primitive (read-only: kept with the plan, which
    packing, its signature and the trace each ask)."""
    bits = plan.__dict__.get("_prim_bits")
    if bits is None:
        bits = np.array([visibility_bits(p) for p in plan.prims], np.int32)
        bits.flags.writeable = False
        object.__setattr__(plan, "_prim_bits", bits)
    return bits


def _unit_members(plan: Plan) -> dict[int, list[int]]:
    """The primitives of every bounding unit (its CSG parts and clipping objects), in plan order."""
    members: dict[int, list[int]] = {}
    for i, u in enumerate(plan.prim_unit):
        members.setdefault(u, []).append(i)
    return members


def csg_units(plan: Plan, bits: np.ndarray) -> tuple[int, ...]:
    """The bounding units the native hierarchy holds as CSG objects (one item each, its box the
    unit's; bvh.cc evaluates which crossing of a member counts): CSG and clipped objects whose
    primitives all have a native kernel and one item (planes too: the object's box bounds them), a
    finite box (transparent members filter shadows through the all-crossings query, one entry per
    counted crossing) and a tree at most ``MAX_CSG_HEIGHT`` deep.
    ``bits``: ``prim_bits(plan)``. (A part's conditions only name parts
    of its own unit: only a splittable union, which adds no condition, lies above a unit.)"""
    if all(isinstance(tree, InPrim) and not _refines(plan.prims[tree.prim].obj.shape) for tree in plan.units):
        return ()  # no CSG or clipped object (nor a polynomial on its own)
    members = _unit_members(plan)

    def member_ok(i):
        shape = plan.prims[i].obj.shape
        return type(shape).native_kernel is not None and type(shape).n_native_items(shape) == 1

    def boxed(u, tree):
        if has_box(tree, plan.prims):
            return not isinstance(tree, InPrim)
        # an object without a box whose part the hierarchy's solver finds (a polynomial on its
        # own, or clipped by planes and quadrics: objects/quartic/helix.pov) is cheaper there
        # than searched by every ray's JAX kernel: its box is everything (``_accel.UNBOUNDED``)
        return any(_refines(plan.prims[i].obj.shape) for i in members.get(u, []))

    return tuple(u for u, tree in enumerate(plan.units)
                 if boxed(u, tree) and _height(tree) <= MAX_CSG_HEIGHT
                 and all(member_ok(i) for i in members.get(u, [])))


def csg_program(plan: Plan, units: Sequence[int], member_rank: dict[int, int],
                bits: np.ndarray) -> _accel.CsgUnits:
    """The programs of the CSG objects ``units`` (bvh.cc's layout: CSG units), a member written as
    ``-1 - member_rank[prim]`` (``_accel.pack_accel`` numbers the members' items)."""
    members = _unit_members(plan)
    ops = {InAll: 1, InAny: 2, InDiff: 3}
    prog: list[int] = []
    offsets, masks, alive = [], [], []
    for u in units:
        rendered = [i for i in members[u] if plan.prims[i].rendered]
        offsets.append(len(prog))
        prog.append(len(rendered))
        header = len(prog)
        prog.extend([0] * (_accel.MEMBER_INTS * len(rendered)))
        at_node: dict[int, int] = {}

        def node(tree: InsideTree, at_node=at_node) -> int:
            if id(tree) not in at_node:
                if isinstance(tree, InPrim):
                    row = [0, int(tree.inverse), -1 - member_rank[tree.prim], 0]
                else:
                    kids = [node(t, at_node) for t in tree.terms]
                    row = [ops[type(tree)], int(tree.inverse), len(prog), len(kids)]
                    prog.extend(kids)
                    row[2] = len(prog) - len(kids)
                at_node[id(tree)] = len(prog)
                prog.extend(row)
            return at_node[id(tree)]

        for j, i in enumerate(rendered):
            conds = [(node(c.tree), int(c.want)) for c in plan.prims[i].conditions]
            # its bounds (``Prim.bounds``): one primitive of each crossed, else the ray sees none of it
            crossed = 0  # (none: offset 0 is the first unit's count, never a node)
            if plan.prims[i].bounds:
                bounds = plan.prims[i].bounds
                alive.append(InAll(tuple(InAny(tuple(InPrim(b, False) for b in bound)) for bound in bounds)))
                crossed = node(alive[-1])  # (kept alive: ``node`` knows a tree by its id)
            at = header + _accel.MEMBER_INTS * j
            prog[at: at + _accel.MEMBER_INTS] = [-1 - member_rank[i], len(prog), len(conds), crossed]
            for pair in conds:
                prog.extend(pair)
        masks.append(np.bitwise_or.reduce(bits[rendered]) if rendered else 0)
    return _accel.CsgUnits(np.asarray(units, np.int32), np.asarray(prog, np.int32),
                           np.asarray(offsets, np.int32), np.asarray(masks, np.int32))


def pack_geometry(plan: Plan, dtype, accelerate: bool | None = None) -> PackedGeometry:
    """Every primitive of ``plan`` packed by group. ``accelerate``: let the native hierarchy choose
    among the primitives it can (None: when ``_accel.mode()`` is native and there are at least
    ``_accel.MIN_ITEMS`` items)."""
    bits = prim_bits(plan)
    accel_ok, csg = hierarchy_choice(plan, accelerate, bits)
    chosen = set(csg)
    in_csg = [u in chosen for u in plan.prim_unit]
    keyed: dict[tuple, list[int]] = {}
    for i, p in enumerate(plan.prims):
        role = "item" if accel_ok[i] else "csg" if in_csg[i] else "candidate"
        keyed.setdefault((_variant(p.obj.shape), role), []).append(i)
    groups, shapes, ofw, wfo, where, cand_prim = [], [], [], [], {}, []
    for (variant, role), ids in keyed.items():
        members = [plan.prims[i].obj.shape for i in ids]
        k = members[0].n_crossings()
        accelerated = role != "candidate"
        groups.append(Group(members[0].kind, tuple(ids), type(members[0]).solid, accelerated, role == "csg"))
        shapes.append(_stack(members, plain=isinstance(variant[0], type)))
        transforms = [plan.prims[i].world_from_object() for i in ids]
        wfo.append(stack([EYE4 if t is None else t.matrix for t in transforms], dtype))
        ofw.append(inverse_affines(wfo[-1]))
        for j, i in enumerate(ids):
            where[i] = (len(groups) - 1, j)
            if not accelerated:
                cand_prim.extend([i] * k)
    geo = PackedGeometry(tuple(groups), tuple(shapes), tuple(ofw), where,
                         np.asarray(cand_prim, dtype=np.int32), len(cand_prim),
                         prim_sign=np.array([-1.0 if p.inverse else 1.0 for p in plan.prims]))
    if len(plan.units) > 1 or csg:
        boxes = unit_boxes(plan, geo, wfo)
        geo = dataclasses.replace(geo, prim_unit=np.asarray(plan.prim_unit, np.int32),
                                  unit_boxes=tuple(pad_rows(b, bucket(len(plan.units))) for b in boxes))
    accel_groups = [(g, grp.prims) for g, grp in enumerate(groups) if grp.accelerated and not grp.csg_member]
    csg_groups = [(g, grp.prims) for g, grp in enumerate(groups) if grp.csg_member]
    if accel_groups or csg_groups:
        programs = None
        if csg:
            # a member's first row of parameters (a polynomial takes two: ``native_rows``)
            rows = [shapes[g].n_native_rows() for g, ids in csg_groups for _ in ids]
            ids = [int(i) for _, group in csg_groups for i in group]
            rank = dict(zip(ids, np.cumsum([0, *rows[:-1]]).tolist(), strict=True))
            programs = csg_program(plan, csg, rank, bits)
        geo = dataclasses.replace(geo, accel=_accel.pack_accel(
            shapes, ofw, wfo, accel_groups, bits, dtype,
            geo.prim_unit, geo.unit_boxes, programs, csg_groups))
    if plan.effects.csg:
        conditions = build_csg_conditions(geo, plan)
        geo = dataclasses.replace(geo, conditions=conditions if conditions.cand.size else None)
    geo = dataclasses.replace(geo, bounds=build_bound_checks(geo, plan, geo.cand_prim))
    return _padded_to_bucket(geo, plan)


def _padded_to_bucket(geo: PackedGeometry, plan: Plan) -> PackedGeometry:
    """``geo`` with its per-primitive tables (``prim_table``) and the stacks of its hierarchy's
    groups of one-item shapes padded to ``bucket`` sizes (copies of the last member, never named
    by the hierarchy: ``_accel.pack_accel`` pads its own tables). Candidates are not padded: every
    ray computes every candidate. A mesh's group is not either: its size is its triangles'."""
    n = bucket(len(plan.prims))
    unit = geo.prim_unit if geo.prim_unit is not None else np.zeros(len(plan.prims), np.int32)
    solid = np.array([type(p.obj.shape).solid for p in plan.prims], bool)
    table = {"sign": pad_rows(geo.prim_sign, n), "unit": pad_rows(unit, n),
             "medium": pad_rows(medium_ids(plan.prims), n), "solid": pad_rows(solid, n)}
    shapes, ofw = list(geo.shapes), list(geo.object_from_world)
    members: list = [None] * len(geo.groups)
    solo = solo_prims(plan)
    for g, group in enumerate(geo.groups):
        if padded_group(geo, g):
            size = bucket(len(group.prims))
            shapes[g] = jax.tree_util.tree_map(lambda x, size=size: pad_rows(x, size), shapes[g])
            ofw[g] = pad_rows(ofw[g], size)
            if not group.csg_member:  # (a CSG member's object is a tree: the inside circuit's)
                own = np.fromiter((i if i in solo else -1 for i in group.prims), np.int32, len(group.prims))
                members[g] = pad_rows(own, size, -1)
    return dataclasses.replace(geo, shapes=tuple(shapes), object_from_world=tuple(ofw), prim_table=table,
                               member_prims=tuple(members))


def hierarchy_filters(geo: PackedGeometry, plan: Plan) -> tuple[bool, bool, int]:
    """Whether the hierarchy holds transparent shadow-casting items (``MASK_FILTER``: its groups'
    ``filters``), whether some of them have an interior that fades, and the most texture layers
    one of them has (a primitive's present layers are its first ones)."""
    if geo.accel is None:
        return False, False, 0
    groups = [ag for ag in geo.accel.groups if ag.filters]
    bits = prim_bits(plan)
    filtering = [i for ag in groups for i in geo.groups[ag.group].prims if bits[i] & _accel.MASK_FILTER]
    fades = any(plan.prims[i].fades for i in filtering)
    layers = max((len(plan.prims[i].texture.layers) for i in filtering), default=0)
    return bool(groups), fades, layers


def solo_prims(plan: Plan) -> set[int]:
    """The primitives that are objects of their own (their object's inside tree is theirs alone;
    not a union's child): ``initial_media`` tests those of the padded groups as arrays."""
    return {tree.prim for tree in plan.roots if isinstance(tree, InPrim)}


def padded_group(geo: PackedGeometry, g: int) -> bool:
    """Whether group ``g``'s stack is padded to a bucket: a group of one-item shapes the hierarchy
    holds (as objects of their own, or as members of CSG objects)."""
    one_item = type(geo.shapes[g]).n_native_items is AbstractShape.n_native_items
    return geo.groups[g].accelerated and one_item


_world_bounds = jax.jit(jax.vmap(world_bounds))  # one program per group signature, not one per op
_NUMPY_BOUNDS_MAX = 256  # concrete groups up to this size: a numpy loop (no compile at all)


def _group_bounds(shapes, mats):
    """World boxes (lo, hi) (n, 3) of a stacked group (no gradient). A small group of concrete
    values is a loop of numpy ``world_bounds`` (a compiled program would cost ~0.3 s of a cold
    start); a large or traced one is one jitted vmap."""
    leaves = jax.tree_util.tree_leaves((shapes, mats))
    n = mats.shape[0]
    concrete = all(isinstance(x, np.ndarray) for x in leaves)
    if n <= _NUMPY_BOUNDS_MAX and concrete:
        boxes = [world_bounds(jax.tree_util.tree_map(lambda a, j=j: a[j], shapes), mats[j]) for j in range(n)]
        return np.stack([b[0] for b in boxes]), np.stack([b[1] for b in boxes])
    lo, hi = _world_bounds(jax.lax.stop_gradient(shapes), jax.lax.stop_gradient(mats))
    # concrete boxes stay numpy: the CSG circuit over them is then numpy too, not one dispatch per op
    return (np.asarray(lo), np.asarray(hi)) if concrete else (lo, hi)


def unit_boxes(plan: Plan, geo: PackedGeometry, world_from_object) -> tuple:
    """World boxes ``(lo, hi)`` (U, 3) of the plan's bounding units as POV-Ray bounds them
    (semantics §4.4): a primitive's box is its shape's ``bounds()`` carried to the world
    (``world_from_object``: per group, (n, 4, 4)) and grown by ``pov_bounds_margin`` (±inf where
    unbounded); a union or merge holds its parts' boxes, an intersection (and a clipped object)
    the overlap of their parts that are not inverted, a difference its first part's box; ``inverse``
    changes nothing else (an inverted object's own box is its box). The hierarchy also culls by them
    (a CSG object it holds is seen only in its box, as in POV-Ray). No gradient flows. One
    vectorised step per group and per height of the CSG units' inside circuit, not one per object;
    numpy when every box is concrete (no JAX dispatch: a cold start compiles nothing here), jnp
    otherwise."""
    boxes = [None if plan.prims[g.prims[0]].obj.shape.bounds() is None else _group_bounds(shapes, mats)
             for g, shapes, mats in zip(geo.groups, geo.shapes, world_from_object, strict=True)]
    xp = np if all(b is None or isinstance(b[0], np.ndarray) for b in boxes) else jnp
    los, his = [], []
    for group, box in zip(geo.groups, boxes, strict=True):
        n = len(group.prims)
        if box is None:
            lo, hi = xp.full((n, 3), -np.inf), xp.full((n, 3), np.inf)
        else:
            margin = type(plan.prims[group.prims[0]].obj.shape).pov_bounds_margin
            lo, hi = xp.asarray(box[0]) - margin, xp.asarray(box[1]) + margin
        los.append(lo)
        his.append(hi)
    flat = np.cumsum([0] + [len(g.prims) for g in geo.groups])
    row = np.array([flat[g] + j for g, j in (geo.where[i] for i in range(len(plan.prims)))])
    prim_lo, prim_hi = xp.concatenate(los)[row], xp.concatenate(his)[row]
    # a unit of one primitive is one row of a gather; CSG units go through their inside circuit,
    # with boxes for values: an "all" node is the overlap of its children, an "any" node their
    # hull, a negated child (the subtracted parts of a difference) the whole space
    single = np.array([isinstance(u, InPrim) for u in plan.units])
    first = np.array([u.prim if isinstance(u, InPrim) else 0 for u in plan.units], np.int64)
    lo, hi = prim_lo[first], prim_hi[first]
    csg = np.flatnonzero(~single)
    if csg.size:
        circuit = build_inside_circuit([(plan.units[u], 0) for u in csg])
        inf = np.full((1, 3), np.inf)
        vlo = xp.concatenate([inf, -inf, prim_lo[circuit.leaf_prim]])  # False: empty, True: all
        vhi = xp.concatenate([-inf, inf, prim_hi[circuit.leaf_prim]])
        inverted = np.zeros(2 + circuit.leaf_prim.shape[0], bool)  # static: which nodes are inverse
        for is_all, children, negate, inverse in circuit.levels:
            # an intersection (and so a difference) is bounded by its parts that are not inverted
            skip = (negate | (inverted[children] & is_all[:, None]))[..., None]
            klo = xp.where(skip, -np.inf, vlo[children])
            khi = xp.where(skip, np.inf, vhi[children])
            inverted = np.concatenate([inverted, inverse])
            a = is_all[:, None]
            vlo = xp.concatenate([vlo, xp.where(a, klo.max(axis=1), klo.min(axis=1))])
            vhi = xp.concatenate([vhi, xp.where(a, khi.min(axis=1), khi.max(axis=1))])
        if xp is np:
            lo, hi = lo.copy(), hi.copy()
            lo[csg], hi[csg] = vlo[circuit.roots], vhi[circuit.roots]
        else:
            lo, hi = lo.at[csg].set(vlo[circuit.roots]), hi.at[csg].set(vhi[circuit.roots])
    dtype = geo.object_from_world[0].dtype
    return lo.astype(dtype), hi.astype(dtype)


def box_entry(lo, hi, o, d):
    """Where the line ``o + t d`` enters the box ``[lo, hi]`` (``-inf`` for an unbounded box),
    or ``+inf`` when it misses it."""
    moving = d != 0
    safe_d = jnp.where(moving, d, 1.0)
    t1, t2 = (lo - o) / safe_d, (hi - o) / safe_d
    within = (o >= lo) & (o <= hi)
    near = jnp.where(moving, jnp.minimum(t1, t2), jnp.where(within, -jnp.inf, jnp.inf))
    far = jnp.where(moving, jnp.maximum(t1, t2), jnp.where(within, jnp.inf, -jnp.inf))
    t_near, t_far = near.max(), far.min()
    return jnp.where(t_near <= t_far, t_near, jnp.inf)


def _to_object(m, o, d):
    return matvec(m[:3, :3], o) + m[:3, 3], matvec(m[:3, :3], d)


def _culled(one, shapes, ofw, o, d, count: int):
    """``one`` (a member's crossings) for the ``count`` members of a group whose bounds the ray
    enters first, +inf slots for the others: a costly kernel (an isosurface's march) paid for
    ``count`` members a ray, not for every member (``AbstractShape.cull_to``)."""
    def entry(shape, ofw_i):
        oo, dd = _to_object(ofw_i, o, d)
        return shape.entry(oo, dd)

    t_entry = jax.lax.stop_gradient(jax.vmap(entry)(shapes, ofw))
    _, nearest = jax.lax.top_k(-t_entry, count)
    picked = jax.tree_util.tree_map(lambda a: jnp.asarray(a)[nearest], shapes)
    t, n = jax.vmap(one)(picked, jnp.asarray(ofw)[nearest])
    missed = ~jnp.isfinite(t_entry[nearest])[:, None]
    t = jnp.where(missed, jnp.inf, t)
    full_t = jnp.full((ofw.shape[0],) + t.shape[1:], jnp.inf, t.dtype).at[nearest].set(t)
    full_n = jnp.zeros((ofw.shape[0],) + n.shape[1:], n.dtype).at[nearest].set(n)
    return full_t, full_n


def all_crossings(geo: PackedGeometry, o, d, members=None, world: bool = True):
    """Every crossing of the ray with every primitive not in the hierarchy, or with the members
    ``members`` (per group, an index array: a :class:`CandidateView`'s) only.

    Returns:
        t: (C,) ray parameters (world units of ``|d|``), +inf where a slot is empty.
        n: (C, 3) unit outward world normals (``inverse`` not applied); with ``world`` False the
           object's normals as its kernel gives them, and a third array (C, 3, 3), each slot's
           ``object_from_world`` (not per ray): ``world_normal(n[c], m[c])`` is slot c's world
           normal, for a query that needs one slot's normal (the closest hit), not every slot's
           (whitted.pov's refined pixels: the transforms and normalisations of every crossing of
           its two spheres were 1.5 ms of a 4.8 ms call).
    """
    ts, ns, ms = [jnp.zeros(0, o.dtype)], [jnp.zeros((0, 3), o.dtype)], [jnp.zeros((0, 3, 3), o.dtype)]
    for g, (group, shapes, ofw) in enumerate(zip(geo.groups, geo.shapes, geo.object_from_world, strict=True)):
        if group.accelerated:
            continue
        if members is not None and members[g].size < len(group.prims):
            if not members[g].size:
                continue
            shapes = jax.tree_util.tree_map(lambda a, idx=members[g]: a[idx], shapes)
            ofw = ofw[members[g]]

        def one(shape, ofw_i):
            oo, dd = _to_object(ofw_i, o, d)
            t, n = shape.hits(oo, dd)
            return t, (world_normal(n, ofw_i) if world else n)

        cull = type(shapes).cull_to
        if cull is not None and ofw.shape[0] > cull:
            t, n = _culled(one, shapes, ofw, o, d, cull)
        else:
            t, n = jax.vmap(one)(shapes, ofw)
        ts.append(t.reshape(-1))
        ns.append(n.reshape(-1, 3))
        if not world:
            ms.append(jnp.repeat(ofw[:, :3, :3], t.shape[-1], axis=0))
    joined = jnp.concatenate(ts), jnp.concatenate(ns)
    return joined if world else (*joined, jnp.concatenate(ms))


@dataclasses.dataclass(frozen=True)
class CandidateView:
    """Some primitives' candidate slots (whole members of the groups not accelerated) and the CSG
    conditions of those slots: what a query that ignores the other primitives computes (shadow
    rays skip ``no_shadow`` objects without computing their crossings). Inside tests of a kept
    slot's conditions still reach every primitive of its CSG tree.

    members:    per group, the indices of its kept members (empty for an accelerated group).
    cand_prim:  (C',) the primitive of each slot, in ``all_crossings(…, members)`` order.
    conditions: the slots' CSG conditions, or None (no kept slot has any).
    bounds:     the slots' bounds to cross, or None (no kept slot has any).
    """

    members: tuple
    cand_prim: np.ndarray
    conditions: CSGConditions | None
    bounds: "BoundChecks | None" = None


def candidate_view(geo: PackedGeometry, plan: Plan, keep) -> CandidateView:
    """The view of the primitives ``i`` with ``keep(i)``."""
    members, cand_prim = [], []
    for g in geo.groups:
        if g.accelerated:
            members.append(np.zeros(0, np.int32))
            continue
        k = int(np.count_nonzero(geo.cand_prim == g.prims[0]))  # slots per member
        kept = [j for j, i in enumerate(g.prims) if keep(i)]
        members.append(np.asarray(kept, np.int32))
        cand_prim.extend(g.prims[j] for j in kept for _ in range(k))
    cand_prim = np.asarray(cand_prim, np.int32)
    conditions = build_csg_conditions(geo, plan, cand_prim) if geo.conditions is not None else None
    if conditions is not None and not conditions.cand.size:
        conditions = None
    return CandidateView(tuple(members), cand_prim, conditions, build_bound_checks(geo, plan, cand_prim))


@dataclasses.dataclass(frozen=True)
class InsideCircuit:
    """Inside trees instantiated at points, as one flat boolean circuit: the ONE evaluation of CSG
    inside tests (hit conditions of the renderer, ``inside()`` / ``trace()`` at parse time).

    Node values live in one array: two constants (False, True), then the leaves (an inside test of
    primitive ``leaf_prim`` at point ``leaf_point``), then internal nodes, grouped by height so each
    height is one gather-and-reduce. ``difference`` is rewritten as ``all(first, not rest…)``. The
    trace size grows with the circuit's height, not with the number of trees.
    """

    leaf_point: np.ndarray  # (L,) point index of each leaf
    leaf_prim: np.ndarray  # (L,) primitive of each leaf
    levels: tuple  # per height: (is_all (n,), children (n, A), negate (n, A), inverse (n,))
    roots: np.ndarray  # (Q,) node id of each instantiated tree


def build_inside_circuit(trees: Sequence[tuple[InsideTree, int]]) -> InsideCircuit:
    """The circuit of ``(tree, point index)`` pairs, roots in the order given."""
    leaves: list[tuple[int, int]] = []
    internal: list[tuple[int, bool, list[tuple[int, bool]], bool]] = []  # (height, all, kids, inv)

    def instantiate(tree: InsideTree, point: int) -> tuple[int, int]:
        """(node ref, height); refs < 0 are leaves (-1 - leaf index), refs >= 0 internal."""
        if isinstance(tree, InPrim):
            leaves.append((point, tree.prim))
            ref = -len(leaves)
            if not tree.inverse:
                return ref, 0
            internal.append((1, True, [(ref, False)], True))
            return len(internal) - 1, 1
        kids = [instantiate(t, point) for t in tree.terms]
        height = 1 + max(h for _, h in kids)
        if isinstance(tree, InDiff):
            children = [(kids[0][0], False)] + [(r, True) for r, _ in kids[1:]]
            is_all = True
        else:
            children = [(r, False) for r, _ in kids]
            is_all = isinstance(tree, InAll)
        internal.append((height, is_all, children, tree.inverse))
        return len(internal) - 1, height

    root_refs = [instantiate(tree, point)[0] for tree, point in trees]
    # node ids: 0 False, 1 True, 2.. leaves, then internal nodes by height
    order = sorted(range(len(internal)), key=lambda i: internal[i][0])
    node_id = {i: 2 + len(leaves) + rank for rank, i in enumerate(order)}

    def ref_id(ref: int) -> int:
        return 2 + (-ref - 1) if ref < 0 else node_id[ref]

    levels = []
    for h in sorted({internal[i][0] for i in order}):
        nodes = [i for i in order if internal[i][0] == h]
        arity = max(len(internal[i][2]) for i in nodes)
        children = np.zeros((len(nodes), arity), np.int32)
        negate = np.zeros((len(nodes), arity), bool)
        for row, i in enumerate(nodes):
            kids = internal[i][2]
            pad = 1 if internal[i][1] else 0  # True pads an "all", False pads an "any"
            children[row] = [ref_id(r) for r, _ in kids] + [pad] * (arity - len(kids))
            negate[row] = [neg for _, neg in kids] + [False] * (arity - len(kids))
        levels.append((np.array([internal[i][1] for i in nodes]), children, negate,
                       np.array([internal[i][3] for i in nodes])))
    return InsideCircuit(
        leaf_point=np.array([c for c, _ in leaves], np.int32),
        leaf_prim=np.array([q for _, q in leaves], np.int32),
        levels=tuple(levels),
        roots=np.array([ref_id(r) for r in root_refs], np.int32))


def _leaf_rows(geo: PackedGeometry, circuit: InsideCircuit):
    """Per group with an inside test and leaves in ``circuit``: ``(g, rows, local)``, the leaves'
    rows and their members' indices in the group (triangles, polygons, meshes have no inside: their
    leaves stay False)."""
    for g, group in enumerate(geo.groups):
        rows = np.flatnonzero(np.isin(circuit.leaf_prim, np.asarray(group.prims)))
        if group.solid and rows.size:
            yield g, rows, np.array([geo.where[int(q)][1] for q in circuit.leaf_prim[rows]], np.int32)


def _leaf_values(geo: PackedGeometry, circuit: InsideCircuit, points):
    """Inside tests of every leaf (primitive's own ``inverse`` excluded), vectorised per group."""
    values = jnp.zeros(circuit.leaf_prim.shape[0], bool)
    for g, rows, local in _leaf_rows(geo, circuit):
        members = jax.tree_util.tree_map(lambda a, local=local: a[local], geo.shapes[g])
        m = geo.object_from_world[g][local]
        obj_pts = jnp.einsum("nij,nj->ni", m[:, :3, :3], points[circuit.leaf_point[rows]]) + m[:, :3, 3]
        values = values.at[rows].set(jax.vmap(lambda s, p: s.inside(p))(members, obj_pts))
    return values


def leaf_values_of(geo: PackedGeometry, circuit: InsideCircuit, inside_of) -> jax.Array:
    """The leaves' inside tests read from ``inside_of(g)``: (n,) bool, group ``g``'s members'
    inside tests (their own ``inverse`` excluded) at the circuit's only point, computed once."""
    values = jnp.zeros(circuit.leaf_prim.shape[0], bool)
    for g, rows, local in _leaf_rows(geo, circuit):
        values = values.at[rows].set(inside_of(g)[local])
    return values


def evaluate_inside(geo: PackedGeometry, circuit: InsideCircuit, points, leaf_values=None) -> jax.Array:
    """(Q,) bool: each root tree of ``circuit`` evaluated at its point of ``points`` (P, 3); its
    leaves' tests ``leaf_values`` where given (``leaf_values_of``)."""
    if leaf_values is None:
        leaf_values = _leaf_values(geo, circuit, points)
    values = jnp.concatenate([jnp.array([False, True]), leaf_values])
    for is_all, children, negate, inverse in circuit.levels:
        kid = values[children] != jnp.asarray(negate)
        v = jnp.where(jnp.asarray(is_all), jnp.all(kid, axis=1), jnp.any(kid, axis=1))
        values = jnp.concatenate([values, v != jnp.asarray(inverse)])
    return values[circuit.roots]


@dataclasses.dataclass(frozen=True)
class CSGConditions:
    """The CSG / clipping conditions of every candidate slot: condition q holds when its tree,
    evaluated at candidate ``cand[q]``'s point, is ``want[q]`` (inside wanted or outside)."""

    circuit: InsideCircuit
    cand: np.ndarray  # (Q,) candidate slot of each condition
    want: np.ndarray  # (Q,) bool


def build_csg_conditions(geo: PackedGeometry, plan: Plan, cand_prim=None) -> CSGConditions:
    """The conditions of the candidate slots ``cand_prim`` (default: all of ``geo``'s)."""
    trees, cand, want = [], [], []
    for c, prim in enumerate(geo.cand_prim if cand_prim is None else cand_prim):
        for cond in plan.prims[int(prim)].conditions:
            trees.append((cond.tree, c))
            cand.append(c)
            want.append(cond.want)
    return CSGConditions(build_inside_circuit(trees), np.array(cand, np.int32), np.array(want, bool))


def csg_mask(geo: PackedGeometry, conds: CSGConditions | None, o, d, t):
    """(C,) bool: crossings that satisfy their primitive's CSG / clipping conditions ``conds``
    (``geo.conditions``, or a :class:`CandidateView`'s)."""
    if conds is None:
        return jnp.ones(t.shape, bool)
    safe_t = jnp.where(jnp.isfinite(t), t, 0.0)
    points = o[None, :] + safe_t[:, None] * d[None, :]
    failed = evaluate_inside(geo, conds.circuit, points) != jnp.asarray(conds.want)
    bad = jnp.zeros(t.shape, bool).at[conds.cand].max(failed)
    return ~bad


@dataclasses.dataclass(frozen=True)
class BoundChecks:
    """POV-Ray's ``bounded_by`` for candidate slots (``Prim.bounds``): a slot's crossings count
    only if the ray crosses a primitive of each of its bounds beyond ``t_min``. The bounds'
    primitives (never rendered, so never held by the hierarchy) are crossed by ``all_crossings``
    with ``members``; slot ``j`` of that is bound primitive ``slot_prim[j]``; bound ``set_of[m]``
    holds bound primitive ``set_prim[m]``; candidate slot ``cand[q]`` needs bound ``cand_set[q]``."""

    members: tuple
    slot_prim: np.ndarray
    set_prim: np.ndarray
    set_of: np.ndarray
    cand: np.ndarray
    cand_set: np.ndarray
    n_prims: int
    n_sets: int


def build_bound_checks(geo: PackedGeometry, plan: Plan, cand_prim) -> BoundChecks | None:
    """The bounds the candidate slots ``cand_prim`` need crossed, or None if none needs any."""
    sets: dict[tuple[int, ...], int] = {}
    cand, cand_set = [], []
    for c, prim in enumerate(cand_prim):
        for bound in plan.prims[int(prim)].bounds:
            cand.append(c)
            cand_set.append(sets.setdefault(bound, len(sets)))
    if not cand:
        return None
    needed = set().union(*sets)
    members, slot_prim, index = [], [], {}
    for g in geo.groups:
        kept = [] if g.accelerated else [j for j, i in enumerate(g.prims) if i in needed]
        k = int(np.count_nonzero(geo.cand_prim == g.prims[0])) if kept else 0  # slots per member
        for j in kept:
            slot_prim.extend([index.setdefault(g.prims[j], len(index))] * k)
        members.append(np.asarray(kept, np.int32))
    set_prim, set_of = [], []
    for bound, s in sets.items():
        for i in bound:
            if i in index:
                set_prim.append(index[i])
                set_of.append(s)
    as_int = functools.partial(np.asarray, dtype=np.int32)
    return BoundChecks(tuple(members), as_int(slot_prim), as_int(set_prim), as_int(set_of), as_int(cand),
                       as_int(cand_set), len(index), len(sets))


def bound_mask(geo: PackedGeometry, checks: BoundChecks | None, o, d, t_min, n_slots: int):
    """(n_slots,) bool: candidate slots whose bounds (``checks``) the ray crosses beyond ``t_min``."""
    if checks is None:
        return jnp.ones(n_slots, bool)
    t, _ = all_crossings(geo, jax.lax.stop_gradient(o), jax.lax.stop_gradient(d), checks.members)
    crossed = jnp.zeros(checks.n_prims, bool).at[checks.slot_prim].max(jnp.isfinite(t) & (t > t_min))
    # a bound none of whose primitives is a candidate (held by the hierarchy) counts as crossed
    held = np.setdiff1d(np.arange(checks.n_sets), checks.set_of)
    ok = jnp.zeros(checks.n_sets, bool).at[checks.set_of].max(crossed[checks.set_prim]).at[held].set(True)
    return ~jnp.zeros(n_slots, bool).at[checks.cand].max(~ok[checks.cand_set])


def static_prim_mask(geo: PackedGeometry, predicate) -> np.ndarray:
    """(C,) numpy bool: ``predicate(prim_index)`` for every candidate slot."""
    return np.array([bool(predicate(int(i))) for i in geo.cand_prim], dtype=bool)


@dataclasses.dataclass
class Hit:
    """The closest accepted crossing of one ray."""

    found: jax.Array  # bool
    t: jax.Array  # ray parameter (0 where not found)
    prim: jax.Array  # int32 primitive index (0 where not found)
    normal: jax.Array  # (3,) unit outward world normal with ``inverse`` applied
    # (3,) the hit point computed near the surface (``closest_hit(…, refine=True)``), or None: ``o + t d``
    point: jax.Array | None = None
    # int32: the item hit within its primitive (a mesh's triangle; for a shape of one item, the
    # crossing slot or 0: ``AbstractShape.sub_hits`` and ``item_margin`` do not read it)
    sub: jax.Array | None = None


# crossings within this many machine epsilons of the nearest (relative) are one surface: float32
# kernels of two shapes differ by a few ulps where POV-Ray's float64 ones tie exactly (§4.4)
TIE_EPSILONS = 64


def _closest(geo: PackedGeometry, tt, prim, o, d):
    """Which of the crossings ``tt`` (of primitives ``prim``) POV-Ray's test order shows
    (semantics §4.4): the nearest; among crossings tied with it, the nearest of the unit whose box
    the ray enters first, else of the earlier unit in the scene. Decides between the first two
    tied units (as the native hierarchy's closest-hit query, ``bvh.cc``)."""
    if geo.unit_boxes is None:
        return jnp.argmin(tt)
    tmin = tt.min()
    tied = tt <= tmin + jnp.abs(tmin) * (TIE_EPSILONS * jnp.finfo(tt.dtype).eps)
    unit = jnp.asarray(geo.prim_table["unit"])[prim]
    last = np.int32(np.iinfo(np.int32).max)
    u1 = jnp.where(tied, unit, last).min()
    u2 = jnp.where(tied & (unit != u1), unit, last).min()
    c1 = jnp.argmin(jnp.where(unit == u1, tt, jnp.inf))
    c2 = jnp.argmin(jnp.where(unit == u2, tt, jnp.inf))
    lo, hi = (jnp.asarray(b) for b in geo.unit_boxes)  # (numpy when a query closes over them)
    o, d = jax.lax.stop_gradient(o), jax.lax.stop_gradient(d)
    k1, k2 = jnp.minimum(u1, lo.shape[0] - 1), jnp.minimum(u2, lo.shape[0] - 1)
    e1, e2 = box_entry(lo[k1], hi[k1], o, d), box_entry(lo[k2], hi[k2], o, d)
    return jnp.where((u2 < last) & (e2 < e1), c2, c1)


def candidate_crossings(geo: PackedGeometry, o, d, t_min, visible: jax.Array):
    """``all_crossings(…, world=False)`` of the candidates, ``t`` set to inf where a crossing does
    not count: not beyond ``t_min``, past ``T_MAX``, of a slot not ``visible``, outside its CSG or
    clipping conditions or its bounds."""
    t, n, slot_ofw = all_crossings(geo, o, d, world=False)
    ok = visible & (t > t_min) & jnp.isfinite(t) & (t < _accel.T_MAX)
    ok = ok & csg_mask(geo, geo.conditions, o, d, t)
    ok = ok & bound_mask(geo, geo.bounds, o, d, t_min, t.shape[0])
    return jnp.where(ok, t, jnp.inf), n, slot_ofw


def closest_hit(geo: PackedGeometry, plan: Plan, o, d, t_min, visible: jax.Array, want=None,
                refine: bool = False) -> Hit:
    """Closest crossing with ``t > t_min`` among candidates where ``visible`` (C,) holds and
    accelerated primitives with the visibility bit ``want`` (``_accel.MASK_*``, traced or not).
    Exact ties between coincident surfaces go as POV-Ray's (``_closest``).

    With ``refine`` (static) the hit point is computed again near the surface (``Hit.point``): the
    chosen primitive's kernel from ``o + t d`` along ``d``, its crossing nearest there. ``o + t d``
    itself is only as exact as ``eps · max(|o|, t)``: a float32 camera 500 units from a checker
    plane rounds the point 3e-5 off the plane, past a face the pattern must decide on; from a start
    on the surface the kernel's point is exact to ``eps · |p|``. A primitive is refined where it
    has a discrete pattern (``Prim.discrete``), at one more evaluation of its kernel per group that
    has one. Values and derivatives are those of ``o + t d`` (the start's ``t`` is held fixed: the
    kernel's crossing from there is the same function of the scene)."""
    ts, ns, prims, subs = [], [], [], []
    if geo.n_candidates:
        # the object's normals: the closest slot's alone is made a world normal, below
        t, n, slot_ofw = candidate_crossings(geo, o, d, t_min, visible)
        ts.append(t)
        ns.append(n)
        prims.append(jnp.asarray(geo.cand_prim))
        subs.append(jnp.asarray(_slot_in_prim(geo.cand_prim)))
    if geo.accel is not None:
        found, t, prim, n, sub = _accel.closest(geo.accel, geo.shapes, geo.object_from_world, o, d, t_min,
                                                _accel.MASK_CAMERA if want is None else want)
        ts.append(jnp.where(found, t, jnp.inf)[None])
        ns.append(n[None])
        prims.append(jnp.asarray(prim, jnp.int32)[None])
        subs.append(sub[None])
    if not ts:  # nothing to hit
        ts, ns = [jnp.full(1, jnp.inf, o.dtype)], [jnp.zeros((1, 3), o.dtype)]
        prims, subs = [jnp.zeros(1, jnp.int32)], [jnp.zeros(1, jnp.int32)]
    join = (lambda xs: xs[0]) if len(ts) == 1 else jnp.concatenate
    tt, nn, pp, ss = join(ts), join(ns), join(prims), join(subs)
    c = _closest(geo, tt, pp, o, d)
    best_t, best_n, best_prim, best_sub = tt[c], nn[c], pp[c], ss[c]
    if geo.n_candidates:
        slots = slot_ofw.shape[0]
        own = world_normal(nn[jnp.minimum(c, slots - 1)], slot_ofw[jnp.minimum(c, slots - 1)])
        best_n = own if len(ts) == 1 else jnp.where(c < slots, own, best_n)
    found = jnp.isfinite(best_t)
    normal = best_n * jnp.asarray(geo.prim_table["sign"], best_n.dtype)[best_prim]
    best_t = jnp.where(found, best_t, 0.0)
    point = _refined_point(geo, plan, o, d, best_t, best_prim) if refine else None
    return Hit(found, best_t, best_prim, normal, point, best_sub)


def _slot_in_prim(cand_prim: np.ndarray) -> np.ndarray:
    """(C,) each candidate slot's place among its primitive's slots (a mesh's slot k is its
    triangle k: one crossing slot per triangle)."""
    cand_prim = np.asarray(cand_prim)
    if cand_prim.size == 0:
        return np.zeros(0, np.int32)
    start = np.r_[True, cand_prim[1:] != cand_prim[:-1]]
    first = np.maximum.accumulate(np.where(start, np.arange(cand_prim.size), 0))
    return (np.arange(cand_prim.size) - first).astype(np.int32)


def _refined_point(geo: PackedGeometry, plan: Plan, o, d, t, prim):
    """The hit point of primitive ``prim`` at ``t``, computed again by its kernel from ``o + t d``
    (``closest_hit``'s ``refine``) where its group has a discrete pattern; ``o + t d`` elsewhere
    (and for a mesh in the hierarchy, whose kernel would compute all of its triangles)."""
    sg = jax.lax.stop_gradient
    per_item = {} if geo.accel is None else {ag.group: ag.per_member for ag in geo.accel.groups}
    refined = [g for g, group in enumerate(geo.groups)
               if per_item.get(g, 1) == 1 and any(plan.prims[i].discrete for i in group.prims)]
    if not refined:
        return o + t * d
    n_prims = len(plan.prims)
    group_of = np.full(n_prims, -1, np.int32)
    member_of = np.zeros(n_prims, np.int32)
    for i, (g, k) in geo.where.items():
        group_of[i], member_of[i] = g, k
    group, member = jnp.asarray(group_of)[prim], jnp.asarray(member_of)[prim]
    mine = jnp.isin(group, np.asarray(refined, np.int32))
    start = jnp.where(mine, sg(t), t)  # a refined hit's derivatives come through its kernel below
    origin = o + start * d
    rest = jnp.zeros((), o.dtype)
    for g in refined:
        k = jnp.where(group == g, member, 0)
        shape = jax.tree_util.tree_map(lambda a, k=k: a[k], geo.shapes[g])
        oo, dd = _to_object(geo.object_from_world[g][k], origin, d)
        near = shape.near_hit(oo, dd, jnp.zeros((), o.dtype))
        tk = (near if near is not None else shape.hits(oo, dd))[0]
        nearest = jnp.argmin(jnp.where(jnp.isfinite(tk), jnp.abs(tk), jnp.inf))
        ok = (group == g) & jnp.isfinite(tk[nearest])
        rest = jnp.where(ok, jnp.where(ok, tk[nearest], 0.0), rest)
    return origin + rest * d
