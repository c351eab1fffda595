"""Axis-aligned box between two corners: the slab method (Kay & Kajiya 1986, as pbrt-v4 `IntersectP`)."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits
from ..kernels._numerics import as_float_arrays, solve_linear
from ._base import (
    NATIVE_BOX,
    AbstractShape,
    MitsubaShape,
    NoEquivalent,
    SdlArguments,
    affine,
    array_module,
    box_corners,
    native_params,
)

BOX_K = 2


def _face_normal(axis: Array, sign: Array, dtype) -> Float[Array, "3"]:
    return jnp.where(jnp.arange(3) == axis, sign, 0.0).astype(dtype)


def box_hits(
    corner1: Float[ArrayLike, "3"],
    corner2: Float[ArrayLike, "3"],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "2"], Float[Array, "2 3"]]:
    """Entry and exit of the line ``o + t d`` through the box.

    Args:
        corner1, corner2: (3,) opposite corners in any order (sorted per axis here, as POV-Ray does).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (2,) = (entry, exit), both ``+inf`` on a miss; n (2, 3) outward face normals
        (``-e_i`` on a low face, ``+e_i`` on a high face).
    """
    corner1, corner2, o, d = as_float_arrays(corner1, corner2, o, d)
    lo, hi = jnp.minimum(corner1, corner2), jnp.maximum(corner1, corner2)
    t_lo, ok = solve_linear(d, o - lo)
    t_hi, _ = solve_linear(d, o - hi)
    # A slab the line runs parallel to: the whole line if o is between its faces, else nothing.
    inside_slab = (o >= lo) & (o <= hi)
    lo_first = t_lo <= t_hi
    near = jnp.where(ok, jnp.minimum(t_lo, t_hi), jnp.where(inside_slab, -jnp.inf, jnp.inf))
    far = jnp.where(ok, jnp.maximum(t_lo, t_hi), jnp.where(inside_slab, jnp.inf, -jnp.inf))
    near_axis, far_axis = jnp.argmax(near), jnp.argmin(far)
    t_near, t_far = near[near_axis], far[far_axis]
    hit = jnp.isfinite(t_near) & jnp.isfinite(t_far) & (t_near <= t_far)
    n_near = _face_normal(near_axis, jnp.where(lo_first[near_axis], -1.0, 1.0), o.dtype)
    n_far = _face_normal(far_axis, jnp.where(lo_first[far_axis], 1.0, -1.0), o.dtype)
    t = jnp.stack([t_near, t_far])
    return masked_hits(t, jnp.stack([n_near, n_far]), jnp.stack([hit, hit]))


def box_inside(
    corner1: Float[ArrayLike, "3"], corner2: Float[ArrayLike, "3"], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside the box."""
    corner1, corner2, p = as_float_arrays(corner1, corner2, p)
    lo, hi = jnp.minimum(corner1, corner2), jnp.maximum(corner1, corner2)
    return jnp.all((p > lo) & (p < hi))


# ---------------------------------------------------------------- the record

class Box(AbstractShape):
    """``box { corner1, corner2 }`` (axis-aligned in object space)."""

    kind: ClassVar[str] = "box"
    crossings: ClassVar[int] = BOX_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("box",)
    sdl_arguments: ClassVar[SdlArguments] = (("corner1", "vector"), ("corner2", "vector"))
    corner1: Float[Array, "3"] = eqx.field(converter=as_float)
    corner2: Float[Array, "3"] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        # the depth of the line's deepest point in the box, max over t of min over the six faces of
        # the distance inside each (negative: how far it passes outside): a concave piecewise-linear
        # function of t, so its maximum is where two of the six lines meet. Its value is taken as
        # that meeting's (a_i + b_i t_ij, a smooth function of the box and the line), so that its
        # derivative is the envelope's: a min or max over tied values would split it between them
        corner1, corner2, o, d = as_float_arrays(self.corner1, self.corner2, o, d)
        lo, hi = jnp.minimum(corner1, corner2), jnp.maximum(corner1, corner2)
        a = jnp.concatenate([o - lo, hi - o])  # face k's inside distance along the line: a_k + b_k t
        b = jnp.concatenate([d, -d])
        i, j = np.triu_indices(6, 1)
        slope = b[i] - b[j]
        meet = jnp.abs(slope) > jnp.finfo(o.dtype).tiny
        t = (a[j] - a[i]) / jnp.where(meet, slope, 1.0)
        value = a[i] + b[i] * t
        depth = jnp.min(a[None, :] + t[:, None] * b[None, :], axis=1)  # ≤ value; equal where both lines bind
        best = jnp.argmax(jnp.where(meet, 2 * depth - value, -jnp.inf))
        return value[best]

    faces: ClassVar[int] = 6  # face 2i (2i + 1): the plane x_i = lo_i (hi_i)

    def face(self, p):
        corner1, corner2, p = as_float_arrays(self.corner1, self.corner2, p)
        lo, hi = jnp.minimum(corner1, corner2), jnp.maximum(corner1, corner2)
        centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        axis = jnp.argmax(jnp.abs(p - centre) - half)  # 0 on the face p lies on, below 0 on the others
        return (2 * axis + (p[axis] > centre[axis])).astype(jnp.int32)

    def face_distance(self, o, d, face, t_ref):
        corner1, corner2, o, d = as_float_arrays(self.corner1, self.corner2, o, d)
        axis = face // 2
        lo, hi = jnp.minimum(corner1, corner2), jnp.maximum(corner1, corner2)
        return solve_linear(d[axis], o[axis] - jnp.where(face % 2 == 1, hi[axis], lo[axis]))[0]

    def hits(self, o, d):
        return box_hits(self.corner1, self.corner2, o, d)

    def inside(self, p):
        return box_inside(self.corner1, self.corner2, p)

    def bounds(self):
        xp = array_module(self.corner1, self.corner2)
        return xp.minimum(self.corner1, self.corner2), xp.maximum(self.corner1, self.corner2)

    native_kernel: ClassVar[int] = NATIVE_BOX

    def native_items(self):
        return native_params(self.corner1, self.corner2), box_corners(*self.bounds())[None]


    def to_mitsuba(self, m, camera_origin):
        m = np.asarray(m, np.float64)
        lo, hi = (np.asarray(b, np.float64) for b in self.bounds())
        p = np.linalg.solve(m, np.append(camera_origin, 1.0))[:3]
        if np.all((p > lo) & (p < hi)):
            raise NoEquivalent("camera inside a box")
        local = affine(np.diag((hi - lo) / 2.0), (hi + lo) / 2.0)
        return MitsubaShape([{"type": "cube", "to_world": m @ local}], closed=True, planar=False)
