"""Cylinder and cone (a frustum): one side surface plus two flat caps.

Both are the frustum ``|p⊥|² = r(h)²`` with ``h`` the height along the axis from ``base`` (0) to
``cap`` (``L``) and ``r(h) = r_base + k h``, ``k = (r_cap - r_base) / L``; the cylinder is ``k = 0``.
Slots: ``[side crossing 0, side crossing 1, base cap, cap cap]``.
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits, points_at
from ..kernels._numerics import as_float_arrays, safe_div, safe_normalize, solve_linear, solve_quadratic
from ._base import (
    NATIVE_FRUSTUM,
    AbstractShape,
    MitsubaShape,
    NoEquivalent,
    SdlArguments,
    affine,
    apply_point,
    array_module,
    box_corners,
    disc_bounds,
    frame,
    native_params,
    similarity_scale,
    unit,
)

CYLINDER_K = 4
CONE_K = 4


def _frame(base, cap):
    """Unit axis, axis length and slope denominator of the frustum."""
    axis = cap - base
    length_sq = jnp.dot(axis, axis)
    a_hat = safe_normalize(axis)
    return a_hat, jnp.sqrt(jnp.where(length_sq > 0, length_sq, 1.0)), length_sq > 0


def _frustum_surfaces(base, base_radius, cap, cap_radius, o, d):
    """The line's crossings with the frustum's three surfaces whole (the cone or cylinder of its
    side, unbounded; the planes of its two ends): ``(t_side (2,), t_caps (2,), ok_caps (2,), h0,
    hd, l_perp, d_perp, a_hat, length, slope, proper)``; the side's +inf where the line misses it,
    a cap's plane crossed where ``ok_caps``."""
    a_hat, length, proper = _frame(base, cap)
    slope = safe_div(cap_radius - base_radius, length)
    l = o - base
    h0, hd = jnp.dot(l, a_hat), jnp.dot(d, a_hat)
    l_perp, d_perp = l - h0 * a_hat, d - hd * a_hat
    r0 = base_radius + slope * h0  # radius of the cone at the height of o
    a = jnp.dot(d_perp, d_perp) - (slope * hd) ** 2
    b = 2.0 * (jnp.dot(l_perp, d_perp) - slope * hd * r0)
    c = jnp.dot(l_perp, l_perp) - r0 * r0
    # b² - 4ac expanded to 4 (|r0 d⊥ - k hd l⊥|² - |d⊥ × l⊥|²): for the cylinder this is the
    # distance-of-closest-approach form, which does not cancel for distant rays.
    w = r0 * d_perp - slope * hd * l_perp
    cross = jnp.cross(d_perp, l_perp)
    t0, t1, _ = solve_quadratic(a, b, c, 4.0 * (jnp.dot(w, w) - jnp.dot(cross, cross)))
    t_base, ok_base = solve_linear(hd, h0)
    t_cap, ok_cap = solve_linear(hd, h0 - length)
    t_caps, ok_caps = jnp.stack([t_base, t_cap]), jnp.stack([ok_base, ok_cap])
    return jnp.stack([t0, t1]), t_caps, ok_caps, h0, hd, l_perp, d_perp, a_hat, length, slope, proper


def _frustum_hits(base, base_radius, cap, cap_radius, o, d, open_):
    t_side, t_caps, ok_caps, h0, hd, l_perp, d_perp, a_hat, length, slope, proper = _frustum_surfaces(
        base, base_radius, cap, cap_radius, o, d)
    h_side = h0 + jnp.where(jnp.isfinite(t_side), t_side, 0.0) * hd
    side_ok = jnp.isfinite(t_side) & (h_side >= 0) & (h_side <= length) & proper
    p_perp = points_at(l_perp, d_perp, t_side)
    # Gradient of |p⊥|² - r(h)², halved: outward, since the solid is |p⊥| < r(h).
    n_side = safe_normalize(p_perp - ((base_radius + slope * h_side) * slope)[:, None] * a_hat[None, :])

    radii = jnp.stack([base_radius, cap_radius])
    q_perp = points_at(l_perp, d_perp, t_caps)
    caps_ok = (
        ok_caps
        & (jnp.sum(q_perp * q_perp, axis=-1) <= radii * radii)
        & (radii > 0)
        & proper
        & ~jnp.asarray(open_)  # (a static flag, or a frustum form's array)
    )
    n_caps = jnp.stack([-a_hat, a_hat])
    t = jnp.concatenate([t_side, t_caps])
    return masked_hits(t, jnp.concatenate([n_side, n_caps]), jnp.concatenate([side_ok, caps_ok]))


FRUSTUM_FACES = 3  # the side, the base's disc, the cap's disc


def _frustum_face(base, base_radius, cap, cap_radius, p, open_):
    """Which of the frustum's faces the surface point ``p`` lies on (``AbstractShape.face``): 0 the
    side, 1 the base's disc, 2 the cap's; the nearest surface of the three. An open frustum has its
    side only."""
    a_hat, length, _ = _frame(base, cap)
    slope = safe_div(cap_radius - base_radius, length)
    l = p - base
    h = jnp.dot(l, a_hat)
    r = jnp.sqrt(jnp.maximum(jnp.sum((l - h * a_hat) ** 2), 0.0))
    side = jnp.abs(r - (base_radius + slope * h)) / jnp.sqrt(1.0 + slope * slope)
    face = jnp.argmin(jnp.stack([side, jnp.abs(h), jnp.abs(h - length)])).astype(jnp.int32)
    return jnp.where(jnp.asarray(open_), 0, face)


def _frustum_face_distance(base, base_radius, cap, cap_radius, o, d, face, t_ref):
    """The line's crossing with face ``face``'s whole surface nearest ``t_ref`` (held)
    (``AbstractShape.face_distance``)."""
    t_side, t_caps, ok_caps, *_ = _frustum_surfaces(base, base_radius, cap, cap_radius, o, d)
    gap = jnp.where(jnp.isfinite(t_side), jnp.abs(t_side - t_ref), jnp.inf)
    near = jnp.argmin(jax.lax.stop_gradient(gap))
    t_caps = jnp.where(ok_caps, t_caps, jnp.inf)
    return jnp.where(face == 0, t_side[near], t_caps[jnp.clip(face - 1, 0, 1)])


def _frustum_margin(base, base_radius, cap, cap_radius, o, d, open_):
    """The closed frustum's silhouette margin (``AbstractShape.silhouette_margin``): the largest, over
    the line, of the least of its three insides — ``r(h)² − |p⊥|²`` (the cone's side, quadratic in
    t), ``h`` and ``length − h`` (the two caps' planes, linear) — positive exactly where the line
    passes through the solid. The largest least value is the vertex of the side's quadratic or a
    meeting of two of the three; its value is that candidate's own (a smooth function of the shape
    and the line: a min or max over tied values would split the derivative between them).

    An open frustum is its side alone: a line through both end openings passes down the bore and
    misses it. With ``e₀, e₁`` the side's inside where the line crosses the two ends' planes (the
    openings' margins: zero where the line passes through a rim), the margin is ``−e₀ e₁`` through
    either opening (positive through one only: the line crosses the side between the ends) and the
    closed frustum's through neither; it is continuous, and each piece is smooth where it vanishes
    (a rim seen past the other's opening, a rim's outline, the side's; where the two rims' images
    cross, the product's two factors vanish together: a corner of the bore's outline, each edge
    the zero of its own factor). NaN for a degenerate frustum: no margin."""
    a_hat, length, proper = _frame(base, cap)
    slope = safe_div(cap_radius - base_radius, length)
    l = o - base
    h0, hd = jnp.dot(l, a_hat), jnp.dot(d, a_hat)
    l_perp, d_perp = l - h0 * a_hat, d - hd * a_hat
    r0 = base_radius + slope * h0
    # side(t) = qa t² + qb t + qc; base(t) = h0 + hd t; top(t) = length − h0 − hd t
    qa = (slope * hd) ** 2 - jnp.dot(d_perp, d_perp)
    qb = 2.0 * (slope * hd * r0 - jnp.dot(l_perp, d_perp))
    qc = r0 * r0 - jnp.dot(l_perp, l_perp)
    tiny = jnp.finfo(o.dtype).tiny

    def safe(x):
        return jnp.where(jnp.abs(x) > tiny, x, 1.0)

    def side(t):
        return (qa * t + qb) * t + qc

    candidates, defined = [-qb / (2 * safe(qa))], [qa < -tiny]  # the side's vertex (concave)
    for lin_a, lin_b in ((h0, hd), (length - h0, -hd)):  # side = plane: qa t² + (qb − b) t + (qc − a)
        b_, c_ = qb - lin_b, qc - lin_a
        disc = b_ * b_ - 4 * qa * c_
        root = jnp.sqrt(jnp.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            quadratic = jnp.abs(qa) > tiny
            t = jnp.where(quadratic, (-b_ + sign * root) / (2 * safe(qa)), -c_ / safe(b_))
            candidates.append(t)
            defined.append(jnp.where(quadratic, disc >= 0, jnp.abs(b_) > tiny))
    candidates.append((length - 2 * h0) / (2 * safe(hd)))  # the two planes meet (mid-height)
    defined.append(jnp.abs(hd) > tiny)
    t = jnp.stack(candidates)
    ok = jnp.stack(defined)
    base_in, top_in = h0 + hd * t, length - h0 - hd * t
    depth = jnp.minimum(side(t), jnp.minimum(base_in, top_in))
    # each candidate's own value: the side's at the vertex and the side–plane meetings, the planes'
    # where they meet
    value = jnp.concatenate([side(t[:5]), base_in[5:]])
    best = jnp.argmax(jnp.where(ok, 2 * depth - value, -jnp.inf))
    closed = jnp.where(jnp.any(ok), value[best], jnp.nan)
    # open: the side's inside where the line crosses each end's plane (positive: through that
    # end's opening). Through one opening only, the line crosses the side between the ends; through
    # both it passes down the bore; through neither it crosses the side where it crosses the solid
    ends, along = _ends_insides(base, base_radius, cap, cap_radius, o, d)
    through = along & (ends > 0)
    # (through neither, a line that meets no candidate, along the axis, misses the side)
    neither = jnp.where(jnp.any(ok), closed, -1.0)
    opened = jnp.where(through[0] | through[1], -ends[0] * ends[1], neither)  # (both finite there)
    return jnp.where(proper, jnp.where(jnp.asarray(open_), opened, closed), jnp.nan)


def _ends_insides(base, base_radius, cap, cap_radius, o, d):
    """``(inside (2,), ok)``: the side's inside ``r(h)² − |p⊥|²`` where the line crosses the base's
    and the cap's planes (positive: through that end's opening; zero: through its rim), and whether
    the line crosses them (not parallel to them, the frustum not degenerate)."""
    a_hat, length, proper = _frame(base, cap)
    l = o - base
    h0, hd = jnp.dot(l, a_hat), jnp.dot(d, a_hat)
    ok = proper & (jnp.abs(hd) > jnp.finfo(o.dtype).tiny)
    h = jnp.stack([jnp.zeros_like(length), length])
    p = l[None, :] + ((h - h0) / jnp.where(ok, hd, 1.0))[:, None] * d[None, :]
    radius = jnp.stack([base_radius, cap_radius])
    return radius * radius - jnp.sum((p - h[:, None] * a_hat[None, :]) ** 2, axis=-1), ok


def _frustum_rim_margin(base, base_radius, cap, cap_radius, o, d):
    """``AbstractShape.rim_margin`` of an open frustum: the side's inside where the line crosses the
    plane of the end whose rim it passes nearer (zero where it passes through that rim: the bore's
    wall seen past it on one side, the side's outside on the other). NaN for a line parallel to the
    ends' planes or a degenerate frustum."""
    inside, ok = _ends_insides(base, base_radius, cap, cap_radius, o, d)
    nearer = jnp.argmin(jax.lax.stop_gradient(jnp.abs(inside)))
    return jnp.where(ok, inside[nearer], jnp.nan)


def frustum_form_hits(arrays, o, d):
    """The kernel of cylinders and cones alike (``AbstractShape.kernel_form``): the crossings of
    the frustum ``arrays`` = (base, base radius, cap, cap radius, open) (one
    shape's: ``Cylinder.kernel_form``, ``Cone.kernel_form``) with the line ``o + t d``: the
    cylinder's and the cone's own ``hits``, bit for bit."""
    base, base_radius, cap, cap_radius, open_ = arrays
    return _frustum_hits(base, base_radius, cap, cap_radius, o, d, open_)


def _frustum_inside(base, base_radius, cap, cap_radius, p):
    a_hat, length, proper = _frame(base, cap)
    l = p - base
    h = jnp.dot(l, a_hat)
    l_perp = l - h * a_hat
    r = base_radius + safe_div(cap_radius - base_radius, length) * h
    return proper & (h > 0) & (h < length) & (jnp.dot(l_perp, l_perp) < r * r)


def cylinder_hits(
    base: Float[ArrayLike, "3"],
    cap: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
    open: bool = False,
) -> tuple[Float[Array, "4"], Float[Array, "4 3"]]:
    """Crossings of the line ``o + t d`` with a finite cylinder.

    Args:
        base, cap: (3,) centres of the two end discs; equal points give a miss.
        radius: () radius (> 0).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.
        open: static; True removes the end caps (their slots are always ``+inf``).

    Returns:
        ``(t, n)``: t (4,) = (side, side, base cap, cap cap), ``+inf`` where absent; n (4, 3) unit
        outward normals (radial on the side, ``∓ axis`` on the caps).
    """
    base, cap, radius, o, d = as_float_arrays(base, cap, radius, o, d)
    return _frustum_hits(base, radius, cap, radius, o, d, open)


def cylinder_inside(
    base: Float[ArrayLike, "3"],
    cap: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    p: Float[ArrayLike, "3"],
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside the solid cylinder (also for an ``open`` one, as in POV-Ray)."""
    base, cap, radius, p = as_float_arrays(base, cap, radius, p)
    return _frustum_inside(base, radius, cap, radius, p)


def cone_hits(
    base: Float[ArrayLike, "3"],
    base_radius: Float[ArrayLike, ""],
    cap: Float[ArrayLike, "3"],
    cap_radius: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
    open: bool = False,
) -> tuple[Float[Array, "4"], Float[Array, "4 3"]]:
    """Crossings of the line ``o + t d`` with a cone frustum.

    Args:
        base, cap: (3,) centres of the two end discs.
        base_radius, cap_radius: () radii (>= 0); a zero radius is an apex and has no cap disc.
        o: (3,) ray origin.
        d: (3,) ray direction, any length.
        open: static; True removes the end caps.

    Returns:
        ``(t, n)``: t (4,) = (side, side, base cap, cap cap), ``+inf`` where absent; n (4, 3) unit
        outward normals. At the apex itself the side normal is undefined and is some finite unit vector.
    """
    base, base_radius, cap, cap_radius, o, d = as_float_arrays(base, base_radius, cap, cap_radius, o, d)
    return _frustum_hits(base, base_radius, cap, cap_radius, o, d, open)


def cone_inside(
    base: Float[ArrayLike, "3"],
    base_radius: Float[ArrayLike, ""],
    cap: Float[ArrayLike, "3"],
    cap_radius: Float[ArrayLike, ""],
    p: Float[ArrayLike, "3"],
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside the solid frustum."""
    base, base_radius, cap, cap_radius, p = as_float_arrays(base, base_radius, cap, cap_radius, p)
    return _frustum_inside(base, base_radius, cap, cap_radius, p)


# ---------------------------------------------------------------- the record

class Cylinder(AbstractShape):
    """``cylinder { base, cap, radius [open] }``."""

    kind: ClassVar[str] = "cylinder"
    crossings: ClassVar[int] = CYLINDER_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("cylinder",)
    sdl_arguments: ClassVar[SdlArguments] = (("base", "vector"), ("cap", "vector"), ("radius", "float"))
    sdl_flags: ClassVar[tuple[str, ...]] = ("open",)
    base: Float[Array, "3"] = eqx.field(converter=as_float)
    cap: Float[Array, "3"] = eqx.field(converter=as_float)
    radius: Float[Array, ""] = eqx.field(converter=as_float)
    open: bool = eqx.field(static=True, default=False)
    line_crossings: ClassVar[int] = 2  # convex: side and caps together are crossed at most twice

    def hits(self, o, d):
        return cylinder_hits(self.base, self.cap, self.radius, o, d, open=self.open)

    def silhouette_margin(self, o, d):
        base, cap, radius, o, d = as_float_arrays(self.base, self.cap, self.radius, o, d)
        return _frustum_margin(base, radius, cap, radius, o, d, self.open)

    def shows_inside(self):
        return self.open

    def rim_margin(self, o, d):
        base, cap, radius, o, d = as_float_arrays(self.base, self.cap, self.radius, o, d)
        return _frustum_rim_margin(base, radius, cap, radius, o, d)

    faces: ClassVar[int] = FRUSTUM_FACES

    def face(self, p):
        return _frustum_face(self.base, self.radius, self.cap, self.radius, p, self.open)

    def face_distance(self, o, d, face, t_ref):
        return _frustum_face_distance(self.base, self.radius, self.cap, self.radius, o, d, face, t_ref)

    def kernel_form(self):
        open_ = jnp.full(jnp.shape(self.radius), self.open)
        return frustum_form_hits, (self.base, self.radius, self.cap, self.radius, open_)

    def inside(self, p):
        # open or not, the inside is the solid's (semantics §4.1)
        return cylinder_inside(self.base, self.cap, self.radius, p)

    def bounds(self):
        return _segment_bounds(self.base, self.cap, self.radius, self.radius)

    native_kernel: ClassVar[int] = NATIVE_FRUSTUM

    def native_items(self):
        return (native_params(self.base, self.radius, self.cap, self.radius, float(self.open)),
                box_corners(*self.bounds())[None])


    def to_mitsuba(self, m, camera_origin):
        s = similarity_scale(m)
        if s is None:
            raise NoEquivalent("non-uniformly scaled cylinder")
        base, cap = apply_point(m, self.base), apply_point(m, self.cap)
        radius = s * float(self.radius)
        entries = [{"type": "cylinder", "p0": base.tolist(), "p1": cap.tolist(), "radius": radius}]
        axis = unit(cap - base)
        if not self.open:
            for centre, normal in ((base, -axis), (cap, axis)):
                entries.append({"type": "disk",
                                "to_world": affine(frame(normal) @ np.diag([radius, radius, 1.0]), centre)})
        return MitsubaShape(entries, closed=not self.open, planar=False)


class Cone(AbstractShape):
    """``cone { base, base_radius, cap, cap_radius [open] }`` (a frustum)."""

    kind: ClassVar[str] = "cone"
    crossings: ClassVar[int] = CONE_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("cone",)
    sdl_arguments: ClassVar[SdlArguments] = (
        ("base", "vector"), ("base_radius", "float"), ("cap", "vector"), ("cap_radius", "float"))
    sdl_flags: ClassVar[tuple[str, ...]] = ("open",)
    base: Float[Array, "3"] = eqx.field(converter=as_float)
    base_radius: Float[Array, ""] = eqx.field(converter=as_float)
    cap: Float[Array, "3"] = eqx.field(converter=as_float)
    cap_radius: Float[Array, ""] = eqx.field(converter=as_float)
    open: bool = eqx.field(static=True, default=False)
    line_crossings: ClassVar[int] = 2  # convex: side and caps together are crossed at most twice

    def hits(self, o, d):
        return cone_hits(self.base, self.base_radius, self.cap, self.cap_radius, o, d, open=self.open)

    def silhouette_margin(self, o, d):
        base, r0, cap, r1, o, d = as_float_arrays(self.base, self.base_radius, self.cap, self.cap_radius,
                                                  o, d)
        return _frustum_margin(base, r0, cap, r1, o, d, self.open)

    def shows_inside(self):
        return self.open

    def rim_margin(self, o, d):
        base, r0, cap, r1, o, d = as_float_arrays(self.base, self.base_radius, self.cap, self.cap_radius,
                                                  o, d)
        return _frustum_rim_margin(base, r0, cap, r1, o, d)

    faces: ClassVar[int] = FRUSTUM_FACES

    def face(self, p):
        return _frustum_face(self.base, self.base_radius, self.cap, self.cap_radius, p, self.open)

    def face_distance(self, o, d, face, t_ref):
        return _frustum_face_distance(self.base, self.base_radius, self.cap, self.cap_radius, o, d, face,
                                      t_ref)

    def kernel_form(self):
        return frustum_form_hits, (self.base, self.base_radius, self.cap, self.cap_radius,
                         jnp.full(jnp.shape(self.base_radius), self.open))

    def inside(self, p):
        return cone_inside(self.base, self.base_radius, self.cap, self.cap_radius, p)

    def bounds(self):
        return _segment_bounds(self.base, self.cap, self.base_radius, self.cap_radius)

    native_kernel: ClassVar[int] = NATIVE_FRUSTUM

    def native_items(self):
        return (native_params(self.base, self.base_radius, self.cap, self.cap_radius, float(self.open)),
                box_corners(*self.bounds())[None])



def _segment_bounds(base, cap, r0, r1):
    """The exact box of the frustum: the box of its two end discs (radius ``r0`` about ``base``,
    ``r1`` about ``cap``, both normal to the axis), as POV-Ray bounds cylinders and cones (the box
    decides ties between coincident surfaces, semantics §4.4)."""
    xp = array_module(base, cap, r0, r1)
    axis = xp.asarray(cap) - xp.asarray(base)
    lo0, hi0 = disc_bounds(base, axis, r0)
    lo1, hi1 = disc_bounds(cap, axis, r1)
    return xp.minimum(lo0, lo1), xp.maximum(hi0, hi1)
