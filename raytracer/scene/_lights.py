"""Light sources: point, parallel and spotlights, optional fading and area (soft-shadow) sampling,
and the one list of light types (:data:`LIGHT_TYPES`) from which the render plan's light effects
and every default are derived.

Colours are used as irradiance directly: no 1/π and no inverse-square falloff (semantics §2.4).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._build import Record
from .._dtype import as_float, as_float_or_none
from ..kernels import safe_div, safe_normalize, safe_pow

# POV-Ray's defaults, the one place they are written (the SDL parser's records take them from here).
LIGHT_DEFAULTS: Mapping[str, Any] = {"color": (1.0, 1.0, 1.0), "point_at": (0.0, 0.0, 1.0)}
SPOT_DEFAULTS: Mapping[str, Any] = {"radius": 30.0, "falloff": 45.0, "tightness": 0.0}  # degrees


class Spot(Record):
    """Spotlight cone (semantics §2.4): ``cosθ^tightness · smoothstep(cos falloff, cos radius, cosθ)``.

    Attributes: angles in degrees, measured from the axis ``position → point_at``.
    """

    radius_degrees: Float[Array, ""] = eqx.field(converter=as_float, default=SPOT_DEFAULTS["radius"])
    falloff_degrees: Float[Array, ""] = eqx.field(converter=as_float, default=SPOT_DEFAULTS["falloff"])
    tightness: Float[Array, ""] = eqx.field(converter=as_float, default=SPOT_DEFAULTS["tightness"])


class AreaLight(Record):
    """A rectangular grid of ``size1 × size2`` shadow samples spanning ``axis1`` and ``axis2``.

    Only the shadow is area-sampled (diffuse and highlights use the centre), with POV-Ray's
    recursive corner-averaging (semantics §2.5): fully subdivided without ``adaptive``; with
    ``adaptive`` N, split N times, then only where a block's corner samples differ
    (:func:`area_blocks`). ``circular`` pulls the grid onto a disc; ``orient`` is parsed and not
    simulated, nor is ``jitter`` (deterministic grid).
    """

    axis1: Float[Array, "3"] = eqx.field(converter=as_float)
    axis2: Float[Array, "3"] = eqx.field(converter=as_float)
    size1: int = eqx.field(static=True)
    size2: int = eqx.field(static=True)
    circular: bool = eqx.field(static=True, default=False)
    orient: bool = eqx.field(static=True, default=False)
    adaptive: int | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.size1 * self.size2 > MAX_AREA_SAMPLES:
            raise ValueError(area_grid_too_large(self.size1, self.size2))


# Samples of one area light's grid. A shading point in a penumbra traces its whole grid at once
# (``_model._adaptive_visibility``; without ``adaptive``, every point does): 256×256 at 160×120 took
# 40 s and 2.2 GB, 512×512 176 s and 7.9 GB, 1024×1024 ran out of memory.
MAX_AREA_SAMPLES = 256 * 256



# POV-Ray's factors on the light arriving (semantics §2.4): the light types' own formulas
def fade(dist, fade_distance, fade_power):
    """``2 / (1 + (dist/fade_distance)^fade_power)``; 1 where fading is off (power or distance 0)."""
    on = (fade_power > 0) & (jnp.abs(fade_distance) > 1e-10)
    ratio = safe_div(dist, jnp.where(on, fade_distance, 1.0))
    return jnp.where(on, 2.0 / (1.0 + safe_pow(jnp.abs(ratio), jnp.where(on, fade_power, 1.0))), 1.0)


def spot(cos_theta, radius_degrees, falloff_degrees, tightness):
    """Spotlight factor ``cosθ^tightness · cubic_spline(cos falloff, cos radius, cosθ)``."""
    lo = jnp.cos(jnp.deg2rad(falloff_degrees))
    hi = jnp.cos(jnp.deg2rad(radius_degrees))
    span = hi - lo
    s = jnp.clip(safe_div(cos_theta - lo, jnp.where(span > 0, span, 1.0)), 0.0, 1.0)
    smooth = jnp.where(cos_theta >= hi, 1.0, jnp.where(cos_theta < lo, 0.0, (3 - 2 * s) * s * s))
    c = jnp.maximum(cos_theta, 0.0)
    tight = jnp.where(tightness != 0, safe_pow(c, tightness), 1.0)
    return jnp.where(cos_theta > 0, tight * smooth, 0.0)

def area_grid_too_large(n1: int, n2: int) -> str:
    return (f"an area_light grid of {n1}×{n2} = {n1 * n2:,} samples is more than this renderer "
            f"holds ({MAX_AREA_SAMPLES:,} per light, e.g. 256×256): every sample of a point in a "
            "penumbra is traced at once")


class Light(Record):
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


def point_geometry(light: Light, p):
    """Unit direction from ``p`` to the light, its distance (for fading), and the shadow-ray length."""
    v = light.position - p
    dist = jnp.sqrt(jnp.maximum(jnp.dot(v, v), 1e-30))
    return v / dist, dist, dist


def _parallel_geometry(light: Light, p):
    l = safe_normalize(light.position - light.point_at)
    to_light = light.position - p
    dist = jnp.sqrt(jnp.maximum(jnp.dot(to_light, to_light), 1e-30))
    return l, dist, jnp.dot(l, to_light)  # objects beyond the light's plane cast no shadow


def _fade_factor(light: Light, l, dist):
    return fade(dist, light.fade_distance, light.fade_power)


def _spot_factor(light: Light, l, dist):
    axis = safe_normalize(light.point_at - light.position)
    return spot(jnp.dot(-l, axis), light.spot.radius_degrees, light.spot.falloff_degrees,
                         light.spot.tightness)


def _lower_fade(values, linear):
    return {"fade_distance": values["fade_distance"], "fade_power": values["fade_power"]}


def _lower_spot(values, linear):
    return {"spot": Spot(values["radius"], values["falloff"], values["tightness"])}


def _lower_area(values, linear):
    if values["area_light"] is None:  # circular, adaptive, ... without area_light: a point light
        return {}
    a1, a2, n1, n2 = values["area_light"]
    a1, a2 = np.asarray(a1, np.float64), np.asarray(a2, np.float64)
    if linear is not None:
        a1, a2 = linear @ a1, linear @ a2
    adaptive = values["adaptive"]
    if adaptive is not None:  # an int, at least 0 (POV-Ray's manual); past the grid's depth: full
        adaptive = int(min(max(adaptive, 0.0), MAX_ADAPTIVE))
    return {"area": AreaLight(a1, a2, n1, n2, circular=values["circular"], orient=values["orient"],
                              adaptive=adaptive)}


MAX_ADAPTIVE = 64  # deeper than any grid's recursion (sizes are at most 4096)


def area_weights(n: int) -> np.ndarray:
    """POV's recursive corner-averaging weights along one area-light axis (semantics §2.5):
    3 samples → ¼ ½ ¼, 5 → ⅛ ¼ ¼ ¼ ⅛, 4 → uniform."""
    w = np.zeros(n)

    def rec(a, b, weight):
        if b - a <= 1:
            w[a] += weight / 2
            w[b] += weight / 2
            return
        m = (a + b) / 2
        rec(a, int(np.floor(m)), weight / 2)
        rec(int(np.ceil(m)), b, weight / 2)

    if n == 1:
        w[0] = 1.0
    else:
        rec(0, n - 1, 1.0)
    return w


@dataclasses.dataclass(frozen=True)
class AreaBlock:
    """A block of an area light's grid in POV-Ray's recursion (semantics §2.5): its value is the
    mean of its four corner samples, or, once split, the mean of its children's values.

    corners:  the grid indices ``u·size2 + v`` of its corners (repeated on an axis of width 0).
    children: the blocks it splits into (each axis wider than 1 is split at the floor and ceil of
              its midpoint), or () for a leaf.
    """

    corners: tuple[int, int, int, int]
    children: tuple[AreaBlock, ...]


@functools.cache
def area_blocks(n1: int, n2: int) -> AreaBlock:
    """The recursion tree of an ``n1 × n2`` grid; fully subdivided, its leaves' corner means give
    :func:`area_weights` per axis."""

    def halves(lo, hi):
        if hi - lo <= 1:
            return [(lo, hi)]
        m = (lo + hi) / 2
        return [(lo, int(np.floor(m))), (int(np.ceil(m)), hi)]

    def block(r1, r2):
        corners = tuple(u * n2 + v for u in r1 for v in r2)
        children = ()
        if r1[1] - r1[0] > 1 or r2[1] - r2[0] > 1:
            children = tuple(block(c1, c2) for c1 in halves(*r1) for c2 in halves(*r2))
        return AreaBlock(corners, children)

    return block((0, n1 - 1), (0, n2 - 1))


CIRCULAR_OFFSET = 0.002  # POV-Ray 3.7 shifts a circular grid by this (in [-1, 1]² units; measured)


def _area_samples(light: Light, dtype):
    """The grid of shadow-ray targets and their weights (semantics §2.5): point (i, j) at
    centre + axis1 (i/(n1-1) - ½) + axis2 (j/(n2-1) - ½); with ``circular``, each point's offset
    (a, b) in [-1, 1]² (plus ``CIRCULAR_OFFSET``) is scaled by max(|a|, |b|)/√(a² + b²), onto the
    disc the square grid is inscribed in."""
    a = light.area
    w1, w2 = area_weights(a.size1), area_weights(a.size2)
    f1 = np.zeros(1) if a.size1 == 1 else np.arange(a.size1) / (a.size1 - 1) - 0.5
    f2 = np.zeros(1) if a.size2 == 1 else np.arange(a.size2) / (a.size2 - 1) - 0.5
    fu, fv = (g.reshape(-1) for g in np.meshgrid(f1, f2, indexing="ij"))
    if a.circular:  # the square grid pulled radially onto the disc it is inscribed in (semantics §2.5)
        fu, fv = fu + CIRCULAR_OFFSET / 2, fv + CIRCULAR_OFFSET / 2  # (fu, fv) are half the square's
        r_square, r_disc = np.maximum(np.abs(fu), np.abs(fv)), np.hypot(fu, fv)
        shrink = np.divide(r_square, r_disc, out=np.ones_like(r_disc), where=r_disc > 0)
        fu, fv = fu * shrink, fv * shrink
    weights = jnp.asarray(np.outer(w1, w2).reshape(-1), dtype)
    positions = (light.position[None, :] + jnp.asarray(fu, dtype)[:, None] * a.axis1[None, :]
                 + jnp.asarray(fv, dtype)[:, None] * a.axis2[None, :])
    return positions, weights


@dataclasses.dataclass(frozen=True)
class LightType:
    """One kind of POV-Ray light source, or one modifier any light may carry, as :class:`Light`
    models it, with everything the rest of the system asks of it.

    Attributes:
        name:        the SDL keyword (``fade`` stands for ``fade_distance`` with ``fade_power``).
        modifier:    False for the kinds a light is one of (point, spotlight, cylinder); True for
                     what combines with any kind (parallel, area_light, fade, shadowless).
        effects:     the ``Effects`` flags (``raytracer._plan``) the compiled tracer needs when a
                     scene has such a light: absent types cost nothing in the compiled program.
        present:     whether a :class:`Light` is of this type / uses this modifier (structure only).
        defaults:    POV-Ray's defaults of the type's own keywords.
        rendered_as: the type it is approximated by, with a parse-time warning (cylinder lights
                     are spotlights), or None when it is rendered as itself (only those shade).
        geometry:    ``(light, p) → (l, dist, shadow_len)``: unit direction to the light, distance
                     for fading, shadow-ray length; replaces :func:`point_geometry`, or None.
        arrival:     ``(light, l, dist) → factor`` the arriving colour is multiplied by, or None;
                     factors apply in the order of :data:`LIGHT_TYPES`.
        shadow_samples: ``(light, dtype) → (positions (N, 3), weights (N,))``: the shadow is the
                     weighted sum of shadow rays to these points instead of one to the light.
        shadows:     False when such a light casts no shadows and makes no highlights.
        describe:    ``light → str`` for summaries (``raytracer info``), or None for the name.
        sdl_keywords: the ``light_source`` items the type owns → how each is read: ``"kind"`` (the
                     bare keyword makes the light this type), ``"flag"`` (bare keyword: True),
                     ``"float"``, ``"float?"`` (an optional float, read and not used), or a tuple
                     of ``"vector"`` / ``"size"`` (an area-light sample count) read comma-separated.
                     Position, colour and ``point_at`` belong to every light, not to a type.
        lower:       ``(values, linear) → Light fields``: the type's fields from its keywords'
                     values (POV-Ray's ``defaults`` filled in) and the light's 3×3 linear
                     transform (or None). Called for a kind when the light is of it, for a modifier
                     when one of its keywords was given.
    """

    name: str
    modifier: bool
    effects: tuple[str, ...]
    present: Callable[[Light], bool]
    defaults: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    rendered_as: str | None = None
    geometry: Callable[[Light, Any], tuple] | None = None
    arrival: Callable[[Light, Any, Any], Any] | None = None
    shadow_samples: Callable[[Light, Any], tuple] | None = None
    shadows: bool = True
    describe: Callable[[Light], str] | None = None
    sdl_keywords: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    lower: Callable[[Mapping[str, Any], Any], Mapping[str, Any]] | None = None


_SPOT_KEYWORDS = {"radius": "float", "falloff": "float", "tightness": "float"}

LIGHT_TYPES: tuple[LightType, ...] = (
    LightType("point", False, (), lambda light: light.spot is None, LIGHT_DEFAULTS),
    # before the spotlight: the arriving colour is faded, then cut by the cone
    LightType("fade", True, ("fade",),
              lambda light: light.fade_distance is not None and light.fade_power is not None,
              {"fade_distance": None, "fade_power": None}, arrival=_fade_factor,
              sdl_keywords={"fade_distance": "float", "fade_power": "float"}, lower=_lower_fade),
    LightType("spotlight", False, ("spotlights",), lambda light: light.spot is not None, SPOT_DEFAULTS,
              arrival=_spot_factor, sdl_keywords={"spotlight": "kind", **_SPOT_KEYWORDS},
              lower=_lower_spot),
    LightType("cylinder", False, ("spotlights",), lambda light: light.spot is not None, SPOT_DEFAULTS,
              rendered_as="spotlight", sdl_keywords={"cylinder": "kind", **_SPOT_KEYWORDS},
              lower=_lower_spot),
    LightType("parallel", True, ("parallel_lights",), lambda light: light.parallel,
              geometry=_parallel_geometry, sdl_keywords={"parallel": "flag"},
              lower=lambda values, linear: {"parallel": True}),
    # only the shadow is area-sampled, so a shadowless area light needs no samples; jitter is not
    # simulated (a deterministic grid), so it is read and unused
    LightType("area_light", True, ("area_lights",),
              lambda light: light.area is not None and not light.shadowless, shadow_samples=_area_samples,
              describe=lambda light: f"area {light.area.size1}x{light.area.size2}"
              + ("" if light.area.adaptive is None else f" adaptive {light.area.adaptive}"),
              defaults={"area_light": None, "circular": False, "orient": False, "adaptive": None},
              sdl_keywords={"area_light": ("vector", "vector", "size", "size"), "circular": "flag",
                            "orient": "flag", "adaptive": "float?", "jitter": "float?",
                            "area_illumination": "float?"},
              lower=_lower_area),
    LightType("shadowless", True, (), lambda light: light.shadowless, shadows=False,
              sdl_keywords={"shadowless": "flag"}, lower=lambda values, linear: {"shadowless": True}),
)
"""Every light type and modifier, each with the effects it needs; one entry per POV-Ray keyword."""

UNSIMULATED_LIGHT_KEYWORDS: Mapping[str, str] = {
    "jitter": "area-light jitter is not simulated (the sample grid stays regular)",
    "orient": "area-light orient is not simulated (the grid keeps its axes)",
    "area_illumination": "area_illumination is not simulated (diffuse and highlights come from the "
                         "light's centre)",
}
"""``light_source`` items that are read and change nothing (semantics §2.5): the parser warns when
one is given (``area_illumination`` only when on)."""

LIGHT_EFFECTS: tuple[str, ...] = tuple(dict.fromkeys(e for t in LIGHT_TYPES for e in t.effects))
"""The ``Effects`` flags that only lights decide."""


def _keyword_table() -> dict[str, tuple[LightType, Any]]:
    table: dict[str, tuple[LightType, Any]] = {}
    for t in LIGHT_TYPES:
        for keyword, how in t.sdl_keywords.items():
            if keyword in table and table[keyword][1] != how:
                raise AssertionError(f"light keyword {keyword!r} is read two ways")
            table.setdefault(keyword, (t, how))
    return table


LIGHT_SDL_KEYWORDS: Mapping[str, tuple[LightType, Any]] = _keyword_table()
"""``light_source`` item → (the first type that owns it, how it is read); shared keywords (a
spotlight's and a cylinder light's ``radius``) are read the same way."""


def light_fields(kind: str, values: Mapping[str, Any], linear=None) -> dict[str, Any]:
    """The :class:`Light` fields its types give a parsed light: ``kind`` names the non-modifier
    type, ``values`` maps the ``light_source`` items given to their values, ``linear`` is the
    light's 3×3 linear transform or None."""
    fields: dict[str, Any] = {}
    for t in LIGHT_TYPES:
        given = {k: values[k] for k in t.sdl_keywords if k in values}
        chosen = bool(given) if t.modifier else t.name == kind
        if t.lower is not None and chosen:
            fields.update(t.lower({**t.defaults, **given}, linear))
    return fields


def light_types(light: Light, effects: Any = None) -> tuple[LightType, ...]:
    """The entries of :data:`LIGHT_TYPES` a light is of or carries (those rendered as another type
    left out), all of whose ``effects`` are on in ``effects`` (a plan's ``Effects``) when given."""
    return tuple(t for t in LIGHT_TYPES if t.rendered_as is None and t.present(light)
                 and (effects is None or all(getattr(effects, e) for e in t.effects)))


def light_effects(lights: Iterable[Light]) -> dict[str, bool]:
    """Each flag of :data:`LIGHT_EFFECTS`: whether some light's type needs it (structure only)."""
    lights = tuple(lights)
    return {effect: any(t.present(light) for t in LIGHT_TYPES if effect in t.effects for light in lights)
            for effect in LIGHT_EFFECTS}
