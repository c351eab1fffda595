"""POV-Ray's wave functions: the map of a pattern value in [0, 1] before the colour map (each checked
against POV-Ray renders of ``gradient x``)."""

from __future__ import annotations

import math

import jax.numpy as jnp

WAVES = ("ramp", "triangle", "sine", "scallop", "cubic", "poly")


def apply_wave(v, wave: str = "ramp", exponent=1.0):
    """Map v in [0, 1] through a POV wave type.

    ramp: v; triangle: 1 - |2v - 1|; sine: (1 + sin 2πv)/2; scallop: |sin πv|; cubic: 3v² - 2v³;
    poly: v**exponent (POV's ``poly_wave`` exponent, default 1 = ramp).
    """
    if wave == "ramp":
        return v
    if wave == "triangle":
        return 1.0 - jnp.abs(2.0 * v - 1.0)
    if wave == "sine":
        return 0.5 + 0.5 * jnp.sin((2.0 * math.pi) * v)
    if wave == "scallop":
        return jnp.abs(jnp.sin(math.pi * v))
    if wave == "cubic":
        return v * v * (3.0 - 2.0 * v)
    if wave == "poly":
        ok = v > 0
        return jnp.where(ok, jnp.power(jnp.where(ok, v, 1.0), exponent), 0.0)
    raise ValueError(f"unknown wave type {wave!r}")

