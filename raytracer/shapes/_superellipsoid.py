"""Superquadric ellipsoid (POV-Ray's ``superellipsoid { <e, n> }``) in the unit box.

POV-Ray's surface is ``(|x|^(2/e) + |y|^(2/e))^(e/n) + |z|^(2/n) = 1``: ``e`` (east-west) shapes the
x–y cross-sections, ``n`` (north-south) the profile along z; ``e = n = 1`` is the unit sphere and
``e, n -> 0`` the box ``[-1, 1]^3``. Inside is where the left side is < 1.

Evaluated as a nested p-norm, ``N(p) = ‖(‖(x, y)‖_{2/e}, z)‖_{2/n}``: ``N^(2/n)`` is the left side
above, so the surface is ``N = 1`` and the inside ``N < 1``. ``N`` is homogeneous of degree 1 (distance
like: its gradient is O(1) on the surface whatever e and n), and each p-norm is evaluated scaled by its
larger argument, so no power overflows or underflows to a wrong value for any e, n > 0.

Crossings of a line, K = 8. The line is cut by the unit box (the surface lies inside it: ``N >= max(|x|,
|y|, |z|)``) and by the three coordinate planes into at most 4 pieces, each within one octant, where
|x|, |y|, |z| are affine in the line parameter. In an octant ``N`` is

* convex when e <= 2 and n <= 2 (p-norms with p >= 1 are convex and nondecreasing in each argument):
  the solid is convex and a line crosses it at most twice in all;
* concave when e >= 2 and n >= 2 (the power mean with p <= 1 is concave and nondecreasing, and so is
  its composition with one): at most 2 crossings per piece, 8 in all.

So each piece is split at its one critical point (found by bisection on the sign of the directional
derivative), which makes ``N - 1`` monotone on both halves: every crossing is bracketed, grazing
ones included. Mixed exponents (one of e, n below 2, the other above) are neither; dense sampling of
random lines over e, n in [0.1, 10] found at most 3 crossings in a piece and 6 in all, so each half
is further cut into ``_SUBDIVISIONS`` equal parts, and a pair of crossings closer than a part can be
missed there (POV-Ray's own solver samples too). The first K sign changes are refined by bisection
without gradient, and :func:`differentiable_root` attaches implicit-function-theorem derivatives.

Exponents below ``EXPONENT_FLOOR`` are taken as the floor (the shape is then the box to ~1e-4; POV-Ray
accepts e, n <= 0 but its manual says they must be > 0).
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits
from ..kernels._numerics import (
    _bisect,
    as_float_arrays,
    centred_line,
    differentiable_root,
    safe_normalize,
    safe_pow,
    solve_linear,
)
from ._base import NATIVE_SUPERELLIPSOID, AbstractShape, array_module, box_corners, native_params

SUPERELLIPSOID_K = 8
_SUBDIVISIONS = 4  # equal parts of each monotone-or-not half piece (mixed exponents only need them)
_INSET = 1e-3  # the critical-point search stays this fraction inside a piece (|.|^p kinks at its ends)
EXPONENT_FLOOR = 1e-4
_MARGIN = 1e-3  # the box span is widened by this (in units of the box half-size)


def _pnorm(a, b, p):
    """``(a^p + b^p)^(1/p)`` for ``a, b >= 0``, evaluated as ``m ((a/m)^p + (b/m)^p)^(1/p)``.

    ``m`` is the larger argument held constant (stop-gradient): the identity holds for any constant
    ``m > 0``, so values and derivatives of every order are exact, and the sum lies in [1, 2].
    """
    big = lax.stop_gradient(jnp.maximum(a, b))
    ok = big > 0
    scale = jnp.where(ok, big, 1.0)
    total = safe_pow(a / scale, p) + safe_pow(b / scale, p)
    return jnp.where(ok, scale * safe_pow(total, 1.0 / p), 0.0)


def _exponents(e, n):
    return 2.0 / jnp.maximum(e, EXPONENT_FLOOR), 2.0 / jnp.maximum(n, EXPONENT_FLOOR)


def superellipsoid_norm(
    e: Float[ArrayLike, ""], n: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Float[Array, ""]:
    """``N(p)``: 1 on the surface, < 1 inside, homogeneous of degree 1 (``N(λp) = |λ| N(p)``)."""
    e, n, p = as_float_arrays(e, n, p)
    a_e, a_n = _exponents(e, n)
    q = jnp.abs(p)
    return _pnorm(_pnorm(q[0], q[1], a_e), q[2], a_n)


def _box_span(o, d):
    """Entry and exit parameters of ``o + s d`` through ``[-1, 1]^3``, and whether it passes."""
    s_lo, ok = solve_linear(d, o + 1.0)
    s_hi, _ = solve_linear(d, o - 1.0)
    in_slab = jnp.abs(o) <= 1.0
    near = jnp.where(ok, jnp.minimum(s_lo, s_hi), jnp.where(in_slab, -jnp.inf, jnp.inf))
    far = jnp.where(ok, jnp.maximum(s_lo, s_hi), jnp.where(in_slab, jnp.inf, -jnp.inf))
    s_in, s_out = jnp.max(near), jnp.min(far)
    hit = jnp.isfinite(s_in) & jnp.isfinite(s_out) & (s_in <= s_out)
    # Widened by _MARGIN: for small e or n the surface lies within rounding of the box faces, and the
    # span must start and end strictly outside the solid (beyond the box, N > 1).
    return jnp.where(hit, s_in - _MARGIN, 0.0), jnp.where(hit, s_out + _MARGIN, 0.0), hit


def _pieces(e, n, o, d):
    """The line's span through the box cut at the coordinate planes into (at most) 4 pieces within
    one octant each, and each piece's critical point of ``N`` (its one extremum where N is convex or
    concave there; the middle where the slope keeps its sign). No gradients.

    Returns ``(lo, hi, crit, through)``: (4,) piece ends and critical points, and whether the line
    passes through the box.
    """
    s_in, s_out, through = _box_span(o, d)

    def slope(s):
        return jax.vmap(lambda si: jax.jvp(lambda q: superellipsoid_norm(e, n, q), (o + si * d,), (d,))[1])(s)

    planes, _ = solve_linear(d, o)
    cuts = jnp.sort(jnp.clip(jnp.where(jnp.isfinite(planes), planes, s_out), s_in, s_out))
    knots = jnp.concatenate([s_in[None], cuts, s_out[None]])
    lo, hi = knots[:-1], knots[1:]
    inset = _INSET * (hi - lo)
    iterations = jnp.finfo(o.dtype).nmant + 4
    crit, has_crit = _bisect(slope, lo + inset, hi - inset, iterations)
    return lo, hi, jnp.where(has_crit, crit, 0.5 * (lo + hi)), through


def superellipsoid_margin(
    e: Float[ArrayLike, ""], n: Float[ArrayLike, ""], o: Float[ArrayLike, "3"], d: Float[ArrayLike, "3"]
) -> Float[Array, ""]:
    """``1 − min N`` along the line ``o + t d``: positive where it crosses the solid, zero where it
    touches it.

    ``N`` restricted to the line is smooth within an octant and kinks where the line crosses a
    coordinate plane, so its minimum is at a piece's critical point (where ``N`` is convex there:
    e, n ≤ 2) or at a plane crossing (where it is concave: e, n ≥ 2, the star's ridges). Both are
    candidates: a critical point, found without gradient, carries the derivatives of the value
    there (its slope along the line vanishes: the envelope theorem), a plane crossing those of its
    own place on the line. Mixed exponents can hold a second critical point in a piece that is
    not searched (as for their crossings)."""
    e, n, o, d = as_float_arrays(e, n, o, d)
    _, _, d_hat, _, o_c = centred_line(o, d)
    sg = lax.stop_gradient
    lo, hi, crit, through = _pieces(sg(e), sg(n), sg(o_c), sg(d_hat))

    def norm_at(s, axis=None):
        p = o_c + s * d_hat
        if axis is not None:  # on a coordinate plane exactly (|x|^p kinks there)
            p = jnp.where(jnp.arange(3) == axis, 0.0, p)
        return superellipsoid_norm(e, n, p)

    values = [norm_at(jnp.zeros((), o.dtype))]  # the line's point nearest the centre: an upper bound
    values += [jnp.where(through & (lo[k] < c) & (c < hi[k]), norm_at(sg(c)), jnp.inf)
               for k, c in enumerate(crit)]
    span_lo, span_hi = lo[0], hi[-1]
    for axis in range(3):
        s_plane, ok = solve_linear(d_hat[axis], o_c[axis])
        inner = through & ok & (sg(s_plane) > span_lo) & (sg(s_plane) < span_hi)
        values.append(jnp.where(inner, norm_at(jnp.where(inner, s_plane, 0.0), axis), jnp.inf))
    return 1.0 - jnp.min(jnp.stack(values))


def _brackets(e, n, o, d):
    """The first K sub-intervals of ``[s_in, s_out]`` where ``N - 1`` changes sign (no gradients).

    Returns ``(lo, hi, valid, level)``: (K,) brackets in ascending order, which are real, and
    ``level(s)``, ``N(o + s d) - 1`` for a vector of ``s``.
    """
    lo, hi, crit, through = _pieces(e, n, o, d)

    def level(s):
        return jax.vmap(lambda si: superellipsoid_norm(e, n, o + si * d))(s) - 1.0

    starts = jnp.stack([lo, crit], axis=1).ravel()  # 8 halves, in order along the line
    ends = jnp.stack([crit, hi], axis=1).ravel()
    frac = jnp.arange(_SUBDIVISIONS + 1, dtype=o.dtype) / _SUBDIVISIONS
    grid = starts[:, None] + (ends - starts)[:, None] * frac[None, :]  # (8, S + 1)
    inside = (level(grid.ravel()) < 0).reshape(grid.shape)
    sub_lo, sub_hi = grid[:, :-1].ravel(), grid[:, 1:].ravel()
    change = (inside[:, :-1] != inside[:, 1:]).ravel() & through
    rank = jnp.cumsum(change)
    slot = jnp.arange(SUPERELLIPSOID_K)
    index = jnp.argmax(change[None, :] & (rank[None, :] == slot[:, None] + 1), axis=1)
    valid = rank[-1] > slot
    return sub_lo[index], sub_hi[index], valid, level


def superellipsoid_hits(
    e: Float[ArrayLike, ""],
    n: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "8"], Float[Array, "8 3"]]:
    """All crossings (up to 8) of the line ``o + t d`` with the superellipsoid ``<e, n>``.

    Args:
        e, n: () east-west and north-south exponents (> 0; differentiable).
        o: (3,) ray origin.
        d: (3,) ray direction, any length (zero length: a miss).

    Returns:
        ``(t, n)``: t (8,), the finite ones ascending, ``+inf`` where absent; n (8, 3) unit outward
        normals (the normalised gradient of the implicit function).
    """
    e, n, o, d = as_float_arrays(e, n, o, d)
    moving, inv_len, d_hat, t_c, o_c = centred_line(o, d)

    sg = lax.stop_gradient
    lo, hi, valid, level = _brackets(sg(e), sg(n), sg(o_c), sg(d_hat))
    s_star, _ = _bisect(level, lo, hi, jnp.finfo(o.dtype).nmant + 4)
    s_star = jnp.where(valid, s_star, 0.0)
    s = jax.vmap(
        lambda s0: differentiable_root(lambda si: superellipsoid_norm(e, n, o_c + si * d_hat), s0)
    )(s_star)
    p = o_c[None, :] + s[:, None] * d_hat[None, :]
    normal = safe_normalize(jax.vmap(jax.grad(lambda q: superellipsoid_norm(e, n, q)))(p))
    return masked_hits(t_c + s * inv_len, normal, valid & moving)


def superellipsoid_inside(
    e: Float[ArrayLike, ""], n: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside: ``(|x|^(2/e) + |y|^(2/e))^(e/n) + |z|^(2/n) < 1``."""
    return superellipsoid_norm(e, n, p) < 1.0


# ---------------------------------------------------------------- the record

class Superellipsoid(AbstractShape):
    """``superellipsoid { <e, n> }``: centred at the origin, filling the box ``[-1, 1]^3`` as e, n -> 0."""

    kind: ClassVar[str] = "superellipsoid"
    crossings: ClassVar[int] = SUPERELLIPSOID_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("superellipsoid",)
    e: Float[Array, ""] = eqx.field(converter=as_float)
    n: Float[Array, ""] = eqx.field(converter=as_float)

    @property
    def line_crossings(self) -> int:
        """2 when the solid is convex (e, n <= 2, known at plan time), else K."""
        if isinstance(self.e, jax.core.Tracer) or isinstance(self.n, jax.core.Tracer):
            return SUPERELLIPSOID_K
        return 2 if float(self.e) <= 2.0 and float(self.n) <= 2.0 else SUPERELLIPSOID_K

    def silhouette_margin(self, o, d):
        return superellipsoid_margin(self.e, self.n, o, d)

    def hits(self, o, d):
        return superellipsoid_hits(self.e, self.n, o, d)

    def inside(self, p):
        return superellipsoid_inside(self.e, self.n, p)

    def bounds(self):
        xp = array_module(self.e, self.n)
        one = xp.ones(3, dtype=xp.result_type(self.e))
        return -one, one

    # the hierarchy chooses among superellipsoids by its own solver (``_native/bvh.cc``): with
    # every ray testing every one, objects/superel1.pov (nine of them) took 8.6 s at 160×120
    native_kernel: ClassVar[int] = NATIVE_SUPERELLIPSOID

    def native_items(self):
        return native_params(self.e, self.n), box_corners(*self.bounds())[None]

    def near_hit(self, o, d, t0):
        # the crossing the hierarchy's solver found: two Newton steps of the norm attach its
        # implicit derivatives (``differentiable_root``: the value stays t0)
        e, n, o, d = as_float_arrays(self.e, self.n, o, d)
        t = differentiable_root(lambda ti: superellipsoid_norm(e, n, o + ti * d), t0)
        normal = safe_normalize(jax.grad(lambda q: superellipsoid_norm(e, n, q))(o + t * d))
        return t[None], normal[None]

    @classmethod
    def parse_sdl(cls, keyword, args):
        e, n = args.vector(2)
        return {"e": e, "n": n}
