"""``fog`` (semantics §2.8), constant and ground: what the space between surfaces does to the colour a
ray carries."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..._build import Record, build
from ..._dtype import as_float
from ...errors import fmt_number
from ._base import EnvironmentArgs, EnvironmentLowering, EnvironmentType


class Fog(Record):
    """A ``fog``: a ray segment that crosses fog of optical depth ``L`` before its hit (infinitely
    far where it hits nothing) keeps ``a = max(exp(−L/distance), transmit)`` of its colour, tinted
    by the fog's filter, and takes ``1 − a`` of the fog's colour. A constant fog (``ground``
    False) has density 1 everywhere (``L`` is the segment's length); a ground fog (``fog_type
    2``) has density 1 below the height ``offset`` along ``up`` and ``1/(1 + ((h −
    offset)/alt)²)`` above it.

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


def _pack(fogs: tuple[Fog, ...], dtype, pack_pigments) -> tuple[FogArrays, ...]:
    names = ("distance", "color", "offset", "alt", "up")
    return tuple(FogArrays(*(jnp.asarray(getattr(f, k), dtype) for k in names), f.ground) for f in fogs)


def _depth(fog: FogArrays, origin, unit, distance):
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


def _segment(fogs: tuple[FogArrays, ...], origin, unit, distance):
    """``(scale (3,), add (3,))``: a colour ``c`` seen through the fogs along the ray ``origin +
    s·unit`` over ``distance`` (None: infinitely far) is ``c·scale + add``. Each fog keeps ``a =
    max(exp(−L/D), transmit)`` of what lies behind it, L its optical depth there
    (:func:`_depth`), tinted by its filter (``1 − f + f·rgb``), and adds ``(1 − a)·rgb``;
    several fogs multiply what they keep and add what they add, as POV-Ray renders them
    (semantics §2.8)."""
    scale, add = 1.0, 0.0
    for fog in fogs:
        rgb, filt, transmit = fog.color[:3], fog.color[3], fog.color[4]
        depth = _depth(fog, origin, unit, distance)
        finite = jnp.isfinite(depth)
        keep = jnp.where(finite, jnp.exp(-jnp.where(finite, depth, 0.0) / fog.distance), 0.0)
        keep = jnp.maximum(keep, transmit)
        scale = scale * keep * (1 - filt + filt * rgb)
        add = add + (1 - keep) * rgb
    return scale, add


# ---------------------------------------------------------------- SDL
@dataclasses.dataclass
class _Statement:
    """``fog { [FOG_IDENTIFIER] [fog_type 1|2] distance D COLOUR [fog_offset O fog_alt A up V]
    [turbulence …] [transformations] }`` as read (POV-Ray's defaults)."""

    fog_type: int = 1
    distance: float = 0.0
    color: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)
    turbulence: bool = False
    offset: float = 0.0
    alt: float = 0.0
    up: tuple = (0.0, 1.0, 0.0)


_TURBULENCE = ("turbulence", "turb_depth", "omega", "lambda", "octaves")


def _item(args: EnvironmentArgs, fog: _Statement) -> None:
    if args.keyword("distance"):
        fog.distance = args.float()
    elif args.keyword("fog_type"):
        fog.fog_type = int(args.float())
    elif args.keyword("fog_offset"):
        fog.offset = args.float()
    elif args.keyword("fog_alt"):
        fog.alt = args.float()
    elif args.keyword("up"):
        fog.up = args.vector(3)
    elif kw := args.keyword(*_TURBULENCE):  # read; not rendered (``_placed`` warns)
        args.expr()
        fog.turbulence = fog.turbulence or kw == "turbulence"
    elif args.transformation() is not None:  # they move the turbulence and a ground fog's layer only
        pass
    elif args.colour_follows():  # a colour keyword or any colour expression (`White`, `Wheat*.5`)
        fog.color = args.colour()
    else:
        raise args.error(f"expected a fog item (distance, a colour, fog_type, turbulence …), found "
                         f"{args.describe_next()}")


def _placed(args: EnvironmentArgs, fog: _Statement) -> bool:
    """Whether the fog is rendered; warns where it is not, or only in part."""
    if fog.fog_type not in (1, 2):
        args.warn("fog", f"fog_type {fog.fog_type} is not a fog type (1: constant, 2: ground); "
                  "the fog is left out")
        return False
    if not fog.distance > 0:
        args.warn("fog", f"a fog distance of {fmt_number(fog.distance)} hides nothing; the fog is left out")
        return False
    if fog.fog_type == 2 and not (fog.alt > 0 and any(fog.up)):  # (POV-Ray's image is NaN there)
        args.warn("fog", f"a ground fog needs fog_alt > 0 and an up vector (fog_alt {fmt_number(fog.alt)}); "
                  "the fog is left out")
        return False
    if fog.turbulence:
        args.warn("fog", "fog turbulence is not rendered; the fog is smooth")
    return True


def _lower(fog: _Statement, low: EnvironmentLowering) -> Fog:
    up = np.asarray(fog.up, np.float64)
    ground = fog.fog_type == 2
    return build(Fog, distance=fog.distance, color=fog.color, offset=fog.offset,
                 alt=fog.alt if ground else 1.0, up=up / np.linalg.norm(up), ground=ground)


FOG = EnvironmentType("fog", Fog, many=True, pack=_pack, needs_media=True, segment=_segment,
                      sdl_new=_Statement, sdl_item=_item, sdl_placed=_placed, sdl_lower=_lower)
