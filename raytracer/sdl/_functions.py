"""User functions compiled for the renderer: ``function { … }`` → an expression
(``raytracer/patterns/_expression.py``) and its constants.

POV-Ray compiles a function when it is declared, reading the declared floats it names then; here a
function is compiled where a shape or pattern takes it, with the identifiers bound at that point
(the same values unless the scene re-declares them in between). The body is read with the float
expression grammar of the interpreter (``_expr.py``), with comparisons and ``&``/``|`` allowed as
inside parentheses. Calls to other user functions are inlined with their arguments.

POV-Ray's internal functions (``functions.inc``'s ``f_… = function { internal(n) }``) are
compiled where ``patterns._expression.INTERNAL`` has them. What is not compiled raises
:class:`Unsupported` (the caller leaves the object out with a warning that names it): the other
internal functions, pattern, pigment, spline and transform functions, vector members of declared
vectors other than a constant component, ``sum``/``prod``.
"""

from __future__ import annotations

from ..patterns._expression import ARITY, INTERNAL, Expression
from ._builtins import constant
from ._expr import _LEVELS_PAREN, dot
from ._lexer import ID, NUM, OP
from ._values import FunctionValue, Vec

MAX_INLINE_DEPTH = 64
MAX_WHOLE_POWER = 16  # x^n for a written whole n up to this: repeated products (x^2 of x < 0)


class Unsupported(Exception):
    """A construct of the function language that is not compiled; ``loc`` where it is."""

    def __init__(self, what: str, loc):
        super().__init__(what)
        self.what, self.loc = what, loc


class Malformed(Unsupported):
    """A function body that is not a function (a syntax error, an undeclared name): the scene's
    error, as POV-Ray's."""


def compile_function(p, fn: FunctionValue, n_args: int = 3) -> tuple[Expression, tuple[float, ...]]:
    """``fn`` called with the arguments ``(arg 0 … arg n_args−1)``: its expression and constants.
    ``p`` is the interpreter (identifiers are looked up in its scope)."""
    compiler = _Compiler(p)
    args = tuple(("arg", k) for k in range(n_args))
    tree = compiler.inline(fn, args, fn.loc)
    return tree, tuple(compiler.constants)


class _Compiler:
    def __init__(self, p):
        self.p = p
        self.constants: list[float] = []
        self.depth = 0

    def const(self, value: float) -> Expression:
        self.constants.append(float(value))
        return ("const", len(self.constants) - 1)

    def inline(self, fn: FunctionValue, args: tuple, loc) -> Expression:
        number = _internal_number(fn)
        if number is not None:
            if number not in INTERNAL:
                raise Unsupported(f"POV-Ray's internal function {number} (functions.inc)", loc)
            name, count, _ = INTERNAL[number]
            if len(args) != count:
                raise Malformed(f"expected {count} arguments to {name}, found {len(args)}", loc)
            return ("internal", number, *args)
        if fn.kind != "float":
            head = fn.tokens[0].value if fn.tokens else "function"
            raise Unsupported(f"a {head} function" if head != "internal" else
                              "POV-Ray's internal functions (functions.inc)", loc)
        if len(args) != len(fn.params):
            raise Malformed(f"expected {len(fn.params)} arguments to the function, found {len(args)}", loc)
        if self.depth >= MAX_INLINE_DEPTH:
            raise Unsupported(f"functions nested deeper than {MAX_INLINE_DEPTH}", loc)
        scope = dict(zip(fn.params, args, strict=True))
        # x and u, y and v name the same parameter
        for a, b in (("x", "u"), ("y", "v")):
            if a in scope and b not in scope:
                scope[b] = scope[a]
            elif b in scope and a not in scope:
                scope[a] = scope[b]
        self.depth += 1
        body = _Body(self, fn.tokens[:-1], scope)
        tree = body.expr()
        if not body.done():
            raise Malformed(f"expected the end of the function body, found {body.peek_desc()}", body.loc())
        self.depth -= 1
        return tree


def _internal_number(fn: FunctionValue) -> int | None:
    """n of a function whose body is ``internal(n)``, else None."""
    t = fn.tokens
    if len(t) >= 4 and t[0].kind == ID and t[0].value == "internal" and t[2].kind == NUM:
        return int(t[2].value)
    return None


class _Body:
    """A recursive-descent reader of one function body's tokens."""

    def __init__(self, compiler: _Compiler, tokens: list, scope: dict):
        self.c, self.toks, self.i, self.scope = compiler, tokens, 0, scope

    # ---- tokens ----
    def done(self) -> bool:
        return self.i >= len(self.toks)

    def peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else None

    def peek_desc(self) -> str:
        t = self.peek()
        return t.describe() if t is not None else "the end"

    def loc(self):
        t = self.peek() or (self.toks[-1] if self.toks else None)
        return t.loc if t is not None else None

    def is_op(self, op: str) -> bool:
        t = self.peek()
        return t is not None and t.kind == OP and t.value == op

    def next(self):
        t = self.peek()
        if t is None:
            raise Malformed("expected a value, found the end of the function body", self.loc())
        self.i += 1
        return t

    def expect(self, op: str):
        if not self.is_op(op):
            raise Malformed(f"expected '{op}' in the function body, found {self.peek_desc()}", self.loc())
        self.i += 1

    # ---- grammar ----
    def expr(self) -> Expression:
        c = self.logic(1)
        if self.is_op("?"):
            self.next()
            a = self.expr()
            self.expect(":")
            b = self.expr()
            return ("if", c, a, b)
        return c

    def logic(self, min_level: int) -> Expression:
        a = self.unary()
        while True:
            t = self.peek()
            if t is None or t.kind != OP:
                return a
            level = _LEVELS_PAREN.get(t.value)  # the interpreter's, as inside parentheses
            if level is None or level < min_level:
                return a
            self.next()
            b = self.logic(level + 1)
            a = (t.value, a, b)

    def unary(self) -> Expression:
        t = self.peek()
        if t is not None and t.kind == OP and t.value in ("-", "+", "!"):
            self.next()
            v = self.unary()
            return ("neg", v) if t.value == "-" else ("not", v) if t.value == "!" else v
        a = self.primary()
        while self.is_op("."):
            loc = self.next().loc
            name = self.next()
            raise Unsupported(f"the member '.{name.value}' of a value computed in a function", loc)
        if self.is_op("^"):
            self.next()
            n = self._whole_number()
            return ("pow", a, n) if n is not None else ("^", a, self.unary())
        return a

    def _whole_number(self) -> int | None:
        """A written whole exponent (``2``, ``-3``) is read and returned; else nothing is read."""
        start, sign = self.i, 1
        if self.is_op("-"):
            sign = -1
            self.next()
        t = self.peek()
        if t is not None and t.kind == NUM and float(t.value).is_integer() \
                and abs(t.value) <= MAX_WHOLE_POWER:
            self.next()
            if not (self.is_op("^") or self.is_op(".")):
                return sign * int(t.value)
        self.i = start
        return None

    def args(self) -> list:
        self.expect("(")
        out = []
        if not self.is_op(")"):
            out.append(self.expr())
            while self.is_op(","):
                self.next()
                out.append(self.expr())
        self.expect(")")
        return out

    def primary(self) -> Expression:
        t = self.next()
        if t.kind == NUM:
            return self.c.const(t.value)
        if t.kind == OP and t.value == "(":
            v = self.expr()
            self.expect(")")
            return v
        if t.kind != ID:
            raise Malformed(f"expected a value in the function body, found {t.describe()}", t.loc)
        name = t.value
        if name in self.scope:
            return self.scope[name]
        if name in ARITY and self.is_op("("):
            args = self.args()
            lo, hi = ARITY[name]
            if not lo <= len(args) <= hi:
                raise Malformed(f"expected {lo if lo == hi else f'{lo} to {hi}'} arguments to {name}(), "
                                f"found {len(args)}", t.loc)
            if name == "pow" and args[1][0] == "const":
                n = self.c.constants[args[1][1]]
                if float(n).is_integer() and abs(n) <= MAX_WHOLE_POWER:
                    return ("pow", args[0], int(n))
            return ("call", name, *args)
        value = constant(self.c.p, name)
        if value is None:
            value = self.c.p.lookup(name)
        if isinstance(value, float | int) and not isinstance(value, bool):
            return self.c.const(value)
        if isinstance(value, Vec) and self.is_op("."):
            self.next()
            member = self.next()
            return self.c.const(dot(self.c.p, value, member.value, member.loc))  # as the interpreter reads it
        if isinstance(value, FunctionValue):
            args = tuple(self.args()) if self.is_op("(") else ()
            return self.c.inline(value, args, t.loc)
        if value is None:
            raise Malformed(f"expected a value in the function body, found undeclared identifier '{name}'",
                            t.loc)
        raise Unsupported(f"'{name}' ({type(value).__name__}) in a function body", t.loc)
