"""Values of the SDL interpreter and the builder-level records objects are parsed into.

Numbers are Python floats; vectors and colours are :class:`Vec` (a tuple of 2–5 floats plus a flag
saying whether the value can carry filter/transmit). Scene items are light mutable records that are
lowered to the JAX scene model only at the end (``_lower.py``), so ``object { Ident … }`` can copy and
modify a declared object cheaply.
"""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np

from ..errors import SourceLoc
from ..scene._lights import LIGHT_DEFAULTS
from ..scene.environment import EnvironmentType


class Vec:
    """A vector or colour value: 2–5 float components.

    Attributes:
        c:  tuple of floats (colours always have 5: r g b filter transmit).
        ft: whether the value may carry filter/transmit (rgbf/rgbt/rgbft, the ``filter``/``transmit``
            keywords, a float promoted to a colour); decides ``Pigment.transparent``.
    """

    __slots__ = ("c", "ft")

    def __init__(self, comps, ft: bool = False):
        self.c = tuple(float(v) for v in comps)
        self.ft = ft

    @classmethod
    def of_floats(cls, floats: tuple[float, ...]) -> Vec:
        """A vector of a tuple of floats (no conversion: the parser's fast path)."""
        v = object.__new__(cls)
        v.c, v.ft = floats, False
        return v

    def __len__(self) -> int:
        return len(self.c)

    def __repr__(self) -> str:
        return f"Vec({self.c}{', ft' if self.ft else ''})"

    def __eq__(self, other) -> bool:
        return isinstance(other, Vec) and self.c == other.c

    __hash__ = None  # type: ignore[assignment]

    def padded(self, n: int) -> tuple[float, ...]:
        return (self.c + (0.0,) * n)[:n]

    def as_color(self) -> Vec:
        """The 5-component colour of this value (missing filter/transmit are 0)."""
        return Vec(self.padded(5), self.ft)


@dataclasses.dataclass
class ArrayValue:
    """``array[d1][d2]…``: ``data`` is a flat list in row-major order (None = not initialised)."""

    dims: list[int]
    data: list

    def flat_index(self, idx: list[int]) -> int:
        k = 0
        for i, d in zip(idx, self.dims, strict=True):
            if not 0 <= i < d:
                raise IndexError(f"array index {i} out of range 0..{d - 1}")
            k = k * d + i
        return k


@dataclasses.dataclass
class Alias:
    """A macro parameter passed by reference: reads and writes go to ``table[name]``."""

    table: dict
    name: str


@dataclasses.dataclass
class MacroDef:
    name: str
    params: list[str]
    tokens: list
    start: int
    stop: int
    loc: SourceLoc


@dataclasses.dataclass
class FunctionValue:
    """A user ``function(params) { body }``: the body's tokens are re-parsed on each call.

    ``kind`` is "float" (the expression in ``tokens``) or "opaque" (pattern/pigment/internal
    functions, which evaluate to 0 with a warning).
    """

    params: list[str]
    tokens: list
    kind: str = "float"
    loc: SourceLoc | None = None


@dataclasses.dataclass
class SplineValue:
    """``spline { … }``: control points ``(t, Vec)``, evaluated piecewise-linearly."""

    points: list
    kind: str = "linear_spline"


@dataclasses.dataclass
class RandStream:
    """``seed(n)``: the random stream of ``rand``, POV-Ray's own sequence.

    Measured against POV-Ray 3.7 (``#debug`` of ``rand`` to 12 digits for seeds 0 to 3, negative,
    fractional and out-of-range ones; agreement to the digits printed): a 32-bit linear congruential
    generator ``s ← 1812433253 s + 12345 (mod 2³²)`` whose value is ``s / (2³² − 1)``, started at
    the seed truncated to a 32-bit integer (a seed outside that range starts at −2³¹, as the
    processor's conversion gives). :func:`seed_state` makes the start.
    """

    state: int

    def next(self) -> float:
        self.state = (self.state * 1812433253 + 12345) & 0xFFFFFFFF
        return self.state / 4294967295.0


def seed_state(value: float) -> int:
    """The start of ``seed(value)``'s stream (:class:`RandStream`)."""
    whole = int(value) if value == value and abs(value) != float("inf") else -(2**31)
    if not -(2**31) <= whole < 2**31:
        whole = -(2**31)
    return whole & 0xFFFFFFFF


@dataclasses.dataclass
class Opaque:
    """A parsed value we keep only so identifiers resolve (media, normal, photons …)."""

    kind: str
    loc: SourceLoc | None = None


def identity() -> np.ndarray:
    return np.eye(4)


@dataclasses.dataclass
class TransformRec:
    """A ``transform { … }`` value: a world_from_object 4×4 numpy matrix."""

    matrix: np.ndarray


@dataclasses.dataclass
class PigRec:
    """A pigment as parsed. ``cmap`` is a list of ``(value, Vec5)``; ``pattern`` "solid" or a name."""

    pattern: str = "solid"
    cmap: list = dataclasses.field(default_factory=lambda: [(0.0, Vec((0, 0, 0, 0, 0)))])
    cmap_given: bool = False
    transform: np.ndarray | None = None
    vector: tuple = (0.0, 1.0, 0.0)
    frequency: float = 1.0
    phase: float = 0.0
    turbulence: tuple | None = None
    omega: float = 0.5
    lambda_: float = 2.0
    octaves: int = 6
    wave: str | None = None
    ft: bool = False
    entries: list | None = None  # a pigment map's or list's pigments (PigRec), at cmap's positions
    image: dict | None = None  # image_map: pixels (H, W, 5) linear RGBFT, map_type, once, interpolate

    def transformed(self, m: np.ndarray) -> PigRec:
        if self.pattern == "solid":
            return self
        t = m if self.transform is None else m @ self.transform
        return dataclasses.replace(self, transform=t)


@dataclasses.dataclass
class PigmentMapRec:
    """A ``pigment_map`` value (``#declare M = pigment_map { … }``): ``(position, PigRec)`` pairs."""

    entries: list


@dataclasses.dataclass
class NormRec:
    """A ``normal { }`` as parsed: its pattern as a pigment holds one (``PigRec``; "solid" for a
    normal that perturbs nothing we render), ``bump_size`` and ``accuracy``."""

    pigment: PigRec = dataclasses.field(default_factory=PigRec)
    amount: float = 0.5
    accuracy: float = 0.02
    slope_map: list | None = None  # [value, height, slope] rows

    def transformed(self, m: np.ndarray) -> NormRec:
        return dataclasses.replace(self, pigment=self.pigment.transformed(m))


@dataclasses.dataclass
class SlopeMapRec:
    """A ``slope_map`` value (``#declare S = slope_map { … }``): ``[value, height, slope]`` rows."""

    entries: list


@dataclasses.dataclass
class EnvRec:
    """An environment statement as read (and as ``#declare`` keeps it): its entry, the entry's parse
    state, and where it stands."""

    entry: EnvironmentType
    state: Any
    loc: Any

    @property
    def sdl_type_name(self) -> str:
        """What an error message calls it: the statement's keyword."""
        return self.entry.name


@dataclasses.dataclass
class LayerRec:
    """One texture layer: pigment, finish (a dict of the keywords given) and its normal, if given;
    or a patterned texture (``patterned``: its pattern and its ``(position, TextureRec)``
    entries), which POV-Ray allows only as a texture's one layer."""

    pigment: PigRec = dataclasses.field(default_factory=PigRec)
    finish: dict = dataclasses.field(default_factory=dict)
    normal: NormRec | None = None
    patterned: tuple[PigRec, list] | None = None

    def transformed(self, m: np.ndarray) -> LayerRec:
        patterned = None
        if self.patterned is not None:
            pattern, entries = self.patterned
            patterned = (pattern.transformed(m),
                         [(v, TextureRec([layer.transformed(m) for layer in t.layers])) for v, t in entries])
        return LayerRec(self.pigment.transformed(m), self.finish,
                        None if self.normal is None else self.normal.transformed(m), patterned)


@dataclasses.dataclass
class TextureRec:
    """A texture value: layers bottom first (as written)."""

    layers: list


@dataclasses.dataclass
class TextureMapRec:
    """A ``texture_map`` value (``#declare M = texture_map { … }``): ``(position, TextureRec)`` pairs."""

    entries: list


@dataclasses.dataclass
class InteriorRec:
    values: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class MaterialRec:
    texture: TextureRec | None = None
    interior: InteriorRec | None = None


@dataclasses.dataclass
class LightRec:
    """A light source as parsed; defaults are POV-Ray's, from ``raytracer.scene._lights``."""

    position: np.ndarray
    color: Vec = dataclasses.field(default_factory=lambda: Vec(LIGHT_DEFAULTS["color"]).as_color())
    point_at: np.ndarray = dataclasses.field(
        default_factory=lambda: np.array(LIGHT_DEFAULTS["point_at"], dtype=np.float64))
    kind: str = "point"  # a non-modifier entry of LIGHT_TYPES: point, spotlight, cylinder
    values: dict = dataclasses.field(default_factory=dict)  # item of LIGHT_SDL_KEYWORDS → value
    transform: np.ndarray | None = None
    loc: SourceLoc | None = None

    def clone(self) -> LightRec:
        c = copy.copy(self)
        c.values = dict(self.values)
        return c


@dataclasses.dataclass
class ObjRec:
    """An object as parsed: a primitive (``shape`` = (kind, params)) or a CSG (``children``)."""

    kind: str
    shape: dict = dataclasses.field(default_factory=dict)
    children: list = dataclasses.field(default_factory=list)
    transform: np.ndarray | None = None
    layers: list | None = None  # LayerRec, bottom first; None = no texture given
    interior: InteriorRec | None = None
    clipped_by: list = dataclasses.field(default_factory=list)
    flags: dict = dataclasses.field(default_factory=dict)
    default_layer: LayerRec | None = None  # the #default when placed at top level (§2.1)
    layers_given: bool = False
    bounded_by: list = dataclasses.field(default_factory=list)
    supported: bool = True
    loc: SourceLoc | None = None
    depth: int = 0  # CSG levels in it (a primitive: 0)

    def clone(self) -> ObjRec:
        o = copy.copy(self)
        o.layers = None if self.layers is None else list(self.layers)
        o.clipped_by = list(self.clipped_by)
        o.flags = dict(self.flags)
        o.shape = dict(self.shape)
        return o

    def apply_transform(self, m: np.ndarray) -> None:
        """Applies ``m`` after the current transform; textures already attached move with it."""
        self.transform = m if self.transform is None else m @ self.transform
        if self.layers is not None:
            self.layers = [layer.transformed(m) for layer in self.layers]


@dataclasses.dataclass
class CameraRec:
    values: dict = dataclasses.field(default_factory=dict)
    transform: np.ndarray | None = None
    projection: str = "perspective"
    loc: SourceLoc | None = None
    angle_loc: SourceLoc | None = None  # where its angle was given
    other_projection: str | None = None  # a POV-Ray projection rendered as perspective (fisheye …)

    def clone(self) -> CameraRec:
        return CameraRec(dict(self.values), self.transform, self.projection, self.loc, self.angle_loc,
                         self.other_projection)
