"""Tokenizer for POV-Ray SDL: every token carries its ``SourceLoc``.

Comments (``//`` and nested ``/* */``) and whitespace are dropped. Keywords are not special at this
level: they are identifiers, and the interpreter decides what they mean in context.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from ..errors import SceneError, SourceLoc

NUM, STR, ID, OP, EOF = "num", "str", "id", "op", "eof"

# two-character operators first
_OPS2 = ("<=", ">=", "!=")
_OPS1 = set("{}()[]<>,;=+-*/?:.!&|#^")
_NUMBER = re.compile(r"([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# ASCII only, as POV-Ray: str.isdigit/isalpha accept "٣" and "Ø", which the patterns do not match
_DIGITS = frozenset("0123456789")
_IDENT_START = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_")
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "\\": "\\", '"': '"', "'": "'", "a": "\a", "b": "\b",
            "f": "\f", "v": "\v"}


class Token(NamedTuple):
    """One token: ``kind`` is num/str/id/op/eof; ``value`` a float, str or operator text."""

    kind: str
    value: object
    loc: SourceLoc

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


class _Cursor:
    def __init__(self, text: str, file: str):
        self.text, self.file = text, file
        self.i, self.line, self.line_start = 0, 1, 0

    def loc(self, i: int | None = None) -> SourceLoc:
        i = self.i if i is None else i
        return SourceLoc(self.file, self.line, i - self.line_start + 1)

    def advance_to(self, j: int) -> None:
        """Moves to index ``j``, counting the newlines passed."""
        k = self.text.find("\n", self.i, j)
        while k != -1:
            self.line += 1
            self.line_start = k + 1
            k = self.text.find("\n", k + 1, j)
        self.i = j


def _skip_block_comment(c: _Cursor) -> None:
    start = c.loc()
    depth, j, text = 0, c.i, c.text
    while True:
        a, b = text.find("/*", j), text.find("*/", j)
        if b == -1:
            raise SceneError("expected '*/' to close the comment, found end of file", start)
        if a != -1 and a < b:
            depth, j = depth + 1, a + 2
        else:
            depth, j = depth - 1, b + 2
            if depth == 0:
                c.advance_to(j)
                return


def _read_string(c: _Cursor) -> Token:
    start = c.loc()
    text, j, out = c.text, c.i + 1, []
    while True:
        if j >= len(text) or text[j] == "\n":
            raise SceneError("expected '\"' to close the string, found end of line", start)
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
    c.advance_to(j + 1)
    return Token(STR, "".join(out), start)


def tokenize(text: str, file: str = "<string>") -> list[Token]:
    """Splits SDL text into tokens, ending with one EOF token.

    Raises:
        SceneError: on an unterminated comment or string or a character that is not SDL.
    """
    c, toks, n = _Cursor(text, file), [], len(text)
    while True:
        # whitespace and comments
        while c.i < n:
            ch = text[c.i]
            if ch in " \t\r\n\f\v\ufeff\x1a":
                c.advance_to(c.i + 1)
            elif text.startswith("//", c.i):
                k = text.find("\n", c.i)
                c.advance_to(n if k == -1 else k)
            elif text.startswith("/*", c.i):
                _skip_block_comment(c)
            else:
                break
        if c.i >= n:
            toks.append(Token(EOF, None, c.loc()))
            return toks
        ch = text[c.i]
        if ch in _DIGITS or (ch == "." and c.i + 1 < n and text[c.i + 1] in _DIGITS):
            m = _NUMBER.match(text, c.i)
            toks.append(Token(NUM, _number(m.group(0), c.loc()), c.loc()))
            c.advance_to(m.end())
        elif ch in _IDENT_START:
            m = _IDENT.match(text, c.i)
            toks.append(Token(ID, m.group(0), c.loc()))
            c.advance_to(m.end())
        elif ch == '"':
            toks.append(_read_string(c))
        elif text[c.i:c.i + 2] in _OPS2:
            toks.append(Token(OP, text[c.i:c.i + 2], c.loc()))
            c.advance_to(c.i + 2)
        elif ch in _OPS1:
            toks.append(Token(OP, ch, c.loc()))
            c.advance_to(c.i + 1)
        else:
            why = " (identifiers and numbers are ASCII: A-Z, a-z, 0-9, _)" if ch.isalnum() else ""
            raise SceneError(f"expected a token, found character {ch!r}{why}", c.loc())
