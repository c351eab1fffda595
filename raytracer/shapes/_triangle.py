"""Flat and smooth triangles (Möller & Trumbore 1997, "Fast, minimum storage ray/triangle intersection").

Barycentric convention: the hit is ``(1 - u - v) p1 + u p2 + v p3``, so the weights of
``(p1, p2, p3)`` are ``(1 - u - v, u, v)``. POV-Ray writes the smooth normal as
``(1-u')N1 + u'(1-v')N2 + u'v'N3`` in its own parametrisation; both are the unique barycentric weights
of the hit point, so the interpolated normals agree.
"""


from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._dtype import as_float
from ..kernels._numerics import as_float_arrays, eps_of, safe_mask, safe_normalize
from ._base import (
    NATIVE_TRIANGLE,
    AbstractShape,
    MitsubaShape,
    SdlArguments,
    array_module,
    mesh_entry,
    native_params,
)

TRIANGLE_K = 1
SMOOTH_TRIANGLE_K = 1


def _barycentric_hit(p1, p2, p3, o, d):
    """``(t, u, v, hit, geometric normal)``; t, u, v are finite (but meaningless) where not ``hit``."""
    e1, e2, s = p2 - p1, p3 - p1, o - p1
    area = jnp.cross(e1, e2)  # twice the area, along the geometric normal
    pvec = jnp.cross(d, e2)
    det = jnp.dot(e1, pvec)  # = -d · area
    eps = eps_of(det)
    area_sq = jnp.dot(area, area)
    # A sliver whose sine of angle is below eps is degenerate (zero area); a line within eps of the
    # plane's direction is parallel. Both scale-free, both a miss.
    proper = area_sq > (eps * eps) * jnp.dot(e1, e1) * jnp.dot(e2, e2)
    ok = proper & (det * det > (eps * eps) * jnp.dot(d, d) * area_sq)
    inv_det = safe_mask(ok, lambda x: 1.0 / x, det)
    qvec = jnp.cross(s, e1)
    u = jnp.dot(s, pvec) * inv_det
    v = jnp.dot(d, qvec) * inv_det
    t = jnp.dot(e2, qvec) * inv_det
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1)
    return t, u, v, hit, safe_normalize(area)


def triangle_hits(
    p1: Float[ArrayLike, "3"],
    p2: Float[ArrayLike, "3"],
    p3: Float[ArrayLike, "3"],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the triangle (edges included).

    Args:
        p1, p2, p3: (3,) vertices; a zero-area triangle never hits.
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss; n (1, 3) = ``normalize((p2 - p1) × (p3 - p1))``, which
        may face either way (triangles have no inside; shading flips it towards the ray).
    """
    p1, p2, p3, o, d = as_float_arrays(p1, p2, p3, o, d)
    t, _, _, hit, n = _barycentric_hit(p1, p2, p3, o, d)
    up = jnp.zeros_like(n).at[2].set(1.0)
    return jnp.where(hit, t, jnp.inf)[None], jnp.where(hit, n, up)[None]


def smooth_triangle_hits(
    p1: Float[ArrayLike, "3"],
    p2: Float[ArrayLike, "3"],
    p3: Float[ArrayLike, "3"],
    n1: Float[ArrayLike, "3"],
    n2: Float[ArrayLike, "3"],
    n3: Float[ArrayLike, "3"],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing with a triangle whose normal is interpolated from vertex normals.

    Args:
        p1, p2, p3: (3,) vertices.
        n1, n2, n3: (3,) vertex normals, any lengths (used as given, then the blend is normalised).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss; n (1, 3) = ``normalize((1-u-v) n1 + u n2 + v n3)``
        (the geometric normal if that blend vanishes); it may face either way.
    """
    p1, p2, p3, n1, n2, n3, o, d = as_float_arrays(p1, p2, p3, n1, n2, n3, o, d)
    t, u, v, hit, n_geo = _barycentric_hit(p1, p2, p3, o, d)
    n = safe_normalize((1.0 - u - v) * n1 + u * n2 + v * n3, fallback=n_geo)
    up = jnp.zeros_like(n).at[2].set(1.0)
    return jnp.where(hit, t, jnp.inf)[None], jnp.where(hit, n, up)[None]


def _triangle_margin(p1, p2, p3, o, d):
    """The least barycentric coordinate of the line's crossing with the triangle's plane."""
    p1, p2, p3, o, d = as_float_arrays(p1, p2, p3, o, d)
    _, u, v, _, _ = _barycentric_hit(p1, p2, p3, o, d)
    return jnp.minimum(jnp.minimum(u, v), 1.0 - u - v)


# ---------------------------------------------------------------- the record
class Triangle(AbstractShape):
    """``triangle { p1, p2, p3 }`` (no inside)."""

    kind: ClassVar[str] = "triangle"
    crossings: ClassVar[int] = TRIANGLE_K
    solid: ClassVar[bool] = False
    sdl_keywords: ClassVar[tuple[str, ...]] = ("triangle",)
    sdl_arguments: ClassVar[SdlArguments] = (("p1", "vector"), ("p2", "vector"), ("p3", "vector"))
    p1: Float[Array, "3"] = eqx.field(converter=as_float)
    p2: Float[Array, "3"] = eqx.field(converter=as_float)
    p3: Float[Array, "3"] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        return _triangle_margin(self.p1, self.p2, self.p3, o, d)

    def hits(self, o, d):
        return triangle_hits(self.p1, self.p2, self.p3, o, d)

    def bounds(self):
        return _vertex_bounds(self.p1, self.p2, self.p3)

    native_kernel: ClassVar[int] = NATIVE_TRIANGLE  # the smooth normal does not move the hit

    def native_items(self):
        xp = array_module(self.p1, self.p2, self.p3)
        return native_params(self.p1, self.p2, self.p3), xp.stack([self.p1, self.p2, self.p3])[None]


    def to_mitsuba(self, m, camera_origin):
        tris = np.stack([np.asarray(v, np.float64) for v in (self.p1, self.p2, self.p3)])[None]
        return MitsubaShape([mesh_entry(tris, None, m)], closed=False, planar=True)


def normals_on_one_side(p1, p2, p3, n1, n2, n3) -> bool:
    """Whether the three vertex normals point strictly to one side of the triangle's plane (what
    POV-Ray 3.7 asks of a ``smooth_triangle`` outside a mesh; semantics §4.1)."""
    p1, p2, p3 = (np.asarray(v, np.float64) for v in (p1, p2, p3))
    face = np.cross(p2 - p1, p3 - p1)
    dots = np.array([np.dot(np.asarray(n, np.float64), face) for n in (n1, n2, n3)])
    return bool(np.all(dots > 0) or np.all(dots < 0))


class SmoothTriangle(AbstractShape):
    """``smooth_triangle { p1, n1, p2, n2, p3, n3 }``: normals interpolated barycentrically."""

    kind: ClassVar[str] = "smooth_triangle"
    crossings: ClassVar[int] = SMOOTH_TRIANGLE_K
    solid: ClassVar[bool] = False
    sdl_keywords: ClassVar[tuple[str, ...]] = ("smooth_triangle",)
    sdl_arguments: ClassVar[SdlArguments] = (
        ("p1", "vector"), ("n1", "vector"), ("p2", "vector"), ("n2", "vector"),
        ("p3", "vector"), ("n3", "vector"))
    p1: Float[Array, "3"] = eqx.field(converter=as_float)
    p2: Float[Array, "3"] = eqx.field(converter=as_float)
    p3: Float[Array, "3"] = eqx.field(converter=as_float)
    n1: Float[Array, "3"] = eqx.field(converter=as_float)
    n2: Float[Array, "3"] = eqx.field(converter=as_float)
    n3: Float[Array, "3"] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        return _triangle_margin(self.p1, self.p2, self.p3, o, d)

    def hits(self, o, d):
        return smooth_triangle_hits(self.p1, self.p2, self.p3, self.n1, self.n2, self.n3, o, d)

    def bounds(self):
        return _vertex_bounds(self.p1, self.p2, self.p3)

    native_kernel: ClassVar[int] = NATIVE_TRIANGLE  # the smooth normal does not move the hit

    def native_items(self):
        xp = array_module(self.p1, self.p2, self.p3)
        return native_params(self.p1, self.p2, self.p3), xp.stack([self.p1, self.p2, self.p3])[None]

    @classmethod
    def parse_sdl(cls, keyword, args):
        fields = super().parse_sdl(keyword, args)
        if not normals_on_one_side(*(fields[n] for n in ("p1", "p2", "p3", "n1", "n2", "n3"))):
            # POV-Ray 3.7: "Parse Warning: Degenerate triangle. Please remove." and draws nothing
            # (measured: a zero normal, one in the triangle's plane, or one on its other side)
            args.leave_out("smooth_triangle whose normals do not all point to one side of it (a "
                           "zero normal, one in its plane or one on its other side) is degenerate; "
                           "left out, as POV-Ray does")
        return fields

    def to_mitsuba(self, m, camera_origin):
        tris = np.stack([np.asarray(v, np.float64) for v in (self.p1, self.p2, self.p3)])[None]
        normals = np.stack([np.asarray(v, np.float64) for v in (self.n1, self.n2, self.n3)])[None]
        return MitsubaShape([mesh_entry(tris, normals, m)], closed=False, planar=True)


def _vertex_bounds(*vertices):
    xp = array_module(*vertices)
    v = xp.stack(vertices)
    return v.min(axis=0), v.max(axis=0)
