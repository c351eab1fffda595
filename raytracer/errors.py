"""Errors and warnings shared by the parser and the renderer (no JAX here)."""

from __future__ import annotations

import bisect
import dataclasses
import re


class SourceLoc:
    """A position in a scene file: 1-based line and column. Immutable, compared and hashed by
    ``(file, line, col)``.

    A token's location is made from its offset in a lexed file (``at_offset``), and its line and
    column are looked up in the file's line table when first read: the interpreter takes a token's
    location for every operator and call in case of an error, and rarely reads one.
    """

    __slots__ = ("_file", "_line", "_col", "_table", "_pos")

    def __init__(self, file: str, line: int, col: int):
        self._file, self._line, self._col, self._table = file, line, col, None

    @classmethod
    def at_offset(cls, file: str, table: bytes, pos: int) -> SourceLoc:
        """The location of offset ``pos`` in ``file``, whose lines start at the offsets ``table``
        (int64 bytes, the first 0)."""
        loc = object.__new__(cls)
        loc._file, loc._table, loc._pos = file, table, pos
        return loc

    def _resolve(self) -> None:
        table = self._table  # another thread may have resolved it since its caller looked
        if table is None:
            return
        starts = memoryview(table).cast("q")
        line = bisect.bisect_right(starts, self._pos)
        self._line, self._col, self._table = line, self._pos - starts[line - 1] + 1, None

    @property
    def file(self) -> str:
        return self._file

    @property
    def line(self) -> int:
        if self._table is not None:
            self._resolve()
        return self._line

    @property
    def col(self) -> int:
        if self._table is not None:
            self._resolve()
        return self._col

    def _key(self) -> tuple[str, int, int]:
        return self.file, self.line, self.col

    def __eq__(self, other) -> bool:
        if not isinstance(other, SourceLoc):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __reduce__(self):
        return SourceLoc, self._key()

    def __repr__(self) -> str:
        return f"SourceLoc(file={self.file!r}, line={self.line!r}, col={self.col!r})"

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class SceneError(Exception):
    """A scene that cannot be loaded or rendered: the scene's fault, with where and why.

    The message reads ``file:line:col: what was expected, what was found`` when the error has a
    location, followed by the include chain (``included from file:line:col``) when there is one.
    """

    def __init__(self, message: str, location: SourceLoc | None = None,
                 include_chain: tuple[SourceLoc, ...] = ()):
        self.bare_message = message
        self.location = location
        self.include_chain = tuple(include_chain)
        super().__init__(_located(message, location, self.include_chain))


class LimitError(SceneError):
    """A render that would need more of a resource (memory) than the bound allows: refused before
    it starts, with what to change."""


class InternalError(Exception):
    """A failure of the renderer itself while it read a scene: a bug to report, not a scene error.

    ``__cause__`` is the original exception (its traceback is kept); ``location`` is where in the
    scene the interpreter was, when known.
    """

    def __init__(self, message: str, location: SourceLoc | None = None,
                 include_chain: tuple[SourceLoc, ...] = ()):
        self.bare_message = message
        self.location = location
        self.include_chain = tuple(include_chain)
        super().__init__(_located(f"internal error (a bug in raytracer, not in the scene): {message}",
                                  location, self.include_chain))


_CHAIN_SHOWN = 4  # include/call chains longer than twice this show their ends and a count
_LONG_NUMBER = re.compile(r"\d{21,}")


def short_numbers(text: str) -> str:
    """``text`` with every run of more than 20 digits written as ``d.ddde+N`` (no 300-digit integers)."""
    return _LONG_NUMBER.sub(lambda m: f"{m[0][0]}.{m[0][1:4]}e+{len(m[0]) - 1}", text)


_LONGEST_MESSAGE = 1000  # characters of a message (a 100 kB file name is shown by its ends)


def _located(message: str, location: SourceLoc | None, chain: tuple[SourceLoc, ...]) -> str:
    message = short_numbers(message)
    if len(message) > _LONGEST_MESSAGE:
        half = _LONGEST_MESSAGE // 2
        message = f"{message[:half]}… ({len(message) - 2 * half} characters left out) …{message[-half:]}"
    text = f"{location}: {message}" if location is not None else message
    if len(chain) > 2 * _CHAIN_SHOWN + 1:
        hidden = len(chain) - 2 * _CHAIN_SHOWN
        chain_lines = [f"included from {loc}" for loc in chain[:_CHAIN_SHOWN]]
        chain_lines.append(f"… {hidden} more …")
        chain_lines += [f"included from {loc}" for loc in chain[-_CHAIN_SHOWN:]]
    else:
        chain_lines = [f"included from {loc}" for loc in chain]
    return text + "".join(f"\n  {line}" for line in chain_lines)


@dataclasses.dataclass(frozen=True)
class SceneWarning:
    """A feature that was parsed but is not rendered (or not rendered exactly), with its location."""

    feature: str
    message: str
    location: SourceLoc | None = None

    def __str__(self) -> str:
        where = f"{self.location}: " if self.location is not None else ""
        return f"{where}warning: {self.message} [{self.feature}]"


def fmt_number(x: float) -> str:
    """A number as a message prints it (errors and warnings of any layer): at most 6 significant
    digits, a whole number without a point."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))  # chr(1114112), not chr(1.11411e+06)
    return f"{x:.6g}" if isinstance(x, float) else str(x)
