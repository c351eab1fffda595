"""The interpreter: token stream + directives + the scene-level statement loop and values."""

from __future__ import annotations

from ._convert import fmt_number
from ._directives import Directives, skip_block
from ._environment import ENVIRONMENT_KEYWORDS, parse_environment, place_environment
from ._expr import as_float, as_int, binop, parse_expr, parse_expr_paren, type_name
from ._keywords import KEYWORDS
from ._lexer import EOF, ID, OP, STR
from ._objects import (
    is_object_start,
    parse_background,
    parse_camera,
    parse_default,
    parse_global_settings,
    parse_object,
)
from ._stream import Frame, Stream
from ._textures import (
    layered,
    parse_color_map,
    parse_finish,
    parse_interior,
    parse_material,
    parse_normal,
    parse_pigment,
    parse_pigment_map_body,
    parse_slope_map_body,
    parse_texture,
    parse_transform_value,
    skip_braces,
    texture_map_body,
)
from ._values import (
    ArrayValue,
    FunctionValue,
    LayerRec,
    LightRec,
    ObjRec,
    Opaque,
    PigmentMapRec,
    SlopeMapRec,
    SplineValue,
    TextureMapRec,
    TextureRec,
    TransformRec,
    Vec,
)

_SKIPPED_STATEMENTS = ("rainbow", "media", "photons", "radiosity")


class Interpreter(Stream, Directives):
    """Runs a scene: ``run()`` evaluates every statement and collects camera, lights and objects."""

    def __init__(self, *, include_paths=(), strict=False, limits=None, width=160, height=120,
                 animation=None):
        super().__init__(include_paths=include_paths, strict=strict, limits=limits)
        self.directives = self.directive_table()
        self.macro_call = self.invoke_macro
        self.in_parens = False
        self.image_width, self.image_height = width, height
        self.animation_constants = {} if animation is None else animation.constants()
        self.version = 3.7
        self.version_seen = False
        self.virtual_files: dict[str, list[str]] = {}  # #fopen … write: in memory only
        self.written_chars: dict[str, int] = {}  # their lengths (Limits.max_string_length)
        self.open_files: dict[str, tuple[str, str, int]] = {}
        self.first_version = None
        self.old_version_warned = False
        self.assumed_gamma = None
        self.input_file_name = ""
        self.settings = {}
        self.statement_locs = {}  # global_settings, background: where the last one was (for errors)
        self.background = (0.0, 0.0, 0.0)
        self.environment = []  # EnvRec: the environment statements that took effect (sky_sphere, fog …)
        self.default_layer = LayerRec()
        self.camera = None
        self.items: list = []  # ObjRec and LightRec in file order
        self.parse_default = lambda tok: parse_default(self, tok)

    @staticmethod
    def reserved_words():
        return KEYWORDS

    # ---- statements ----------------------------------------------------------------------
    def release(self) -> None:
        """Drops everything this interpreter holds (its tokens, records, frames and tables). Its
        tables of bound methods make it a reference cycle, which only Python's cyclic collector
        frees: until then it kept a scene file's tokens and records alive (for 100,000 spheres
        3 M tokens, ~250 MB, past the parse and through the packing)."""
        vars(self).clear()

    def run(self) -> None:
        while True:
            t = self.peek()
            if t.kind == EOF:
                return
            self.statement(t)

    def statement(self, t) -> None:
        if t.kind != ID:
            raise self.error(f"expected an object, light, camera or directive, found {t.describe()}",
                             t.loc)
        kw = t.value
        if is_object_start(self, t):
            rec = parse_object(self)
            if isinstance(rec, ObjRec):
                # semantics §2.1: the parts left without a texture take the #default current when
                # the object is placed (its top-level statement ends), not when it was declared
                rec.default_layer = self.default_layer
            self.items.append(rec)
        elif kw == "camera":
            self.next()
            if self.camera is not None:
                self.warn("camera", "a second camera replaces the first", t.loc)
            self.camera = parse_camera(self, t)
        elif kw == "global_settings":
            self.next()
            parse_global_settings(self, t)
        elif kw == "background":
            self.next()
            parse_background(self, t)
        elif kw in ENVIRONMENT_KEYWORDS:  # fogs add up; a later sky_sphere replaces an earlier one
            self.next()
            place_environment(self, parse_environment(self, t, ENVIRONMENT_KEYWORDS[kw]), t.loc)
        elif kw == "default":  # the old spelling of #default
            self.next()
            parse_default(self, t)
        elif kw in _SKIPPED_STATEMENTS:
            self.next()
            self.warn(kw, f"{kw} is not supported; ignored", t.loc)
            skip_braces(self)
        elif kw in KEYWORDS:
            raise self.error(f"expected an object, light, camera or directive, found '{kw}'", t.loc)
        else:
            v = self.lookup(kw)
            what = f"identifier '{kw}' ({type_name(v)})" if v is not None else \
                f"undeclared identifier '{kw}'"
            raise self.error(f"expected an object, light, camera or directive, found {what}", t.loc)

    # ---- right-hand sides of #declare and macro arguments ---------------------------------
    def parse_rvalue(self):
        t = self.peek()
        if t.kind == ID:
            kw = t.value
            if is_object_start(self, t):
                return parse_object(self)
            handler = _RVALUE_BLOCKS.get(kw)
            if handler is not None:
                self.next()
                return handler(self, t)
        return parse_expr(self)

    def parse_expr_paren(self):
        """An expression inside ( ), [ ] or an argument list: how the built-ins read arguments."""
        return parse_expr_paren(self)

    # ---- arrays ----------------------------------------------------------------------------
    def parse_array(self, t):
        dims = []
        while self._peek_op_is("["):
            self.next()
            loc = self.peek().loc
            dims.append(as_int(self, parse_expr_paren(self), loc, "an array size", 1))
            self.expect_op("]")
        if not dims:
            raise self.error("expected '[' size ']' after array", t.loc)
        size = 1
        for d in dims:
            size *= d
        if size > self.limits.max_array_elements:
            raise self.error(f"expected at most {self.limits.max_array_elements} array elements "
                             f"(Limits.max_array_elements), found {fmt_number(float(size))}", t.loc)
        self.reserve(8 * size, t.loc)  # a list slot an element, filled or not
        arr = ArrayValue(dims, [None] * size)
        if self._peek_op_is("{"):
            flat = []
            self._array_init(flat, len(dims))
            if len(flat) > size:
                raise self.error(f"expected at most {size} array initialisers, found {len(flat)}",
                                 t.loc)
            arr.data[:len(flat)] = flat
        return arr

    def _array_init(self, out, depth):
        self.expect_op("{")
        while not self.is_op("}"):
            if depth > 1 and self.is_op("{"):
                self._array_init(out, depth - 1)
            else:
                out.append(self.parse_rvalue())
            self.accept_op(",")  # POV lets the commas out
        self.expect_op("}", "'}' to close the array initialiser")

    def _peek_op_is(self, op: str) -> bool:
        t = self.peek_op()
        return t.kind == OP and t.value == op

    # ---- functions and splines -------------------------------------------------------------
    def parse_function(self):
        t = self.next()  # 'function'
        params = ["x", "y", "z"]
        if self.accept_op("("):
            params = []
            if not self.is_op(")"):
                params.append(self.raw_ident("a parameter name").value)
                while self.accept_op(","):
                    params.append(self.raw_ident("a parameter name").value)
            self.expect_op(")")
        self.expect_op("{", "'{' to start the function body")
        body, depth = [], 1
        while True:
            tok = self.next()
            if tok.kind == EOF:
                raise self.error("expected '}' to close the function, found end of file", t.loc)
            if tok.kind == OP and tok.value in "{}":
                depth += 1 if tok.value == "{" else -1
                if depth == 0:
                    break
            body.append(tok)
        kind = "float"
        if body and body[0].kind == ID and body[0].value in ("pattern", "pigment", "internal",
                                                            "spline", "transform"):
            kind = "opaque"
        body.append(tok)
        return FunctionValue(params, body, kind, t.loc)

    def call_function(self, f: FunctionValue, t):
        self.expect_op("(")
        args = []
        if not self.is_op(")"):
            args.append(parse_expr_paren(self))
            while self.accept_op(","):
                args.append(parse_expr_paren(self))
        self.expect_op(")")
        if f.kind == "opaque":
            return 0.0
        if len(args) != len(f.params):
            raise self.error(f"expected {len(f.params)} arguments to the function, found {len(args)}",
                             t.loc)
        return self.evaluate_tokens(f.tokens, dict(zip(f.params, args, strict=True)), t.loc)

    def in_function(self) -> bool:
        """Whether a function body is being evaluated (``sum``/``prod`` exist only there)."""
        return any(f.kind == "func" for f in self.frames)

    def evaluate_tokens(self, tokens: list, scope: dict, call_loc):
        """The expression ``tokens[:-1]`` (the last token ends it) with the names of ``scope``
        bound: a function's body for one call, or ``sum``/``prod``'s term for one index."""
        if self.macro_depth >= self.limits.max_macro_depth:
            raise self.error(f"function calls nested deeper than {self.limits.max_macro_depth}",
                             call_loc)
        saved_la, saved_raw = self.la, self.la_raw
        self.la, self.la_raw = None, False
        self.scopes.append(scope)
        self.macro_depth += 1
        self.frames.append(Frame(tokens, 0, len(tokens) - 1, "func", True, call_loc=call_loc))
        saved_gt, self.in_parens = self.in_parens, True
        try:
            v = parse_expr(self)
            end = self.peek()
            if end.kind != EOF:
                raise self.error(f"expected the end of the function body, found {end.describe()}",
                                 end.loc)
        finally:
            self.in_parens = saved_gt
        self.la = None
        self.pop_frame()
        self.la, self.la_raw = saved_la, saved_raw
        return v

    def parse_spline(self, t):
        self.expect_op("{")
        pts, kind = [], "linear_spline"
        while not self.accept_op("}"):
            nt = self.peek()
            if nt.kind == ID and nt.value.endswith("_spline"):
                kind = self.next().value
                continue
            if nt.kind == ID and isinstance(self.lookup(nt.value), SplineValue):
                s = self.lookup(self.next().value)
                pts, kind = list(s.points), s.kind
                continue
            k = as_float(self, parse_expr(self), nt.loc)
            self.accept_op(",")
            v = parse_expr(self)
            self.accept_op(",")
            pts.append((k, v))
        if kind != "linear_spline":
            self.warn(kind, f"{kind} is evaluated as a linear spline", t.loc)
        return SplineValue(sorted(pts, key=lambda kv: kv[0]), kind)

    def call_spline(self, s: SplineValue, t):
        self.expect_op("(")
        x = as_float(self, parse_expr_paren(self), t.loc)
        if self.accept_op(","):
            self.next()
        self.expect_op(")")
        pts = s.points
        if not pts:
            return 0.0
        if x <= pts[0][0]:
            return pts[0][1]
        for (k0, v0), (k1, v1) in zip(pts, pts[1:], strict=False):
            if x <= k1:
                w = (x - k0) / (k1 - k0) if k1 != k0 else 0.0
                return binop(self, "+", binop(self, "*", v0, 1 - w, t.loc),
                             binop(self, "*", v1, w, t.loc), t.loc)
        return pts[-1][1]


def _opaque(kind):
    def handler(p, t):
        if p.is_op("{"):
            skip_braces(p)
        p.warn(kind, f"{kind} is not supported; ignored", t.loc)
        return Opaque(kind, t.loc)
    return handler


def _layered_texture(p):
    """``texture {…} texture {…}…``: a layered texture (later layers on top)."""
    tex = parse_texture(p, p.default_layer)
    while True:
        t = p.peek_op()
        if not (t.kind == ID and t.value == "texture"):
            return tex
        p.next()
        tex = TextureRec(layered(p, tex.layers, parse_texture(p, p.default_layer).layers, t.loc))


def _normal_value(p, t):
    return parse_normal(p)


def _array_handler(p, t):
    return p.parse_array(t)


def _string_literal(p, t):
    return t.value


_RVALUE_BLOCKS = {
    "texture": lambda p, t: _layered_texture(p),
    "pigment": lambda p, t: parse_pigment(p),
    "finish": lambda p, t: parse_finish(p),
    "interior": lambda p, t: parse_interior(p),
    "material": lambda p, t: parse_material(p, p.default_layer),
    "normal": _normal_value,
    "camera": lambda p, t: parse_camera(p, t),
    "transform": lambda p, t: TransformRec(parse_transform_value(p, t)),
    "color_map": lambda p, t: parse_color_map(p),
    "colour_map": lambda p, t: parse_color_map(p),
    "array": _array_handler,
    "spline": lambda p, t: p.parse_spline(t),
    "media": _opaque("media"), "density": _opaque("density"), "rainbow": _opaque("rainbow"),
    "pigment_map": lambda p, t: PigmentMapRec(parse_pigment_map_body(p, t.loc)),
    "normal_map": _opaque("normal_map"),
    "slope_map": lambda p, t: SlopeMapRec(parse_slope_map_body(p, t.loc)),
    "texture_map": lambda p, t: TextureMapRec(texture_map_body(p, t.loc, p.default_layer)),
    "density_map": _opaque("density_map"), "photons": _opaque("photons"),
    "interior_texture": _opaque("interior_texture"),
    **{name: (lambda e: lambda p, t: parse_environment(p, t, e))(entry)
       for name, entry in ENVIRONMENT_KEYWORDS.items()},
}

__all__ = ["Interpreter", "LightRec", "ObjRec", "Vec", "STR", "skip_block"]
