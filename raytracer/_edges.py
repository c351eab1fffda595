"""The boundary term of a pixel's derivative, where a parameter moves an edge of what camera rays see.

A pixel of a ``spp = k²`` render is the mean of the radiance L over its area (a box filter, which
the k×k lattice of sub-pixel centres integrates). Where L jumps along a curve Γ of the image that a
parameter θ moves, the derivative of the pixel has a second term besides the mean of ∂θL (what
``jax.jvp`` of the render gives, the hit held fixed):

    dI/dθ = ∫_P ∂θL dA + ∫_{Γ∩P} (L⁻ − L⁺) v_n ds,

v_n the normal speed of Γ. Here Γ is where what a camera ray sees changes: its primitive — an
outline over what lies behind it (``AbstractShape.silhouette_margin``; a mesh's, the edge of the
triangle seen last before it, ``item_margin``), or a seam where two surfaces cross or a CSG
difference's cut meets the surface it cuts (the difference of their distances along the ray, each
primitive crossed nearest the distance seen) — the face of its primitive (a crease: a box's edge, a
closed cylinder's rim; ``AbstractShape.face``, the margin the difference of the two faces'
``face_distance``; a flat mesh's crease, between triangles of two faces:
``AbstractShape.items_are_faces``) — the cell of its primitive's discrete pattern
(``Pattern.cell``, ``Pattern.face``) or of its continuous pattern's value in the colour map (its
steps, and its wraps from 1 to 0: ``_level_cell``), or the first shadow caster between the point it
sees and a light whose shadow is one ray (point, spot, parallel; the caster's outline along the
line from that point to the light) or one sample of an area light's fixed grid (each sample's hard
shadow is an edge of its own, with its weight's share of the light) — and the same along the ray's
path through mirrors and glass: a surface whose pigment can transmit passes the refracted ray on
(or, past the critical angle, the mirror ray), one whose finish reflects the mirror ray, up to
``PATH_BOUNCES`` of them, each a deterministic, differentiable function of the image point and the
scene. The term is computed deterministically on a lattice of at least ``EDGE_LATTICE``² samples a pixel:

1. Each lattice sample's signature (at each level of its path: the primitive, its pattern cell, the
   branch taken there, its face, the item seen — a mesh's triangle, carried for its margin,
   compared only on a flat mesh — and each such light's or grid sample's caster, with the triangle
   a shadow ray crosses where the caster is a mesh); a pair of neighbouring samples
   (across the whole image and a ring of samples half a spacing outside it, in rows and in
   columns) with different ones holds a crossing of Γ — in
   channel 0 where the path, its cells or a point light's caster differ, else one crossing for each
   grid sample whose caster differs (a penumbra's sample outlines lie closer together than the
   lattice's spacing, and each is an edge). The (pair, channel)s are compacted
   (``_chunks.nonzero``: a native loop on the CPU) into a static room, so the work follows the
   edges' length. The lattice's rows are split over the local devices, as the render's tiles are.
2. On each pair, the first change of its channel is bisected (a fixed number of steps, values only,
   tracing only the levels and shadow rays the pair differs in, then a Newton step on the margin),
   and at the first level of the path where the two sides differ, the margin ``g`` whose zero it
   is chosen: the nearer primitive's outline along that level's ray, the farther one's, their
   seam, the pattern's cell face or the level its value crosses, a crease, the onset of total
   internal reflection, or a shadow caster's outline — the one nearest the
   crossing. A pair that differs in more than the face it sees is bisected for that difference.
3. There, by forward-mode derivatives: ``g_u, g_v`` along the image and ``g_θ`` along the
   parameters' tangent. The crossing of a row moves by ``−g_θ/g_u``; rows and columns share the edge
   integral by the weights ``g_u⁴/(g_u⁴ + g_v⁴)`` and ``g_v⁴/(…)`` (they add up to ∫ ds, and neither
   pass divides by a vanishing ``g_u``), so a row's crossing adds ``−b (L⁻ − L⁺) g_θ g_u³/(g_u⁴ +
   g_v⁴)``, spread over the pixels its stretch of the edge passes. ``b`` is the stretch of rows the
   crossing stands for: on a smooth edge its band of the lattice, ``h`` (the spacing in pixels);
   where the edge turns between two lattice lines (a polygon's vertex, a box's corner, a cell's
   corner where another edge ends it), up to where its tangent line meets that of the crossing
   beyond the turn — the vertex itself on straight edges (``_extents``).
4. ``L⁻``, ``L⁺``: two camera rays just either side of the crossing, traced through the whole
   model (shadows, reflections, refraction), so the jump is that of the image.

The term is linear in the tangent (only ``g_θ`` carries it), so reverse mode is its transpose:
``render(…, edges=True)`` wraps the render in a ``jax.custom_jvp`` whose tangent is the render's
own plus this one. Every step after the compaction runs over the room's chunks that hold crossings
and no others (a loop whose length the program computes; the bisections' and the edge's stretches'
chunks dealt to the local devices in turn); the linear map and its transpose are two such loops
(``_linear.linear_call``), so forward and reverse mode both cost what the edges' length asks, not
what the room holds.

Discretised, and where it fails: the row and column sums are a quadrature of the edge integral with
spacing ``h`` — second order on smooth edges; a vertex between straight edges is located (exact for
a polygon's), but not one whose edges both run steeply across the lattice lines of both passes,
nor the corners of features a few lattice steps across (first order there, as a curve's tip is);
two edges between neighbouring samples count as one, a crossing's jump takes in any other edge
within ``2 SIDE_OFFSET`` of it (a dense area light's penumbra: 1.2 % at 16×16 samples; farther,
``SIDE_CHECKS``, where a float32 shadow flickers), and
features thinner than ``h`` are missed, and so is a shape's outline over itself (a torus's near
tube over its far one, a smooth mesh's over itself: one primitive on both sides, the signature
does not change); a shape without a margin (polynomials) and a turbulent
discrete pattern get no term (``Edges.unresolved`` counts those crossings), nor does the shadow of
a rim (a CSG cut's, a ``clipped_by``'s); the onset of total internal reflection is the zero of
refraction's discriminant there. Not in this term: the shadows of area lights whose samples
adaptive sampling chooses (a warning says so), a shadow's edge inside another caster's shadow (the
first caster along the shadow ray is the one seen), what the mirror ray of a transparent surface
shows (the path follows its refracted ray), and paths longer than ``PATH_BOUNCES``. The path's ray
crosses a surface as if from air into the surface's interior or back (POV-Ray's list of nested
interiors is not followed).
"""

from __future__ import annotations

import contextlib
import warnings
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import ClosedJaxpr, jaxpr_as_fun
from jax.flatten_util import ravel_pytree

from . import patterns
from ._linear import linear_call
from ._packed import pack
from ._plan import make_plan
from ._tiles import _mesh, _replicated
from .kernels import world_normal
from .scene import Scene, environment_of
from .shading import _accel, lighting
from .shading._chunks import map_in_place, nonzero, stable_order
from .shading._geometry import _slot_in_prim, _to_object, candidate_crossings, closest_hit, prim_bits
from .shading._materials import _color_map, _pattern_point, _raw_value, discrete_face_nudge, waved_value
from .shading._model import (
    adaptive_shadow_lights,
    grid_shadow_lights,
    hard_shadow_lights,
    initial_media,
    light_geometry,
    make_context,
    shadow_sample_points,
)
from .shading.camera import camera_rays
from .shading.whitted import trace
from .shapes import AbstractShape

# bisection steps from a lattice spacing to the crossing: 2⁻¹² of it (6.1e-5 px at 4×4 samples a pixel),
# then a Newton step on the margin chosen there, so that the crossing is placed to second order
# (the edge tests' errors are those of 14 steps without it; 8 steps lose an area light's penumbra)
BISECTIONS = 12
# the boundary term's lattice is at least this many samples across a pixel (a render of fewer rays,
# spp 1 or 4, still gets its edges at this resolution: the term's error falls as its square)
EDGE_LATTICE = 4
# the lattice's signatures are computed in blocks of whole rows that trace about this many rays (a
# sample traces one a level of its path, and one to each point light and area-light sample there):
# wide operations, few of them, and memory bounded (the 64×48 lattice at 4×4 samples a pixel, three
# rays a sample, is two blocks)
LATTICE_BLOCK = 131072
# the lattice is split over the local devices where each gets at least this many rays to trace
LATTICE_SHARD_RAYS = 16384
# the two rays that see either side of a crossing are this far (pixels) beyond the bisection's
# last interval. Their difference is the jump, and it takes in any other edge between them: in a
# dense area light's penumbra the samples' outlines lie close together (16×16 samples, a penumbra
# ~5 px wide: ~50 outlines a pixel), and with 1e-3 px and 2⁻¹⁰ of a spacing the jumps took in
# their neighbours', the term 12 % over central differences (8×8: 2.5 %); here 1.2 % (0.1 %)
SIDE_OFFSET = 1e-4
# ... unless what is seen there is not what the bisection saw on that side: a float32 shadow that
# grazes the surface seen (an area light's sample beyond its horizon) flickers over ~5e-4 px (the
# shading point's rounding against the 4e-5 spawn offset), and rays 2e-4 px apart then saw the same
# side for ~40 % of such crossings (no jump). A crossing whose bisection traced shadows checks its
# side points at each of these offsets (pixels) in turn, with the sample's own shadow ray, and takes
# the first that sees its side; SIDE_FALLBACK where none does
SIDE_CHECKS = (1e-4, 1e-3)
SIDE_FALLBACK = 5e-3
# a camera ray's path is followed through this many mirror or refracted rays (each a level of a
# lattice sample's signature; at most the scene's max_trace_level − 1)
PATH_BOUNCES = 3
# the branch a path takes at a surface
STOP, REFLECT, REFRACT, TIR = 0, 1, 2, 3


class Edges(NamedTuple):
    """The boundary term of a render's tangent and what it found."""

    tangent: jax.Array  # (H, W, 3): the linear image's boundary term along the tangent
    crossings: jax.Array  # () int: lattice pairs that see different primitives or pattern cells
    unresolved: jax.Array  # () int: of those, the ones no margin resolved (no term)
    overflow: jax.Array  # () int: crossings past the static room (no term)
    dropped: jax.Array  # () int: rays of the jumps' ray trees past the trace's capacity (left out)


def _prim_tables(geo, n_prims: int):
    """(group (P,), index in its group (P,), has a margin (P,), has creases (P,), has a margin as a
    shadow caster (P,), its items are faces (P,): ``AbstractShape.items_are_faces``, it shows its
    inside across a rim of its own (P,): ``AbstractShape.shows_inside``) of every primitive
    (static)."""
    group = np.full(max(n_prims, 1), -1, np.int32)
    index = np.zeros(max(n_prims, 1), np.int32)
    for i, (g, j) in geo.where.items():
        group[i], index[i] = g, j

    def of_shape(test):  # (P,): ``test`` of each primitive's group of shapes
        per_group = np.array([bool(test(s)) for s in geo.shapes], bool)
        return np.where(group >= 0, per_group[np.maximum(group, 0)] if len(per_group) else False, False)

    def of_class(test):  # (P,): ``test`` of each primitive's shape class
        return of_shape(lambda s: test(type(s)))

    # (a shape whose margin is its items' (a mesh) casts a term where the shadow entries carry the
    # item a shadow ray crosses: ``_first_caster``'s ``items``)
    return (group, index, of_class(lambda c: c.has_margin()), of_class(lambda c: c.faces > 1),
            of_class(_whole_margin), of_shape(lambda s: s.items_are_faces()),
            of_shape(lambda s: s.shows_inside()))


def _whole_margin(cls) -> bool:
    """Whether shape class ``cls`` has a margin of the whole shape, not only of each item's."""
    return cls.silhouette_margin is not AbstractShape.silhouette_margin


def _per_prim(geo, tables, p, o, d, fn, fill, every_shape: bool = False, creased: bool = False,
              meshes: bool = False, only=None):
    """``fn(shape, object-space o, d, object_from_world)`` of the primitive ``p`` (traced index),
    over every group of a shape class with a margin (``every_shape``: of any class but meshes, whose
    every triangle a call would cross, unless ``meshes``: ``fn`` then asks one; ``creased``: of a
    class of several faces; ``only``: of the groups whose stacked shapes it holds for); ``fill``
    where it has none."""
    group, index = tables[:2]
    out = jnp.asarray(fill, o.dtype)
    g_of, j_of = jnp.asarray(group)[p], jnp.asarray(index)[p]
    for g, (shapes, ofw) in enumerate(zip(geo.shapes, geo.object_from_world, strict=True)):
        if only is not None:
            if not only(shapes):
                continue
        elif creased:
            if type(shapes).faces <= 1:
                continue
        elif not (type(shapes).has_margin() or (every_shape and (meshes or shapes.kind != "mesh"))):
            continue
        j = jnp.clip(j_of, 0, ofw.shape[0] - 1)
        shape = jax.tree_util.tree_map(lambda x, j=j: x[j], shapes)
        oo, dd = _to_object(ofw[j], o, d)
        out = jnp.where(g_of == g, fn(shape, oo, dd, ofw[j]), out)
    return out


def _margin(geo, tables, p, o, d, sub=0):
    """The outline margin of primitive ``p`` (of its item ``sub``: a mesh's triangle) along the line."""
    return _per_prim(geo, tables, p, o, d, lambda s, oo, dd, _: s.item_margin(oo, dd, sub), jnp.nan)


def _one_face(geo, tables, p, sub_a, sub_b):
    """Whether items ``sub_a`` and ``sub_b`` of primitive ``p`` lie in one face
    (``AbstractShape.one_face``; True for a primitive whose items are not faces)."""
    at = jnp.zeros(3, geo.object_from_world[0].dtype)  # (no line: the items' own geometry)
    one = _per_prim(geo, tables, p, at, at, lambda s, *_: s.one_face(sub_a, sub_b).astype(at.dtype), 1.0,
                    only=lambda shapes: shapes.items_are_faces())
    return one > 0.5


def _face_of(geo, tables, p, o, d, t):
    """The face (``AbstractShape.face``) of primitive ``p`` at ``o + t d`` (0: a shape of one face)."""
    at = jnp.where(jnp.isfinite(t), t, 0.0)
    face = _per_prim(geo, tables, p, o, d, lambda s, oo, dd, _: s.face(oo + at * dd).astype(o.dtype), 0.0,
                     creased=True)
    return face.astype(jnp.int32)


def _crease(geo, tables, p, o, d, face_a, face_b, t_ref):
    """The crease margin between faces ``face_a`` and ``face_b`` of primitive ``p`` along the line
    ``o + t d``: the difference of the line's crossings with their whole surfaces, nearest ``t_ref``
    (``AbstractShape.face_distance``), zero where it meets their common edge."""
    def gap(s, oo, dd, _):
        return s.face_distance(oo, dd, face_a, t_ref) - s.face_distance(oo, dd, face_b, t_ref)

    return _per_prim(geo, tables, p, o, d, gap, jnp.nan, creased=True)


def _nearest_hit(geo, tables, p, o, d, t_min, t_ref=None, sub=None):
    """``(t, n)``: the first crossing beyond ``t_min`` of the line ``o + t d`` with primitive ``p``
    (with ``sub``, of its item ``sub`` alone, ``AbstractShape.sub_hits``: a mesh's triangle; any
    shape but a mesh without; ``inf`` where none) and its unit world normal; with a finite ``t_ref``
    (held), the crossing beyond ``t_min`` nearest it — the one seen where a CSG operand's far side
    is (a difference's cut) or where a surface is seen through another (the choice is held: its
    value and derivatives are that crossing's)."""
    def nearest(s, oo, dd, m):
        t, n = s.hits(oo, dd) if sub is None else s.sub_hits(oo, dd, sub)
        t = jnp.where(t > t_min, t, jnp.inf)
        key = t if t_ref is None else jnp.where(jnp.isfinite(t_ref), jnp.abs(t - t_ref), t)
        i = jnp.argmin(jax.lax.stop_gradient(key))
        return jnp.concatenate([t[i][None], world_normal(n[i], m)])

    fill = jnp.concatenate([jnp.full(1, jnp.inf, o.dtype), jnp.zeros(3, o.dtype)])
    out = _per_prim(geo, tables, p, o, d, nearest, fill, every_shape=True, meshes=sub is not None)
    return out[0], out[1:]


def _crossings(geo, tables, p, o, d, k: int):
    """(k,): every crossing of the line ``o + t d`` with primitive ``p`` (any shape but a mesh; inf
    past its own, and where none)."""
    def all_t(s, oo, dd, _):
        t = s.hits(oo, dd)[0]
        t = t[:k] if t.shape[0] >= k else jnp.concatenate([t, jnp.full(k - t.shape[0], jnp.inf, t.dtype)])
        return jnp.where(jnp.isfinite(t), t, jnp.inf)

    return _per_prim(geo, tables, p, o, d, all_t, jnp.full(k, jnp.inf, o.dtype), every_shape=True)


def _condition_leaves(plan) -> np.ndarray:
    """(P, M) int32: the primitives of each primitive's CSG and clipping conditions (its own
    excluded; -1 past them), M at least 1."""
    def leaves(tree):
        if hasattr(tree, "prim"):
            return [tree.prim]
        return [p for t in tree.terms for p in leaves(t)]

    per = [sorted({q for c in prim.conditions for q in leaves(c.tree)} - {i})
           for i, prim in enumerate(plan.prims)]
    out = np.full((max(len(per), 1), max([len(x) for x in per] + [1])), -1, np.int32)
    for i, x in enumerate(per):
        out[i, :len(x)] = x
    return out


# a conditioned primitive's (CSG, clipping) face entry: its face, plus this where the ray leaves its
# surface (the inside of a bowl cut out of a sphere, seen past its rim, is the sphere again)
LEAVING = 16


def _nearest_t(geo, tables, p, o, d, t_min, t_ref=None, sub=None):
    return _nearest_hit(geo, tables, p, o, d, t_min, t_ref, sub)[0]


def _discrete(mats):
    """The scene's discrete patterns (static): ``[(k, face or None)]``, k an index into
    ``mats.pattern_names``."""
    return [(k, patterns.REGISTRY[name].face) for k, name in enumerate(mats.pattern_names)
            if patterns.REGISTRY[name].discrete and patterns.REGISTRY[name].rendered]


def _continuous(mats):
    """The scene's continuous patterns (static): indices into ``mats.pattern_names`` of those whose
    value a colour map looks up (its steps and the value's wraps are edges: ``_level_cell``)."""
    return [k for k, name in enumerate(mats.pattern_names)
            if name != "solid" and patterns.REGISTRY[name].rendered and not patterns.REGISTRY[name].discrete]


# a continuous pattern's cell edge (``_face``'s ``step``): a plane face of a discrete pattern, the
# wrap of the value from 1 to 0, the value's crossing of ½ (where no step is: an edge only if the
# map's ends differ, a wrap's companion), or (≥ 0) the colour-map entry j whose position equals
# entry j − 1's: a step of the colour
PLANE, WRAP, HALF = -3, -1, -2


def _steps(values, colors):
    """(E − 1,): whether colour-map entry j + 1 is a step: at entry j's position, of another colour."""
    return (values[1:] == values[:-1]) & jnp.any(colors[1:] != colors[:-1], axis=-1)


def _level_cell(mats, row, w):
    """The cell of the value ``w`` (``waved_value``) in row ``row``'s colour map: the steps at or
    below it, and whether it is ½ or more where the map's ends differ (a wrap from 1 to 0 of the
    value is an edge of the colour then, found by the change of this half)."""
    values, colors = mats.values[row], mats.colors[row]
    steps = jnp.sum(_steps(values, colors) & (w >= values[1:])).astype(jnp.int32)
    one, zero = jnp.ones((), w.dtype), jnp.zeros((), w.dtype)
    ends = jnp.any(_color_map(one, values, colors) != _color_map(zero, values, colors))
    return steps + values.shape[0] * (ends & (w >= 0.5)).astype(jnp.int32)


def _waved(mats, row, q):
    """The value row ``row``'s colour map looks up at pattern-space point ``q``, of its continuous
    pattern (0 for any other)."""
    pid = jnp.asarray(mats.tables["pattern_id"])[row]
    w = jnp.zeros((), q.dtype)
    for k in _continuous(mats):
        w = jnp.where(pid == k, waved_value(mats, row, _raw_value(mats, k, row, q)), w)
    return w


def _cell(mats, prim, p):
    """The cell of primitive ``prim``'s top layer's pattern at world point ``p``: of a discrete
    pattern, ``Pattern.cell``, else its value (the colour's index); of a continuous one, its value's
    place in the colour map (``_level_cell``); 0 for a plain colour."""
    row = prim * mats.n_layers
    q = _pattern_point(mats, row, p)
    pid = jnp.asarray(mats.tables["pattern_id"])[row]
    cell = jnp.zeros((), jnp.int32)
    nudge = discrete_face_nudge(mats, row, q)  # the faces the shading decides on, as it does
    for k, _ in _discrete(mats):
        record = patterns.REGISTRY[mats.pattern_names[k]]
        if record.cell is not None:
            own = record.cell(q if nudge is None else q + nudge)
        else:
            own = _raw_value(mats, k, row, q).astype(jnp.int32)
        cell = jnp.where(pid == k, own, cell)
    if _continuous(mats):
        continuous = jnp.isin(pid, jnp.asarray(_continuous(mats)))
        cell = jnp.where(continuous, _level_cell(mats, row, _waved(mats, row, q)), cell)
    return cell


def _face(mats, prim, q_a, q_b):
    """``(normal, offset, step, has)``: the edge between the cells of pattern-space points ``q_a``
    and ``q_b`` of primitive ``prim``'s top layer: of a discrete pattern the plane ``normal · q =
    offset`` (``Pattern.face``; step ``PLANE``), of a continuous one the level its value crosses
    there (``step``: ``WRAP``, ``HALF`` or a colour-map entry); ``has`` False where a discrete
    pattern has no face function or a turbulence that bends its faces."""
    row = prim * mats.n_layers
    pid = jnp.asarray(mats.tables["pattern_id"])[row]
    normal, offset, has = jnp.zeros(3, q_a.dtype), jnp.zeros((), q_a.dtype), jnp.zeros((), bool)
    step = jnp.asarray(PLANE, jnp.int32)
    if _continuous(mats):  # the level between the two sides' values: a wrap, else a step between them
        w_a, w_b = _waved(mats, row, q_a), _waved(mats, row, q_b)
        values = mats.values[row]
        low, high = jnp.minimum(w_a, w_b), jnp.maximum(w_a, w_b)
        between = _steps(values, mats.colors[row]) & (values[1:] > low) & (values[1:] <= high)
        level = jnp.where(jnp.abs(w_a - w_b) > 0.5, WRAP,
                          jnp.where(jnp.any(between), jnp.argmax(between) + 1, HALF)).astype(jnp.int32)
        continuous = jnp.isin(pid, jnp.asarray(_continuous(mats)))
        step, has = jnp.where(continuous, level, step), has | continuous
    for k, face in _discrete(mats):
        if face is None or mats.turbulent[k]:
            continue
        n_k, c_k, found = face(q_a, q_b, lambda q, k=k: _raw_value(mats, k, row, q))
        normal, offset, has = (jnp.where(pid == k, n_k, normal), jnp.where(pid == k, c_k, offset),
                               has | ((pid == k) & found))
    return normal, offset, step, has


def _first_caster(geo, plan, o, d, t_min, t_max, visible, want, items: int = 0):
    """The primitive of the nearest crossing of the ray with ``t_min < t < t_max`` among the shadow
    casters (candidates where ``visible`` holds, accelerated primitives with bits ``want``), -1
    where none: ``closest_hit`` without what a caster's identity does not need (normals, POV-Ray's
    order among exactly tied crossings: the first candidate of a tie is the caster). With
    ``items`` (static: the scene's primitive count), the primitive and its item crossed, as
    ``prim + items · item`` (``_caster_prim``, ``_caster_item``: a mesh's shadow outline is the edge
    of the triangle crossed)."""
    if geo.accel is not None or not geo.n_candidates:
        caster = closest_hit(geo, plan, o, d, t_min, visible, want)
        code = caster.prim + items * caster.sub if items else caster.prim
        return jnp.where(caster.found & (caster.t < t_max), code, -1)
    t = candidate_crossings(geo, o, d, t_min, visible)[0]
    c = jnp.argmin(t)
    code = jnp.asarray(geo.cand_prim)[c]
    if items:
        code = code + items * jnp.asarray(_slot_in_prim(geo.cand_prim))[c]
    return jnp.where(t[c] < t_max, code, -1)


def _caster_prim(code, items: int):
    """The primitive of shadow entries ``code`` (``_first_caster``; negative: none, or unlit)."""
    return jnp.where(code >= 0, code % items, code) if items else code


def _caster_item(code, items: int):
    return jnp.where(code >= 0, code // items, 0) if items else jnp.zeros_like(code)


def _image_ray(camera, width: int, height: int, u, v):
    """The camera ray through image point (u, v) in pixels (u right, v down from the top left)."""
    o, d = camera_rays(camera, jnp.asarray(u / width - 0.5)[None], jnp.asarray(0.5 - v / height)[None])
    return o[0], d[0]


# a level's signature: primitive, pattern cell, branch, face, item, then the shadow casters' columns;
# the item (``Hit.sub``: a mesh's triangle) is carried: it names the triangle whose edge a mesh's
# outline is; it is compared only on a primitive whose items are faces (a flat mesh), between items
# of two faces (``AbstractShape.one_face``)
FACE, ITEM, CASTERS = 3, 4, 5
# a grid sample's entry where the light's centre does not light the point seen (POV-Ray shades an
# area light by its centre's direction): whatever its sample's shadow, the light adds nothing there,
# so a change to or from it is no edge (a sphere's terminator, where its own shadow towards the
# samples beyond its horizon ends: such changes were half the crossings of a lit sphere and none
# had a term)
UNLIT = -2
CELL, CREASE = 3, 4  # the margins' kinds of a pattern's cell edge and of a crease (``boundary_term.margins``)


# crossings are located, differentiated and traced this many at a time, in chunks of the room up to
# the last that holds one (the room's tail is not run)
CHUNK = 256


def _room(width: int, height: int, k: int) -> int:
    """Static room for crossings: 32 image perimeters at the lattice's resolution (a checker floor
    of 16 cells across the image crosses ~20), or every pair if the image has fewer; a multiple of
    ``CHUNK``."""
    pairs = 2 * (width * k) * (height * k)
    return -(-min(pairs, 32 * k * (width + height)) // CHUNK) * CHUNK


class _Held:
    """Values that functions traced inside a devices' program read by name: there they are swapped
    for the program's own copies, passed in as arguments (JAX refuses an array closed over from
    outside once the caller's values carry a sharding over the devices)."""

    def __init__(self, **values):
        vars(self).update(values)

    @contextlib.contextmanager
    def swapped(self, values: dict):
        """``values`` in place of this one's for the duration."""
        kept = dict(vars(self))
        vars(self).update(values)
        try:
            yield
        finally:
            vars(self).clear()
            vars(self).update(kept)


def _model(scene: Scene, packed, ctx) -> _Held:
    """What the lattice and the bisections read (``boundary_term``): the scene, packed, its trace
    context and the media a camera ray starts in."""
    return _Held(scene=scene, packed=packed, geo=packed.geo, mats=packed.mats, ctx=ctx,
                 media=initial_media(ctx, scene.camera.frame()[0]))


def _split(fn, items, n_dev: int, whole, on_devices):
    """``fn(items)`` with the leading axis of ``items`` (a multiple of ``n_dev``) dealt to ``n_dev``
    local devices in turn (device d: entries d, d + n_dev, …, so that each gets a like share of
    the image or of the live chunks), the result in the items' order and whole on each device.
    ``whole`` goes into the devices' program as an argument, and ``fn`` is traced there within
    ``on_devices(its copy)``."""
    if n_dev == 1:
        return fn(items)
    n = jax.tree.leaves(items)[0].shape[0]
    order = np.arange(n).reshape(-1, n_dev).T.reshape(-1)

    def run(it, copy):
        with on_devices(copy):
            return fn(it)

    spec = jax.sharding.PartitionSpec("tiles")
    out = jax.shard_map(run, mesh=_mesh(n_dev), in_specs=(spec, jax.sharding.PartitionSpec()), out_specs=spec,
                        check_vma=False)(jax.tree.map(lambda x: x[order], items), whole)
    return _replicated(jax.tree.map(lambda x: x[np.argsort(order)], out), n_dev)


def _dealt_map(fn, items, live, n_dev: int, whole, on_devices):
    """``map_in_place(fn, items, live, CHUNK)`` with the room's chunks dealt to the devices
    (``_split``): each device loops up to its own last live chunk."""
    def chunked(x):
        return x.reshape(-1, CHUNK, *x.shape[1:])

    def flat(x):
        return x.reshape(-1, *x.shape[2:])

    def run(chunks_):
        it, lv = jax.tree.map(flat, chunks_)
        return jax.tree.map(chunked, map_in_place(fn, it, lv, CHUNK))

    return jax.tree.map(flat, _split(run, jax.tree.map(chunked, (items, live)), n_dev, whole, on_devices))


def _take(x, i):
    """Chunk ``i`` (``CHUNK`` rows) of the room-sized array ``x``."""
    return jax.lax.dynamic_slice_in_dim(x, i * CHUNK, CHUNK)


def _transition(pa, pb, idx, j, ch, levels: int, width_: int, own: int, n_samples: int):
    """(N, D) × 2: whether the crossings ``j`` (N, D) separate the same signatures as the crossings
    ``idx`` (N,) (its first side ``pa``, its other ``pb``) in the crossing's channel ``ch``, in the
    same order, and in the other order."""
    ch = ch[idx]

    def agree(x, y):  # x of each crossing against y of the crossings j
        # (the faces seen are not compared: an outline goes on through the corner where the face
        # beside it changes, and the creases that meet at a corner are one edge's turn there)
        ne = ((y[j] != x[idx][:, None, :]).reshape(*j.shape, levels, width_)
              & ((jnp.arange(width_) != FACE) & (jnp.arange(width_) != ITEM))[None, None, None, :])
        path = jnp.any(ne[..., :own], axis=(-2, -1))
        if not n_samples:
            return ~path
        column = jnp.clip(ch - 1, 0, n_samples - 1)[:, None, None, None]
        grid = jnp.any(jnp.take_along_axis(ne[..., own:], column, axis=-1)[..., 0], axis=-1)
        return jnp.where((ch == 0)[:, None], ~path, ~grid)

    return agree(pa, pa) & agree(pb, pb), agree(pa, pb) & agree(pb, pa)


# an edge turns between two lattice lines (a vertex) where two crossings' tangent lines meet at
# more than this sine of an angle (11.5°); a smooth edge turns by the lattice spacing times its
# curvature and keeps the band's midpoint rule
TURN = 0.2
# and only between crossings whose edge runs across their lines at a slope of at most this: a steep
# crossing's neighbour is far along the edge, where its tangent line no longer follows a curved one
STEEP = 1.5
# a crossing's neighbour on the next row (column) of the lattice is looked for this many lattice
# steps either side of where its tangent line meets that row
WINDOW = 2


def _extents(usable, in_rows, r, c, ch, at, across, along, other, slope, pa, pb, transition, rows: int,
             cols: int, channels: int, h: float, n_dev: int = 1):
    """``(low, high)``: the stretch ``[across + low, across + high]`` of the across axis (v for a
    row's crossing, u for a column's) whose edge integral each crossing stands for.

    A crossing stands for its band of the lattice, ±h/2, on a smooth edge; where the edge turns
    between two lattice lines — a polygon's vertex, a box's corner — the band's straight piece is
    not the edge, and the error is first order in h. So where the next line (row or column) holds
    a crossing of the same transition near where this one's tangent line meets it, the two stand
    for the edge up to where their tangent lines meet, if they bend by more than ``TURN`` (a
    vertex, exactly); where the edge ends there at another (its own turn onto the other pass's
    lines, a cell corner, an outline over it), up to where its tangent line meets that edge's, found
    among the other pass's crossings nearby; elsewhere (a smooth edge, a steep crossing) ±h/2.
    Computed for the chunks of the room up to the last usable crossing, dealt to ``n_dev`` local
    devices (``transition(pa, pb, idx, j, ch)``: whether crossings ``j`` separate the same
    signatures as crossings ``idx``, in the same order, ``pa``, ``pb`` the signatures either side
    of each crossing)."""
    room = r.shape[0]
    first, second = jnp.where(in_rows, r, c), jnp.where(in_rows, c, r)  # across, along lattice index
    sizes = {True: (rows, max(cols - 1, 1)), False: (cols, max(rows - 1, 1))}
    grids = {}
    for rows_pass, (n_a, n_b) in sizes.items():
        mine = usable & (in_rows if rows_pass else ~in_rows)
        grids[rows_pass] = jnp.full((n_a, n_b, channels), -1, jnp.int32).at[first, second, ch].max(
            jnp.where(mine, jnp.arange(room), -1).astype(jnp.int32), mode="drop")
    deltas = jnp.arange(-WINDOW, WINDOW + 1)
    lanes_ = jnp.arange(CHUNK)

    # in the image plane: each crossing's point and its margin's gradient
    pu, pv = jnp.where(in_rows, at, across), jnp.where(in_rows, across, at)
    gu, gv = jnp.where(in_rows, along, other), jnp.where(in_rows, other, along)

    # (the searches read these through their arguments: in a program split over the devices, its own
    # copies, passed in whole)
    arrays = dict(usable=usable, in_rows=in_rows, ch=ch, at=at, across=across, along=along, other=other,
                  slope=slope, first=first, second=second, grids=grids, pu=pu, pv=pv, gu=gu, gv=gv,
                  pa=pa, pb=pb)

    def searches(usable, in_rows, ch, at, across, along, other, slope, first, second, grids, pu, pv, gu, gv,
                 pa, pb, searched=None, seen=None):
        """(both, ends): the searches of a chunk's crossings ``idx``, of ``arrays`` as given."""
        def same(idx, j):
            return transition(pa, pb, idx, j, ch)

        def boundary(idx, step):
            """For the crossings ``idx``: whether the next line (``step``) holds a crossing of the same
            transition near where its tangent line meets that line, bending by more than ``TURN``
            (a vertex) or not (a smooth edge); that crossing, where the two tangent lines meet, and
            the bend."""
            in_rows_i, ch_i, at_i, across_i = in_rows[idx], ch[idx], at[idx], across[idx]
            along_i, other_i, slope_i = along[idx], other[idx], slope[idx]
            line = first[idx] + step
            predicted = at_i + step * h * slope_i
            # (lattice point i lies at (i − ½) h: the pair b spans [(b − ½) h, (b + ½) h])
            lanes = jnp.floor(predicted / h + 0.5).astype(jnp.int32)[:, None] + deltas[None, :]
            cand, inside = [], []
            for rows_pass, (n_a, n_b) in sizes.items():
                cand.append(grids[rows_pass][jnp.clip(line, 0, n_a - 1)[:, None], jnp.clip(lanes, 0, n_b - 1),
                                             ch_i[:, None]])
                inside.append(((line >= 0) & (line < n_a))[:, None] & (lanes >= 0) & (lanes < n_b))
            cand = jnp.where(in_rows_i[:, None], cand[0], cand[1])
            inside = jnp.where(in_rows_i[:, None], inside[0], inside[1])
            j = jnp.maximum(cand, 0)
            valid = inside & (cand >= 0) & usable[idx][:, None] & same(idx, j)[0]
            distance = jnp.where(valid, jnp.abs(at[j] - predicted[:, None]), jnp.inf)
            k = jnp.argmin(distance, axis=1)
            found = jnp.isfinite(distance[lanes_, k])
            n = j[lanes_, k]
            # where the two tangent lines meet, in the across coordinate (Cramer's rule)
            rhs_i, rhs_n = along_i * at_i + other_i * across_i, along[n] * at[n] + other[n] * across[n]
            det = along_i * other[n] - other_i * along[n]
            scale = jnp.sqrt((along_i ** 2 + other_i ** 2) * (along[n] ** 2 + other[n] ** 2))
            meet = (along_i * rhs_n - along[n] * rhs_i) / jnp.where(det != 0, det, 1.0)
            shallow = found & (jnp.abs(slope_i) <= STEEP) & (jnp.abs(slope[n]) <= STEEP)
            bend = jnp.where(shallow, jnp.abs(det) / jnp.where(scale > 0, scale, 1.0), jnp.inf)
            vertex = bend > TURN
            meet = jnp.clip(meet, jnp.minimum(across_i, across[n]), jnp.maximum(across_i, across[n]))
            return vertex & shallow, shallow & ~vertex, n, meet, bend

        def turn(idx, step):
            """Where the edge of the crossings ``idx`` ends towards their next line (``step``) at
            another edge — its own turning onto the other pass's lines at a vertex, or another edge
            that crosses it (a cell corner, an outline over it): the meeting of the crossing's tangent
            line with that of a crossing of the other pass nearby, within four lattice steps of both
            (a crossing's edge may run at 1.5 steps a line). The meeting may lie up to a step past
            the next line: a vertex just past a line (a box's corner 0.0005 px past a column) leaves
            the line no pair of samples either side of the edge, and where a crease ends on an
            outline, the outline's crossing on that line hides the crease's (the lit box translated:
            3.7 % at 4×4 samples a pixel with the meeting up to the next line and within two steps
            of both, 0.22 % now)."""
            in_rows_i, pu_i, pv_i, gu_i, gv_i, across_i = (x[idx] for x in (in_rows, pu, pv, gu, gv, across))
            # the other pass's lattice pairs between the two lines, and the next ones beyond (the other
            # edge may cross the other pass's lines only beyond the vertex), on its lines about this one
            bands = (first[idx] + (step - 1) // 2)[:, None] + jnp.array([0, step])[None, :]
            lanes = second[idx][:, None] + jnp.arange(-1, 3)[None, :]
            bands, lanes = (jnp.broadcast_to(x, (CHUNK, 2, 4)).reshape(CHUNK, 8)
                            for x in (bands[:, :, None], lanes[:, None, :]))
            cand, inside = [], []
            for rows_pass in (True, False):
                n_a, n_b = sizes[not rows_pass]
                cand.append(grids[not rows_pass][jnp.clip(lanes, 0, n_a - 1), jnp.clip(bands, 0, n_b - 1),
                                                 ch[idx][:, None]])
                inside.append((lanes >= 0) & (lanes < n_a) & (bands >= 0) & (bands < n_b))
            cand = jnp.where(in_rows_i[:, None], cand[0], cand[1])
            inside = jnp.where(in_rows_i[:, None], inside[0], inside[1])
            j = jnp.maximum(cand, 0)
            rhs_i = (gu_i * pu_i + gv_i * pv_i)[:, None]
            rhs_j = gu[j] * pu[j] + gv[j] * pv[j]
            det = gu_i[:, None] * gv[j] - gv_i[:, None] * gu[j]
            scale = jnp.sqrt((gu_i ** 2 + gv_i ** 2)[:, None] * (gu[j] ** 2 + gv[j] ** 2))
            safe = jnp.where(det != 0, det, 1.0)
            mu = (rhs_i * gv[j] - gv_i[:, None] * rhs_j) / safe
            mv = (gu_i[:, None] * rhs_j - gu[j] * rhs_i) / safe
            meet = jnp.where(in_rows_i[:, None], mv, mu)  # in the across coordinate
            reach = jnp.maximum(jnp.hypot(mu - pu_i[:, None], mv - pv_i[:, None]),
                                jnp.hypot(mu - pu[j], mv - pv[j]))
            offset = step * (meet - across_i[:, None])
            valid = (inside & (cand >= 0) & usable[idx][:, None] & (jnp.abs(det) > TURN * scale)
                     & (jnp.abs(slope[idx]) <= STEEP)[:, None] & (jnp.abs(slope[j]) <= STEEP)
                     & (offset >= 0) & (offset <= 2 * h) & (reach <= 4 * h))
            distance = jnp.where(valid, reach, jnp.inf)
            k = jnp.argmin(distance, axis=1)
            return jnp.isfinite(distance[lanes_, k]), meet[lanes_, k]

        def both(idx):
            return boundary(idx, -1), boundary(idx, 1)

        def ends(idx):
            out = []
            for step in (-1, 1):
                vertex, smooth, _, meet, _ = (x[idx] for x in searched[step])
                bend_back = searched[-step][4][idx]
                seen_back, meet_seen = (x[idx] for x in seen[step])
                turned, meet_turn = turn(idx, step)
                # (only from a straight edge: the other side's neighbour in line; a small curve's
                # crossings bend by more than that between lattice lines, and meet the other pass's)
                turned = turned & (bend_back <= TURN / 4)
                across_i = across[idx]
                middle = across_i + 0.5 * step * h
                end = jnp.where(vertex, meet, jnp.where(seen_back, meet_seen, jnp.where(
                    smooth, middle, jnp.where(turned, meet_turn, middle))))
                out.append(end - across_i)
            return tuple(out)

        return both, ends

    def chunks(which: int, given: dict):
        """``searches(**given)[which](idx)`` for each chunk's crossings ``idx`` up to the last usable
        one, in room order."""
        held = _Held(**given)
        return _dealt_map(lambda idx: searches(**vars(held))[which](idx), jnp.arange(room, dtype=jnp.int32),
                          usable, n_dev, given, held.swapped)

    searched = dict(zip((-1, 1), chunks(0, arrays), strict=True))

    # a vertex with this side's neighbour, else with a crossing of that line that found this one
    # looking back (a steep edge's crossing may not see a shallow one beyond a vertex that sees it);
    # a smooth neighbour: the band's midpoint; none (or a steep one): where another edge ends this
    # one, else the midpoint
    seen = {}
    for step in (-1, 1):
        _, _, n_back, meet_back, _ = searched[-step]
        target = jnp.where(searched[-step][0], n_back, room)  # (room: dropped)
        seen[step] = (jnp.zeros(room, bool).at[target].set(True, mode="drop"),
                      jnp.zeros(room, meet_back.dtype).at[target].set(meet_back, mode="drop"))

    low, high = chunks(1, {**arrays, "searched": searched, "seen": seen})
    return jax.lax.stop_gradient(low), jax.lax.stop_gradient(high)


def _spread(contribution, in_rows, at, across, low, high, slope, span, width: int, height: int, dtype):
    """(H, W, 3): each crossing's contribution spread over the pixels its stretch of the edge passes
    through: the stretch ``[across + low, across + high]`` cut at the pixel lines across, and each
    piece's straight run along the axis (slope ``slope``) shared by length among the cells it
    overlaps (a run longer than three cells keeps its whole share in these three)."""
    tiny = jnp.finfo(dtype).tiny
    image = jnp.zeros((height, width, 3), dtype)
    pixel = jnp.floor(across)
    for piece in (-1, 0, 1):
        a = jnp.clip(across + low, pixel + piece, pixel + piece + 1)
        b = jnp.clip(across + high, pixel + piece, pixel + piece + 1)
        part = jnp.where(span > 0, (b - a) / jnp.where(span > 0, span, 1.0), float(piece == 0))
        run_a, run_b = at + (a - across) * slope, at + (b - across) * slope
        run_lo, run_hi = jnp.minimum(run_a, run_b), jnp.maximum(run_a, run_b)
        centre = jnp.floor(0.5 * (run_lo + run_hi))
        overlaps = [jnp.clip(jnp.minimum(run_hi, centre + s + 1) - jnp.maximum(run_lo, centre + s), 0.0, None)
                    for s in (-1, 0, 1)]
        total = overlaps[0] + overlaps[1] + overlaps[2]
        across_cell = (pixel + piece).astype(jnp.int32)
        for shift, overlap in zip((-1, 0, 1), overlaps, strict=True):
            share = jnp.where(total > tiny, overlap / jnp.maximum(total, tiny), float(shift == 0))
            along_cell = (centre + shift).astype(jnp.int32)
            px = jnp.where(in_rows, along_cell, across_cell)
            py = jnp.where(in_rows, across_cell, along_cell)
            inside = (px >= 0) & (px < width) & (py >= 0) & (py < height) & (part > 0)
            image = image.at[jnp.clip(py, 0, height - 1), jnp.clip(px, 0, width - 1)].add(
                jnp.where(inside[:, None], (part * share)[:, None] * contribution, 0.0))
    return image


def _left_out(plan, mats, ctx, item_casters: bool) -> list[str]:
    """What the scene has whose edges the term does not see (static): shapes without a margin,
    discrete patterns without cell faces, pigment maps, image maps and normal {} patterns, the
    shadows of rims, adaptive area lights' shadows."""
    out = []
    shapes = sorted({prim.obj.shape.kind for prim in plan.prims
                     if prim.rendered and not type(prim.obj.shape).has_margin()})
    if shapes:
        out.append("the outlines of " + ", ".join(shapes))
    lit = bool(hard_shadow_lights(ctx) or grid_shadow_lights(ctx) or adaptive_shadow_lights(ctx))
    per_item = sorted({prim.obj.shape.kind for prim in plan.prims if prim.rendered
                       and type(prim.obj.shape).has_margin() and not _whole_margin(type(prim.obj.shape))})
    if lit and per_item and not item_casters:  # (a scene of more than 2³¹ primitives × items)
        out.append("the shadow's outline of " + ", ".join(per_item))
    if lit and any(prim.conditions for prim in plan.prims if prim.rendered):
        out.append("the shadows of the rims of CSG cuts and clipped_by")
    cells = sorted(mats.pattern_names[k] for k, face in _discrete(mats) if face is None or mats.turbulent[k])
    if cells:
        out.append("the cell edges of " + ", ".join(cells) + " (turbulent, or without a face)")
    if mats.entries is not None:
        out.append("the pattern edges of pigment maps and pigment lists")
    if mats.textures is not None:
        out.append("the pattern edges of patterned textures (texture_map, a block pattern's textures)")
    if mats.images is not None:
        out.append("the pixel edges of image maps")
    if mats.normals is not None:
        out.append("the pattern edges of normal {} perturbations")
    if adaptive_shadow_lights(ctx):
        out.append(f"the shadows of area lights with adaptive sampling (lights "
                   f"{', '.join(map(str, adaptive_shadow_lights(ctx)))}: their samples change with the "
                   "scene; without `adaptive` the grid's shadows are seen)")
    return out


@eqx.filter_jit
def boundary_term(dynamic, tangent, static, width: int, height: int, k: int,
                  capacity: int | None = None, room: int | None = None) -> Edges:
    """The boundary term of the linear image's derivative along ``tangent`` (the scene is
    ``eqx.combine(dynamic, static)``; ``tangent`` has ``dynamic``'s structure)."""
    scene: Scene = eqx.combine(dynamic, static)
    dtype = scene.camera.location.dtype
    plan = make_plan(scene)

    def model_of(dyn) -> _Held:
        sc = eqx.combine(dyn, static)
        pk = pack(sc, plan)
        return _model(sc, pk, make_context(plan, pk.geo, pk.mats, sc.lights, sc.settings, sc.background,
                                           dtype, environment_of(sc)))

    # what the scene's arrays make, read through ``M`` by the lattice and the bisections: in a
    # program split over the devices it is built again from the program's own copy of ``dynamic``
    # (an array closed over from outside cannot be read there once the caller's values carry a
    # sharding over the devices: a fit's parameters after its first step)
    M = model_of(dynamic)
    packed, geo, ctx = M.packed, M.geo, M.ctx
    tables = _prim_tables(geo, len(plan.prims))

    def on_devices(dyn):  # M, while the devices' program is traced, built from its ``dyn``
        return M.swapped(vars(model_of(dyn)))

    h = 1.0 / k
    # the lattice: k×k samples a pixel, and a ring of samples half a spacing outside the image, so
    # that an edge running along the image's border within half a spacing of it is crossed too
    rows, cols = height * k + 2, width * k + 2
    sg = jax.lax.stop_gradient

    mats = packed.mats
    cells = bool(_discrete(mats) or _continuous(mats))
    creases = bool(np.any(tables[3]))  # a primitive of several faces (a box, a closed cylinder)
    # a primitive whose items are faces (a flat mesh's triangles): a change of the item seen on it is
    # a crease, or its outline over itself
    item_faces = jnp.asarray(tables[5]) if np.any(tables[5]) else None
    # the primitives a primitive's CSG and clipping conditions test (a rim: where its surface meets
    # theirs, what is seen past it is another primitive, or its own far side)
    leaves = _condition_leaves(plan)
    rims = bool(np.any(leaves >= 0))
    conditioned = jnp.asarray(np.any(leaves >= 0, axis=1)) if rims else None
    # primitives seen from inside and outside across a rim of their own (an open cylinder's): the
    # side seen is part of the signature (as a conditioned one's), the rim's margin the shape's own
    open_rims = bool(np.any(tables[6]))
    shows_inside = jnp.asarray(tables[6]) if open_rims else None
    sided = jnp.asarray(np.any(leaves >= 0, axis=1) | tables[6]) if (rims or open_rims) else None
    # crossings of a line a rim's margin compares (the most any shape class but meshes gives)
    rim_k = max([type(g).crossings for g in geo.shapes if g.kind != "mesh"] + [1])
    # lights whose shadow is one ray: the first caster on it is part of what a sample sees; and
    # area lights sampled on a fixed grid: the first caster towards each sample of it (an entry of
    # its own, and a channel of its own below, since its edges lie within a penumbra close together)
    shadow_lights = hard_shadow_lights(ctx)
    grid_lights = tuple((i, shadow_sample_points(ctx, scene.lights[i])[0].shape[0])
                        for i in grid_shadow_lights(ctx))
    n_points, n_samples = len(shadow_lights), sum(n for _, n in grid_lights)
    # a shadow caster whose margin is its items' (a mesh's triangles): the shadow entries carry the
    # item crossed too, as ``prim + items · item`` (``_first_caster``), where that fits in int32
    per_item = tables[2] & ~tables[4]
    most = max((prim.obj.shape.n_crossings() for i, prim in enumerate(plan.prims) if per_item[i]), default=0)
    items = len(plan.prims) if (n_points + n_samples) and most and len(plan.prims) * most < 2 ** 31 else 0
    left_out = _left_out(plan, packed.mats, ctx, bool(items))
    if left_out:  # (said when the term is traced: once a program)
        warnings.warn("edges=True: no boundary term for " + "; ".join(left_out) + " (docs/gradients.md): "
                      "their derivatives hold what is seen fixed", RuntimeWarning, stacklevel=2)
    entries = n_points + n_samples  # a level's shadow entries: point lights, then grid samples
    casters = _accel.MASK_SHADOW | _accel.MASK_FILTER
    vis_shadow = jnp.asarray((prim_bits(plan)[geo.cand_prim] & casters) != 0)
    # a camera ray's path: the camera ray, then each surface's refracted ray (where its pigment can
    # transmit) or else its mirror ray (where its finish reflects), up to PATH_BOUNCES of them
    effects = plan.effects
    bounces = min(PATH_BOUNCES, max(int(scene.settings.max_trace_level) - 1, 0))
    levels = 1 + (bounces if (effects.reflection or effects.refraction) else 0)
    width_ = CASTERS + entries  # a level's entries: primitive, cell, branch, face, item, casters
    transparent = jnp.asarray(mats.tables["transparent"], bool)
    # float32 points of discrete patterns computed at the surface, as the shading computes them
    refine = bool(_discrete(mats)) and dtype == jnp.float32
    # each grid sample's shadow outline is an edge of its own: room for four image perimeters of it
    if room is None:
        room = _room(width, height, k) + n_samples * 4 * k * (width + height)
    # the local devices the lattice's rows and the crossings' chunks are split over (as the
    # render's tiles are), where each gets at least LATTICE_SHARD_RAYS of the lattice's rays
    n_dev = len(jax.local_devices())
    lattice_rays = (height * k + 2) * (width * k + 2) * levels * (1 + entries)
    n_dev = n_dev if lattice_rays >= n_dev * LATTICE_SHARD_RAYS else 1
    room = -(-room // (CHUNK * n_dev)) * CHUNK * n_dev

    def guard(x):
        """The model's rounding guard at point ``x`` (a start offset along a ray, a spawn offset),
        held constant: the derivative of max |x| needs its argmax found again, which a rounding of
        ``x`` recomputed differently can miss (0/0)."""
        return jax.lax.stop_gradient(M.ctx.eps * (1.0 + jnp.max(jnp.abs(x))))

    def reflects(prim):
        rows = prim * M.mats.n_layers + jnp.arange(M.mats.n_layers)
        return jnp.any((jnp.asarray(M.mats.finish.refl_max)[rows] != 0)
                       | (jnp.asarray(M.mats.finish.refl_min)[rows] != 0))

    def child(mats_, prim, o, d, t, n, branch):
        """The ray that leaves the crossing ``o + t d`` of ``prim`` (world normal ``n``) along
        ``branch`` (REFLECT, REFRACT or TIR), and whether refraction there is total."""
        d = d / jnp.sqrt(jnp.sum(d * d))
        p = o + jnp.where(jnp.isfinite(t), t, 0.0) * d
        entering = jnp.dot(n, d) < 0
        n = jnp.where(entering, n, -n)
        offset = guard(p)
        ior = jnp.asarray(mats_.ior)[prim]
        d_t, tir = lighting.refract(d, n, jnp.where(entering, 1.0 / ior, ior))
        d_next = jnp.where(branch == REFLECT, lighting.reflect(d, n), d_t)
        o_next = jnp.where(branch == REFRACT, p - offset * n, p + offset * n)
        return o_next, d_next, tir

    # 1. what each lattice sample sees, its signature (levels × (3 + entries),) flattened: at each
    # level of its path, the primitive (-1: none), the cell of its discrete pattern (0: none), the
    # branch the path takes there (STOP, REFLECT, REFRACT, TIR), and for each light of
    # ``shadow_lights``, then each sample of each light of ``grid_lights``, the first shadow caster
    # between the point seen and the light or sample (-1: none, or the light is behind the surface)
    def seen(u, v, sample=None, focus=None):
        """The signature of image point (u, v); with ``sample`` (a grid sample's index, traced), of
        the grid's casters only that sample's (the others -1): what a bisection of its channel, or
        of channel 0, which has none, needs. With it, the distance to the surface seen at each
        level (levels,) (inf: none). With ``focus`` = (reference signature, last level, shadows),
        the levels past the last and, unless ``shadows``, every shadow entry are not traced but
        copied from the reference (a bisection's chunk asks only what its crossings differ in;
        the last level and ``shadows`` are the chunk's, not batched, so that skipping is skipping)."""
        reference = None if focus is None else focus[0].reshape(levels, width_)

        def level_of(carry, index):
            if focus is None:
                return traced_level(carry, index, True)
            skipped = (carry, (reference[index], jnp.asarray(jnp.inf, dtype)))
            return jax.lax.cond(index <= focus[1], lambda c: traced_level(c, index, focus[2]),
                                lambda c: skipped, carry)

        # one level of the path: a loop over the levels, so that the program holds one copy of it
        def traced_level(carry, index, shadows):
            o, d, alive, mirror = carry
            scale = guard(o)
            vis = jnp.where(mirror, jnp.asarray(M.ctx.vis_reflect), jnp.asarray(M.ctx.vis_camera))
            want = jnp.where(mirror, _accel.MASK_REFLECT, _accel.MASK_CAMERA)
            hit = closest_hit(M.geo, plan, o, d, scale, vis, want, refine=refine)
            found = alive & hit.found
            p = o + jnp.where(found, hit.t, 0.0) * d
            p_cell = p if hit.point is None else hit.point
            # the face of the primitive seen (creases: a box's edges, a cylinder's rims)
            face = _face_of(M.geo, tables, hit.prim, o, d, hit.t) if creases else jnp.zeros((), jnp.int32)
            if rims or open_rims:  # which side of the surface: a bowl's inside past its rim, a bore's
                leaving = sided[jnp.maximum(hit.prim, 0)] & (jnp.dot(hit.normal, d) > 0)
                face = face + LEAVING * leaving.astype(jnp.int32)
            cell = _cell(M.mats, hit.prim, p_cell) if cells else jnp.zeros((), jnp.int32)
            casts = []

            def shadow_entries():
                return jnp.stack(casters_at(found, hit, p, d)).astype(jnp.int32)

            if entries and focus is None:
                casts = list(shadow_entries())
            elif entries:
                casts = list(jax.lax.cond(shadows, shadow_entries,
                                          lambda: reference[index, CASTERS:].astype(jnp.int32)))
            branch = jnp.asarray(STOP)
            if levels > 1:
                prim = jnp.maximum(hit.prim, 0)
                branch = jnp.where(transparent[prim], REFRACT, jnp.where(reflects(prim), REFLECT, STOP))
                branch = jnp.where(found & (index + 1 < levels), branch, STOP)
                o, d, tir = child(M.mats, prim, o, d, hit.t, hit.normal, branch)
                branch = jnp.where((branch == REFRACT) & tir, TIR, branch)
                alive, mirror = branch != STOP, branch == REFLECT
            row = jnp.stack([jnp.where(found, hit.prim, -1), jnp.where(found, cell, 0), branch,
                             jnp.where(found, face, 0), jnp.where(found, hit.sub, 0), *casts])
            return (o, d, alive, mirror), (row.astype(jnp.int32), jnp.where(found, hit.t, jnp.inf))

        def casters_at(found, hit, p, d):
            """The first caster towards each point light, then each grid sample (or ``sample``)."""
            casts = []
            if entries:  # the shadow ray as the model spawns it: from just off the surface
                n = jnp.where(jnp.dot(hit.normal, d) < 0, hit.normal, -hit.normal)
                p_out = p + guard(p) * n
                start = guard(p_out)
                for i in shadow_lights:
                    l, _, shadow_len = light_geometry(M.ctx, M.scene.lights[i], p)
                    caster = _first_caster(M.geo, plan, p_out, l, start, shadow_len - start, vis_shadow,
                                           casters, items)
                    casts.append(jnp.where(found & (jnp.dot(n, l) > lighting.NL_EPSILON), caster, -1))
            if grid_lights:  # towards each sample, as the model's shadow rays go
                towards = []  # (position, lit) of every sample
                for i, n_i in grid_lights:
                    l_i = light_geometry(M.ctx, M.scene.lights[i], p)[0]
                    lit = found & (jnp.dot(n, l_i) > lighting.NL_EPSILON)
                    towards.append((shadow_sample_points(M.ctx, M.scene.lights[i])[0],
                                    jnp.broadcast_to(lit, (n_i,))))
                targets, lit = (jnp.concatenate(x) for x in zip(*towards, strict=True))

                def caster_towards(q, lit, start=start, p_out=p_out):
                    to = q - p_out
                    dist = jnp.sqrt(jnp.maximum(jnp.dot(to, to), 1e-30))
                    first = _first_caster(M.geo, plan, p_out, to / dist, start, dist - start, vis_shadow,
                                          casters, items)
                    return jnp.where(lit, first, jnp.where(found, UNLIT, -1))

                if sample is None:
                    casts.extend(jax.vmap(caster_towards)(targets, lit))
                else:
                    one = caster_towards(targets[sample], lit[sample])
                    casts.extend(jnp.where(jnp.arange(n_samples) == sample, one, -1))
            return casts

        o, d = _image_ray(M.scene.camera, width, height, u, v)
        _, (rows_, ts) = jax.lax.scan(level_of, (o, d, jnp.asarray(True), jnp.asarray(False)),
                                      jnp.arange(levels))
        return rows_.reshape(-1), ts

    def path_ray(sc, pk, sig, level, u, v):
        """The ray at ``level`` of the path of signature ``sig`` through image point (u, v) of scene
        ``sc`` packed as ``pk``, a differentiable function of (u, v) and the scene: the camera ray,
        then each level's crossing with its primitive and the branch the signature took there."""
        o, d = _image_ray(sc.camera, width, height, u, v)
        if levels == 1:
            return o, d
        rows = sig.reshape(levels, width_)

        def bounce(carry, x):
            o, d, out_o, out_d = carry
            index, prim, branch, item = x
            prim = jnp.maximum(prim, 0)
            t, n = _nearest_hit(pk.geo, tables, prim, o, d, guard(o), sub=item)
            o, d, _ = child(pk.mats, prim, o, d, t, n, branch)
            out_o, out_d = jnp.where(level == index, o, out_o), jnp.where(level == index, d, out_d)
            return (o, d, out_o, out_d), None

        (_, _, out_o, out_d), _ = jax.lax.scan(bounce, (o, d, o, d),
                                               (jnp.arange(1, levels), rows[:-1, 0], rows[:-1, 2],
                                                rows[:-1, ITEM]))
        return out_o, out_d

    own = CASTERS + n_points  # channel 0's entries of a level: primitive … face, point-light casters
    channels = 1 + n_samples

    def stripped(s):
        """The signatures ``s`` (..., levels · width_) with each shadow entry its caster's primitive
        alone (the item a shadow ray crosses is carried, not compared: its outline is the edge)."""
        if not items:
            return s
        x = s.reshape(*s.shape[:-1], levels, width_)
        column = jnp.expand_dims(jnp.arange(width_) >= CASTERS, tuple(range(x.ndim - 1)))
        return jnp.where(column, _caster_prim(x, items), x).reshape(s.shape)

    def unequal(s_a, s_b):
        """(..., levels, width_): the entries in which signatures differ, but for the item seen (an
        entry of the primitive's own, unless its items are faces: a flat mesh's triangles), the item
        a shadow ray crosses, and the UNLIT entries (the light adds nothing either side)."""
        s_a, s_b = stripped(s_a), stripped(s_b)
        ne = ((s_a != s_b) & (s_a != UNLIT) & (s_b != UNLIT)).reshape(*s_a.shape[:-1], levels, width_)
        keep = jnp.expand_dims(jnp.arange(width_) != ITEM, tuple(range(ne.ndim - 1)))
        if item_faces is None:
            return ne & keep
        # the item, where one primitive whose items are faces is seen both sides on items of two
        # faces (two triangles of one quad are one face: no crease between them)
        a, b = s_a.reshape(ne.shape), s_b.reshape(ne.shape)
        prim = jnp.maximum(a[..., 0], 0)
        apart = ((a[..., 0] >= 0) & (a[..., 0] == b[..., 0]) & item_faces[prim]
                 & (a[..., ITEM] != b[..., ITEM]))
        one = jax.vmap(lambda p_, i, j: _one_face(M.geo, tables, p_, i, j))(
            prim.reshape(-1), a[..., ITEM].reshape(-1), b[..., ITEM].reshape(-1)).reshape(apart.shape)
        return (ne & keep) | (~keep & (apart & ~one)[..., None])

    def differs(s_a, s_b):
        """(..., channels): the channels in which signatures differ — 0: a level's primitive, cell,
        branch or point-light caster; 1 + s: the caster towards grid sample s at some level, where
        channel 0 agrees (an edge of the path itself counts once, in channel 0)."""
        ne = unequal(s_a, s_b)
        path = jnp.any(ne[..., :own], axis=(-2, -1))
        grid = jnp.any(ne[..., own:], axis=-2) & ~path[..., None]
        return jnp.concatenate([path[..., None], grid], axis=-1)

    def changed(s_a, s_b, ch, faces=True):
        """``(changed, level, entry)``: whether channel ``ch`` of the signatures differs, the first
        level of the path where it does, and there the shadow entry that differs (channel 0: the
        first point light's; else its grid sample's). Unless ``faces`` (a traced bool), the faces
        seen are not compared, nor the items (a flat mesh's triangles)."""
        ne = unequal(s_a, s_b)
        if faces is not True:
            ne = ne & (((jnp.arange(width_) != FACE) & (jnp.arange(width_) != ITEM)) | faces)[None, :]
        level = jnp.argmax(jnp.any(ne[:, :own], axis=1))
        differ = jnp.any(ne[:, :own])
        if n_samples:
            column = own + jnp.clip(ch - 1, 0, n_samples - 1)
            grid = ne[:, column]
            level = jnp.where(ch == 0, level, jnp.argmax(grid))
            differ = jnp.where(ch == 0, differ, jnp.any(grid))
        entry = jnp.argmax(ne[level, CASTERS:own]) if n_points else jnp.zeros((), jnp.int32)
        entry = jnp.where(ch == 0, entry, n_points + ch - 1)
        return differ, level, entry

    def towards_light(sc, entry, p):
        """The unit direction from ``p`` to the light or grid sample of shadow entry ``entry``."""
        l = jnp.zeros(3, p.dtype)
        for k_, i in enumerate(shadow_lights):
            l = jnp.where(entry == k_, light_geometry(M.ctx, sc.lights[i], p)[0], l)
        start = n_points
        for i, n in grid_lights:
            to = shadow_sample_points(M.ctx, sc.lights[i])[0][jnp.clip(entry - start, 0, n - 1)] - p
            l = jnp.where((entry >= start) & (entry < start + n),
                          to / jnp.sqrt(jnp.maximum(jnp.dot(to, to), 1e-30)), l)
            start += n
        return l

    def pattern_point(sc, pk, sig, level, prim, t_ref, u, v):
        """The pattern-space point of ``prim``'s top layer where the ray at ``level`` of the path
        through (u, v) crosses it (nearest ``t_ref``)."""
        o, d = path_ray(sc, pk, sig, level, u, v)
        item = sig.reshape(levels, width_)[level, ITEM]
        return point_in_pattern(pk, prim, o, d, _nearest_t(pk.geo, tables, prim, o, d, guard(o), t_ref, item))

    def point_in_pattern(pk, prim, o, d, t):
        """The pattern-space point of ``prim``'s top layer at ``o + t d`` (``o`` where t is inf)."""
        return _pattern_point(pk.mats, prim * pk.mats.n_layers, o + jnp.where(jnp.isfinite(t), t, 0.0) * d)

    centres = (jnp.arange(max(rows, cols), dtype=dtype) - 0.5) * h
    rays = levels * (1 + entries)  # a sample's rays: one a level, and one to each light or sample there
    # the lattice's rows split over the devices (each block of rows independent), each device's
    # share in blocks of whole rows
    per_block = max(1, min(-(-rows // n_dev), LATTICE_BLOCK // (rays * cols)))
    blocks = -(-rows // (per_block * n_dev)) * n_dev
    v_rows = jnp.concatenate([centres[:rows], jnp.full(blocks * per_block - rows, centres[0])])

    def lattice(v_blocks):  # (blocks, per_block) rows' v → their signatures
        def row(v):
            return jax.vmap(lambda u: seen(u, v)[0])(centres[:cols])

        return jax.lax.map(jax.vmap(row), v_blocks)

    sig = _split(lambda v: lattice(v.reshape(-1, per_block)).reshape(v.shape[0], cols, -1), v_rows, n_dev,
                 dynamic, on_devices)[:rows]

    # pairs that differ, by channel: rows' (r, c)–(r, c+1), then columns' (r, c)–(r+1, c), compacted
    across = differs(sig[:, :-1], sig[:, 1:]).reshape(-1)
    down = differs(sig[:-1, :], sig[1:, :]).reshape(-1)
    found = jnp.concatenate([across, down])
    which, count = nonzero(found, room)
    live = jnp.arange(room) < count

    def crossings(which):
        in_rows = which < across.size
        pair, ch = jnp.where(in_rows, which, which - across.size) // channels, which % channels
        r = jnp.where(in_rows, pair // max(cols - 1, 1), pair // cols)
        c = jnp.where(in_rows, pair % max(cols - 1, 1), pair % cols)
        return in_rows, ch, r, c

    # the crossings in order of the deepest level their bisection traces (the first where the pair
    # differs), those whose shadow entries differ after the others: a chunk's bisection traces the
    # levels and shadow rays its crossings ask for (a chunk of outlines seen directly, one ray)
    in_rows, ch, r, c = crossings(which)
    pa, pb_ = sig[r, c], sig[r + ~in_rows, c + in_rows]
    first_level = jax.vmap(lambda a, b, k: changed(a, b, k)[1])(pa, pb_, ch)
    ne = (stripped(pa) != stripped(pb_)).reshape(room, levels, width_)[..., CASTERS:]
    in_shadow = (ch > 0) | jnp.any(ne & (jnp.arange(levels)[None, :, None] <= first_level[:, None, None]),
                                   axis=(1, 2))
    order = stable_order(jnp.where(live, 2 * first_level + in_shadow, 2 * levels + 2), 2 * levels + 3)
    which, first_level, in_shadow = which[order], first_level[order], in_shadow[order]
    in_rows, ch, r, c = crossings(which)
    pa = sig[r, c]
    u0, v0 = (c.astype(dtype) - 0.5) * h, (r.astype(dtype) - 0.5) * h
    axis = jnp.stack([in_rows, ~in_rows], axis=-1).astype(dtype)  # (room, 2): along u or along v

    has, creased, casts_term = (jnp.asarray(x) for x in tables[2:5])
    if items:  # (a caster's item is known: a mesh's shadow outline is its triangle's)
        casts_term = casts_term | has

    def margins(sc, pk, s_lo, s_hi, face, level, entry, t_ref, u, v):
        """(6 or 8,) the margins an edge between the signatures ``s_lo`` and ``s_hi`` can be the zero
        of, at image point (u, v) of scene ``sc`` packed as ``pk``, along the ray of their paths'
        level ``level``: the outline of ``s_lo``'s primitive there, the outline of ``s_hi``'s,
        their seam (the distances' difference), the cell face ``face`` = (normal, offset) of a
        discrete pattern on one primitive (``normal · q − offset``, q its pattern-space point), the
        crease between two faces of one primitive (the difference of the line's crossings with the
        two faces' whole surfaces, ``AbstractShape.face_distance``), the onset of total internal
        reflection where the path refracts (``lighting.refract``'s discriminant, 1 + η²(c² − 1),
        at ``s_lo``'s crossing of the level: refraction on one side, its mirror ray on the
        other), and with shadows, the outlines
        of shadow entry ``entry``'s caster on ``s_lo``'s side and on
        ``s_hi``'s, along the line from the point seen towards that light or grid sample. Each
        primitive's crossing is the one nearest ``t_ref`` (held), the distance seen at the
        crossing: a CSG difference's cut is seen on its subtracted operand's far side."""
        a, b = s_lo.reshape(levels, width_)[level], s_hi.reshape(levels, width_)[level]
        geo_ = pk.geo
        o, d = path_ray(sc, pk, s_lo, level, u, v)
        lo_, hi_ = jnp.maximum(a[0], 0), jnp.maximum(b[0], 0)
        scale = guard(o)
        # both sides' crossings in one batch: the program holds one copy of each shape's kernels
        ts, ns = jax.vmap(lambda p_, item: _nearest_hit(geo_, tables, p_, o, d, scale, t_ref, item))(
            jnp.stack([lo_, hi_]), jnp.stack([a[ITEM], b[ITEM]]))
        t_lo, n_lo = ts[0], ns[0]
        seam = t_lo - ts[1]
        on_face = jnp.zeros((), o.dtype)
        if cells:  # the same ray and crossing as the outline's
            q = point_in_pattern(pk, lo_, o, d, t_lo)
            on_face = jnp.dot(face[0], q) - face[1]
            if _continuous(pk.mats):  # the value less the level it crosses, about it (a wrap: 0 or 1)
                row = lo_ * pk.mats.n_layers
                level = jnp.where(face[2] >= 0, pk.mats.values[row, jnp.maximum(face[2], 0)],
                                  jnp.where(face[2] == HALF, 0.5, 0.0))
                on_level = jnp.mod(_waved(pk.mats, row, q) - level + 0.5, 1.0) - 0.5
                on_face = jnp.where(face[2] == PLANE, on_face, on_level)
        crease = jnp.zeros((), o.dtype)
        if creases:  # between the faces of one primitive either side, along the same ray
            crease = _crease(geo_, tables, lo_, o, d, a[FACE] % LEAVING, b[FACE] % LEAVING, t_ref)
        entering = jnp.dot(n_lo, d) < 0
        n_facing = jnp.where(entering, n_lo, -n_lo)  # towards the ray, as ``child`` and the model turn it
        onset = jnp.zeros((), o.dtype)
        if levels > 1:  # total internal reflection: refraction's discriminant there (``child``)
            ior = jnp.asarray(pk.mats.ior)[lo_]
            onset = lighting.refraction_discriminant(d / jnp.sqrt(jnp.dot(d, d)), n_facing,
                                                     jnp.where(entering, 1.0 / ior, ior))
        # the outlines' margins, both sides' and (with shadows) both sides' casters', in one batch
        prims, subs = [lo_, hi_], [a[ITEM], b[ITEM]]
        origins, directions = [o, o], [d, d]
        if entries:
            p = o + jnp.where(jnp.isfinite(t_lo), t_lo, 0.0) * d
            l = towards_light(sc, entry, p)
            # along the shadow ray as the model spawns it (``casters_at``): from just off the
            # surface, so that where the caster is the surface seen (an area light's sample beyond
            # its horizon while the light's centre, which shades it, is not) its outline margin has
            # a simple zero where the ray grazes it, not the double zero of the line through p
            p_out = p + guard(p) * n_facing
            for s in (a, b):
                prims.append(jnp.maximum(_caster_prim(s[CASTERS + entry], items), 0))
                subs.append(_caster_item(s[CASTERS + entry], items))
                origins.append(p_out)
                directions.append(l)
        outline = jax.vmap(lambda p_, o_, d_, item: _margin(geo_, tables, p_, o_, d_, item))(
            *(jnp.stack(x) for x in (prims, origins, directions, subs)))
        out = [outline[0], outline[1], seam, on_face, crease, onset]
        if entries:
            seen_at = jnp.where(jnp.isfinite(t_lo), 0.0, jnp.nan)  # NaN: no point
            out += [outline[2] + seen_at, outline[3] + seen_at]
        if rims:  # each side's rim (one batch): its crossing nearest one of a primitive its conditions test
            def rim(p_):
                tested = jnp.asarray(leaves)[p_]
                own = _crossings(geo_, tables, p_, o, d, rim_k)
                others = jax.vmap(lambda q: _crossings(geo_, tables, jnp.maximum(q, 0), o, d, rim_k))(tested)
                gap = own[None, :, None] - jnp.where((tested >= 0)[:, None], others, jnp.inf)[:, None, :]
                size = jnp.where(jnp.isfinite(gap), jnp.abs(gap), jnp.inf)  # (M, k, k)
                nearest = jnp.argmin(jax.lax.stop_gradient(size).reshape(-1))
                return jnp.where(jnp.isfinite(jnp.min(size)), gap.reshape(-1)[nearest], jnp.nan)

            out += list(jax.vmap(rim)(jnp.stack([lo_, hi_])))
        if open_rims:  # a rim of the primitive's own, its inside seen on one side
            out.append(_per_prim(geo_, tables, lo_, o, d, lambda s, oo, dd, _: s.rim_margin(oo, dd), jnp.nan,
                                 only=lambda shapes: shapes.shows_inside()))
        return jnp.stack(out)

    def locate(s_a, u, v, e, ch, upto, shadows):
        """The first change of channel ``ch`` of what is seen along the pair's segment from its
        first sample, by bisection of the signature seen (a fixed number of steps): ``(lo, hi,
        signature seen at hi, kind, face, level, entry, t_ref, g_u, g_v, cross, signature seen at lo)``
        — ``lo``, ``hi`` in pixels
        along ``e`` from (u, v); ``kind`` the margin whose zero it is, at the paths' first level
        where the channel differs (0: the outline of ``s_a``'s primitive, 1: of the primitive
        beyond, 2: their seam, 3: a cell face of one primitive's pattern, 4: a crease between two of
        its faces, 5: the onset of total internal reflection, 6, 7: the outline of shadow entry
        ``entry``'s caster on either side; the one
        nearest the crossing in pixels, -1
        where none is within a hundredth of the spacing), ``t_ref`` the distance seen beyond the
        crossing at that level, the margin's derivatives along the image, and the crossing itself
        (pixels along ``e``: a Newton step on that margin from the bracket's middle, within it)."""
        # what is seen at ``hi`` is carried from the step that put it there: seen again, a ray a
        # rounding away may see the other side (the steps end at float resolution, on the edge)
        # (step 0 sees the pair's second sample: one copy of ``seen`` in the program)
        # (a channel's bisection traces its own grid sample's shadow ray, not the grid's)
        sample = jnp.clip(ch - 1, 0, n_samples - 1) if n_samples else None

        # a pair whose samples differ in more than the face seen looks for that difference: a crease
        # between them (a face a sliver's width) must not hide the outline beyond it
        # (the signature at ``lo`` is carried too: a mesh's outline is the edge of the triangle seen
        # there, not of the one the pair's first sample sees)
        checks = jnp.asarray(SIDE_CHECKS, dtype)

        def step(i, state):
            lo, hi, s_lo, s_hi, t_hi, faces, sides = state
            first = i == 0
            # past the bisection: the side points, lo's then hi's at each offset of SIDE_CHECKS
            j = i - (BISECTIONS + 1)
            bisecting, side = j < 0, jnp.clip(j, 0) % 2
            offset = checks[jnp.clip(j, 0) // 2]
            mid = jnp.where(first, hi, jnp.where(bisecting, 0.5 * (lo + hi),
                                                 jnp.where(side == 0, lo - offset, hi + offset)))
            s_mid, t_mid = seen(u + mid * e[0], v + mid * e[1], sample, (s_a, upto, shadows))
            faces = jnp.where(first, ~changed(s_a, s_mid, ch, False)[0], faces)
            same = ~changed(s_a, s_mid, ch, faces)[0] & ~first & bisecting
            as_side = ~changed(jnp.where(side == 0, s_lo, s_hi), s_mid, ch, faces)[0]
            take = ~bisecting & as_side & (sides[side] == SIDE_FALLBACK)  # (the first offset that does)
            sides = sides.at[side].set(jnp.where(take, offset, sides[side]))
            return (jnp.where(same, mid, lo), jnp.where(same | first | ~bisecting, hi, mid),
                    jnp.where(same, s_mid, s_lo), jnp.where(same | ~bisecting, s_hi, s_mid),
                    jnp.where(same | ~bisecting, t_hi, t_mid), faces, sides)

        start = (jnp.zeros((), dtype), jnp.asarray(h, dtype), s_a, s_a, jnp.full(levels, jnp.inf, dtype),
                 jnp.asarray(True), jnp.full(2, SIDE_FALLBACK, dtype))
        # (a chunk without shadows keeps SIDE_OFFSET: its edges are outlines, seams, cells, creases)
        steps = BISECTIONS + 1 + jnp.where(shadows, 2 * len(SIDE_CHECKS), 0)
        lo, hi, s_lo, s_hi, t_hi, faces, sides = jax.lax.fori_loop(0, steps, step, start)
        sides = jnp.where(shadows, sides, SIDE_OFFSET)
        _, level, entry = changed(s_a, s_hi, ch, faces)
        # the distance seen just beyond the crossing, at its level: each side's primitive is crossed
        # nearest it (a difference's cut is on its subtracted operand's far side)
        t_ref = jax.lax.stop_gradient(t_hi[level])
        a, b = s_lo.reshape(levels, width_)[level], s_hi.reshape(levels, width_)[level]
        p_lo, p_hi = a[0], b[0]
        one = (p_lo == p_hi) & (p_lo >= 0)
        face = (jnp.zeros(3, dtype), jnp.zeros((), dtype), jnp.asarray(PLANE, jnp.int32))
        has_face = jnp.zeros((), bool)
        if cells:  # the face between the cells just before and just after the crossing
            prim = jnp.maximum(p_lo, 0)
            q_a, q_b = (pattern_point(M.scene, M.packed, sig_, level, prim, t_ref, u + s * e[0], v + s * e[1])
                        for sig_, s in ((s_lo, lo - SIDE_OFFSET), (s_hi, hi + SIDE_OFFSET)))
            normal, offset, crossed, has_face = _face(M.mats, prim, q_a, q_b)
            face = (normal, offset, crossed)
        mid = 0.5 * (lo + hi)
        # every margin and its derivatives along the image at the crossing: one jvp, two tangents
        point = jnp.stack([u + mid * e[0], v + mid * e[1]])
        def at(uv):
            return margins(M.scene, M.packed, s_lo, s_hi, face, level, entry, t_ref, uv[0], uv[1])

        g, (g_u, g_v) = jax.vmap(lambda t: jax.jvp(at, (point,), (t,)), out_axes=(None, 0))(
            jnp.eye(2, dtype=dtype))
        g_s = g_u * e[0] + g_v * e[1]
        has_lo, has_hi = (p_lo >= 0) & has[jnp.maximum(p_lo, 0)], (p_hi >= 0) & has[jnp.maximum(p_hi, 0)]
        path = ch == 0
        # two items of one primitive whose items are faces (a flat mesh's triangles): a crease between
        # them, or its outline over itself, the zero of either item's outline margin (a crease: of
        # both, and of their seam)
        apart = ~one
        if item_faces is not None:
            apart = apart | (one & (a[ITEM] != b[ITEM]) & item_faces[jnp.maximum(p_lo, 0)])
        valid = [path & has_lo & apart, path & has_hi & apart, path & has_lo & has_hi & apart,
                 path & one & has_face & (a[1] != b[1]),
                 path & one & creased[jnp.maximum(p_lo, 0)] & (a[FACE] % LEAVING != b[FACE] % LEAVING),
                 path & one & (jnp.minimum(a[2], b[2]) == REFRACT) & (jnp.maximum(a[2], b[2]) == TIR)]
        if entries:  # (channel 0's shadow entries are the point lights')
            c_a, c_b = (_caster_prim(x[CASTERS + entry], items) for x in (a, b))
            shadow = one & (c_a != c_b) & (path == (entry < n_points))
            valid += [shadow & (c_ >= 0) & casts_term[jnp.maximum(c_, 0)] for c_ in (c_a, c_b)]
        if rims:  # where what is seen changes, or one primitive's side: a conditioned one's rim
            valid += [path & (p_ >= 0) & conditioned[jnp.maximum(p_, 0)] & (~one | (a[FACE] != b[FACE]))
                      for p_ in (p_lo, p_hi)]
        if open_rims:
            valid.append(path & one & shows_inside[jnp.maximum(p_lo, 0)] & (a[FACE] != b[FACE]))
        valid = jnp.stack(valid)
        valid = valid & jnp.isfinite(g) & (g_s != 0)
        distance = jnp.where(valid, jnp.abs(g) / jnp.where(g_s != 0, jnp.abs(g_s), 1.0), jnp.inf)
        kind = jnp.argmin(distance)
        # the crossing: one Newton step on the chosen margin from the bracket's middle, within it
        # (its place second order in the bracket's width)
        cross = jnp.clip(mid - g[kind] / jnp.where(g_s[kind] != 0, g_s[kind], 1.0), lo, hi)
        return (lo, hi, s_hi, jnp.where(distance[kind] <= 0.01 * h, kind, -1), face, level, entry, t_ref,
                g_u[kind], g_v[kind], cross, s_lo, sides)

    # 2.–4. a loop over the chunks of the room that hold crossings (the rest costs nothing): each
    # crossing located, and the two camera rays just before and just after it along its axis traced
    # through the model (3.: the chosen margin's derivatives along the image come with it: g_u, g_v)
    # (``_chunks.map_in_place``: a while loop up to the last chunk with a live crossing)

    def locate_chunk(x):
        pa_, u_, v_, e_, ch_, alive, first_, shadow_ = x
        # (the chunk's deepest level and whether it needs shadows: not batched, so skipping skips)
        upto = jnp.max(jnp.where(alive, first_, 0)).astype(jnp.int32)
        res = jax.vmap(locate, in_axes=(0, 0, 0, 0, 0, None, None))(pa_, u_, v_, e_, ch_, upto,
                                                                   jnp.any(alive & shadow_))
        lo_, hi_, kind_, sides_ = res[0], res[1], res[3], res[12]
        ok_ = alive & (kind_ >= 0)
        points = jnp.concatenate([jnp.stack([u_ + s_ * e_[:, 0], v_ + s_ * e_[:, 1]], -1)
                                  for s_ in (lo_ - sides_[:, 0], hi_ + sides_[:, 1])])
        o, d = camera_rays(M.scene.camera, points[:, 0] / width - 0.5, 0.5 - points[:, 1] / height)
        colours, dropped = trace(M.ctx, o, d, chunk=CHUNK, capacity=capacity, media=M.media,
                                 alive=jnp.concatenate([ok_, ok_]))
        lost = jnp.zeros(CHUNK, jnp.int32).at[0].set(jnp.sum(dropped).astype(jnp.int32))
        return (*res, colours[:CHUNK] - colours[CHUNK:], lost)

    found_ = _dealt_map(locate_chunk, (pa, u0, v0, axis, ch, live, first_level, in_shadow), live, n_dev,
                        dynamic, on_devices)
    (lo, hi, pb, kind, face, level, entry, t_ref, g_u, g_v, cross, p_lo, _, jump,
     lost) = jax.tree.map(sg, found_)
    dropped = jnp.sum(lost)
    ok = live & (kind >= 0)
    g_u, g_v = jnp.where(ok, g_u, 0.0), jnp.where(ok, g_v, 0.0)
    pu, pv = u0 + cross * axis[:, 0], v0 + cross * axis[:, 1]
    # the margin's tangent is taken where its derivatives along the image were (the bracket's
    # middle, within 2⁻¹³ of a spacing of the crossing), on the same side of the edge: a margin that
    # is one function on each side (an open tube's rim) has one scale on each
    mid = 0.5 * (lo + hi)
    mu, mv = u0 + mid * axis[:, 0], v0 + mid * axis[:, 1]

    # a crossing of a row moves by −g_θ/g_u; its share of the edge integral is w_u = g_u⁴/(g_u⁴ + g_v⁴)
    # (a column's w_v = 1 − w_u): the shares add up to ∫ ds, and the row integrand vanishes as
    # n_u³ where the edge turns along the rows, so the rows' midpoint sums converge fast there
    along, other = jnp.where(in_rows, g_u, g_v), jnp.where(in_rows, g_v, g_u)
    quartic = along ** 4 + other ** 4
    # a crease across which the shading does not change (a flat-coloured box, two triangles of a
    # mesh in one plane: equal but for roundings) is no edge: it has no term, and must not end the
    # stretch of an outline beside it
    crease = (kind == CREASE) | (kind == CELL)  # (a cell edge between two cells of one colour)
    if item_faces is not None:  # (an outline of one of two items of one primitive: a mesh's crease)
        at_level = jnp.arange(room), level
        crease = crease | ((kind <= 2) & (p_lo.reshape(room, levels, width_)[at_level][:, 0]
                                          == pb.reshape(room, levels, width_)[at_level][:, 0]))
    flat = jnp.all(jnp.abs(jump) <= 64 * jnp.finfo(dtype).eps, axis=-1)
    usable = ok & (quartic > 0) & ~(crease & flat)
    at, across = jnp.where(in_rows, pu, pv), jnp.where(in_rows, pv, pu)
    slope = jnp.where(usable, -other / jnp.where(along != 0, along, 1.0), 0.0)  # d(at)/d(across)
    low, high = _extents(usable, in_rows, r, c, ch, at, across, along, other, slope, stripped(pa),
                         stripped(pb),
                         lambda pa_, pb_, idx, j, ch_: _transition(pa_, pb_, idx, j, ch_, levels, width_, own,
                                                                  n_samples),
                         rows, cols, channels, h, n_dev)
    span = high - low
    weight = jnp.where(usable, -span * along ** 3 / jnp.where(usable, quartic, 1.0), 0.0)
    scale = jnp.where(usable[:, None], weight[:, None] * jump, 0.0)  # (room, 3): the jump L⁻ − L⁺ per g_θ

    # 3. the chosen margin's derivative along the tangent g_θ, and the term: each crossing's
    # ``scale · g_θ`` spread over the pixels its stretch of the edge passes. A linear map of the
    # tangent by a loop over the live chunks, and its transpose by another (``linear_call``: JAX
    # transposes no loop whose length the program computes): reverse mode's work follows the
    # edges too. The margins are a function of the scene's arrays and of its packed arrays (packed
    # once, outside the loops; reverse mode transposes the packing once).
    pk_held = eqx.filter(packed, eqx.is_inexact_array, inverse=True)

    def packed_floats(dyn_):
        return eqx.filter(pack(eqx.combine(dyn_, static), plan), eqx.is_inexact_array)

    pk_floats, pk_dot = jax.jvp(packed_floats, (dynamic,), (tangent,))
    flat_dot, unravel = ravel_pytree((tangent, pk_dot))
    per_margin = (kind, p_lo, pb, face, level, entry, t_ref, mu, mv)
    per_spread = (scale, in_rows, at, across, low, high, slope, span)

    def chosen(point, i, per):
        """(CHUNK,): the chosen margin of chunk ``i``'s crossings, the scene's arrays and its packed
        arrays ``point``."""
        dyn_, pkf = point
        sc, pk = eqx.combine(dyn_, static), eqx.combine(pkf, pk_held)
        kind_, *rest = (jax.tree.map(lambda x: _take(x, i), y) for y in per)
        return jax.vmap(lambda k_, *a: margins(sc, pk, *a)[jnp.maximum(k_, 0)])(kind_, *rest)

    # (closure-free: the transpose is traced when reverse mode gets to it, after this trace ends,
    # so every array it uses is an argument; the margins' own arrays are the jaxpr's constants)
    point = (dynamic, pk_floats)
    program = jax.make_jaxpr(chosen)(point, jnp.zeros((), jnp.int32), per_margin)

    def margin_of(consts, point, i, per):
        fn = jaxpr_as_fun(ClosedJaxpr(program.jaxpr, consts))
        return fn(*jax.tree.leaves((point, i, per)))[0]

    def spread_chunk(per, i, g):
        scale_, *rest = (_take(x, i) for x in per)
        return _spread(scale_ * g[:, None], *rest, width, height, dtype)

    def term(res, flat):
        consts, point, n, per_m, per_s = res
        lin = unravel(flat)

        def body(i, image):
            g = jax.jvp(lambda p: margin_of(consts, p, i, per_m), (point,), (lin,))[1]
            return image + spread_chunk(per_s, i, g)

        return jax.lax.fori_loop(0, n, body, jnp.zeros((height, width, 3), dtype))

    def term_transposed(res, ct):
        consts, point, n, per_m, per_s = res

        def body(i, acc):
            (g_ct,) = jax.linear_transpose(lambda g: spread_chunk(per_s, i, g), jnp.zeros(CHUNK, dtype))(ct)
            _, pull = jax.vjp(lambda p: margin_of(consts, p, i, per_m), point)
            return acc + ravel_pytree(pull(g_ct)[0])[0]

        return jax.lax.fori_loop(0, n, body, jnp.zeros_like(flat_dot))

    n_live = ((jnp.minimum(count, room) + CHUNK - 1) // CHUNK).astype(jnp.int32)
    held = (program.consts, point, n_live, per_margin, per_spread)
    image = linear_call(term, term_transposed, held, flat_dot)
    unresolved = jnp.sum(live & ~ok)
    return Edges(image, count, unresolved, jnp.maximum(count - room, 0), dropped)
