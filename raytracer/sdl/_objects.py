"""Builders for objects, CSG, light sources, the camera and the scene-level statements."""

from __future__ import annotations

import numpy as np

from ._expr import COLOR_KEYWORDS, as_color, as_float, as_vector, parse_color, parse_expr, type_name
from ._lexer import EOF, ID, OP
from ._textures import (
    TRANSFORM_KEYWORDS,
    _opt_bool,
    _starts_value,
    declared,
    float_,
    opt_comma,
    parse_finish,
    parse_interior,
    parse_material,
    parse_normal,
    parse_pigment,
    parse_texture,
    parse_transform_item,
    skip_braces,
    vector3,
)
from ._values import CameraRec, LayerRec, LightRec, ObjRec, TextureRec, Vec

PRIMITIVES = ("sphere", "plane", "box", "cylinder", "cone", "torus", "disc", "quadric", "polygon",
              "triangle", "smooth_triangle", "mesh", "mesh2")
CSG_KEYWORDS = ("union", "intersection", "difference", "merge")
UNSUPPORTED_OBJECTS = ("lathe", "sor", "prism", "sphere_sweep", "blob", "superellipsoid",
                       "height_field", "text", "isosurface", "parametric", "julia_fractal",
                       "bicubic_patch", "ovus", "lemon", "poly", "cubic", "quartic")
OBJECT_KEYWORDS = PRIMITIVES + CSG_KEYWORDS + UNSUPPORTED_OBJECTS + ("object", "light_source",
                                                                     "light_group")
FLAGS = ("no_shadow", "no_image", "no_reflection", "double_illuminate")


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
    rec = ObjRec(kw, loc=t.loc, default_layer=p.default_layer)
    p.expect_op("{", f"'{{' after {kw}")
    SHAPES[kw](p, rec)
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
    rec = ObjRec(kw, loc=t.loc, default_layer=p.default_layer)
    p.expect_op("{", f"'{{' after {t.value}")
    object_modifiers(p, rec, csg=True)
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
        rec.layers = [LayerRec(d.pigment, dict(d.finish))]
    return rec.layers


def _modifier(p, rec: ObjRec, t) -> None:
    kw = t.value
    if kw in TRANSFORM_KEYWORDS:
        rec.apply_transform(parse_transform_item(p, t))
    elif kw == "texture":
        tex = parse_texture(p, p.default_layer)
        old = rec.layers if rec.layers_given and rec.layers else []
        rec.layers = old + list(tex.layers)
        rec.layers_given = True
    elif kw == "pigment":
        layers = _layers(p, rec)
        top = layers[-1]
        layers[-1] = LayerRec(parse_pigment(p, top.pigment), top.finish)
    elif kw == "finish":
        layers = _layers(p, rec)
        top = layers[-1]
        layers[-1] = LayerRec(top.pigment, parse_finish(p, top.finish))
    elif kw == "normal":
        parse_normal(p, t)
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
    elif kw == "open" and rec.kind in ("cylinder", "cone"):
        rec.shape["open"] = True
    elif kw in ("hollow", "sturm", "smooth", "split_union", "global_lights", "cutaway_textures",
                "no_radiosity",
                "uv_mapping", "hierarchy"):
        if _starts_value(p):
            float_(p)
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
            rec.clipped_by.append(child)
        elif isinstance(child, ObjRec):
            p.warn("clipped_by", f"clipped_by {child.kind} is left out", t.loc)


def _bounded_by(p, rec):
    """bounded_by is only an acceleration hint: parsed, kept for clipped_by { bounded_by }."""
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
    rec.bounded_by = [k for k in kids if isinstance(k, ObjRec) and k.supported]


# ---- shapes ----------------------------------------------------------------------------------
def _sphere(p, rec):
    rec.shape = {"center": vector3(p)}
    opt_comma(p)
    rec.shape["radius"] = float_(p)


def _plane(p, rec):
    t = p.peek()
    n = np.asarray(vector3(p), dtype=np.float64)
    opt_comma(p)
    d = float_(p)
    length = float(np.linalg.norm(n))
    if length == 0:
        raise p.error("expected a non-zero plane normal, found <0,0,0>", t.loc)
    rec.shape = {"normal": tuple(n / length), "distance": d}


def _box(p, rec):
    a = vector3(p)
    opt_comma(p)
    rec.shape = {"corner1": a, "corner2": vector3(p)}


def _cylinder(p, rec):
    a = vector3(p)
    opt_comma(p)
    b = vector3(p)
    opt_comma(p)
    rec.shape = {"base": a, "cap": b, "radius": float_(p)}


def _cone(p, rec):
    a = vector3(p)
    opt_comma(p)
    r0 = float_(p)
    opt_comma(p)
    b = vector3(p)
    opt_comma(p)
    rec.shape = {"base": a, "base_radius": r0, "cap": b, "cap_radius": float_(p)}


def _torus(p, rec):
    a = float_(p)
    opt_comma(p)
    rec.shape = {"major": a, "minor": float_(p)}


def _disc(p, rec):
    c = vector3(p)
    opt_comma(p)
    n = vector3(p)
    opt_comma(p)
    r = float_(p)
    hole = 0.0
    if p.accept_op(","):
        hole = float_(p)
    rec.shape = {"center": c, "normal": n, "radius": r, "hole_radius": hole}


def _quadric(p, rec):
    a = vector3(p)
    opt_comma(p)
    b = vector3(p)
    opt_comma(p)
    c = vector3(p)
    opt_comma(p)
    rec.shape = {"coeffs": (*a, *b, *c, float_(p))}


def _polygon(p, rec):
    t = p.peek()
    n = int(float_(p))
    pts = []
    for _ in range(n):
        opt_comma(p)
        v = parse_expr(p)
        pts.append(as_vector(p, v, 3, t.loc) if isinstance(v, Vec) and len(v) >= 3
                   else as_vector(p, v, 2, t.loc) + (0.0,))
    if n < 3:
        raise p.error(f"expected at least 3 polygon points, found {n}", t.loc)
    rec.shape = {"points": pts}


def _triangle(p, rec):
    a = vector3(p)
    opt_comma(p)
    b = vector3(p)
    opt_comma(p)
    rec.shape = {"p1": a, "p2": b, "p3": vector3(p)}


def _smooth_triangle(p, rec):
    vals = []
    for i in range(6):
        if i:
            opt_comma(p)
        vals.append(vector3(p))
    rec.shape = {"p1": vals[0], "n1": vals[1], "p2": vals[2], "n2": vals[3], "p3": vals[4],
                 "n3": vals[5]}


def _mesh(p, rec):
    tris, norms, smooth = [], [], False
    while p.peek().kind == ID and p.peek().value in ("triangle", "smooth_triangle"):
        t = p.next()
        p.expect_op("{")
        sub = ObjRec(t.value)
        (_triangle if t.value == "triangle" else _smooth_triangle)(p, sub)
        s = sub.shape
        tris.append((s["p1"], s["p2"], s["p3"]))
        if t.value == "smooth_triangle":
            smooth = True
            norms.append((s["n1"], s["n2"], s["n3"]))
        else:
            norms.append(None)
        while not p.accept_op("}"):
            k = p.next()
            if k.kind == ID and k.value == "texture":
                _mesh_texture(p, rec, k)
            elif k.kind == ID and k.value == "uv_vectors":
                for i in range(3):
                    if i:
                        opt_comma(p)
                    parse_expr(p)
            else:
                raise p.error(f"expected '}}' after the mesh triangle, found {k.describe()}", k.loc)
    _set_mesh(p, rec, tris, norms, smooth)


def _mesh_texture(p, rec, k):
    if not rec.flags.get("_mesh_tex_warned"):
        p.warn("mesh texture", "per-triangle mesh textures are not supported; the first one is used "
               "for the whole mesh", k.loc)
    tex = p.lookup(p.peek().value) if p.peek().kind == ID and not p.is_op("{") else None
    if isinstance(tex, TextureRec):
        p.next()
    else:
        tex = parse_texture(p, p.default_layer)
    if not rec.flags.get("_mesh_tex_warned"):
        rec.flags["_mesh_tex_warned"] = True
        rec.layers = list(tex.layers)


def _set_mesh(p, rec, tris, norms, smooth):
    if not tris:
        rec.supported = False
        p.warn("mesh", "empty mesh; left out", rec.loc)
        return
    n = None
    if smooth:
        n = []
        for tri, nn in zip(tris, norms, strict=True):
            if nn is None:
                a, b, c = (np.asarray(v) for v in tri)
                fn = np.cross(b - a, c - a)
                nn = (fn, fn, fn)
            n.append(nn)
        n = np.asarray(n, dtype=np.float64)
    rec.shape = {"triangles": np.asarray(tris, dtype=np.float64), "normals": n}


def _count_list(p, name):
    p.expect_op("{", f"'{{' after {name}")
    t = p.peek()
    n = int(float_(p))
    items = []
    for _ in range(n):
        opt_comma(p)
        items.append(parse_expr(p))
    opt_comma(p)
    p.expect_op("}", f"'}}' to close {name} ({n} entries)")
    return items, t.loc


def _mesh2(p, rec):
    verts = normals = faces = nidx = None
    while p.peek().kind == ID and p.peek().value in ("vertex_vectors", "normal_vectors",
                                                      "uv_vectors", "texture_list", "face_indices",
                                                      "normal_indices", "uv_indices"):
        t = p.next()
        if t.value == "texture_list":
            p.warn("mesh2 texture_list", "mesh2 texture_list is not supported; ignored", t.loc)
            skip_braces(p)
            continue
        if t.value == "face_indices":
            faces = _face_list(p)
            continue
        items, loc = _count_list(p, t.value)
        if t.value == "vertex_vectors":
            verts = [as_vector(p, v, 3, loc) for v in items]
        elif t.value == "normal_vectors":
            normals = [as_vector(p, v, 3, loc) for v in items]
        elif t.value == "normal_indices":
            nidx = [tuple(int(c) for c in as_vector(p, v, 3, loc)) for v in items]
    if verts is None or faces is None:
        raise p.error("expected vertex_vectors and face_indices in mesh2", rec.loc)
    try:
        tris = [tuple(verts[i] for i in f) for f in faces]
        norms = None
        if normals is not None:
            idx = nidx if nidx is not None else faces
            norms = [tuple(normals[i] for i in f) for f in idx]
    except IndexError:
        raise p.error("mesh2 index out of range", rec.loc) from None
    _set_mesh(p, rec, tris, norms or [None] * len(tris), norms is not None)


def _face_list(p):
    p.expect_op("{")
    t = p.peek()
    n = int(float_(p))
    faces = []
    for _ in range(n):
        opt_comma(p)
        v = parse_expr(p)
        faces.append(tuple(int(c) for c in as_vector(p, v, 3, t.loc)))
        # optional texture indices after a face
        while p.is_op(",") and _texture_index_follows(p):
            p.next()
            float_(p)
    opt_comma(p)
    p.expect_op("}")
    return faces


def _texture_index_follows(p) -> bool:
    t = p.raw_peek(0) if p.la is not None else None
    return t is not None and t.kind == "num"


SHAPES = {"sphere": _sphere, "plane": _plane, "box": _box, "cylinder": _cylinder, "cone": _cone,
          "torus": _torus, "disc": _disc, "quadric": _quadric, "polygon": _polygon,
          "triangle": _triangle, "smooth_triangle": _smooth_triangle, "mesh": _mesh, "mesh2": _mesh2}


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
    elif kw in ("spotlight", "cylinder"):
        rec.kind = kw
        if kw == "cylinder":
            p.warn("cylinder light", "cylinder lights are treated as spotlights", t.loc)
    elif kw == "parallel":
        rec.parallel = True
    elif kw == "shadowless":
        rec.shadowless = True
    elif kw in ("radius", "falloff", "tightness", "fade_distance", "fade_power"):
        setattr(rec, kw, float_(p))
    elif kw == "point_at":
        rec.point_at = np.asarray(vector3(p), dtype=np.float64)
    elif kw in ("color", "colour") or kw in COLOR_KEYWORDS:
        p.la = t  # let the colour parser see the keyword
        rec.color = parse_color(p)
    elif kw == "area_light":
        a1 = vector3(p)
        opt_comma(p)
        a2 = vector3(p)
        opt_comma(p)
        n1 = int(float_(p))
        opt_comma(p)
        rec.area = (a1, a2, max(1, n1), max(1, int(float_(p))))
    elif kw in ("adaptive", "jitter", "area_illumination"):
        if _starts_value(p):
            float_(p)
    elif kw in ("circular", "orient"):
        setattr(rec, kw, True)
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
    return cam


def _camera_item(p, cam, k):
    kw = k.value
    if kw in CAMERA_VECTORS:
        cam.values[kw] = vector3(p)
    elif kw == "angle":
        cam.values["angle"] = float_(p)
        opt_comma(p)
        if _starts_value(p):
            float_(p)
    elif kw in ("perspective", "orthographic"):
        cam.projection = kw
    elif kw in ("fisheye", "ultra_wide_angle", "omnimax", "panoramic", "spherical", "cylinder",
                "mesh_camera", "user_defined"):
        p.warn(kw, f"{kw} camera is rendered as perspective", k.loc)
        if kw == "cylinder":
            float_(p)
        elif kw in ("mesh_camera", "user_defined"):
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
        parse_normal(p, k)
    else:
        raise p.error(f"expected a camera item, found '{kw}'", k.loc)


# ---- scene-level statements ------------------------------------------------------------------
def parse_global_settings(p, t) -> None:
    p.expect_op("{", "'{' after global_settings")
    while not p.accept_op("}"):
        k = p.next()
        if k.kind != ID:
            raise p.error(f"expected a global setting, found {k.describe()}", k.loc)
        kw = k.value
        if kw == "assumed_gamma":
            p.assumed_gamma = float_(p)
        elif kw == "max_trace_level":
            p.settings["max_trace_level"] = int(float_(p))
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
            elif _starts_value(p):
                float_(p)
        elif kw in ("radiosity", "photons", "subsurface"):
            p.warn(kw, f"{kw} is not supported; ignored", k.loc)
            skip_braces(p)
        else:
            raise p.error(f"expected a global setting, found '{kw}'", k.loc)


def parse_background(p, t) -> None:
    p.expect_op("{", "'{' after background")
    c = parse_color(p)
    p.expect_op("}", "'}' to close background")
    # POV 3.7 pre-multiplies the background by (1 - transmit) at parse time (reference §2.2)
    p.background = tuple(v * (1.0 - c.c[4]) for v in c.c[:3])


def parse_default(p, tok) -> None:
    p.expect_op("{", "'{' after #default")
    while not p.accept_op("}"):
        k = p.next()
        d = p.default_layer
        if k.kind == ID and k.value == "texture":
            tex = parse_texture(p, d)
            p.default_layer = tex.layers[-1]
        elif k.kind == ID and k.value == "pigment":
            p.default_layer = LayerRec(parse_pigment(p, d.pigment), d.finish)
        elif k.kind == ID and k.value == "finish":
            p.default_layer = LayerRec(d.pigment, parse_finish(p, d.finish))
        elif k.kind == ID and k.value == "normal":
            parse_normal(p, k)
        elif k.kind == ID and k.value in ("camera", "light_source", "interior", "media"):
            p.warn("#default", f"#default {k.value} is not supported; ignored", k.loc)
            skip_braces(p)
        else:
            raise p.error(f"expected texture, pigment, finish or normal in #default, found "
                          f"{k.describe()}", k.loc)


def as_float_any(p, v, loc):
    return as_float(p, v, loc)
