"""Continuous closed-form patterns (exact POV-Ray 3.7: the manual's definitions and, where it is
silent — the orientation of radial — what POV-Ray 3.7.0.10 renders; pixel for pixel in
``tests/shading/test_patterns.py``), and ``solid``, the pattern of a plain colour."""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..kernels import safe_sqrt
from ._common import frac, safe_atan2
from ._record import BLACK, Pattern, rgb


def solid(p, inputs):
    """A plain colour: the first entry of its one-entry map."""
    return jnp.zeros((), p.dtype)


def gradient(p, inputs):
    """Distance along the unit ``vector``; values above 1 wrap here, negatives in the caller's fmod."""
    vector = jnp.asarray(inputs.vector, p.dtype)
    n2 = jnp.sum(vector * vector)
    ok = n2 > 0
    unit = jnp.where(ok, vector / safe_sqrt(jnp.where(ok, n2, 1.0)), 0.0)
    v = jnp.dot(p, unit)
    return jnp.where(v > 1.0, frac(v), v)


def radial(p, inputs):
    """0 at +x, 0.25 at -z, 0.5 at -x, 0.75 at +z (POV-Ray manual, Pattern > General Patterns >
    Radial Pattern; checked against renders)."""
    v = safe_atan2(-p[2], p[0]) * (0.5 / math.pi)
    return jnp.where(v < 0.0, v + 1.0, v)


def onion(p, inputs):
    return frac(safe_sqrt(jnp.sum(p * p)))


def spherical(p, inputs):
    return 1.0 - jnp.minimum(1.0, safe_sqrt(jnp.sum(p * p)))


def cylindrical(p, inputs):
    return 1.0 - jnp.minimum(1.0, safe_sqrt(p[0] * p[0] + p[2] * p[2]))


def planar(p, inputs):
    return 1.0 - jnp.minimum(1.0, jnp.abs(p[1]))


def boxed(p, inputs):
    return 1.0 - jnp.minimum(1.0, jnp.max(jnp.abs(p)))


def leopard(p, inputs):
    s = (jnp.sin(p[0]) + jnp.sin(p[1]) + jnp.sin(p[2])) / 3.0
    return s * s


PATTERNS = (
    Pattern("solid", solid, keyword=False, default_map=((0.0, BLACK),)),
    Pattern("average", solid, averaged=True),
    Pattern("image_map", solid, imaged=True),
    Pattern("gradient", gradient, argument="vector"),
    # POV-Ray's built-in map, measured (povray beside a black-to-white map on the same plane)
    Pattern("radial", radial, default_map=((0.0, rgb(0, 1, 1)), (1 / 3, rgb(1, 1, 0)), (2 / 3, rgb(1, 0, 1)),
                                           (1.0, rgb(0, 1, 1)))),
    Pattern("onion", onion),
    Pattern("spherical", spherical),
    Pattern("cylindrical", cylindrical),
    Pattern("planar", planar),
    Pattern("boxed", boxed),
    Pattern("leopard", leopard),
)
