"""``sky_sphere`` (semantics §2.8): the colour a ray that hits nothing sees, by its direction."""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..._build import Record, build
from ..._dtype import as_float
from .._texture import Pigment
from ._base import EnvironmentArgs, EnvironmentLowering, EnvironmentType


class SkySphere(Record):
    """``sky_sphere``: what a ray that hits nothing sees, as a function of its direction.

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


def _pack(sky: SkySphere, dtype, pack_pigments) -> _SkyArrays:
    return _SkyArrays(pack_pigments(sky.pigments, dtype), jnp.asarray(sky.emission, dtype))


def _miss(sky: _SkyArrays, d, below, pigment_at):
    """The sky's pigments at the unit direction of ``d``, bottom first, each over what lies below as a
    texture layer is (filter multiplies, transmit passes), the opaque part of their colour times
    the emission (as POV-Ray renders it: not the filtered part; semantics §2.8)."""
    u = d / jnp.sqrt(jnp.maximum(jnp.dot(d, d), jnp.finfo(d.dtype).tiny))
    for row in range(len(sky.pigments.pattern_id)):
        rgbft = pigment_at(sky.pigments, row, u)
        rgb, f, t = rgbft[:3], rgbft[3], rgbft[4]
        below = (1 - f - t) * rgb * sky.emission + f * rgb * below + t * below
    return below


# ---------------------------------------------------------------- SDL
@dataclasses.dataclass
class _Statement:
    """``sky_sphere { [SKY_IDENTIFIER] [pigment {…}]… [transformations]… [emission COLOUR] }`` as read:
    the pigments bottom first (as written), the sky's world-from-sky matrix (its transformations,
    wherever they stand among the pigments: they move the whole sky) and its emission."""

    pigments: list = dataclasses.field(default_factory=list)
    transform: Any = None
    emission: tuple = (1.0, 1.0, 1.0)


def _item(args: EnvironmentArgs, sky: _Statement) -> None:
    if args.keyword("pigment"):
        sky.pigments.append(args.pigment())
    elif (m := args.transformation()) is not None:
        sky.transform = m if sky.transform is None else m @ sky.transform
    elif args.keyword("emission"):
        sky.emission = args.colour()[:3]
    else:
        raise args.error(f"expected pigment, a transformation or emission in sky_sphere, found "
                         f"{args.describe_next()}")


def _lower(sky: _Statement, low: EnvironmentLowering) -> SkySphere | None:
    if not sky.pigments:  # without a pigment: the background
        return None
    return build(SkySphere, pigments=tuple(low.pigment(pig, sky.transform) for pig in sky.pigments),
                 emission=sky.emission)


SKY_SPHERE = EnvironmentType("sky_sphere", SkySphere, many=False, pack=_pack,
                             pigments=lambda sky: sky.pigments, miss=_miss,
                             sdl_new=_Statement, sdl_item=_item, sdl_lower=_lower)
