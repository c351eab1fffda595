"""Tokenizer for POV-Ray SDL: every token carries its offset in its file, and so its ``SourceLoc``.

Comments (``//`` and nested ``/* */``) and whitespace are dropped. Keywords are not special at this
level: they are identifiers, and the interpreter decides what they mean in context.
"""

from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from .._gc import paused
from ..errors import SceneError, SourceLoc

NUM, STR, ID, OP, EOF = "num", "str", "id", "op", "eof"

_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "\\": "\\", '"': '"', "'": "'", "a": "\a", "b": "\b",
            "f": "\f", "v": "\v"}


# A lexed file, for a token's line and column: ``(file, starts)``, ``starts`` the offsets where its
# lines begin (int64 bytes). A token keeps its offset: tokens are made by the million in a large
# scene (a ``mesh2`` of 100,000 triangles is 1.3 M), building a ``SourceLoc`` for each was half of
# the lexer's time, and few are ever read; a ``SourceLoc`` made from an offset finds its line when
# it is read.
Source = tuple


def _source(file: str, text: str) -> Source:
    if text.isascii():  # offsets in the text are offsets in its bytes
        starts = np.flatnonzero(np.frombuffer(text.encode("ascii"), np.uint8) == 10) + 1
    else:
        starts = np.fromiter((m.end() for m in _NEWLINE.finditer(text)), np.int64)
    return file, np.concatenate([[0], starts]).astype(np.int64).tobytes()


def _line_col(src: Source, pos: int) -> SourceLoc:
    return SourceLoc.at_offset(src[0], src[1], pos)


_NEWLINE = re.compile("\n")


class Token(NamedTuple):
    """One token: ``kind`` is num/str/id/op/eof; ``value`` a float, str or operator text; ``pos``
    its offset in the file ``src``, which gives its ``loc`` (or ``src`` is the ``SourceLoc`` of a
    token the interpreter made)."""

    kind: str
    value: object
    pos: int
    src: Source | SourceLoc

    @property
    def loc(self) -> SourceLoc:
        src = self.src
        return SourceLoc.at_offset(src[0], src[1], self.pos) if type(src) is tuple else src

    @classmethod
    def at(cls, kind: str, value: object, loc: SourceLoc) -> Token:
        """A token the interpreter makes, located at ``loc``."""
        return cls(kind, value, 0, loc)

    def describe(self) -> str:
        if self.kind == EOF:
            return "end of file"
        if self.kind == STR:
            return f'string "{self.value}"'
        if self.kind == NUM:
            return f"number {_fmt(self.value)}"
        return f"'{self.value}'"


def _fmt(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _number(text: str, loc: SourceLoc) -> float:
    """A number literal's value; one beyond the double range (1e309) is an error, not infinity."""
    v = float(text)
    if v == float("inf"):
        shown = text if len(text) <= 24 else f"{text[:12]}…{text[-8:]} ({len(text)} characters)"
        raise SceneError(f"expected a number within the float range (up to 1.8e308), found {shown}", loc)
    return v


def _block_comment_end(text: str, i: int, src: Source) -> int:
    """The offset just past the (nested) block comment that starts at ``i``."""
    depth, j = 0, i
    while True:
        a, b = text.find("/*", j), text.find("*/", j)
        if b == -1:
            raise SceneError("expected '*/' to close the comment, found end of file", _line_col(src, i))
        if a != -1 and a < b:
            depth, j = depth + 1, a + 2
        else:
            depth, j = depth - 1, b + 2
            if depth == 0:
                return j


def _read_string(text: str, i: int, src: Source) -> tuple[Token, int]:
    """The string token that starts at ``i``, and the offset just past it."""
    j, out = i + 1, []
    while True:
        if j >= len(text) or text[j] == "\n":
            raise SceneError("expected '\"' to close the string, found end of line", _line_col(src, i))
        ch = text[j]
        if ch == '"':
            break
        if ch == "\\" and j + 1 < len(text):
            nxt = text[j + 1]
            if nxt == "u" and re.fullmatch(r"[0-9A-Fa-f]{4}", text[j + 2:j + 6]):
                out.append(chr(int(text[j + 2:j + 6], 16)))
                j += 6
                continue
            out.append(_ESCAPES.get(nxt, "\\" + nxt))
            j += 2
            continue
        out.append(ch)
        j += 1
    return Token(STR, "".join(out), i, src), j + 1


# One match per token: the token, then the blanks after it (whitespace, line comments and block
# comments without a nested one), so the loop below runs once per token, not also once per gap.
# Identifiers and numbers are ASCII, as in POV-Ray (str.isdigit and str.isalpha would accept "٣"
# and "Ø"). Numbers come before operators (".5" is a number, "." alone an operator). A "/*" left
# at a token's place opens a nested or unterminated comment, and a '"' left there an unterminated
# string: both are read by hand, as is a string with escapes. ``other`` is any other character.
_BLANKS = r"""(?:[ \t\r\n\f\v\ufeff\x1a]+|//[^\n]*|/\*(?:[^*/]|\*(?!/)|/(?!\*))*\*/)*"""
_TOKEN = re.compile(r"""
    (?: (?P<num>(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)
      | (?P<id>[A-Za-z_][A-Za-z0-9_]*)
      | (?P<str>"[^"\\\n]*")
      | (?P<hand>/\*|")
      | (?P<op><=|>=|!=|[{}()\[\]<>,;=+\-*/?:.!&|\#^])
      | (?P<other>[\s\S])
    )""" + _BLANKS, re.VERBOSE)
_SKIP = re.compile(_BLANKS)


def tokenize(text: str, file: str = "<string>") -> list[Token]:
    """Splits SDL text into tokens, ending with one EOF token.

    Raises:
        SceneError: on an unterminated comment or string or a character that is not SDL.
    """
    # Tokens make no reference cycles, and the collections that a million new tracked objects set
    # off (the full ones walk every token made so far) were ~40 % of lexing a large mesh.
    with paused():
        return _tokens(text, file)


def _tokens(text: str, file: str) -> list[Token]:
    src, toks, n = _source(file, text), [], len(text)
    append, new = toks.append, tuple.__new__
    i = _SKIP.match(text).end()
    while i < n:
        for m in _TOKEN.finditer(text, i):
            kind = m.lastgroup
            if kind == "num":
                v = float(m.group(1))
                if v == _INF:
                    _number(m.group(1), _line_col(src, m.start()))
                append(new(Token, (NUM, v, m.start(), src)))
            elif kind == "id":
                append(new(Token, (ID, m.group(2), m.start(), src)))
            elif kind == "op":
                append(new(Token, (OP, m.group(5), m.start(), src)))
            elif kind == "str":
                append(new(Token, (STR, m.group(3)[1:-1], m.start(), src)))
            else:
                i = m.start()
                break
        else:
            break
        if kind == "other":
            ch = text[i]
            why = " (identifiers and numbers are ASCII: A-Z, a-z, 0-9, _)" if ch.isalnum() else ""
            raise SceneError(f"expected a token, found character {ch!r}{why}", _line_col(src, i))
        if text[i] == '"':
            tok, i = _read_string(text, i, src)
            append(tok)
        else:
            i = _block_comment_end(text, i, src)
        i = _SKIP.match(text, i).end()
    append(Token(EOF, None, n, src))
    return toks


_INF = float("inf")
