"""Errors and warnings shared by the parser and the renderer (no JAX here)."""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class SourceLoc:
    """A position in a scene file: 1-based line and column."""

    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class SceneError(Exception):
    """A scene that cannot be loaded or rendered.

    The message reads ``file:line:col: what was expected, what was found`` when the error has a
    location, followed by the include chain (``included from file:line:col``) when there is one.
    """

    def __init__(self, message: str, location: SourceLoc | None = None,
                 include_chain: tuple[SourceLoc, ...] = ()):
        self.bare_message = message
        self.location = location
        self.include_chain = tuple(include_chain)
        text = f"{location}: {message}" if location is not None else message
        for loc in self.include_chain:
            text += f"\n  included from {loc}"
        super().__init__(text)


@dataclasses.dataclass(frozen=True)
class SceneWarning:
    """A feature that was parsed but is not rendered (or not rendered exactly), with its location."""

    feature: str
    message: str
    location: SourceLoc | None = None

    def __str__(self) -> str:
        where = f"{self.location}: " if self.location is not None else ""
        return f"{where}warning: {self.message} [{self.feature}]"
