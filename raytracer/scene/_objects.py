"""Objects (a shape with a transform, texture and interior) and CSG trees of them (semantics §4.2)."""

from __future__ import annotations

import equinox as eqx

from .._build import Record
from ..shapes import AbstractShape
from ._texture import Interior, Texture
from ._transform import Transform

CSG_OPERATIONS = ("union", "intersection", "difference", "merge")


class AbstractObject(Record):
    """Something with an inside and a surface that can be placed in a scene or a CSG tree."""


class Object(AbstractObject):
    """A primitive placed in the world.

    Attributes:
        shape:      the primitive in its object space.
        transform:  ``world_from_object``, or None for the identity.
        texture:    its texture; None means "not given" (a CSG parent's texture, else POV's default).
        interior:   index of refraction and fading; None = default interior (ior 1).
        clipped_by: objects the surface is clipped to (only hits inside all of them are kept).
        bounded_by: objects that hold it (POV-Ray's ``bounded_by``): their box bounds the object
                    in the hierarchy where it has no finite box of its own (semantics §4.4).
        inverse:    static: inside and outside swapped.
        no_shadow, no_image, no_reflection, double_illuminate: static POV object flags.
    """

    shape: AbstractShape
    transform: Transform | None = None
    texture: Texture | None = None
    interior: Interior | None = None
    clipped_by: tuple[AbstractObject, ...] = ()
    bounded_by: tuple[AbstractObject, ...] = ()
    inverse: bool = eqx.field(static=True, default=False)
    no_shadow: bool = eqx.field(static=True, default=False)
    no_image: bool = eqx.field(static=True, default=False)
    no_reflection: bool = eqx.field(static=True, default=False)
    double_illuminate: bool = eqx.field(static=True, default=False)


class CSG(AbstractObject):
    """``union``, ``intersection``, ``difference`` or ``merge`` of child objects.

    ``transform``, ``texture`` and ``interior`` apply to every child (a child's own texture wins;
    the transform is applied after the child's own). Flags given here apply to every child;
    ``clipped_by`` and ``bounded_by`` as for ``Object``.
    """

    operation: str = eqx.field(static=True)
    children: tuple[AbstractObject, ...]
    transform: Transform | None = None
    texture: Texture | None = None
    interior: Interior | None = None
    clipped_by: tuple[AbstractObject, ...] = ()
    bounded_by: tuple[AbstractObject, ...] = ()
    inverse: bool = eqx.field(static=True, default=False)
    no_shadow: bool = eqx.field(static=True, default=False)
    no_image: bool = eqx.field(static=True, default=False)
    no_reflection: bool = eqx.field(static=True, default=False)
    double_illuminate: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        if self.operation not in CSG_OPERATIONS:
            raise ValueError(f"unknown CSG operation {self.operation!r}")
        if not self.children:
            raise ValueError("a CSG needs at least one child")
