"""Builders for transforms, pigments, finishes, textures, interiors and materials."""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from .. import patterns
from ..errors import SceneError
from ..scene._transform import pov_matrix, rotation_matrix, scale_matrix, translation_matrix
from ._convert import fmt_number
from ._expr import COLOR_KEYWORDS, as_color, as_float, as_vector, parse_color, parse_expr, type_name
from ._lexer import ID, NUM, OP
from ._values import (
    InteriorRec,
    LayerRec,
    MaterialRec,
    NormRec,
    PigmentMapRec,
    PigRec,
    SlopeMapRec,
    TextureMapRec,
    TextureRec,
    TransformRec,
    Vec,
)

TRANSFORM_KEYWORDS = ("translate", "rotate", "scale", "matrix", "transform")
# Pattern keywords, arguments, default maps and waves come from ``raytracer.patterns.REGISTRY``.
WAVE_KEYWORDS = {f"{wave}_wave": wave for wave in patterns.WAVES}
# texture-level patterns (``checker texture {…} texture {…}``, ``texture_map``, ``tiles``)
TEXTURE_PATTERNS = patterns.SDL_KEYWORDS | {"texture_map", "tiles", "material_map"}
NEUTRAL = Vec((0.5, 0.5, 0.5, 0, 0))  # the colour of a pattern we do not render


def vector3(p, loc=None) -> tuple:
    t = p.peek()
    return as_vector(p, parse_expr(p), 3, loc or t.loc)


def float_(p) -> float:
    t = p.peek()
    return as_float(p, parse_expr(p), t.loc)


def opt_comma(p) -> None:
    p.accept_op(",")


# ---- transforms ------------------------------------------------------------------------------
def parse_transform_item(p, tok) -> np.ndarray:
    """The matrix of ``translate/rotate/scale/matrix/transform`` (``tok`` already consumed)."""
    kw = tok.value
    if kw == "translate":
        return translation_matrix(vector3(p))
    if kw == "rotate":
        return rotation_matrix(vector3(p))
    if kw == "scale":
        v = list(vector3(p))
        if any(c == 0.0 for c in v):
            p.warn("scale", "a scale component of 0 is replaced by 1", tok.loc)
            v = [1.0 if c == 0.0 else c for c in v]
        return scale_matrix(v)
    if kw == "matrix":
        vals = _matrix_values(p, tok)
        # POV-Ray's rule, found by rendering: a column of the 3×3 that is all zero gets a 1 on the
        # diagonal, with its warning; a matrix still singular after that is refused
        for j in range(3):
            if all(vals[3 * i + j] == 0.0 for i in range(3)):
                p.warn("matrix", "Illegal matrix column: Scale by 0.0. Changed to 1.0", tok.loc)
                vals[4 * j] = 1.0
        if np.linalg.det(np.array(vals[:9], np.float64).reshape(3, 3)) == 0.0:
            raise p.error("expected an invertible matrix, found a singular one (POV-Ray refuses it "
                          "too: 'Singular matrix')", tok.loc)
        return pov_matrix(vals)
    return parse_transform_value(p, tok)


def _matrix_values(p, tok) -> list[float]:
    p.expect_op("<", "'<' after matrix")
    saved, p.in_parens = p.in_parens, False
    try:
        vals = [float_(p)]
        while p.accept_op(","):
            vals.append(float_(p))
    finally:
        p.in_parens = saved
    p.expect_op(">")
    if len(vals) != 12:
        raise p.error(f"expected 12 matrix values, found {len(vals)}", tok.loc)
    return vals


def parse_transform_value(p, tok) -> np.ndarray:
    """``transform Ident`` or ``transform { [Ident] items… [inverse] }``."""
    if not p.is_op("{"):
        return _transform_ident(p, p.next())
    p.next()
    m = np.eye(4)
    while not p.accept_op("}"):
        t = p.next()
        if t.kind == ID and t.value in TRANSFORM_KEYWORDS:
            m = parse_transform_item(p, t) @ m
        elif t.kind == ID and t.value == "inverse":
            m = np.linalg.inv(m)
        elif t.kind == ID:
            m = _transform_ident(p, t) @ m
        else:
            raise p.error(f"expected a transformation, found {t.describe()}", t.loc)
    return m


def _transform_ident(p, t) -> np.ndarray:
    v = p.lookup(t.value) if t.kind == ID else None
    if isinstance(v, TransformRec):
        return v.matrix
    raise p.error(f"expected a transform identifier, found {t.describe()}", t.loc)


# ---- colour maps -----------------------------------------------------------------------------
def parse_color_map(p) -> list:
    """``color_map { [v color] … }`` (also the old ``[v1 v2 color c1 color c2]`` form) or Ident."""
    start = p.peek().loc
    p.expect_op("{")
    entries = []
    if p.peek().kind == ID and not p.is_id("color") and not p.is_id("colour"):
        v = p.lookup(p.peek().value)
        if isinstance(v, list):
            p.next()
            entries = list(v)
    while p.accept_op("["):
        a = float_(p)
        opt_comma(p)
        if p.peek().kind == NUM or (p.peek().kind == OP and p.peek().value in ("-", "(", ".")):
            b = float_(p)
            c1 = parse_color(p)
            opt_comma(p)
            c2 = parse_color(p)
            entries += [(a, c1), (b, c2)]
        else:
            entries.append((a, parse_color(p)))
        p.expect_op("]", "']' to close the colour map entry")
    if not entries:  # POV-Ray: "Must have at least one color in color map"
        raise p.error("expected at least one [value colour] entry in the colour map, found "
                      f"{p.peek().describe()}", start)
    p.expect_op("}", "'}' to close the colour map")
    return entries


def _default_map(record: patterns.Pattern) -> list:
    return [(v, Vec(c)) for v, c in record.default_map]


# ---- pigments --------------------------------------------------------------------------------
def parse_pigment(p, base: PigRec | None = None) -> PigRec:
    """``pigment { … }``; ``base`` is the pigment being modified (an object's current one)."""
    p.expect_op("{", "'{' after pigment")
    pig = dataclasses.replace(base) if base is not None else PigRec()
    while not p.accept_op("}"):
        pig = pigment_item(p, pig)
    return pig


def _declared_value(p, t, cls, what: str):
    v = parse_expr(p)
    if not isinstance(v, cls):
        raise p.error(f"expected a {what}, found {type_name(v)} '{t.value}'", t.loc)
    return v


def declared(p, t) -> bool:
    """Whether ``t`` is an identifier the scene declared (so it is a value, not a keyword)."""
    return t.kind == ID and p.find(t.value)[0] is not None


def _solid(c: Vec) -> PigRec:
    return PigRec("solid", [(0.0, c)], ft=c.ft)


def pigment_item(p, pig: PigRec) -> PigRec:
    t = p.peek()
    if t.kind != ID:
        return _solid(as_color(p, parse_expr(p), t.loc))
    if declared(p, t):
        v = parse_expr(p)
        if isinstance(v, PigRec):
            return dataclasses.replace(v)
        if isinstance(v, list):  # a colour map identifier
            return dataclasses.replace(pig, cmap=list(v), cmap_given=True, ft=pig.ft or _map_ft(v))
        if isinstance(v, (float, Vec)):
            return _solid(as_color(p, v, t.loc))
        raise p.error(f"expected a pigment, found {type_name(v)} '{t.value}'", t.loc)
    kw = t.value
    if kw in COLOR_KEYWORDS or kw in ("red", "green", "blue", "filter", "transmit"):
        return _solid(parse_color(p))
    if kw in patterns.SDL_KEYWORDS:
        p.next()
        return _pattern(p, patterns.REGISTRY[kw], pig, t.loc)
    if kw in ("color_map", "colour_map"):
        p.next()
        cmap = parse_color_map(p)
        return dataclasses.replace(pig, cmap=cmap, cmap_given=True, ft=pig.ft or _map_ft(cmap))
    if kw in TRANSFORM_KEYWORDS:
        p.next()
        return pig.transformed(parse_transform_item(p, t)) if pig.pattern != "solid" else _keep(
            pig, parse_transform_item(p, t))
    if kw in WAVE_KEYWORDS:
        p.next()
        if kw == "poly_wave" and _starts_value(p):
            float_(p)
        return dataclasses.replace(pig, wave=WAVE_KEYWORDS[kw])
    if kw in ("turbulence", "octaves", "omega", "lambda", "frequency", "phase"):
        p.next()
        return _pattern_modifier(p, kw, pig)
    if kw in ("pigment_map", "texture_map", "normal_map", "slope_map"):
        p.next()
        return _pigment_map(p, kw, pig, t.loc)
    if kw in patterns.MODIFIERS or kw in (
              "warp", "quick_color", "quick_colour", "noise_generator",
              "arms", "form", "metric", "offset", "solid", "exponent", "interior",
              "exterior", "control0", "control1", "coords", "size", "orientation", "dist_exp",
              "major_radius", "repeat", "flip", "black_hole", "falloff", "uv_mapping", "interpolate",
              "map_type", "once", "gamma", "premultiplied", "accuracy", "return", "turb_depth",
              "use_color", "use_colour", "use_index", "use_alpha"):
        p.next()
        return _ignored_modifier(p, kw, pig, t.loc)
    raise p.error(f"expected a pigment item, found {t.describe()}", t.loc)


def _keep(pig, m):
    # transforming a solid colour changes nothing, but a pattern given later must see it
    return dataclasses.replace(pig, transform=m if pig.transform is None else m @ pig.transform)


def _map_ft(cmap) -> bool:
    return any(c.ft for _, c in cmap)


def _starts_value(p) -> bool:
    from ._builtins import _CONSTANTS, _VECTORS, BUILTIN_FUNCTIONS

    t = p.peek()
    if t.kind == NUM or (t.kind == OP and t.value in ("-", "+", "(", "<", "!")):
        return True
    if t.kind != ID:
        return False
    if t.value in _CONSTANTS or t.value in _VECTORS or t.value in BUILTIN_FUNCTIONS:
        return p.find(t.value)[0] is None or isinstance(p.lookup(t.value), (float, Vec))
    return isinstance(p.lookup(t.value), (float, Vec))


def _pattern(p, record: patterns.Pattern, pig: PigRec, loc) -> PigRec:
    """A pattern keyword (consumed) and its arguments, as its registry record declares them."""
    kw = record.name
    if not record.rendered:
        return _unsupported_pattern(p, record, loc)
    if record.imaged:
        return PigRec(kw, [(0.0, Vec((0, 0, 0, 0, 0)))], cmap_given=True, transform=pig.transform,
                      image=parse_image_map(p, loc), ft=True)
    new = PigRec(kw, _default_map(record), transform=pig.transform, turbulence=pig.turbulence,
                 wave=record.default_wave if record.default_wave != "ramp" else None)
    if record.discrete:
        new.frequency = 0.0
        colors = []
        n = record.colours
        while len(colors) < n and (_starts_color(p) or p.is_id("pigment")):
            if p.accept_id("pigment"):
                colors.append(parse_pigment(p))
            else:
                colors.append(parse_color(p))
            opt_comma(p)
        if colors:
            defaults = [c for _, c in new.cmap]
            colors += defaults[len(colors):]
            # the value of a discrete pattern is the index of its colour
            if any(isinstance(c, PigRec) for c in colors):  # a list of pigments: a pigment map
                pigments = [c if isinstance(c, PigRec) else _solid(c) for c in colors]
                new.entries = [(float(i), pg) for i, pg in enumerate(pigments)]
                new.cmap = [(float(i), Vec((0, 0, 0, 0, 0))) for i in range(len(pigments))]
                new.ft = any(pg.ft for pg in pigments)
            else:
                new.cmap = [(float(i), c) for i, c in enumerate(colors)]
                new.ft = _map_ft(new.cmap)
            new.cmap_given = True
    if record.argument == "vector":
        new.vector = vector3(p)
    return new


IMAGE_TYPES = ("exr", "gif", "hdr", "iff", "jpeg", "pgm", "png", "ppm", "sys", "tga", "tiff")


def parse_image_map(p, loc) -> dict:
    """``image_map { [type] "file" [gamma G|srgb] [premultiplied B] modifiers… }``: the image read
    (Pillow; OpenEXR for ``exr``) into linear RGBFT and how it wraps (semantics §5.6)."""
    from ..imageio import load_image_map

    p.expect_op("{", "'{' after image_map")
    kind = p.next().value if p.peek().kind == ID and p.peek().value in IMAGE_TYPES else None
    t = p.peek()
    name = parse_expr(p)
    if not isinstance(name, str):
        raise p.error(f"expected an image file name, found {type_name(name)}", t.loc)
    path = _image_file(p, name, kind, t.loc)
    gamma = None
    image = {"map_type": 0, "once": False, "interpolate": 0, "filter": 0.0, "transmit": 0.0}
    while not p.accept_op("}"):
        k = p.next()
        kw = k.value if k.kind == ID else None
        if kw == "gamma":
            gamma = "srgb" if p.accept_id("srgb") else float_(p)
        elif kw == "premultiplied":
            _opt_bool(p)
        elif kw == "map_type":
            mt = int(float_(p))
            if mt not in (0, 1, 2):
                p.warn("map_type", f"map_type {mt} is not rendered; the planar map (0) is used", k.loc)
                mt = 0
            image["map_type"] = mt
        elif kw == "once":
            image["once"] = True
        elif kw == "interpolate":
            n = int(float_(p))
            if n not in (0, 2):
                p.warn("interpolate", f"interpolate {n} is rendered as bilinear (2)", k.loc)
            image["interpolate"] = 2 if n else 0
        elif kw in ("filter", "transmit"):
            if p.accept_id("all"):
                image[kw] = float_(p)
            else:
                float_(p)
                opt_comma(p)
                float_(p)
                p.warn("image palette", f"{kw} of a palette entry is not rendered; ignored", k.loc)
        elif kw == "use_alpha":
            pass
        else:
            raise p.error(f"expected an image_map item, found {k.describe()}", k.loc)
    try:
        image["pixels"] = load_image_map(path, gamma, image.pop("filter"), image.pop("transmit"))
    except (OSError, ValueError) as e:
        raise p.error(f'cannot read the image "{name}": {e}', t.loc) from None
    return image


_SUFFIXES = {"jpeg": ("jpg", "jpeg"), "tiff": ("tif", "tiff")}


def _image_file(p, name: str, kind: str | None, loc) -> str:
    """The image file ``name`` names, found as an include is; as POV-Ray, a name without a suffix
    is tried with its type's too."""
    tries = [name]
    if kind is not None and not os.path.splitext(name)[1]:
        tries += [f"{name}.{s}" for s in _SUFFIXES.get(kind, (kind,))]
    for i, candidate in enumerate(tries):
        try:
            return p.resolve_include(candidate, loc, what="an image file")
        except SceneError:
            if i == len(tries) - 1:
                raise
    raise AssertionError("unreachable")


def _starts_color(p) -> bool:
    t = p.peek()
    if t.kind == ID and (t.value in COLOR_KEYWORDS or t.value in ("red", "green", "blue")):
        return True
    return _starts_value(p)


def _pattern_modifier(p, kw, pig):
    if kw == "turbulence":
        v = parse_expr(p)
        return dataclasses.replace(pig, turbulence=as_vector(p, v, 3))
    if kw == "octaves":
        return dataclasses.replace(pig, octaves=max(1, min(10, int(float_(p)))))
    if kw == "omega":
        return dataclasses.replace(pig, omega=float_(p))
    if kw == "lambda":
        return dataclasses.replace(pig, lambda_=float_(p))
    if kw == "frequency":
        return dataclasses.replace(pig, frequency=float_(p))
    return dataclasses.replace(pig, phase=float_(p))


def _skip_args(p):
    """Skips the values or block after an ignored keyword."""
    if p.is_op("{"):
        skip_braces(p)
        return
    while _starts_value(p) or p.peek().kind == 'str':
        parse_expr(p)
        if not p.accept_op(","):
            return


def warn_noise_generator(p, generator: float, loc) -> None:
    """Our noise has the statistics of POV-Ray's generator 2 (its default); 1 and 3 differ."""
    if generator != 2:
        p.warn("noise_generator", f"noise_generator {fmt_number(generator)} is not simulated; the noise has "
               "the statistics of generator 2", loc)


def _ignored_modifier(p, kw, pig, loc):
    if kw not in ("quick_color", "quick_colour", "noise_generator", "once",
                  "interpolate", "map_type", "use_color", "use_colour", "use_index", "accuracy"):
        p.warn(kw, f"pattern modifier '{kw}' is not supported; ignored", loc)
    if kw in ("quick_color", "quick_colour"):
        parse_color(p)
        return pig
    if kw == "noise_generator":
        warn_noise_generator(p, float_(p), loc)
        return pig
    _skip_args(p)
    return pig


def _unsupported_pattern(p, record: patterns.Pattern, loc):
    """A pattern we parse but do not render: its arguments are skipped, a neutral colour is used."""
    p.warn(record.name, f"pattern '{record.name}' is not supported; a neutral colour is used", loc)
    if record.argument == "file":
        p.next()  # the file type (df3)
        parse_expr(p)
    else:
        _skip_args(p)
    return PigRec("solid", [(0.0, NEUTRAL)], cmap_given=True)


def _pigment_map(p, kw, pig, loc):
    if kw == "pigment_map":
        # an average's entries weigh 1 unless given, a map's sit at 0, 1, … unless given
        entries = parse_pigment_map_body(p, loc, 1.0 if patterns.REGISTRY[pig.pattern].averaged else None)
        return dataclasses.replace(pig, cmap=[(v, Vec((0, 0, 0, 0, 0))) for v, _ in entries], cmap_given=True,
                                   ft=any(e.ft for _, e in entries), entries=entries)
    p.warn(kw, f"'{kw}' is approximated by the first colour of each entry", loc)
    p.expect_op("{")
    entries = []
    while p.accept_op("["):
        entries.append(float_(p) if _starts_value(p) else float(len(entries)))
        _skip_to(p, "]")
        p.expect_op("]")
    if not entries:  # as POV-Ray: "Must have at least one entry in map"
        raise p.error(f"expected at least one [value …] entry in {kw}, found '}}'", loc)
    p.expect_op("}")
    return pig


def parse_pigment_map_body(p, loc, unwritten: float | None = None) -> list:
    """``{ [v PIGMENT_BODY] … }`` or ``{ Identifier }`` after ``pigment_map``: ``(v, PigRec)``
    pairs in order; an entry without ``v`` has ``unwritten`` (None: its index)."""

    def entry(p, entries):
        v = float_(p) if _starts_value(p) else (float(len(entries)) if unwritten is None else unwritten)
        opt_comma(p)
        sub = PigRec()
        while not p.is_op("]"):
            sub = pigment_item(p, sub)
        return v, sub

    return _map_body(p, loc, "pigment_map", PigmentMapRec, entry)


def _map_body(p, loc, kw: str, declared_type, entry) -> list:
    """``{ [ … ] … }`` or ``{ Identifier }`` after map keyword ``kw``: what ``entry(p, entries so
    far)`` reads between each pair of brackets, or the declared map's (a ``declared_type``)."""
    p.expect_op("{", f"'{{' after {kw}")
    t = p.peek()
    if declared(p, t):
        entries = list(_declared_value(p, t, declared_type, kw).entries)
        p.expect_op("}")
        return entries
    entries = []
    while p.accept_op("["):
        entries.append(entry(p, entries))
        p.expect_op("]")
    if not entries:  # as POV-Ray: "Must have at least one entry in map"
        raise p.error(f"expected at least one [value …] entry in {kw}, found '}}'", loc)
    p.expect_op("}")
    return entries


def _skip_to(p, op: str) -> None:
    """Skips tokens (balanced in braces and brackets) up to, not including, ``op``."""
    depth = 0
    while True:
        t = p.peek()
        if t.kind == "eof":
            raise p.error(f"expected '{op}', found end of file", t.loc)
        if t.kind == OP and depth == 0 and t.value == op:
            return
        p.next()
        if t.kind == OP and t.value in "{[(":
            depth += 1
        elif t.kind == OP and t.value in "}])":
            depth -= 1


MAP_KEYWORDS = frozenset({"pigment_map", "normal_map", "slope_map", "texture_map", "material_map",
                          "color_map", "colour_map", "density_map"})


def _refuse_empty_map(p, t) -> None:
    """After a map keyword ``t`` whose ``{`` was just read: ``{ }`` is an error, as in POV-Ray."""
    if p.is_op("}"):
        raise p.error(f"expected at least one [value …] entry in {t.value}, found '}}'", t.loc)


def skip_braces(p) -> None:
    """Skips a balanced ``{ … }`` block (directives and macros inside still run); an empty map
    inside it is still an error, as in POV-Ray."""
    start = p.expect_op("{")
    depth = 1
    while depth:
        t = p.next()
        if t.kind == "eof":
            raise p.error("expected '}', found end of file", start.loc)
        if t.kind == ID and t.value in MAP_KEYWORDS and p.accept_op("{"):
            _refuse_empty_map(p, t)
            depth += 1
            continue
        if t.kind == OP:
            if t.value == "{":
                depth += 1
            elif t.value == "}":
                depth -= 1


# ---- finish ----------------------------------------------------------------------------------
def parse_finish(p, base: dict | None = None) -> dict:
    p.expect_op("{", "'{' after finish")
    fin = dict(base or {})
    while not p.accept_op("}"):
        t = p.peek()
        if declared(p, t):
            fin = dict(_declared_value(p, t, dict, "finish"))
            continue
        p.next()
        if t.kind != ID:
            raise p.error(f"expected a finish item, found {t.describe()}", t.loc)
        finish_item(p, t, fin)
    return fin


def _rgb_of(p, loc):
    return as_color(p, parse_expr(p), loc).c[:3]


def finish_item(p, t, fin: dict) -> None:
    kw = t.value
    if kw in ("ambient", "emission"):
        fin[kw] = _rgb_of(p, t.loc)
    elif kw == "diffuse":
        if p.accept_id("albedo"):
            p.warn("albedo", "diffuse albedo is used as the plain diffuse value", t.loc)
        fin["diffuse"] = float_(p)
        if p.accept_op(","):
            float_(p)
            p.warn("diffuse back", "the back-side diffuse term is not supported", t.loc)
    elif kw in ("phong", "specular"):
        if p.accept_id("albedo"):
            p.warn("albedo", f"{kw} albedo is used as the plain {kw} value", t.loc)
        fin[kw] = float_(p)
    elif kw in ("brilliance", "phong_size", "roughness"):
        fin[kw] = float_(p)
    elif kw == "metallic":
        fin["metallic"] = float_(p) if _starts_value(p) else 1.0
    elif kw == "reflection":
        fin["reflection"] = _parse_reflection(p, t, fin.get("reflection"))
    elif kw == "reflection_exponent":
        fin["reflection"] = dict(fin.get("reflection") or _refl_default(), exponent=float_(p))
    elif kw == "conserve_energy":
        fin["conserve_energy"] = _opt_bool(p)
    elif kw in ("crand", "irid", "subsurface", "caustics", "refraction", "ior", "fade_distance",
                "fade_power", "reflect_metallic", "brilliance_", "translucency"):
        _legacy_finish(p, t, fin)
    else:
        raise p.error(f"expected a finish item, found '{kw}'", t.loc)


def _opt_bool(p) -> bool:
    if _starts_value(p) or p.peek().kind == ID and p.peek().value in ("on", "off", "true", "false",
                                                                       "yes", "no"):
        return float_(p) != 0.0
    return True


def _legacy_finish(p, t, fin):
    kw = t.value
    if kw == "ior":
        fin["legacy_ior"] = float_(p)
    elif kw == "refraction":
        fin["legacy_refraction"] = float_(p)
    elif kw in ("fade_distance", "fade_power"):
        fin["legacy_" + kw] = float_(p)
    elif kw in ("irid", "subsurface"):
        p.warn(kw, f"finish {kw} is not supported; ignored", t.loc)
        if p.is_op("{"):
            skip_braces(p)
    elif kw == "reflect_metallic":
        pass
    else:
        p.warn(kw, f"finish {kw} is not supported; ignored", t.loc)
        _skip_args(p)


def _refl_default():
    return {"min": (0.0, 0.0, 0.0), "max": (0.0, 0.0, 0.0), "falloff": 1.0, "exponent": 1.0,
            "metallic": None, "fresnel": False}


def _parse_reflection(p, t, old):
    """``reflection C`` or ``reflection { [Cmin,] [Cmax] items }`` over the finish's earlier reflection
    (semantics §2.6): the colours are those of this statement (none in a block = 0), the old form
    turns ``fresnel`` off, and ``falloff``, ``exponent``, ``metallic`` and (in a block) ``fresnel``
    carry over from earlier statements, as POV-Ray 3.7 does."""
    r = dict(old or _refl_default())
    if not p.is_op("{"):
        c = _rgb_of(p, t.loc)
        r["min"] = r["max"] = c
        r["fresnel"] = False
        return r
    p.next()
    r["min"] = r["max"] = (0.0, 0.0, 0.0)
    one_colour = False
    if not p.is_id("fresnel") and not p.is_id("falloff") and not p.is_id("exponent") \
            and not p.is_id("metallic") and not p.is_op("}"):
        c1 = _rgb_of(p, t.loc)
        r["min"] = r["max"] = c1
        opt_comma(p)
        if _starts_color(p):
            r["max"] = _rgb_of(p, t.loc)
        else:
            one_colour = True
    while not p.accept_op("}"):
        k = p.next()
        if k.kind == ID and k.value == "fresnel":
            r["fresnel"] = _opt_bool(p)
            if r["fresnel"] and one_colour:  # one colour with fresnel on is the maximum; the minimum is 0
                r["min"] = (0.0, 0.0, 0.0)
        elif k.kind == ID and k.value in ("falloff", "exponent"):
            r[k.value] = float_(p)
        elif k.kind == ID and k.value == "metallic":
            r["metallic"] = float_(p) if _starts_value(p) else 1.0
        else:
            raise p.error(f"expected a reflection item, found {k.describe()}", k.loc)
    return r


# ---- interior --------------------------------------------------------------------------------
def parse_interior(p, base: InteriorRec | None = None) -> InteriorRec:
    p.expect_op("{", "'{' after interior")
    vals = dict(base.values) if base else {}
    while not p.accept_op("}"):
        t = p.peek()
        if declared(p, t):
            vals = dict(_declared_value(p, t, InteriorRec, "interior").values)
            continue
        p.next()
        if t.kind != ID:
            raise p.error(f"expected an interior item, found {t.describe()}", t.loc)
        if t.value in ("ior", "fade_distance", "fade_power"):
            vals[t.value] = float_(p)
        elif t.value in ("fade_color", "fade_colour"):
            vals["fade_color"] = as_color(p, parse_expr(p), t.loc).c[:3]
        elif t.value in ("caustics", "dispersion", "dispersion_samples"):
            p.warn(t.value, f"interior {t.value} is not supported; ignored", t.loc)
            float_(p)
        elif t.value == "media":
            p.warn("media", "media is not supported; ignored", t.loc)
            skip_braces(p)
        else:
            raise p.error(f"expected an interior item, found '{t.value}'", t.loc)
    return InteriorRec(vals)


# ---- textures --------------------------------------------------------------------------------
def parse_texture(p, default: LayerRec) -> TextureRec:
    """``texture { [Ident] pigment finish normal transforms … }`` → a TextureRec (layers)."""
    p.expect_op("{", "'{' after texture")
    layers = [LayerRec(default.pigment, dict(default.finish), default.normal)]
    while not p.accept_op("}"):
        t = p.peek()
        if declared(p, t):
            v = parse_expr(p)
            if not isinstance(v, TextureRec):
                raise p.error(f"expected a texture, found {type_name(v)} '{t.value}'", t.loc)
            layers = list(v.layers)
            continue
        p.next()
        layers = texture_item(p, t, layers, default)
    return TextureRec(layers)


def texture_item(p, t, layers, default):
    kw = t.value if t.kind == ID else None
    top = layers[-1]
    if kw == "pigment":
        return layers[:-1] + [dataclasses.replace(top, pigment=parse_pigment(p, top.pigment))]
    if kw == "finish":
        return layers[:-1] + [dataclasses.replace(top, finish=parse_finish(p, top.finish))]
    if kw == "normal":
        return layers[:-1] + [dataclasses.replace(top, normal=parse_normal(p, top.normal))]
    if kw in TRANSFORM_KEYWORDS:
        m = parse_transform_item(p, t)
        return [layer.transformed(m) for layer in layers]
    if kw in TEXTURE_PATTERNS:
        return _patterned_texture(p, t, layers, default)
    if kw == "uv_mapping":
        p.warn(kw, "uv_mapping is not rendered; the texture uses the object's x, y, z coordinates", t.loc)
        return layers
    if kw == "interior_texture":
        return layers
    if kw in ("quick_color", "quick_colour"):
        parse_color(p)
        return layers
    raise p.error(f"expected a texture item, found {t.describe()}", t.loc)


def _patterned_texture(p, t, layers, default):
    """``texture { PATTERN [modifiers] texture_map {…} }``, a block pattern's list
    (``checker texture {A} texture {B}``) or ``tiles A tile2 B``: a patterned texture, the
    texture's one layer (semantics §5.7). A transform applies to the pattern and to the textures
    read before it, as each is parsed. ``material_map`` is approximated by its first texture
    (warned)."""
    kw = t.value
    pattern = PigRec()
    listed: list = []  # a block pattern's textures, or tiles and tile2
    mapped: list | None = None  # texture_map's (position, TextureRec)
    approximated = None  # where a material_map was read
    tiles = kw == "tiles"
    if kw == "material_map":
        approximated = t.loc
        listed.extend(_material_map_textures(p, t, default))
    elif kw == "tiles":
        pattern = _tiles_pattern()
        listed.extend(_tiles(p, default))
    elif kw == "texture_map":
        mapped = texture_map_body(p, t.loc, default, None)
    elif not patterns.REGISTRY[kw].rendered:
        # a pattern we do not render: its first texture (warned), found in its arguments where
        # they are a block (``object { Obj texture {…}, texture {…} }``)
        p.warn(kw, f"pattern '{kw}' is not supported; the patterned texture shows its first texture", t.loc)
        if p.is_op("{"):
            listed.extend(_block_textures(p, t, default))
        else:
            _skip_args(p)
    else:
        pattern = _pattern(p, patterns.REGISTRY[kw], pattern, t.loc)
    while not p.is_op("}"):
        q = p.peek()
        if q.kind == ID and q.value == "texture" and not declared(p, q):
            p.next()
            listed.append(parse_texture(p, default))
            opt_comma(p)
        elif q.kind == ID and q.value == "tile2":
            p.next()
            listed.append(_tile(p, default))
        elif q.kind == ID and q.value == "tiles":
            p.next()
            pattern = _tiles_pattern()
            listed.extend(_tiles(p, default))
            tiles = True
        elif q.kind == ID and q.value == "texture_map":
            p.next()
            # an average's entries weigh 1 unless given, a map's sit at 0, 1, … unless given
            averaged = pattern.pattern != "solid" and patterns.REGISTRY[pattern.pattern].averaged
            mapped = texture_map_body(p, q.loc, default, 1.0 if averaged else None)
        elif q.kind == ID and q.value in TRANSFORM_KEYWORDS:
            p.next()
            m = parse_transform_item(p, q)
            pattern = pattern.transformed(m)
            listed = [_transformed(tex, m) for tex in listed]
            mapped = None if mapped is None else [(v, _transformed(tex, m)) for v, tex in mapped]
        elif q.kind == ID and q.value == "material_map":
            p.next()
            approximated = approximated or q.loc
            listed.extend(_material_map_textures(p, q, default))
        elif q.kind == ID and q.value in patterns.SDL_KEYWORDS and not declared(p, q):
            p.next()
            pattern = _pattern(p, patterns.REGISTRY[q.value], pattern, q.loc)
        else:
            pattern = pigment_item(p, pattern)
    if tiles:  # (measured: tiles' texture is where a checker's second is, tile2's where its first is)
        listed[:2] = listed[:2][::-1]
    entries = mapped if mapped is not None else [(float(i), tex) for i, tex in enumerate(listed)]
    if not entries:
        raise p.error(f"expected the textures of patterned texture '{kw}' (texture {{…}} or texture_map)",
                      t.loc)
    if mapped is None and pattern.pattern != "solid" and patterns.REGISTRY[pattern.pattern].discrete:
        record = patterns.REGISTRY[pattern.pattern]
        while len(entries) < record.colours:  # a list too short: the default texture for the rest
            entries.append((float(len(entries)), TextureRec([LayerRec(default.pigment, dict(default.finish),
                                                                      default.normal)])))
    if approximated is not None:
        p.warn("material_map", "material_map is approximated by its first texture", approximated)
    if approximated is not None or pattern.pattern == "solid":  # (a pattern we do not render: warned)
        return list(_first_plain_layers(entries[0][1]))
    cmap = [(v, Vec((0, 0, 0, 0, 0))) for v, _ in entries]  # (the map's positions; no colours)
    pattern = dataclasses.replace(pattern, cmap=cmap, cmap_given=True)
    return [LayerRec(patterned=(pattern, entries))]


def layered(p, under: list, over: list, loc) -> list:
    """The layers of texture ``over`` laid on texture ``under`` (both bottom first); a patterned
    texture takes no part in a layered one (POV-Ray's errors, word for word)."""
    if under and under[-1].patterned is not None:
        raise p.error("cannot layer over a patterned texture", loc)
    if under and over and over[0].patterned is not None:
        raise p.error("cannot layer a patterned texture over another", loc)
    return under + over


def _tiles_pattern() -> PigRec:
    """``tiles``' pattern: a checker (its textures listed the other way round)."""
    return PigRec("checker", [(0.0, Vec((0, 0, 0, 0, 0))), (1.0, Vec((0, 0, 0, 0, 0)))], frequency=0.0)


def _first_plain_layers(tex: TextureRec) -> list:
    """The layers of a texture's first plain texture (itself, or its first entry's, nested)."""
    layers = tex.layers
    while len(layers) == 1 and layers[0].patterned is not None:
        layers = layers[0].patterned[1][0][1].layers
    return layers


def _transformed(tex: TextureRec, m) -> TextureRec:
    return TextureRec([layer.transformed(m) for layer in tex.layers])


def _tile(p, default) -> TextureRec:
    """The texture after ``tiles`` or ``tile2``: ``texture {…}`` items (layers) up to the next keyword."""
    layers = [LayerRec(default.pigment, dict(default.finish), default.normal)]
    first = True
    while p.is_id("texture"):
        p.next()
        got = parse_texture(p, default).layers
        layers = list(got) if first else layers + list(got)
        first = False
    return TextureRec(layers)


def _tiles(p, default) -> list:
    """``tiles`` is followed by its texture, or by ``{ TEXTURE tile2 TEXTURE }``: the textures read
    (the second, tile2's, read by the caller when outside the braces)."""
    if not p.accept_op("{"):
        return [_tile(p, default)]
    got = [_tile(p, default)]
    while not p.accept_op("}"):
        t = p.next()
        if t.kind == ID and t.value == "tile2":
            got.append(_tile(p, default))
        else:
            raise p.error(f"expected tile2 or '}}' in tiles, found {t.describe()}", t.loc)
    return got


def _block_textures(p, t, default) -> list:
    """The ``texture {…}`` items of a block (an unrendered pattern's arguments), the rest skipped."""
    p.expect_op("{")
    textures = []
    depth = 1
    while depth:
        q = p.next()
        if q.kind == "eof":
            raise p.error("expected '}', found end of file", t.loc)
        if q.kind == ID and q.value == "texture" and p.is_op("{") and depth == 1:
            textures.append(parse_texture(p, default))
            opt_comma(p)
        elif q.kind == OP and q.value in "{}":
            depth += 1 if q.value == "{" else -1
    return textures


def texture_map_body(p, loc, default, unwritten: float | None = None) -> list:
    """``{ [v TEXTURE_BODY] … }`` or ``{ Identifier }`` after ``texture_map``: ``(v, TextureRec)``
    pairs in order; an entry without ``v`` has ``unwritten`` (None: its index). An entry is what a
    ``texture {…}`` may hold (its items, a declared texture, or ``texture {…}`` itself)."""

    def entry(p, entries):
        v = float_(p) if _starts_value(p) else (float(len(entries)) if unwritten is None else unwritten)
        opt_comma(p)
        layers = [LayerRec(default.pigment, dict(default.finish), default.normal)]
        while not p.is_op("]"):
            q = p.peek()
            if declared(p, q):
                got = _declared_value(p, q, TextureRec, "texture")
                layers = list(got.layers)
                continue
            p.next()
            if q.kind == ID and q.value == "texture" and p.is_op("{"):
                layers = list(parse_texture(p, default).layers)
            else:
                layers = texture_item(p, q, layers, default)
        return v, TextureRec(layers)

    return _map_body(p, loc, "texture_map", TextureMapRec, entry)


def _material_map_textures(p, t, default) -> list:
    """``material_map { TYPE "file" modifiers… texture {…}… }``: its textures (the image that
    chooses among them is not read)."""
    p.expect_op("{", "'{' after material_map")
    _refuse_empty_map(p, t)
    textures = []
    while not p.accept_op("}"):
        q = p.next()
        if q.kind == "eof":
            raise p.error("expected '}', found end of file", t.loc)
        if q.kind == ID and q.value == "texture" and p.is_op("{"):
            textures.append(parse_texture(p, default))
        elif q.kind == OP and q.value == "{":
            depth = 1
            while depth:
                r = p.next()
                if r.kind == "eof":
                    raise p.error("expected '}', found end of file", t.loc)
                if r.kind == OP and r.value in "{}":
                    depth += 1 if r.value == "{" else -1
    if not textures:
        textures.append(TextureRec([LayerRec(default.pigment, dict(default.finish), default.normal)]))
    return textures


def parse_normal(p, base: NormRec | None = None) -> NormRec:
    """``normal { [Ident] PATTERN [amount] modifiers… }``; ``base`` is the normal being modified
    (a layer's current one). A pattern we do not perturb with is warned and perturbs nothing."""
    p.expect_op("{", "'{' after normal")
    nrm = dataclasses.replace(base) if base is not None else NormRec()
    while not p.accept_op("}"):
        t = p.peek()
        if declared(p, t):
            nrm = dataclasses.replace(_declared_value(p, t, NormRec, "normal"))
            continue
        kw = t.value if t.kind == ID else None
        if kw in patterns.SDL_KEYWORDS:
            p.next()
            record = patterns.REGISTRY[kw]
            if record.rendered and not record.discrete:
                nrm.pigment = _pattern(p, record, nrm.pigment, t.loc)
                if p.accept_op(",") or _starts_value(p):  # ``gradient x, 5.6`` as ``gradient x 5.6``
                    nrm.amount = float_(p)
            else:
                nrm.pigment = _unrendered_normal(p, record, nrm.pigment, t.loc)
        elif kw == "bump_size":
            p.next()
            nrm.amount = float_(p)
        elif kw == "accuracy":
            p.next()
            nrm.accuracy = float_(p)
        elif kw == "no_bump_scale":
            p.next()
            if _opt_bool(p):
                p.warn("no_bump_scale", "no_bump_scale is not rendered: the bumps scale with their space",
                       t.loc)
        elif kw in ("slope_map", "normal_map"):
            p.next()
            if kw == "slope_map":
                nrm.slope_map = parse_slope_map_body(p, t.loc)
                continue
            else:
                p.warn("normal_map", "normal_map is not rendered; the surface's own normal is used", t.loc)
                nrm.pigment = PigRec("solid", transform=nrm.pigment.transform)
            p.expect_op("{", f"'{{' after {kw}")
            _refuse_empty_map(p, t)
            _skip_to(p, "}")
            p.expect_op("}")
        elif kw == "bump_map":
            p.next()
            p.warn("bump_map", "bump_map is not rendered; ignored", t.loc)
            skip_braces(p)
        elif kw is None:
            raise p.error(f"expected a normal item, found {t.describe()}", t.loc)
        else:
            nrm.pigment = pigment_item(p, nrm.pigment)
    return nrm


def parse_slope_map_body(p, loc) -> list:
    """``{ [v, <height, slope>] … }`` or ``{ Identifier }`` after ``slope_map``."""

    def entry(p, entries):
        v = float_(p)
        opt_comma(p)
        e = p.peek()
        hs = as_vector(p, parse_expr(p), 2)
        if len(hs) != 2:
            raise p.error("expected <height, slope> in a slope_map entry", e.loc)
        return [v, float(hs[0]), float(hs[1])]

    return _map_body(p, loc, "slope_map", SlopeMapRec, entry)


def _unrendered_normal(p, record: patterns.Pattern, pig: PigRec, loc) -> PigRec:
    """A normal pattern we do not perturb with (a block pattern and its normal list, a pattern we do
    not render): its arguments are skipped; the normal perturbs nothing."""
    what = "a block pattern's normal" if record.rendered else "normal pattern"
    p.warn(record.name, f"{what} '{record.name}' is not rendered; the surface's own normal is used", loc)
    if record.discrete:
        while p.accept_id("normal"):
            skip_braces(p)
            opt_comma(p)
    elif record.argument == "file":
        p.next()  # the file type (df3)
        parse_expr(p)
    elif p.is_op("{"):  # pigment_pattern { … }, function { … }
        skip_braces(p)
    while p.accept_op(",") or _starts_value(p) or p.peek().kind == "str":  # arguments, the amount
        if not p.is_op(","):
            parse_expr(p)
    return PigRec("solid", transform=pig.transform)


def skip_camera_normal(p, t) -> None:
    """A camera's ``normal { }`` (its rays perturbed): not rendered."""
    p.warn("camera normal", "a camera's normal {} is not rendered; ignored", t.loc)
    skip_braces(p)


def parse_material(p, default: LayerRec) -> MaterialRec:
    p.expect_op("{", "'{' after material")
    mat = MaterialRec()
    while not p.accept_op("}"):
        t = p.peek()
        if declared(p, t):
            m = _declared_value(p, t, MaterialRec, "material")
            mat = MaterialRec(m.texture, m.interior)
            continue
        p.next()
        if t.kind == ID and t.value == "texture":
            tex = parse_texture(p, default)
            under = [] if mat.texture is None else mat.texture.layers
            mat.texture = TextureRec(layered(p, under, tex.layers, t.loc))
        elif t.kind == ID and t.value == "interior":
            mat.interior = parse_interior(p, mat.interior)
        elif t.kind == ID and t.value in TRANSFORM_KEYWORDS:
            m = parse_transform_item(p, t)
            if mat.texture is not None:
                mat.texture = TextureRec([layer.transformed(m) for layer in mat.texture.layers])
        elif t.kind == ID and t.value == "interior_texture":
            skip_braces(p)
        else:
            raise p.error(f"expected a material item, found {t.describe()}", t.loc)
    return mat


def describe_value(v) -> str:
    return type_name(v)
