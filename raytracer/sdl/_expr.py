"""Expressions: POV-Ray's float/vector/colour/string arithmetic with its precedence.

Lowest to highest: ``?:``; ``|`` ``&``; comparisons (these three only inside parentheses, as the
manual requires: at the top level ``<`` starts a vector); ``+ -``; ``* /``; unary ``- + !``; ``^`` (function
bodies); postfix ``.x``/``.red`` and ``[i]``; primaries (literals, ``< >`` vectors, identifiers,
built-in constants and functions, colour keywords).
"""

from __future__ import annotations

import math

from ._builtins import BUILTIN_FUNCTIONS, constant
from ._convert import (  # re-exported: the builders read values through this module
    EPSILON,
    as_color,
    as_float,
    as_int,
    as_vector,
    finite,
    fmt_number,
    truthy,
    type_name,
)
from ._lexer import ID, NUM, OP, STR
from ._values import ArrayValue, FunctionValue, SplineValue, Vec

COLOR_KEYWORDS = ("color", "colour", "rgb", "rgbf", "rgbt", "rgbft", "srgb", "srgbf", "srgbt", "srgbft")
_COLOR_PARTS = {"red": 0, "green": 1, "blue": 2, "filter": 3, "transmit": 4}
_DOT = {"x": 0, "u": 0, "red": 0, "y": 1, "v": 1, "green": 1, "z": 2, "blue": 2,
        "t": 3, "filter": 3, "transmit": 4}


# ---- value helpers ---------------------------------------------------------------------------
def _num(p, v, loc):
    if isinstance(v, (float, Vec)):
        return v
    raise p.error(f"expected a float or vector, found {type_name(v)}", loc)


def binop(p, op: str, a, b, loc):
    a, b = _num(p, a, loc), _num(p, b, loc)
    if isinstance(a, float) and isinstance(b, float):
        return _fop(p, op, a, b, loc)
    n = max(len(a) if isinstance(a, Vec) else 0, len(b) if isinstance(b, Vec) else 0)
    ft = (isinstance(a, Vec) and a.ft) or (isinstance(b, Vec) and b.ft)
    ac = a.padded(n) if isinstance(a, Vec) else (a,) * n
    bc = b.padded(n) if isinstance(b, Vec) else (b,) * n
    return Vec([_fop(p, op, x, y, loc) for x, y in zip(ac, bc, strict=True)], ft)


def _fop(p, op, x, y, loc) -> float:
    if op == "+":
        r = x + y
    elif op == "-":
        r = x - y
    elif op == "*":
        r = x * y
    elif op == "/":
        if y == 0.0:
            raise p.error("division by zero", loc)
        r = x / y
    elif op == "^":
        try:
            return float(math.pow(x, y))
        except (ValueError, OverflowError):
            raise p.error(f"cannot raise {fmt_number(x)} to the power {fmt_number(y)}", loc) from None
    else:
        raise p.error(f"unknown operator {op}", loc)
    if r - r == 0.0:  # finite (the inputs are finite: only an overflow makes an infinity)
        return r
    return finite(p, r, loc, f"{fmt_number(x)} {op} {fmt_number(y)}")


# ---- grammar ---------------------------------------------------------------------------------
def parse_expr(p):
    """A full expression (ternary level)."""
    first = p.peek()  # (its loc is found only when needed: a token's line is looked up)
    c = _logic(p)
    if p.in_parens and _is(p, "?"):
        p.next()
        a = parse_expr(p)
        p.expect_op(":")
        b = parse_expr(p)
        return a if truthy(p, c, first.loc) else b
    return c


def _is(p, op: str) -> bool:
    t = p.peek_op()
    return t.kind == OP and t.value == op


# Binary operators by binding level (higher binds tighter). Comparisons and & | exist only inside
# parentheses: as the manual says, at the top level '<' starts a vector.
_LEVELS_TOP = {"+": 3, "-": 3, "*": 4, "/": 4}
_LEVELS_PAREN = {"&": 1, "|": 1, "<": 2, "<=": 2, "=": 2, "!=": 2, ">=": 2, ">": 2, **_LEVELS_TOP}


def _logic(p, min_level: int = 1):
    """Binary operators by precedence climbing: one loop instead of a function per level."""
    a = _unary(p)
    levels = _LEVELS_PAREN if p.in_parens else _LEVELS_TOP
    while True:
        t = p.la or p.peek_op()  # (a token is a non-empty tuple: truthy)
        if t.kind != OP:
            return a
        level = levels.get(t.value)
        if level is None or level < min_level:
            return a
        loc = p.next().loc
        b = _logic(p, level + 1)
        op = t.value
        if level >= 3:
            a = binop(p, op, a, b, loc)
        elif level == 2:
            a = _compare(p, op, a, b, loc)
        else:
            x, y = truthy(p, a, loc), truthy(p, b, loc)
            a = float((x and y) if op == "&" else (x or y))


def _compare(p, op, a, b, loc) -> float:
    if isinstance(a, str) and isinstance(b, str):
        x, y = (a > b) - (a < b), 0.0
    else:
        x, y = as_float(p, a, loc), as_float(p, b, loc)
    if op == "=":
        return float(abs(x - y) < EPSILON)
    if op == "!=":
        return float(abs(x - y) >= EPSILON)
    return float({"<": x < y, "<=": x <= y, ">=": x >= y, ">": x > y}[op])


def _unary(p):
    t = p.peek()
    if t.kind == OP and t.value in ("-", "+", "!"):
        p.next()
        v = _unary(p)
        if t.value == "-":
            return -v if type(v) is float else binop(p, "*", v, -1.0, t.loc)
        if t.value == "!":
            return float(not truthy(p, v, t.loc))
        return _num(p, v, t.loc)
    # postfix: primary, then .x / [i] (inlined: this is the interpreter's hottest path)
    if t.kind == NUM:
        p.la = None
        p.last = t
        a = t.value
    else:
        a = _primary(p)
    while True:
        t = p.la or p.peek_op()
        if t.kind != OP:
            return a
        if t.value == "[" and isinstance(a, ArrayValue):
            a = _index(p, a)
        elif t.value == ".":
            loc = p.next().loc
            a = dot(p, a, p.expect_ident("a component name after '.'").value, loc)
        else:
            break
    if t.value == "^":
        loc = p.next().loc
        a = binop(p, "^", a, _unary(p), loc)
    return a


def dot(p, v, name: str, loc):
    if isinstance(v, float):
        v = Vec((v,) * 5, True)
    if not isinstance(v, Vec):
        raise p.error(f"expected a vector or colour before '.{name}', found {type_name(v)}", loc)
    if name in ("gray", "grey"):
        r, g, b = v.padded(3)
        return 0.297 * r + 0.589 * g + 0.114 * b
    if name in ("hf",):
        return 0.0
    i = _DOT.get(name)
    if i is None:
        raise p.error(f"expected a component such as .x or .red, found '.{name}'", loc)
    if i >= len(v):
        raise p.error(f"the {len(v)}-component vector has no '.{name}'", loc)
    return v.c[i]


def index_list(p) -> list[int]:
    """``[i][j]…`` after an array name being assigned (``#declare A[i] = …``)."""
    idx = []
    while _is(p, "["):
        p.next()
        loc = p.peek().loc
        idx.append(as_int(p, parse_expr_paren(p), loc, "an array index", 0))
        p.expect_op("]")
    return idx


def _index(p, arr: ArrayValue):
    loc = p.peek().loc
    idx = []
    while _is(p, "[") and len(idx) < len(arr.dims):
        p.next()
        i_loc = p.peek().loc
        i = as_float(p, parse_expr_paren(p), i_loc)
        # an index a hair below an integer (0.1*30 = 2.9999…) means that integer (i is finite)
        idx.append(as_int(p, math.floor(i + 1e-9), i_loc, "an array index", 0, arr.dims[len(idx)] - 1))
        p.expect_op("]")
    if len(idx) < len(arr.dims):
        # a sub-array: copy the slice
        size = 1
        for d in arr.dims[len(idx):]:
            size *= d
        start = arr.flat_index(idx + [0] * (len(arr.dims) - len(idx)))
        p.reserve(8 * size, i_loc)
        return ArrayValue(arr.dims[len(idx):], arr.data[start:start + size])
    v = arr.data[arr.flat_index(idx)]
    if v is None:
        raise p.error(f"array element {idx} was never initialised", loc)
    return v


def parse_expr_paren(p):
    """An expression inside () [] or function arguments: comparisons, & | and ?: are allowed."""
    saved, p.in_parens = p.in_parens, True
    try:
        return parse_expr(p)
    finally:
        p.in_parens = saved


def parse_vector_literal(p):
    start = p.expect_op("<")
    comps = p.literal_components()
    if comps is not None:
        return Vec.of_floats(comps)
    comps = _components(p, start, 5)
    if not 2 <= len(comps) <= 5:
        raise p.error(f"expected a vector of 2 to 5 components, found {len(comps)}", start.loc)
    return Vec(comps)


def parse_coefficients(p, count: int) -> tuple[float, ...]:
    """``<A1, …, A_count>``: a shape's list of ``count`` coefficients (a polynomial's 35), a
    vector of more components than an expression's value can have."""
    start = p.expect_op("<")
    comps = _components(p, start, count)
    if len(comps) != count:
        raise p.error(f"expected {count} coefficients, found {len(comps)}", start.loc)
    return tuple(comps)


def _components(p, start, limit: int) -> list:
    """A vector's components after its '<', and its '>' (at most ``limit`` + 1 read)."""
    saved, p.in_parens = p.in_parens, False
    try:
        comps = [_component(p, parse_expr(p), start)]
        while not p.is_op(">"):  # commas between components are optional
            if p.accept_op(",") and p.is_op(">"):
                break  # a trailing comma
            comps.append(_component(p, parse_expr(p), start))
            if len(comps) > limit:
                break
    finally:
        p.in_parens = saved
    p.expect_op(">", "'>' to close the vector")
    return comps


def _component(p, v, start) -> float:
    return v if type(v) is float else as_float(p, v, start.loc)


def _primary(p):
    t = p.peek()
    if t.kind == NUM:
        p.next()
        return t.value
    if t.kind == STR:
        p.next()
        return t.value
    if t.kind == OP:
        if t.value == "(":
            p.next()
            v = parse_expr_paren(p)
            p.expect_op(")")
            return v
        if t.value == "<":
            return parse_vector_literal(p)
        raise p.error(f"expected a value, found {t.describe()}", t.loc)
    if t.kind == ID:
        return _identifier(p, t)
    raise p.error(f"expected a value, found {t.describe()}", t.loc)


def _identifier(p, t):
    name = t.value
    table, v = p.find(name)
    if table is not None:
        p.next()
        if isinstance(v, FunctionValue) and _is(p, "("):
            return p.call_function(v, t)
        if isinstance(v, SplineValue) and _is(p, "("):
            return p.call_spline(v, t)
        return v
    if name in COLOR_KEYWORDS:
        return parse_color(p)
    fn = BUILTIN_FUNCTIONS.get(name)
    if fn is not None:
        p.next()
        return _finite_result(p, fn(p, t), t)
    c = constant(p, name)
    if c is not None:
        p.next()
        return c
    if name == "function":
        return p.parse_function()
    raise p.error(f"expected a value, found undeclared identifier '{name}'", t.loc)


def _finite_result(p, v, t):
    """A built-in's result, refused when it left the float range (degrees(1e308), vlength …)."""
    if isinstance(v, float):
        return finite(p, v, t.loc, f"the result of {t.value}()")
    if isinstance(v, Vec):
        for c in v.c:
            finite(p, c, t.loc, f"the result of {t.value}()")
    return v


# ---- colours ---------------------------------------------------------------------------------
def parse_color(p) -> Vec:
    """``[color|colour] (rgb… V | red r | green g | blue b | filter f | transmit t | expression)…``."""
    p.accept_id("color") or p.accept_id("colour")
    c = None
    while True:
        t = p.peek()
        if t.kind == ID and t.value in ("rgb", "rgbf", "rgbt", "rgbft", "srgb", "srgbf", "srgbt", "srgbft"):
            if c is not None:  # a second rgb… starts the next colour (checker rgb A rgb B)
                return c
            p.next()
            c = _keyword_color(p, t.value, parse_expr(p), t.loc)
        elif t.kind == ID and (t.value in _COLOR_PARTS or t.value == "alpha"):
            p.next()
            val = as_float(p, parse_expr(p), t.loc)
            if t.value == "alpha":
                p.warn("alpha", "'alpha' is obsolete; treated as transmit", t.loc)
            i = _COLOR_PARTS.get(t.value, 4)
            base = list((c or Vec((0, 0, 0, 0, 0))).padded(5))
            base[i] = val
            c = Vec(base, (c.ft if c else False) or i >= 3)
        elif c is None:
            c = as_color(p, parse_expr(p), t.loc)
        else:
            return c


def _keyword_color(p, kw: str, v, loc) -> Vec:
    srgb = kw.startswith("s")
    kw = kw.lstrip("s")
    n = {"rgb": 3, "rgbf": 4, "rgbt": 4, "rgbft": 5}[kw]
    if isinstance(v, float):
        comps = [v] * n
    else:
        comps = list(as_vector(p, v, n, loc))
    if srgb:
        comps[:3] = [p.srgb_to_working(x) for x in comps[:3]]
    if kw == "rgb":
        return Vec(comps[:3] + [0.0, 0.0])
    if kw == "rgbf":
        return Vec(comps[:4] + [0.0], True)
    if kw == "rgbt":
        return Vec(comps[:3] + [0.0, comps[3]], True)
    return Vec(comps, True)
