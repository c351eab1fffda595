"""The camera: POV-Ray's perspective, orthographic, fisheye, spherical and cylindrical cameras.

The user-facing fields are the modifiers as written (``location``, ``look_at``, ``angle``…); the
final ``direction``/``right``/``up`` vectors are computed in JAX by :meth:`Camera.frame` following
POV-Ray 3.5+'s fixed modifier order (semantics §1.1), so every modifier is differentiable.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._build import Record
from .._dtype import as_float, as_float_or_none
from ._transform import Transform


def _norm(v, xp=jnp):
    # sqrt of a guarded square norm: finite gradient even for a zero vector
    s = xp.sum(v * v)
    ok = s > 0
    return xp.where(ok, xp.sqrt(xp.where(ok, s, 1.0)), 0.0)


def _normalize(v, xp=jnp):
    n = _norm(v, xp)
    return v / xp.where(n > 0, n, 1.0)


def _numpy(*xs) -> bool:
    """Whether every value is a NumPy array (or None): then NumPy computes with them. JAX would
    dispatch each operation to XLA and compile it on its first use, ~15 ms each: the camera frame
    of the parse-time precision check was 16 programs, 0.26 s of a command-line parse."""
    return all(x is None or isinstance(x, np.ndarray) for x in xs)


PINHOLE = ("perspective", "orthographic")  # a ray through a point of the image plane
PROJECTIONS = (*PINHOLE, "fisheye", "spherical", "cylinder 1", "cylinder 2", "cylinder 3", "cylinder 4")
SEES_EVERYWHERE = tuple(p for p in PROJECTIONS if p != "fisheye")  # a ray for every image point


class Camera(Record):
    """POV-Ray camera (left-handed: +x right, +y up, +z into the screen).

    Attributes (POV defaults; units are scene units, angles in degrees):
        location:      (3,) eye point, default <0,0,0>.
        direction:     (3,) default <0,0,1>; its length is the focal distance before ``angle``.
        up:            (3,) default <0,1,0>; with ``look_at`` only its length matters.
        right:         (3,) default <1.33,0,0> (not 4/3); ``|up|/|right|`` is the aspect ratio.
        sky:           (3,) default <0,1,0>; sets the roll with ``look_at``.
        look_at:       (3,) or None.
        angle_degrees: horizontal field of view across the full image width, or None.
        transform:     camera transform applied after everything else, or None.
        projection:    one of ``PROJECTIONS`` (static): "perspective", "orthographic",
                       "fisheye", "spherical", "cylinder 1" … "cylinder 4" (semantics §1.4).
        up_or_right_given: whether the scene gave ``up`` or ``right`` (static; orthographic sizing).
        angle_vertical: the spherical camera's vertical angle (``angle H, V``), or None (H / 2).
    """

    location: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0))
    direction: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 1.0))
    up: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 1.0, 0.0))
    right: Float[Array, "3"] = eqx.field(converter=as_float, default=(1.33, 0.0, 0.0))
    sky: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 1.0, 0.0))
    look_at: Float[Array, "3"] | None = eqx.field(converter=as_float_or_none, default=None)
    angle_degrees: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    transform: Transform | None = None
    projection: str = eqx.field(static=True, default="perspective")
    up_or_right_given: bool = eqx.field(static=True, default=False)
    angle_vertical: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)

    def __check_init__(self):
        if self.projection not in PROJECTIONS:
            raise ValueError(f"unknown camera projection {self.projection!r}")
        if self.look_at is None or any(isinstance(v, jax.core.Tracer)
                                       for v in (self.look_at, self.location, self.sky)):
            return  # values under a transformation cannot be checked here
        view = np.asarray(self.look_at, np.float64) - np.asarray(self.location, np.float64)
        sky = np.asarray(self.sky, np.float64)
        if not np.any(view):
            raise ValueError("camera look_at equals its location: no viewing direction")
        view = view / np.max(np.abs(view))  # a tiny view (1e-320) would underflow in the norms below
        if np.linalg.norm(np.cross(sky, view)) <= 1e-12 * np.linalg.norm(sky) * np.linalg.norm(view):
            raise ValueError("camera look_at direction is parallel to sky: the image's roll is undefined "
                             "(give a different sky vector)")

    def frame(self):
        """Final ``(origin, D, R, U)`` (each (3,)) as POV-Ray computes them (semantics §1.1–1.2).

        The ray through image coordinates ``x0, y0 ∈ [-½, ½]`` is ``D + x0 R + y0 U`` from ``origin``
        (perspective) or ``D`` from ``origin + x0 R + y0 U`` (orthographic).
        """
        loc, d, u, r = self.location, self.direction, self.up, self.right
        xp = np if _numpy(loc, d, u, r, self.sky, self.look_at, self.angle_degrees,
                          None if self.transform is None else self.transform.matrix) else jnp
        if self.angle_degrees is not None and self.projection in PINHOLE:
            # |D| = |R| / (2 tan(α/2)): α is the horizontal angle across the full width (the other
            # projections read their angle themselves: shading/camera.py)
            half = xp.deg2rad(self.angle_degrees) / 2
            d = _normalize(d, xp) * (_norm(r, xp) / (2 * xp.tan(half)))
        if self.look_at is not None:
            handedness = xp.dot(xp.cross(u, d), r)
            d_hat = _normalize(self.look_at - loc, xp)
            r_hat = _normalize(xp.cross(self.sky, d_hat), xp)
            u_hat = xp.cross(d_hat, r_hat)
            # right is kept where (up × direction)·right > 0 and mirrored otherwise: with up along
            # direction (0, `up z` with the default direction) POV-Ray mirrors (objects/prism3a.pov)
            sign = xp.where(handedness > 0, 1.0, -1.0).astype(d.dtype)
            d, r, u = _norm(d, xp) * d_hat, sign * _norm(r, xp) * r_hat, _norm(u, xp) * u_hat
            if self.projection == "orthographic" and (self.angle_degrees is not None
                                                      or not self.up_or_right_given):
                # orthographic: the view size follows the distance to look_at
                k = _norm(self.look_at - loc, xp) / _norm(d, xp)
                r, u = r * k, u * k
        if self.transform is not None:
            loc = self.transform.apply_point(loc)
            d, r, u = (self.transform.apply_vector(v) for v in (d, r, u))
        return loc, d, r, u
