"""A closed 2-D outline of spline segments swept along an axis: POV-Ray's ``prism`` (the outline in
the x-z plane, swept along y between two heights, straight up or towards the origin) and ``text``
(TrueType glyph outlines in the x-y plane, extruded along z; ``_text.py``).

Every segment is held in Bernstein form (the curve's control points, degree 1, 2 or 3 for the whole
shape): linear splines are their two points, quadratic splines three, cubic and Bézier splines
four. POV-Ray's quadratic and cubic splines pass through their points; their Bernstein points are
worked out from the points and their neighbours when the prism is built (``spline_segments``;
docs/semantics.md §4.1).

A line crosses a segment's wall where a polynomial in the curve parameter ``s`` vanishes: for a
straight sweep, the 2-D cross product of the line's direction with the curve point seen from its
origin; for a conic sweep (the outline scaled by the height, walls ruled through the origin), the
dot product of the curve point ``(x(s), 1, z(s))`` with the normal of the plane through the origin
and the line. Both are linear in the curve, so the polynomial's Bernstein coefficients are the
control points' values. Its roots in ``[0, 1)`` are found piece by piece between its critical
points, where it is monotone: a piece holds a crossing exactly when its end values straddle zero,
and a segment's end values are its end control points' own, the same numbers as its neighbour's,
so a line through a joint crosses once. Quadratics solve in closed form, cubics by bisection with
the implicit function theorem's derivatives (``differentiable_root``). The caps are filled by the
even-odd rule (POV-Ray: "wherever an even number of sub-prisms overlaps a hole appears"): a point
is inside where a half-line from it crosses the outline an odd number of times, counted by the
same straddle rule.

A segment's outward side is found when the prism is built (``sense``: the side of its middle
where the fill is), so a solid's wall normals point out wherever the outline's loops turn.

The outline's segments are padded to a power of two (``padded_segments``), so prisms and texts of
similar size stack into one group of the program (``shading/_geometry._variant``): the program
grows with the log of the largest outline, not with the number of different ones.
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
    solve_linear,
    solve_quadratic,
)
from ._base import NATIVE_PRISM, AbstractShape, box_corners

SPLINES = {"linear_spline": 1, "quadratic_spline": 2, "cubic_spline": 3, "bezier_spline": 3}
SWEEPS = ("linear_sweep", "conic_sweep")
MIN_SEGMENTS = 4


# ------------------------------------------------------------------ Bernstein polynomials on [0, 1]
def _power(w):
    """Power-basis coefficients (lowest first) of the Bernstein polynomial ``w`` (…, n + 1)."""
    n = w.shape[-1] - 1
    if n == 1:
        return w[..., 0], w[..., 1] - w[..., 0]
    if n == 2:
        return w[..., 0], 2.0 * (w[..., 1] - w[..., 0]), w[..., 0] - 2.0 * w[..., 1] + w[..., 2]
    return (w[..., 0], 3.0 * (w[..., 1] - w[..., 0]), 3.0 * (w[..., 0] - 2.0 * w[..., 1] + w[..., 2]),
            w[..., 3] - w[..., 0] + 3.0 * (w[..., 1] - w[..., 2]))


def _eval(w, s):
    """The Bernstein polynomial ``w`` (…, n + 1) at ``s`` (…) by de Casteljau's steps."""
    b = [w[..., k] for k in range(w.shape[-1])]
    while len(b) > 1:
        b = [b[k] + s * (b[k + 1] - b[k]) for k in range(len(b) - 1)]
    return b[0]


def _derivative(w):
    """The derivative's Bernstein coefficients (…, n)."""
    n = w.shape[-1] - 1
    return n * (w[..., 1:] - w[..., :-1])


def _splits(w):
    """(…, n + 1): 0, the critical points of ``w`` in (0, 1) in order (1 where there are fewer), 1:
    the ends of the pieces on which ``w`` is monotone."""
    n = w.shape[-1] - 1
    zero, one = jnp.zeros_like(w[..., 0]), jnp.ones_like(w[..., 0])
    if n == 1:
        return jnp.stack([zero, one], -1)
    dw = _derivative(w)
    if n == 2:
        s = safe_div(dw[..., 0], dw[..., 0] - dw[..., 1], 1.0)
        s = jnp.where((s > 0) & (s < 1), s, 1.0)
        return jnp.stack([zero, s, one], -1)
    c0, c1, c2 = _power(dw)
    r0, r1, _ = solve_quadratic(c2, c1, c0)
    r0 = jnp.where((r0 > 0) & (r0 < 1), r0, 1.0)
    r1 = jnp.where((r1 > 0) & (r1 < 1), r1, 1.0)
    return jnp.stack([zero, jnp.minimum(r0, r1), jnp.maximum(r0, r1), one], -1)


def _straddles(w, splits):
    """(…, n): whether each monotone piece of ``w`` crosses zero, half-open as the polygon's edges
    (a zero at an end counts for one of the two pieces that share it). The curve's own ends take
    the end coefficients, exactly."""
    inner = _eval(w[..., None, :], splits[..., 1:-1])
    ends = jnp.concatenate([w[..., :1], inner, w[..., -1:]], -1)
    positive = ends > 0
    return positive[..., :-1] != positive[..., 1:]


def _piece_roots(w, splits):
    """(…, n): the root in each monotone piece ``[splits_k, splits_k+1]`` of ``w`` (meaningful where
    the piece straddles zero), without gradient."""
    w, splits = jax.lax.stop_gradient(w), jax.lax.stop_gradient(splits)
    n = w.shape[-1] - 1
    if n == 1:
        return safe_div(w[..., :1], w[..., :1] - w[..., 1:], 0.0)
    if n == 2:
        return jnp.clip(_quadratic_root(w, splits), splits[..., :-1], splits[..., 1:])
    iterations = jnp.finfo(w.dtype).nmant + 4
    root, _ = _bisect(lambda s: _eval(w[..., None, :], s), splits[..., :-1], splits[..., 1:], iterations)
    return root


# ------------------------------------------------------------------ the kernel
def _frame(o, d, axis: int):
    """The line in the prism's own axes (outline in x-z, sweep along y): text sweeps along z."""
    if axis == 1:
        return o, d
    perm = jnp.array([0, 2, 1])
    return o[perm], d[perm]


def _unframe(n, axis: int):
    return n if axis == 1 else n[..., jnp.array([0, 2, 1])]


def prism_hits(controls, sense, height1, height2, o, d, *, conic: bool, open_: bool, axis: int = 1):
    """Every crossing of the line ``o + t d`` with the swept outline: each segment's wall crossings
    (``n`` slots a segment, degree ``n``), then the two caps' (``+inf`` where ``open_``).

    Args:
        controls: (S, n + 1, 2) Bernstein control points (x, z) of the outline's segments.
        sense: (S,) int: +1 where the fill lies left of a segment's direction (rotating its tangent
            (x', z') to (−z', x')), −1 right, 0 for a padding segment.
        height1, height2: the sweep's two heights (either order).
        o, d: (3,) the line (any length of ``d``).
        conic: the outline scaled by the height (POV-Ray's ``conic_sweep``), else straight.
        axis: 1 (POV-Ray's prism, swept along y) or 2 (text, swept along z: x-y outline).

    Returns:
        ``(t, n)``: t (S·n + 2,), n (S·n + 2, 3) outward unit normals.
    """
    controls, height1, height2, o, d = as_float_arrays(controls, height1, height2, o, d)
    o, d = _frame(o, d, axis)
    lo, hi = jnp.minimum(height1, height2), jnp.maximum(height1, height2)

    wall_t, wall_n = _walls(controls, sense, lo, hi, o, d, conic)

    # the caps
    h = jnp.stack([lo, hi])
    t_cap, ok = solve_linear(d[1], o[1] - h)
    p = o[None, :] + jnp.where(ok, t_cap, 0.0)[:, None] * d[None, :]
    scale = h if conic else jnp.ones_like(h)
    px, pz = safe_div(p[:, 0], scale, 0.0), safe_div(p[:, 2], scale, 0.0)
    filled = jax.vmap(lambda x, z: outline_inside(controls, sense, x, z))(px, pz)
    cap_ok = ok & filled & (not open_) & ((scale != 0) if conic else True)
    up = jnp.stack([jnp.zeros_like(lo), jnp.ones_like(lo), jnp.zeros_like(lo)])
    cap_n = jnp.stack([-up, up])
    cap_t, cap_n = masked_hits(t_cap, cap_n, cap_ok)
    t_all = jnp.concatenate([wall_t, cap_t])
    n_all = jnp.concatenate([wall_n, cap_n])
    return t_all, _unframe(n_all, axis)


NEAR_CANDIDATES = 8  # segments ``prism_near_hit`` solves: those whose boxes lie nearest the point


def prism_near_hit(controls, sense, height1, height2, o, d, t0, *, conic: bool, open_: bool, axis: int = 1):
    """The crossing at ``t0`` (the native hierarchy's, found in double precision, held) computed
    again with its derivatives, without solving every segment: a cap where the point lies nearer
    its plane than any wall's crossing, else the crossing nearest ``t0`` of the
    ``NEAR_CANDIDATES`` segments whose control boxes (which hold the curve) lie nearest the
    point. Returns ``(t (1,), n (1, 3))``."""
    controls, height1, height2, o, d = as_float_arrays(controls, height1, height2, o, d)
    o, d = _frame(o, d, axis)
    lo, hi = jnp.minimum(height1, height2), jnp.maximum(height1, height2)
    sg = jax.lax.stop_gradient
    t0 = sg(jnp.asarray(t0, o.dtype))
    p = sg(o + t0 * d)
    scale = p[1] if conic else 1.0
    x, z = safe_div(p[0], scale, 0.0), safe_div(p[2], scale, 0.0)
    c = sg(controls)
    gap_x = jnp.maximum(jnp.maximum(c[..., 0].min(-1) - x, x - c[..., 0].max(-1)), 0.0)
    gap_z = jnp.maximum(jnp.maximum(c[..., 1].min(-1) - z, z - c[..., 1].max(-1)), 0.0)
    gap = jnp.where(sense != 0, gap_x + gap_z, jnp.inf)
    count = min(NEAR_CANDIDATES, controls.shape[0])
    _, pick = jax.lax.top_k(-gap, count)
    t_wall, n_wall = _walls(controls[pick], sense[pick], lo, hi, o, d, conic)
    k = jnp.argmin(jnp.where(jnp.isfinite(t_wall), jnp.abs(sg(t_wall) - t0), jnp.inf))
    h = jnp.stack([lo, hi])
    t_cap, ok = solve_linear(d[1], o[1] - h)
    ok = ok & (not open_)
    j = jnp.argmin(jnp.where(ok, jnp.abs(sg(t_cap) - t0), jnp.inf))
    cap_better = ok[j] & (jnp.abs(sg(t_cap[j]) - t0) < jnp.where(jnp.isfinite(t_wall[k]),
                                                                   jnp.abs(sg(t_wall[k]) - t0), jnp.inf))
    up = jnp.zeros(3, o.dtype).at[1].set(jnp.where(j == 1, 1.0, -1.0))
    t = jnp.where(cap_better, jnp.where(ok[j], t_cap[j], 0.0), t_wall[k])
    n = jnp.where(cap_better, up, n_wall[k])
    return t[None], _unframe(n, axis)[None]


def _walls(controls, sense, lo, hi, o, d, conic: bool):
    """The wall crossings of segments ``controls`` (S, n + 1, 2) in the prism's frame: t (S·n,) and
    outward unit normals (S·n, 3), +inf where a piece holds none."""
    bx, bz = controls[..., 0], controls[..., 1]
    # the wall polynomial's Bernstein coefficients (S, n + 1)
    if conic:
        m = jnp.cross(o, d)  # normal of the plane through the origin and the line
        w = m[0] * bx + m[2] * bz + m[1]
    else:
        w = d[0] * (bz - o[2]) - d[2] * (bx - o[0])
    splits = _splits(jax.lax.stop_gradient(w))
    crosses = _straddles(jax.lax.stop_gradient(w), splits) & (sense != 0)[:, None]
    degree = controls.shape[1] - 1
    if degree == 3:
        def root(w_k, s_k):
            return differentiable_root(lambda s: _eval(w_k, s), s_k)
        s = jax.vmap(jax.vmap(root, (None, 0)))(w, _piece_roots(w, splits))
    elif degree == 2:
        s = _quadratic_root(w, splits)
    else:
        s = safe_div(w[:, :1], w[:, :1] - w[:, 1:], 0.0)
    cx = _eval(bx[:, None, :], s)
    cz = _eval(bz[:, None, :], s)
    tx = _eval(_derivative(bx)[:, None, :], s)
    tz = _eval(_derivative(bz)[:, None, :], s)
    if conic:
        v = jnp.stack([cx, jnp.ones_like(cx), cz], -1)
        dv, ov = jnp.cross(d, v), jnp.cross(o, v)
        t = -safe_div(jnp.sum(ov * dv, -1), jnp.sum(dv * dv, -1), jnp.inf)
        y = o[1] + t * d[1]
        normal = jnp.stack([tz, cz * tx - cx * tz, -tx], -1) * jnp.sign(y)[..., None]
    else:
        dd = d[0] * d[0] + d[2] * d[2]
        t = safe_div((cx - o[0]) * d[0] + (cz - o[2]) * d[2], dd, jnp.inf)
        y = o[1] + t * d[1]
        normal = jnp.stack([tz, jnp.zeros_like(tz), -tx], -1)
    normal = normal * sense.astype(normal.dtype)[:, None, None]
    wall_ok = crosses & jnp.isfinite(t) & (y >= lo) & (y <= hi)
    return masked_hits(t.reshape(-1), safe_normalize(normal).reshape(-1, 3), wall_ok.reshape(-1))


def _quadratic_root(w, splits):
    """The root in each monotone piece of each quadratic ``w`` (…, 3), from the stable closed form
    (differentiable as it stands; the piece's root chosen without gradient): of the two roots, the
    one nearer the piece's middle (a quadratic's two roots sit in its two monotone pieces)."""
    c0, c1, c2 = _power(w)
    r0, r1, _ = solve_quadratic(c2, c1, c0)
    mid = jax.lax.stop_gradient(0.5 * (splits[..., 1:] + splits[..., :-1]))
    near0 = jax.lax.stop_gradient(jnp.abs(r0[..., None] - mid) <= jnp.abs(r1[..., None] - mid))
    r = jnp.where(near0, r0[..., None], r1[..., None])
    return jnp.where(jnp.isfinite(r), r, mid)


def outline_inside(controls, sense, px, pz):
    """Whether the point (px, pz) is filled: the half-line from it towards +x crosses the outline an
    odd number of times (even-odd rule; without gradient)."""
    controls = jax.lax.stop_gradient(controls)
    g = controls[..., 1] - pz  # (S, n + 1)
    splits = _splits(g)
    crosses = _straddles(g, splits) & (sense != 0)[:, None]
    s = _piece_roots(g, splits)
    x = _eval(controls[:, None, :, 0], s)
    return jnp.sum(crosses & (x > px)) % 2 == 1


def prism_inside(controls, sense, height1, height2, p, *, conic: bool, axis: int = 1):
    """Strictly inside the swept outline (between the heights and filled there)."""
    p = _frame(jnp.asarray(p), jnp.zeros(3, jnp.asarray(p).dtype), axis)[0]
    lo, hi = jnp.minimum(height1, height2), jnp.maximum(height1, height2)
    between = (p[1] > lo) & (p[1] < hi)
    scale = p[1] if conic else 1.0
    x, z = safe_div(p[0], scale, 0.0), safe_div(p[2], scale, 0.0)
    return between & outline_inside(controls, sense, x, z) & ((p[1] != 0) if conic else True)


# ------------------------------------------------------------------ building the outline
def _closed_runs(points: np.ndarray, lead: int, tail: int, auto_close: bool) -> list[np.ndarray]:
    """Sub-outlines of POV-Ray's point list: after ``lead`` control points, a run ends where its
    first point repeats, then ``tail`` more control points follow."""
    runs, i, n = [], 0, len(points)
    while i < n:
        start = i + lead
        if start >= n:
            break
        j = start + 1
        while j < n and not np.array_equal(points[j], points[start]):
            j += 1
        if j >= n:  # not closed
            if auto_close:
                runs.append(np.concatenate([points[i:], points[start:start + 1]]))
            elif n - i >= lead + 2 + tail:
                runs.append(points[i:])
            break
        end = min(j + 1 + tail, n)
        runs.append(points[i:end])
        i = end
    return runs


def spline_segments(spline: str, points) -> np.ndarray:
    """(S, n + 1, 2) Bernstein control points of POV-Ray's spline through ``points`` (N, 2).

    * ``linear_spline``: a sub-outline closes where its first point repeats; the last one is
      closed if it is not.
    * ``quadratic_spline``: each sub-outline starts with a control point ``c``; the segment from
      ``P_i`` to ``P_i+1`` is the second half of the parabola through ``P_i−1``, ``P_i``, ``P_i+1``
      at ``s`` = −1, 0, 1: ``P_i + (P_i+1 − P_i−1) s/2 + (P_i+1 − 2 P_i + P_i−1) s²/2`` (measured:
      POV-Ray's outline of a quadratic prism, docs/semantics.md §4.1).
    * ``cubic_spline``: a control point before and after each sub-outline; the segment from
      ``P_i`` to ``P_i+1`` is Catmull–Rom's, with tangents ``(P_i+1 − P_i−1)/2`` and
      ``(P_i+2 − P_i)/2``.
    * ``bezier_spline``: four points a segment.
    """
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    segs = []
    if spline == "bezier_spline":
        for k in range(len(pts) // 4):
            segs.append(pts[4 * k:4 * k + 4])
    elif spline == "linear_spline":
        for run in _closed_runs(pts, 0, 0, auto_close=True):
            segs += [np.stack([run[k], run[k + 1]]) for k in range(len(run) - 1)]
    elif spline == "quadratic_spline":
        for run in _closed_runs(pts, 1, 0, auto_close=False):
            for k in range(1, len(run) - 1):
                prev, a, b = run[k - 1], run[k], run[k + 1]
                segs.append(np.stack([a, a + 0.25 * (b - prev), b]))
    elif spline == "cubic_spline":
        for run in _closed_runs(pts, 1, 1, auto_close=False):
            for k in range(1, len(run) - 2):
                p0, p1, p2, p3 = run[k - 1], run[k], run[k + 1], run[k + 2]
                segs.append(np.stack([p1, p1 + (p2 - p0) / 6.0, p2 - (p3 - p1) / 6.0, p2]))
    else:
        raise ValueError(f"unknown spline {spline!r}")
    degree = SPLINES[spline]
    if not segs:
        return np.zeros((0, degree + 1, 2))
    return np.stack(segs)


def segment_senses(controls: np.ndarray) -> np.ndarray:
    """(S,) int8: +1 where the fill lies left of each segment's direction at its middle, −1 right, 0
    for a degenerate (point) segment. Host-side, once per outline (float64): a probe a millionth
    of the outline's extent to the left of each middle, filled or not by the even-odd rule on the
    outline drawn as a fine polyline."""
    controls = np.asarray(controls, np.float64)
    out = np.zeros(len(controls), np.int8)
    if not len(controls):
        return out
    extent = float(np.ptp(controls.reshape(-1, 2), axis=0).max()) or 1.0
    n = controls.shape[1] - 1
    mid = _np_bernstein(controls, np.array([0.5]))[:, 0]
    tangent = n * _np_bernstein(np.diff(controls, axis=1), np.array([0.5]))[:, 0]
    length = np.hypot(tangent[:, 0], tangent[:, 1])
    live = length > 1e-12 * extent
    left = np.stack([-tangent[:, 1], tangent[:, 0]], -1) / np.where(live, length, 1.0)[:, None]
    probes = mid + 1e-6 * extent * left
    pts = _np_bernstein(controls, np.linspace(0.0, 1.0, 65))  # (S, 65, 2)
    a, b = pts[:, :-1].reshape(-1, 2), pts[:, 1:].reshape(-1, 2)
    for start in range(0, len(probes), 256):
        q = probes[start:start + 256, None, :]
        straddle = (a[None, :, 1] > q[..., 1]) != (b[None, :, 1] > q[..., 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
            x = a[None, :, 0] + (q[..., 1] - a[None, :, 1]) * slope
        filled = np.sum(straddle & (x > q[..., 0]), axis=1) % 2 == 1
        out[start:start + 256] = np.where(filled, 1, -1)
    return np.where(live, out, 0).astype(np.int8)


def outline_is_convex(segments: np.ndarray) -> bool:
    """Whether the segments (S, n + 1, 2) make one closed loop that turns one way by one full
    turn (host side, on the curve drawn as a fine polyline): a line then crosses it at most twice."""
    segments = np.asarray(segments, np.float64)
    if len(segments) < 2:
        return False
    extent = float(np.ptp(segments.reshape(-1, 2), axis=0).max()) or 1.0
    ends, starts = segments[:, -1], np.roll(segments[:, 0], -1, axis=0)
    if np.abs(ends - starts).max() > 1e-9 * extent:  # not one loop in order
        return False
    pts = _np_bernstein(segments, np.linspace(0.0, 1.0, 17))[:, :-1].reshape(-1, 2)
    edges = np.roll(pts, -1, axis=0) - pts
    edges = edges[np.hypot(edges[:, 0], edges[:, 1]) > 1e-12 * extent]
    if len(edges) < 3:
        return False
    nxt = np.roll(edges, -1, axis=0)
    cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
    dot = np.sum(edges * nxt, axis=1)
    turning = np.arctan2(cross, dot)
    tol = 1e-9
    one_way = bool(np.all(turning >= -tol)) or bool(np.all(turning <= tol))
    return one_way and abs(abs(turning.sum()) - 2 * np.pi) < 1e-6


def _np_bernstein(controls: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(S, len(s), 2): the segments at the parameters ``s`` (host side)."""
    from math import comb

    n = controls.shape[1] - 1
    basis = np.stack([comb(n, k) * s ** k * (1.0 - s) ** (n - k) for k in range(n + 1)], -1)  # (m, n + 1)
    return np.einsum("mk,skc->smc", basis, controls)


def padded_segments(controls: np.ndarray, sense: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The outline padded with point segments at the origin (sense 0) to a power of two, at least
    ``MIN_SEGMENTS``."""
    s = len(controls)
    size = max(MIN_SEGMENTS, 1 << max(0, (s - 1).bit_length()))
    pad = size - s
    controls = np.concatenate([controls, np.zeros((pad, *controls.shape[1:]))]) if pad else controls
    sense = np.concatenate([sense, np.zeros(pad, np.int8)]) if pad else sense
    return controls, sense


# ------------------------------------------------------------------ the record
class Prism(AbstractShape):
    """``prism { [spline] [sweep] h1, h2, n, <points> [open] }``: an outline in the x-z plane swept
    along y from ``height1`` to ``height2``, straight (``linear_sweep``) or scaled with the height
    from the origin (``conic_sweep``). Filled by the even-odd rule; a solid unless ``open``.

    Attributes:
        controls: (S, n + 1, 2) Bernstein control points (x, z) of the segments (S a power of two,
                  padding segments have ``sense`` 0).
        sense:    (S,) int8, which side of each segment is filled (``segment_senses``).
        height1, height2: the sweep's heights.
        conic:    ``conic_sweep``.
        open:     no caps (and no inside).
    """

    kind: ClassVar[str] = "prism"
    crossings: ClassVar[int] = 2
    sdl_keywords: ClassVar[tuple[str, ...]] = ("prism",)
    sdl_flags: ClassVar[tuple[str, ...]] = ("open",)
    axis: ClassVar[int] = 1
    controls: Float[Array, "S m 2"] = eqx.field(converter=as_float)
    sense: Int[Array, " S"] = eqx.field(converter=lambda x: jnp.asarray(x, jnp.int8))
    height1: Float[Array, ""] = eqx.field(converter=as_float)
    height2: Float[Array, ""] = eqx.field(converter=as_float)
    conic: bool = eqx.field(static=True, default=False)
    open: bool = eqx.field(static=True, default=False)
    convex: bool = eqx.field(static=True, default=False)  # one convex loop (``outline_is_convex``)

    # the native hierarchy chooses among prisms (bvh.cc's prism: the whole outline is one item
    # over several rows); the JAX kernel then computes the chosen one's crossings again
    native_kernel: ClassVar[int | None] = NATIVE_PRISM
    costly_kernel: ClassVar[bool] = True

    def n_crossings(self) -> int:
        return self.controls.shape[-3] * (self.controls.shape[-2] - 1) + 2

    def near_hit(self, o, d, t0):
        return prism_near_hit(self.controls, self.sense, self.height1, self.height2, o, d, t0,
                              conic=self.conic, open_=self.open, axis=self.axis)

    def n_native_rows(self) -> int:
        s, m = self.controls.shape[-3], self.controls.shape[-2]
        return -(-(24 + s * (2 * m + 1)) // 24)

    def native_items(self):
        """One item: the header ``[S, n, conic, open, h1, h2, axis]``, then the control points
        and the senses (bvh.cc's prism), zero padded to its rows; the corners of its box."""
        from ._base import array_module

        xp = array_module(self.controls, self.height1, self.height2)
        s, m = self.controls.shape[-3], self.controls.shape[-2]
        dtype = self.controls.dtype
        head = xp.stack([xp.asarray(v, dtype) for v in (s, m - 1, float(self.conic), float(self.open),
                                                          self.height1, self.height2, self.axis)])
        body = xp.concatenate([head, xp.zeros(5, dtype), xp.reshape(self.controls, (-1,)),
                               xp.asarray(self.sense).astype(dtype)])
        size = 24 * self.n_native_rows() - 12
        lo, hi = self.bounds()
        return xp.pad(body, (0, size - body.shape[0]))[None], box_corners(lo, hi)[None]

    @property
    def line_crossings(self) -> int:
        """2 for one convex outline (a convex solid, or an open convex tube); else every wall
        piece of every live segment and the two caps."""
        if self.convex:
            return 2
        live = int(np.count_nonzero(np.asarray(self.sense)))
        return live * (self.controls.shape[-2] - 1) + 2

    def hits(self, o, d):
        return prism_hits(self.controls, self.sense, self.height1, self.height2, o, d,
                          conic=self.conic, open_=self.open, axis=self.axis)

    def inside(self, p):
        if self.open:
            return jnp.zeros((), bool)
        return prism_inside(self.controls, self.sense, self.height1, self.height2, p, conic=self.conic,
                            axis=self.axis)

    def bounds(self):
        from ._base import array_module

        xp = array_module(self.controls, self.height1, self.height2)
        live = xp.asarray(self.sense) != 0
        pts = xp.asarray(self.controls).reshape(-1, 2)
        mask = xp.repeat(live, self.controls.shape[-2])[:, None]
        big = xp.asarray(np.finfo(np.float32).max, pts.dtype)
        lo2 = xp.where(mask, pts, big).min(axis=0)
        hi2 = xp.where(mask, pts, -big).max(axis=0)
        h_lo = xp.minimum(self.height1, self.height2)
        h_hi = xp.maximum(self.height1, self.height2)
        if self.conic:  # the outline scaled by every height between h_lo and h_hi (and 0)
            k = xp.maximum(xp.abs(h_lo), xp.abs(h_hi))
            r = xp.maximum(xp.abs(lo2), xp.abs(hi2)) * k
            lo2, hi2 = -r, r
        lo = xp.stack([lo2[0], h_lo, lo2[1]])
        hi = xp.stack([hi2[0], h_hi, hi2[1]])
        if self.axis == 2:
            lo, hi = lo[xp.asarray([0, 2, 1])], hi[xp.asarray([0, 2, 1])]
        return lo, hi

    @classmethod
    def parse_sdl(cls, keyword, args):
        spline, sweep = "linear_spline", "linear_sweep"
        while True:
            kw = args.keyword(*SPLINES, *SWEEPS)
            if kw is None:
                break
            if kw in SPLINES:
                spline = kw
            else:
                sweep = kw
        loc = args.loc
        h1 = args.float()
        args.comma()
        h2 = args.float()
        args.comma()
        pts = read_points(args, "prism points")
        n = len(pts)
        need = {"linear_spline": 3, "quadratic_spline": 4, "cubic_spline": 5, "bezier_spline": 4}[spline]
        if n < need:
            raise args.error(f"expected at least {need} points for a {spline} prism, found {n}", loc)
        segs = spline_segments(spline, pts)
        if not len(segs):
            raise args.error(f"the {spline} prism's points close no outline", loc)
        return {"spline": spline, "conic": sweep == "conic_sweep", "height1": h1, "height2": h2,
                "segments": segs}

    @classmethod
    def from_sdl(cls, fields):
        return prism_from_segments(fields["segments"], fields["height1"], fields["height2"],
                                   conic=fields["conic"], open_=bool(fields.get("open", False)), cls=cls)


def read_points(args, what: str) -> list:
    """A count, then that many 2-D points, each after an optional comma (a prism's, a lathe's)."""
    n = args.count(what)
    pts = []
    for _ in range(n):
        args.comma()
        pts.append(args.vector(2))
    return pts


def prism_from_segments(segments, height1, height2, *, conic=False, open_=False, cls=Prism):
    """A prism (or ``cls``) from Bernstein segments (S, n + 1, 2): their fill sides found, padded.
    Records are immutable, so one outline asked for again (a text lowered for ``min_extent``, then
    for the scene) is the record made the first time."""
    segments = np.ascontiguousarray(segments, np.float64)
    key = (cls, segments.shape, segments.tobytes(), float(height1), float(height2), bool(conic), bool(open_))
    shape = _MADE.get(key)
    if shape is None:
        controls, sense = padded_segments(segments, segment_senses(segments))
        convex = outline_is_convex(segments) and (not conic or float(height1) * float(height2) >= 0)
        shape = cls(controls=controls, sense=sense, height1=height1, height2=height2, conic=conic, open=open_,
                    convex=convex)
        if len(_MADE) >= 4096:
            _MADE.pop(next(iter(_MADE)))
        _MADE[key] = shape
    return shape


_MADE: dict = {}
