"""Torus in the x–z plane, the y axis through its hole: ``(|p|² + R² - r²)² - 4R²(x² + z²) = 0``.

The quartic is solved in a well-scaled frame: along the unit direction ``d̂`` from ``o_c``, the point of
the line closest to the centre. There every crossing has ``|s| <= R + r`` (the bounding sphere), which
brackets :func:`solve_quartic`, and the coefficients are O((R + r)⁴) whatever the distance of the ray.
The roots found without gradient get their derivatives from the implicit function theorem
(:func:`differentiable_root`).
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
    solve_quartic,
)
from ._base import (
    NATIVE_TORUS,
    AbstractShape,
    SdlArguments,
    array_module,
    box_corners,
    native_params,
)

TORUS_K = 4


def _implicit(major, minor, p):
    """Torus quartic; < 0 inside the tube."""
    rho_sq = p[..., 0] ** 2 + p[..., 2] ** 2
    return (jnp.sum(p * p, axis=-1) + major**2 - minor**2) ** 2 - 4.0 * major**2 * rho_sq


def _implicit_factored(major, minor, p):
    """The same quartic as a product, ``((ρ - R)² + y² - r²) ((ρ + R)² + y² - r²)``.

    Far better conditioned near the surface in float32 (the first factor is the squared distance to the
    core circle minus r², with no cancellation of O(R²ρ²) terms); used for the sign in the root search.
    """
    rho = jnp.sqrt(p[..., 0] ** 2 + p[..., 2] ** 2)
    y_sq = p[..., 1] ** 2
    return ((rho - major) ** 2 + y_sq - minor**2) * ((rho + major) ** 2 + y_sq - minor**2)


def _gradient(major, minor, p):
    """∇ of the quartic: ``4 (|p|² + R² - r²) p - 8 R² (x, 0, z)``; points out of the solid."""
    planar = p * jnp.array([1.0, 0.0, 1.0], p.dtype)
    return 4.0 * (jnp.dot(p, p) + major**2 - minor**2) * p - 8.0 * major**2 * planar


def torus_value(
    major: Float[ArrayLike, ""], minor: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Float[Array, ""]:
    """The torus quartic at ``p``: negative inside, zero on the surface, positive outside."""
    major, minor, p = as_float_arrays(major, minor, p)
    return _implicit(major, minor, p)


def _quartic_coefficients(major, minor, o_c, d_hat):
    """Coefficients (highest first) of the quartic in s at ``o_c + s d̂``."""
    a = jnp.dot(d_hat, d_hat)  # 1 up to rounding
    beta = jnp.dot(o_c, d_hat)  # 0 up to rounding
    e = jnp.dot(o_c, o_c) + major**2 - minor**2
    a2 = d_hat[0] ** 2 + d_hat[2] ** 2
    b2 = 2.0 * (o_c[0] * d_hat[0] + o_c[2] * d_hat[2])
    c2 = o_c[0] ** 2 + o_c[2] ** 2
    four_r2 = 4.0 * major**2
    # (a s² + 2β s + e)² - 4R² (a2 s² + b2 s + c2), expanded.
    return jnp.stack(
        [
            a * a,
            4.0 * a * beta,
            4.0 * beta * beta + 2.0 * a * e - four_r2 * a2,
            4.0 * beta * e - four_r2 * b2,
            e * e - four_r2 * c2,
        ]
    )


def torus_hits(
    major: Float[ArrayLike, ""],
    minor: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "4"], Float[Array, "4 3"]]:
    """All (up to four) crossings of the line ``o + t d`` with the torus.

    Args:
        major: () R, radius of the core circle (in the x–z plane, centred at the origin).
        minor: () r, radius of the tube.
        o: (3,) ray origin.
        d: (3,) ray direction, any length (zero length: a miss).

    Returns:
        ``(t, n)``: t (4,), the finite ones ascending, ``+inf`` where absent; n (4, 3) unit outward normals
        (the normalised gradient of the quartic).
    """
    major, minor, o, d = as_float_arrays(major, minor, o, d)
    moving, inv_len, d_hat, t_c, o_c = centred_line(o, d)
    bound = (jnp.abs(major) + jnp.abs(minor)) * 1.001

    sg = lax.stop_gradient
    s_star, found = solve_quartic(
        _quartic_coefficients(major, minor, o_c, d_hat),
        -bound,
        bound,
        lambda s: _implicit_factored(
            sg(major), sg(minor), sg(o_c)[None, :] + s[:, None] * sg(d_hat)[None, :]
        ),
    )
    s_star = jnp.where(found, s_star, 0.0)
    s = jax.vmap(lambda s0: differentiable_root(lambda s: _implicit(major, minor, o_c + s * d_hat), s0))(
        s_star
    )
    p = o_c[None, :] + s[:, None] * d_hat[None, :]
    n = safe_normalize(jax.vmap(lambda q: _gradient(major, minor, q))(p))
    return masked_hits(t_c + s * inv_len, n, found & moving)


# angles at which the core circle's squared distance from a line is sampled before its minimum is
# bisected: the distance is a trigonometric polynomial of degree 2 in the angle (at most two minima)
_CIRCLE_SAMPLES = 32


def torus_margin(
    major: Float[ArrayLike, ""],
    minor: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> Float[Array, ""]:
    """``r² − δ²``, δ the distance between the line ``o + t d`` and the core circle: the solid torus
    is the set of points within r of that circle, so the line crosses it exactly where this is
    positive, and touches it (an outline, outer or inner) where it vanishes.

    δ² = min over the circle's angle φ of ``|w|² − (w · d̂)²``, ``w = c(φ) − o``. Sampled at
    ``_CIRCLE_SAMPLES`` angles, its minimum is bisected on the slope (no gradient) in the two
    sample intervals about the least sample; at the minimum the slope in φ vanishes, so the value
    there, evaluated with the angle held, carries the right first derivatives (the envelope
    theorem)."""
    major, minor, o, d = as_float_arrays(major, minor, o, d)
    _, _, d_hat, _, o_c = centred_line(o, d)

    def dist_sq(phi, big, o_, d_):  # phi (N,)
        w = big * jnp.stack([jnp.cos(phi), jnp.zeros_like(phi), jnp.sin(phi)], -1) - o_[None, :]
        along = w @ d_
        return jnp.sum(w * w, -1) - along * along

    sg = lax.stop_gradient
    big, o_s, d_s = sg(major), sg(o_c), sg(d_hat)
    step = 2.0 * jnp.pi / _CIRCLE_SAMPLES
    phis = jnp.arange(_CIRCLE_SAMPLES, dtype=o.dtype) * step
    best = phis[jnp.argmin(dist_sq(phis, big, o_s, d_s))]
    slope = jax.vmap(jax.grad(lambda phi: dist_sq(phi[None], big, o_s, d_s)[0]))
    lo, hi = jnp.stack([best - step, best]), jnp.stack([best, best + step])
    crit, has = _bisect(slope, lo, hi, jnp.finfo(o.dtype).nmant + 4)
    crit = jnp.where(has, crit, best)
    phi = sg(crit[jnp.argmin(dist_sq(crit, big, o_s, d_s))])
    return minor * minor - dist_sq(phi[None], major, o_c, d_hat)[0]


def torus_inside(
    major: Float[ArrayLike, ""], minor: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside the tube (the quartic is negative)."""
    return torus_value(major, minor, p) < 0


# ---------------------------------------------------------------- the record

class Torus(AbstractShape):
    """``torus { major, minor }`` in the x–z plane, the y axis through the hole."""

    kind: ClassVar[str] = "torus"
    crossings: ClassVar[int] = TORUS_K
    # a quartic per ray as a candidate: advanced/cliche/sign.pov (2 tori, 2 cylinders, no light)
    # 27 -> 10 ms warm held (160x120); objects/wtorus.pov (one torus) the same warm, compiled 0.4 s faster
    costly_kernel: ClassVar[bool] = True
    sdl_keywords: ClassVar[tuple[str, ...]] = ("torus",)
    sdl_arguments: ClassVar[SdlArguments] = (("major", "float"), ("minor", "float"))
    major: Float[Array, ""] = eqx.field(converter=as_float)
    minor: Float[Array, ""] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        return torus_margin(self.major, self.minor, o, d)

    def hits(self, o, d):
        return torus_hits(self.major, self.minor, o, d)

    def inside(self, p):
        return torus_inside(self.major, self.minor, p)

    def bounds(self):
        xp = array_module(self.major, self.minor)
        r = xp.abs(self.minor)
        big = xp.abs(self.major) + r
        hi = xp.stack([big, r, big])
        return -hi, hi

    native_kernel: ClassVar[int] = NATIVE_TORUS

    def native_items(self):
        return native_params(self.major, self.minor), box_corners(*self.bounds())[None]

