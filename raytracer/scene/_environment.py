"""Environment effects: what a ray sees beyond every object, and what the space between surfaces does
to the light a ray carries. One record per effect (``ENVIRONMENT``), as ``LIGHT_TYPES`` is for
lights: the plan, the shading model and the image of a scene without objects apply the entries a
scene switches on, without naming one.

Each entry declares its scene field, the ``Effects`` name it turns on, the pigments it evaluates (so
the plan compiles their patterns), whether it must know if a ray is inside an object, how its value
packs into the arrays the program reads, and its two behaviours: ``miss``, the colour a ray that
hits nothing sees over what lies below it (the background, or the entries before it), and
``segment``, what a ray segment of a given length does to the colour it carries (``c·scale + add``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._build import Record
from .._dtype import as_float
from ._texture import Pigment


# ---------------------------------------------------------------- sky_sphere
class SkySphere(Record):
    """``sky_sphere`` (semantics §2.8): the colour a ray that hits nothing sees, as a function of its
    direction.

    Attributes:
        pigments: layered bottom first: each later pigment lies on top, through its filter and
                  transmit as texture layers are, and the scene's background shows through the
                  bottom one. Each is evaluated at the ray's unit direction, in world space (the
                  ``sky_sphere``'s own transformations are part of each pigment's transform).
        emission: (3,) multiplies the opaque part of each pigment's colour (not what its filter
                  and transmit let through).
    """

    pigments: tuple[Pigment, ...] = ()
    emission: Float[Array, "3"] = eqx.field(converter=as_float, default=(1.0, 1.0, 1.0))


class _SkyArrays(NamedTuple):
    pigments: Any  # the pigments packed (shading's ``pack_pigments``), rows bottom first
    emission: jax.Array  # (3,)


def _pack_sky(sky: SkySphere, dtype, pack_pigments) -> _SkyArrays:
    return _SkyArrays(pack_pigments(sky.pigments, dtype), jnp.asarray(sky.emission, dtype))


def _sky_miss(sky: _SkyArrays, d, below, pigment_at):
    """The sky's pigments at the unit direction of ``d``, bottom first, each over what lies below as a
    texture layer is (filter multiplies, transmit passes), the opaque part of their colour times
    the emission (as POV-Ray renders it: not the filtered part; semantics §2.8)."""
    u = d / jnp.sqrt(jnp.maximum(jnp.dot(d, d), jnp.finfo(d.dtype).tiny))
    for row in range(len(sky.pigments.pattern_id)):
        rgbft = pigment_at(sky.pigments, row, u)
        rgb, f, t = rgbft[:3], rgbft[3], rgbft[4]
        below = (1 - f - t) * rgb * sky.emission + f * rgb * below + t * below
    return below


# ---------------------------------------------------------------- fog
class Fog(Record):
    """A ``fog`` (semantics §2.8): a ray segment that crosses fog of optical depth ``L`` before
    its hit (infinitely far where it hits nothing) keeps ``a = max(exp(−L/distance), transmit)`` of
    its colour, tinted by the fog's filter, and takes ``1 − a`` of the fog's colour. A constant fog
    (``ground`` False) has density 1 everywhere (``L`` is the segment's length); a ground fog
    (``fog_type 2``) has density 1 below the height ``offset`` along ``up`` and
    ``1/(1 + ((h − offset)/alt)²)`` above it.

    Attributes:
        distance: () the distance at which ``exp(−L/distance)`` is 1/e.
        color:    (5,) RGBFT: the fog's colour, its filter and its transmit.
        offset:   () a ground fog's height of full density (``fog_offset``).
        alt:      () the height over it at which the density is halved (``fog_alt``).
        up:       (3,) the direction of height (unit).
        ground:   static: a ground fog.
    """

    distance: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    color: Float[Array, "5"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0, 0.0, 0.0))
    offset: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    alt: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    up: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 1.0, 0.0))
    ground: bool = eqx.field(static=True, default=False)


class FogArrays(NamedTuple):
    """A ``Fog`` as the shading reads it: its arrays in the working dtype, ``ground`` static."""

    distance: jax.Array
    color: jax.Array
    offset: jax.Array
    alt: jax.Array
    up: jax.Array
    ground: bool


def _pack_fogs(fogs: tuple[Fog, ...], dtype, pack_pigments) -> tuple[FogArrays, ...]:
    names = ("distance", "color", "offset", "alt", "up")
    return tuple(FogArrays(*(jnp.asarray(getattr(f, k), dtype) for k in names), f.ground) for f in fogs)


def _fog_depth(fog: FogArrays, origin, unit, distance):
    """The optical depth along the ray ``origin + s·unit`` (``unit`` a unit vector) for ``s`` in [0,
    ``distance``] (None: to infinity; then ``inf`` where the ray does not climb out of a ground fog):
    the length for a constant fog; for a ground fog the integral of its density, by its
    antiderivative over the height ``h``: ``h − offset`` below the offset, ``alt·atan((h −
    offset)/alt)`` above (semantics §2.8)."""
    if not fog.ground:
        return jnp.inf if distance is None else distance

    def antiderivative(h):
        u = (h - fog.offset) / fog.alt
        return jnp.where(u < 0, h - fog.offset, fog.alt * jnp.arctan(jnp.maximum(u, 0.0)))

    def density(h):
        u = jnp.maximum((h - fog.offset) / fog.alt, 0.0)
        return 1 / (1 + u * u)

    h0, climb = jnp.dot(origin, fog.up), jnp.dot(unit, fog.up)
    level = jnp.abs(climb) < 1e-6
    safe = jnp.where(level, 1.0, climb)
    if distance is None:
        # to infinity: up and out of it (the antiderivative tends to alt·π/2), else all of it
        out = (fog.alt * (jnp.pi / 2) - antiderivative(h0)) / safe
        return jnp.where(climb > 1e-6, out, jnp.inf)
    across = (antiderivative(h0 + climb * distance) - antiderivative(h0)) / safe
    return jnp.where(level, distance * density(h0), across)


def _fog_segment(fogs: tuple[FogArrays, ...], origin, unit, distance):
    """``(scale (3,), add (3,))``: a colour ``c`` seen through the fogs along the ray ``origin +
    s·unit`` over ``distance`` (None: infinitely far) is ``c·scale + add``. Each fog keeps ``a =
    max(exp(−L/D), transmit)`` of what lies behind it, L its optical depth there
    (:func:`_fog_depth`), tinted by its filter (``1 − f + f·rgb``), and adds ``(1 − a)·rgb``;
    several fogs multiply what they keep and add what they add, as POV-Ray renders them
    (semantics §2.8)."""
    scale, add = 1.0, 0.0
    for fog in fogs:
        rgb, filt, transmit = fog.color[:3], fog.color[3], fog.color[4]
        depth = _fog_depth(fog, origin, unit, distance)
        finite = jnp.isfinite(depth)
        keep = jnp.where(finite, jnp.exp(-jnp.where(finite, depth, 0.0) / fog.distance), 0.0)
        keep = jnp.maximum(keep, transmit)
        scale = scale * keep * (1 - filt + filt * rgb)
        add = add + (1 - keep) * rgb
    return scale, add


# ---------------------------------------------------------------- the record
@dataclasses.dataclass(frozen=True)
class EnvironmentType:
    """One environment effect, with everything the rest of the system asks of it.

    Attributes:
        name:        the ``Effects.environment`` name it turns on, and its SDL keyword.
        field:       the ``Scene`` field that holds it: one value or None (``many`` False), or a
                     tuple of values (``many`` True); the effect is on when it is set or not empty.
        many:        see ``field``.
        pigments:    ``value → pigments`` it evaluates (the plan compiles their patterns), or None.
        needs_media: its rays must know whether they are inside an object (the plan then keeps
                     every ray's interior list where the scene has transmission).
        pack:        ``(value, dtype, pack_pigments) → arrays``: what the program reads of it.
        miss:        ``(arrays, d, below, pigment_at) → (3,)``: the colour a ray of direction ``d``
                     that hits nothing sees over ``below``, or None (it shows ``below``).
        segment:     ``(arrays, origin, unit, distance or None) → (scale, add)``: a colour ``c``
                     carried along ``origin + s·unit`` over ``distance`` (None: infinitely far)
                     arrives as ``c·scale + add``; or None (it changes nothing). A ray inside an
                     object is not changed.
    """

    name: str
    field: str
    many: bool
    pack: Callable
    pigments: Callable | None = None
    needs_media: bool = False
    miss: Callable | None = None
    segment: Callable | None = None

    def value(self, scene):
        """The scene's value of this effect, or None when the effect is off."""
        v = getattr(scene, self.field)
        return (v or None) if self.many else v


ENVIRONMENT: tuple[EnvironmentType, ...] = (
    EnvironmentType("sky_sphere", "sky_sphere", many=False, pack=_pack_sky,
                    pigments=lambda sky: sky.pigments, miss=_sky_miss),
    EnvironmentType("fog", "fogs", many=True, pack=_pack_fogs, needs_media=True, segment=_fog_segment),
)
"""Every environment effect, in the order they apply: a miss's colour from the first to the last
(each over the one before it, the background at the bottom), and a segment's too (the first acts on
the carried colour first)."""


def environment_of(scene) -> tuple[tuple[EnvironmentType, Any], ...]:
    """The effects the scene switches on, each with its value."""
    return tuple((e, v) for e in ENVIRONMENT if (v := e.value(scene)) is not None)
