"""The ``#`` directives: declarations, conditionals, loops, macros, includes and messages."""

from __future__ import annotations

import math
import re

from ._convert import check_string_length
from ._expr import as_float, as_int, finite, index_list, parse_expr, parse_expr_paren, truthy, type_name
from ._lexer import EOF, ID, OP, STR
from ._stream import Frame, logger
from ._values import Alias, ArrayValue, MacroDef, Vec

OPENERS = ("if", "ifdef", "ifndef", "while", "for", "switch", "macro")


def skip_block(p, stops=()) -> str:
    """Skips raw tokens of the current frame to the matching ``#end`` (or a directive in ``stops``
    at the same depth), consuming it; returns the directive name found."""
    f, depth = p.frames[-1], 0
    toks = f.tokens
    while True:
        if f.pos >= f.stop:
            raise p.error("expected '#end', found end of file", toks[min(f.pos, len(toks) - 1)].loc)
        tok = toks[f.pos]
        f.pos += 1
        if tok.kind == OP and tok.value == "#" and f.pos < f.stop and toks[f.pos].kind == ID:
            name = toks[f.pos].value
            if name in OPENERS:
                depth += 1
            elif name == "end":
                if depth == 0:
                    f.pos += 1
                    return "end"
                depth -= 1
            elif depth == 0 and name in stops:
                f.pos += 1
                return name


def _cond(p):
    """A directive condition ``( expr )``; nothing after the ')' is read, so a false branch can be
    skipped from exactly there."""
    loc = p.expect_op("(", "'(' before the condition").loc
    v = parse_expr_paren(p)
    p.close_raw(")")
    return truthy(p, v, loc)


def directive_expr(p):
    """An expression ending a directive: a following '#' is not processed before we are done."""
    p.push_stop_mark()
    try:
        return parse_expr(p)
    finally:
        p.stop_marks.pop()


def _file_text(v) -> str:
    """How #write renders a value (strings verbatim, numbers and vectors as SDL literals)."""
    if isinstance(v, str):
        return v
    if isinstance(v, float | int):
        return repr(float(v))
    comps = getattr(v, "c", None)
    if comps is not None:
        return "<" + ",".join(repr(float(x)) for x in comps) + ">"
    return str(v)


def _file_values(text: str) -> list:
    """Comma-separated literals of a file for #read: floats, <vectors> and "strings"."""
    out = []
    for m in re.finditer(r'"((?:[^"\\]|\\.)*)"|<([^>]*)>|([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)', text):
        if m.group(1) is not None:
            out.append(m.group(1))
        elif m.group(2) is not None:
            out.append(Vec(tuple(float(x) for x in m.group(2).split(","))))
        else:
            out.append(float(m.group(3)))
    return out


class Directives:
    """Mixin with a handler per directive name; handlers are called with the name token."""

    def directive_table(self):
        return {
            "declare": self.d_declare, "local": self.d_local, "undef": self.d_undef,
            "if": self.d_if, "ifdef": self.d_ifdef, "ifndef": self.d_ifndef, "else": self.d_else,
            "elseif": self.d_elseif, "end": self.d_end, "while": self.d_while, "for": self.d_for,
            "switch": self.d_switch, "case": self.d_case, "range": self.d_case, "break": self.d_break,
            "macro": self.d_macro, "include": self.d_include, "version": self.d_version,
            "default": self.d_default, "debug": self.d_message, "warning": self.d_message,
            "error": self.d_error, "render": self.d_message, "statistics": self.d_message,
            "fopen": self.d_file, "read": self.d_file, "write": self.d_file, "fclose": self.d_file,
        }

    # ---- declarations --------------------------------------------------------------------
    def d_declare(self, tok):
        self._assign(tok, False)

    def d_local(self, tok):
        self._assign(tok, True)

    def _assign(self, tok, is_local):
        name_tok = self.raw_ident(f"an identifier after #{tok.value}")
        if name_tok.value == "deprecated":  # #declare deprecated [once] ["message"] Name = …
            name_tok = self.raw()
            if name_tok.kind == ID and name_tok.value == "once":
                name_tok = self.raw()
            if name_tok.kind == STR:
                name_tok = self.raw()
            if name_tok.kind != ID:
                raise self.error(f"expected an identifier, found {name_tok.describe()}", name_tok.loc)
        name = name_tok.value
        # the target table is chosen before the value is read: a macro called on the right-hand
        # side has its own table, gone by the time we assign
        target = self.scopes[-1] if is_local else self._owner_table(name)
        idx = index_list(self) if self.is_op("[") else []
        self.expect_op("=", f"'=' after #{tok.value} {name}")
        self.push_stop_mark()
        self.warning_capture.append([])
        try:
            value = self.parse_rvalue()
            t = self.peek_op()
        finally:
            self.stop_marks.pop()
            held = self.warning_capture.pop()
        if t.kind == OP and t.value == ";":
            self.next()
        if idx:
            for w in held:  # an array element: no identifier to wait with
                self.warn(w.feature, w.message, w.location)
            arr = self.lookup(name)
            if not isinstance(arr, ArrayValue):
                raise self.error(f"expected an array '{name}', found {type_name(arr)}", name_tok.loc)
            try:
                arr.data[arr.flat_index(idx)] = value
            except (IndexError, ValueError) as e:
                raise self.error(str(e), name_tok.loc) from None
            return
        self.hold_warnings(*self._write(target, name, value), held)

    def d_undef(self, tok):
        self.undef(self.raw_ident("an identifier after #undef").value)

    # ---- conditionals --------------------------------------------------------------------
    def _push_cond(self, entry):
        self.frames[-1].conds.append(entry)

    def _if_branch(self, taken: bool):
        if taken:
            self._push_cond(("if",))
            return
        while True:
            name = skip_block(self, ("else", "elseif"))
            if name == "end":
                return
            if name == "else":
                self._push_cond(("if",))
                return
            if _cond(self):  # elseif
                self._push_cond(("if",))
                return

    def d_if(self, tok):
        self._if_branch(_cond(self))

    def _defined_name(self):
        self.expect_op("(")
        name = self.raw_ident().value
        table, value = self.find(name)
        indices = []
        while self.accept_op("["):  # #ifdef (A[i][j]): is that array element initialised?
            loc = self.peek().loc
            indices.append(as_int(self, parse_expr(self), loc, "an array index"))
            self.expect_op("]")
        self.expect_op(")")
        if indices:
            if not isinstance(value, ArrayValue):
                return False
            try:
                return value.data[value.flat_index(indices)] is not None
            except (IndexError, ValueError):
                return False
        return table is not None or self.lookup_macro(name) is not None

    def d_ifdef(self, tok):
        self._if_branch(self._defined_name())

    def d_ifndef(self, tok):
        self._if_branch(not self._defined_name())

    def _top(self, tok, what):
        conds = self.frames[-1].conds
        if not conds:
            raise self.error(f"'#{tok.value}' without {what}", tok.loc)
        return conds[-1]

    def d_else(self, tok):
        top = self._top(tok, "#if or #switch")
        if top[0] == "switch":
            return  # #else inside a running #switch case: fall through into it
        if top[0] != "if":
            raise self.error(f"'#else' inside #{top[0]}", tok.loc)
        self.frames[-1].conds.pop()
        skip_block(self)

    def d_elseif(self, tok):
        top = self._top(tok, "#if")
        if top[0] != "if":
            raise self.error(f"'#elseif' inside #{top[0]}", tok.loc)
        self.frames[-1].conds.pop()
        skip_block(self)

    # ---- loops ---------------------------------------------------------------------------
    def d_while(self, tok):
        f = self.frames[-1]
        cond_pos = f.pos
        if _cond(self):
            self._push_cond(["while", cond_pos, 0, tok.loc])
        else:
            skip_block(self)

    def d_for(self, tok):
        loc = tok.loc
        self.expect_op("(")
        name = self.raw_ident("the loop variable of #for").value
        self.expect_op(",")
        start = as_float(self, parse_expr_paren(self), loc)
        self.expect_op(",")
        end = as_float(self, parse_expr_paren(self), loc)
        step = 1.0
        if self.accept_op(","):
            step = as_float(self, parse_expr_paren(self), loc)
        self.expect_op(")")
        if step == 0:
            raise self.error("#for step must not be 0", loc)
        self.local_or_declare(name, start)
        if (step > 0 and start <= end + 1e-10) or (step < 0 and start >= end - 1e-10):
            self._push_cond(["for", self.frames[-1].pos, 0, loc, name, end, step])
        else:
            skip_block(self)

    def local_or_declare(self, name, value):
        if self.find(name)[0] is not None:
            self.declare(name, value)
        else:
            self.local(name, value)

    def _count(self, entry):
        entry[2] += 1
        if entry[2] > self.limits.max_loop_iterations:
            raise self.error(f"loop exceeds {self.limits.max_loop_iterations} iterations", entry[3])

    def d_end(self, tok):
        f = self.frames[-1]
        if not f.conds:
            raise self.error("'#end' without an open #if, #while, #for, #switch or #macro", tok.loc)
        top = f.conds[-1]
        if top[0] == "while":
            self._count(top)
            f.pos = top[1]
            if not _cond(self):
                f.conds.pop()
                skip_block(self)
        elif top[0] == "for":
            self._count(top)
            name, end, step = top[4], top[5], top[6]
            v = finite(self, as_float(self, self.lookup(name), tok.loc) + step, tok.loc,
                       f"the #for variable {name}")
            self.declare(name, v)
            if (step > 0 and v <= end + 1e-10) or (step < 0 and v >= end - 1e-10):
                f.pos = top[1]
            else:
                f.conds.pop()
        else:
            f.conds.pop()

    # ---- switch --------------------------------------------------------------------------
    def d_switch(self, tok):
        self.expect_op("(")
        value = as_float(self, parse_expr_paren(self), tok.loc)
        self.expect_op(")")
        entry = ["switch", value]
        self._push_cond(entry)
        self._next_case(entry)

    def _case_matches(self, name, value, loc) -> bool:
        self.expect_op("(")
        a = as_float(self, parse_expr_paren(self), loc)
        if name == "range":
            self.expect_op(",")
            b = as_float(self, parse_expr_paren(self), loc)
            self.expect_op(")")
            return a <= value <= b
        self.expect_op(")")
        return abs(a - value) < 1e-10

    def _next_case(self, entry):
        """Skips to the first #case/#range that matches, #else, or #end."""
        while True:
            name = skip_block(self, ("case", "range", "else"))
            if name == "end":
                self.frames[-1].conds.pop()
                return
            if name == "else" or self._case_matches(name, entry[1], self.here()):
                return

    def d_case(self, tok):
        top = self._top(tok, "#switch")
        if top[0] != "switch":
            raise self.error(f"'#{tok.value}' outside #switch", tok.loc)
        # falling through from a previous case: this clause's condition is evaluated
        if not self._case_matches(tok.value, top[1], tok.loc):
            self._next_case(top)

    def d_break(self, tok):
        f = self.frames[-1]
        depth = 0
        while f.conds:
            entry = f.conds.pop()
            depth += 1
            if entry[0] in ("while", "for", "switch"):
                for _ in range(depth):
                    skip_block(self)
                return
        if f.kind == "macro":
            f.pos = f.stop
            return
        # a #break outside loops and switches is ignored, as POV does
        for _ in range(depth):
            skip_block(self)

    # ---- macros --------------------------------------------------------------------------
    def d_macro(self, tok):
        name = self.raw_ident("a macro name").value
        self.expect_op("(")
        params = []
        if not self.is_op(")"):
            params.append(self.raw_ident("a parameter name").value)
            while self.accept_op(","):
                params.append(self.raw_ident("a parameter name").value)
        self.expect_op(")")
        f = self.frames[-1]
        start = f.pos
        skip_block(self)
        stop = f.pos - 2  # the '#' of the closing #end
        self.macro_names.add(name)
        self.declare(name, MacroDef(name, params, f.tokens, start, stop, tok.loc))

    def invoke_macro(self, tok, m: MacroDef):
        if self.macro_depth >= self.limits.max_macro_depth:
            raise self.error(f"macro calls nested deeper than {self.limits.max_macro_depth} "
                             f"(runaway recursion in {m.name}?)", tok.loc)
        t = self.raw_peek() if self.la is None else self.la
        if t is None or t.kind != OP or t.value != "(":
            raise self.error(f"expected '(' after macro {m.name}, found "
                             f"{t.describe() if t else 'end of frame'}", tok.loc)
        self.expect_op("(")
        table = {}
        args = []
        nxt = self.raw_peek() if self.la is None else self.la
        if m.params and not (nxt is not None and nxt.kind == OP and nxt.value == ")"):
            args.append(self._macro_arg(table, m, 0))
            # POV-Ray tolerates a missing comma after an object argument
            while self.accept_op(",") or (len(args) < len(m.params) and not self.is_op(")")):
                args.append(self._macro_arg(table, m, len(args)))
        if len(args) != len(m.params):
            raise self.error(f"expected {len(m.params)} arguments to macro {m.name}, found "
                             f"{len(args)}", tok.loc)
        self._close_macro_args(tok, m)
        self.scopes.append(table)
        self.macro_depth += 1
        self.frames.append(Frame(m.tokens, m.start, m.stop, "macro", True, call_loc=tok.loc))

    def _close_macro_args(self, tok, m):
        # the ')' is read raw: reading on through peek would run the caller's next directive
        self.close_raw(")", f"')' to close the call of macro {m.name}")

    def close_raw(self, op: str, what: str | None = None):
        """Consumes ``op`` without looking at the token after it."""
        if self.la is not None and not self.la_raw:
            t = self.la
        else:
            if self.la_raw:
                t = self.la
            else:
                t = self.raw()
        self.la, self.la_raw = None, False
        if t.kind != OP or t.value != op:
            raise self.error(f"expected {what or repr(op)}, found {t.describe()}", t.loc)
        self.last = t
        return t

    def _macro_arg(self, table, m, i):
        if i >= len(m.params):
            raise self.error(f"too many arguments to macro {m.name}", self.here())
        name = m.params[i]
        a, b = self.raw_peek(0), self.raw_peek(1)
        if (self.la is None and a is not None and a.kind == ID and b is not None and b.kind == OP
                and b.value in (",", ")")):
            owner, _ = self.find(a.value)
            if owner is not None and self.lookup_macro(a.value) is None:
                self.raw()
                table[name] = Alias(self._owner_table(a.value), a.value)
                return name
        table[name] = self.parse_rvalue()
        return name

    def _owner_table(self, name):
        """The most local table binding ``name``, else the global table (where #declare writes)."""
        for table in reversed(self.scopes):
            if name in table:
                return table
        return self.scopes[0]

    # ---- files and messages --------------------------------------------------------------
    def d_include(self, tok):
        nxt = self.raw_peek() if self.la is None else None
        if nxt is not None and nxt.kind == STR:
            # read the name raw: looking past it could end (and pop) this file before the include
            # is pushed, which would also hide an include cycle
            v = self.raw().value
        else:
            v = directive_expr(self)
        if not isinstance(v, str):
            raise self.error(f"expected a file name string after #include, found {type_name(v)}",
                             tok.loc)
        self.unread_lookahead()
        self.push_include(v, tok.loc)

    def d_version(self, tok):
        self.push_stop_mark()
        try:
            v = as_float(self, parse_expr(self), tok.loc)
            t = self.peek_op()
        finally:
            self.stop_marks.pop()
        if t.kind == OP and t.value == ";":
            self.next()
        if v > 3.7 + 1e-9:  # as POV-Ray 3.7: "Your scene file requires POV-Ray version … or later"
            raise self.error(f"expected a #version of at most 3.7 (POV-Ray 3.7's language), found {v:g}: "
                             "the scene requires a later POV-Ray", tok.loc)
        self.version = v
        if not self.version_seen:
            self.version_seen = True
            self.first_version = v
        if v < 3.5 and not self.old_version_warned:
            self.old_version_warned = True
            self.warn("version", f"#version {v:g}: the pre-3.5 order-dependent camera syntax is "
                      "treated like 3.5+", tok.loc)

    def d_message(self, tok):
        v = directive_expr(self)
        if tok.value in ("debug", "warning", "render", "statistics"):
            text = v if isinstance(v, str) else str(v)
            level = logging_level(tok.value)
            # the command line shows them as POV-Ray does (``cli._SceneMessages``): the record
            # carries the directive, its text and where it is
            logger.log(level, "%s: #%s %s", tok.loc, tok.value, text.rstrip("\n"),
                       extra={"directive": tok.value, "text": text, "location": str(tok.loc)})

    def d_error(self, tok):
        v = directive_expr(self)
        raise self.error(f"#error: {v if isinstance(v, str) else v}", tok.loc)

    # ---- files: an in-memory sandbox ---------------------------------------------------------
    # Scenes may not touch the file system. #fopen … write/append creates a file in memory that
    # #write fills and #include or #fopen … read can use later in the same parse (POV's sample
    # scenes generate include files this way); reading a file from disk is refused.
    def d_file(self, tok):
        handler = {"fopen": self._fopen, "write": self._fwrite, "read": self._fread,
                   "fclose": self._fclose}[tok.value]
        handler(tok)

    def _fopen(self, tok):
        ident = self.expect_ident("a file identifier after #fopen").value
        name = directive_expr(self)
        if not isinstance(name, str):
            raise self.error(f"expected a file name string after #fopen {ident}, found {type_name(name)}",
                             tok.loc)
        mode = self.expect_ident("read, write or append").value
        if mode in ("write", "append"):
            if mode == "write" or name not in self.virtual_files:
                self.virtual_files[name] = []
                self.written_chars[name] = 0
            self.open_files[ident] = (name, mode, 0)
        elif mode == "read":
            if name not in self.virtual_files:
                raise self.error(f'#fopen {ident} "{name}" read is refused: scenes may not read files '
                                 "from disk (only files the scene itself wrote)", tok.loc)
            self.open_files[ident] = (name, mode, 0)
        else:
            raise self.error(f"expected read, write or append after the file name, found {mode}", tok.loc)
        self.declare(ident, name)

    def _file_args(self, tok):
        self.expect_op("(", f"'(' after #{tok.value}")
        ident = self.expect_ident("a file identifier").value
        if ident not in self.open_files:
            raise self.error(f"#{tok.value}: {ident} is not an open file", tok.loc)
        return ident

    def _fwrite(self, tok):
        ident = self._file_args(tok)
        name, mode, _ = self.open_files[ident]
        if mode == "read":
            raise self.error(f"#write: {ident} was opened for reading", tok.loc)
        while not self.accept_op(")"):  # commas between items are optional, as in POV-Ray
            self.accept_op(",")
            if self.accept_op(")"):
                break
            text = _file_text(parse_expr(self))
            self.written_chars[name] += len(text)
            check_string_length(self, self.written_chars[name], tok.loc, f'#write to "{name}"',
                                "max_written_chars")
            self.virtual_files[name].append(text)

    def _fread(self, tok):
        ident = self._file_args(tok)
        name, mode, pos = self.open_files[ident]
        if mode != "read":
            raise self.error(f"#read: {ident} was opened for writing", tok.loc)
        values = _file_values("".join(self.virtual_files[name]))
        while not self.accept_op(")"):
            self.accept_op(",")
            if self.accept_op(")"):
                break
            var = self.expect_ident("a variable to read into").value
            if pos < len(values):
                self.declare(var, values[pos])
                pos += 1
        self.open_files[ident] = (name, mode, pos)

    def _fclose(self, tok):
        ident = self.expect_ident("a file identifier after #fclose").value
        self.open_files.pop(ident, None)

    def d_default(self, tok):
        self.parse_default(tok)

    def srgb_to_working(self, c: float) -> float:
        lin = c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
        g = self.assumed_gamma
        if g is None or g == 1.0:
            return lin
        return math.copysign(abs(lin) ** (1.0 / g), lin)


def logging_level(kind: str) -> int:
    import logging

    return logging.WARNING if kind == "warning" else logging.INFO


__all__ = ["Directives", "skip_block", "EOF"]
