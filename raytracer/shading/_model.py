"""POV-Ray's shading model for ONE ray: what it hits, the colour it sees there, the rays it spawns.

``shade(ctx, ray)`` takes one ray and returns a :class:`Shading`: the local colour at the hit and
the children the hit spawns (:class:`Child`: the child ray with the coefficient and exponent its
colour is combined with). It knows nothing of pools, levels or compaction of the tree: the
scheduler (``_scheduler.py``) calls ``shade_batch(ctx, rays)`` on chunks of a pool (``shade``
vmapped; the shadows of adaptive area lights are computed for the chunk at once) and assembles
the tree.

What one hit computes:
  * every texture layer, top first (semantics §2.3): each layer's ambient + emission + diffuse + highlights
    (phong, specular, metallic tint; none from shadowless lights), scaled by the layer's opacity
    ``1 - filter - transmit`` and filtered by the layers above it; a layer is skipped once the
    layers above let less than ``adc_bailout`` through. The layers' reflection colours add up
    (the mirror ray's weight is the largest); with ``conserve_energy`` a layer's filter is reduced
    by its reflection. The transmitted ray sees through the product of all layers' filters;
  * light arrival per light (semantics §2.4, §2.5): fade with distance, spotlight cone, shadow rays that
    opaque objects block and transparent ones filter (every layer of a crossed object filters,
    and an exit crossing fades by the interior crossed), area lights as a grid of shadow rays
    with POV's corner-averaging weights;
  * reflectivity (semantics §2.6): reflection min/max with falloff, fresnel, metallic tint;
  * the children: the transmitted ray (refracted, or straight through where the ior is 1; the
    totally internally reflected ray in its place under TIR), attenuated by the interior it
    leaves; and the mirror ray, weighted by the summed reflection colour.

Only the children the scene can spawn exist: the mirror ray only if some finish reflects, the
transmitted ray only if some pigment can be transparent (semantics §2.3, semantics §2.7).

Modelling shortcuts (stated, not hidden):
  * the layers' reflections are summed and traced along ONE mirror ray, with the top layer's
    ``exponent`` (the plan warns when more than one layer of a texture reflects);
  * entering/leaving an object is decided from the geometric normal; the media on either side come
    from the ray's list of the interiors it is inside (POV-Ray's per-ray interior list, at most
    ``Effects.media_slots`` ≤ ``_plan.MEDIA_SLOTS`` deep), with POV-Ray's quirk at exits from two
    or more (semantics §2.7);
  * shadow rays go straight through transparent objects (no refraction, no caustics), as POV's;
  * straight transmission (ior 1) does not use up a trace level (as in POV-Ray), but a ray path may
    pass at most ``Effects.straight_passes`` straight surfaces beyond ``max_trace_level`` levels.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import patterns
from .._plan import Effects, InPrim, Plan, leaf_prims
from ..kernels import matvec, safe_pow
from ..scene import Light, Settings
from ..scene._lights import area_blocks, light_types, point_geometry
from . import _accel, lighting
from ._chunks import map_live
from ._geometry import (
    CandidateView,
    PackedGeometry,
    all_crossings,
    bound_mask,
    build_inside_circuit,
    candidate_view,
    closest_hit,
    csg_mask,
    evaluate_inside,
    hierarchy_filters,
    leaf_values_of,
    prim_bits,
    solo_prims,
)
from ._materials import (
    PackedMaterials,
    costly_patterns,
    pack_pigments,
    pigment_at,
    pigments_at,
    solid_rows,
    texture_choice,
    texture_pigments,
)
from ._normals import perturbed


class Rays(NamedTuple):
    """Rays, one per leading index (or a single ray: no leading axis).

    origin:     (..., 3) start point, world space.
    direction:  (..., 3) unit direction of travel.
    weight:     (...,)   POV-Ray's ray weight: the largest factor by which this ray's colour can
                         reach the pixel (compared with ``adc_bailout``).
    alive:      (...,)   bool; a dead ray hits nothing and sees black (an empty slot of the tree).
    reflection: (...,)   bool; the ray is a mirror ray (``no_reflection`` objects hide from it).
    level:      (...,)   int32 POV-Ray trace level (1 for camera rays).
    media:      (..., K) int32 the primitives whose interiors the ray is inside, in the order it
                         entered them, packed at the front, ``-1`` after (K = ``media_slots``; 0
                         in scenes without refraction).
    """

    origin: jax.Array
    direction: jax.Array
    weight: jax.Array
    alive: jax.Array
    reflection: jax.Array
    level: jax.Array
    media: jax.Array


def media_slots(effects: Effects) -> int:
    """The length of a ray's interior list (``Effects.media_slots``): only refraction needs to
    know the medium a ray is in."""
    return effects.media_slots


def dead_rays(n: int, dtype, slots: int) -> Rays:
    """``n`` empty slots of a pool (a unit direction keeps their masked maths finite)."""
    unit_z = jnp.broadcast_to(jnp.asarray([0.0, 0.0, 1.0], dtype), (n, 3))
    return Rays(origin=jnp.zeros((n, 3), dtype), direction=unit_z, weight=jnp.zeros(n, dtype),
                alive=jnp.zeros(n, bool), reflection=jnp.zeros(n, bool), level=jnp.ones(n, jnp.int32),
                media=jnp.full((n, slots), -1, jnp.int32))


def _media_last(media):
    """The innermost interior of a packed list (-1 if empty)."""
    count = jnp.sum(media >= 0)
    return jnp.where(count > 0, media[jnp.maximum(count - 1, 0)], -1)


def _media_without(media, prim):
    """The list with the last entry of ``prim`` taken out (the rest keep their order, packed at the
    front): a ray inside two overlapping parts of one medium is still inside after leaving one.
    A list is always packed (``_media_with``, ``initial_media``), so the entries after the one
    taken out move down one slot: selects, not a scatter (XLA's CPU scatter is a serial loop)."""
    index = jnp.arange(media.shape[0])
    last = jnp.max(jnp.where(media == prim, index, -1))
    after = jnp.concatenate([media[1:], jnp.full((1,), -1, media.dtype)])
    return jnp.where((last >= 0) & (index >= last), after, media)


def _media_with(media, prim):
    """The list with ``prim`` entered last (the oldest entry is dropped if the list is full)."""
    count = jnp.sum(media >= 0)
    full = count >= media.shape[0]
    shifted = jnp.where(full, jnp.roll(media, -1), media)
    at = jnp.where(full, media.shape[0] - 1, count)
    return jnp.where(jnp.arange(media.shape[0]) == at, prim, shifted)  # (a select, not a scatter)


class Child(NamedTuple):
    """A ray spawned by a hit and how its colour ``c`` comes back: ``coef · c^power``.

    ray:   the child ray (``alive`` False where the hit spawns none).
    coef:  (..., 3) colour coefficient.
    power: (...,) exponent applied to the child's colour (the mirror ray's ``1/exponent``), or
           None where there is none (the transmitted ray): static, not a value of 1.
    """

    ray: Rays
    coef: jax.Array
    power: jax.Array | None


class Shading(NamedTuple):
    """What one ray sees: its local colour (..., 3) and its children, in a fixed static order
    (:func:`child_slots`): the mirror ray, then the transmitted ray, each only if the scene has it."""

    local: jax.Array
    children: tuple[Child, ...]


def child_slots(effects: Effects) -> int:
    """How many children a hit can spawn in this scene (0, 1 or 2: see :class:`Shading`)."""
    return int(effects.reflection) + int(effects.transmission)


def camera_rays(origin, direction, media=None, alive=None) -> Rays:
    """Camera rays (N, 3): alive (or as ``alive`` (N,) bool says: a dead one is padding, traced by
    nothing), weight 1, trace level 1 (POV counts the camera ray as level 1), inside the interiors
    ``media`` (K,) (``initial_media``; None: none)."""
    n = origin.shape[0]
    media = jnp.zeros((0,), jnp.int32) if media is None else media
    return Rays(origin=origin, direction=direction, weight=jnp.ones(n, origin.dtype),
                alive=jnp.ones(n, bool) if alive is None else alive, reflection=jnp.zeros(n, bool),
                level=jnp.ones(n, jnp.int32),
                media=jnp.broadcast_to(media, (n, media.shape[0])))


def initial_media(ctx: TraceContext, eye) -> jax.Array:
    """(K,) the media containing the point ``eye`` (the camera), in scene order: POV-Ray starts
    every camera ray inside every object that contains the camera, infinite planes included. An
    object counts once (a hollow glass ``difference`` does not contain its cavity); primitives with
    no inside (triangles, meshes) contain nothing.

    A medium is named by the first primitive sharing its interior (``medium_ids``), and every
    object's primitives are numbered in scene order, so "in scene order" is the order of the
    media's names. The objects of one primitive (``solo_prims``) in the hierarchy's padded groups
    are tested as arrays, one vmap per group (no table of the scene's size in the program:
    another number of them is the same program); the others (a union's children among them:
    their object's tree decides) through the inside circuit."""
    slots = media_slots(ctx.plan.effects)
    if not slots or not ctx.plan.roots:
        return jnp.full(slots, -1, jnp.int32)
    geo = ctx.geo
    eye = jnp.asarray(eye)
    medium = jnp.asarray(geo.prim_table["medium"])
    sign = jnp.asarray(geo.prim_table["sign"])
    present = jnp.zeros(medium.shape[0], bool)
    tested: dict[int, jax.Array] = {}

    def inside_of(g):  # every member of group g at the eye, once for both uses below
        if g not in tested:
            tested[g] = jax.vmap(lambda s, m: s.inside(matvec(m[:3, :3], eye) + m[:3, 3]))(
                geo.shapes[g], geo.object_from_world[g])
        return tested[g]

    held: set[int] = set()  # objects of one primitive tested here (a union's children are not)
    solo = solo_prims(ctx.plan)
    for g, members in enumerate(geo.member_prims or ()):
        if members is None:
            continue
        held.update(solo.intersection(geo.groups[g].prims))
        members = jnp.asarray(members)
        inside = inside_of(g) if geo.groups[g].solid else jnp.zeros(members.shape[0], bool)
        prim = jnp.maximum(members, 0)
        inside = (inside != (sign[prim] < 0)) & (members >= 0)  # the object is its primitive
        present = present.at[medium[prim]].max(inside)
    roots = [tree for tree in ctx.plan.roots if not (isinstance(tree, InPrim) and tree.prim in held)]
    if roots:
        leaves = [sorted(leaf_prims(tree)) for tree in roots]
        trees = [(tree, 0) for tree in roots] + [(InPrim(q, ctx.plan.prims[q].inverse), 0)
                                                   for ls in leaves for q in ls]
        circuit = build_inside_circuit(trees)
        inside = evaluate_inside(geo, circuit, eye[None, :], leaf_values_of(geo, circuit, inside_of))
        # a leaf's medium is present where both its object and the leaf itself contain the eye
        root_of = np.concatenate([np.full(len(ls), r, np.int32) for r, ls in enumerate(leaves)])
        leaf = np.concatenate([np.asarray(ls, np.int32) for ls in leaves])
        present = present.at[medium[leaf]].max(inside[root_of] & inside[len(roots):])
    return jnp.nonzero(present, size=slots, fill_value=-1)[0].astype(jnp.int32)


@dataclasses.dataclass(frozen=True)
class TraceContext:
    """The scene as the shading model sees it (packed arrays and static masks over candidates)."""

    plan: Plan
    geo: PackedGeometry
    mats: PackedMaterials
    lights: tuple[Light, ...]
    settings: Settings
    background: jax.Array
    dtype: object
    eps: float  # relative spawn offset (times 1 + |p|)
    vis_camera: np.ndarray  # (C,) visible to camera and transmitted rays
    vis_reflect: np.ndarray  # (C,) visible to reflected rays
    shadow: CandidateView  # the candidates that cast shadows (slots S below)
    transparent_cands: np.ndarray  # (S,) slot belongs to a transparent-capable prim
    inverse_sign: np.ndarray  # (S,) -1 where the prim is inverted
    fading_cands: np.ndarray  # shadow slots of transparent prims whose interior may fade
    accel_filters: bool  # the hierarchy holds transparent shadow-casting items (``MASK_FILTER``)
    accel_fades: bool  # ... and some of them have an interior that fades
    accel_filter_layers: int  # ... and the most texture layers one of them has
    # the scene's environment effects that are on, each with its packed arrays (``pack_environment``)
    environment: tuple = ()


def pack_environment(environment, dtype) -> tuple:
    """``scene.environment_of(scene)``'s effects, each with the arrays its entry packs."""
    return tuple((e, e.pack(v, dtype, pack_pigments)) for e, v in environment)


def make_context(plan: Plan, geo: PackedGeometry, mats: PackedMaterials, lights, settings,
                 background, dtype, environment=()) -> TraceContext:
    """``environment``: ``scene.environment_of(scene)``."""
    prims = plan.prims
    bits = prim_bits(plan)  # the hierarchy's items use them too
    # shadow rays compute the crossings of shadow casters only (no_shadow objects are skipped)
    shadow = candidate_view(geo, plan, lambda i: bool(bits[i] & (_accel.MASK_SHADOW | _accel.MASK_FILTER)))
    filters, fades, filter_layers = hierarchy_filters(geo, plan)
    return TraceContext(
        plan=plan, geo=geo, mats=mats, lights=tuple(lights), settings=settings,
        background=background.astype(dtype), dtype=dtype,
        environment=pack_environment(environment, dtype),
        eps=2e-5 if dtype == jnp.float32 else 1e-9,
        vis_camera=(bits[geo.cand_prim] & _accel.MASK_CAMERA) != 0,
        vis_reflect=(bits[geo.cand_prim] & _accel.MASK_REFLECT) != 0,
        shadow=shadow,
        transparent_cands=np.asarray(mats.transparent, bool)[shadow.cand_prim],
        inverse_sign=geo.prim_sign[shadow.cand_prim],
        fading_cands=np.flatnonzero([prims[i].transparent and prims[i].fades for i in shadow.cand_prim]),
        accel_filters=filters,
        accel_fades=fades,
        accel_filter_layers=filter_layers,
    )


# ---------------------------------------------------------------- shadows
def _filter_of(mats: PackedMaterials, row, p):
    """RGB filter ``f·P + t`` of material row ``row``'s pigment at world point ``p`` (semantics §2.5)."""
    return _textured_filters(mats, row[None], p[None], _rgb_filter(pigment_at(mats, row, p))[None])[0]


def _textured_filters(mats: PackedMaterials, rows, points, f):
    """The filters ``f`` (E, 3) of material rows ``rows`` (E,) at ``points`` (E, 3), a patterned
    texture's made its own (semantics §5.7): at its top layer's row the product of each of its
    textures' layers' filters, blended by its pattern as its colours are; 1 at its other rows."""
    textures = mats.textures
    if textures is None:
        return f
    prim = rows // mats.n_layers
    patterned = jnp.asarray(textures.tables["prim_patterned"])[prim]

    def blended(prim, p):
        leaves, weights = texture_choice(textures, prim, p)

        def leaf_filter(leaf):
            pig, present = texture_pigments(textures, leaf, p)
            return jnp.prod(jnp.where(present[:, None], _rgb_filter(pig), 1.0), axis=0)

        return jnp.tensordot(weights, jax.vmap(leaf_filter)(leaves), axes=1)

    mine = jnp.where((rows % mats.n_layers == 0)[:, None], jax.vmap(blended)(prim, points), 1.0)
    return jnp.where(patterned[:, None], mine, f)


def _rgb_filter(pig):
    """RGB filter ``f·P + t`` of RGBFT pigments ``pig`` (…, 5)."""
    return pig[..., 3:4] * pig[..., :3] + pig[..., 4:5]


def _transparent_pairs(ctx: TraceContext):
    """The (transparent shadow candidate, present layer) pairs, static: each pair's material row and
    its candidate slot of ``ctx.shadow``, and whether the row's pigment is a solid colour."""
    cands = np.flatnonzero(ctx.transparent_cands)
    prims = ctx.shadow.cand_prim[cands]
    slot, layer = np.nonzero(ctx.mats.layer_present[prims])
    rows = prims[slot] * ctx.mats.n_layers + layer
    return rows, cands[slot], solid_rows(ctx.mats, rows)


class _Filters(NamedTuple):
    """A shadow segment's transmittance: ``base`` (its opaque crossings, solid pigments, interior
    fade) times the filter ``f·P + t`` of the patterned pigment of material row ``rows[e]`` at
    ``points[e]`` for every ``e`` where ``use[e]``. Kept apart so that a batch can compute the
    patterned pigments of all its shadow rays together (``shade_batch``)."""

    base: jax.Array  # (3,)
    rows: jax.Array  # (E,) int32
    points: jax.Array  # (E, 3)
    use: jax.Array  # (E,) bool


def _filters(base, requests, dtype) -> _Filters:
    if not requests:
        return _Filters(base, jnp.zeros((0,), jnp.int32), jnp.zeros((0, 3), dtype), jnp.zeros((0,), bool))
    rows, points, use = (jnp.concatenate(x) for x in zip(*requests, strict=True))
    return _Filters(base, rows, points, use)


def _filtered(fl: _Filters, f):
    """The transmittance ``fl`` stands for, given the RGB filters ``f`` (E, 3) of its pigments."""
    return fl.base * jnp.prod(jnp.where(fl.use[:, None], f, 1.0), axis=0)


def _filters_value(ctx: TraceContext, fl: _Filters):
    """``_filtered`` with the pigments computed here (every pattern of the scene, one ray's code)."""
    if fl.rows.shape[-1] == 0:
        return fl.base  # (no pigment to trace: a vmap over no entries traces every pattern all the same)
    f = jax.vmap(lambda row, p: _filter_of(ctx.mats, row, p))(fl.rows, fl.points)
    return _filtered(fl, f)


def _shadow_filter(ctx: TraceContext, o, l, dist):
    """RGB transmittance of the segment ``o → o + dist·l`` (semantics §2.5): opaque crossings block,
    transparent ones multiply by ``f·P + t`` at each crossing; refraction is ignored."""
    return _filters_value(ctx, _shadow_filters(ctx, o, l, dist))


def _shadow_filters(ctx: TraceContext, o, l, dist) -> _Filters:
    """:func:`_shadow_filter`'s transmittance with its patterned pigments still to compute."""
    scale = ctx.eps * (1.0 + jnp.max(jnp.abs(o)))
    base = jnp.ones(3, ctx.dtype)
    requests = []
    # opaque primitives the hierarchy holds: does any lie on the segment (an any-hit query)
    blocked = (jnp.zeros((), bool) if ctx.geo.accel is None
               else _accel.blocked(ctx.geo.accel, o, l, scale, dist - scale))
    crossed = None
    if ctx.geo.accel is not None and ctx.accel_filters:
        # transparent items the hierarchy holds: each crossing filters by its layers' pigments
        overflow, request, crossed = _accel_filter(ctx, o, l, scale, dist - scale)
        base = jnp.where(overflow, 0.0, base)
        requests.append(request)
    if not ctx.accel_fades:
        crossed = None  # (no item of the hierarchy has an interior that fades)
    view = ctx.shadow
    if not view.cand_prim.size:
        if crossed is not None and ctx.plan.effects.interior_fade:
            base = base * _shadow_fade(ctx, l, None, crossed)
        return _filters(jnp.where(blocked, 0.0, 1.0) * base, requests, ctx.dtype)
    t, n = all_crossings(ctx.geo, o, l, view.members)
    ok = jnp.isfinite(t) & (t > scale) & (t < dist - scale)
    ok = ok & csg_mask(ctx.geo, view.conditions, o, l, t) & bound_mask(ctx.geo, view.bounds, o, l, scale,
                                                                        t.shape[0])
    if not ctx.plan.effects.filtered_shadows:
        return _filters(jnp.where(jnp.any(ok) | blocked, 0.0, 1.0) * base, requests, ctx.dtype)
    opaque = ok & ~jnp.asarray(ctx.transparent_cands)
    safe_t = jnp.where(jnp.isfinite(t), t, 0.0)
    # every present layer of every transparent crossing filters (semantics §2.5): the (crossing,
    # layer) pairs are static, and one vmapped pigment evaluation serves them all. (A Python loop
    # over them traced a pattern per pair: advanced/pawns.pov's noise patterns made a program of
    # 316,000 operations that took 4 minutes to compile.)
    rows, where, solid = _transparent_pairs(ctx)  # (pairs,) static
    if rows.size:
        # a solid pigment's filter is its colour's, wherever the crossing is: no point, no pattern
        # (interior/iortest.pov: 40 crossings of 7 lights' shadow rays, most of them clear glass,
        # each took its point into pattern space and evaluated the scene's checker)
        if solid.any():
            f = _rgb_filter(ctx.mats.colors[jnp.asarray(rows[solid], jnp.int32), 0])  # (solid pairs, 3)
            base = base * jnp.prod(jnp.where(ok[where[solid]][:, None], f, 1.0), axis=0)
        if not solid.all():
            points = o[None, :] + safe_t[where[~solid]][:, None] * l[None, :]
            requests.append((jnp.asarray(rows[~solid], jnp.int32), points, ok[where[~solid]]))
    if ctx.plan.effects.interior_fade and (ctx.fading_cands.size or crossed is not None):
        base = base * _shadow_fade(ctx, l, (t, n, ok), crossed)
    return _filters(jnp.where(jnp.any(opaque) | blocked, 0.0, 1.0) * base, requests, ctx.dtype)


def _shadow_fade(ctx: TraceContext, l, cand, crossed):
    """Interior fade of a shadow segment: at every exit crossing of a fading object, over the depth
    since the previous crossing (or the shadow ray's start), since the shadow ray continues from
    each hit (semantics §2.4; povray 3.7 measured: a fading sphere attenuates a shadow by its chord,
    not by the air before it). ``cand``: the candidates' crossings ``(t (S,), n (S, 3), ok (S,))``
    on the segment, or None; ``crossed``: the hierarchy's transparent items on it (``Crossed``), or
    None. The previous crossing is taken over both."""
    m = ctx.mats
    accepted, tc, normals, prims, signs, oks = [], [], [], [], [], []
    if cand is not None:
        t, n, ok = cand
        fading = ctx.fading_cands
        accepted.append(jnp.where(ok, t, -jnp.inf))
        tc.append(accepted[-1][fading])
        normals.append(n[fading])
        prims.append(jnp.asarray(ctx.shadow.cand_prim[fading]))
        signs.append(jnp.asarray(ctx.inverse_sign[fading], n.dtype))
        oks.append(ok[fading])
    if crossed is not None:
        k, j = crossed.t.shape
        ok = jnp.isfinite(crossed.t).reshape(-1)
        accepted.append(jnp.where(ok, crossed.t.reshape(-1), -jnp.inf))
        tc.append(accepted[-1])  # every crossing: an interior without fade attenuates by 1
        normals.append(crossed.normal.reshape(k * j, 3))
        prims.append(jnp.repeat(crossed.prim, j))
        signs.append(jnp.asarray(ctx.geo.prim_table["sign"], crossed.t.dtype)[prims[-1]])
        oks.append(ok)
    accepted, tc, n, prims, sign, ok = map(jnp.concatenate, (accepted, tc, normals, prims, signs, oks))
    prev = jnp.max(jnp.where(accepted[None, :] < tc[:, None], accepted[None, :], 0.0), axis=1)
    exiting = ok & (jnp.einsum("ri,i->r", n, l) * sign > 0)
    att = lighting.interior_fade(jnp.where(exiting, tc - prev, 0.0)[:, None],
                                 m.fade_distance[prims][:, None], m.fade_power[prims][:, None],
                                 m.fade_color[prims], on=exiting[:, None], shadow_ray=True)
    return jnp.prod(att, axis=0)


def _accel_filter(ctx: TraceContext, o, l, t_min, t_max):
    """The transparent shadow-casting items the hierarchy holds on the segment: whether there are
    more than ``_accel.FILTER_ITEMS`` of them (the farthest are dropped and the segment counts as
    blocked: a shadow through that many transparent surfaces is dark already; documented in
    architecture.md), the pigments that filter the light (every present layer of every crossing,
    as for candidates: ``(rows, points, use)`` of a ``_Filters``), and the items crossed
    (``_accel.Crossed``: their interiors' fade is ``_shadow_fade``'s)."""
    crossed = _accel.filtering(ctx.geo.accel, ctx.geo.shapes, ctx.geo.object_from_world, o, l, t_min, t_max)
    m = ctx.mats
    # the layers a transparent item can have, not the scene's most: every slot here is an entry of
    # every shadow ray's requests (incdemo/texture2.pov: 16 items x 4 crossings x 3 layers of which
    # its glass has 1, 154,800 entries a chunk of 400 points and 2 lights)
    n_layers = ctx.accel_filter_layers
    present = jnp.asarray(m.tables["layer_present"])[crossed.prim][:, :n_layers]  # (k, L)
    ok = jnp.isfinite(crossed.t)  # (k, J)
    points = o[None, None, :] + jnp.where(ok, crossed.t, 0.0)[..., None] * l[None, None, :]  # (k, J, 3)
    rows = crossed.prim[:, None] * m.n_layers + jnp.arange(n_layers)[None, :]  # (k, L)
    rows = jnp.broadcast_to(rows[:, None, :], ok.shape + (n_layers,))  # (k, J, L)
    at = jnp.broadcast_to(points[:, :, None, :], rows.shape + (3,))
    use = ok[:, :, None] & present[:, None, :]  # (k, J, L)
    return crossed.overflow, (rows.reshape(-1).astype(jnp.int32), at.reshape(-1, 3), use.reshape(-1)), crossed


def _shadow_sampler(types):
    """The sampler ``(light, dtype) → (positions, weights)`` of a light's types, or None."""
    return next((t.shadow_samples for t in types if t.shadow_samples is not None), None)


def _light_visibility(ctx: TraceContext, light: Light, types, p_spawn, l, shadow_len):
    """The shadow filter of one light: one shadow ray, or the weighted sum over the shadow samples of
    its type (area lights; vmapped, so compile time does not grow with the grid)."""
    if not _casts_shadows(ctx, types):
        return jnp.ones(3, ctx.dtype)
    sampler = _shadow_sampler(types)
    if sampler is None:
        return _shadow_filter(ctx, p_spawn, l, shadow_len)
    positions, weights = sampler(light, ctx.dtype)
    return jnp.sum(weights[:, None] * jax.vmap(lambda q: _sample_filter(ctx, p_spawn, q))(positions), axis=0)


def _light_filters(ctx: TraceContext, light: Light, types, p_spawn, l, shadow_len):
    """A shadow-casting light's shadow rays as ``_Filters`` with a leading axis over its samples
    (one for a point light), and their weights (S,)."""
    sampler = _shadow_sampler(types)
    if sampler is None:
        fl = _shadow_filters(ctx, p_spawn, l, shadow_len)
        return jnp.ones((1,), ctx.dtype), jax.tree_util.tree_map(lambda x: x[None], fl)
    positions, weights = sampler(light, ctx.dtype)
    return weights, jax.vmap(lambda q: _sample_filters(ctx, p_spawn, q))(positions)


def _casts_shadows(ctx: TraceContext, types) -> bool:
    return all(t.shadows for t in types) and ctx.plan.effects.shadows


def _sample_filter(ctx: TraceContext, p, q):
    """The shadow filter of the segment from ``p`` to the light sample at ``q``."""
    return _filters_value(ctx, _sample_filters(ctx, p, q))


def _sample_filters(ctx: TraceContext, p, q) -> _Filters:
    v = q - p
    dist = jnp.sqrt(jnp.maximum(jnp.dot(v, v), 1e-30))
    return _shadow_filters(ctx, p, v / dist, dist)


def _adaptive(ctx: TraceContext, light: Light) -> bool:
    """Whether the light's shadow is POV-Ray's adaptive area sampling with something left to
    decide (computed for a batch of rays at once by :func:`_adaptive_visibility`)."""
    types = light_types(light, ctx.plan.effects)
    if not (_casts_shadows(ctx, types) and _shadow_sampler(types) is not None
            and light.area.adaptive is not None):
        return False
    # split N times everywhere down to the leaves: every sample is traced, as without adaptive
    return _adaptive_plan(light.area.size1, light.area.size2, light.area.adaptive).blocks.shape[0] > 0


def _sampled(ctx: TraceContext, light: Light) -> bool:
    """Whether the light's shadow is the weighted sum over samples of its type (an area light)."""
    types = light_types(light, ctx.plan.effects)
    return _casts_shadows(ctx, types) and _shadow_sampler(types) is not None


ADAPTIVE_THRESHOLD = 0.1  # corner samples differ when colour·filter differs by more (see _differ)
# the corners of a block are (u0,v0), (u0,v1), (u1,v0), (u1,v1) (AreaBlock.corners): its four edges
_EDGES = ((0, 2), (1, 3), (0, 1), (2, 3))


def _differ(colour, corners):
    """POV-Ray's test of whether a block's corner samples differ "significantly" (manual: Area
    Lights, adaptive; the rule measured with POV-Ray 3.7, semantics §2.5): the arriving colours
    ``colour · filter`` of the two ends of one of the block's four edges differ by more than
    ``ADAPTIVE_THRESHOLD`` in the sum of their channels' absolute differences. The diagonals are
    not compared. ``colour`` (B, 3) is the light's colour after fade and spot cone, ``corners``
    (B, M, 4, 3) the corners' shadow filters → (B, M)."""
    seen = colour[:, None, None, :] * corners
    out = jnp.zeros(corners.shape[:2], bool)
    for i, j in _EDGES:
        out = out | (jnp.sum(jnp.abs(seen[:, :, i] - seen[:, :, j]), axis=-1) > ADAPTIVE_THRESHOLD)
    return out


class _AdaptivePlan(NamedTuple):
    """The static tables of adaptive sampling over an area light's recursion tree (all blocks in
    breadth-first order, ``j``; two extra columns of the split table: ``pad`` (written by padding,
    never read) and ``always`` (True: the root's parent)). The first N levels split whatever the
    samples; decision round r (r ≥ 0) decides the blocks of depth N + r that have children. Per
    round (leading axis), padded to the widest level:

    blocks:  (R, M) block index (``pad`` for padding); corners (R, M, 4) their corners' grid
             indices; parent (R, M) their parents' (``always`` for the root); valid (R, M);
    first:   (P,) the first N levels' corners (what round 0 decides on);
    split0:  (NB + 2,) the split table before round 0: the first N levels split, ``always``;
    levels:  per depth of the tree, from the root: the blocks' indices (n,), their corners (n, 4)
             and their children as indices into the next depth's blocks (n, 4) with weights (n, 4)
             (1/number of children; 0 pads) — the final means, bottom up.
    """

    blocks: np.ndarray
    corners: np.ndarray
    parent: np.ndarray
    valid: np.ndarray
    first: np.ndarray
    split0: np.ndarray
    levels: tuple


@functools.cache
def _adaptive_plan(n1: int, n2: int, forced: int) -> _AdaptivePlan:
    root = area_blocks(n1, n2)
    levels = [[root]]
    while any(b.children for b in levels[-1]):
        levels.append([c for b in levels[-1] for c in b.children])
    every = [b for level in levels for b in level]
    index = {id(b): j for j, b in enumerate(every)}
    pad, always = len(every), len(every) + 1
    parent_of = {id(c): index[id(b)] for b in every for c in b.children}
    forced = min(forced, len(levels) - 1)
    decided = [[b for b in level if b.children] for level in levels[forced:-1]]
    width = max([len(level) for level in decided] + [1])
    blocks = np.full((len(decided), width), pad, np.int32)
    corners = np.zeros((len(decided), width, 4), np.int32)
    parent = np.full((len(decided), width), always, np.int32)
    valid = np.zeros((len(decided), width), bool)
    first = np.zeros(n1 * n2, bool)
    first[[k for level in levels[:forced + 1] for b in level for k in b.corners]] = True
    for r, level in enumerate(decided):
        for m, b in enumerate(level):
            blocks[r, m], corners[r, m], valid[r, m] = index[id(b)], b.corners, True
            parent[r, m] = parent_of.get(id(b), always)
    split0 = np.zeros(len(every) + 2, bool)
    split0[[index[id(b)] for level in levels[:forced] for b in level if b.children]] = True
    split0[always] = True
    tables = []
    for depth, level in enumerate(levels):
        below = {id(c): i for i, c in enumerate(levels[depth + 1])} if depth + 1 < len(levels) else {}
        children = np.zeros((len(level), 4), np.int32)
        weights = np.zeros((len(level), 4))
        for m, b in enumerate(level):
            for i, c in enumerate(b.children):
                children[m, i], weights[m, i] = below[id(c)], 1 / len(b.children)
        tables.append((np.asarray([index[id(b)] for b in level], np.int32),
                       np.asarray([b.corners for b in level], np.int32), children, weights))
    return _AdaptivePlan(blocks, corners, parent, valid, first, split0, tuple(tables))


SAMPLES_PER_CHUNK = 2048  # shadow rays traced per skippable chunk of adaptive area sampling


def _traced_samples(ctx: TraceContext, p_spawn, sets) -> list:
    """The shadow filters of (point, light sample) pairs, in one traced shadow test for all
    ``sets``: each ``(positions (L, P, 3), ks (K,), alive (L·B,))`` asks, for L lights' points
    ``p_spawn`` (B, 3), the samples ``ks`` of each light's grid where ``alive`` → its (L·B, K, 3)
    filters (zeros where not alive). The pairs of every set are traced together, the live ones
    moved to the front and chunks of none skipped (``map_live``), so the program holds one
    shadow test whatever the lights' grids (one per grid and phase was ~0.13 s of compile each:
    advanced/lamppost's 5×5 and 4×4 lights)."""
    b_size = p_spawn.shape[0]
    ps, qs, alive, sizes = [], [], [], []
    for positions, ks, live in sets:
        n_lights, k = positions.shape[0], len(ks)
        shape = (n_lights, b_size, k, 3)
        ps.append(jnp.broadcast_to(p_spawn[None, :, None], shape).reshape(-1, 3))
        qs.append(jnp.broadcast_to(positions[:, None, ks], shape).reshape(-1, 3))
        alive.append(jnp.broadcast_to(live.reshape(n_lights, b_size, 1), shape[:3]).reshape(-1))
        sizes.append(n_lights * b_size * k)
    n = sum(sizes)
    chunk = min(SAMPLES_PER_CHUNK, n)
    pad = -n % chunk  # dead pairs (never traced unless in a chunk with live ones: a unit segment)
    ps.append(jnp.zeros((pad, 3), p_spawn.dtype))
    qs.append(jnp.ones((pad, 3), p_spawn.dtype))
    alive.append(jnp.zeros(pad, bool))

    by_pattern = _by_pattern(ctx)

    def trace(items):  # (chunk, 3) points and samples → (chunk, 3) filters
        if not by_pattern:
            return jax.vmap(lambda p, q: _sample_filter(ctx, p, q))(*items)
        # the chunk's patterned pigments together, each entry's own pattern where it is used (as
        # _batch_shadows does; per pair, every pattern at every slot: gamma/gamma_showcase's
        # shadow rays through T_Stone11 cost ~70 µs each)
        fl = jax.vmap(lambda p, q: _sample_filters(ctx, p, q))(*items)
        if fl.rows.shape[-1] == 0:
            return fl.base
        rows, points = fl.rows.reshape(-1), fl.points.reshape(-1, 3)
        pig = pigments_at(ctx.mats, rows, points, fl.use.reshape(-1))
        f = _textured_filters(ctx.mats, rows, points, _rgb_filter(pig))
        return jax.vmap(_filtered)(fl, f.reshape(fl.rows.shape + (3,)))

    out = map_live(trace, (jnp.concatenate(ps), jnp.concatenate(qs)), jnp.concatenate(alive), chunk)
    ends = np.cumsum([0] + sizes)
    return [out[lo:hi].reshape(-1, len(ks), 3)
            for lo, hi, (_, ks, _) in zip(ends[:-1], ends[1:], sets, strict=True)]


def _adaptive_visibility(ctx: TraceContext, groups, p_spawn, full=()) -> tuple[list, list]:
    """The shadow filters of area lights with ``adaptive`` sampling, for a batch of B shading
    points ``p_spawn`` (B, 3). ``groups``: per plan (lights of one grid and ``adaptive`` N), ``(plan,
    positions (L, P, 3), live (L·B,), colour (L·B, 3))``, the lights' sample positions and, light
    by light, which points are lit with a hit and the colour arriving there → per group (L·B, 3).
    One traced shadow test per phase serves them all (``_traced_samples``), so a scene's area
    lights do not each add a copy to the program; the first also traces the area lights sampled
    in ``full`` (``(positions (L, P, 3), weights (P,), live (L·B,))`` each → (L·B, 3), their
    weighted sums), so a scene's other area lights add none either. Each light is sampled as
    POV-Ray samples it (semantics §2.5): the grid's recursion tree
    (:func:`~raytracer.scene._lights.area_blocks`) is split N times everywhere; below that, a block
    is split only where its corner samples differ (:func:`_differ`, on the arriving colours
    ``colour`` times the filters), else its value is the mean of its corners.

    What is traced, for the ``live`` points: the first N levels' corners for every point, and the
    rest of the grid only for the points where the first block the rule decides splits (a
    penumbra); the others' value is already decided. The rule is then applied to the traced grid
    as selects, round by round (one ``lax.scan``): a sample it never asks for is traced for a
    penumbra point but never read. Two phases per point rather than a round of (point, sample)
    pairs per level of the tree cost up to about twice the shadow rays in penumbrae
    (``lights/soft``) and much less compaction. The choice of
    blocks is piecewise constant (no gradient); the samples' filters and the means differentiate
    as usual.
    """
    def decide(colour, cols):
        def step(split, table):
            blocks, corners, parent, valid = table
            split_here = split[:, parent] & valid[None] & _differ(colour, cols[:, corners])  # (B, M)
            return split.at[:, blocks].set(split_here), split_here
        return step

    firsts = [np.flatnonzero(plan.first) for plan, *_ in groups]  # traced for every live point
    rests = [np.flatnonzero(~plan.first) for plan, *_ in groups]  # where the first decision splits
    sets = [(positions, first, live) for (_, positions, live, _), first in zip(groups, firsts, strict=True)]
    sets += [(positions, np.arange(positions.shape[1]), live) for positions, _, live in full]
    traced = _traced_samples(ctx, p_spawn, sets)
    ahead = traced[:len(groups)]
    sums = [jnp.sum(weights[None, :, None] * f, axis=1)
            for (_, weights, _), f in zip(full, traced[len(groups):], strict=True)]
    penumbrae, starts = [], []
    for (plan, _, live, colour), first, cols in zip(groups, firsts, ahead, strict=True):
        start = jnp.broadcast_to(jnp.asarray(plan.split0), (live.shape[0], plan.split0.size))
        # the first decision reads only corners in ``first`` (ascending): its corner table there
        round0 = tuple(jnp.asarray(a) for a in (plan.blocks[0], np.searchsorted(first, plan.corners[0]),
                                                plan.parent[0], plan.valid[0]))
        _, split_first = decide(colour, cols)(start, round0)
        penumbrae.append(live & jnp.any(split_first, axis=1))
        starts.append(start)
    todo = [(g[1], rest, penumbra) for g, rest, penumbra in zip(groups, rests, penumbrae, strict=True)
            if len(rest)]
    behind = iter(_traced_samples(ctx, p_spawn, todo) if todo else ())
    out = []
    for (plan, _, _, colour), first, rest, cols, start in zip(groups, firsts, rests, ahead, starts,
                                                            strict=True):
        back = np.argsort(np.concatenate([first, rest]))  # grid order from [first, rest]
        cols = jnp.concatenate([cols, next(behind)], axis=1)[:, back] if len(rest) else cols[:, back]
        tables = tuple(jnp.asarray(a) for a in (plan.blocks, plan.corners, plan.parent, plan.valid))
        split, _ = jax.lax.scan(decide(colour, cols), start, tables)
        out.append(_block_means(plan, cols, split))
    return out, sums


def _block_means(plan: _AdaptivePlan, cols, split):
    """The root's value (B, 3) of the recursion tree, bottom up, one depth at a time: a block that
    split (``split`` (B, NB + 2)) is the mean of its children, any other the mean of its corners'
    filters ``cols`` (B, P, 3)."""
    value = None  # (B, n, 3) of the depth below
    for blocks, corners, children, weights in reversed(plan.levels):
        mean = jnp.mean(cols[:, corners], axis=2)  # (B, n, 3)
        if value is not None:
            below = jnp.einsum("bnkc,nk->bnc", value[:, children], jnp.asarray(weights, cols.dtype))
            mean = jnp.where(split[:, blocks, None], below, mean)
        value = mean
    return value[:, 0]


# ---------------------------------------------------------------- local shading
class _Arrival(NamedTuple):
    """One light as it arrives at the shading point."""

    l: jax.Array  # (3,) unit direction towards the light
    color: jax.Array  # (3,) after fade, spot cone and shadow filter
    cos_nl: jax.Array  # () n·l
    lit: jax.Array  # () bool: the light is on the viewer's side of the surface


def light_geometry(ctx: TraceContext, light: Light, p):
    """``(l, dist, shadow_len)`` at ``p``: the unit direction to the light, its distance (for
    fading) and the shadow ray's length, as the light's types define them."""
    geometry = point_geometry
    for t in light_types(light, ctx.plan.effects):
        geometry = t.geometry or geometry
    return geometry(light, p)


def hard_shadow_lights(ctx: TraceContext) -> tuple[int, ...]:
    """The indices of the lights whose shadow is one ray to the light (static): those that cast
    shadows and are not sampled over an area."""
    return tuple(i for i, light in enumerate(ctx.lights)
                 if _casts_shadows(ctx, light_types(light, ctx.plan.effects))
                 and _shadow_sampler(light_types(light, ctx.plan.effects)) is None)


def grid_shadow_lights(ctx: TraceContext) -> tuple[int, ...]:
    """The indices of the lights whose shadow is the weighted sum over a fixed grid of shadow rays
    (static): area lights sampled in full — without ``adaptive``, or with one that splits every
    block down to the grid — not those whose samples adaptive sampling chooses per point."""
    return tuple(i for i, light in enumerate(ctx.lights)
                 if _sampled(ctx, light) and not _adaptive(ctx, light))


def adaptive_shadow_lights(ctx: TraceContext) -> tuple[int, ...]:
    """The indices of the lights whose shadow samples POV-Ray's adaptive sampling chooses per point
    (static)."""
    return tuple(i for i, light in enumerate(ctx.lights) if _adaptive(ctx, light))


def shadow_sample_points(ctx: TraceContext, light: Light):
    """``(positions (N, 3), weights (N,))``: the targets of a sampled light's shadow rays."""
    return _shadow_sampler(light_types(light, ctx.plan.effects))(light, ctx.dtype)


def _unshadowed(ctx: TraceContext, light: Light, p, n):
    """Direction to the light, the colour arriving before the shadow (each of its types' factors:
    fade, spot cone), ``n·l`` and the shadow ray's length. Only types whose effects the plan turns
    on are traced."""
    types = light_types(light, ctx.plan.effects)
    l, dist, shadow_len = light_geometry(ctx, light, p)
    c = light.color.astype(ctx.dtype)
    for t in types:
        if t.arrival is not None:
            c = c * t.arrival(light, l, dist)
    return l, c, jnp.dot(n, l), shadow_len


def _light_arrival(ctx: TraceContext, light: Light, p, p_spawn, n, visibility=None) -> _Arrival:
    """Direction to the light, the colour arriving (fade, spot cone, then the shadow filter, or
    ``visibility`` when the batch computed it) and whether the light is on the viewer's side of the
    surface (``n·l > 1e-10``, semantics §2.4)."""
    l, c, cos_nl, shadow_len = _unshadowed(ctx, light, p, n)
    if visibility is None:
        types = light_types(light, ctx.plan.effects)
        visibility = _light_visibility(ctx, light, types, p_spawn, l, shadow_len)
    return _Arrival(l, c * visibility, cos_nl, cos_nl > lighting.NL_EPSILON)


def _layer_light(ctx: TraceContext, mats: PackedMaterials, light: Light, arrival: _Arrival, row, rgb, att,
                 d, n):
    """Diffuse and highlight terms of one texture layer (row ``row`` of ``mats``) for one light;
    ``n`` is the layer's shading normal (perturbed by its ``normal {}``, which then decides ``n·l``)."""
    l, c, cos_nl, lit = arrival
    if ctx.plan.effects.normals:
        cos_nl = jnp.dot(n, l)
        lit = cos_nl > lighting.NL_EPSILON
    fin = mats.finish
    out = lighting.diffuse(att, fin.diffuse[row], fin.brilliance[row], cos_nl, rgb) * c
    eff = ctx.plan.effects
    if eff.highlights and all(t.shadows for t in light_types(light, eff)):
        h = lighting.phong(fin.phong[row], fin.phong_size[row], d, n, l)
        h = h + lighting.specular(fin.specular[row], fin.roughness[row], d, n, l)
        tint = lighting.metallic_tint(fin.metallic[row], cos_nl, rgb) if eff.metallic else 1.0
        out = out + h * c * tint
    return jnp.where(lit, out, 0.0)


def _reflectivity(ctx: TraceContext, mats: PackedMaterials, row, cos_i, eta_rel, rgb):
    """Reflection colour (semantics §2.6) and its ray weight (row ``row`` of ``mats``)."""
    fin = mats.finish
    rmin, rmax = fin.refl_min[row], fin.refl_max[row]
    frac = safe_pow(1.0 - cos_i, fin.refl_falloff[row])
    reflec = frac * rmax + (1 - frac) * rmin
    weight = jnp.maximum(jnp.max(rmax), jnp.max(rmin))
    if ctx.plan.effects.fresnel:
        f, total = lighting.fresnel(cos_i, eta_rel)
        fres = jnp.where(total, rmax, f * rmax + (1 - f) * rmin)
        is_f = jnp.asarray(mats.tables["fresnel"])[row]
        reflec = jnp.where(is_f, fres, reflec)
        weight = jnp.where(is_f, jnp.max(reflec), weight)
    if ctx.plan.effects.reflection_metallic:
        reflec = reflec * lighting.metallic_tint(fin.refl_metallic[row], cos_i, rgb)
    return reflec, weight


class _Surface(NamedTuple):
    """The hit of one ray, seen from the ray's side."""

    found: jax.Array  # () bool: the (live) ray hit a visible surface
    missed: jax.Array  # () bool: the live ray hit nothing (it sees the background)
    t: jax.Array  # () distance along the ray
    prim: jax.Array  # () int primitive index
    p: jax.Array  # (3,) hit point
    n: jax.Array  # (3,) unit normal facing the incoming ray
    entering: jax.Array  # () bool: the geometric normal faces the ray (entering the object)
    p_out: jax.Array  # (3,) spawn point on the ray's side of the surface
    p_in: jax.Array  # (3,) spawn point beyond the surface
    medium: jax.Array  # () int the medium of the primitive hit (``_geometry.medium_ids``)


def _surface(ctx: TraceContext, ray: Rays) -> _Surface:
    o, d = ray.origin, ray.direction
    vis = jnp.where(ray.reflection, jnp.asarray(ctx.vis_reflect), jnp.asarray(ctx.vis_camera))
    scale = ctx.eps * (1.0 + jnp.max(jnp.abs(o)))
    want = jnp.where(ray.reflection, _accel.MASK_REFLECT, _accel.MASK_CAMERA)
    # float32 points of discrete patterns are computed at the surface (closest_hit's refine): in
    # float64, o + t d is exact enough for POV-Ray's own 1e-10 face nudge
    refine = o.dtype == jnp.float32 and any(patterns.REGISTRY[name].discrete
                                            for name in ctx.plan.effects.patterns)
    hit = closest_hit(ctx.geo, ctx.plan, o, d, scale, vis, want, refine=refine)
    p = o + hit.t * d if hit.point is None else hit.point
    entering = jnp.dot(hit.normal, d) < 0
    n = jnp.where(entering, hit.normal, -hit.normal)  # faces the incoming ray
    offset = ctx.eps * (1.0 + jnp.max(jnp.abs(p)))
    return _Surface(found=hit.found & ray.alive, missed=ray.alive & ~hit.found, t=hit.t, prim=hit.prim,
                    p=p, n=n, entering=entering, p_out=p + offset * n, p_in=p - offset * n,
                    medium=jnp.asarray(ctx.geo.prim_table["medium"])[hit.prim])


class _Layers(NamedTuple):
    """The texture layers at a hit, summed top to bottom."""

    local: jax.Array  # (3,) local colour
    fil: jax.Array  # (3,) filter of all layers (what the transmitted ray's colour is multiplied by)
    trans: jax.Array  # () grey of ``fil``, at most 1
    reflec: jax.Array  # (3,) summed reflection colour
    r_weight: jax.Array  # () weight of the mirror ray relative to this ray's
    normal: jax.Array | None  # (3,) the top layer's shading normal (normal {}), which the mirror
    #                           and refracted rays use; None without normals (the surface's)
    exponent: jax.Array  # () the top layer's reflection exponent (the mirror ray's)


class _Lights(NamedTuple):
    """Lights of one structure: the one light (``count`` 1), or the lights stacked on a leading
    axis."""

    light: Light
    count: int


def _light_classes(lights, visibility, effects) -> list[tuple[tuple[int, ...], _Lights, object]]:
    """The scene's lights grouped by structure (pytree, leaf shapes and dtypes, types, and whether
    the batch computed their shadow): ``(indices, lights, visibility)``, the last two stacked when
    a class has more than one light."""
    keyed: dict[tuple, list[int]] = {}
    for i, (light, v) in enumerate(zip(lights, visibility, strict=True)):
        leaves, treedef = jax.tree_util.tree_flatten(light)
        key = (treedef, tuple((np.shape(x), jnp.result_type(x)) for x in leaves),
               tuple(t.name for t in light_types(light, effects)), v is None)
        keyed.setdefault(key, []).append(i)
    out = []
    for ids in keyed.values():
        if len(ids) == 1:
            out.append((tuple(ids), _Lights(lights[ids[0]], 1), visibility[ids[0]]))
            continue
        stacked = jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *(lights[i] for i in ids))
        vis = None if visibility[ids[0]] is None else jnp.stack([visibility[i] for i in ids])
        out.append((tuple(ids), _Lights(stacked, len(ids)), vis))
    return out


def _batched(fn, lights: _Lights, extra):
    """``fn(light, extra)`` for one light, or vmapped over a class's stacked lights."""
    if lights.count == 1:
        return fn(lights.light, extra)
    return jax.vmap(fn)(lights.light, extra)


def _layers(ctx: TraceContext, ray: Rays, s: _Surface, cos_i, eta_rel, visibility,
            pigments=None) -> _Layers:
    """The texture at a hit: its layers summed (:func:`_texture_layers`), or a patterned
    texture's textures there, each shaded in full and blended (semantics §5.7). ``visibility``:
    per light, its shadow filter if the batch computed it, else None; ``pigments``: each layer's
    pigment (layers, 5) if the batch computed them, else None."""
    # lights of one structure are one vmapped computation (their shadow rays too), so the program
    # holds each kind of light once, not once per light
    classes = _light_classes(ctx.lights, visibility, ctx.plan.effects)
    arrivals = [_batched(lambda lt, v: _light_arrival(ctx, lt, s.p, s.p_out, s.n, v), lights, vis)
                for _, lights, vis in classes]
    textures = ctx.mats.textures
    if textures is None:
        return _texture_layers(ctx, ctx.mats, s.prim, ray, s, cos_i, eta_rel, classes, arrivals, pigments)
    # the width ** depth textures a patterned texture blends at the hit (a plain one: itself,
    # weight 1), in one vmapped evaluation: the program holds a texture's shading once
    leaves, weights = texture_choice(textures, s.prim, s.p)
    each = jax.vmap(lambda leaf: _texture_layers(ctx, textures.leaves, leaf, ray, s, cos_i, eta_rel, classes,
                                                 arrivals, None))(leaves)

    def blend(x):
        return jnp.tensordot(weights.astype(x.dtype), x, axes=1)

    # the colour a texture gives is linear in its local colour and in its children's coefficients:
    # blending those blends the colours, the mirror and transmitted rays being the same rays (the
    # dominant texture's, where normal {} perturbations differ)
    main = jnp.argmax(weights)
    return _Layers(local=blend(each.local), fil=blend(each.fil), trans=blend(each.trans),
                   reflec=blend(each.reflec), r_weight=blend(each.r_weight),
                   normal=None if each.normal is None else each.normal[main], exponent=each.exponent[main])


def _texture_layers(ctx: TraceContext, mats: PackedMaterials, base, ray: Rays, s: _Surface, cos_i, eta_rel,
                    classes, arrivals, pigments) -> _Layers:
    """Texture layers, top first (semantics §2.3), of rows ``base · n_layers + k`` of ``mats``:
    each adds its local colour filtered by the layers above; the loop stops once the layers above
    let less than adc_bailout through."""
    fin = mats.finish
    d, n = ray.direction, s.n
    n_layers = mats.n_layers
    reflection = ctx.plan.effects.reflection

    def one_layer(k):
        # what a layer contributes by itself: its local colour (before the layers above filter
        # it), its filter, its reflection colour and weight, and its shading normal
        row = base * n_layers + k
        n_k, cos_i_k = n, cos_i
        if ctx.plan.effects.normals:  # the layer's normal {} (semantics §5.5)
            n_k = perturbed(mats.normals, row, s.p, n)
            cos_i_k = -jnp.dot(d, n_k)
        pig = pigment_at(mats, row, s.p) if pigments is None else pigments[k]
        rgb, f, t = pig[:3], pig[3], pig[4]
        att = 1.0 - f - t
        tmp = att * rgb * (fin.ambient[row] * ctx.settings.ambient_light + fin.emission[row])
        for (_, lights, _), arrival in zip(classes, arrivals, strict=True):
            terms = _batched(lambda lt, a: _layer_light(ctx, mats, lt, a, row, rgb, att, d, n_k), lights,
                             arrival)
            tmp = tmp + (terms if lights.count == 1 else jnp.sum(terms, axis=0))
        layer_fil = f * rgb + t
        if not reflection:
            return tmp, layer_fil, None, None, n_k
        reflec_k, w_k = _reflectivity(ctx, mats, row, cos_i_k, eta_rel, rgb)
        conserve = jnp.asarray(mats.tables["conserve_energy"])[row]
        # 1 - reflection, at most 1 (POV-Ray's, measured: a negative reflection passes all); at a
        # reflection of exactly 0 (a Fresnel exit, min 0) the derivative is the physical side's, -1
        kept = jnp.where(reflec_k < 0, 1.0, 1.0 - reflec_k)
        layer_fil = jnp.where(conserve, layer_fil * kept, layer_fil)
        return tmp, layer_fil, reflec_k, w_k, n_k

    # every layer in one vmapped evaluation: the program holds a layer's pigments, lights and
    # reflectivity once, not once per layer (noise patterns are large programs)
    if n_layers == 1:
        per_layer = jax.tree_util.tree_map(lambda x: x[None], one_layer(0))
    else:
        per_layer = jax.vmap(one_layer)(jnp.arange(n_layers))
    tmps, layer_fils, reflecs, weights, normals = per_layer
    fil = jnp.ones(3, ctx.dtype)
    trans = jnp.ones((), ctx.dtype)
    local = jnp.zeros(3, ctx.dtype)
    reflec = jnp.zeros(3, ctx.dtype)
    r_weight = jnp.zeros((), ctx.dtype)
    for k in range(n_layers):
        # top first: each layer is seen through the filters of those above it, and the loop
        # stops once they let less than adc_bailout through
        present = jnp.asarray(mats.tables["layer_present"])[base, k]
        active = present & ((trans > ctx.settings.adc_bailout) | (k == 0))
        local = local + jnp.where(active, fil * tmps[k], 0.0)
        if reflection:
            reflec = reflec + jnp.where(active, reflecs[k], 0.0)  # layers' reflections add up
            r_weight = jnp.maximum(r_weight, jnp.where(active, trans * weights[k], 0.0))
        fil = jnp.where(active, fil * layer_fils[k], fil)
        trans = jnp.minimum(1.0, jnp.abs(lighting.grey(fil)))
    # (the shading normal only where a layer perturbs it: otherwise the conditional that
    # materialises the layers would carry the surface normal through as one more buffer)
    return _Layers(local, fil, trans, reflec, r_weight, normals[0] if ctx.plan.effects.normals else None,
                   mats.finish.refl_exponent[base * n_layers])  # the top layer's exponent


# ---------------------------------------------------------------- children
def _transmitted(ctx: TraceContext, ray: Rays, s: _Surface, layers: _Layers,
                 eta_rel) -> tuple[Child, jax.Array]:
    """The transmitted ray (refracted, or straight on where ior is 1), or under total internal
    reflection the reflected ray in its place; its colour is filtered by the layers and faded by
    the interior it leaves (distance travelled inside = this segment's length). Also returns
    whether this is the TIR ray (which then replaces the mirror ray)."""
    eff, mats, settings = ctx.plan.effects, ctx.mats, ctx.settings
    d, prim, level, weight = ray.direction, s.prim, ray.level, ray.weight
    fil = layers.fil
    tir = jnp.asarray(False)
    if eff.refraction:
        d_t, tir = lighting.refract(d, s.n, 1.0 / eta_rel)
    else:
        d_t = d
    fd, fp = mats.fade_distance[prim], mats.fade_power[prim]
    if eff.interior_fade:
        att_col = lighting.interior_fade(s.t, fd, fp, mats.fade_color[prim], on=~s.entering)
    else:
        att_col = jnp.ones(3, ctx.dtype)
    t_weight = jax.lax.stop_gradient(weight * jnp.max(jnp.abs(fil)))
    t_alive = s.found & (layers.trans > settings.adc_bailout) & (t_weight >= settings.adc_bailout)
    t_alive = t_alive & jnp.asarray(mats.tables["transparent"])[prim]  # opaque pigments never transmit
    # TIR is found by the refraction step, so it only replaces the mirror ray where that step
    # runs; a conserve_energy + fresnel surface under TIR has fil = 0 and reflects instead (semantics §2.3)
    tir = tir & t_alive
    straight = jnp.abs(eta_rel - 1.0) < 1e-10
    t_level = jnp.where(straight & ~tir, level, level + 1)
    media = ray.media
    if media.shape[-1]:  # through the surface: into its interior, or out of it
        # a surface without an inside (a triangle, a mesh without inside_vector) is entered from
        # either side, as POV-Ray keeps it: a ray past one has no fog (semantics §2.8)
        enters = s.entering | ~jnp.asarray(ctx.geo.prim_table["solid"])[s.prim]
        crossed = jnp.where(enters, _media_with(media, s.medium), _media_without(media, s.medium))
        media = jnp.where(tir, media, crossed)
    child = Rays(origin=jnp.where(tir, s.p_out, s.p_in), direction=d_t,
                 weight=jnp.where(tir, weight, t_weight),
                 alive=t_alive & (level < settings.max_trace_level), reflection=jnp.asarray(False),
                 level=t_level, media=media)
    return Child(ray=child, coef=jnp.where(tir, att_col, att_col * fil), power=None), tir


def _mirror(ctx: TraceContext, ray: Rays, s: _Surface, layers: _Layers, tir, surface_normal=None) -> Child:
    """The mirror ray, with the layers' summed reflection colour and the top layer's exponent.
    ``surface_normal``: the unperturbed normal where ``s.n`` is a layer's perturbed one."""
    settings = ctx.settings
    w = jax.lax.stop_gradient(ray.weight * layers.r_weight)
    r_alive = s.found & jnp.any(layers.reflec != 0) & ~tir & (w >= settings.adc_bailout)
    expo = layers.exponent
    direction = lighting.reflect(ray.direction, s.n)
    if surface_normal is not None:
        direction = lighting.above_surface(direction, surface_normal)
    child = Rays(origin=s.p_out, direction=direction, weight=w,
                 alive=r_alive & (ray.level < settings.max_trace_level), reflection=jnp.asarray(True),
                 level=ray.level + 1, media=ray.media)
    return Child(ray=child, coef=layers.reflec, power=1.0 / expo)


def _relative_ior(ctx: TraceContext, ray: Rays, s: _Surface):
    """``(η_rel, η for Fresnel)``, ``η_rel = n_t / n_i`` at the hit (semantics §2.7).

    The medium on the near side of an entry, and on the far side of an exit, is the innermost
    interior of the ray's list (air, ior 1, when the list is empty). At an exit from a ray inside
    two or more interiors, POV-Ray's Fresnel amount and ``conserve_energy`` factor take the object
    being left on both sides (η = 1: no reflection from that surface); the refraction does not.
    """
    ior = ctx.mats.ior
    here = ior[s.prim]
    if not ray.media.shape[-1]:
        eta = jnp.where(s.entering, here, 1.0 / here)
        return eta, eta

    def ior_of(prim):
        return jnp.where(prim >= 0, ior[jnp.maximum(prim, 0)], 1.0)

    outside = ior_of(_media_last(ray.media))
    beyond = ior_of(_media_last(_media_without(ray.media, s.medium)))
    eta = jnp.where(s.entering, here / outside, beyond / here)
    quirk = ~s.entering & (jnp.sum(ray.media >= 0) >= 2)
    return eta, jnp.where(quirk, 1.0, eta)


def _materialised(ctx: TraceContext, tree):
    """``tree``, computed once into buffers that its consumers read.

    XLA's CPU fusion copies a cheap producer into each consumer, so the texture layers' chain
    (pigments, lights, Fresnel, reflectivity: ~200 instructions a ray) was computed again in
    each of the four fusions that read it (the local colour, each child's coefficient and
    liveness, its interior list). ``lax.optimization_barrier`` does not stop this (XLA's CPU
    pipeline removes barriers before fusion); a conditional's operands are buffers, and fusion
    does not cross it. The predicate is a run-time value of the scene (unbatched under the
    shading's ``vmap``, so the conditional stays one) and either branch returns ``tree``.
    whitted.pov 1024×768, one device: 1.42–1.52 → 1.24–1.33 s a render; glass.pov 640×480:
    1.12 → 0.99 s; PSNR against POV-Ray unchanged (a fusion may round differently)."""
    keep = ctx.settings.adc_bailout < 2.0
    # both branches give ``tree``; the second copies it, so that JAX does not forward the values
    # around the conditional as it does for an identity branch
    return jax.lax.cond(keep, lambda x: x, lambda x: jax.tree.map(jnp.copy, x), tree)


def shade(ctx: TraceContext, ray: Rays, s: _Surface | None = None, visibility=None,
          pigments=None) -> Shading:
    """Shades one ray (no leading axis): its local colour and the children its hit spawns.

    A dead ray sees black and spawns nothing; a live ray that misses sees the background. A ray
    spawns children only if its level is below ``max_trace_level``; straight transmission (ior 1)
    keeps the level (semantics §2.7). ``s``, ``visibility`` (per light, a shadow filter or None) and
    ``pigments`` (the layers' (layers, 5), or None) are what :func:`shade_batch` computed for the
    whole batch.
    """
    eff = ctx.plan.effects
    if s is None:
        s = _surface(ctx, ray)
    if visibility is None:
        visibility = (None,) * len(ctx.lights)
    cos_i = -jnp.dot(ray.direction, s.n)
    eta_rel, eta_fresnel = _relative_ior(ctx, ray, s)
    layers = _layers(ctx, ray, s, cos_i, eta_fresnel, visibility, pigments)
    if (eff.reflection or eff.transmission) and jax.default_backend() == "cpu":
        # (a CPU fusion workaround: elsewhere a conditional may cost a device-to-host sync)
        layers = _materialised(ctx, layers)
    surface_normal = None
    if eff.normals:  # the mirror and refracted rays leave about the top layer's shading normal
        surface_normal, s = s.n, s._replace(n=layers.normal)
    children = []
    transmitted, tir = None, jnp.asarray(False)
    if eff.transmission:
        transmitted, tir = _transmitted(ctx, ray, s, layers, eta_rel)
    if eff.reflection:
        children.append(_mirror(ctx, ray, s, layers, tir, surface_normal))
    if transmitted is not None:
        children.append(transmitted)
    local = jnp.where(s.found, layers.local,
                      jnp.where(s.missed, unlit_colour(ctx.environment, ctx.background, ray.direction), 0.0))
    if any(e.segment is not None for e, _ in ctx.environment):
        # what the space along the ray, up to its hit or forever, does to what it carries: a
        # colour c seen along it is c·scale + add, and so is what the children bring back,
        # through their coefficients. A ray inside an object (its interior list not empty: a
        # transmitted ray that entered a surface and has not left it, a sphere or a triangle
        # alike) is not changed, as in POV-Ray's fog
        d2 = jnp.maximum(jnp.dot(ray.direction, ray.direction), jnp.finfo(ctx.dtype).tiny)
        unit = ray.direction / jnp.sqrt(d2)
        length = jnp.where(s.found, s.t * jnp.sqrt(d2), 0.0)
        near_scale, near_add = segment_factors(ctx.environment, ray.origin, unit, length)
        far_scale, far_add = segment_factors(ctx.environment, ray.origin, unit, None)
        scale = jnp.where(s.found, near_scale, far_scale)
        add = jnp.where(s.found, near_add, far_add)
        inside = jnp.any(ray.media >= 0) if ray.media.shape[-1] else False
        changed = (s.found | s.missed) & ~inside
        scale, add = jnp.where(changed, scale, 1.0), jnp.where(changed, add, 0.0)
        local = jnp.where(changed, local * scale + add, local)
        children = [c._replace(coef=c.coef * scale) for c in children]
    return Shading(local=local, children=tuple(children))


def unlit_colour(environment, background, d):
    """What a ray of direction ``d`` (3,) that hits nothing sees: the ``background`` (3,), under each
    environment effect's ``miss`` colour in turn (``environment``: ``pack_environment``'s)."""
    colour = background
    for e, arrays in environment:
        if e.miss is not None:
            colour = e.miss(arrays, d, colour, pigment_at)
    return colour


def segment_factors(environment, origin, unit, distance):
    """``(scale, add)``: a colour ``c`` carried along ``origin + s·unit`` over ``distance`` (None:
    infinitely far) arrives as ``c·scale + add``, through each effect's ``segment`` in turn."""
    scale, add = 1.0, 0.0
    for e, arrays in environment:
        if e.segment is not None:
            s, a = e.segment(arrays, origin, unit, distance)
            scale, add = scale * s, add * s + a
    return scale, add


def shade_batch(ctx: TraceContext, rays: Rays) -> Shading:
    """:func:`shade` for a batch of rays (a leading axis). Computed for the batch at once: the
    shadows of area lights (:func:`_adaptive_visibility`: with adaptive sampling the full grid only
    for points in a penumbra; every light's samples in one shadow test, for the points it lights),
    and, where transparent shadow casters have noise patterns or turbulence, the other lights'
    shadows (:func:`_batch_shadows`: the patterned pigments of all the batch's shadow crossings
    together, each computing its own pattern and only where a crossing is). Everything else is one
    ray's computation, vmapped."""
    adaptive = [_adaptive(ctx, light) for light in ctx.lights]
    by_pattern = _by_pattern(ctx)
    # the other area lights' samples in the same shadow test (one in the program; only the points
    # they light traced), but not where _batch_shadows computes their patterned filters
    full = [not a and not by_pattern and _sampled(ctx, light) for a, light in zip(adaptive, ctx.lights,
                                                                                   strict=True)]
    if not any(adaptive) and not any(full) and not by_pattern:
        return jax.vmap(lambda r: shade(ctx, r))(rays)
    s = jax.vmap(lambda r: _surface(ctx, r))(rays)
    visibility: list = [None] * len(ctx.lights)
    if any(adaptive) or any(full):
        visibility = _batch_visibility(ctx, s, adaptive, full)
    if by_pattern:
        # (a patterned texture's layers are its leaves', which the batch does not compute)
        visibility, pigments = _batch_shadows(ctx, s, visibility, layers=ctx.mats.textures is None)
        if pigments is not None:
            return jax.vmap(lambda r, s_, v, pig: shade(ctx, r, s_, v, pig))(rays, s, tuple(visibility),
                                                                              pigments)
    return jax.vmap(lambda r, s_, v: shade(ctx, r, s_, v))(rays, s, tuple(visibility))


# a shadow ray's slots of patterned pigments from which computing them for the batch pays (20
# sample scenes with noise patterns, 160×120: 8–24 candidate slots 2.1–7× faster, 2–4 slots
# 1.4× slower, the hierarchy's 16 items × crossings × layers 1.5–4.7× faster)
MIN_FILTER_SLOTS = 8


def _by_pattern(ctx: TraceContext) -> bool:
    """Whether a batch computes its shadow rays' patterned pigments together (``pigments_at``):
    transparent shadow casters with noise patterns or turbulence, and enough slots of them."""
    return ctx.plan.effects.filtered_shadows and costly_patterns(ctx.mats) and _many_filter_slots(ctx)


def _many_filter_slots(ctx: TraceContext) -> bool:
    """Whether a shadow ray has at least ``MIN_FILTER_SLOTS`` slots of patterned pigments: the
    hierarchy's transparent items, or that many (transparent candidate, layer) pairs. (So
    ``_batch_shadows`` never sees a light without such slots.)"""
    return ctx.accel_filters or int(np.count_nonzero(~_transparent_pairs(ctx)[2])) >= MIN_FILTER_SLOTS


def _batch_shadows(ctx: TraceContext, s: _Surface, visibility: list, layers: bool = False):
    """``visibility`` with the shadow filter of every other shadow-casting light computed for the
    batch: the shadow rays' geometry ray by ray (lights of one structure vmapped together, as in
    ``_layers``), then the patterned pigments of all their transparent crossings together
    (``pigments_at``: each computes its own pattern, and the many slots of crossings a ray does not
    have compute nothing), then each ray's product. With ``layers``, the same call also computes
    the pigment of every texture layer at the batch's hits (returned (B, layers, 5), else None):
    the program holds the scene's patterns once, not once for shadows and once for the surfaces
    (``advanced/pawns``: ~900 of its ~8,300 equations), and a surface computes only its own
    pattern, not every pattern of the scene."""
    b_size = s.p.shape[0]
    todo = [v is None and _casts_shadows(ctx, light_types(light, ctx.plan.effects))
            for light, v in zip(ctx.lights, visibility, strict=True)]
    classes, rows, points, needed = [], [], [], []
    for ids, lights, _ in _light_classes(ctx.lights, visibility, ctx.plan.effects):
        if not todo[ids[0]]:
            continue
        types = light_types(ctx.lights[ids[0]], ctx.plan.effects)

        def shadow_rays(light, p, p_spawn, n, types=types):
            l, c, cos_nl, shadow_len = _unshadowed(ctx, light, p, n)
            weights, fl = _light_filters(ctx, light, types, p_spawn, l, shadow_len)
            # (not masked where the light's colour is 0: its derivative still sees the shadow);
            # a layer's normal {} can turn a point to a light its surface faces away from
            lit = (cos_nl > lighting.NL_EPSILON) | bool(ctx.plan.effects.normals)
            return weights, fl, lit

        def per_ray(p, p_spawn, n, lights=lights):
            return _batched(lambda lt, _: shadow_rays(lt, p, p_spawn, n), lights, None)

        weights, fl, lit = jax.vmap(per_ray)(s.p, s.p_out, s.n)  # (B, [lights,] S, …)
        wanted = s.found.reshape((b_size,) + (1,) * (lit.ndim - 1)) & lit
        fl = fl._replace(use=fl.use & wanted[..., None, None])
        classes.append((ids, lights, weights, fl))
        rows.append(fl.rows.reshape(-1))
        points.append(fl.points.reshape(-1, 3))
        needed.append(fl.use.reshape(-1))
    n_layers = ctx.mats.n_layers
    if layers:
        k = jnp.arange(n_layers, dtype=jnp.int32)
        rows.append((s.prim[:, None] * n_layers + k[None, :]).reshape(-1))
        points.append(jnp.repeat(s.p, n_layers, axis=0))
        present = jnp.asarray(ctx.mats.tables["layer_present"])[s.prim]  # (B, layers)
        needed.append((s.found[:, None] & present).reshape(-1))
    out = list(visibility)
    if not rows:
        return out, None
    rows, points = jnp.concatenate(rows), jnp.concatenate(points)
    pig = pigments_at(ctx.mats, rows, points, jnp.concatenate(needed))
    start = 0
    for ids, lights, weights, fl in classes:
        size = fl.rows.size
        f = _textured_filters(ctx.mats, rows[start:start + size], points[start:start + size],
                              _rgb_filter(pig[start:start + size])).reshape(fl.rows.shape + (3,))
        start += size
        shape = fl.base.shape[:-1]  # (B, [lights,] S)
        flat = _Filters(fl.base.reshape(-1, 3), fl.rows.reshape(-1, fl.rows.shape[-1]),
                        fl.points.reshape(-1, fl.rows.shape[-1], 3), fl.use.reshape(-1, fl.rows.shape[-1]))
        seen = jax.vmap(_filtered)(flat, f.reshape(-1, fl.rows.shape[-1], 3)).reshape(shape + (3,))
        vis = jnp.sum(weights[..., None] * seen, axis=-2)  # (B, [lights,] 3)
        for j, i in enumerate(ids):
            out[i] = vis if lights.count == 1 else vis[:, j]
    return out, (pig[start:].reshape(b_size, n_layers, 5) if layers else None)


def _batch_visibility(ctx: TraceContext, s: _Surface, adaptive: list[bool], full: list[bool]) -> list:
    """Per light, the batch's shadow filters where the light has adaptive area sampling or is an
    area light in ``full`` (every sample traced, in the same shadow test), else None."""
    grids: dict[tuple, list[int]] = {}  # lights with one plan share their decisions
    for i, (light, batched) in enumerate(zip(ctx.lights, adaptive, strict=True)):
        if batched:
            grids.setdefault((light.area.size1, light.area.size2, light.area.adaptive), []).append(i)
    visibility: list = [None] * len(ctx.lights)
    b_size = s.p.shape[0]

    def lit(light):  # which points the light reaches before its shadow, the colour arriving there
        def unshadowed(p, n):
            return _unshadowed(ctx, light, p, n)

        _, c, cos_nl, _ = jax.vmap(unshadowed)(s.p, s.n)
        faces = (cos_nl > lighting.NL_EPSILON) | bool(ctx.plan.effects.normals)  # (normal {}: any side)
        return s.found & faces & jnp.any(c != 0, axis=-1), c

    def samples(light):
        return _shadow_sampler(light_types(light, ctx.plan.effects))(light, ctx.dtype)

    groups = []
    for key, ids in grids.items():
        lives, colours = zip(*(lit(ctx.lights[i]) for i in ids), strict=True)
        groups.append((_adaptive_plan(*key), jnp.stack([samples(ctx.lights[i])[0] for i in ids]),
                       jnp.concatenate(lives), jnp.concatenate(colours)))
    sampled = [i for i, f in enumerate(full) if f]
    extra = [(positions[None], weights, lit(ctx.lights[i])[0])
             for i in sampled for positions, weights in [samples(ctx.lights[i])]]
    if groups or extra:
        seen, sums = _adaptive_visibility(ctx, groups, s.p_out, extra)
        for ids, vis in zip(grids.values(), seen, strict=True):
            for j, i in enumerate(ids):
                visibility[i] = vis[j * b_size:(j + 1) * b_size]
        for i, vis in zip(sampled, sums, strict=True):
            visibility[i] = vis
    return visibility
