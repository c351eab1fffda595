"""Tokenizer for POV-Ray SDL: every token carries its ``SourceLoc``.

Comments (``//`` and nested ``/* */``) and whitespace are dropped. Keywords are not special at this
level: they are identifiers, and the interpreter decides what they mean in context.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from ..errors import SceneError, SourceLoc

NUM, STR, ID, OP, EOF = "num", "str", "id", "op", "eof"

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


# one scan step: blanks and line comments, or the start of a token. Identifiers and numbers are ASCII,
# as in POV-Ray (str.isdigit and str.isalpha would accept "٣" and "Ø").
# Numbers come before operators (".5" is a number, "." alone an operator); "/*" and '"' are read by
# hand (nesting, escapes).
_STEP = re.compile(r"""
    (?P<blank>(?:[ \t\r\n\f\v\ufeff\x1a]+|//[^\n]*)+)
  | (?P<num>(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)
  | (?P<id>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<comment>/\*)
  | (?P<op><=|>=|!=|[{}()\[\]<>,;=+\-*/?:.!&|\#^])
  | (?P<str>")
""", re.VERBOSE)


def tokenize(text: str, file: str = "<string>") -> list[Token]:
    """Splits SDL text into tokens, ending with one EOF token.

    Raises:
        SceneError: on an unterminated comment or string or a character that is not SDL.
    """
    c, toks, n = _Cursor(text, file), [], len(text)
    match, append, count, rfind = _STEP.match, toks.append, text.count, text.rfind
    i, line, line_start = 0, 1, 0
    while i < n:
        m = match(text, i)
        if m is None:
            ch = text[i]
            why = " (identifiers and numbers are ASCII: A-Z, a-z, 0-9, _)" if ch.isalnum() else ""
            raise SceneError(f"expected a token, found character {ch!r}{why}",
                             SourceLoc(file, line, i - line_start + 1))
        kind, j = m.lastgroup, m.end()
        if kind == "blank":
            k = count("\n", i, j)
            if k:
                line += k
                line_start = rfind("\n", i, j) + 1
        elif kind == "id":
            append(Token(ID, m.group(), SourceLoc(file, line, i - line_start + 1)))
        elif kind == "op":
            append(Token(OP, m.group(), SourceLoc(file, line, i - line_start + 1)))
        elif kind == "num":
            loc = SourceLoc(file, line, i - line_start + 1)
            append(Token(NUM, _number(m.group(), loc), loc))
        else:  # a block comment or a string: the cursor counts their lines
            c.i, c.line, c.line_start = i, line, line_start
            if kind == "comment":
                _skip_block_comment(c)
            else:
                append(_read_string(c))
            j, line, line_start = c.i, c.line, c.line_start
        i = j
    append(Token(EOF, None, SourceLoc(file, line, i - line_start + 1)))
    return toks
