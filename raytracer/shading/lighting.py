"""POV-Ray 3.7's local lighting model, term by term (semantics §2.4–2.7).

Plain functions of arrays for one shading point; vectors are (3,). ``d`` is the incoming ray
direction (towards the surface), ``n`` the unit normal flipped to face the ray (``n·d < 0``),
``l`` the unit direction towards the light. There is no 1/π, no inverse-square falloff and no
energy conservation unless the scene asks for it: these are POV-Ray's rules, not physics.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..kernels import safe_arccos, safe_div, safe_pow, safe_sqrt

GREY = (0.297, 0.589, 0.114)  # POV-Ray's grey weights for "trans" (semantics §2.3)
NL_EPSILON = 1e-10  # lights with n·l below this do not light the point (semantics §2.4)


def interior_fade(depth, fade_distance, fade_power, fade_color, on=True, *, shadow_ray=False):
    """Attenuation after ``depth`` inside an object (semantics §2.7): ``fc + (1 - fc)/(1 + (d/fd)^fp)``, or
    ``exp(-(1 - fc)·d/fd)`` when ``fade_power >= 1000``; 1 where ``on`` is False or ``fade_distance`` is 0.

    As POV-Ray 3.7 renders it (measured): a transmitted ray fades for every ``fade_power``, 0 (its
    default: ``(1 + fc)/2`` at any depth) and negative ones included; a shadow ray (``shadow_ray``,
    static) only where ``fade_power > 0``."""
    on = on & (fade_distance != 0)
    if shadow_ray:
        on = on & (fade_power > 0)
    fd = jnp.where(on, fade_distance, 1.0)
    ratio = jnp.where(on, depth / fd, 0.0)
    exponential = fade_power >= 1000
    # the branch not taken gets a harmless exponent, so its gradient cannot be inf · 0
    power = jnp.where(on & ~exponential, fade_power, 1.0)
    rational = fade_color + (1 - fade_color) / (1 + safe_pow(ratio, power))
    return jnp.where(on, jnp.where(exponential, jnp.exp(-(1 - fade_color) * ratio), rational), 1.0)


def empirical_fresnel(cos_angle):
    """POV's empirical metallic Fresnel ``F(x)``, ``x = acos(cos)/(π/2)`` (semantics §2.4)."""
    x = safe_arccos(jnp.clip(cos_angle, -1.0, 1.0)) / (jnp.pi / 2)
    f = 0.014567225 / ((x - 1.12) ** 2) - 0.011612903
    return jnp.clip(f, 0.0, 1.0)


def metallic_tint(metallic, cos_angle, rgb):
    """Highlight/reflection colour multiplier ``1 + m(1 − F)(P − 1)``."""
    return 1.0 + metallic * (1.0 - empirical_fresnel(cos_angle)) * (rgb - 1.0)


def diffuse(att, k_diffuse, brilliance, cos_nl, rgb):
    """``att · diffuse · |n·l|^brilliance · P`` (to be multiplied by the light colour)."""
    return att * k_diffuse * safe_pow(jnp.abs(cos_nl), brilliance) * rgb


def phong(k_phong, phong_size, d, n, l):
    """``phong · max(0, r·l)^phong_size`` with ``r = d − 2(d·n)n``; zero when size ≥ 60 and r·l ≤ 8e-4."""
    r = d - 2.0 * jnp.dot(d, n) * n
    c = jnp.dot(r, l)
    on = (c > 0) & ~((phong_size >= 60) & (c <= 0.0008))
    return jnp.where(on, k_phong * safe_pow(jnp.where(on, c, 1.0), phong_size), 0.0)


def specular(k_specular, roughness, d, n, l):
    """``specular · max(0, n·h)^(1/roughness)`` with ``h = normalize(l − d)``."""
    h = l - d
    hh = jnp.dot(h, h)
    ok = hh > 0
    c = safe_div(jnp.dot(n, h), safe_sqrt(jnp.where(ok, hh, 1.0)))
    on = ok & (c > 0)
    return jnp.where(on, k_specular * safe_pow(jnp.where(on, c, 1.0), safe_div(1.0, roughness)), 0.0)


def fresnel(cos_i, eta_rel):
    """Unpolarised dielectric Fresnel reflectance in POV's form (semantics §2.6).

    ``eta_rel = n_t/n_i``; returns ``(F, total)`` where ``total`` marks ``n² + c² − 1 ≤ 0`` (TIR).
    """
    g2 = eta_rel * eta_rel + cos_i * cos_i - 1.0
    total = g2 <= 0
    g = safe_sqrt(jnp.where(total, 1.0, g2))
    a = safe_div(g - cos_i, g + cos_i)
    b = safe_div(cos_i * (g + cos_i) - 1.0, cos_i * (g - cos_i) + 1.0)
    f = 0.5 * a * a * (1.0 + b * b)
    return jnp.clip(f, 0.0, 1.0), total


def refract(d, n, eta):
    """Heckbert refraction of unit ``d`` at a normal ``n`` facing the ray, ``eta = n_i/n_t``.

    Returns ``(direction, tir)``; where ``tir`` the direction is the mirror direction.
    """
    c = -jnp.dot(d, n)
    t = refraction_discriminant(d, n, eta)
    tir = t < 0
    out = eta * d + (eta * c - safe_sqrt(jnp.where(tir, 1.0, t))) * n
    mirror = d + 2.0 * c * n
    return jnp.where(tir, mirror, out), tir


def refraction_discriminant(d, n, eta):
    """``1 + η²(c² − 1)``, c = −d·n: what is under :func:`refract`'s square root; below 0 refraction
    is total internal reflection (its zero is where that begins: ``_edges``' margin of it)."""
    c = -jnp.dot(d, n)
    return 1.0 + eta * eta * (c * c - 1.0)


def reflect(d, n):
    return d - 2.0 * jnp.dot(d, n) * n


def above_surface(r, n):
    """A mirror direction ``r`` about a perturbed normal, kept on the viewer's side of the surface
    whose normal (facing the viewer) is ``n``: below it, it is mirrored about the surface."""
    along = jnp.dot(r, n)
    return jnp.where(along < 0, r - 2.0 * along * n, r)


def grey(rgb):
    return GREY[0] * rgb[..., 0] + GREY[1] * rgb[..., 1] + GREY[2] * rgb[..., 2]
