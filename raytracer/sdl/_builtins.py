"""Built-in constants and functions of the SDL (manual 3.3.1.5–3.3.1.8).

Each function is ``fn(p, tok)``: ``p`` is the interpreter, positioned after the function's name;
the function reads its own arguments with ``p.parse_expr_paren()`` (the expression grammar lives in
``_expr``, which looks functions up here: this module does not import it).
"""

from __future__ import annotations

import datetime
import math

import numpy as np

from ._convert import as_float, as_int, as_vector, check_string_length, fmt_number, type_name
from ._lexer import EOF, OP
from ._values import ArrayValue, ObjRec, RandStream, Vec, seed_state

MAX_FORMAT_WIDTH = 1000  # str()/vstr() width and decimal places: beyond it only padding grows

_CONSTANTS = {
    "pi": math.pi, "tau": 2 * math.pi, "true": 1.0, "yes": 1.0, "on": 1.0, "false": 0.0, "no": 0.0,
    "off": 0.0, "clock": 0.0, "clock_delta": 0.0, "clock_on": 0.0, "frame_number": 0.0,
    "initial_clock": 0.0, "final_clock": 0.0, "initial_frame": 0.0, "final_frame": 0.0,
    "radiosity": 0.0,
}
_VECTORS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0),
            "t": (0.0, 0.0, 0.0, 1.0), "u": (1.0, 0.0), "v": (0.0, 1.0)}


def constant(p, name: str):
    if name in _CONSTANTS:
        return p.animation_constants.get(name, _CONSTANTS[name])
    if name in _VECTORS:
        return Vec(_VECTORS[name])
    if name == "image_width":
        return float(p.image_width)
    if name == "image_height":
        return float(p.image_height)
    if name == "version":
        return float(p.version)
    if name == "input_file_name":
        return p.input_file_name
    if name == "now":
        return _now()
    return None


def _args(p, tok, n_min: int, n_max: int | None = None) -> list:
    p.expect_op("(", f"'(' after {tok.value}")
    args = []
    if not p.is_op(")"):
        args.append(p.parse_expr_paren())
        while p.accept_op(","):
            args.append(p.parse_expr_paren())
    p.expect_op(")", f"')' to close {tok.value}(")
    hi = n_min if n_max is None else n_max
    if not n_min <= len(args) <= hi:
        want = n_min if n_min == hi else f"{n_min} to {hi}"
        raise p.error(f"expected {want} arguments to {tok.value}, found {len(args)}", tok.loc)
    return args


def _floats(p, tok, n):
    return [as_float(p, a, tok.loc) for a in _args(p, tok, n)]


def _f1(fn):
    def call(p, tok):
        (a,) = _floats(p, tok, 1)
        try:
            return float(fn(a))
        except (ValueError, OverflowError, ZeroDivisionError):
            raise p.error(f"{tok.value}({fmt_number(a)}) is undefined", tok.loc) from None
    return call


def _f2(fn):
    def call(p, tok):
        a, b = _floats(p, tok, 2)
        try:
            return float(fn(a, b))
        except (ValueError, OverflowError, ZeroDivisionError):
            raise p.error(f"{tok.value}({fmt_number(a)}, {fmt_number(b)}) is undefined", tok.loc) from None
    return call


def _minmax(fn):
    def call(p, tok):
        args = [as_float(p, a, tok.loc) for a in _args(p, tok, 1, 1000)]
        return float(fn(args))
    return call


def _select(p, tok):
    args = _args(p, tok, 3, 4)
    a = as_float(p, args[0], tok.loc)
    if len(args) == 3:
        return args[1] if a < 0 else args[2]
    return args[1] if a < 0 else (args[2] if a == 0 else args[3])


def _mod(a, b):
    return math.fmod(a, b)


def _int(a):
    return float(math.trunc(a))


def _div(a, b):
    return float(math.trunc(a / b))


def _log(a):
    return math.log10(a)


def _vec_args(p, tok, n):
    return [as_vector(p, a, 3, tok.loc) for a in _args(p, tok, n)]


def _vlength(p, tok):
    (a,) = _vec_args(p, tok, 1)
    return math.sqrt(sum(c * c for c in a))


def _vdot(p, tok):
    a, b = _vec_args(p, tok, 2)
    return sum(x * y for x, y in zip(a, b, strict=True))


def _vcross(p, tok):
    a, b = _vec_args(p, tok, 2)
    return Vec((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


def _vnormalize(p, tok):
    (a,) = _vec_args(p, tok, 1)
    n = math.sqrt(sum(c * c for c in a))
    if n == 0:
        return Vec((0.0, 0.0, 0.0))
    return Vec(tuple(c / n for c in a))


def _vrotate(p, tok):
    import numpy as np

    from ..scene._transform import rotation_matrix

    a, r = _vec_args(p, tok, 2)
    return Vec(tuple(rotation_matrix(r)[:3, :3] @ np.asarray(a)))


def _vaxis_rotate(p, tok):
    import numpy as np

    from ..scene._transform import axis_rotation_matrix

    args = _args(p, tok, 3)
    a, ax = as_vector(p, args[0], 3, tok.loc), as_vector(p, args[1], 3, tok.loc)
    ang = as_float(p, args[2], tok.loc)
    if not any(ax):
        raise p.error("vaxis_rotate needs a non-zero axis", tok.loc)
    return Vec(tuple(axis_rotation_matrix(ax, ang)[:3, :3] @ np.asarray(a)))


def _vturbulence(p, tok):
    _args(p, tok, 4)
    p.warn("vturbulence", "vturbulence is not implemented; it returns <0,0,0>", tok.loc)
    return Vec((0.0, 0.0, 0.0))


def _tracer(p):
    if getattr(p, "tracer", None) is None:
        from ._trace import Tracer  # JAX and the renderer's kernels: imported only when used

        p.tracer = Tracer()
    return p.tracer


def _object_arg(p, tok):
    t = p.peek()
    v = p.parse_expr_paren()
    if not isinstance(v, ObjRec):
        raise p.error(f"expected an object identifier in {tok.value}(), found {type_name(v)}", t.loc)
    _warn_unseen(p, tok, v)
    return v


def _unrendered_kinds(rec: ObjRec) -> list[str]:
    """The kinds of the parts of ``rec`` that are not rendered (so not seen by trace/inside)."""
    if not rec.supported:
        return [rec.kind]
    kinds = []
    for child in (*rec.children, *rec.clipped_by):
        if isinstance(child, ObjRec):
            kinds += [k for k in _unrendered_kinds(child) if k not in kinds]
    return kinds


def _warn_unseen(p, tok, rec: ObjRec) -> None:
    """A trace()/inside() whose object has parts we do not render answers as if they were absent:
    said at the call, at once (its answer already shapes the scene: placements, #if), once per
    call site and set of kinds."""
    kinds = _unrendered_kinds(rec)
    if not kinds:
        return
    seen = p.__dict__.setdefault("_unseen_warned", set())
    key = (tok.loc, tuple(kinds))
    if key in seen:
        return
    seen.add(key)
    what = ", ".join(kinds)
    p.warn_now(kinds[0], f"{tok.value}() cannot see the {what} in this object (not rendered); it "
               "answers as if that part were absent", tok.loc)


def _trace(p, tok):
    """``trace(OBJECT, A, B [, N])``: the nearest hit of the ray A + t·B, N := its normal."""
    p.expect_op("(", f"'(' after {tok.value}")
    obj = _object_arg(p, tok)
    p.expect_op(",", "',' after the object in trace()")
    a = as_vector(p, p.parse_expr_paren(), 3, tok.loc)
    p.expect_op(",", "',' after the start point in trace()")
    b = as_vector(p, p.parse_expr_paren(), 3, tok.loc)
    normal_name = None
    if p.accept_op(","):
        normal_name = p.expect_ident("a vector identifier for trace()'s normal").value
    p.expect_op(")", "')' to close trace(")
    point, normal = _tracer(p).trace(obj, a, b)
    if normal_name is not None:
        p.declare(normal_name, Vec(normal))
    return Vec(point)


def _extent(p, tok):
    """``min_extent(OBJECT)`` / ``max_extent(OBJECT)``: a corner of the object's world box, as
    POV-Ray bounds it (measured): a union's box holds its children's, an intersection's is their
    common part, a difference's is its first child's, ``clipped_by`` cuts it down; an unbounded
    object (a plane) gives ±1e10. An object of which nothing is rendered (a blob) gives the
    origin, with the warning that the call cannot see it."""
    p.expect_op("(", f"'(' after {tok.value}")
    rec = _object_arg(p, tok)
    p.expect_op(")", f"')' to close {tok.value}(")
    from ._lower import Lowerer

    obj = Lowerer().obj(rec, None, True)
    if obj is None:  # nothing of it is rendered (warned at the call): an empty box at the origin
        return Vec((0.0, 0.0, 0.0))
    box = _world_box(obj, np.eye(4))
    if box is None:
        box = (np.full(3, -UNBOUNDED_EXTENT), np.full(3, UNBOUNDED_EXTENT))
    return Vec(tuple(float(v) for v in box[0 if tok.value == "min_extent" else 1]))


UNBOUNDED_EXTENT = 1e10  # POV-Ray's min_extent/max_extent of a plane


def _world_box(obj, parent: np.ndarray):
    """``(lo, hi)`` world corners of a lowered object under ``parent`` (4×4), None if unbounded."""
    from ..scene import CSG
    from ..shapes import world_bounds

    m = parent if obj.transform is None else parent @ np.asarray(obj.transform.matrix, np.float64)
    if isinstance(obj, CSG):
        boxes = [_world_box(c, m) for c in obj.children]
        if obj.operation == "difference":
            box = boxes[0]
        elif obj.operation == "intersection":
            bounded = [b for b in boxes if b is not None]
            box = None if not bounded else (np.max([b[0] for b in bounded], 0),
                                            np.min([b[1] for b in bounded], 0))
        else:
            box = None if any(b is None for b in boxes) else (np.min([b[0] for b in boxes], 0),
                                                              np.max([b[1] for b in boxes], 0))
    else:
        shape = obj.shape.absorb_transform(m)  # a sphere's own box, not its rotated one's
        b = world_bounds(shape) if shape is not None else world_bounds(obj.shape, m)
        box = None if b is None else (np.asarray(b[0], np.float64), np.asarray(b[1], np.float64))
    for clip in obj.clipped_by:
        c = _world_box(clip, m)
        if c is not None:
            box = c if box is None else (np.maximum(box[0], c[0]), np.minimum(box[1], c[1]))
    return box


def _inside(p, tok):
    """``inside(OBJECT, P)``: 1 when P is inside the object's solid, else 0."""
    p.expect_op("(", f"'(' after {tok.value}")
    obj = _object_arg(p, tok)
    p.expect_op(",", "',' after the object in inside()")
    pt = as_vector(p, p.parse_expr_paren(), 3, tok.loc)
    p.expect_op(")", "')' to close inside(")
    return float(_tracer(p).inside(obj, pt))


def _sum_or_prod(p, tok):
    """``sum(I, B, N, A)`` / ``prod(I, B, N, A)`` in a function body: A evaluated for I = B, B + 1,
    … up to N, added or multiplied (1 term per whole step, N included, as POV-Ray)."""
    if not p.in_function():
        raise p.error(f"{tok.value}() can only be used in a function body", tok.loc)
    p.expect_op("(", f"'(' after {tok.value}")
    name = p.raw_ident(f"an index name in {tok.value}()").value
    p.expect_op(",", f"',' after the index name in {tok.value}()")
    lo = as_float(p, p.parse_expr_paren(), tok.loc)
    p.expect_op(",", f"',' after the first index in {tok.value}()")
    hi = as_float(p, p.parse_expr_paren(), tok.loc)
    p.expect_op(",", f"',' after the last index in {tok.value}()")
    term, depth = [], 0
    while True:  # the term's tokens, evaluated again for every index
        t = p.next()
        if t.kind == EOF:
            raise p.error(f"expected ')' to close {tok.value}(, found the end of the function", tok.loc)
        if t.kind == OP and t.value in "()":
            if t.value == ")" and depth == 0:
                break
            depth += 1 if t.value == "(" else -1
        term.append(t)
    term.append(t)  # the closing ')' ends the term
    total, i = (0.0 if tok.value == "sum" else 1.0), lo
    while i <= hi:
        v = as_float(p, p.evaluate_tokens(term, {name: i}, tok.loc), tok.loc)
        total = total + v if tok.value == "sum" else total * v
        i += 1.0
    return total


def _now() -> float:
    """Days since 2000-01-01 00:00 UTC (POV-Ray's ``now``)."""
    return (datetime.datetime.now(datetime.UTC) - _EPOCH).total_seconds() / 86400.0


_EPOCH = datetime.datetime(2000, 1, 1, tzinfo=datetime.UTC)


def _datetime(p, tok):
    """``datetime(DAYS [, FORMAT])``: the time DAYS after 2000-01-01 00:00 UTC as strftime text,
    by default ``%Y-%m-%d %H:%M:%SZ`` (POV-Ray's)."""
    args = _args(p, tok, 1, 2)
    days = as_float(p, args[0], tok.loc)
    fmt = _str_arg(p, tok, args[1]) if len(args) > 1 else "%Y-%m-%d %H:%M:%SZ"
    try:
        when = _EPOCH + datetime.timedelta(days=days)
    except OverflowError:
        raise p.error(f"expected a date in datetime(), found {fmt_number(days)} days after 2000-01-01",
                      tok.loc) from None
    return when.strftime(fmt)


def _seed(p, tok):
    (a,) = _floats(p, tok, 1)
    return RandStream(seed_state(a))


def _rand(p, tok):
    (s,) = _args(p, tok, 1)
    if not isinstance(s, RandStream):
        raise p.error(f"expected a seed() stream in rand(), found {type_name(s)}", tok.loc)
    return s.next()


def _str_arg(p, tok, v):
    if not isinstance(v, str):
        raise p.error(f"expected a string in {tok.value}(), found {type_name(v)}", tok.loc)
    return v


def _strlen(p, tok):
    (a,) = _args(p, tok, 1)
    return float(len(_str_arg(p, tok, a)))


def _str(p, tok):
    a, w, prec = _args(p, tok, 3)
    return _format_float(as_float(p, a, tok.loc), *_width_and_precision(p, tok, w, prec))


def _width_and_precision(p, tok, w, prec) -> tuple[int, int]:
    n = MAX_FORMAT_WIDTH
    return (as_int(p, w, tok.loc, f"a width in {tok.value}()", -n, n),
            as_int(p, prec, tok.loc, f"a number of decimal places in {tok.value}()", -n, n))


def _format_float(a: float, w: int, prec: int) -> str:
    prec = 6 if prec < 0 else prec
    s = f"{a:.{prec}f}"
    if w < 0:
        s = s.zfill(-w) if a >= 0 else "-" + s[1:].zfill(-w - 1)
    else:
        s = s.rjust(w)
    return s


def _vstr(p, tok):
    args = _args(p, tok, 5)  # vstr(N, A, S, L, P): N components of vector A (manual)
    n = as_int(p, args[0], tok.loc, "a number of components in vstr()", 2, 5)
    v = as_vector(p, args[1], n, tok.loc)
    sep = _str_arg(p, tok, args[2])
    w, prec = _width_and_precision(p, tok, args[3], args[4])
    return sep.join(_format_float(c, w, prec) for c in v)


def _chr(p, tok):
    (a,) = _args(p, tok, 1)
    code = as_int(p, a, tok.loc, "a Unicode code point in chr()", 0, 0x10FFFF)
    if 0xD800 <= code <= 0xDFFF:  # UTF-16 surrogates are not characters
        raise p.error(f"expected a Unicode code point in chr(), found the surrogate {code:#x}", tok.loc)
    return chr(code)


def _asc(p, tok):
    (a,) = _args(p, tok, 1)
    s = _str_arg(p, tok, a)
    return float(ord(s[0])) if s else 0.0


def _val(p, tok):
    (a,) = _args(p, tok, 1)
    s = _str_arg(p, tok, a).strip()
    import re

    m = re.match(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?", s)  # ASCII digits
    return float(m.group(0)) if m else 0.0


def _concat(p, tok):
    args = [_str_arg(p, tok, a) for a in _args(p, tok, 1, 10000)]
    check_string_length(p, sum(len(a) for a in args), tok.loc, "concat()")
    return "".join(args)


def _substr(p, tok):
    s, a, n = _args(p, tok, 3)
    s = _str_arg(p, tok, s)
    a = as_int(p, a, tok.loc, "a start position in substr()", 1, len(s) + 1)
    n = as_int(p, n, tok.loc, "a length in substr()", 0, len(s) - a + 1)
    return s[a - 1:a - 1 + n]


def _strcase(fn):
    def call(p, tok):
        (a,) = _args(p, tok, 1)
        return fn(_str_arg(p, tok, a))
    return call


def _strcmp(p, tok):
    a, b = (_str_arg(p, tok, v) for v in _args(p, tok, 2))
    return float((a > b) - (a < b))


def _file_exists(p, tok):
    _args(p, tok, 1)
    return 0.0


def _defined(p, tok):
    p.expect_op("(")
    name = p.raw_ident().value
    p.expect_op(")")
    return float(p.find(name)[0] is not None or p.lookup_macro(name) is not None)


def _array_arg(p, tok):
    p.expect_op("(")
    v = p.parse_expr_paren()
    if not isinstance(v, ArrayValue):
        raise p.error(f"expected an array in {tok.value}(), found {type_name(v)}", tok.loc)
    return v


def _dimensions(p, tok):
    a = _array_arg(p, tok)
    p.expect_op(")")
    return float(len(a.dims))


def _dimension_size(p, tok):
    a = _array_arg(p, tok)
    p.expect_op(",")
    n = as_int(p, p.parse_expr_paren(), tok.loc, "a dimension in dimension_size()")
    p.expect_op(")")
    return float(a.dims[n - 1]) if 1 <= n <= len(a.dims) else 0.0


def _bitwise(fn):
    def call(p, tok):
        args = [as_int(p, a, tok.loc, f"an integer in {tok.value}()", -(2**53), 2**53)
                for a in _args(p, tok, 2, 100)]
        out = args[0]
        for a in args[1:]:
            out = fn(out, a)
        return float(out)
    return call


BUILTIN_FUNCTIONS = {
    "abs": _f1(abs), "acos": _f1(math.acos), "acosh": _f1(math.acosh), "asin": _f1(math.asin),
    "asinh": _f1(math.asinh), "atan": _f1(math.atan), "atanh": _f1(math.atanh),
    "atan2": _f2(math.atan2), "ceil": _f1(math.ceil), "cos": _f1(math.cos), "cosh": _f1(math.cosh),
    "degrees": _f1(math.degrees), "radians": _f1(math.radians), "exp": _f1(math.exp),
    "floor": _f1(math.floor), "int": _f1(_int), "ln": _f1(math.log), "log": _f1(_log),
    "mod": _f2(_mod), "div": _f2(_div), "pow": _f2(math.pow), "sin": _f1(math.sin),
    "sinh": _f1(math.sinh), "sqrt": _f1(math.sqrt), "tan": _f1(math.tan), "tanh": _f1(math.tanh),
    "max": _minmax(max), "min": _minmax(min), "select": _select,
    "vlength": _vlength, "vdot": _vdot, "vcross": _vcross, "vnormalize": _vnormalize,
    "vrotate": _vrotate, "vaxis_rotate": _vaxis_rotate, "vturbulence": _vturbulence,
    "trace": _trace, "min_extent": _extent, "max_extent": _extent, "inside": _inside,
    "seed": _seed, "rand": _rand, "strlen": _strlen, "str": _str, "vstr": _vstr, "chr": _chr,
    "asc": _asc, "val": _val, "concat": _concat, "substr": _substr, "strupr": _strcase(str.upper),
    "strlwr": _strcase(str.lower), "strcmp": _strcmp, "file_exists": _file_exists,
    "defined": _defined, "dimensions": _dimensions, "dimension_size": _dimension_size,
    "bitwise_and": _bitwise(lambda a, b: a & b), "bitwise_or": _bitwise(lambda a, b: a | b),
    "bitwise_xor": _bitwise(lambda a, b: a ^ b),
    "sum": _sum_or_prod, "prod": _sum_or_prod, "datetime": _datetime,
}
