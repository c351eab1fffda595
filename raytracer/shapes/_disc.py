"""Disc: the part of a plane through ``center`` with ``hole_radius <= |p - center| <= radius``."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits, points_at
from ..kernels._numerics import as_float_arrays, safe_normalize, solve_linear
from ._base import (
    NATIVE_DISC,
    AbstractShape,
    MitsubaShape,
    NoEquivalent,
    SdlArguments,
    affine,
    apply_point,
    box_corners,
    disc_bounds,
    frame,
    native_params,
    unit,
)

DISC_K = 1


def disc_hits(
    center: Float[ArrayLike, "3"],
    normal: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    hole_radius: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the disc (an annulus when ``hole_radius > 0``).

    Args:
        center: (3,) centre.
        normal: (3,) normal, any nonzero length; it points to the outside half-space.
        radius: () outer radius.
        hole_radius: () inner radius (0 for no hole).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss or a parallel ray; n (1, 3) = unit ``normal``.
    """
    center, normal, radius, hole_radius, o, d = as_float_arrays(center, normal, radius, hole_radius, o, d)
    n_hat = safe_normalize(normal)
    l = o - center
    t, ok = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, l))
    r = points_at(l, d, t[None])[0]
    rho_sq = jnp.dot(r, r)
    hit = ok & (rho_sq <= radius * radius) & (rho_sq >= hole_radius * hole_radius)
    return masked_hits(t[None], n_hat[None], hit[None])


def disc_inside(
    center: Float[ArrayLike, "3"],
    normal: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    hole_radius: Float[ArrayLike, ""],
    p: Float[ArrayLike, "3"],
) -> Bool[Array, ""]:
    """POV-Ray's disc inside: the half-space behind the disc's plane, ``n̂ · (p - center) < 0``."""
    center, normal, radius, hole_radius, p = as_float_arrays(center, normal, radius, hole_radius, p)
    return jnp.dot(safe_normalize(normal), p - center) < 0


# ---------------------------------------------------------------- the record

class Disc(AbstractShape):
    """``disc { center, normal, radius [, hole_radius] }``; its inside is its plane's half-space."""

    kind: ClassVar[str] = "disc"
    crossings: ClassVar[int] = DISC_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("disc",)
    pov_bounds_margin: ClassVar[float] = 1e-3
    sdl_arguments: ClassVar[SdlArguments] = (("center", "vector"), ("normal", "vector"), ("radius", "float"))
    center: Float[Array, "3"] = eqx.field(converter=as_float)
    normal: Float[Array, "3"] = eqx.field(converter=as_float)
    radius: Float[Array, ""] = eqx.field(converter=as_float)
    hole_radius: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)

    def silhouette_margin(self, o, d):
        # at the line's crossing with the disc's plane: radius² − ρ² (and ρ² − hole² with a hole)
        center, normal, radius, hole, o, d = as_float_arrays(self.center, self.normal, self.radius,
                                                             self.hole_radius, o, d)
        n_hat = safe_normalize(normal)
        l = o - center
        t, _ = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, l))
        r = l + t * d
        rho_sq = jnp.dot(r, r)
        outer = radius * radius - rho_sq
        return jnp.where(hole > 0, jnp.minimum(outer, rho_sq - hole * hole), outer)

    def hits(self, o, d):
        return disc_hits(self.center, self.normal, self.radius, self.hole_radius, o, d)

    def inside(self, p):
        return disc_inside(self.center, self.normal, self.radius, self.hole_radius, p)

    def bounds(self):
        return disc_bounds(self.center, self.normal, self.radius)

    native_kernel: ClassVar[int] = NATIVE_DISC

    def native_items(self):
        return (native_params(self.center, self.normal, self.radius, self.hole_radius),
                box_corners(*self.bounds())[None])

    @classmethod
    def parse_sdl(cls, keyword, args):
        fields = super().parse_sdl(keyword, args)
        fields["hole_radius"] = args.float() if args.accept(",") else 0.0
        return fields

    def to_mitsuba(self, m, camera_origin):
        if float(self.hole_radius) != 0.0:
            raise NoEquivalent("disc with a hole")
        m = np.asarray(m, np.float64)
        centre = apply_point(m, self.center)
        n_world = np.linalg.inv(m[:3, :3]).T @ unit(self.normal)
        if np.dot(camera_origin - centre, n_world) < 0:
            n_world = -n_world  # one-sided emitters face the camera; POV shades both sides
        r = float(self.radius)
        a = m[:3, :3] @ frame(unit(self.normal))  # disc plane axes, transformed
        linear = np.stack([a[:, 0] * r, a[:, 1] * r, unit(n_world)], axis=1)
        return MitsubaShape([{"type": "disk", "to_world": affine(linear, centre)}], closed=False, planar=True)
