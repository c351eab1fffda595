"""Sphere ``|p - center| = radius``: two crossings, outward normal ``(p - center) / |p - center|``."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._build import build
from .._dtype import as_float
from ..kernels._common import masked_hits, points_at
from ..kernels._numerics import as_float_arrays, offset_sq_minus, safe_normalize, solve_quadratic
from ._base import (
    NATIVE_SPHERE,
    AbstractShape,
    MitsubaShape,
    NoEquivalent,
    SdlArguments,
    apply_point,
    array_module,
    box_corners,
    native_params,
    similarity_scale,
)

SPHERE_K = 2


def sphere_hits(
    center: Float[ArrayLike, "3"],
    radius: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "2"], Float[Array, "2 3"]]:
    """Both crossings of the line ``o + t d`` with the sphere, in object space.

    Args:
        center: (3,) sphere centre.
        radius: () radius (> 0 for a solid; differentiable).
        o: (3,) ray origin.
        d: (3,) ray direction, any length (``t`` is in units of ``|d|``).

    Returns:
        ``(t, n)``: t (2,) ascending, ``+inf`` for missing crossings (any sign of t is reported);
        n (2, 3) unit outward normals.
    """
    center, radius, o, d = as_float_arrays(center, radius, o, d)
    l = o - center
    a = jnp.dot(d, d)
    b = 2.0 * jnp.dot(d, l)
    c = offset_sq_minus(o, center, radius)  # compensated: no cancellation near huge spheres
    # b² - 4ac = 4 (r² |d|² - |d × l|²): the squared distance of the line from the centre appears
    # directly, so it does not cancel for distant rays (Hearn & Baker's form, as in pbrt-v4).
    cross = jnp.cross(d, l)
    disc = 4.0 * (radius * radius * a - jnp.dot(cross, cross))
    t0, t1, _ = solve_quadratic(a, b, c, disc)
    t = jnp.stack([t0, t1])
    n = safe_normalize(points_at(o, d, t) - center[None, :])
    # a radius ≤ 0 has no surface: POV-Ray renders ``sphere { c, -1 }`` as nothing (measured: the
    # image without the sphere, 86 dB)
    return masked_hits(t, n, jnp.isfinite(t) & (radius > 0))


def sphere_inside(
    center: Float[ArrayLike, "3"], radius: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside the sphere: ``|p - center| < radius``."""
    center, radius, p = as_float_arrays(center, radius, p)
    l = p - center
    return (jnp.dot(l, l) < radius * radius) & (radius > 0)


# ---------------------------------------------------------------- the record

class Sphere(AbstractShape):
    """``sphere { center, radius }``."""

    kind: ClassVar[str] = "sphere"
    crossings: ClassVar[int] = SPHERE_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("sphere",)
    sdl_arguments: ClassVar[SdlArguments] = (("center", "vector"), ("radius", "float"))
    center: Float[Array, "3"] = eqx.field(converter=as_float)
    radius: Float[Array, ""] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        # r² − (the line's distance from the centre)², times |d|²: |d × (o − c)|² = |d|²·dist²
        center, radius, o, d = as_float_arrays(self.center, self.radius, o, d)
        cross = jnp.cross(d, o - center)
        return radius * jnp.abs(radius) * jnp.dot(d, d) - jnp.dot(cross, cross)  # < 0: no surface

    def hits(self, o, d):
        return sphere_hits(self.center, self.radius, o, d)

    def inside(self, p):
        return sphere_inside(self.center, self.radius, p)

    def bounds(self):
        r = array_module(self.radius).abs(self.radius)
        return self.center - r, self.center + r

    native_kernel: ClassVar[int] = NATIVE_SPHERE

    def native_items(self):
        return native_params(self.center, self.radius), box_corners(*self.bounds())[None]

    def absorb_transform(self, world_from_object):
        m = np.asarray(world_from_object, np.float64)
        a = m[:3, :3]
        s2 = np.trace(a.T @ a) / 3.0
        if not (s2 > 0 and np.allclose(a.T @ a, s2 * np.eye(3), rtol=0.0, atol=1e-12 * s2)):
            return None  # an ellipsoid
        return build(Sphere, center=apply_point(m, self.center),
                     radius=np.sqrt(s2) * np.asarray(self.radius, np.float64))

    def to_mitsuba(self, m, camera_origin):
        s = similarity_scale(m)
        if s is None:
            raise NoEquivalent("ellipsoid", "a non-uniformly scaled sphere needs tessellation in Mitsuba")
        centre, radius = apply_point(m, self.center), s * float(self.radius)
        if np.linalg.norm(camera_origin - centre) < radius:
            raise NoEquivalent("camera inside a sphere")
        return MitsubaShape([{"type": "sphere", "center": centre.tolist(), "radius": radius}],
                            closed=True, planar=False)
