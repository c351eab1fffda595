"""General quadric ``A x² + B y² + C z² + D xy + E xz + F yz + G x + H y + I z + J = 0``; inside is < 0."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits, points_at
from ..kernels._numerics import as_float_arrays, safe_normalize, solve_quadratic
from ._base import NATIVE_QUADRIC, AbstractShape, array_module, native_params

QUADRIC_K = 2


def _matrix_form(coeffs):
    """``Q(p) = pᵀ M p + g · p + J`` with M symmetric (the cross terms split in half)."""
    A, B, C, D, E, F, G, H, I, J = (coeffs[i] for i in range(10))
    m = jnp.stack(
        [jnp.stack([A, 0.5 * D, 0.5 * E]), jnp.stack([0.5 * D, B, 0.5 * F]), jnp.stack([0.5 * E, 0.5 * F, C])]
    )
    return m, jnp.stack([G, H, I]), J


def quadric_value(coeffs: Float[ArrayLike, "10"], p: Float[ArrayLike, "3"]) -> Float[Array, ""]:
    """``Q(p)``: negative inside, zero on the surface, positive outside."""
    coeffs, p = as_float_arrays(coeffs, p)
    m, g, j = _matrix_form(coeffs)
    return jnp.dot(p, m @ p) + jnp.dot(g, p) + j


def quadric_hits(
    coeffs: Float[ArrayLike, "10"], o: Float[ArrayLike, "3"], d: Float[ArrayLike, "3"]
) -> tuple[Float[Array, "2"], Float[Array, "2 3"]]:
    """Crossings of the line ``o + t d`` with the quadric surface ``Q = 0``.

    Args:
        coeffs: (10,) POV-Ray's ``<A,B,C>, <D,E,F>, <G,H,I>, J``.
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (2,) ascending, ``+inf`` where absent (one root when ``dᵀ M d = 0``, e.g. along a
        cylinder's axis or a paraboloid's); n (2, 3) = ``∇Q / |∇Q|``, outward (towards Q > 0), or ``+z``
        where ``∇Q = 0`` (a cone's apex).
    """
    coeffs, o, d = as_float_arrays(coeffs, o, d)
    m, g, j = _matrix_form(coeffs)
    md = m @ d
    a = jnp.dot(d, md)
    b = 2.0 * jnp.dot(o, md) + jnp.dot(g, d)
    c = jnp.dot(o, m @ o) + jnp.dot(g, o) + j
    t0, t1, _ = solve_quadratic(a, b, c)
    t = jnp.stack([t0, t1])
    p = points_at(o, d, t)
    grad = 2.0 * p @ m + g[None, :]  # M is symmetric, so p M = M p
    return masked_hits(t, safe_normalize(grad), jnp.isfinite(t))


def quadric_inside(coeffs: Float[ArrayLike, "10"], p: Float[ArrayLike, "3"]) -> Bool[Array, ""]:
    """True where ``Q(p) < 0``."""
    return quadric_value(coeffs, p) < 0


# ---------------------------------------------------------------- the record

class Quadric(AbstractShape):
    """``quadric { <A,B,C>, <D,E,F>, <G,H,I>, J }``:
    ``A x² + B y² + C z² + D xy + E xz + F yz + G x + H y + I z + J = 0``, inside < 0.

    Unbounded in general (``bounds`` is None); POV-Ray users bound it with ``clipped_by``."""

    kind: ClassVar[str] = "quadric"
    bounded: ClassVar[bool] = False
    crossings: ClassVar[int] = QUADRIC_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("quadric",)
    coeffs: Float[Array, "10"] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        # the discriminant b² − 4ac of Q(o + t d) = a t² + b t + c: positive where the line crosses
        # the surface twice, zero where it touches it (a sphere's margin, four times over)
        coeffs, o, d = as_float_arrays(self.coeffs, o, d)
        m, g, j = _matrix_form(coeffs)
        md = m @ d
        b = 2.0 * jnp.dot(o, md) + jnp.dot(g, d)
        return b * b - 4.0 * jnp.dot(d, md) * (jnp.dot(o, m @ o) + jnp.dot(g, o) + j)

    def hits(self, o, d):
        return quadric_hits(self.coeffs, o, d)

    def inside(self, p):
        return quadric_inside(self.coeffs, p)

    # unbounded, as a plane: never an item of its own, only a member of a bounded CSG object (an
    # intersection with a box, shapes.inc's Cylinder_X clipped by one); its crossings' choice is
    # then the hierarchy's (``_accel``)
    native_kernel: ClassVar[int] = NATIVE_QUADRIC

    def native_items(self):
        return native_params(self.coeffs), array_module(self.coeffs).zeros((1, 1, 3), self.coeffs.dtype)

    @classmethod
    def parse_sdl(cls, keyword, args):
        a = args.vector()
        args.comma()
        b = args.vector()
        args.comma()
        c = args.vector()
        args.comma()
        return {"coeffs": (*a, *b, *c, args.float())}
