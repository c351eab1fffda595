"""TraceRay: POV-Ray's recursive (Whitted) model as a scan over trace levels.

The seed's recursion — shoot shadow rays to all lights, add the local lighting, shoot the
reflected and the refracted ray, combine — is written once: ``shade`` handles one ray, a
``lax.scan`` step shades every ray of one level of the tree (``vmap``, in chunks, skipping chunks
with no live ray) and writes the children into the next level's pool, and a reverse scan combines
``local + coef · child`` on the way back. The shading body is traced once, so compile time does
not grow with ``max_trace_level``; per-ray decisions are masks and weights: a child whose weight
falls below ``adc_bailout`` (or that does not exist) is a dead slot and contributes nothing.

Only the child slots the scene can spawn exist: reflection rays only if some finish reflects,
transmitted rays only if some pigment can be transparent (reference §2.3, §2.7).

Modelling shortcuts (stated, not hidden):
  * only the top texture layer is shaded (layered textures warn in the plan);
  * entering/leaving an object is decided from the geometric normal (the ray is assumed to come
    from air when entering, and to leave into air), rather than POV's per-ray interior list —
    identical for non-nested objects, including POV's quirk-free cases (§2.7);
  * straight transmission (ior 1) does not use up a trace level (as in POV-Ray), but a ray path may
    pass at most ``Effects.straight_passes`` straight surfaces beyond ``max_trace_level`` levels.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .._plan import Plan
from ..kernels import safe_normalize, safe_pow
from ..scene import Light, Settings
from . import lighting as lt
from ._geometry import PackedGeometry, all_crossings, closest_hit, csg_mask, static_prim_mask
from ._materials import PackedMaterials, pigment_at


@dataclasses.dataclass
class TraceContext:
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
    casts_shadow: np.ndarray  # (C,)
    transparent_cands: np.ndarray  # (C,) candidate belongs to a transparent-capable prim
    inverse_sign: np.ndarray  # (C,) -1 where the prim is inverted
    fading_cands: np.ndarray  # candidate slots of transparent prims whose interior may fade


def make_context(plan: Plan, geo: PackedGeometry, mats: PackedMaterials, lights, settings,
                 background, dtype) -> TraceContext:
    prims = plan.prims
    return TraceContext(
        plan=plan, geo=geo, mats=mats, lights=tuple(lights), settings=settings,
        background=background.astype(dtype), dtype=dtype,
        eps=2e-5 if dtype == jnp.float32 else 1e-9,
        vis_camera=static_prim_mask(geo, lambda i: prims[i].rendered and "no_image" not in prims[i].flags),
        vis_reflect=static_prim_mask(geo, lambda i: prims[i].rendered
                                     and "no_reflection" not in prims[i].flags),
        casts_shadow=static_prim_mask(geo, lambda i: prims[i].rendered
                                      and "no_shadow" not in prims[i].flags),
        transparent_cands=static_prim_mask(geo, lambda i: bool(mats.transparent[i])),
        inverse_sign=np.where(static_prim_mask(geo, lambda i: prims[i].inverse), -1.0, 1.0),
        fading_cands=np.flatnonzero(static_prim_mask(
            geo, lambda i: bool(mats.transparent[i]) and prims[i].interior is not None
            and prims[i].interior.fade_distance is not None
            and prims[i].interior.fade_power is not None)),
    )


# ---------------------------------------------------------------- shadows
def _shadow_filter(ctx: TraceContext, o, l, dist):
    """RGB transmittance of the segment ``o → o + dist·l`` (§2.5): opaque crossings block,
    transparent ones multiply by ``f·P + t`` at each crossing; refraction is ignored."""
    t, n = all_crossings(ctx.geo, o, l)
    scale = ctx.eps * (1.0 + jnp.max(jnp.abs(o)))
    ok = jnp.asarray(ctx.casts_shadow) & jnp.isfinite(t) & (t > scale) & (t < dist - scale)
    ok = ok & csg_mask(ctx.geo, ctx.plan, o, l, t)
    one = jnp.ones(3, ctx.dtype)
    if not ctx.plan.effects.filtered_shadows:
        return jnp.where(jnp.any(ok), 0.0, 1.0) * one
    opaque = ok & ~jnp.asarray(ctx.transparent_cands)
    filt = one
    safe_t = jnp.where(jnp.isfinite(t), t, 0.0)
    n_layers = ctx.mats.n_layers
    for c in np.flatnonzero(ctx.transparent_cands):
        prim = int(ctx.geo.cand_prim[c])
        for k in np.flatnonzero(ctx.mats.layer_present[prim]):  # every layer filters (§2.5)
            pig = pigment_at(ctx.mats, prim * n_layers + int(k), o + safe_t[c] * l)
            f = pig[3] * pig[:3] + pig[4]
            filt = filt * jnp.where(ok[c], f, 1.0)
    fading = ctx.fading_cands
    if ctx.plan.effects.interior_fade and fading.size:
        # interior fade at every exit crossing, over the depth since the previous crossing (or
        # the shadow ray's start): the shadow ray continues from each hit (§2.4; povray 3.7
        # measured: a fading sphere attenuates a shadow by its chord, not by the air before it)
        accepted = jnp.where(ok, t, -jnp.inf)
        tc = accepted[fading]
        prev = jnp.max(jnp.where(accepted[None, :] < tc[:, None], accepted[None, :], 0.0), axis=1)
        prims = ctx.geo.cand_prim[fading]
        exiting = ok[fading] & (jnp.einsum("ri,i->r", n[fading], l)
                                * jnp.asarray(ctx.inverse_sign[fading], n.dtype) > 0)
        m = ctx.mats
        att = lt.interior_fade(jnp.where(exiting, tc - prev, 0.0)[:, None],
                               m.fade_distance[prims][:, None], m.fade_power[prims][:, None],
                               m.fade_color[prims], on=exiting[:, None])
        filt = filt * jnp.prod(att, axis=0)
    return jnp.where(jnp.any(opaque), 0.0, 1.0) * filt


def _area_weights(n: int) -> np.ndarray:
    """POV's recursive corner-averaging weights along one area-light axis (§2.5):
    3 samples → ¼ ½ ¼, 5 → ⅛ ¼ ¼ ¼ ⅛, 4 → uniform."""
    w = np.zeros(n)

    def rec(a, b, weight):
        if b - a <= 1:
            w[a] += weight / 2
            w[b] += weight / 2
            return
        m = (a + b) / 2
        rec(a, int(np.floor(m)), weight / 2)
        rec(int(np.ceil(m)), b, weight / 2)

    if n == 1:
        w[0] = 1.0
    else:
        rec(0, n - 1, 1.0)
    return w


def _light_geometry(light: Light, p):
    """Unit direction to the light, its distance (for fading), and the shadow-ray length."""
    if light.parallel:
        l = safe_normalize(light.position - light.point_at)
        to_light = light.position - p
        dist = jnp.sqrt(jnp.maximum(jnp.dot(to_light, to_light), 1e-30))
        return l, dist, jnp.dot(l, to_light)  # objects beyond the light's plane cast no shadow
    v = light.position - p
    dist = jnp.sqrt(jnp.maximum(jnp.dot(v, v), 1e-30))
    return v / dist, dist, dist


def _light_visibility(ctx: TraceContext, light: Light, p_spawn, l, shadow_len):
    if light.shadowless or not ctx.plan.effects.shadows:
        return jnp.ones(3, ctx.dtype)
    if light.area is None:
        return _shadow_filter(ctx, p_spawn, l, shadow_len)
    a = light.area
    w1, w2 = _area_weights(a.size1), _area_weights(a.size2)
    # grid point (i, j) at centre + axis1 (i/(n1-1) - ½) + axis2 (j/(n2-1) - ½); one shadow ray
    # each, vmapped (compile time does not grow with the grid)
    f1 = np.zeros(1) if a.size1 == 1 else np.arange(a.size1) / (a.size1 - 1) - 0.5
    f2 = np.zeros(1) if a.size2 == 1 else np.arange(a.size2) / (a.size2 - 1) - 0.5
    fu, fv = (g.reshape(-1) for g in np.meshgrid(f1, f2, indexing="ij"))
    weights = jnp.asarray(np.outer(w1, w2).reshape(-1), ctx.dtype)
    positions = (light.position[None, :] + jnp.asarray(fu, ctx.dtype)[:, None] * a.axis1[None, :]
                 + jnp.asarray(fv, ctx.dtype)[:, None] * a.axis2[None, :])

    def one(pos):
        v = pos - p_spawn
        dist = jnp.sqrt(jnp.maximum(jnp.dot(v, v), 1e-30))
        return _shadow_filter(ctx, p_spawn, v / dist, dist)

    return jnp.sum(weights[:, None] * jax.vmap(one)(positions), axis=0)


# ---------------------------------------------------------------- local shading
def _light_arrival(ctx: TraceContext, light: Light, p, p_spawn, n):
    """Direction to the light, the colour arriving (fade, spot cone, shadow filter) and whether the
    light is on the viewer's side of the surface (``n·l > 1e-10``, §2.4)."""
    l, dist, shadow_len = _light_geometry(light, p)
    c = light.color.astype(ctx.dtype)
    if light.fade_distance is not None and light.fade_power is not None:
        c = c * lt.fade(dist, light.fade_distance, light.fade_power)
    if light.spot is not None:
        axis = safe_normalize(light.point_at - light.position)
        c = c * lt.spot(jnp.dot(-l, axis), light.spot.radius_degrees, light.spot.falloff_degrees,
                        light.spot.tightness)
    cos_nl = jnp.dot(n, l)
    c = c * _light_visibility(ctx, light, p_spawn, l, shadow_len)
    return l, c, cos_nl, cos_nl > lt.NL_EPSILON


def _layer_light(ctx: TraceContext, light: Light, arrival, row, rgb, att, d, n):
    """Diffuse and highlight terms of one texture layer (material ``row``) for one light."""
    l, c, cos_nl, lit = arrival
    fin = ctx.mats.finish
    out = lt.diffuse(att, fin["diffuse"][row], fin["brilliance"][row], cos_nl, rgb) * c
    eff = ctx.plan.effects
    if eff.highlights and not light.shadowless:
        h = lt.phong(fin["phong"][row], fin["phong_size"][row], d, n, l)
        h = h + lt.specular(fin["specular"][row], fin["roughness"][row], d, n, l)
        tint = lt.metallic_tint(fin["metallic"][row], cos_nl, rgb) if eff.metallic else 1.0
        out = out + h * c * tint
    return jnp.where(lit, out, 0.0)


def _reflectivity(ctx: TraceContext, row, cos_i, eta_rel, rgb):
    """Reflection colour (§2.6) and its ray weight."""
    fin, mats = ctx.mats.finish, ctx.mats
    rmin, rmax = fin["refl_min"][row], fin["refl_max"][row]
    frac = safe_pow(1.0 - cos_i, fin["refl_falloff"][row])
    reflec = frac * rmax + (1 - frac) * rmin
    weight = jnp.maximum(jnp.max(rmax), jnp.max(rmin))
    if ctx.plan.effects.fresnel:
        f, total = lt.fresnel(cos_i, eta_rel)
        fres = jnp.where(total, rmax, f * rmax + (1 - f) * rmin)
        is_f = jnp.asarray(mats.fresnel)[row]
        reflec = jnp.where(is_f, fres, reflec)
        weight = jnp.where(is_f, jnp.max(reflec), weight)
    if ctx.plan.effects.metallic:
        reflec = reflec * lt.metallic_tint(fin["refl_metallic"][row], cos_i, rgb)
    return reflec, weight


def shade(ctx: TraceContext, o, d, weight, alive, is_reflection_ray, level):
    """Shades one ray. Returns the local colour and up to two child rays with their coefficients.

    ``level`` is POV-Ray's trace level of the ray (1 for camera rays). Children (each a dict with
    origin, direction, weight, coef (3,), alive, power, reflection, level): slot "T" the transmitted
    (or totally internally reflected) ray, slot "R" the mirror ray. A ray spawns children only if
    its level is below ``max_trace_level``; straight transmission (ior 1) keeps the level (§2.7).
    """
    eff = ctx.plan.effects
    max_level = ctx.settings.max_trace_level
    vis = jnp.where(is_reflection_ray, jnp.asarray(ctx.vis_reflect), jnp.asarray(ctx.vis_camera))
    scale = ctx.eps * (1.0 + jnp.max(jnp.abs(o)))
    hit = closest_hit(ctx.geo, ctx.plan, o, d, scale, vis, ctx.inverse_sign)
    found = hit.found & alive
    prim = hit.prim
    p = o + hit.t * d
    n_geom = hit.normal
    entering = jnp.dot(n_geom, d) < 0
    n = jnp.where(entering, n_geom, -n_geom)  # faces the incoming ray
    offset = ctx.eps * (1.0 + jnp.max(jnp.abs(p)))
    p_out = p + offset * n  # on the ray's side of the surface
    p_in = p - offset * n

    mats, fin = ctx.mats, ctx.mats.finish
    cos_i = -jnp.dot(d, n)
    ior = mats.ior[prim]
    eta_rel = jnp.where(entering, ior, 1.0 / ior)  # n_t / n_i
    arrivals = [_light_arrival(ctx, light, p, p_out, n) for light in ctx.lights]
    # texture layers, top first (§2.3): each adds its local colour filtered by the layers above;
    # the loop stops once the layers above let less than adc_bailout through
    fil = jnp.ones(3, ctx.dtype)
    trans = jnp.ones((), ctx.dtype)
    local = jnp.zeros(3, ctx.dtype)
    reflec = jnp.zeros(3, ctx.dtype)
    r_weight = jnp.zeros((), ctx.dtype)
    n_layers = mats.n_layers
    for k in range(n_layers):
        row = prim * n_layers + k
        active = jnp.asarray(mats.layer_present)[prim, k] & ((trans > ctx.settings.adc_bailout) | (k == 0))
        pig = pigment_at(mats, row, p)
        rgb, f, t = pig[:3], pig[3], pig[4]
        att = 1.0 - f - t
        tmp = att * rgb * (fin["ambient"][row] * ctx.settings.ambient_light + fin["emission"][row])
        for light, arrival in zip(ctx.lights, arrivals, strict=True):
            tmp = tmp + _layer_light(ctx, light, arrival, row, rgb, att, d, n)
        local = local + jnp.where(active, fil * tmp, 0.0)
        layer_fil = f * rgb + t
        if eff.reflection:
            reflec_k, w_k = _reflectivity(ctx, row, cos_i, eta_rel, rgb)
            reflec = reflec + jnp.where(active, reflec_k, 0.0)  # layers' reflections add up
            r_weight = jnp.maximum(r_weight, jnp.where(active, trans * w_k, 0.0))
            conserve = jnp.asarray(mats.conserve_energy)[row]
            layer_fil = jnp.where(conserve, layer_fil * jnp.minimum(1.0, 1.0 - reflec_k), layer_fil)
        fil = jnp.where(active, fil * layer_fil, fil)
        trans = jnp.minimum(1.0, jnp.abs(lt.grey(fil)))
    top = prim * n_layers
    children = {}
    tir = jnp.asarray(False)
    if eff.transmission:
        if eff.refraction:
            d_t, tir = lt.refract(d, n, 1.0 / eta_rel)
        else:
            d_t = d
        # interior fade on leaving (distance travelled inside = this segment's length)
        fd, fp = mats.fade_distance[prim], mats.fade_power[prim]
        if eff.interior_fade:
            att_col = lt.interior_fade(hit.t, fd, fp, mats.fade_color[prim], on=~entering)
        else:
            att_col = jnp.ones(3, ctx.dtype)
        t_weight = weight * jnp.max(jnp.abs(fil))
        t_alive = found & (trans > ctx.settings.adc_bailout) & (t_weight >= ctx.settings.adc_bailout)
        t_alive = t_alive & jnp.asarray(mats.transparent)[prim]  # opaque pigments never transmit
        # TIR is found by the refraction step, so it only replaces the mirror ray where that step
        # runs; a conserve_energy + fresnel surface under TIR has fil = 0 and reflects instead (§2.3)
        tir = tir & t_alive
        straight = jnp.abs(eta_rel - 1.0) < 1e-10
        t_level = jnp.where(straight & ~tir, level, level + 1)
        children["T"] = dict(
            origin=jnp.where(tir, p_out, p_in), direction=d_t,
            weight=jnp.where(tir, weight, t_weight),
            coef=jnp.where(tir, att_col, att_col * fil), power=jnp.ones((), ctx.dtype),
            alive=t_alive & (level < max_level), reflection=jnp.asarray(False), level=t_level)
    if eff.reflection:
        w = weight * r_weight
        r_alive = found & jnp.any(reflec != 0) & ~tir & (w >= ctx.settings.adc_bailout)
        expo = fin["refl_exponent"][top]  # the top layer's exponent for the summed reflection
        children["R"] = dict(
            origin=p_out, direction=lt.reflect(d, n), weight=w, coef=reflec, power=1.0 / expo,
            alive=r_alive & (level < max_level), reflection=jnp.asarray(True), level=level + 1)
    local = jnp.where(found, local, jnp.where(alive & ~hit.found, ctx.background, 0.0))
    return local, children


def _partition(alive):
    """A permutation putting live rays first (stable), and its inverse, in O(n) (no sort)."""
    n = alive.shape[0]
    live = alive.astype(jnp.int32)
    n_live = jnp.sum(live)
    pos = jnp.where(alive, jnp.cumsum(live) - 1, n_live + jnp.cumsum(1 - live) - 1)
    order = jnp.zeros(n, jnp.int32).at[pos].set(jnp.arange(n, dtype=jnp.int32))
    return order, pos


def _shade_batch(ctx: TraceContext, o, d, weight, alive, is_reflection, level, chunk: int):
    """``shade`` over a batch, in chunks of ``chunk`` rays with the live rays moved to the front;
    chunks with no live ray are skipped (``lax.cond`` runs only the taken branch and differentiates
    like any branch), so the empty slots of the Whitted tree cost almost nothing."""

    def shade_all(o, d, weight, alive, is_reflection, level):
        return jax.vmap(lambda *a: shade(ctx, *a))(o, d, weight, alive, is_reflection, level)

    n = o.shape[0]
    if chunk >= n:
        return shade_all(o, d, weight, alive, is_reflection, level)
    order, inverse = _partition(alive)
    n_chunks = n // chunk
    # two levels of skipping: blocks of chunks, then chunks, so a sparse level costs
    # O(blocks + chunks of one block) loop steps rather than O(chunks)
    per_block = _divisor_near(n_chunks, int(n_chunks ** 0.5))
    args = tuple(a[order].reshape((n_chunks // per_block, per_block, chunk) + a.shape[1:])
                 for a in (o, d, weight, alive, is_reflection, level))
    shapes = jax.eval_shape(shade_all, *(a[0, 0] for a in args))

    def zeros(lead=()):
        return jax.tree_util.tree_map(lambda x: jnp.zeros(lead + x.shape, x.dtype), shapes)

    def one_chunk(a):
        return jax.lax.cond(jnp.any(a[3]), lambda: shade_all(*a), zeros)

    def one_block(a):
        return jax.lax.cond(jnp.any(a[3]), lambda: jax.lax.map(one_chunk, a), lambda: zeros((per_block,)))

    out = jax.lax.map(one_block, args)
    return jax.tree_util.tree_map(lambda x: x.reshape((n,) + x.shape[3:])[inverse], out)


def _divisor_near(n: int, target: int) -> int:
    """The divisor of ``n`` closest to ``target`` (at least 1)."""
    divisors = [k for k in range(1, n + 1) if n % k == 0]
    return min(divisors, key=lambda k: abs(k - max(1, target)))


def pool_size(ctx: TraceContext, n_camera_rays: int, capacity: int | None = None) -> int:
    """Ray slots per level: the widest level of the Whitted tree, ``n · branch^(depth-1)``, or
    ``n · capacity`` when live rays are compacted (never more than the full width)."""
    eff = ctx.plan.effects
    branch = int(eff.reflection) + int(eff.transmission)
    full = n_camera_rays * (branch ** (eff.depth - 1) if branch > 1 else 1)
    return full if capacity is None else min(full, n_camera_rays * capacity)


def trace(ctx: TraceContext, o, d, chunk: int, capacity: int | None = None):
    """Colours (N, 3) of N camera rays: the whole Whitted tree, one ``lax.scan`` step per level.

    Each level lives in a pool of slots; a step shades the level (skipping dead chunks) and writes
    the children into the next level's pool; a reverse scan then combines ``local + coef · child``
    from the deepest level up. The shading body is traced once, so compile time does not grow with
    ``max_trace_level``; scan and cond are differentiable, so reverse mode works.

    Two layouts of the pool:
      * ``capacity=None`` (exact, the default): the pool is as wide as the tree's widest level
        (``N·branch^(depth-1)``), the children of slot i go to slots i and i + N·branch^k.
      * ``capacity=c``: the pool has ``N·c`` slots and the live children are compacted into it.
        Far cheaper for deep trees, where few of the 2^k slots hold a ray; children beyond the
        capacity are dropped and counted.

    Returns:
        ``(colours (N, 3), dropped)``: ``dropped`` counts children that did not fit (always 0
        without a capacity); a caller that needs the exact image re-renders with more capacity.
    """
    n = o.shape[0]
    depth = ctx.plan.effects.depth
    p = pool_size(ctx, n, capacity)
    compact = capacity is not None and p < pool_size(ctx, n)
    dtype = o.dtype
    pad = p - n
    pool = dict(
        o=jnp.concatenate([o, jnp.zeros((pad, 3), dtype)]),
        d=jnp.concatenate([d, jnp.broadcast_to(jnp.asarray([0.0, 0.0, 1.0], dtype), (pad, 3))]),
        weight=jnp.concatenate([jnp.ones(n, dtype), jnp.zeros(pad, dtype)]),
        alive=jnp.arange(p) < n,
        reflection=jnp.zeros(p, bool),
        level=jnp.ones(p, jnp.int32))  # POV counts the camera ray as level 1
    if depth == 1:
        local, _ = _shade_batch(ctx, pool["o"], pool["d"], pool["weight"], pool["alive"],
                                pool["reflection"], pool["level"], chunk)
        return local[:n], jnp.zeros((), jnp.int32)
    slots = None
    index = jnp.arange(p)
    keys = {"o": "origin", "d": "direction", "weight": "weight", "reflection": "reflection",
            "level": "level"}

    def level(pool, k):
        nonlocal slots
        local, children = _shade_batch(ctx, pool["o"], pool["d"], pool["weight"], pool["alive"],
                                       pool["reflection"], pool["level"], chunk)
        slots = sorted(children)
        has_next = k + 1 < depth
        live = {s: children[s]["alive"] & has_next for s in slots}
        if compact:
            # live children, in slot order, packed into the first slots of the next pool
            every = jnp.concatenate([live[s] for s in slots])
            pos = jnp.cumsum(every.astype(jnp.int32)) - 1
            keep = every & (pos < p)
            dest_all = jnp.where(keep, pos, p)  # p: dropped (out of range, scatter drops it)
            dropped = jnp.sum(every) - jnp.sum(keep)
            nxt = {key: jnp.zeros((p,) + children[slots[0]][src].shape[1:], children[slots[0]][src].dtype)
                   .at[dest_all].set(jnp.concatenate([children[s][src] for s in slots]), mode="drop")
                   for key, src in keys.items()}
            nxt["alive"] = jnp.zeros(p, bool).at[dest_all].set(keep, mode="drop")
            dest = {s: dest_all[i * p:(i + 1) * p] for i, s in enumerate(slots)}
            live = {s: keep[i * p:(i + 1) * p] for i, s in enumerate(slots)}
        else:
            width = n * jnp.power(len(slots), k)  # live slots of this level: [0, width)
            dest = {s: index + width * i for i, s in enumerate(slots)}
            dropped = jnp.zeros((), jnp.int32)
            if len(slots) == 1:
                ch = children[slots[0]]
                nxt = {key: ch[src] for key, src in keys.items()}
                nxt["alive"] = live[slots[0]]
            else:
                second = index >= width
                src_slot = jnp.where(second, index - width, index)
                a, b = children[slots[0]], children[slots[1]]

                def pick(key):
                    sel = second.reshape((p,) + (1,) * (a[key].ndim - 1))
                    return jnp.where(sel, b[key][src_slot], a[key][src_slot])

                nxt = {key: pick(src) for key, src in keys.items()}
                nxt["alive"] = pick("alive") & (index < 2 * width) & has_next
        record = {"local": local}
        for s in slots:
            record[s] = {"coef": children[s]["coef"], "alive": live[s], "power": children[s]["power"],
                         "dest": jnp.minimum(dest[s], p - 1)}
        return nxt, (record, dropped)

    _, (records, dropped) = jax.lax.scan(level, pool, jnp.arange(depth))

    def combine(colour_next, rec):
        out = rec["local"]
        for s in slots:
            c = colour_next[rec[s]["dest"]]
            if s == "R":
                # c^(1/exponent) written as c · c^(p-1): exact at p = 1 (the default), where
                # d/dp = c·log c must survive (a where(p == 1, c, …) shortcut would drop it)
                pw = rec[s]["power"][:, None]
                c = c * safe_pow(c, pw - 1.0)
            out = out + jnp.where(rec[s]["alive"][:, None], rec[s]["coef"] * c, 0.0)
        return out, None

    colour, _ = jax.lax.scan(combine, jnp.zeros((p, 3), dtype), records, reverse=True)
    return colour[:n], jnp.sum(dropped)
