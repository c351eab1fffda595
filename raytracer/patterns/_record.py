"""The record every pigment pattern is registered with, and the inputs its evaluator receives."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, Literal, NamedTuple

from jaxtyping import Array, Float

BLACK, WHITE = (0.0, 0.0, 0.0, 0.0, 0.0), (1.0, 1.0, 1.0, 0.0, 0.0)
RED, GREEN, BLUE = (1.0, 0.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0, 0.0)
BLACK_TO_WHITE = ((0.0, BLACK), (1.0, WHITE))  # POV-Ray's colour map when a pigment gives none


def rgb(r: float, g: float, b: float) -> tuple[float, ...]:
    return (r, g, b, 0.0, 0.0)


class PatternInputs(NamedTuple):
    """What every pigment carries for its pattern (``Pigment``'s fields of the same names).

    Attributes:
        vector:     (3,) direction (``gradient``'s vector; any length).
        turbulence: (3,) amount, or None (static) for none.
        octaves:    static number of turbulence octaves.
        omega, lambda_: turbulence amplitude and frequency ratios between octaves.
        face_nudge: what a discrete pattern adds to each coordinate so that a face at an integer
                    coordinate belongs to the cell above it: POV-Ray's 1e-10 (``FACE_NUDGE``) unless
                    the caller knows its point to be rounded more (float32 points in a rotated space).
    """

    vector: Float[Array, "3"]
    turbulence: Float[Array, "3"] | None
    octaves: int
    omega: Float[Array, ""]
    lambda_: Float[Array, ""]
    face_nudge: Float[Array, ""] | float = 1e-10


Evaluator = Callable[..., Float[Array, ""]]


@dataclasses.dataclass(frozen=True)
class Pattern:
    """One POV-Ray pigment pattern: everything the scene model, the plan, the shader and the SDL
    parser ask of it. The registry (``raytracer.patterns.REGISTRY``) holds one per name and every
    other table is derived from it.

    Attributes:
        name:         ``Pigment.pattern`` and, when ``keyword``, the SDL keyword.
        evaluate:     ``evaluate(p, inputs, **modifiers)``: the raw value at ONE pattern-space point
                      ``p`` (3,) (the caller vmaps), before frequency, phase, wave and colour map;
                      pure JAX with finite gradients everywhere. None: parsed only — the parser warns
                      and substitutes a neutral colour, the plan warns if a scene built through the
                      API uses it.
        colours:      discrete patterns choose an entry of a list: how many colours the SDL keyword
                      may list (checker 2, hexagon 3, brick 2); the value is the index of the chosen
                      entry (colour-map positions 0, 1, …) and skips frequency and phase. 0 for
                      continuous patterns.
        argument:     what follows the SDL keyword besides a discrete colour list: None, "vector"
                      (stored in ``Pigment.vector``), "values" (numbers or a block we skip) or "file"
                      (a file type keyword and a file name we skip).
        default_wave: the wave applied unless the pigment names one (marble and wood: triangle).
        turbulence:   "warp": turbulence displaces ``p`` before ``evaluate`` (POV's rule for ordinary
                      patterns); "internal": ``evaluate`` uses ``inputs.turbulence`` itself.
        modifiers:    pattern-specific keywords and POV-Ray's defaults (``brick_size``, ``mortar``…),
                      passed to ``evaluate`` as keyword arguments. ``Pigment`` does not carry them
                      yet, so the SDL parser warns that they are ignored and the defaults render.
        default_map:  the colour map when the pigment gives none: ``((value, rgbft), …)``.
        keyword:      whether the name is an SDL pattern keyword (False only for ``solid``, which
                      is written as a plain colour).
        noise:        its value costs lattice noise evaluations (tens of them with turbulence):
                      the shader then computes shadow filters pattern by pattern
                      (``shading/_materials.costly_patterns``).
        face:         a discrete pattern's cell faces: ``face(q_a, q_b, value) → (normal (3,),
                      offset (), found ())``, the plane ``normal · q = offset`` between the cells
                      of pattern-space points ``q_a`` and ``q_b`` (``normal · q − offset``
                      positive on ``q_b``'s side), whose motion is the boundary term of a cell edge
                      (``raytracer/_edges.py``); ``value`` (q → the pattern's value with the
                      layer's parameters) for faces found by probing (``_tilings.axis_face``),
                      ``found`` False where there is none to find; None: its cell edges get none.
        cell:         with ``face``: ``cell(q) → int32``, an id of the cell of pattern-space point
                      ``q`` that differs between any two cells sharing a face (two cells of one
                      colour too, so that a corner's two faces are told apart).
        normal_gain:  POV-Ray's own normal patterns (``bumps``, ``dents``, ``wrinkles``,
                      ``ripples``, ``waves``), which POV-Ray perturbs with by rules of their own and
                      ignores ``accuracy`` for: the gain that gives our perturbation POV-Ray's
                      standard deviation (``shading/_normals.py``). 0 for every other pattern, which
                      perturbs through its value as POV-Ray measures.
        imaged:       its colour is its pigment's image at the point (``Pigment.image``:
                      ``image_map``), not a lookup by its value (which is 0).
        averaged:     its colour is the mean of its ``pigment_map``'s pigments weighted by their
                      map positions (``average``), not a lookup by its value (which is 0).
        normal_bias:  with ``normal_gain``: the tilt POV-Ray's pattern gives every point, per unit
                      of amount, along (1, 1, 1) of pattern space (its ``wrinkles``: 0.444).
    """

    name: str
    evaluate: Evaluator | None
    colours: int = 0
    argument: Literal["vector", "values", "file"] | None = None
    default_wave: str = "ramp"
    turbulence: Literal["warp", "internal"] = "warp"
    modifiers: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    default_map: tuple[tuple[float, tuple[float, ...]], ...] = BLACK_TO_WHITE
    keyword: bool = True
    noise: bool = False
    face: Callable | None = None
    cell: Callable | None = None
    normal_gain: float = 0.0
    normal_bias: float = 0.0
    averaged: bool = False
    imaged: bool = False

    def __post_init__(self):
        if self.colours and len(self.default_map) != self.colours:
            raise ValueError(f"{self.name}: the default map of a discrete pattern lists its {self.colours} "
                             "colours")
        if self.colours and [v for v, _ in self.default_map] != list(range(self.colours)):
            raise ValueError(f"{self.name}: discrete colour-map positions are the indices 0, 1, …")

    @property
    def rendered(self) -> bool:
        return self.evaluate is not None

    @property
    def discrete(self) -> bool:
        return self.colours > 0


def parsed_only(name: str, argument: Literal["vector", "values", "file"] | None = "values") -> Pattern:
    """A POV-Ray pattern we parse (skipping its arguments) but do not render."""
    return Pattern(name, None, argument=argument)
