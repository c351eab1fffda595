"""What an environment effect is to the rest of the system (:class:`EnvironmentType`), and what its
SDL reader and lowering may ask of the interpreter (:class:`EnvironmentArgs`,
:class:`EnvironmentLowering`, which ``raytracer.sdl`` implements, so that an effect's module never
imports the interpreter)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Protocol


class EnvironmentArgs(Protocol):
    """What an effect's SDL reader may ask of the interpreter while it reads the effect's statement.

    Values are evaluated expressions; every method raises the interpreter's ``SceneError`` with
    ``file:line:col`` on bad input.
    """

    def keyword(self, *names: str) -> str | None:
        """Consumes and returns the next token if it is one of the keywords ``names`` (not an
        identifier the scene declared)."""

    def float(self) -> float: ...

    def vector(self, size: int = 3) -> tuple[float, ...]: ...

    def expr(self) -> Any:
        """Any expression's value (read and, where an item is not rendered, dropped)."""

    def colour_follows(self) -> bool:
        """Whether a colour expression comes next: a colour keyword (``rgb``, ``color`` …), an
        identifier the scene declared, a vector or a number."""

    def colour(self) -> tuple[float, ...]:
        """A colour expression, as RGBFT (5,) (a float fills every channel, as POV-Ray's)."""

    def pigment(self) -> Any:
        """``{…}`` of a ``pigment`` (the keyword consumed): an opaque value for
        :meth:`EnvironmentLowering.pigment`."""

    def transformation(self) -> Any | None:
        """The world-from-local 4×4 matrix (NumPy) of a transformation item (``translate``,
        ``rotate``, ``scale``, ``matrix``, ``transform``) if one comes next, else None (nothing read)."""

    def describe_next(self) -> str:
        """The next token as an error message shows it (``'foo'``, ``end of file``)."""

    def warn(self, feature: str, message: str) -> None:
        """A warning about ``feature`` (what ``docs/features.md`` lists as warned), located at the
        statement."""

    def error(self, message: str, loc: Any = None) -> Exception:
        """The ``SceneError`` to raise (at ``loc``, default: the next token)."""


class EnvironmentLowering(Protocol):
    """What an effect's lowering may ask of the interpreter: parsed values into scene records."""

    def pigment(self, pigment: Any, transform: Any | None) -> Any:
        """The scene's ``Pigment`` of a value :meth:`EnvironmentArgs.pigment` read, moved by the 4×4
        matrix ``transform`` (None: not moved)."""


@dataclasses.dataclass(frozen=True)
class EnvironmentType:
    """One environment effect, with everything the rest of the system asks of it.

    Attributes:
        name:        its SDL keyword, and the ``Effects.environment`` name it turns on.
        record:      the ``Record`` class of its values in ``Scene.environment``.
        many:        several values add up (fogs); else a later value replaces an earlier one and
                     ``environment_of`` gives the one value.
        pack:        ``(value, dtype, pack_pigments) → arrays``: what the program reads of it
                     (``value``: ``environment_of``'s, a tuple of records when ``many``).
        pigments:    ``value → pigments`` it evaluates (the plan compiles their patterns), or None.
        needs_media: its rays must know whether they are inside an object (the plan then keeps
                     every ray's interior list where the scene has transmission).
        miss:        ``(arrays, d, below, pigment_at) → (3,)``: the colour a ray of direction ``d``
                     that hits nothing sees over ``below``, or None (it shows ``below``).
        segment:     ``(arrays, origin, unit, distance or None) → (scale, add)``: a colour ``c``
                     carried along ``origin + s·unit`` over ``distance`` (None: infinitely far)
                     arrives as ``c·scale + add``; or None (it changes nothing). A ray inside an
                     object is not changed.
        sdl_new:     ``() → state``: a fresh parse state of the statement (POV-Ray's defaults);
                     the interpreter copies a declared one for ``name { IDENT … }``.
        sdl_item:    ``(args, state) → None``: reads one item of the statement's body into
                     ``state`` (``args``: :class:`EnvironmentArgs`), or raises ``args.error``.
        sdl_placed:  ``(args, state) → bool``: called where the statement takes effect (not where
                     it is declared): whether it is rendered; warns (``args.warn``) what is not.
        sdl_lower:   ``(state, lowering) → record or None``: the scene value (None: the statement
                     leaves the scene as it was).
    """

    name: str
    record: type
    many: bool
    pack: Callable
    sdl_new: Callable[[], Any]
    sdl_item: Callable[[EnvironmentArgs, Any], None]
    sdl_lower: Callable[[Any, EnvironmentLowering], Any]
    sdl_placed: Callable[[EnvironmentArgs, Any], bool] = lambda args, state: True
    pigments: Callable | None = None
    needs_media: bool = False
    miss: Callable | None = None
    segment: Callable | None = None
