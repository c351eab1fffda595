"""Light sources: point, parallel and spotlights, optional fading and area (soft-shadow) sampling.

Colours are used as irradiance directly: no 1/π and no inverse-square falloff (reference §2.4).
"""

from __future__ import annotations

import equinox as eqx
from jaxtyping import Array, Float

from .._dtype import as_float, as_float_or_none


class Spot(eqx.Module):
    """Spotlight cone (reference §2.4): ``cosθ^tightness · smoothstep(cos falloff, cos radius, cosθ)``.

    Attributes: angles in degrees, measured from the axis ``position → point_at``.
    """

    radius_degrees: Float[Array, ""] = eqx.field(converter=as_float, default=30.0)
    falloff_degrees: Float[Array, ""] = eqx.field(converter=as_float, default=45.0)
    tightness: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)


class AreaLight(eqx.Module):
    """A rectangular grid of ``size1 × size2`` shadow samples spanning ``axis1`` and ``axis2``.

    Only the shadow is area-sampled (diffuse and highlights use the centre), with POV-Ray's
    recursive corner-averaging weights (reference §2.5). ``jitter`` is not simulated (deterministic
    grid), and ``adaptive`` is treated as full subdivision.
    """

    axis1: Float[Array, "3"] = eqx.field(converter=as_float)
    axis2: Float[Array, "3"] = eqx.field(converter=as_float)
    size1: int = eqx.field(static=True)
    size2: int = eqx.field(static=True)
    circular: bool = eqx.field(static=True, default=False)
    orient: bool = eqx.field(static=True, default=False)


class Light(eqx.Module):
    """A POV-Ray ``light_source``.

    Attributes:
        position:      (3,) light position (for ``parallel``, a point the light comes from).
        color:         (3,) RGB irradiance, default white.
        point_at:      (3,) target of parallel lights and spotlights, default <0,0,1> (as POV's code).
        fade_distance, fade_power: optional fading ``2 / (1 + (d/fade_distance)^fade_power)``.
        spot:          spotlight cone, or None.
        area:          area-light shadow sampling, or None.
        parallel:      static; light direction is ``position - point_at`` everywhere.
        shadowless:    static; casts no shadows and makes no highlights.
    """

    position: Float[Array, "3"] = eqx.field(converter=as_float)
    color: Float[Array, "3"] = eqx.field(converter=as_float, default=(1.0, 1.0, 1.0))
    point_at: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 1.0))
    fade_distance: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    fade_power: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    spot: Spot | None = None
    area: AreaLight | None = None
    parallel: bool = eqx.field(static=True, default=False)
    shadowless: bool = eqx.field(static=True, default=False)
