"""POV-Ray's ``lathe``: a 2-D spline curve ``(r(s), y(s))`` turned about the y axis.

The curve's segments are held in Bernstein form, as a prism's outline is (``_prism.py``: POV-Ray's
linear, quadratic, cubic and Bézier splines; a lathe's curve is not closed for it). A line
``o + t d`` is at distance ``ρ(t)`` from the axis with ``ρ² = a t² + 2 b t + c`` (``a = d_x² +
d_z²``, ``b = o_x d_x + o_z d_z``, ``c = o_x² + o_z²``), so it reaches the radius of the curve
point ``s`` at the two roots ``t_lo(s) ≤ t_hi(s)`` of ``a t² + 2 b t + c − r(s)² = 0``, and it
crosses the surface where, on one of these two branches, its height there is the curve's:
``g(s) = y(s) − o_y − d_y t(s) = 0``.

Eliminating ``t`` instead gives one polynomial of degree 2n in ``s``, whose two roots of one height
(the line entering and leaving a ring) merge into a double root as the line turns horizontal,
where no sign change finds them; on the branches each is a simple root, the entry on one and the
exit on the other. The branches exist where the line reaches the radius (``r(s) ≥ ρ_min``, its
nearest approach to the axis) and meet where ``r(s) = ρ_min``: those junctions (a polynomial of the
curve's degree, solved as a prism's walls are) split each segment into pieces on which both
branches exist or neither. Each branch of each such piece is sampled at ``SAMPLES`` + 1 points; the
lathe's first ``slots`` intervals where ``g`` changes sign are bisected (half-open at the ends, so
a line through a joint crosses once; at most ``MAX_CROSSINGS``, far more than a line meets a
real lathe; past it the last found are dropped), and the roots get the implicit function theorem's derivatives
(``differentiable_root``). A line along
the axis (``a`` ~ 0) meets the surface where ``r(s)² = c``, at ``t = (y(s) − o_y) / d_y``.

The native hierarchy chooses among lathes with the same method in double precision (bvh.cc's
lathe); ``near_hit`` then computes the chosen crossing again on the ``NEAR_SEGMENTS`` segments
nearest it. Two roots of one branch closer than a sample interval (a line grazing a wavy curve) are missed:
the sampling's resolution, as for features thinner than a pixel. Normals are the curve's normal
turned about the axis, outward by the fill side of each segment (``segment_senses``); the inside is
the curve's even-odd fill in the meridian plane, as a prism's outline is filled.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .._dtype import as_float
from ..kernels._common import masked_hits
from ..kernels._numerics import (
    _bisect,
    as_float_arrays,
    differentiable_root,
    safe_div,
    safe_normalize,
    safe_sqrt,
)
from ._base import NATIVE_LATHE, AbstractShape, box_corners
from ._prism import (
    SPLINES,
    _derivative,
    _eval,
    _piece_roots,
    _splits,
    _straddles,
    outline_inside,
    padded_segments,
    read_points,
    segment_senses,
)

SAMPLES = 16  # intervals a branch of a piece of a segment is sampled in to find where it changes sign
AXIAL = 1e-6  # a line with a ≤ AXIAL |d|² runs along the axis
MAX_CROSSINGS = 16  # crossings of a line with a lathe that are kept (``lathe_hits``: the first found)


def lathe_segments(spline: str, points) -> np.ndarray:
    """(S, n + 1, 2) Bernstein control points ``(r, y)`` of POV-Ray's lathe spline through ``points``
    (N, 2): ``linear_spline`` N − 1 segments; ``quadratic_spline`` N − 2 (the first point sets the
    first slope); ``cubic_spline`` N − 3 (the first and last set the slopes); ``bezier_spline`` N/4
    (manual 3.4.5.1.8). Each segment is the prism's of the same spline (``spline_segments``)."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    n = len(pts)
    if spline == "linear_spline":
        segs = [pts[k:k + 2] for k in range(n - 1)]
    elif spline == "quadratic_spline":
        segs = [np.stack([pts[k], pts[k] + 0.25 * (pts[k + 1] - pts[k - 1]), pts[k + 1]])
                for k in range(1, n - 1)]
    elif spline == "cubic_spline":
        segs = [np.stack([pts[k], pts[k] + (pts[k + 1] - pts[k - 1]) / 6.0,
                          pts[k + 1] - (pts[k + 2] - pts[k]) / 6.0, pts[k + 1]]) for k in range(1, n - 2)]
    elif spline == "bezier_spline":
        segs = [pts[4 * k:4 * k + 4] for k in range(n // 4)]
    else:
        raise ValueError(f"unknown spline {spline!r}")
    if not segs:
        return np.zeros((0, SPLINES[spline] + 1, 2))
    return np.stack(segs)


def _branches(r, y, s, a, b, c, oy, dy, axial, junction=None):
    """At curve parameters ``s`` of the segments ``r``, ``y`` (…, n + 1): the two branches' ``g``
    and ``t``, and whether the line reaches the radius there: ``(g (2, …), t (2, …), reached (…))``.
    Along the axis the first branch is ``r² − c`` with ``t`` from the height, the second has none.
    ``junction`` (…) bool: points taken as junctions, where the two branches are one (the line's
    nearest approach), so that both see one value there whatever the rounding of ``s``."""
    rs, ys = _eval(r, s), _eval(y, s)
    cc = c - rs * rs
    disc = b * b - a * cc
    if junction is not None:
        disc = jnp.where(junction, 0.0, disc)
    reached = disc >= 0
    sq = safe_sqrt(disc)
    q = -(b + jnp.where(b < 0, -sq, sq))  # the stable pair of roots: q / a and cc / q
    t_far = safe_div(q, a, 0.0)
    # (where the line does not reach the radius both are its nearest approach, -b / a: the two
    # branches then agree exactly, at a junction too)
    t_near = jnp.where((q != 0) & (disc > 0), safe_div(cc, q, 0.0), t_far)
    t_lo, t_hi = jnp.minimum(t_far, t_near), jnp.maximum(t_far, t_near)
    h = ys - oy
    g_axial = -cc  # r² − c
    t_axial = safe_div(h, dy, 0.0)
    g = jnp.stack([jnp.where(axial, g_axial, h - dy * t_lo), jnp.where(axial, 1.0, h - dy * t_hi)])
    t = jnp.stack([jnp.where(axial, t_axial, t_lo), jnp.where(axial, jnp.inf, t_hi)])
    return g, t, reached | axial


def lathe_hits(controls, sense, o, d, *, slots: int):
    """The crossings of the line ``o + t d`` with the lathe, ``slots`` of them: those of the first
    sign changes in the order branch, segment, piece (where a line has more, which no lathe of
    POV-Ray's samples gives, the last in that order are dropped).

    Args:
        controls: (S, n + 1, 2) Bernstein control points ``(r, y)`` of the curve's segments.
        sense: (S,) int: +1 where the fill lies left of a segment's direction in the (r, y) plane,
            −1 right, 0 for a padding segment.
        o, d: (3,) the line (any length of ``d``).
        slots: crossings sought (static).

    Returns:
        ``(t, n)``: t (slots,), n (slots, 3) outward unit normals; +inf where none.
    """
    controls, o, d = as_float_arrays(controls, o, d)
    r, y = controls[..., 0], controls[..., 1]  # (S, n + 1)
    a = d[0] * d[0] + d[2] * d[2]
    b = o[0] * d[0] + o[2] * d[2]
    c = o[0] * o[0] + o[2] * o[2]
    axial = a <= AXIAL * (a + d[1] * d[1])
    sg = jax.lax.stop_gradient
    count = r.shape[0]

    # where the line's nearest approach to the axis equals the curve's radius the two branches
    # meet: the junctions split each segment into pieces on which both branches exist or neither
    rho_min = safe_sqrt(safe_div(sg(a) * sg(c) - sg(b) * sg(b), sg(a), 0.0))
    w = sg(r) - rho_min  # (S, n + 1): r(s) − ρ_min in Bernstein form
    splits = _splits(w)
    meets = _straddles(w, splits) & ~axial
    junctions = jnp.where(meets, _piece_roots(w, splits), 1.0)  # (S, n)
    ends = jnp.concatenate([jnp.zeros((count, 1), o.dtype), junctions, jnp.ones((count, 1), o.dtype)], -1)
    is_junction = jnp.concatenate([jnp.zeros((count, 1), bool), meets, jnp.zeros((count, 1), bool)], -1)
    rank = jnp.argsort(ends, -1)  # (S, n + 2)
    ends, is_junction = jnp.take_along_axis(ends, rank, -1), jnp.take_along_axis(is_junction, rank, -1)
    frac = jnp.linspace(0.0, 1.0, SAMPLES + 1, dtype=o.dtype)
    # (S, pieces, K + 1)
    grid = ends[:, :-1, None] + (ends[:, 1:] - ends[:, :-1])[..., None] * frac[None, None, :]
    pieces = grid.shape[1]
    first = (jnp.arange(SAMPLES + 1) == 0)[None, None, :]
    pinched = (first & is_junction[:, :-1, None]) | (first[..., ::-1] & is_junction[:, 1:, None])
    mids = 0.5 * (ends[:, :-1] + ends[:, 1:])
    _, _, exists = _branches(sg(r)[:, None, :], sg(y)[:, None, :], mids, sg(a), sg(b), sg(c), sg(o[1]),
                             sg(d[1]), axial)  # (S, pieces)
    # sample each branch of each piece; the lathe's first ``slots`` sign changes are bisected
    g_grid, _, _ = _branches(sg(r)[:, None, None, :], sg(y)[:, None, None, :], grid, sg(a), sg(b), sg(c),
                             sg(o[1]), sg(d[1]), axial, pinched)  # (2, S, pieces, K + 1)
    positive = g_grid > 0
    change = (positive[..., :-1] != positive[..., 1:]) & exists[None, :, :, None] & (
        jnp.asarray(sense) != 0)[None, :, None, None]  # (2, S, pieces, K)
    total = change.size
    change = change.reshape(-1)
    # the first ``slots`` changes: where the running count of changes first reaches 1, 2, …
    running = jnp.cumsum(change.astype(jnp.int32))
    order = jnp.minimum(jnp.searchsorted(running, jnp.arange(1, slots + 1, dtype=jnp.int32)), total - 1)
    found = change[order] & (running[order] == jnp.arange(1, slots + 1))
    per_branch = count * pieces * SAMPLES
    branch, rest = order // per_branch, order % per_branch
    seg = rest // (pieces * SAMPLES)
    interval = rest % (pieces * SAMPLES)
    lo = grid[..., :-1].reshape(count, -1)[seg, interval]
    hi = grid[..., 1:].reshape(count, -1)[seg, interval]
    iterations = jnp.finfo(o.dtype).nmant + 4

    def solve(j, k_, lo_, hi_):
        # bisected without gradient, then the implicit function theorem's derivatives
        def held(s):
            return _branches(sg(r)[k_], sg(y)[k_], s, sg(a), sg(b), sg(c), sg(o[1]), sg(d[1]), axial)[0][j]

        root, _ = _bisect(held, lo_, hi_, iterations)
        return _crossing(r[k_], y[k_], jnp.asarray(sense)[k_], j, root, o, d, axial)

    t, normal, reached = jax.vmap(solve)(branch, seg, lo, hi)
    ok = found & reached & jnp.isfinite(t)
    return masked_hits(t, normal, ok)


def _crossing(r, y, side, j, root, o, d, axial):
    """The crossing on branch ``j`` of segment ``r``, ``y`` (n + 1,) at curve parameter ``root``
    (held: a root of the branch's ``g``): ``(t, unit outward normal (3,), reached)``, ``t`` and the
    normal with the implicit function theorem's derivatives."""
    a = d[0] * d[0] + d[2] * d[2]
    b = o[0] * d[0] + o[2] * d[2]
    c = o[0] * o[0] + o[2] * o[2]
    s = differentiable_root(lambda s: _branches(r, y, s, a, b, c, o[1], d[1], axial)[0][j], root)
    _, t, reached = _branches(r, y, s, a, b, c, o[1], d[1], axial)
    # at the root the line's height gives t too: (y(s) − o_y) / d_y. Of the two, take the one less
    # sensitive to s: near a junction the branch's t moves as 1/√disc (a line crossing a ring near
    # its nearest approach to the axis), a near-horizontal line's height as 1/d_y
    sg = jax.lax.stop_gradient
    rs, dr_held = _eval(sg(r), sg(s)), _eval(_derivative(sg(r)), sg(s))
    dh_held = _eval(_derivative(sg(y)), sg(s))
    disc = sg(b) * sg(b) - sg(a) * (sg(c) - rs * rs)
    by_height = ~axial & (jnp.abs(dh_held) * safe_sqrt(disc) < jnp.abs(sg(d[1])) * jnp.abs(rs * dr_held))
    t = jnp.where(by_height, safe_div(_eval(y, s) - o[1], d[1], jnp.inf), t[j])
    # the normal: the curve's, (y', −r') on the side away from the fill, turned about the axis
    dr, dy = _eval(_derivative(r), s), _eval(_derivative(y), s)
    side = side.astype(o.dtype)
    nr, ny = side * dy, -side * dr
    p = o + jnp.where(jnp.isfinite(t), t, 0.0) * d
    rho = safe_sqrt(p[0] * p[0] + p[2] * p[2])
    on_axis = rho <= 0
    ux = jnp.where(on_axis, 1.0, safe_div(p[0], rho, 1.0))
    uz = jnp.where(on_axis, 0.0, safe_div(p[2], rho, 0.0))
    return t, safe_normalize(jnp.stack([nr * ux, ny, nr * uz])), reached


NEAR_SEGMENTS = 2  # segments ``lathe_near_hit`` looks at: those whose boxes lie nearest the point


def lathe_near_hit(controls, sense, o, d, t0):
    """The crossing at ``t0`` (the native hierarchy's, found in double precision, held) computed
    again with its derivatives, without sampling: the point there lies on the curve, so its curve
    parameter is the nearest point of the nearest of the ``NEAR_SEGMENTS`` segments whose control
    boxes (which hold the curve) lie nearest it in the meridian plane, and its branch is the near
    one where ``t0`` comes before the line's nearest approach to the axis. Returns
    ``(t (1,), n (1, 3))``."""
    controls, o, d = as_float_arrays(controls, o, d)
    sg = jax.lax.stop_gradient
    t0 = sg(jnp.asarray(t0, o.dtype))
    p = sg(o + t0 * d)
    q = jnp.stack([safe_sqrt(p[0] * p[0] + p[2] * p[2]), p[1]])
    c = sg(controls)
    gap_r = jnp.maximum(jnp.maximum(c[..., 0].min(-1) - q[0], q[0] - c[..., 0].max(-1)), 0.0)
    gap_y = jnp.maximum(jnp.maximum(c[..., 1].min(-1) - q[1], q[1] - c[..., 1].max(-1)), 0.0)
    gap = jnp.where(jnp.asarray(sense) != 0, gap_r + gap_y, jnp.inf)
    _, pick = jax.lax.top_k(-gap, min(NEAR_SEGMENTS, controls.shape[0]))

    def nearest(k):  # the curve parameter nearest q on segment k, and the distance
        grid = jnp.linspace(0.0, 1.0, 17, dtype=o.dtype)
        pts = jnp.stack([_eval(c[k, None, :, 0], grid), _eval(c[k, None, :, 1], grid)], -1)
        s = grid[jnp.argmin(jnp.sum((pts - q[None, :]) ** 2, -1))]
        for _ in range(4):  # Newton on (C(s) − q)·C'(s) = 0
            point = jnp.stack([_eval(c[k, :, 0], s), _eval(c[k, :, 1], s)])
            tangent = jnp.stack([_eval(_derivative(c[k, :, 0]), s), _eval(_derivative(c[k, :, 1]), s)])
            bend = (jnp.stack([_eval(_derivative(_derivative(c[k, :, 0])), s),
                               _eval(_derivative(_derivative(c[k, :, 1])), s)])
                    if c.shape[1] > 2 else jnp.zeros(2, o.dtype))
            f = jnp.dot(point - q, tangent)
            df = jnp.dot(tangent, tangent) + jnp.dot(point - q, bend)
            s = jnp.clip(s - safe_div(f, df, 0.0), 0.0, 1.0)
        point = jnp.stack([_eval(c[k, :, 0], s), _eval(c[k, :, 1], s)])
        return s, jnp.sum((point - q) ** 2)

    s_near, dist = jax.vmap(nearest)(pick)
    best = jnp.argmin(dist)
    k, root = pick[best], s_near[best]
    a = sg(d[0] * d[0] + d[2] * d[2])
    b = sg(o[0] * d[0] + o[2] * d[2])
    axial = a <= AXIAL * (a + sg(d[1]) * sg(d[1]))
    j = jnp.where(axial | (t0 * a <= -b), 0, 1)
    r, y = controls[k, :, 0], controls[k, :, 1]
    t, n, _ = _crossing(r, y, jnp.asarray(sense)[k], j, root, o, d, axial)
    return t[None], n[None]


def lathe_inside(controls, sense, p):
    """Whether ``p`` (3,) is inside: its meridian point ``(ρ, y)`` filled by the curve (even-odd)."""
    rho = safe_sqrt(p[0] * p[0] + p[2] * p[2])
    return outline_inside(controls, sense, rho, p[1])


class Lathe(AbstractShape):
    """``lathe { [spline] n, <r, y>… [sturm] }``: the curve through the points, turned about y.

    Attributes:
        controls: (S, n + 1, 2) Bernstein control points ``(r, y)`` of the segments (S a power of
                  two; padding segments have ``sense`` 0).
        sense:    (S,) int8, which side of each segment is filled (``segment_senses``).
    """

    kind: ClassVar[str] = "lathe"
    crossings: ClassVar[int] = 2
    sdl_keywords: ClassVar[tuple[str, ...]] = ("lathe",)
    sdl_flags: ClassVar[tuple[str, ...]] = ("sturm",)
    controls: Float[Array, "S m 2"] = eqx.field(converter=as_float)
    sense: Int[Array, " S"] = eqx.field(converter=lambda x: jnp.asarray(x, jnp.int8))

    # the native hierarchy chooses among lathes (bvh.cc's lathe, in double, the item laid out as a
    # prism's); the JAX kernel then computes the chosen crossing again (``near_hit``)
    native_kernel: ClassVar[int | None] = NATIVE_LATHE
    costly_kernel: ClassVar[bool] = True

    def n_native_rows(self) -> int:
        s, m = self.controls.shape[-3], self.controls.shape[-2]
        return -(-(24 + s * (2 * m + 1)) // 24)

    def native_items(self):
        """One item: a prism's header ``[S, n, 0, 0, 0, 0, 1]``, then the control points (r, y) and
        the senses (bvh.cc's lathe), zero padded to its rows; the corners of its box."""
        from ._base import array_module

        xp = array_module(self.controls)
        s, m = self.controls.shape[-3], self.controls.shape[-2]
        dtype = self.controls.dtype
        head = xp.asarray([s, m - 1, 0.0, 0.0, 0.0, 0.0, 1.0], dtype)
        body = xp.concatenate([head, xp.zeros(5, dtype), xp.reshape(self.controls, (-1,)),
                               xp.asarray(self.sense).astype(dtype)])
        size = 24 * self.n_native_rows() - 12
        lo, hi = self.bounds()
        return xp.pad(body, (0, size - body.shape[0]))[None], box_corners(lo, hi)[None]

    def near_hit(self, o, d, t0):
        return lathe_near_hit(self.controls, self.sense, o, d, t0)

    @property
    def slots(self) -> int:
        """Crossings sought (static): 2n a segment of degree n (a line meets a segment's surface
        at most 2n times), at most ``MAX_CROSSINGS`` for the whole lathe."""
        s, m = self.controls.shape[-3], self.controls.shape[-2]
        return min(2 * (m - 1) * s, MAX_CROSSINGS)

    def n_crossings(self) -> int:
        return self.slots

    @property
    def line_crossings(self) -> int:
        live = int(np.count_nonzero(np.asarray(self.sense)))
        return min(live * 2 * (self.controls.shape[-2] - 1), MAX_CROSSINGS)

    def hits(self, o, d):
        return lathe_hits(self.controls, self.sense, o, d, slots=self.slots)

    def inside(self, p):
        return lathe_inside(self.controls, self.sense, p)

    def bounds(self):
        from ._base import array_module

        xp = array_module(self.controls)
        live = xp.asarray(self.sense) != 0
        pts = xp.asarray(self.controls).reshape(-1, 2)
        mask = xp.repeat(live, self.controls.shape[-2])
        big = xp.asarray(np.finfo(np.float32).max, pts.dtype)
        radius = xp.where(mask, xp.abs(pts[:, 0]), 0.0).max()
        y_lo = xp.where(mask, pts[:, 1], big).min()
        y_hi = xp.where(mask, pts[:, 1], -big).max()
        return xp.stack([-radius, y_lo, -radius]), xp.stack([radius, y_hi, radius])

    @classmethod
    def parse_sdl(cls, keyword, args):
        spline = args.keyword(*SPLINES) or "linear_spline"
        loc = args.loc
        pts = read_points(args, "lathe points")
        n = len(pts)
        need = {"linear_spline": 2, "quadratic_spline": 3, "cubic_spline": 4, "bezier_spline": 4}[spline]
        if n < need or (spline == "bezier_spline" and n % 4):
            multiple = " (a multiple of 4)" if spline == "bezier_spline" else ""
            raise args.error(f"expected at least {need} points for a {spline} lathe{multiple}, found {n}",
                             loc)
        return {"segments": lathe_segments(spline, pts)}

    @classmethod
    def from_sdl(cls, fields):
        return lathe_from_segments(fields["segments"])


def lathe_from_segments(segments) -> Lathe:
    """A lathe from Bernstein segments ``(r, y)`` (S, n + 1, 2): their fill sides found, padded."""
    segments = np.ascontiguousarray(segments, np.float64)
    controls, sense = padded_segments(segments, segment_senses(segments))
    return Lathe(controls=controls, sense=sense)
