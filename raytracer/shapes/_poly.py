"""Polynomial surfaces ``P(x, y, z) = 0`` of order 2 to 4, inside where ``P < 0``: POV-Ray's
``quartic``, ``cubic``, ``poly`` (orders 2–4) and ``polynomial`` (orders 2–4).

Every order is held as a quartic: the 35 coefficients of the monomials ``x^i y^j z^k`` (``i + j + k
<= 4``) in POV-Ray's order (``i``, then ``j``, then ``k`` descending: ``A1 = x⁴``, ``A2 = x³y``, …,
``A35 = 1``; the manual's table of terms), so one kernel serves them all.

Along a ray the polynomial is a quartic in ``s`` at ``o_c + s d̂`` (``o_c`` the point of the line closest
to the object's origin, ``d̂`` unit), whose real roots all lie within Fujiwara's bound of its
coefficients (from the highest nonzero one; at most ``S_MAX``). :func:`solve_quartic` brackets them
there, its sign taken from ``P`` evaluated at the points (better conditioned than the expanded
coefficients); Newton steps on the expanded polynomial, each no longer than the bisection's
resolution, refine a root when the bound is large (a near-zero leading coefficient: a ray almost
along an asymptotic direction). The roots found without gradient get their derivatives from the
implicit function theorem (:func:`differentiable_root`), normals are ``∇P / |∇P|`` (outward).

Unbounded in general, as POV-Ray's (``bounds`` is None): POV-Ray's scenes clip or intersect them
with bounded shapes. POV-Ray's ``sturm`` (its more careful root solver) is accepted and has no
effect: every root is bracketed here. Orders above 4 are parsed and left out with a warning.
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits
from ..kernels._numerics import (
    _horner,
    as_float_arrays,
    centred_line,
    differentiable_root,
    safe_div,
    safe_normalize,
    solve_quartic,
)
from ._base import NATIVE_POLY, AbstractShape, array_module

ORDER_MAX = 4
POLY_K = 4  # crossings of a line with a quartic
S_MAX = 1e7  # roots farther along the line than this are not looked for (``_accel.T_MAX``)
_POLISH_STEPS = 3


def povray_terms(order: int) -> tuple[tuple[int, int, int], ...]:
    """The exponents ``(i, j, k)`` of ``x^i y^j z^k`` of POV-Ray's coefficients ``A1, A2, …`` of a
    polynomial of ``order``: ``i``, then ``j``, then ``k`` descending."""
    return tuple((i, j, k) for i in range(order, -1, -1) for j in range(order - i, -1, -1)
                 for k in range(order - i - j, -1, -1))


TERMS = povray_terms(ORDER_MAX)  # 35
_INDEX = {term: n for n, term in enumerate(TERMS)}
_CUBE = np.asarray([25 * i + 5 * j + k for i, j, k in TERMS], np.int32)  # each term's place in a 5×5×5 cube


def quartic_coefficients(order: int, values) -> np.ndarray:
    """The 35 quartic coefficients of POV-Ray's coefficients ``values`` of a polynomial of
    ``order`` (<= 4), in POV-Ray's order for that order."""
    out = np.zeros(len(TERMS))
    for term, value in zip(povray_terms(order), values, strict=True):
        out[_INDEX[term]] = value
    return out


def _nested(coeffs, x, y, z, times, lift):
    """``Σ_i x^i Σ_j y^j Σ_k c_ijk z^k`` by Horner's rule in z, then y, then x (static indices: no
    gathers): ``times(p, v)`` multiplies by a variable, ``lift(c)`` makes a coefficient a value."""
    total = None
    for i in range(ORDER_MAX, -1, -1):
        in_yz = None
        for j in range(ORDER_MAX - i, -1, -1):
            in_z = None
            for k in range(ORDER_MAX - i - j, -1, -1):
                c = lift(coeffs[_INDEX[(i, j, k)]])
                in_z = c if in_z is None else times(in_z, z) + c
            in_yz = in_z if in_yz is None else times(in_yz, y) + in_z
        total = in_yz if total is None else times(total, x) + in_yz
    return total


def _powers(v):
    """(5,): ``v⁰ … v⁴``."""
    v2 = v * v
    return jnp.stack([jnp.ones_like(v), v, v2, v2 * v, v2 * v2])


def poly_value(coeffs: Float[ArrayLike, "35"], p: Float[ArrayLike, "3"]) -> Float[Array, ""]:
    """``P(p)``: negative inside, zero on the surface, positive outside. The coefficients as a
    5×5×5 cube contracted with the powers of x, y and z: a few dense products, whose derivatives
    of every order stay small programs (the implicit derivatives of a root, the normals, second
    derivatives: Horner's rule differentiated twice over compiled for 90 s)."""
    coeffs, p = as_float_arrays(coeffs, p)
    cube = jnp.zeros(125, coeffs.dtype).at[_CUBE].set(coeffs).reshape(5, 5, 5)
    return jnp.einsum("ijk,i,j,k->", cube, _powers(p[0]), _powers(p[1]), _powers(p[2]))


def _horner_value(coeffs, p):
    """``P(p)`` by Horner's rule with static indices: the root search's sign, in its loop body
    (~6× faster than :func:`poly_value` there; not differentiated)."""
    return _nested(coeffs, p[0], p[1], p[2], lambda a, v: a * v, lambda c: c)


def _line_coefficients(coeffs, o, d):
    """Coefficients (highest first) of the quartic in ``s`` of ``P(o + s d)``: the same Horner
    rule on polynomials in ``s`` (lowest first), each variable the line ``o_a + s d_a``."""
    def times(p, line):  # p · (a + b s), truncated at s⁴ (the product's degree is at most 4)
        a, b = line
        return a * p + b * jnp.concatenate([jnp.zeros(1, p.dtype), p[:-1]])

    def lift(c):
        return jnp.zeros(ORDER_MAX + 1, o.dtype).at[0].set(c)

    return _nested(coeffs, (o[0], d[0]), (o[1], d[1]), (o[2], d[2]), times, lift)[::-1]


def _root_bound(c):
    """Fujiwara's bound on the real roots of the polynomial ``c`` (highest first), from its highest
    nonzero coefficient, at most ``S_MAX`` (0 for a constant)."""
    bound = jnp.zeros((), c.dtype)
    for lead in range(4, 0, -1):  # the leading degree, highest first
        a = c[4 - lead]
        safe = jnp.where(a != 0, a, 1.0)
        terms = [jnp.abs(c[4 - lead + i] / safe) ** (1.0 / i) for i in range(1, lead)]
        terms.append(jnp.abs(c[4] / (2.0 * safe)) ** (1.0 / lead))
        here = 2.0 * jnp.max(jnp.stack(terms))
        higher = jnp.any(c[:4 - lead] != 0) if lead < 4 else jnp.zeros((), bool)
        bound = jnp.where((a != 0) & ~higher, here, bound)
    return jnp.minimum(bound, S_MAX)


def poly_hits(
    coeffs: Float[ArrayLike, "35"], o: Float[ArrayLike, "3"], d: Float[ArrayLike, "3"]
) -> tuple[Float[Array, "4"], Float[Array, "4 3"]]:
    """All (up to four) crossings of the line ``o + t d`` with ``P = 0``.

    Args:
        coeffs: (35,) the quartic's coefficients (``TERMS``' order).
        o: (3,) ray origin.
        d: (3,) ray direction, any length (zero length: a miss).

    Returns:
        ``(t, n)``: t (4,), the finite ones ascending, ``+inf`` where absent; n (4, 3) unit outward
        normals (``∇P / |∇P|``).
    """
    coeffs, o, d = as_float_arrays(coeffs, o, d)
    moving, inv_len, d_hat, t_c, o_c = centred_line(o, d)

    sg = lax.stop_gradient
    a, o0, d0 = sg(coeffs), sg(o_c), sg(d_hat)
    c = _line_coefficients(a, o0, d0)
    bound = _root_bound(c) * 1.001
    s_star, found = solve_quartic(c, -bound, bound,
                                  lambda s: jax.vmap(lambda si: _horner_value(a, o0 + si * d0))(s))
    # Newton on the expanded polynomial, no step longer than the bisection's resolution (a wide
    # bracket leaves its roots coarse; a step that does not lower |P| is not taken)
    resolution = 4.0 * bound * 2.0 ** -(jnp.finfo(c.dtype).nmant + 3)
    slope = c[:4] * jnp.arange(4, 0, -1).astype(c.dtype)
    s0 = jnp.where(found, s_star, 0.0)
    for _ in range(_POLISH_STEPS):
        value, der = _horner(c, s0), _horner(slope, s0)
        step = jnp.clip(safe_div(value, der), -resolution, resolution)
        better = jnp.abs(_horner(c, s0 - step)) < jnp.abs(value)
        s0 = jnp.where(better, s0 - step, s0)
    s = jax.vmap(lambda si: differentiable_root(lambda x: poly_value(coeffs, o_c + x * d_hat), si))(s0)
    p = o_c[None, :] + s[:, None] * d_hat[None, :]
    n = safe_normalize(jax.vmap(jax.grad(lambda q: poly_value(coeffs, q)))(p))
    return masked_hits(t_c + s * inv_len, n, found & moving)


def poly_inside(coeffs: Float[ArrayLike, "35"], p: Float[ArrayLike, "3"]) -> Bool[Array, ""]:
    """True where ``P(p) < 0``."""
    return poly_value(coeffs, p) < 0


# ---------------------------------------------------------------- the record

class Poly(AbstractShape):
    """``quartic { <A1, …, A35> }``, ``cubic { <A1, …, A20> }``, ``poly { order, <A1, …> }`` and
    ``polynomial { order, xyz(i, j, k): A, … }`` of order 2 to 4: ``P(x, y, z) = 0``, inside < 0,
    held as the 35 coefficients of a quartic. Unbounded in general (``bounds`` is None)."""

    kind: ClassVar[str] = "poly"
    bounded: ClassVar[bool] = False
    crossings: ClassVar[int] = POLY_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("quartic", "cubic", "poly", "polynomial")
    coeffs: Float[Array, "35"] = eqx.field(converter=as_float)

    def hits(self, o, d):
        return poly_hits(self.coeffs, o, d)

    def inside(self, p):
        return poly_inside(self.coeffs, p)

    # unbounded, as a quadric: never an item of its own, only a member of a bounded CSG object (a
    # pawn's quartics in a union bounded by a cylinder, advanced/pawns), whose crossings the
    # hierarchy's own solver finds (``_native/bvh.cc``); 35 coefficients take two rows
    native_kernel: ClassVar[int] = NATIVE_POLY
    native_rows: ClassVar[int] = 2

    def native_items(self):
        xp = array_module(self.coeffs)
        params = xp.concatenate([self.coeffs, xp.zeros(1, self.coeffs.dtype)])[None]  # (1, 36)
        return params, xp.zeros((1, 1, 3), self.coeffs.dtype)

    def near_hit(self, o, d, t0):
        # the crossing the hierarchy's solver found (double precision): two Newton steps of P
        # attach its implicit derivatives (``differentiable_root``: the value stays t0) instead of
        # bracketing every root again
        coeffs, o, d = as_float_arrays(self.coeffs, o, d)
        t = differentiable_root(lambda ti: poly_value(coeffs, o + ti * d), t0)
        normal = safe_normalize(jax.grad(lambda q: poly_value(coeffs, q))(o + t * d))
        return t[None], normal[None]

    @classmethod
    def parse_sdl(cls, keyword, args):
        if keyword in ("quartic", "cubic"):
            order = 4 if keyword == "quartic" else 3
            return {"coeffs": quartic_coefficients(order, args.coefficients(len(povray_terms(order))))}
        loc = args.loc
        order = args.float()
        if order != int(order) or not 2 <= order <= 35:
            raise args.error(f"{keyword} order must be a whole number from 2 to 35, found {order:g}", loc)
        order = int(order)
        args.comma()
        terms = povray_terms(order)
        if keyword == "poly":
            values = args.coefficients(len(terms))
        else:  # polynomial: xyz(i, j, k): value entries, any order, the last of one term kept
            given = {}
            while args.keyword("xyz"):
                args.expect("(")
                at = args.loc
                powers = []
                for n in range(3):
                    if n:
                        args.comma()
                    powers.append(args.count("powers of x, y or z"))
                args.expect(")")
                if sum(powers) > order:
                    raise args.error(f"xyz{tuple(powers)} is of a higher order than {order}", at)
                args.expect(":")
                given[tuple(powers)] = args.float()
                args.comma()
            values = [given.get(term, 0.0) for term in terms]
        if order > ORDER_MAX:
            args.leave_out(f"{keyword} of order {order} is not supported (orders 2 to {ORDER_MAX} are); "
                           "the object is left out")
            return {"coeffs": np.zeros(len(TERMS))}
        return {"coeffs": quartic_coefficients(order, values)}
