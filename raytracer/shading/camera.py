"""Camera rays through pixel centres and sub-pixel grids (semantics §1.2)."""

from __future__ import annotations

import jax.numpy as jnp

from ..kernels import safe_normalize, safe_sqrt
from ..scene import PINHOLE, SEES_EVERYWHERE, Camera


def sample_coords(ray, width: int, height: int, k: int = 1, dtype=jnp.float32):
    """Image-plane coordinates ``(x0, y0)`` of the samples numbered ``ray`` (int array), where
    sample ``s`` of pixel ``p`` is number ``p·k² + s`` and pixels run row by row from the top left.

    Pixel (i, j) (column i from the left, row j from the top) spans ``x0 ∈ [i/W − ½, (i+1)/W − ½]``
    and ``y0 ∈ [½ − (j+1)/H, ½ − j/H]``. ``k = 1`` samples the pixel centre (as POV-Ray ``-A``);
    ``k > 1`` a deterministic k×k grid at the centres of k×k sub-cells (``s = row·k + column``).
    """
    pixel, sample = ray // (k * k), ray % (k * k)
    sub = (jnp.arange(k, dtype=dtype) + 0.5) / k  # sub-cell centres in [0, 1]
    x0 = ((pixel % width).astype(dtype) + sub[sample % k]) / width - 0.5
    y0 = 0.5 - ((pixel // width).astype(dtype) + sub[sample // k]) / height
    return x0, y0


def camera_rays(camera: Camera, x0, y0):
    """Rays for image coordinates ``x0, y0`` (any matching shapes).

    Returns:
        ``(origins, directions)`` with a trailing axis of 3; directions are unit vectors.
        Perspective: from ``location`` along ``D + x0 R + y0 U``; orthographic: from
        ``location + x0 R + y0 U`` along ``D``; the other projections as semantics §1.4 measures
        them (:func:`_curved`).
    """
    loc, d, r, u = camera.frame()
    x0 = x0[..., None]
    y0 = y0[..., None]
    if camera.projection not in PINHOLE:
        return _curved(camera, loc, d, r, u, x0, y0)
    offset = x0 * r.reshape((1,) * (x0.ndim - 1) + (3,)) + y0 * u.reshape((1,) * (y0.ndim - 1) + (3,))
    if camera.projection == "orthographic":
        origins = jnp.broadcast_to(loc, offset.shape) + offset
        dirs = jnp.broadcast_to(d, origins.shape)
    else:
        dirs = jnp.broadcast_to(d, offset.shape) + offset
        origins = jnp.broadcast_to(loc, dirs.shape)
    return origins, safe_normalize(dirs)


def camera_sees(camera: Camera, x0, y0):
    """Whether the image point ``x0, y0`` has a ray (a fisheye's image is the disc of radius ½ in
    units of ``right`` and ``up``: outside it POV-Ray's pixels are black), or None where every
    point has one."""
    if camera.projection in SEES_EVERYWHERE:
        return None
    _, _, r, u = camera.frame()
    return jnp.hypot(x0 * _length(r), y0 * _length(u)) <= 0.5


def _length(v):
    return safe_sqrt(jnp.sum(v * v))  # (a zero ``right``: a finite gradient)


def _curved(camera: Camera, loc, d, r, u, x0, y0):
    """The fisheye, spherical and cylindrical projections (measured against POV-Ray 3.7: the
    direction of every pixel's ray read from a sky_sphere that colours directions, the origins of
    the cylinders that move the eye from a plane that colours places; semantics §1.4). Angles in
    degrees; ``R̂ Û D̂`` the unit right, up and direction of the frame."""
    dtype = d.dtype
    shape = (1,) * (x0.ndim - 1) + (3,)  # the frame's vectors against (…, 1) coordinates
    r_hat, u_hat, d_hat = (safe_normalize(v).reshape(shape) for v in (r, u, d))
    r, u = r.reshape(shape), u.reshape(shape)
    kind = camera.projection
    angle = camera.angle_degrees
    origins = jnp.broadcast_to(loc.reshape(shape), x0.shape[:-1] + (3,))
    if kind == "fisheye":
        alpha = jnp.deg2rad(jnp.asarray(90.0 if angle is None else angle, dtype))
        rx, ry = x0 * _length(r), y0 * _length(u)
        rho = jnp.sqrt(rx * rx + ry * ry)
        theta = rho * alpha
        # sin θ / ρ, finite at the centre (θ = ρ α: its limit is α)
        sinc = jnp.where(rho > 0, jnp.sin(theta) / jnp.where(rho > 0, rho, 1.0), alpha)
        dirs = sinc * (rx * r_hat + ry * u_hat) + jnp.cos(theta) * d_hat
        return origins, safe_normalize(dirs)
    if kind == "spherical":
        h = jnp.deg2rad(jnp.asarray(360.0 if angle is None else angle, dtype))
        v = h / 2 if camera.angle_vertical is None else jnp.deg2rad(camera.angle_vertical)
        lon, lat = x0 * h, y0 * v
        dirs = jnp.cos(lat) * (jnp.sin(lon) * r_hat + jnp.cos(lon) * d_hat) + jnp.sin(lat) * u_hat
        return origins, safe_normalize(dirs)
    alpha = jnp.deg2rad(jnp.asarray(90.0 if angle is None else angle, dtype))
    if kind == "cylinder 1":  # vertical cylinder, fixed eye
        a = x0 * alpha
        dirs = jnp.sin(a) * r_hat + jnp.cos(a) * d_hat + y0 * _length(u) * u_hat
    elif kind == "cylinder 2":  # horizontal cylinder, fixed eye
        a = y0 * alpha
        dirs = x0 * _length(r) * r_hat + jnp.sin(a) * u_hat + jnp.cos(a) * d_hat
    elif kind == "cylinder 3":  # vertical cylinder, the eye moves along its axis
        a = x0 * alpha
        dirs = jnp.sin(a) * r_hat + jnp.cos(a) * d_hat
        origins = origins + y0 * u
    else:  # cylinder 4: horizontal cylinder, the eye moves along its axis
        a = y0 * alpha
        dirs = jnp.sin(a) * u_hat + jnp.cos(a) * d_hat
        origins = origins + x0 * r
    return origins, safe_normalize(dirs)
