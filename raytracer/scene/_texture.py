"""Textures: pigment (pattern + colour map), finish, interior — plain data; behaviour lives in
``raytracer.shading`` (as Lajolla separates materials from their evaluation).

Colours are 5-vectors ``(r, g, b, filter, transmit)``. Optional effects (reflection, phong,
specular, metallic, refraction) are ``None`` when the scene does not ask for them, so the render
plan can leave them out of the compiled program; a value of zero is still a parameter.
"""

from __future__ import annotations

import equinox as eqx
import numpy as np
from jaxtyping import Array, Float

from .. import patterns
from .._build import Record
from .._dtype import as_float, as_float_or_none
from ._transform import Transform

PATTERNS = patterns.NAMES  # every registered pattern (some are parsed but not rendered: the plan warns)
WAVES = patterns.WAVES


def _rgbft(c) -> np.ndarray:
    c = np.asarray(c, dtype=np.float64)
    if c.shape[-1] == 3:
        c = np.concatenate([c, np.zeros(c.shape[:-1] + (2,))], axis=-1)
    return c


MAP_TYPES = {0: "planar", 1: "spherical", 2: "cylindrical"}  # image_map's map_type: those we render


class ImageMap(Record):
    """``image_map``'s image and how it wraps the pattern space (semantics §5.6).

    Attributes:
        pixels:      (H, W, 5) linear RGBFT, the image's top row first.
        map_type:    static: 0 planar (the unit square of x-y, repeated), 1 spherical, 2 cylindrical.
        once:        static: outside the unit square (planar, cylindrical's height) the pigment is
                     clear (transmit 1).
        interpolate: static: 0 the nearest pixel, 2 bilinear between pixel centres.
    """

    pixels: Float[Array, "H W 5"] = eqx.field(converter=as_float)
    map_type: int = eqx.field(static=True, default=0)
    once: bool = eqx.field(static=True, default=False)
    interpolate: int = eqx.field(static=True, default=0)

    def __check_init__(self):
        if self.pixels.ndim != 3 or self.pixels.shape[-1] != 5:
            raise ValueError("an image map's pixels are (H, W, 5) RGBFT")
        if self.map_type not in MAP_TYPES:
            raise ValueError(f"map_type {self.map_type} is not one of {sorted(MAP_TYPES)}")


class Pigment(Record):
    """A pattern evaluated at the hit point and mapped through a colour map (semantics §5.2).

    Attributes:
        pattern:     static name, a key of ``raytracer.patterns.REGISTRY`` (``PATTERNS``).
        values:      (M,) colour-map positions, ascending ([0, 1] for continuous patterns). A
                     discrete pattern does not read them: it picks its list entry by index.
        colors:      (M, 5) colour-map entries, RGBFT. A solid pigment has M = 1; a discrete pattern
                     (checker, hexagon, brick) has its listed colours, chosen by the indices 0, 1, ….
        transform:   ``world_from_pattern``; the pattern sees the inverse-transformed hit point.
        vector:      (3,) pattern direction (``gradient``'s vector), unused by others.
        frequency, phase: the value is ``fmod(v·frequency + phase, 1.00001)`` unless frequency is 0.
                     None: POV-Ray's default, 1, or for a discrete pattern (whose value is the index
                     of its colour) 0: POV-Ray wraps an index only where the scene writes a
                     ``frequency`` (measured, semantics §5.2).
        turbulence:  (3,) amount, or None; ``octaves`` (static), ``omega``, ``lambda_``.
        wave:        static wave function name.
        transparent: static: whether any colour carries filter or transmit (enables transmission).
        entries:     a ``pigment_map`` (or a discrete pattern's pigment list): the pigments at the
                     map's positions ``values``, each evaluated at the hit and blended as a colour
                     map blends colours (``colors`` are then unused); None for a colour map.
                     Their transforms are world_from_pattern, the outer pigment's included.
        image:       the ``image_map`` pattern's image (``ImageMap``); None for other patterns.
    """

    pattern: str = eqx.field(static=True)
    values: Float[Array, " M"] = eqx.field(converter=as_float)
    colors: Float[Array, "M 5"] = eqx.field(converter=as_float)
    transform: Transform | None = None
    vector: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 1.0, 0.0))
    frequency: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    phase: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)
    turbulence: Float[Array, "3"] | None = eqx.field(converter=as_float_or_none, default=None)
    omega: Float[Array, ""] = eqx.field(converter=as_float, default=0.5)
    lambda_: Float[Array, ""] = eqx.field(converter=as_float, default=2.0)
    octaves: int = eqx.field(static=True, default=6)
    wave: str = eqx.field(static=True, default="ramp")
    transparent: bool = eqx.field(static=True, default=False)
    entries: tuple[Pigment, ...] | None = None
    image: ImageMap | None = None

    def __check_init__(self):
        if self.pattern not in PATTERNS:
            raise ValueError(f"unknown pattern {self.pattern!r}")
        if patterns.REGISTRY[self.pattern].imaged != (self.image is not None):
            raise ValueError("an image_map pigment, and only one, has an image")
        if self.entries is not None and len(self.entries) != self.values.shape[0]:
            raise ValueError("a pigment map has one pigment per position in values")
        if self.wave not in WAVES:
            raise ValueError(f"unknown wave {self.wave!r}")
        if self.colors.ndim != 2 or self.colors.shape[-1] != 5 or self.values.shape != self.colors.shape[:1]:
            raise ValueError("colors must be (M, 5) and values (M,)")
        if not self.transparent and isinstance(self.colors, np.ndarray) and np.any(self.colors[:, 3:] != 0):
            # an opaque pigment's filter and transmit are 0 in the program (docs/gradients.md)
            raise ValueError("colors carry filter or transmit, but the pigment is not transparent: "
                             "pass transparent=True to render them")

    @classmethod
    def solid(cls, rgb, filter=None, transmit=None) -> Pigment:  # noqa: A002 - POV's name
        """A single colour; passing ``filter`` or ``transmit`` (even 0) makes it transparent-capable."""
        c = np.zeros(5)
        c[:3] = np.broadcast_to(np.asarray(rgb, dtype=np.float64), (3,))
        c[3] = 0.0 if filter is None else filter
        c[4] = 0.0 if transmit is None else transmit
        return cls("solid", values=[0.0], colors=c[None, :],
                   transparent=filter is not None or transmit is not None)

    @classmethod
    def checker(cls, color1, color2, transform: Transform | None = None) -> Pigment:
        c = np.stack([_rgbft(color1), _rgbft(color2)])
        return cls("checker", values=[0.0, 1.0], colors=c, transform=transform, frequency=0.0,
                   transparent=bool(np.any(c[:, 3:] != 0)))

    @classmethod
    def of_map(cls, pattern: str, pigment_map, **kwargs) -> Pigment:
        """A pattern with a pigment map given as ``[(value, Pigment), ...]`` (a discrete pattern:
        its list, at the positions 0, 1, …)."""
        values = np.array([v for v, _ in pigment_map], dtype=np.float64)
        entries = tuple(pg for _, pg in pigment_map)
        kwargs.setdefault("transparent", any(pg.transparent for pg in entries))
        return cls(pattern, values=values, colors=np.zeros((len(entries), 5)), entries=entries, **kwargs)

    def pigments(self):
        """This pigment and, for a map, every pigment in it (depth first)."""
        yield self
        for entry in self.entries or ():
            yield from entry.pigments()

    @classmethod
    def mapped(cls, pattern: str, color_map, **kwargs) -> Pigment:
        """A pattern with a colour map given as ``[(value, rgb or rgbft), ...]``."""
        values = np.array([v for v, _ in color_map], dtype=np.float64)
        colors = np.stack([_rgbft(c) for _, c in color_map])
        kwargs.setdefault("transparent", bool(np.any(colors[:, 3:] != 0)))
        return cls(pattern, values=values, colors=colors, **kwargs)


class Reflection(Record):
    """``reflection { min, max [fresnel] falloff exponent metallic }`` (semantics §2.6). The
    ``metallic`` tint is absent when None (not compiled); a value of 0 is still a parameter."""

    min: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0))
    max: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0))
    falloff: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    exponent: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    metallic: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    fresnel: bool = eqx.field(static=True, default=False)


class Finish(Record):
    """POV-Ray ``finish`` (defaults from semantics §2.1). Highlight terms are absent when None."""

    ambient: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.1, 0.1, 0.1))
    emission: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0))
    diffuse: Float[Array, ""] = eqx.field(converter=as_float, default=0.6)
    brilliance: Float[Array, ""] = eqx.field(converter=as_float, default=1.0)
    phong: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    phong_size: Float[Array, ""] = eqx.field(converter=as_float, default=40.0)
    specular: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    roughness: Float[Array, ""] = eqx.field(converter=as_float, default=0.05)
    metallic: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    reflection: Reflection | None = None
    conserve_energy: bool = eqx.field(static=True, default=False)


class Interior(Record):
    """``interior``: index of refraction (None = 1, straight transmission) and fading (semantics §2.7)."""

    ior: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    fade_distance: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    fade_power: Float[Array, ""] | None = eqx.field(converter=as_float_or_none, default=None)
    fade_color: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0))


class Normal(Record):
    """``normal { pattern amount … }``: a perturbation of the surface normal (semantics §5.5).

    Attributes:
        pattern:  the pattern, its space and its value as a pigment holds them (``pattern``,
                  ``transform``, ``vector``, ``frequency``, ``phase``, ``wave``, turbulence); its
                  colours play no part. The perturbation is computed in the pattern's space from the
                  pattern's value at four points of a tetrahedron around the hit (``accuracy`` from
                  it), as POV-Ray measures: ``bumps``, ``dents``, ``wrinkles``, ``ripples`` and
                  ``waves`` use their raw value at a fixed spacing and their own gain.
        amount:   the depth of the bumps (``bump_size``; POV-Ray's default 0.5); negative inverts.
        accuracy: the tetrahedron's size in pattern space (POV-Ray's default 0.02).
        slope_map: (K, 3) ``[value, height, slope]`` rows, ascending in value: the height of the
                  pattern's value, a cubic Hermite curve through each entry's height whose tangent
                  in each segment's own parameter is the entry's slope (POV-Ray's, measured); None:
                  the value is the height.
    """

    pattern: Pigment
    amount: Float[Array, ""] = eqx.field(converter=as_float, default=0.5)
    accuracy: Float[Array, ""] = eqx.field(converter=as_float, default=0.02)
    slope_map: Float[Array, "K 3"] | None = eqx.field(converter=as_float_or_none, default=None)

    @classmethod
    def of(cls, pattern: str, amount=0.5, **kwargs) -> Normal:
        """A normal of pattern ``pattern`` with the pigment fields ``kwargs`` (``transform``,
        ``vector``, ``frequency``, ``turbulence`` …) and ``accuracy``."""
        accuracy = kwargs.pop("accuracy", 0.02)
        slope_map = kwargs.pop("slope_map", None)
        black_to_white = [(0.0, (0.0, 0.0, 0.0)), (1.0, (1.0, 1.0, 1.0))]  # (unused by a normal)
        return cls(Pigment.mapped(pattern, black_to_white, **kwargs), amount, accuracy, slope_map)


class Layer(Record):
    """One texture layer: a pigment, a finish and, if it has one, a normal perturbation."""

    pigment: Pigment = eqx.field(default_factory=lambda: Pigment.solid((0.0, 0.0, 0.0)))
    finish: Finish = eqx.field(default_factory=Finish)
    normal: Normal | None = None


class Texture(Record):
    """A stack of layers, top layer first (``layers[0]``), or a patterned texture: a pattern
    choosing among whole textures (semantics §5.7).

    Attributes:
        layers:  the layers, top first. Most textures have one layer. A patterned texture's are its
                 first plain entry's: what a shadow ray crossing it filters by (POV-Ray blends its
                 entries there too; semantics §5.7 says what differs).
        pattern: a patterned texture's pattern, its space and its value as a pigment holds them
                 (``pattern``, ``transform``, ``frequency``, ``wave``, turbulence …; ``values`` the
                 map's positions: ``texture_map``'s, or 0, 1, … for a block pattern's list); its
                 colours play no part. None for a plain texture.
        entries: a patterned texture's textures, one per position of ``pattern.values``; each may be
                 patterned itself. At a point the pattern's value falls between two positions and
                 the two textures there are each shaded in full, mirror and transmitted rays
                 included, and their colours blended linearly (POV-Ray's rule, manual 3.4.6.5.1);
                 a block pattern (checker, brick, hexagon …) takes one entry by its index.
    """

    layers: tuple[Layer, ...] = eqx.field(default_factory=lambda: (Layer(),))
    pattern: Pigment | None = None
    entries: tuple[Texture, ...] | None = None

    def __check_init__(self):
        if not self.layers:
            raise ValueError("a texture needs at least one layer")
        if (self.pattern is None) != (self.entries is None):
            raise ValueError("a patterned texture has both a pattern and its entries")
        if self.entries is not None and len(self.entries) != self.pattern.values.shape[0]:
            raise ValueError("a patterned texture has one texture per position in its pattern's values")

    @classmethod
    def of(cls, pigment: Pigment | None = None, finish: Finish | None = None) -> Texture:
        return cls((Layer(pigment if pigment is not None else Pigment.solid((0.0, 0.0, 0.0)),
                          finish if finish is not None else Finish()),))

    @classmethod
    def of_map(cls, pattern: str, texture_map, **kwargs) -> Texture:
        """A patterned texture: pattern ``pattern`` (with the pigment fields ``kwargs``:
        ``transform``, ``vector``, ``turbulence``, ``frequency`` …) choosing among the textures of
        ``texture_map`` ``[(value, Texture), ...]`` (a block pattern: its list, at 0, 1, …)."""
        values = np.array([v for v, _ in texture_map], dtype=np.float64)
        entries = tuple(t for _, t in texture_map)
        if not entries:
            raise ValueError("a texture map needs at least one entry")
        black = [(v, (0.0, 0.0, 0.0)) for v in values]  # (unused: the entries are the colours)
        return cls(layers=entries[0].plain().layers, pattern=Pigment.mapped(pattern, black, **kwargs),
                   entries=entries)

    @property
    def patterned(self) -> bool:
        return self.pattern is not None

    def plain(self) -> Texture:
        """The first plain texture: this one, or its first entry's."""
        return self if self.entries is None else self.entries[0].plain()

    def textures(self):
        """This texture and, if patterned, every texture in it (depth first)."""
        yield self
        for entry in self.entries or ():
            yield from entry.textures()

    def leaves(self):
        """The plain textures this one shows: itself, or its entries' (depth first)."""
        for t in self.textures():
            if t.entries is None:
                yield t

    @property
    def depth(self) -> int:
        """How many patterns a point's texture is chosen through (0 for a plain texture)."""
        return 0 if self.entries is None else 1 + max(e.depth for e in self.entries)
