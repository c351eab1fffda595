"""Builders for objects, CSG, light sources, the camera and the scene-level statements."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..scene._lights import (
    LIGHT_SDL_KEYWORDS,
    MAX_AREA_SAMPLES,
    UNSIMULATED_LIGHT_KEYWORDS,
    area_grid_too_large,
)
from ..shapes import SDL_KEYWORDS
from ._convert import as_int
from ._expr import (
    COLOR_KEYWORDS,
    as_color,
    as_float,
    as_vector,
    parse_coefficients,
    parse_color,
    parse_expr,
    type_name,
)
from ._lexer import EOF, ID, OP
from ._textures import (
    TRANSFORM_KEYWORDS,
    _opt_bool,
    _starts_value,
    declared,
    float_,
    layered,
    opt_comma,
    parse_finish,
    parse_interior,
    parse_material,
    parse_normal,
    parse_pigment,
    parse_texture,
    parse_transform_item,
    skip_braces,
    skip_camera_normal,
    vector3,
    warn_noise_generator,
)
from ._values import CameraRec, LayerRec, LightRec, ObjRec, TextureRec, Vec

PRIMITIVES = tuple(SDL_KEYWORDS)
CSG_KEYWORDS = ("union", "intersection", "difference", "merge")
# POV-Ray's object keywords; those without a registered shape are parsed, warned and left out
POV_OBJECTS = ("lathe", "sor", "prism", "sphere_sweep", "blob", "superellipsoid", "height_field", "text",
               "isosurface", "parametric", "julia_fractal", "bicubic_patch", "ovus", "lemon", "poly",
               "cubic", "quartic")
UNSUPPORTED_OBJECTS = tuple(kw for kw in POV_OBJECTS if kw not in SDL_KEYWORDS)
OBJECT_KEYWORDS = PRIMITIVES + CSG_KEYWORDS + UNSUPPORTED_OBJECTS + ("object", "light_source",
                                                                     "light_group")
FLAGS = ("no_shadow", "no_image", "no_reflection", "double_illuminate")


# object flags that change an image and that we read without rendering (the others change
# nothing we render: hollow, sturm, split_union, no_radiosity …)
_IGNORED_FLAG_WARNINGS = {
    "uv_mapping": "uv_mapping is not rendered; the textures use the object's x, y, z coordinates",
    "cutaway_textures": "cutaway_textures is not rendered; every surface keeps its own texture",
}


def is_object_start(p, t) -> bool:
    return t.kind == ID and t.value in OBJECT_KEYWORDS


def parse_object(p):
    """Parses one object statement (keyword not yet consumed): an ObjRec or a LightRec."""
    t = p.next()
    kw = t.value
    if kw == "light_source":
        return parse_light(p, t)
    if kw == "object":
        return _parse_object_ident(p, t)
    copy = _object_id_copy(p, t)
    if copy is not None:
        return copy
    if kw in CSG_KEYWORDS or kw == "light_group":
        return _parse_csg(p, t)
    if kw in UNSUPPORTED_OBJECTS:
        return _parse_unsupported(p, t)
    rec = ObjRec(kw, loc=t.loc)
    p.expect_op("{", f"'{{' after {kw}")
    rec.shape = SDL_KEYWORDS[kw].parse_sdl(kw, _ShapeArgs(p, rec))
    object_modifiers(p, rec)
    return rec


def _object_id_copy(p, t):
    """``sphere { Ident … }``: as povray does, an object identifier first in any object's braces
    makes the object a copy of it — whatever its kind (``mesh { MySphere }`` is a sphere) — and
    only modifiers may follow (checked with povray 3.7: ``union { A sphere {…} }`` is an error).
    Returns None (nothing read) when the braces do not start with an object identifier."""
    if p.la is not None:
        return None
    brace, ident = p.raw_peek(0), p.raw_peek(1)
    if brace is None or brace.kind != OP or brace.value != "{" or ident is None or ident.kind != ID:
        return None
    v = p.lookup(ident.value)
    if not isinstance(v, ObjRec):
        return None
    p.next(), p.next()
    rec = v.clone()
    object_modifiers(p, rec)
    return rec


def _parse_unsupported(p, t):
    p.warn(t.value, f"{t.value} objects are not supported; the object is left out", t.loc)
    skip_braces(p)
    return ObjRec(t.value, loc=t.loc, supported=False)


def _parse_object_ident(p, t):
    p.expect_op("{", "'{' after object")
    nt = p.peek()
    if is_object_start(p, nt):
        rec = parse_object(p)
    elif declared(p, nt):
        v = parse_expr(p)
        if not isinstance(v, (ObjRec, LightRec)):
            raise p.error(f"expected an object identifier, found {type_name(v)} '{nt.value}'",
                          nt.loc)
        rec = v.clone()
    else:
        raise p.error(f"expected an object identifier or object, found {nt.describe()}", nt.loc)
    if isinstance(rec, LightRec):
        light_modifiers(p, rec)
        return rec
    object_modifiers(p, rec)
    return rec


def _parse_csg(p, t):
    kw = t.value
    if kw == "light_group":
        p.warn("light_group", "light_group is treated as a union (its lights light everything)", t.loc)
        kw = "union"
    rec = ObjRec(kw, loc=t.loc)
    p.expect_op("{", f"'{{' after {t.value}")
    object_modifiers(p, rec, csg=True)
    rec.depth = 1 + max((c.depth for c in rec.children if isinstance(c, ObjRec)), default=0)
    if rec.depth > p.limits.max_csg_depth:
        raise p.error(f"CSG objects nested deeper than {p.limits.max_csg_depth} (Limits.max_csg_depth; "
                      "the renderer walks the tree by recursion)", t.loc)
    if not rec.children:
        p.warn(kw, f"empty {kw}; left out", t.loc)
        rec.supported = False
    return rec


def object_modifiers(p, rec: ObjRec, csg: bool = False) -> None:
    """Reads modifiers (and CSG children) up to and including the closing '}'."""
    while True:
        t = p.peek()
        if t.kind == OP and t.value == "}":
            p.next()
            return
        if t.kind == EOF:
            raise p.error("expected '}' to close the object, found end of file", t.loc)
        if csg and is_object_start(p, t):
            rec.children.append(parse_object(p))
            continue
        p.next()
        if t.kind != ID:
            raise p.error(f"expected an object modifier, found {t.describe()}", t.loc)
        _modifier(p, rec, t)


def _layers(p, rec):
    if rec.layers is None:
        d = p.default_layer
        rec.layers = [LayerRec(d.pigment, dict(d.finish), d.normal)]
    return rec.layers


def _modifier(p, rec: ObjRec, t) -> None:
    kw = t.value
    if kw in TRANSFORM_KEYWORDS:
        rec.apply_transform(parse_transform_item(p, t))
    elif kw == "texture":
        tex = parse_texture(p, p.default_layer)
        old = rec.layers if rec.layers_given and rec.layers else []
        rec.layers = layered(p, old, list(tex.layers), t.loc)
        rec.layers_given = True
    elif kw == "pigment":
        layers = _layers(p, rec)
        top = layers[-1]
        layers[-1] = dataclasses.replace(top, pigment=parse_pigment(p, top.pigment))
    elif kw == "finish":
        layers = _layers(p, rec)
        top = layers[-1]
        layers[-1] = dataclasses.replace(top, finish=parse_finish(p, top.finish))
    elif kw == "normal":
        layers = _layers(p, rec)
        top = layers[-1]
        layers[-1] = dataclasses.replace(top, normal=parse_normal(p, top.normal))
    elif kw == "interior":
        rec.interior = parse_interior(p, rec.interior)
    elif kw == "material":
        mat = parse_material(p, p.default_layer)
        if mat.texture is not None:
            rec.layers = list(mat.texture.layers)
        if mat.interior is not None:
            rec.interior = mat.interior
    elif kw in FLAGS:
        rec.flags[kw] = _opt_bool(p)
    elif kw == "inverse":
        rec.flags["inverse"] = not rec.flags.get("inverse", False)
    elif rec.kind in SDL_KEYWORDS and kw in SDL_KEYWORDS[rec.kind].sdl_flags:
        rec.shape[kw] = True
    elif kw in ("hollow", "sturm", "smooth", "split_union", "global_lights", "cutaway_textures",
                "no_radiosity",
                "uv_mapping", "hierarchy"):
        on = float_(p) != 0 if _starts_value(p) else True
        if on and kw in _IGNORED_FLAG_WARNINGS:
            p.warn(kw, _IGNORED_FLAG_WARNINGS[kw], t.loc)
    elif kw == "clipped_by":
        _clipped_by(p, rec)
    elif kw == "bounded_by":
        _bounded_by(p, rec)
    elif kw in ("photons", "radiosity", "interior_texture"):
        p.warn(kw, f"object {kw} {{}} is not supported; ignored", t.loc)
        skip_braces(p)
    elif kw == "inside_vector":
        vector3(p)
    elif kw == "light_source" and rec.kind in ("union",):
        rec.children.append(parse_light(p, t))
    else:
        raise p.error(f"expected an object modifier, found '{kw}'", t.loc)


def _clipped_by(p, rec):
    p.expect_op("{")
    if p.accept_id("bounded_by"):
        rec.clipped_by = list(rec.bounded_by)
        p.expect_op("}")
        return
    while not p.accept_op("}"):
        t = p.peek()
        if not is_object_start(p, t):
            raise p.error(f"expected an object in clipped_by, found {t.describe()}", t.loc)
        child = parse_object(p)
        if isinstance(child, ObjRec) and child.supported:
            rec.clipped_by.append(_after(rec, child))
        elif isinstance(child, ObjRec):
            p.warn("clipped_by", f"clipped_by {child.kind} is left out", t.loc)


def _bounded_by(p, rec):
    """bounded_by, an acceleration hint: the plan bounds by it an object without a box of its own
    (``_plan.has_box``); kept for clipped_by { bounded_by } too."""
    p.expect_op("{")
    if p.accept_id("clipped_by"):
        p.expect_op("}")
        return
    kids = []
    while not p.accept_op("}"):
        t = p.peek()
        if not is_object_start(p, t):
            raise p.error(f"expected an object in bounded_by, found {t.describe()}", t.loc)
        kids.append(parse_object(p))
    rec.bounded_by = [_after(rec, k) for k in kids if isinstance(k, ObjRec) and k.supported]


def _after(rec: ObjRec, child: ObjRec) -> ObjRec:
    """A ``clipped_by`` or ``bounded_by`` object of ``rec``, moved by the transforms ``rec`` is
    given after it only, as POV-Ray moves it (measured: ``scale 2 clipped_by { box {…} }`` clips by
    the box as written): the object's transforms so far are undone on it, since the renderer
    moves it with all of the object's."""
    if rec.transform is not None:
        try:
            child.apply_transform(np.linalg.inv(rec.transform))
        except np.linalg.LinAlgError:
            pass  # a singular transform (scale 0) has nothing left to see
    return child


# ---- shapes ----------------------------------------------------------------------------------
# Each shape's syntax lives with the shape (``raytracer.shapes``); it reads its arguments through
# this facade, so the shape modules never import the interpreter.
MAX_COUNT = 10_000_000  # entries of a polygon, mesh2 list … (a larger count is an error, not a hang)


class _ShapeArgs:
    """The interpreter as ``raytracer.shapes.ShapeArgs`` for the object record ``rec``."""

    def __init__(self, p, rec: ObjRec):
        self._p, self._rec = p, rec

    @property
    def loc(self):
        return self._p.peek().loc

    def float(self) -> float:
        return float_(self._p)

    def expr(self):
        return parse_expr(self._p)

    def vector(self, size: int = 3, *, allow_2d: bool = False) -> tuple:
        p = self._p
        first = p.peek()
        if first.kind == OP and first.value == "<" and not allow_2d:
            comps = p.literal_vector()
            if comps is not None:
                return (comps + (0.0,) * size)[:size]
        v = parse_expr(p)
        if allow_2d and not (isinstance(v, Vec) and len(v) >= 3):
            return as_vector(p, v, 2, first.loc) + (0.0,)
        if isinstance(v, Vec):
            return v.padded(size)
        return as_vector(p, v, size, first.loc)

    def coefficients(self, count: int) -> tuple[float, ...]:
        return parse_coefficients(self._p, count)

    def count(self, what: str) -> int:
        p = self._p
        loc = p.peek().loc
        return as_int(p, parse_expr(p), loc, f"a number of {what}", 0, MAX_COUNT)

    def comma(self) -> None:
        opt_comma(self._p)

    def accept(self, op: str) -> bool:
        return self._p.accept_op(op)

    def expect(self, op: str, what: str = "") -> None:
        self._p.expect_op(op, what or None)

    def keyword(self, *names: str) -> str | None:
        t = self._p.peek()
        if t.kind == ID and t.value in names:
            self._p.next()
            return t.value
        return None

    def number_after_comma(self) -> bool:
        p = self._p
        if not p.is_op(","):
            return False
        t = p.raw_peek(0) if p.la is not None else None
        return t is not None and t.kind == "num"

    def texture(self, identifier: str | None = None) -> None:
        """A part's ``texture { … }`` or texture identifier; only an identifier where ``identifier``
        names the list it is read in (``texture_list``)."""
        p = self._p
        loc = p.peek().loc
        tex = p.lookup(p.peek().value) if p.peek().kind == ID and not p.is_op("{") else None
        if isinstance(tex, TextureRec):
            p.next()
        elif identifier is not None:
            raise p.error(f"expected a texture identifier in {identifier}, found {p.peek().describe()}", loc)
        else:
            tex = parse_texture(p, p.default_layer)
        self._part_texture(list(tex.layers), loc)

    def _part_texture(self, layers, loc) -> None:
        p, rec = self._p, self._rec
        if not rec.flags.get("_part_texture_seen"):
            rec.flags["_part_texture_seen"] = True
            p.warn(f"{rec.kind} texture", f"per-part {rec.kind} textures are not supported; the first one "
                   f"is used for the whole {rec.kind}", loc)
            rec.layers = layers

    def part(self, what: str) -> np.ndarray:
        p = self._p
        matrix = np.eye(4)
        while True:
            t = p.peek()
            if t.kind == OP and t.value == "}":
                p.next()
                return matrix
            if t.kind == EOF:
                raise p.error(f"expected '}}' to close the {what}, found end of file", t.loc)
            if t.kind != ID:
                raise p.error(f"expected a {what} modifier, found {t.describe()}", t.loc)
            p.next()
            if t.value in TRANSFORM_KEYWORDS:
                matrix = parse_transform_item(p, t) @ matrix
            elif t.value == "texture":
                self._part_texture(list(parse_texture(p, p.default_layer).layers), t.loc)
            elif t.value in ("pigment", "finish", "normal"):
                d = p.default_layer
                layer = LayerRec(d.pigment, dict(d.finish), d.normal)
                if t.value == "pigment":
                    layer = dataclasses.replace(layer, pigment=parse_pigment(p, layer.pigment))
                elif t.value == "finish":
                    layer = dataclasses.replace(layer, finish=parse_finish(p, layer.finish))
                else:
                    layer = dataclasses.replace(layer, normal=parse_normal(p, layer.normal))
                self._part_texture([layer], t.loc)
            else:
                raise p.error(f"expected a {what} modifier (a transform, texture, pigment, finish or "
                              f"normal), found '{t.value}'", t.loc)

    def skip_block(self) -> None:
        skip_braces(self._p)

    def describe_next(self) -> str:
        return self._p.peek().describe()

    def error(self, message: str, loc=None):
        return self._p.error(message, loc)

    def warn(self, feature: str, message: str, loc=None) -> None:
        self._p.warn(feature, message, loc or self._p.peek().loc)

    def find_file(self, name: str, what: str) -> str:
        return self._p.resolve_include(name, self.loc, what=what)

    def leave_out(self, message: str) -> None:
        self._rec.supported = False
        self._p.warn(self._rec.kind, message, self._rec.loc)

    def function(self, n_args: int = 3):
        """``function { … }`` (its body, or a declared function's name and
        arguments), compiled (``_functions.compile_function``): ``(expression, constants)``. What
        is not compiled leaves the object out, its warning naming it (then a constant 1); a body
        that is not a function is the scene's error at its place."""
        from ._functions import Malformed, Unsupported, compile_function

        p = self._p
        t = p.peek()
        if t.kind != ID or t.value != "function":
            raise p.error(f"expected function {{ … }}, found {t.describe()}", t.loc)
        loc = t.loc
        fn = p.parse_function()
        try:
            return compile_function(p, fn, n_args)
        except Malformed as e:
            raise p.error(e.what, e.loc or loc) from None
        except Unsupported as e:
            self._rec.supported = False
            p.warn(self._rec.kind, f"{self._rec.kind} left out: its function uses {e.what}, "
                   "which is not rendered", e.loc or loc)
            return ("const", 0), (1.0,)


# ---- lights ----------------------------------------------------------------------------------
def parse_light(p, t) -> LightRec:
    p.expect_op("{", "'{' after light_source")
    nt = p.peek()
    if declared(p, nt) and not isinstance(p.lookup(nt.value), (float, Vec)):
        v = parse_expr(p)
        if not isinstance(v, LightRec):
            raise p.error(f"expected a light_source, found {type_name(v)} '{nt.value}'", nt.loc)
        rec = v.clone()
    else:
        rec = LightRec(np.asarray(vector3(p), dtype=np.float64), loc=t.loc)
        opt_comma(p)
        if not p.is_op("}") and _light_color_follows(p):
            rec.color = parse_color(p)
    light_modifiers(p, rec)
    return rec


MAX_AREA_LIGHT_SIZE = 4096  # samples along one axis of an area light (POV-Ray's own cap is larger)


def _area_size(p) -> int:
    """One axis of ``area_light``'s sample grid: POV-Ray treats sizes below 1 as 1."""
    loc = p.peek().loc
    n = as_int(p, parse_expr(p), loc, "an area_light size", -MAX_AREA_LIGHT_SIZE, MAX_AREA_LIGHT_SIZE)
    return max(1, n)


def _light_value(p, how):
    """One light_source item's value, read as its type declares (``LightType.sdl_keywords``)."""
    if how == "flag":
        return True
    if how == "float":
        return float_(p)
    if how == "float?":
        return float_(p) if _starts_value(p) else None
    values, grid, at = [], [], None
    for i, part in enumerate(how):
        if i:
            opt_comma(p)
        if part == "size":
            at = at or p.peek().loc
            grid.append(_area_size(p))
        values.append(grid[-1] if part == "size" else vector3(p))
    if len(grid) == 2 and grid[0] * grid[1] > MAX_AREA_SAMPLES:
        raise p.error(area_grid_too_large(*grid), at)
    return tuple(values)


def _light_color_follows(p) -> bool:
    t = p.peek()
    if t.kind == ID and (t.value in COLOR_KEYWORDS or t.value in ("red", "green", "blue")):
        return True
    return _starts_value(p)


def light_modifiers(p, rec: LightRec) -> None:
    while not p.accept_op("}"):
        t = p.next()
        if t.kind != ID:
            raise p.error(f"expected a light_source item, found {t.describe()}", t.loc)
        _light_item(p, rec, t)


def _light_item(p, rec, t):
    kw = t.value
    if kw in TRANSFORM_KEYWORDS:
        m = parse_transform_item(p, t)
        rec.transform = m if rec.transform is None else m @ rec.transform
    elif kw == "point_at":
        rec.point_at = np.asarray(vector3(p), dtype=np.float64)
    elif kw in ("color", "colour") or kw in COLOR_KEYWORDS:
        p.la = t  # let the colour parser see the keyword
        rec.color = parse_color(p)
    elif kw in LIGHT_SDL_KEYWORDS:
        light_type, how = LIGHT_SDL_KEYWORDS[kw]
        if how == "kind":
            rec.kind = kw
            if light_type.rendered_as is not None:
                p.warn(f"{kw} light", f"{kw} lights are treated as {light_type.rendered_as}s", t.loc)
        else:
            rec.values[kw] = _light_value(p, how)
            if kw in UNSIMULATED_LIGHT_KEYWORDS and rec.values[kw] != 0:  # None: given bare
                p.warn(kw, UNSIMULATED_LIGHT_KEYWORDS[kw], t.loc)
    elif kw == "looks_like":
        p.warn("looks_like", "light_source looks_like is not supported; dropped", t.loc)
        skip_braces(p)
    elif kw in ("media_interaction", "media_attenuation"):
        _opt_bool(p)
    elif kw == "photons":
        p.warn("photons", "light photons {} is not supported; ignored", t.loc)
        skip_braces(p)
    elif kw == "projected_through":
        p.warn("projected_through", "projected_through is not supported; ignored", t.loc)
        skip_braces(p)
    else:
        raise p.error(f"expected a light_source item, found '{kw}'", t.loc)


# ---- camera ----------------------------------------------------------------------------------
CAMERA_VECTORS = ("location", "direction", "up", "right", "sky", "look_at")


def parse_camera(p, t) -> CameraRec:
    p.expect_op("{", "'{' after camera")
    nt = p.peek()
    cam = CameraRec(loc=t.loc)
    if declared(p, nt):
        v = parse_expr(p)
        if not isinstance(v, CameraRec):
            raise p.error(f"expected a camera, found {type_name(v)} '{nt.value}'", nt.loc)
        cam = v.clone()
    while not p.accept_op("}"):
        k = p.next()
        if k.kind != ID:
            raise p.error(f"expected a camera item, found {k.describe()}", k.loc)
        _camera_item(p, cam, k)
    angle = cam.values.get("angle")
    # POV-Ray's rule for its perspective camera (a fisheye's or a panorama's angle may be wider)
    if angle is not None and cam.projection == "perspective" and cam.other_projection is None \
            and not angle < 180:
        raise p.error(f"expected a perspective viewing angle below 180 degrees, found {angle:g}",
                      cam.angle_loc)
    return cam


def _camera_item(p, cam, k):
    kw = k.value
    if kw in CAMERA_VECTORS:
        cam.values[kw] = vector3(p)
    elif kw == "angle":
        cam.angle_loc = p.peek().loc
        cam.values["angle"] = float_(p)
        opt_comma(p)
        if _starts_value(p):  # the spherical camera's vertical angle
            cam.values["angle_vertical"] = float_(p)
    elif kw in ("perspective", "orthographic", "fisheye", "spherical"):
        cam.projection, cam.other_projection = kw, None
    elif kw == "cylinder":
        loc = p.peek().loc
        kind = as_int(p, parse_expr(p), loc, "a cylinder camera type", 1, 4)
        cam.projection, cam.other_projection = f"cylinder {kind}", None
    elif kw in ("ultra_wide_angle", "omnimax", "panoramic", "mesh_camera", "user_defined"):
        p.warn(kw, f"{kw} camera is rendered as perspective", k.loc)
        cam.projection, cam.other_projection = "perspective", kw
        if kw in ("mesh_camera", "user_defined"):
            skip_braces(p)
    elif kw in TRANSFORM_KEYWORDS:
        m = parse_transform_item(p, k)
        cam.transform = m if cam.transform is None else m @ cam.transform
    elif kw == "focal_point":
        vector3(p)
    elif kw == "aperture":
        if float_(p) > 0:
            p.warn("focal blur", "focal blur (aperture) is not supported", k.loc)
    elif kw in ("blur_samples", "confidence", "variance"):
        float_(p)
        if kw == "blur_samples" and p.accept_op(","):
            float_(p)
    elif kw == "bokeh":
        skip_braces(p)
    elif kw == "normal":
        skip_camera_normal(p, k)
    else:
        raise p.error(f"expected a camera item, found '{kw}'", k.loc)


# ---- scene-level statements ------------------------------------------------------------------
def parse_global_settings(p, t) -> None:
    p.statement_locs["global_settings"] = t.loc
    p.expect_op("{", "'{' after global_settings")
    while not p.accept_op("}"):
        k = p.next()
        if k.kind != ID:
            raise p.error(f"expected a global setting, found {k.describe()}", k.loc)
        kw = k.value
        if kw == "assumed_gamma":
            loc = p.peek().loc
            p.assumed_gamma = float_(p)
            if not p.assumed_gamma > 0:  # POV-Ray: "gamma value must be positive"
                raise p.error(f"expected a positive assumed_gamma, found {p.assumed_gamma:g}", loc)
        elif kw == "max_trace_level":
            loc = p.peek().loc
            level = as_int(p, parse_expr(p), loc, "max_trace_level")
            if level > 256:  # POV-Ray's words
                p.warn("max_trace_level", f"Maximum max_trace_level is 256 but {level} was specified; "
                       "using 256", loc)
            p.settings["max_trace_level"] = level
        elif kw == "adc_bailout":
            p.settings["adc_bailout"] = float_(p)
        elif kw == "ambient_light":
            p.settings["ambient_light"] = as_color(p, parse_expr(p), k.loc).c[:3]
        elif kw == "number_of_waves":
            if float_(p) != 10:
                p.warn(kw, "number_of_waves is not supported; the default 10 is used", k.loc)
        elif kw in ("noise_generator", "max_intersections", "mm_per_unit", "hf_gray_16",
                    "irid_wavelength", "charset"):
            if kw == "irid_wavelength":
                parse_color(p)
            elif kw == "charset":
                p.next()
            elif kw == "noise_generator":
                warn_noise_generator(p, float_(p), k.loc)
            elif _starts_value(p):
                float_(p)
        elif kw in ("radiosity", "photons", "subsurface"):
            p.warn(kw, f"{kw} is not supported; ignored", k.loc)
            skip_braces(p)
        else:
            raise p.error(f"expected a global setting, found '{kw}'", k.loc)


def parse_background(p, t) -> None:
    p.statement_locs["background"] = t.loc
    p.expect_op("{", "'{' after background")
    c = parse_color(p)
    p.expect_op("}", "'}' to close background")
    # POV 3.7 pre-multiplies the background by (1 - transmit) at parse time (semantics §2.2)
    p.background = tuple(v * (1.0 - c.c[4]) for v in c.c[:3])


def parse_default(p, tok) -> None:
    p.expect_op("{", "'{' after #default")
    while not p.accept_op("}"):
        k = p.next()
        d = p.default_layer
        if k.kind == ID and k.value == "texture":
            tex = parse_texture(p, d)
            if tex.layers[-1].patterned is not None:  # (POV-Ray's error, in its words)
                raise p.error("a default texture cannot be a patterned texture (material map or tiles)",
                              k.loc)
            p.default_layer = tex.layers[-1]
        elif k.kind == ID and k.value == "pigment":
            p.default_layer = dataclasses.replace(d, pigment=parse_pigment(p, d.pigment))
        elif k.kind == ID and k.value == "finish":
            p.default_layer = dataclasses.replace(d, finish=parse_finish(p, d.finish))
        elif k.kind == ID and k.value == "normal":
            p.default_layer = dataclasses.replace(d, normal=parse_normal(p, d.normal))
        elif k.kind == ID and k.value in ("camera", "light_source", "interior", "media"):
            p.warn("#default", f"#default {k.value} is not supported; ignored", k.loc)
            skip_braces(p)
        else:
            raise p.error(f"expected texture, pigment, finish or normal in #default, found "
                          f"{k.describe()}", k.loc)


def as_float_any(p, v, loc):
    return as_float(p, v, loc)
