"""Camera rays through pixel centres and sub-pixel grids (semantics §1.2)."""

from __future__ import annotations

import jax.numpy as jnp

from ..kernels import safe_normalize
from ..scene import Camera


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
        ``location + x0 R + y0 U`` along ``D``.
    """
    loc, d, r, u = camera.frame()
    x0 = x0[..., None]
    y0 = y0[..., None]
    offset = x0 * r.reshape((1,) * (x0.ndim - 1) + (3,)) + y0 * u.reshape((1,) * (y0.ndim - 1) + (3,))
    if camera.projection == "orthographic":
        origins = jnp.broadcast_to(loc, offset.shape) + offset
        dirs = jnp.broadcast_to(d, origins.shape)
    else:
        dirs = jnp.broadcast_to(d, offset.shape) + offset
        origins = jnp.broadcast_to(loc, dirs.shape)
    return origins, safe_normalize(dirs)
