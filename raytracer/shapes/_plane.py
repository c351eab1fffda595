"""Plane ``n̂ · p = distance`` with ``n̂ = normal / |normal|`` (POV-Ray normalises at parse time)."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._dtype import as_float
from ..kernels._common import masked_hits
from ..kernels._numerics import as_float_arrays, safe_normalize, solve_linear
from ._base import (
    NATIVE_PLANE,
    AbstractShape,
    MitsubaShape,
    apply_point,
    array_module,
    native_params,
    unit,
)

PLANE_K = 1


def plane_hits(
    normal: Float[ArrayLike, "3"],
    distance: Float[ArrayLike, ""],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the plane.

    Args:
        normal: (3,) plane normal, any nonzero length; it points to the outside.
        distance: () offset along the unit normal.
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` when the line is parallel to the plane; n (1, 3) = n̂.
    """
    normal, distance, o, d = as_float_arrays(normal, distance, o, d)
    n_hat = safe_normalize(normal)
    t, ok = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, o) - distance)
    return masked_hits(t[None], n_hat[None], ok[None])


def plane_inside(
    normal: Float[ArrayLike, "3"], distance: Float[ArrayLike, ""], p: Float[ArrayLike, "3"]
) -> Bool[Array, ""]:
    """True where ``p`` is strictly inside (below) the plane: ``n̂ · p < distance``."""
    normal, distance, p = as_float_arrays(normal, distance, p)
    return jnp.dot(safe_normalize(normal), p) < distance


# ---------------------------------------------------------------- the record

class Plane(AbstractShape):
    """``plane { normal, distance }``: the surface ``n̂·p = distance``; inside is ``n̂·p < distance``."""

    kind: ClassVar[str] = "plane"
    bounded: ClassVar[bool] = False
    crossings: ClassVar[int] = PLANE_K
    sdl_keywords: ClassVar[tuple[str, ...]] = ("plane",)
    normal: Float[Array, "3"] = eqx.field(converter=as_float)
    distance: Float[Array, ""] = eqx.field(converter=as_float)

    def silhouette_margin(self, o, d):
        # every line but a parallel one crosses a plane: its outline is the horizon, where the
        # crossing passes from ahead of o (t > 0, positive) to behind it
        normal, distance, o, d = as_float_arrays(self.normal, self.distance, o, d)
        n_hat = safe_normalize(normal)
        return -(jnp.dot(n_hat, o) - distance) * jnp.dot(n_hat, d)

    def hits(self, o, d):
        return plane_hits(self.normal, self.distance, o, d)

    def inside(self, p):
        return plane_inside(self.normal, self.distance, p)

    # unbounded: never an item of its own, only a member of a bounded CSG object (``_accel``)
    native_kernel: ClassVar[int] = NATIVE_PLANE

    def native_items(self):
        xp = array_module(self.normal)
        return native_params(self.normal, self.distance), xp.zeros((1, 1, 3), self.normal.dtype)

    @classmethod
    def parse_sdl(cls, keyword, args):
        loc = args.loc
        n = np.asarray(args.vector(), dtype=np.float64)
        args.comma()
        d = args.float()
        length = float(np.linalg.norm(n))
        if length == 0:
            raise args.error("expected a non-zero plane normal, found <0,0,0>", loc)
        return {"normal": tuple(n / length), "distance": d}

    def to_mitsuba(self, m, camera_origin):
        n_obj = unit(self.normal)
        point = apply_point(m, n_obj * float(self.distance))
        normal = unit(np.linalg.inv(np.asarray(m, np.float64)[:3, :3]).T @ n_obj)
        return MitsubaShape([{"type": "_plane", "point": point, "normal": normal}], closed=False, planar=True)
