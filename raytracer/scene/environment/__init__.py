"""Environment effects: what a ray sees beyond every object, and what the space between surfaces does
to the light a ray carries. One record per effect (:data:`ENVIRONMENT`), as ``LIGHT_TYPES`` is for
lights: the SDL interpreter, the plan, the shading model and the image of a scene without objects
apply the entries a scene switches on, without naming one.

Each entry (:class:`EnvironmentType`) declares its value's record class (a scene holds its values in
``Scene.environment``), whether several values add up, the pigments it evaluates (so the plan
compiles their patterns), whether it must know if a ray is inside an object, how its value packs
into the arrays the program reads, its two behaviours — ``miss``, the colour a ray that hits
nothing sees over what lies below it (the background, or the entries before it), and ``segment``,
what a ray segment of a given length does to the colour it carries (``c·scale + add``) — and its
SDL statement: how an item of it is read, where it warns, and how it lowers to its record.

A new effect is a module here with its record and its entry, one line in :data:`ENVIRONMENT`, its
test and a scene.
"""

from __future__ import annotations

from typing import Any

from ._base import EnvironmentArgs as EnvironmentArgs
from ._base import EnvironmentLowering as EnvironmentLowering
from ._base import EnvironmentType as EnvironmentType
from ._fog import FOG
from ._fog import Fog as Fog
from ._sky_sphere import SKY_SPHERE
from ._sky_sphere import SkySphere as SkySphere

ENVIRONMENT: tuple[EnvironmentType, ...] = (SKY_SPHERE, FOG)
"""Every environment effect, in the order they apply: a miss's colour from the first to the last
(each over the one before it, the background at the bottom), and a segment's too (the first acts on
the carried colour first)."""


def environment_of(scene) -> tuple[tuple[EnvironmentType, Any], ...]:
    """The effects the scene switches on, each with its value: the tuple of its records in
    ``scene.environment`` where the entry is ``many``, else its one record."""
    out = []
    for e in ENVIRONMENT:
        values = tuple(v for v in scene.environment if isinstance(v, e.record))
        if values:
            out.append((e, values if e.many else values[0]))
    return tuple(out)
