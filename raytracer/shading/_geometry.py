"""Scene-level geometry: every primitive of the plan packed by kind, closest hits, CSG visibility,
and shadow transmittance — all for ONE ray (the caller vmaps over rays).

Primitives of one kind (and one static variant, e.g. open or closed cylinders) are stacked into
struct-of-arrays *groups*; a ray is inverse-transformed into each instance's object space and the
kind's kernel is vmapped over the instances. Every kernel reports all ``K`` crossings of the line,
so CSG (keep a crossing only where it lies inside/outside the other operands, reference §4.2),
``clipped_by`` and filtered shadows (multiply the filter of every crossing, §2.5) are masks over
the same candidates.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .. import kernels as K
from .._plan import InAll, InDiff, InPrim, InsideTree, Plan
from ..scene._transform import inverse_affine


@dataclasses.dataclass(frozen=True)
class KindSpec:
    """How to call the kernels of one primitive kind."""

    params: Callable  # shape -> tuple of arrays
    hits: Callable  # (*params, o, d) -> (t (K,), n (K, 3))
    inside: Callable | None  # (*params, p) -> bool
    static: Callable = lambda shape: ()  # shape -> hashable static variant key


def _mesh_hits(triangles, normals, o, d):
    if normals is None:
        t, n = jax.vmap(lambda tri: K.triangle_hits(tri[0], tri[1], tri[2], o, d))(triangles)
    else:
        t, n = jax.vmap(lambda tri, nn: K.smooth_triangle_hits(tri[0], tri[1], tri[2], nn[0], nn[1],
                                                               nn[2], o, d))(triangles, normals)
    return t[:, 0], n[:, 0]


KINDS: dict[str, KindSpec] = {
    "sphere": KindSpec(lambda s: (s.center, s.radius), K.sphere_hits, K.sphere_inside),
    "plane": KindSpec(lambda s: (s.normal, s.distance), K.plane_hits, K.plane_inside),
    "box": KindSpec(lambda s: (s.corner1, s.corner2), K.box_hits, K.box_inside),
    "cylinder": KindSpec(
        lambda s: (s.base, s.cap, s.radius),
        None, None, static=lambda s: (s.open,)),
    "cone": KindSpec(
        lambda s: (s.base, s.base_radius, s.cap, s.cap_radius),
        None, None, static=lambda s: (s.open,)),
    "quadric": KindSpec(lambda s: (s.coeffs,), K.quadric_hits, K.quadric_inside),
    "torus": KindSpec(lambda s: (s.major, s.minor), lambda *a: K.torus_hits(*a),
                      lambda *a: K.torus_inside(*a)),
    "disc": KindSpec(lambda s: (s.center, s.normal, s.radius, s.hole_radius), K.disc_hits,
                     K.disc_inside),
    "triangle": KindSpec(lambda s: (s.p1, s.p2, s.p3), K.triangle_hits, None),
    "smooth_triangle": KindSpec(lambda s: (s.p1, s.p2, s.p3, s.n1, s.n2, s.n3),
                                K.smooth_triangle_hits, None),
    "polygon": KindSpec(lambda s: (s.vertices,), None, None,
                        static=lambda s: (s.edges, s.vertices.shape[0])),
    "mesh": KindSpec(lambda s: (s.triangles, s.normals), None, None,
                     static=lambda s: (s.triangles.shape[0], s.normals is None)),
}


def _hits_fn(kind: str, static: tuple) -> Callable:
    if kind == "cylinder":
        return lambda b, c, r, o, d: K.cylinder_hits(b, c, r, o, d, open=static[0])
    if kind == "cone":
        return lambda b, rb, c, rc, o, d: K.cone_hits(b, rb, c, rc, o, d, open=static[0])
    if kind == "polygon":
        return lambda v, o, d: K.polygon_hits(v, static[0], o, d)
    if kind == "mesh":
        return _mesh_hits
    return KINDS[kind].hits


def _inside_fn(kind: str, static: tuple) -> Callable | None:
    if kind == "cylinder":
        return K.cylinder_inside  # open or not, the inside is the solid's (reference §4.1)
    if kind == "cone":
        return K.cone_inside
    return KINDS[kind].inside


@dataclasses.dataclass(frozen=True)
class Group:
    """Static description of one stacked group of primitives."""

    kind: str
    static: tuple
    prims: tuple[int, ...]  # indices into plan.prims
    k: int  # crossings per instance


@dataclasses.dataclass
class PackedGeometry:
    """Arrays of every group (built inside the jit trace from the scene's leaves)."""

    groups: tuple[Group, ...]
    params: tuple[tuple, ...]  # per group: stacked shape parameters
    object_from_world: tuple[jax.Array, ...]  # per group: (n, 4, 4)
    where: dict[int, tuple[int, int]]  # prim -> (group, index in group)
    cand_prim: np.ndarray  # (C,) prim index of every flat candidate
    n_candidates: int
    circuit: CSGCircuit | None = None  # None when no hit has CSG / clipping conditions


def _stack(trees):
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *trees)


def pack_geometry(plan: Plan, dtype) -> PackedGeometry:
    keyed: dict[tuple, list[int]] = {}
    for i, p in enumerate(plan.prims):
        keyed.setdefault((p.kind, KINDS[p.kind].static(p.obj.shape)), []).append(i)
    groups, params, ofw, where, cand_prim = [], [], [], {}, []
    for (kind, static), ids in keyed.items():
        shapes = [plan.prims[i].obj.shape for i in ids]
        k = _candidates_per_instance(kind, shapes[0])
        groups.append(Group(kind, static, tuple(ids), k))
        params.append(_stack([KINDS[kind].params(s) for s in shapes]))
        mats = []
        for i in ids:
            t = plan.prims[i].world_from_object()
            mats.append(jnp.eye(4, dtype=dtype) if t is None else t.matrix.astype(dtype))
        ofw.append(jax.vmap(inverse_affine)(jnp.stack(mats)))
        for j, i in enumerate(ids):
            where[i] = (len(groups) - 1, j)
            cand_prim.extend([i] * k)
    geo = PackedGeometry(tuple(groups), tuple(params), tuple(ofw), where,
                         np.asarray(cand_prim, dtype=np.int32), len(cand_prim))
    if plan.effects.csg:
        geo = dataclasses.replace(geo, circuit=build_csg_circuit(geo, plan))
    return geo


def _candidates_per_instance(kind: str, shape) -> int:
    if kind == "mesh":
        return int(shape.triangles.shape[0])
    return getattr(K, f"{kind.upper()}_K")


def _to_object(m, o, d):
    return m[:3, :3] @ o + m[:3, 3], m[:3, :3] @ d


def all_crossings(geo: PackedGeometry, o, d):
    """Every crossing of the ray with every primitive.

    Returns:
        t: (C,) ray parameters (world units of ``|d|``), +inf where a slot is empty.
        n: (C, 3) unit outward world normals (``inverse`` not applied).
    """
    ts, ns = [], []
    for g, prm, ofw in zip(geo.groups, geo.params, geo.object_from_world, strict=True):
        fn = _hits_fn(g.kind, g.static)

        def one(prm_i, ofw_i, fn=fn):
            oo, dd = _to_object(ofw_i, o, d)
            t, n = fn(*prm_i, oo, dd)
            # normals transform with the inverse transpose
            nw = n @ ofw_i[:3, :3]
            return t, K.safe_normalize(nw)

        t, n = jax.vmap(one)(prm, ofw)
        ts.append(t.reshape(-1))
        ns.append(n.reshape(-1, 3))
    return jnp.concatenate(ts), jnp.concatenate(ns)


@dataclasses.dataclass(frozen=True)
class CSGCircuit:
    """The CSG / clipping conditions of every candidate slot as one flat boolean circuit.

    Every condition tree is instantiated at the candidate point it tests. Node values live in one
    array: two constants (False, True), then the leaves (an inside test of primitive ``prim`` at
    candidate ``cand``'s point), then internal nodes, grouped by height so each height is one
    gather-and-reduce. ``difference`` is rewritten as ``all(first, not rest…)``. The trace size
    grows with the circuit's height, not with the number of conditions.
    """

    leaf_cand: np.ndarray  # (L,) candidate slot of each leaf
    leaf_prim: np.ndarray  # (L,) primitive of each leaf
    levels: tuple  # per height: (is_all (n,), children (n, A), negate (n, A), inverse (n,))
    cond_cand: np.ndarray  # (Q,) candidate slot of each condition
    cond_root: np.ndarray  # (Q,) node id of the condition's tree
    cond_want: np.ndarray  # (Q,) bool: inside wanted


def build_csg_circuit(geo: PackedGeometry, plan: Plan) -> CSGCircuit:
    leaves: list[tuple[int, int]] = []
    internal: list[tuple[int, bool, list[tuple[int, bool]], bool]] = []  # (height, all, kids, inv)
    def instantiate(tree: InsideTree, cand: int) -> tuple[int, int]:
        """(node ref, height); refs < 0 are leaves (-1 - leaf index), refs >= 0 internal."""
        if isinstance(tree, InPrim):
            leaves.append((cand, tree.prim))
            ref = -len(leaves)
            if not tree.inverse:
                return ref, 0
            internal.append((1, True, [(ref, False)], True))
            return len(internal) - 1, 1
        kids = [instantiate(t, cand) for t in tree.terms]
        height = 1 + max(h for _, h in kids)
        if isinstance(tree, InDiff):
            children = [(kids[0][0], False)] + [(r, True) for r, _ in kids[1:]]
            is_all = True
        else:
            children = [(r, False) for r, _ in kids]
            is_all = isinstance(tree, InAll)
        internal.append((height, is_all, children, tree.inverse))
        return len(internal) - 1, height

    roots = []
    for c in range(geo.n_candidates):
        for cond in plan.prims[int(geo.cand_prim[c])].conditions:
            roots.append((c, instantiate(cond.tree, c)[0], cond.want))
    # node ids: 0 False, 1 True, 2.. leaves, then internal nodes by height
    n_leaves = len(leaves)
    order = sorted(range(len(internal)), key=lambda i: internal[i][0])
    node_id = {}
    next_id = 2 + n_leaves
    for i in order:
        node_id[i] = next_id
        next_id += 1

    def ref_id(ref: int) -> int:
        return 2 + (-ref - 1) if ref < 0 else node_id[ref]

    levels = []
    heights = sorted({internal[i][0] for i in order})
    for h in heights:
        nodes = [i for i in order if internal[i][0] == h]
        arity = max(len(internal[i][2]) for i in nodes)
        is_all = np.array([internal[i][1] for i in nodes])
        children = np.zeros((len(nodes), arity), np.int32)
        negate = np.zeros((len(nodes), arity), bool)
        for row, i in enumerate(nodes):
            kids = internal[i][2]
            pad = 1 if internal[i][1] else 0  # True pads an "all", False pads an "any"
            children[row] = [ref_id(r) for r, _ in kids] + [pad] * (arity - len(kids))
            negate[row] = [neg for _, neg in kids] + [False] * (arity - len(kids))
        levels.append((is_all, children, negate, np.array([internal[i][3] for i in nodes])))
    return CSGCircuit(
        leaf_cand=np.array([c for c, _ in leaves], np.int32),
        leaf_prim=np.array([q for _, q in leaves], np.int32),
        levels=tuple(levels),
        cond_cand=np.array([c for c, _, _ in roots], np.int32),
        cond_root=np.array([ref_id(r) for _, r, _ in roots], np.int32),
        cond_want=np.array([w for _, _, w in roots], bool))


def _leaf_values(geo: PackedGeometry, circuit: CSGCircuit, points):
    """Inside tests of every leaf (primitive's own ``inverse`` excluded), vectorised per group."""
    values = jnp.zeros(circuit.leaf_prim.shape[0], bool)
    for gi, g in enumerate(geo.groups):
        fn = _inside_fn(g.kind, g.static)
        rows = np.flatnonzero(np.isin(circuit.leaf_prim, np.asarray(g.prims)))
        if fn is None or rows.size == 0:
            continue  # triangles, polygons, meshes have no inside: False
        local = np.array([geo.where[int(q)][1] for q in circuit.leaf_prim[rows]], np.int32)
        prm = jax.tree_util.tree_map(lambda a, local=local: a[local], geo.params[gi])
        m = geo.object_from_world[gi][local]
        pts = points[circuit.leaf_cand[rows]]
        obj_pts = jnp.einsum("nij,nj->ni", m[:, :3, :3], pts) + m[:, :3, 3]
        values = values.at[rows].set(jax.vmap(fn)(*prm, obj_pts))
    return values


def csg_mask(geo: PackedGeometry, plan: Plan, o, d, t):
    """(C,) bool: crossings that satisfy their primitive's CSG / clipping conditions."""
    circuit = geo.circuit
    if circuit is None:
        return jnp.ones(t.shape, bool)
    safe_t = jnp.where(jnp.isfinite(t), t, 0.0)
    points = o[None, :] + safe_t[:, None] * d[None, :]
    values = jnp.concatenate([jnp.array([False, True]), _leaf_values(geo, circuit, points)])
    for is_all, children, negate, inverse in circuit.levels:
        kid = values[children] != jnp.asarray(negate)
        v = jnp.where(jnp.asarray(is_all), jnp.all(kid, axis=1), jnp.any(kid, axis=1))
        values = jnp.concatenate([values, v != jnp.asarray(inverse)])
    failed = values[circuit.cond_root] != jnp.asarray(circuit.cond_want)
    bad = jnp.zeros(t.shape, bool).at[circuit.cond_cand].max(failed)
    return ~bad


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


def closest_hit(geo: PackedGeometry, plan: Plan, o, d, t_min, visible: jax.Array,
                inverse_sign: np.ndarray) -> Hit:
    """Closest crossing with ``t > t_min`` among candidates where ``visible`` (C,) holds."""
    t, n = all_crossings(geo, o, d)
    ok = visible & (t > t_min) & jnp.isfinite(t) & (t < 1e7)
    ok = ok & csg_mask(geo, plan, o, d, t)
    tt = jnp.where(ok, t, jnp.inf)
    c = jnp.argmin(tt)
    found = jnp.isfinite(tt[c])
    t_hit = jnp.where(found, tt[c], 0.0)
    normal = n[c] * jnp.asarray(inverse_sign, n.dtype)[c]
    prim = jnp.asarray(geo.cand_prim)[c]
    return Hit(found, t_hit, prim, normal)
