"""The token stream: files, include frames, macro frames, lookahead and symbol tables.

POV-Ray evaluates directives while it reads tokens, so ``#if``, ``#while``, ``#include`` and macro
calls are handled here, below the expression parser and the builders: whatever asks for the next
token gets the token the directives produce. Loops jump back in the token list of their frame.
"""

from __future__ import annotations

import collections
import dataclasses
import hashlib
import logging
import os
import resource
import threading
import time
from pathlib import Path

from ..errors import SceneError, SceneWarning, SourceLoc
from ._lexer import EOF, ID, NUM, OP, Token, tokenize
from ._values import Alias, MacroDef

logger = logging.getLogger("raytracer.sdl")

STANDARD_INCLUDE = Path("/usr/share/povray-3.7/include")


@dataclasses.dataclass(frozen=True)
class Limits:
    """Bounds that stop runaway scenes with a SceneError instead of a hang.

    Attributes:
        max_loop_iterations: iterations of one ``#while``/``#for`` loop.
        max_macro_depth:     nested macro (and function) calls.
        max_include_depth:   nested ``#include`` files.
        max_csg_depth:       CSG objects nested in each other, written so or built by a loop
                             (``#declare U = union { object { U } … }``); the renderer's walks of
                             the tree, and JAX's of the scene, recurse (at 512 they ran out).
        max_tokens:          tokens read in total (a budget for the whole scene).
        max_array_elements:  elements of one array (``array[1000000000]`` would need 8 GB).
        max_string_length:   characters of one string (``concat`` doubling a string 34 times
                             reached 6.4 GB).
        max_written_chars:   characters of one file a scene writes with ``#write`` (kept in
                             memory; POV-Ray's ``meshcam_persp_demo.pov`` writes 17 M at 640×480).
        max_parse_seconds:   wall-clock seconds of one parse (the slowest of POV-Ray's sample
                             scenes, ``tracevines.pov``, takes 68 s here; a scene of 10^5 objects 20-30 s);
                             checked every ``PARSE_CLOCK_TOKENS`` tokens read. CLI: ``--parse-timeout``.
        max_parse_memory_mb: growth of the process's peak resident memory during one parse,
                             checked with the clock (the limits above bound single values; this
                             bounds their sum: a million arrays of a million elements, a
                             recursion that keeps every level's strings). In a process that
                             already peaked higher before the parse, the parse may grow up to
                             that old peak first. POV-Ray's sample scenes grow it by at most a
                             few hundred MB.
    """

    max_loop_iterations: int = 1_000_000
    max_macro_depth: int = 150
    max_include_depth: int = 64
    max_csg_depth: int = 256
    max_tokens: int = 50_000_000
    max_array_elements: int = 16_777_216
    max_string_length: int = 16_777_216
    max_written_chars: int = 268_435_456
    max_parse_seconds: float = 600.0
    max_parse_memory_mb: int = 8192


PARSE_CLOCK_TOKENS = 1 << 14  # tokens read between two looks at the parse clock (and memory)


def peak_resident_mb() -> float:
    """This process's peak resident memory so far (``getrusage``: no file is opened, so a parse
    reads nothing but what its scene names; reading ``/proc/self/statm`` showed up in the fuzz
    campaign's audit of opened files)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux


# The tokens of files read by earlier parses in this process (the standard include files above all:
# lexing colors.inc, textures.inc and the files they include was about 70 % of loading a small scene
# that includes them). Keyed by the file's path and a digest of its text, not by its modification
# time: a file rewritten within one tick of the file system's clock is read again. Token lists are
# never mutated, so parses share them.
_LEXED: collections.OrderedDict[tuple, list] = collections.OrderedDict()
_LEXED_LOCK = threading.Lock()
LEXED_CACHE_TOKENS = 1 << 20  # tokens kept in all (about 200 MB at most)


def _lexed_file(path: str) -> list[Token]:
    """``path``'s tokens, from the cache when its text is unchanged."""
    text = Path(path).read_text(encoding="utf-8", errors="replace")
    key = (path, hashlib.blake2b(text.encode("utf-8", "surrogatepass"), digest_size=16).digest())
    with _LEXED_LOCK:
        toks = _LEXED.get(key)
        if toks is not None:
            _LEXED.move_to_end(key)
            return toks
    toks = tokenize(text, path)
    if len(toks) > LEXED_CACHE_TOKENS:
        # a file larger than the whole cache (a generated scene) is not kept: its tokens, ~30 per
        # object, would stay alive for the process, and every full collection of Python's cyclic
        # GC walks them all (for 100,000 spheres, 3 M tokens: ~2 s of the compile after the parse)
        return toks
    with _LEXED_LOCK:
        _LEXED[key] = toks
        total = sum(len(t) for t in _LEXED.values())
        while total > LEXED_CACHE_TOKENS and len(_LEXED) > 1:
            total -= len(_LEXED.popitem(last=False)[1])
    return toks


def _literal_vector(toks: list, i: int, stop: int) -> tuple[tuple[float, ...], int] | None:
    """The components of a vector literal whose '<' is before ``toks[i]`` when they are 2 to 5
    plain numbers, each with an optional sign, between commas, and the index after its '>'."""
    out = []
    stop = min(stop, i + 16)
    while i + 1 < stop:
        t = toks[i]
        kind, value = t[0], t[1]
        if kind == OP and (value == "-" or value == "+"):
            i += 1
            t = toks[i]
            if t[0] != NUM:
                return None
            out.append(-t[1] if value == "-" else t[1])
        elif kind == NUM:
            out.append(value)
        else:
            return None
        t = toks[i + 1]
        if t[0] != OP:
            return None
        if t[1] == ">":
            return (tuple(out), i + 2) if 2 <= len(out) <= 5 else None
        if t[1] != ",":
            return None
        i += 2
    return None


@dataclasses.dataclass
class Frame:
    """A position in a token list: a file, an include, a macro body or a function body."""

    tokens: list
    pos: int
    stop: int
    kind: str  # main, include, macro, func
    scope: bool  # pushed a symbol table
    call_loc: SourceLoc | None = None
    path: str | None = None
    conds: list = dataclasses.field(default_factory=list)


class Stream:
    """Tokens with directives applied, plus the symbol tables (global first)."""

    def __init__(self, *, include_paths=(), strict=False, limits: Limits | None = None):
        self.frames: list[Frame] = []
        self.scopes: list[dict] = [{}]
        self.la: Token | None = None  # lookahead (already processed, or a raw '#')
        self.la_raw = False
        self.last_hash: Token | None = None
        self.last = None  # last consumed token
        self.strict = strict
        self.limits = limits or Limits()
        self.max_tokens = self.limits.max_tokens
        self.include_paths = [Path(p) for p in include_paths]
        self.warnings: list[SceneWarning] = []
        self.warning_capture: list[list[SceneWarning]] = []
        self.held_warnings: dict[tuple[int, str], tuple[dict, list[SceneWarning]]] = {}
        self._emitted: set[int] = set()  # ids of the warnings in self.warnings
        self.token_cache: dict[str, list] = {}
        # (frame index, open conditionals) where each #declare being read started: see peek_op
        self.stop_marks: list[tuple[int, int]] = []
        self.macro_depth = 0
        self.macro_names: set[str] = set()
        self.tokens_read = 0
        self.deadline = time.monotonic() + self.limits.max_parse_seconds
        self.memory_ceiling = peak_resident_mb() + self.limits.max_parse_memory_mb
        self.directives = None  # set by the interpreter: name -> handler(hash_token)
        self.macro_call = None  # set by the interpreter: handler(ident token, MacroDef)

    # ---- errors and warnings -------------------------------------------------------------
    def chain(self) -> tuple[SourceLoc, ...]:
        return tuple(f.call_loc for f in reversed(self.frames) if f.call_loc is not None)

    def error(self, message: str, loc: SourceLoc | None = None) -> SceneError:
        if loc is None:
            loc = self.here()
        return SceneError(message, loc, self.chain())

    def here(self) -> SourceLoc | None:
        if self.la is not None:
            return self.la.loc
        if self.last is not None:
            return self.last.loc
        return None

    def warn(self, feature: str, message: str, loc: SourceLoc | None = None) -> None:
        self._report(SceneWarning(feature, message, loc or self.here()))

    def warn_now(self, feature: str, message: str, loc: SourceLoc | None = None) -> None:
        """Reports at once, even while a value is being declared: for what already changed the
        parse (a ``trace()`` that cannot see an object decides ``#if``s and placements)."""
        self._emit(SceneWarning(feature, message, loc or self.here()))

    def _report(self, w: SceneWarning) -> None:
        if self.warning_capture:  # reading a #declare/#local value: reported when it is used
            self.warning_capture[-1].append(w)
        else:
            self._emit(w)

    def _emit(self, w: SceneWarning) -> None:
        if id(w) in self._emitted:  # a held warning that several values carried
            return
        if self.strict:
            raise self.error(f"{w.message} [{w.feature}]", w.location)
        self._emitted.add(id(w))
        self.warnings.append(w)
        logger.warning("%s", w)

    # Warnings raised while a #declare/#local value is read wait with the identifier until the
    # identifier is used: textures.inc declares dozens of textures with normal { } blocks, and a
    # scene using none of them should not hear about those. Nothing reaches the scene unreported.
    def hold_warnings(self, table: dict, name: str, held: list[SceneWarning]) -> None:
        """Holds ``held`` for the binding ``table[name]`` (as ``_write`` resolved it)."""
        if held:
            self.held_warnings[(id(table), name)] = (table, held)  # the table ref keeps the id unique
        else:
            self.held_warnings.pop((id(table), name), None)

    def _release_warnings(self, table: dict, name: str) -> None:
        """The warnings held for ``table[name]``, now used. Read into a value being declared, they
        pass to that value and stay held here too: the value may never be used while the name is
        (``#declare P = trace(Land, …)`` before ``object { Land }``); each is reported once."""
        key = (id(table), name)
        held = self.held_warnings.get(key) if self.warning_capture else self.held_warnings.pop(key, None)
        if held is not None:
            for w in held[1]:
                self._report(w)

    # ---- files ---------------------------------------------------------------------------
    def file_tokens(self, path: str) -> list[Token]:
        toks = self.token_cache.get(path)
        if toks is None:
            try:
                toks = _lexed_file(path)
            except OSError as e:
                raise self.error(f"cannot read {path}: {e.strerror}") from None
            self.token_cache[path] = toks
        return toks

    def push_main(self, tokens: list[Token], path: str | None) -> None:
        self.frames.append(Frame(tokens, 0, len(tokens) - 1, "main", False, path=path))

    def read_roots(self) -> list[Path]:
        """The folders a scene may read from (semantics §9): the main scene file's folder (the
        working folder for a scene given as text), the ``-L`` folders, ``$RAYTRACER_INCLUDE_PATH``
        and POV-Ray's include folder — the spirit of POV-Ray's I/O restrictions."""
        main = next((f.path for f in self.frames if f.kind == "main" and f.path is not None), None)
        roots = [Path(main).parent if main is not None else Path(".")]
        roots += self.include_paths
        env = os.environ.get("RAYTRACER_INCLUDE_PATH", "")
        roots += [Path(d) for d in env.split(os.pathsep) if d]
        if STANDARD_INCLUDE.is_dir():
            roots.append(STANDARD_INCLUDE)
        return roots

    def resolve_include(self, name: str, loc: SourceLoc, what: str = "an include file") -> str:
        """Search order: including file's folder, include_paths, $RAYTRACER_INCLUDE_PATH, POV's folder.
        The file found must lie (symbolic links resolved) inside one of :meth:`read_roots`."""
        roots = self.read_roots()
        if os.path.isabs(name):
            if not os.path.isfile(name):
                raise self.error(f'expected {what}, found no file "{name}"', loc)
            return self._confined(name, name, roots, loc)
        dirs = []
        for f in reversed(self.frames):
            if f.path is not None and f.kind in ("main", "include"):
                dirs.append(Path(f.path).parent)
                break
        dirs += roots[1:] if dirs else roots  # the main folder is the including file's or first
        for d in dirs:
            for cand in (name, name.lower()):
                p = d / cand
                if os.path.isfile(p):  # (Path.is_file raises for a name too long)
                    return self._confined(str(p), name, roots, loc)
        where = ", ".join(str(d) for d in dirs)
        raise self.error(f'expected {what}, found no "{name}" in {where}', loc)

    def _confined(self, path: str, name: str, roots: list[Path], loc: SourceLoc) -> str:
        real = Path(os.path.realpath(path))
        if any(real.is_relative_to(os.path.realpath(r)) for r in roots):
            return path
        # POV-Ray's own include folder is the system's: Debian links its fonts there from
        # /usr/share/fonts, and those links are the package's, not a scene's
        standard = os.path.realpath(STANDARD_INCLUDE)
        if STANDARD_INCLUDE.is_dir() and os.path.realpath(Path(path).parent) == standard:
            return path
        raise self.error(f'#include "{name}" is outside the folders a scene may read (the scene\'s '
                         f"folder, -L folders, $RAYTRACER_INCLUDE_PATH, POV-Ray's include folder); "
                         "add its folder with -L (include_paths=) to allow it", loc)

    def push_include(self, name: str, loc: SourceLoc) -> None:
        if name in getattr(self, "virtual_files", {}):  # written by this scene with #write
            toks = tokenize("".join(self.virtual_files[name]), f"<written by the scene: {name}>")
            self.scopes.append({})
            self.frames.append(Frame(toks, 0, len(toks) - 1, "include", True, call_loc=loc, path=None))
            return
        path = self.resolve_include(name, loc)
        real = os.path.realpath(path)
        depth = sum(1 for f in self.frames if f.kind == "include")
        if depth >= self.limits.max_include_depth:
            # a file may include itself (POV-Ray's recursion idiom, guarded by a counter): only
            # the depth stops a cycle without a guard
            again = any(f.path is not None and os.path.realpath(f.path) == real for f in self.frames)
            raise self.error(f"include depth exceeds {self.limits.max_include_depth}"
                             + (f' ("{name}" is already being included: a cycle without a guard?)'
                                if again else ""), loc)
        toks = self.file_tokens(path)
        self.scopes.append({})
        self.frames.append(Frame(toks, 0, len(toks) - 1, "include", True, call_loc=loc, path=path))

    def unread_lookahead(self) -> None:
        """Puts the lookahead token back in front of the current frame (before pushing a new one)."""
        if self.la is not None:
            tok = self.la
            self.la, self.la_raw = None, False
            self.frames.append(Frame([tok, tok], 0, 1, "pushback", False))

    # ---- frames --------------------------------------------------------------------------
    def pop_frame(self) -> Frame:
        f = self.frames.pop()
        if f.scope:
            table = self.scopes.pop()
            if self.held_warnings:  # a macro's locals are gone: so are their unused warnings
                for key in [k for k in self.held_warnings if k[0] == id(table)]:
                    del self.held_warnings[key]
        if f.kind in ("macro", "func"):
            self.macro_depth -= 1
        return f

    def raw(self) -> Token:
        """The next token of the current frame, with no directive processing."""
        while True:
            f = self.frames[-1]
            pos = f.pos
            if pos < f.stop:
                f.pos = pos + 1
                self.tokens_read += 1
                if self.tokens_read > self.max_tokens or self.tokens_read % PARSE_CLOCK_TOKENS == 0:
                    self._check_budget()
                return f.tokens[pos]
            if f.kind in ("main", "func"):
                tok = f.tokens[f.stop] if f.stop < len(f.tokens) else f.tokens[-1]
                if f.kind == "func":
                    return Token.at(EOF, None, tok.loc)
                return tok
            self.pop_frame()

    def reserve(self, nbytes: int, loc) -> None:
        """Before an allocation of ``nbytes`` that a few tokens can ask for (an array): stop at
        ``loc`` if it would take the parse's memory past its bound, rather than up to
        ``PARSE_CLOCK_TOKENS`` tokens later (a hundred ``array[16000000]`` are 1,200 tokens and
        13 GB)."""
        if peak_resident_mb() + nbytes / (1 << 20) > self.memory_ceiling:
            raise self.error(
                f"the scene's parse would grow memory by more than {self.limits.max_parse_memory_mb} MB "
                f"here ({nbytes / (1 << 20):.0f} MB more asked; the limit is Limits.max_parse_memory_mb)",
                loc)

    def _check_budget(self) -> None:
        """The token budget, and every ``PARSE_CLOCK_TOKENS`` tokens the parse's clock and memory."""
        if self.tokens_read > self.max_tokens:
            raise self.error(f"the scene reads more than {self.max_tokens} tokens")
        if time.monotonic() > self.deadline:
            raise self.error(
                f"the scene took more than {self.limits.max_parse_seconds:g} s to parse "
                "(stopped here; the limit is Limits.max_parse_seconds, --parse-timeout)")
        if peak_resident_mb() > self.memory_ceiling:
            raise self.error(
                f"the scene's parse grew memory by more than "
                f"{self.limits.max_parse_memory_mb} MB (stopped here; the limit is "
                "Limits.max_parse_memory_mb)")

    def literal_components(self) -> tuple[float, ...] | None:
        """After a vector's '<': its components and its '>' read at once when they are plain
        numbers (each with an optional sign) between commas, which is what the token-by-token
        parse would give them; None, with nothing read, for anything else. A ``mesh2``'s lists are
        such vectors by the hundred thousand, and the expression parser spent ~10 µs on each."""
        f = self.frames[-1]
        if self.la is not None or not 0 < f.pos <= f.stop or f.tokens[f.pos - 1] is not self.last:
            return None  # the '<' read last is not the token before this frame's position
        got = _literal_vector(f.tokens, f.pos, f.stop)
        if got is None:
            return None
        self._skip_to(f, got[1])
        return got[0]

    def literal_vector(self) -> tuple[float, ...] | None:
        """With a '<' peeked: a whole expression that is a vector of plain numbers (as
        ``literal_components``) followed by ',' or '}', which end it, read up to that token; None,
        with nothing read, otherwise."""
        la = self.la
        f = self.frames[-1]
        if self.la_raw or la is None or not 0 < f.pos <= f.stop or f.tokens[f.pos - 1] is not la:
            return None
        got = _literal_vector(f.tokens, f.pos, f.stop)
        if got is None or got[1] >= f.stop:
            return None
        after = f.tokens[got[1]]
        if after[0] != OP or (after[1] != "," and after[1] != "}"):
            return None
        self.la = None
        self._skip_to(f, got[1])
        return got[0]

    def _skip_to(self, f: Frame, pos: int) -> None:
        """Moves frame ``f`` (the current one) to ``pos``, as ``raw`` would read its tokens."""
        self.last = f.tokens[pos - 1]
        before = self.tokens_read
        self.tokens_read += pos - f.pos
        f.pos = pos
        if (self.tokens_read > self.max_tokens
                or before // PARSE_CLOCK_TOKENS != self.tokens_read // PARSE_CLOCK_TOKENS):
            self._check_budget()

    def raw_peek(self, k: int = 0) -> Token | None:
        """Looks ``k`` raw tokens ahead in the current frame (None past its end)."""
        f = self.frames[-1]
        while f.kind == "pushback" and f.pos >= f.stop:
            self.frames.pop()
            f = self.frames[-1]
        i = f.pos + k
        return f.tokens[i] if i < f.stop else None

    def _fetch(self, stop_hash: bool) -> Token:
        while True:
            if self.la is not None:  # a directive handler read one token too far
                tok, self.la, self.la_raw = self.la, None, False
            else:
                tok = self.raw()
            if tok.kind == OP and tok.value == "#":
                if stop_hash and self._stops_declare(True):
                    return tok
                self.directive(tok)
                continue
            if tok.kind == ID and tok.value in self.macro_names:
                m = self.lookup_macro(tok.value)
                if m is not None:
                    if stop_hash and self._stops_declare(False):
                        return tok
                    self.macro_call(tok, m)
                    continue
            return tok

    def push_stop_mark(self) -> None:
        f = self._frame_index()
        self.stop_marks.append((f, len(self.frames[f].conds)))

    def _frame_index(self) -> int:
        i = len(self.frames) - 1
        while self.frames[i].kind == "pushback" and i > 0:
            i -= 1
        return i

    def _stops_declare(self, is_directive: bool) -> bool:
        """Whether a directive or macro call found after a #declare's value ends the value.

        A missing ';' must not let ``#declare A = 1 #declare B = A`` or a loop's ``#end`` run before
        A is assigned; but directives inside a macro the value calls, and the ``#else``/``#end`` of
        an ``#if`` that began inside the value (``#declare A = #if (c) 1 #else 2 #end;``), run.
        """
        frame, conds = self.stop_marks[-1]
        here = self._frame_index()
        if here > frame:
            return False
        if here < frame or not is_directive:
            return True
        name = self.raw_peek()
        closes = name is not None and name.kind == ID and name.value in (
            "else", "elseif", "end", "case", "range", "break")
        return not (closes and len(self.frames[here].conds) > conds)

    def directive(self, hash_tok: Token) -> None:
        name = self.raw_peek()
        if name is None or name.kind != ID:
            # POV-Ray ignores a stray '#'; so do we, with a warning
            self.warn("#", "a '#' not followed by a directive is ignored", hash_tok.loc)
            return
        name = self.raw()
        handler = self.directives.get(name.value)
        if handler is None:
            raise self.error(f"expected a directive, found '#{name.value}'", name.loc)
        handler(name)

    # ---- public token API ----------------------------------------------------------------
    def peek(self) -> Token:
        la = self.la
        if la is None or self.la_raw:
            la = self.la = self._fetch(False)
        return la

    def peek_op(self) -> Token:
        """Like peek, but while reading a #declare expression a directive or macro call ends it."""
        if self.la is None:
            tok = self._fetch(bool(self.stop_marks))
            if self.stop_marks and ((tok.kind == OP and tok.value == "#") or (
                    tok.kind == ID and self.lookup_macro(tok.value) is not None)):
                self.la_raw = True  # a directive or macro call: run it only after the #declare
            self.la = tok
        return self.la

    def next(self) -> Token:
        tok = self.la
        if tok is None or self.la_raw:
            tok = self._fetch(False)
        self.la = None
        self.last = tok
        return tok

    def is_op(self, value: str) -> bool:
        t = self.la
        if t is None or self.la_raw:
            t = self.la = self._fetch(False)
        return t.kind == OP and t.value == value

    def is_id(self, value: str) -> bool:
        t = self.peek()
        return t.kind == ID and t.value == value

    def accept_op(self, value: str) -> bool:
        t = self.la
        if t is None or self.la_raw:
            t = self.la = self._fetch(False)
        if t.kind == OP and t.value == value:
            self.la = None
            self.last = t
            return True
        return False

    def accept_id(self, value: str) -> bool:
        if self.is_id(value):
            self.next()
            return True
        return False

    def expect_op(self, value: str, what: str | None = None) -> Token:
        t = self.la
        if t is None or self.la_raw:
            t = self.la = self._fetch(False)
        if t.kind != OP or t.value != value:
            raise self.error(f"expected {what or repr(value)}, found {t.describe()}", t.loc)
        self.la = None
        self.last = t
        return t

    def expect_ident(self, what: str = "an identifier") -> Token:
        t = self.peek()
        if t.kind != ID:
            raise self.error(f"expected {what}, found {t.describe()}", t.loc)
        return self.next()

    def raw_ident(self, what: str = "an identifier") -> Token:
        """An identifier read without macro expansion (for #declare, #ifdef, #undef …)."""
        if self.la is not None:
            t = self.la
            if t.kind != ID:
                raise self.error(f"expected {what}, found {t.describe()}", t.loc)
            self.la = None
            self.last = t
            return t
        t = self.raw()
        while t.kind == OP and t.value == "#":
            self.directive(t)
            t = self.raw()
        if t.kind != ID:
            raise self.error(f"expected {what}, found {t.describe()}", t.loc)
        self.last = t
        return t

    # ---- symbol tables -------------------------------------------------------------------
    def find(self, name: str):
        """(table, value) of the most local binding of ``name`` (aliases followed), or (None, None)."""
        for table in reversed(self.scopes):
            if name in table:
                v = table[name]
                while isinstance(v, Alias):
                    table, name = v.table, v.name
                    if name not in table:
                        return None, None
                    v = table[name]
                if self.held_warnings:
                    self._release_warnings(table, name)
                return table, v
        return None, None

    def lookup(self, name: str):
        return self.find(name)[1]

    def lookup_macro(self, name: str):
        if name not in self.macro_names:  # fast path: most identifiers never named a macro
            return None
        for table in reversed(self.scopes):
            if name in table:
                v = table[name]
                return v if isinstance(v, MacroDef) else None
        return None

    def _write(self, table: dict, name: str, value) -> tuple[dict, str]:
        """Assigns through aliases; returns the binding written (table, name)."""
        v = table.get(name)
        while isinstance(v, Alias):
            table, name = v.table, v.name
            v = table.get(name)
        table[name] = value
        return table, name

    def declare(self, name: str, value) -> None:
        """#declare: updates the most local existing binding, else creates a global one."""
        for table in reversed(self.scopes):
            if name in table:
                self._write(table, name, value)
                return
        self.scopes[0][name] = value

    def local(self, name: str, value) -> None:
        self._write(self.scopes[-1], name, value)

    def undef(self, name: str) -> None:
        for table in reversed(self.scopes):
            if name in table:
                del table[name]
                return
