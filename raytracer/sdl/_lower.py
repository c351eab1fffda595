"""Lowering: builder-level records → the JAX scene model (``raytracer.scene``)."""

from __future__ import annotations

import pickle

import numpy as np

from .. import scene as S
from .._build import build
from .._dtype import OutOfPrecision
from ..errors import SceneError
from ..scene._lights import light_fields
from ..scene._precision import precision_warnings
from ..scene.environment import ENVIRONMENT
from ..shapes import SDL_KEYWORDS
from ._values import CameraRec, LayerRec, LightRec, NormRec, ObjRec, PigRec

_FINISH_KEYS = ("ambient", "emission", "diffuse", "brilliance", "phong", "phong_size", "specular",
                "roughness", "metallic", "conserve_energy")


def _transform(m) -> S.Transform | None:
    return None if m is None else build(S.Transform, matrix=m)


def lower_pigment(pig: PigRec, world: np.ndarray | None, fit_zero_terms: bool = True) -> S.Pigment:
    """``fit_zero_terms`` (``load_scene``'s): a filter or transmit written as 0 makes the pigment
    transparent (True) or only values that are not 0 do (False)."""
    written = pig.ft and fit_zero_terms
    if pig.pattern == "solid":  # (most objects of a large scene: one colour, read as Python numbers)
        value, color = pig.cmap[0]
        rgbft = color.padded(5)
        return build(S.Pigment, pattern="solid", values=(float(value) * 0.0,), colors=(rgbft,),
                     transparent=bool(written or rgbft[3] != 0 or rgbft[4] != 0))
    colors = np.array([c.padded(5) for _, c in pig.cmap], dtype=np.float64)
    values = np.array([v for v, _ in pig.cmap], dtype=np.float64)
    transparent = bool(written or np.any(colors[:, 3:] != 0))
    m = pig.transform
    if world is not None:
        m = world if m is None else world @ m
    wave = pig.wave or "ramp"
    if pig.image is not None:
        im = pig.image
        image = build(S.ImageMap, pixels=im["pixels"], map_type=im["map_type"], once=im["once"],
                      interpolate=im["interpolate"])
        return build(S.Pigment, pattern=pig.pattern, values=values, colors=colors, transform=_transform(m),
                     image=image, transparent=bool(im["once"] or np.any(im["pixels"][..., 3:] != 0)))
    if pig.entries is not None:  # a pigment map: its pigments live in the map's space
        entries = tuple(lower_pigment(e, m, fit_zero_terms) for _, e in pig.entries)
        return build(S.Pigment, pattern=pig.pattern, values=values, colors=np.zeros((len(entries), 5)),
                     transform=_transform(m), vector=np.asarray(pig.vector, dtype=np.float64),
                     frequency=pig.frequency, phase=pig.phase, turbulence=pig.turbulence, omega=pig.omega,
                     lambda_=pig.lambda_, octaves=pig.octaves, wave=wave, entries=entries,
                     transparent=any(e.transparent for e in entries))
    return build(S.Pigment, pattern=pig.pattern, values=values, colors=colors, transform=_transform(m),
                 vector=np.asarray(pig.vector, dtype=np.float64), frequency=pig.frequency,
                 phase=pig.phase, turbulence=pig.turbulence, omega=pig.omega,
                 lambda_=pig.lambda_, octaves=pig.octaves, wave=wave, transparent=transparent)


def lower_normal(nrm: NormRec | None, world: np.ndarray | None) -> S.Normal | None:
    """A layer's normal; None where it has none or its pattern perturbs nothing we render."""
    if nrm is None or nrm.pigment.pattern == "solid":
        return None
    slope = None if nrm.slope_map is None else np.array(sorted(nrm.slope_map, key=lambda r: r[0]), np.float64)
    return build(S.Normal, pattern=lower_pigment(nrm.pigment, world), amount=nrm.amount,
                 accuracy=nrm.accuracy, slope_map=slope)


# optional finish terms that add nothing at 0: the highlights and their metallic tint
_ZERO_IS_ABSENT = ("phong", "specular", "metallic")


def _zero(value) -> bool:
    return value is not None and not np.any(np.asarray(value, dtype=np.float64))


def lower_finish(fin: dict, fit_zero_terms: bool = True) -> S.Finish:
    """``fit_zero_terms`` (``load_scene``'s): a ``phong``, ``specular``, ``metallic`` or
    ``reflection`` written as 0 is compiled (True) or left out (False: it adds nothing, semantics
    §2.4 and §2.6; a reflection whose minimum and maximum are both 0 reflects nothing, with or
    without ``fresnel``, and its ``metallic`` of 0 tints nothing)."""
    kwargs = {k: fin[k] for k in _FINISH_KEYS if k in fin
              and (fit_zero_terms or k not in _ZERO_IS_ABSENT or not _zero(fin[k]))}
    r = fin.get("reflection")
    if r is not None and (fit_zero_terms or not (_zero(r["min"]) and _zero(r["max"]))):
        metallic = r["metallic"] if fit_zero_terms or not _zero(r["metallic"]) else None
        kwargs["reflection"] = build(S.Reflection, min=r["min"], max=r["max"], falloff=r["falloff"],
                                     exponent=r["exponent"], metallic=metallic,
                                     fresnel=bool(r["fresnel"]))
    return build(S.Finish, **kwargs)


def _exact_key(v):
    """A hashable key equal for equal values, bit for bit (numpy's repr rounds)."""
    if isinstance(v, dict):
        return tuple(sorted((k, _exact_key(x)) for k, x in v.items()))
    if isinstance(v, (list, tuple)):
        return (type(v).__name__, *map(_exact_key, v))
    if isinstance(v, np.ndarray):
        return (v.dtype.str, v.shape, v.tobytes())
    if isinstance(v, float):
        return ("float", v.hex())
    return (type(v).__name__, v if isinstance(v, (int, bool, str, type(None))) else repr(v))


def _pattern_fields(pig: S.Pigment) -> dict:
    """What a patterned texture's pattern keeps of its lowered pigment (its space and value)."""
    return {k: getattr(pig, k) for k in ("transform", "vector", "frequency", "phase", "turbulence", "omega",
                                         "lambda_", "octaves", "wave")}


class Lowerer:
    """Converts records, caching textures so objects sharing one get one pytree."""

    def __init__(self, fit_zero_terms: bool = True):
        self.fit_zero_terms = fit_zero_terms
        self._tex_cache = {}
        self._finish_cache: dict[str, S.Finish] = {}
        self.lights: list[S.Light] = []

    def texture(self, layers: list[LayerRec], world) -> S.Texture:
        key = (tuple(id(layer) for layer in layers), None if world is None else world.tobytes())
        tex = self._tex_cache.get(key)
        if tex is None:
            if len(layers) == 1 and layers[0].patterned is not None:
                pattern, entries = layers[0].patterned
                mapped = [(v, self.texture(t.layers, world)) for v, t in entries]
                fields = _pattern_fields(lower_pigment(pattern, world))
                tex = S.Texture.of_map(pattern.pattern, mapped, **fields)
            else:
                # (a patterned texture is never a layer among others: ``_textures.layered``)
                # the renderer wants the top layer first; records keep them bottom first
                tex = build(S.Texture, layers=tuple(
                    build(S.Layer, pigment=lower_pigment(layer.pigment, world, self.fit_zero_terms),
                          finish=self.finish(layer.finish), normal=lower_normal(layer.normal, world))
                    for layer in reversed(layers)))
            self._tex_cache[key] = (tex, layers)  # keep layers alive so ids stay unique
            return tex
        return tex[0]

    def finish(self, fin: dict) -> S.Finish:
        """``lower_finish``, one module per distinct finish (a declared finish is shared by every
        object that names it; the values are numbers, flags and colour tuples)."""
        try:
            # pickle's bytes tell every value apart bit for bit, as ``_exact_key`` does, ~15x
            # faster (each object's finish is a dict of its own, even where it names a declared one)
            key = pickle.dumps(fin, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # a value pickle cannot take
            key = _exact_key(fin)
        got = self._finish_cache.get(key)
        if got is None:
            got = self._finish_cache[key] = lower_finish(fin, self.fit_zero_terms)
        return got

    def interior(self, rec, layers) -> S.Interior | None:
        vals = dict(rec.values) if rec is not None else {}
        if layers:  # legacy finish { ior refraction fade_* }
            fin = layers[-1].finish
            for k in ("ior", "fade_distance", "fade_power"):
                if "legacy_" + k in fin and k not in vals:
                    vals[k] = fin["legacy_" + k]
        if not vals and rec is None:
            return None
        return S.Interior(**vals)

    def obj(self, rec, parent_world: np.ndarray | None, top_level: bool):
        """One ObjRec → Object/CSG (None when nothing renderable is left); lights are collected.
        A value the working precision cannot hold is an error at the object."""
        try:
            return self._obj(rec, parent_world, top_level)
        except OutOfPrecision as e:
            raise SceneError(str(e), rec.loc) from None

    def _obj(self, rec, parent_world: np.ndarray | None, top_level: bool):
        if isinstance(rec, LightRec):
            self.lights.append(lower_light(rec, parent_world))
            return None
        if not rec.supported:
            return None
        world = rec.transform if parent_world is None else (
            parent_world if rec.transform is None else parent_world @ rec.transform)
        layers = rec.layers
        if layers is None and top_level:
            layers = [rec.default_layer or LayerRec()]
        texture = None if layers is None else self.texture(layers, parent_world)
        common = dict(
            transform=_transform(rec.transform), texture=texture,
            interior=self.interior(rec.interior, layers),
            clipped_by=tuple(c for c in (self.obj(k, world, False) for k in rec.clipped_by)
                             if c is not None),
            # the plan uses them where the object has no box of its own (``_plan.has_box``)
            bounded_by=tuple(b for b in (self.obj(k, world, False) for k in rec.bounded_by)
                             if b is not None),
            inverse=bool(rec.flags.get("inverse", False)),
            no_shadow=bool(rec.flags.get("no_shadow", False)),
            no_image=bool(rec.flags.get("no_image", False)),
            no_reflection=bool(rec.flags.get("no_reflection", False)),
            double_illuminate=bool(rec.flags.get("double_illuminate", False)))
        if rec.kind in ("union", "intersection", "difference", "merge"):
            kids = [self.obj(k, world, False) for k in rec.children]
            if rec.kind == "difference" and rec.children and kids[0] is None:
                return None
            kids = [k for k in kids if k is not None]
            if not kids:
                return None
            return build(S.CSG, operation=rec.kind, children=tuple(kids), **common)
        shape = lower_shape(rec)
        # (not with clipping or bounding objects: they move with the object's transform)
        folded = (None if rec.transform is None or rec.clipped_by or rec.bounded_by
                  else shape.absorb_transform(rec.transform))
        if folded is not None:
            shape, common["transform"] = folded, None
        return build(S.Object, shape=shape, **common)


def lower_shape(rec: ObjRec) -> S.AbstractShape:
    return SDL_KEYWORDS[rec.kind].from_sdl(rec.shape)


def _apply_point(m, v):
    return m[:3, :3] @ np.asarray(v, dtype=np.float64) + m[:3, 3]


def lower_light(rec: LightRec, parent_world) -> S.Light:
    m = rec.transform
    if parent_world is not None:
        m = parent_world if m is None else parent_world @ m
    pos, at = np.asarray(rec.position, dtype=np.float64), np.asarray(rec.point_at, dtype=np.float64)
    if m is not None:
        pos, at = _apply_point(m, pos), _apply_point(m, at)
    fields = light_fields(rec.kind, rec.values, None if m is None else m[:3, :3])
    return S.Light(position=pos, color=rec.color.c[:3], point_at=at, **fields)


def lower_camera(cam: CameraRec | None, warn) -> S.Camera:
    if cam is None:
        return S.Camera()
    v = cam.values
    kwargs = {k: v[k] for k in ("location", "direction", "up", "right", "sky", "look_at") if k in v}
    if "look_at" in kwargs:
        eye = np.asarray(kwargs.get("location", (0, 0, 0)), np.float64)
        if not np.any(np.asarray(kwargs["look_at"], np.float64) - eye):
            # POV-Ray: "Camera location and look_at point must be different"
            raise SceneError("expected a camera look_at point different from its location", cam.loc)
        _fix_degenerate_sky(kwargs, warn)
    try:
        return S.Camera(**kwargs, angle_degrees=v.get("angle"), transform=_transform(cam.transform),
                        projection=cam.projection, up_or_right_given="up" in v or "right" in v,
                        angle_vertical=v.get("angle_vertical") if cam.projection == "spherical" else None)
    except ValueError as e:
        # the model's checks see the values in the working precision: location <0, 0, -1e-320>
        # and look_at 0 differ in float64 but not in float32 (found by benchmarks/fuzz.py)
        import jax

        hint = "" if jax.config.jax_enable_x64 else " (in float32; float64, --x64, may tell them apart)"
        raise SceneError(f"{e}{hint}", cam.loc) from None


def _fix_degenerate_sky(kw: dict, warn) -> None:
    """look_at along sky: POV-Ray warns and keeps the old right vector; we pick the sky that gives
    that right vector (``D̂ × right``), which the Camera's fixed-order frame then reproduces."""
    view = np.asarray(kw["look_at"], np.float64) - np.asarray(kw.get("location", (0, 0, 0)), np.float64)
    sky = np.asarray(kw.get("sky", (0, 1, 0)), np.float64)
    if not np.any(view):
        return  # the Camera reports this one
    view = view / np.max(np.abs(view))  # a tiny view (1e-320) would underflow in the norms below
    if np.linalg.norm(np.cross(sky, view)) > 1e-12 * np.linalg.norm(sky) * np.linalg.norm(view):
        return
    right = np.asarray(kw.get("right", (1.33, 0, 0)), np.float64)
    new_sky = np.cross(view / np.linalg.norm(view), right)
    if np.any(new_sky):
        warn("camera sky", "camera look_at is parallel to sky; the right vector is kept, as POV-Ray does")
        kw["sky"] = tuple(new_sky)


def output_transfer(p) -> tuple[str, float]:
    """semantics §3.1: the transfer from working values to linear output."""
    if p.assumed_gamma is not None and p.assumed_gamma != 1.0:
        return "gamma", float(p.assumed_gamma)
    # POV-Ray 3.7 also turns gamma handling off for a scene with no #version at all ("assumed_gamma
    # not specified, so gamma_correction is turned off for compatibility with this pre POV-Ray 3.7
    # scene"): the seed scene renders sRGB⁻¹(value) to EXR (checked with povray 3.7.0.10)
    if p.assumed_gamma is None and (p.version < 3.7 or not p.version_seen):
        return "srgb_decode", 1.0
    return "linear", 1.0


class _Lowering:
    """The lowering as ``scene.EnvironmentLowering``."""

    def __init__(self, fit_zero_terms: bool):
        self._fit = fit_zero_terms

    def pigment(self, pigment, transform):
        return lower_pigment(pigment, transform, self._fit)


def lower_environment(p, fit_zero_terms: bool) -> tuple:
    """The scene's environment values (``Scene.environment``) of the statements that took effect, in
    the order of ``ENVIRONMENT`` and, within an effect, as written."""
    low = _Lowering(fit_zero_terms)
    values = []
    for entry in ENVIRONMENT:
        for rec in p.environment:
            if rec.entry is entry:
                try:
                    v = entry.sdl_lower(rec.state, low)
                except OutOfPrecision as e:
                    raise SceneError(str(e), rec.loc) from None
                if v is not None:
                    values.append(v)
    return tuple(values)


def lower_scene(p, fit_zero_terms: bool = True) -> S.Scene:
    low = Lowerer(fit_zero_terms)
    objects = []
    for rec in p.items:
        o = low.obj(rec, None, True)
        if o is not None:
            objects.append(o)
    transfer, gamma = output_transfer(p)
    st = dict(p.settings)
    if "max_trace_level" in st:
        st["max_trace_level"] = max(1, min(256, st["max_trace_level"]))
    try:
        settings = S.Settings(**st, output_transfer=transfer, assumed_gamma=gamma)
    except OutOfPrecision as e:  # found by benchmarks/fuzz.py: adc_bailout 1e308
        raise SceneError(str(e), p.statement_locs.get("global_settings")) from None
    try:
        camera = lower_camera(p.camera, lambda f, m: p.warn(f, m, p.camera.loc))
    except OutOfPrecision as e:
        raise SceneError(str(e), p.camera.loc) from None
    environment = lower_environment(p, fit_zero_terms)
    p.warnings.extend(precision_warnings(camera, objects))
    try:
        return build(S.Scene, camera=camera, objects=tuple(objects), lights=tuple(low.lights),
                     background=p.background, environment=environment, settings=settings,
                     warnings=tuple(p.warnings))
    except OutOfPrecision as e:  # the background is the only value not converted before
        raise SceneError(str(e), p.statement_locs.get("background")) from None
