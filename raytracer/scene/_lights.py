"""Light sources: point, parallel and spotlights, optional fading and area (soft-shadow) sampling,
and the one list of light types (:data:`LIGHT_TYPES`) from which the render plan's light effects
and every default are derived.

Colours are used as irradiance directly: no 1/π and no inverse-square falloff (semantics §2.4).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import equinox as eqx
from jaxtyping import Array, Float

from .._dtype import as_float, as_float_or_none

# POV-Ray's defaults, the one place they are written (the SDL parser's records take them from here).
LIGHT_DEFAULTS: Mapping[str, Any] = {"color": (1.0, 1.0, 1.0), "point_at": (0.0, 0.0, 1.0)}
SPOT_DEFAULTS: Mapping[str, Any] = {"radius": 30.0, "falloff": 45.0, "tightness": 0.0}  # degrees


class Spot(eqx.Module):
    """Spotlight cone (semantics §2.4): ``cosθ^tightness · smoothstep(cos falloff, cos radius, cosθ)``.

    Attributes: angles in degrees, measured from the axis ``position → point_at``.
    """

    radius_degrees: Float[Array, ""] = eqx.field(converter=as_float, default=SPOT_DEFAULTS["radius"])
    falloff_degrees: Float[Array, ""] = eqx.field(converter=as_float, default=SPOT_DEFAULTS["falloff"])
    tightness: Float[Array, ""] = eqx.field(converter=as_float, default=SPOT_DEFAULTS["tightness"])


class AreaLight(eqx.Module):
    """A rectangular grid of ``size1 × size2`` shadow samples spanning ``axis1`` and ``axis2``.

    Only the shadow is area-sampled (diffuse and highlights use the centre), with POV-Ray's
    recursive corner-averaging weights (semantics §2.5). ``jitter`` is not simulated (deterministic
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
    color: Float[Array, "3"] = eqx.field(converter=as_float, default=LIGHT_DEFAULTS["color"])
    point_at: Float[Array, "3"] = eqx.field(converter=as_float, default=LIGHT_DEFAULTS["point_at"])
    fade_distance: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    fade_power: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    spot: Spot | None = None
    area: AreaLight | None = None
    parallel: bool = eqx.field(static=True, default=False)
    shadowless: bool = eqx.field(static=True, default=False)


@dataclasses.dataclass(frozen=True)
class LightType:
    """One kind of POV-Ray light source, or one modifier any light may carry, as :class:`Light`
    models it.

    Attributes:
        name:        the SDL keyword (``fade`` stands for ``fade_distance`` with ``fade_power``).
        modifier:    False for the kinds a light is one of (point, spotlight, cylinder); True for
                     what combines with any kind (parallel, area_light, fade, shadowless).
        effects:     the ``Effects`` flags (``raytracer._plan``) the compiled tracer needs when a
                     scene has such a light: absent types cost nothing in the compiled program.
        present:     whether a :class:`Light` is of this type / uses this modifier.
        defaults:    POV-Ray's defaults of the type's own keywords.
        rendered_as: the type it is approximated by, with a parse-time warning (cylinder lights
                     are spotlights), or None when it is rendered as itself.
    """

    name: str
    modifier: bool
    effects: tuple[str, ...]
    present: Callable[[Light], bool]
    defaults: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    rendered_as: str | None = None


LIGHT_TYPES: tuple[LightType, ...] = (
    LightType("point", False, (), lambda light: light.spot is None, LIGHT_DEFAULTS),
    LightType("spotlight", False, ("spotlights",), lambda light: light.spot is not None, SPOT_DEFAULTS),
    LightType("cylinder", False, ("spotlights",), lambda light: light.spot is not None, SPOT_DEFAULTS,
              rendered_as="spotlight"),
    LightType("parallel", True, ("parallel_lights",), lambda light: light.parallel),
    # only the shadow is area-sampled, so a shadowless area light needs no samples
    LightType("area_light", True, ("area_lights",),
              lambda light: light.area is not None and not light.shadowless),
    LightType("fade", True, ("fade",),
              lambda light: light.fade_distance is not None and light.fade_power is not None,
              {"fade_distance": None, "fade_power": None}),
    LightType("shadowless", True, (), lambda light: light.shadowless),
)
"""Every light type and modifier, each with the effects it needs; one entry per POV-Ray keyword."""

LIGHT_EFFECTS: tuple[str, ...] = tuple(dict.fromkeys(e for t in LIGHT_TYPES for e in t.effects))
"""The ``Effects`` flags that only lights decide."""


def light_effects(lights: Iterable[Light]) -> dict[str, bool]:
    """Each flag of :data:`LIGHT_EFFECTS`: whether some light's type needs it (structure only)."""
    lights = tuple(lights)
    return {effect: any(t.present(light) for t in LIGHT_TYPES if effect in t.effects for light in lights)
            for effect in LIGHT_EFFECTS}
