"""The statements of the environment effects (``sky_sphere``, ``fog`` …: ``scene.ENVIRONMENT``),
read through each entry's SDL hooks: this module is the interpreter as the effects'
:class:`~raytracer.scene.EnvironmentArgs` (``_lower.lower_environment`` is it as their
:class:`~raytracer.scene.EnvironmentLowering`), so an effect's module never imports the interpreter."""

from __future__ import annotations

import copy

from ..scene.environment import ENVIRONMENT, EnvironmentType
from ._convert import as_vector, type_name
from ._expr import parse_color, parse_expr
from ._lexer import ID
from ._textures import TRANSFORM_KEYWORDS, declared, float_, parse_pigment, parse_transform_item
from ._values import EnvRec

ENVIRONMENT_KEYWORDS: dict[str, EnvironmentType] = {e.name: e for e in ENVIRONMENT}

# what starts a colour expression besides a declared identifier, a number, a vector or a parenthesis
_COLOUR_WORDS = ("color", "colour", "rgb", "rgbf", "rgbt", "rgbft", "srgb", "srgbf", "srgbt", "srgbft",
                 "red", "green", "blue", "filter", "transmit")


class _Args:
    """The interpreter as ``scene.EnvironmentArgs`` for the statement of ``entry`` at ``loc``."""

    def __init__(self, p, entry: EnvironmentType, loc):
        self._p, self._entry, self._loc = p, entry, loc

    def keyword(self, *names: str) -> str | None:
        t = self._p.peek()
        if t.kind == ID and t.value in names and not declared(self._p, t):
            self._p.next()
            return t.value
        return None

    def float(self) -> float:
        return float_(self._p)

    def vector(self, size: int = 3) -> tuple:
        t = self._p.peek()
        return tuple(as_vector(self._p, parse_expr(self._p), size, t.loc))

    def expr(self):
        return parse_expr(self._p)

    def colour_follows(self) -> bool:
        t = self._p.peek()
        return t.kind != ID or t.value in _COLOUR_WORDS or declared(self._p, t)

    def colour(self) -> tuple:
        return tuple(parse_color(self._p).padded(5))

    def pigment(self):
        return parse_pigment(self._p)

    def transformation(self):
        t = self._p.peek()
        if t.kind != ID or t.value not in TRANSFORM_KEYWORDS or declared(self._p, t):
            return None
        self._p.next()
        return parse_transform_item(self._p, t)

    def describe_next(self) -> str:
        t = self._p.peek()
        if declared(self._p, t):
            return f"{type_name(self._p.lookup(t.value))} '{t.value}'"
        return t.describe()

    def warn(self, feature: str, message: str) -> None:
        self._p.warn(feature, message, self._loc)

    def error(self, message: str, loc=None):
        return self._p.error(message, loc)


def parse_environment(p, t, entry: EnvironmentType) -> EnvRec:
    """``NAME { [IDENTIFIER] items… }`` (``NAME`` already consumed, at ``t``): a declared statement of
    the same effect first is copied, then each item is read by the entry."""
    p.expect_op("{", f"'{{' after {entry.name}")
    first = p.peek()
    state = None
    if declared(p, first) and isinstance(p.lookup(first.value), EnvRec):
        v = parse_expr(p)
        if v.entry is not entry:
            raise p.error(f"expected a {entry.name}, found {type_name(v)} '{first.value}'", first.loc)
        state = copy.deepcopy(v.state)
    if state is None:
        state = entry.sdl_new()
    args = _Args(p, entry, t.loc)
    while not p.accept_op("}"):
        entry.sdl_item(args, state)
    return EnvRec(entry, state, t.loc)


def place_environment(p, rec: EnvRec, loc) -> None:
    """The statement ``rec`` takes effect at ``loc``: added to the scene's (``p.environment``) where
    its entry's values add up, else in place of an earlier one; left out where its entry says
    it is not rendered (with the entry's warning)."""
    entry = rec.entry
    if not entry.sdl_placed(_Args(p, entry, loc), rec.state):
        return
    if not entry.many:
        p.environment = [r for r in p.environment if r.entry is not entry]
    p.environment.append(EnvRec(entry, rec.state, loc))
