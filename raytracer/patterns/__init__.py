"""Pigment patterns: ONE registry, from which every other table is derived.

Each pattern is a :class:`Pattern` record (``_record.py``) declared in the module of its family:

* ``_fields.py``      continuous closed forms (solid, gradient, radial, onion, spherical, …), exact POV-Ray;
* ``_tilings.py``     discrete patterns that choose a list entry (checker, hexagon, brick), exact POV-Ray;
* ``_noisy.py``       noise patterns on our own lattice noise (``_noise.py``): POV-Ray's look and
                      statistics, not its pixels;
* ``_cellular.py``    crackle and cells on our own random points: POV-Ray's look and statistics;
* ``_parsed_only.py`` POV-Ray patterns we parse (with a warning) but do not render.

The scene model validates ``Pigment.pattern`` against :data:`REGISTRY`, the render plan warns about
patterns that are not :attr:`Pattern.rendered`, the shader dispatches on :func:`pattern_value` and
:attr:`Pattern.discrete`, and the SDL parser takes its keywords, arguments, default colour maps and
default waves from the records. Adding a pattern is one record (and its evaluator) in its family's
module, plus its test; a new family is one module added to ``_FAMILIES``.

The renderer evaluates a pigment as (semantics §5.2)::

    v = pattern_value(name, p, ...)            # p is already in pattern space
    v = fmod(v * frequency + phase, 1.00001)   # skipped for discrete patterns
    v -= floor(v) if v < 0
    v = apply_wave(v, wave)
    colour = colour_map(v)

Numerics: every evaluator is pure JAX on one point, has finite values and finite gradients with
respect to ``p`` and ``vector`` everywhere (double-where guards), uses no ``lax.while_loop`` (octave
loops are static Python loops, so reverse-mode AD works), and computes in the dtype of ``p``.
"""

from __future__ import annotations

import types

import jax.numpy as jnp

from . import _cellular, _fields, _noisy, _parsed_only, _tilings
from ._noise import NUMBER_OF_WAVES as NUMBER_OF_WAVES
from ._noise import dnoise as dnoise
from ._noise import dturbulence as dturbulence
from ._noise import noise as noise
from ._noise import turbulence as turbulence
from ._record import Pattern as Pattern
from ._record import PatternInputs as PatternInputs
from ._waves import WAVES as WAVES
from ._waves import apply_wave as apply_wave

_FAMILIES = (_fields, _tilings, _noisy, _cellular, _parsed_only)


def _index(records) -> types.MappingProxyType:
    table: dict[str, Pattern] = {}
    for record in records:
        if record.name in table:
            raise ValueError(f"pattern {record.name!r} is registered twice")
        if record.default_wave not in WAVES:
            raise ValueError(f"pattern {record.name!r}: unknown default wave {record.default_wave!r}")
        table[record.name] = record
    return types.MappingProxyType(table)


REGISTRY: types.MappingProxyType[str, Pattern] = _index(r for family in _FAMILIES for r in family.PATTERNS)
"""Every pattern the system knows, by name (``Pigment.pattern``)."""

# Derived views (read-only; never edit these, edit the records).
NAMES: tuple[str, ...] = tuple(REGISTRY)
RENDERED: frozenset[str] = frozenset(n for n, r in REGISTRY.items() if r.rendered)
DISCRETE: frozenset[str] = frozenset(n for n, r in REGISTRY.items() if r.discrete)
SDL_KEYWORDS: frozenset[str] = frozenset(n for n, r in REGISTRY.items() if r.keyword)
MODIFIERS: frozenset[str] = frozenset(k for r in REGISTRY.values() for k in r.modifiers)
"""Pattern-specific SDL keywords (``brick_size``, ``mortar``, ``agate_turb`` …)."""

FACE_NUDGE = 1e-10
"""POV-Ray's: what a discrete pattern adds to a coordinate so that a face belongs to the cell above."""


def pattern_value(name: str, p, vector, turbulence, octaves: int = 6, omega=0.5, lambda_=2.0, *,
                  face_nudge=None, **modifiers):
    """Raw value of pattern ``name`` at one pattern-space point, before frequency/phase/wave/map.

    Args:
        name:       static pattern name, a rendered entry of :data:`REGISTRY`.
        p:          (3,) point in pattern space (already inverse-transformed).
        vector:     (3,) gradient direction (any length, normalised there); unused by others.
        turbulence: (3,) turbulence amount, or None (static) for none. A warp ``p += DTurbulence(p)⊙T``
                    for ordinary patterns; used by the pattern itself for marble, wood and agate.
        octaves, omega, lambda_: turbulence parameters (octaves static).
        face_nudge: a discrete pattern's nudge towards the cell above a face
                    (``PatternInputs.face_nudge``); None: POV-Ray's ``FACE_NUDGE``.
        **modifiers: the pattern's own keywords (``Pattern.modifiers``: brick's ``brick_size`` and
                    ``mortar``, agate's ``agate_turb``); POV-Ray's defaults where not given.

    Returns:
        Scalar. Continuous patterns give [0, 1] (gradient: (-∞, 1], negatives wrapped by the caller;
        marble and wood are unbounded and wrapped by the caller). Discrete patterns give the index of
        the listed colour: checker 0/1 (COLOR_1/COLOR_2), hexagon 0/1/2, brick 0 = mortar, 1 = brick.
    """
    record = REGISTRY.get(name)
    if record is None or not record.rendered:
        raise ValueError(f"pattern {name!r} is not rendered" if record else f"unknown pattern {name!r}")
    unknown = set(modifiers) - set(record.modifiers)
    if unknown:
        raise ValueError(f"pattern {name!r} has no modifier {', '.join(sorted(unknown))}")
    p = jnp.asarray(p)
    if turbulence is not None and record.turbulence == "warp":
        p = p + dturbulence(p, octaves, omega, lambda_) * jnp.asarray(turbulence, p.dtype)
    inputs = PatternInputs(vector, turbulence, octaves, omega, lambda_,
                           FACE_NUDGE if face_nudge is None else face_nudge)
    return record.evaluate(p, inputs, **{**record.modifiers, **modifiers})
