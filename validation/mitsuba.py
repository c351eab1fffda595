"""A ``raytracer.Scene`` as a Mitsuba 3 scene, rendered through pixel centres or to a box-filtered film.

Mapping (semantics §6; every entry is exact up to float precision unless marked Monte Carlo):

==========================================  =====================================================
POV-Ray                                     Mitsuba 3
==========================================  =====================================================
perspective camera (frame from POV's        ``perspective``, ``fov_axis='x'``, fov ``2·atan(|R|/2/|D|)``,
``direction/right/up/look_at/angle``)       ``look_at(location, location + D, U)`` mirrored in x
                                            (POV is left-handed), ``far_clip 1e7``, box ``rfilter``
``parallel`` light                          ``directional``, irradiance ``π·C`` (Lambert: ρ/π·E = d·P·C)
diffuse (brilliance 1)                      ``twosided(diffuse)``, reflectance ``diffuse·P·(1−f−t)``
ambient·ambient_light (+ emission)          ``area`` emitter, radiance ``(ambient·Ia + emission)·P·(1−f−t)``
``reflection C`` (constant), diffuse 0      ``twosided(conductor material='none')``, reflectance C
``reflection C`` + diffuse                  ``blendbsdf`` ½·diffuse(2ρ) + ½·conductor(2C)  (Monte Carlo)
glass (``filter/transmit 1``, ``ior n``,    ``dielectric int_ior=n ext_ior=1``  (Monte Carlo in R vs T)
``reflection{0,1 fresnel}``, conserve)
checker pigment on a plane                  ``checkerboard`` texture with a ``to_uv`` matching POV's cells
background colour                           ``constant`` environment, seen only by escaping rays
sphere / box / cylinder (+caps) / disc /    ``sphere`` / ``cube`` / ``cylinder`` + 2 ``disk`` / ``disk`` /
plane / triangle, smooth triangle, mesh     ``rectangle`` (≥1e4 wide) / in-memory ``mi.Mesh``
union                                       its children, flattened
``max_trace_level L``                       ``max_depth L``
==========================================  =====================================================

Anything else raises :class:`NotMatchable` naming the feature: never an approximation passed off as
equal. Not matchable, among others: point lights (Mitsuba's have 1/r²), spot/area lights, shadowless
lights, fade, phong, specular, metallic, brilliance ≠ 1, reflection falloff/fresnel on opaque
surfaces, filter/transmit other than clear glass, interior fade, non-black ``ambient`` on open
surfaces, CSG other than union, clipped_by, cones, quadrics, tori, polygons, discs with a hole,
ellipsoids (a non-uniformly scaled sphere would need tessellation), patterns other than checker on
planes, layered and patterned textures, object flags, ``adc_bailout > 0`` with reflection or refraction.

**Integrator.** Mitsuba has no Whitted integrator, and its ``path`` integrator adds diffuse
inter-reflection that POV-Ray (without radiosity) does not compute. The scene therefore uses
``pov_whitted``, a small integrator registered here and built only from Mitsuba's own ray
intersection, BSDFs and emitters: at each hit it adds the surface's emitter (POV's ambient),
next-event estimation from every ``directional`` emitter (POV's parallel lights) with shadow rays
that pass through clear dielectrics (POV's shadow rays ignore refraction and glass with
``filter/transmit 1`` casts no shadow, semantics §2.5), and it continues only along *delta* BSDF
lobes (mirror reflection and refraction), for at most ``max_depth`` segments; escaping rays see the
environment (POV's background). On scenes without specular surfaces and emitters it equals
Mitsuba's ``direct`` integrator, and with emissive surfaces seen via mirrors it equals ``path``
(tests check both). Area emitters are never sampled as lights: POV's ambient illuminates nothing.
"""

from __future__ import annotations

import glob
import math
import os
import re
import sys

import numpy as np

from raytracer.shapes import NoEquivalent
from raytracer.shapes._base import affine, frame, unit

__all__ = ["NotMatchable", "MitsubaDict", "load", "mitsuba", "render_mitsuba_centres", "render_mitsuba_film",
           "to_mitsuba", "variant"]

PLANE_HALF_SIZE = 1.0e4  # rectangle standing in for an infinite plane (times the camera height if larger)
FAR_CLIP = 1.0e7  # POV-Ray ignores hits farther than 1e7 (semantics §2.9)
_LLVM_GLOBS = ("/usr/lib/x86_64-linux-gnu/libLLVM*.so*", "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
               "/usr/lib/llvm-*/lib/libLLVM*.so*", "/usr/lib64/libLLVM*.so*", "/usr/lib/libLLVM*.so*",
               "/usr/local/lib/libLLVM*.so*")

_mi = None


class NotMatchable(Exception):
    """The scene uses a POV-Ray feature that has no exact Mitsuba equivalent.

    Attributes:
        feature: short name of the feature (e.g. ``"phong"``, ``"point light"``).
    """

    def __init__(self, feature: str, detail: str = ""):
        self.feature = feature
        super().__init__(f"not matchable in Mitsuba: {feature}" + (f" ({detail})" if detail else ""))


class MitsubaDict(dict):
    """The ``mi.load_dict`` dictionary, plus ``stochastic``: True when the match is only in expectation
    (glass, reflection + diffuse), i.e. pixel-centre renders need many samples per pixel."""

    stochastic: bool = False


def _find_libllvm() -> str | None:
    best, best_version = None, -1
    for pattern in _LLVM_GLOBS:
        for path in glob.glob(pattern):
            m = re.search(r"LLVM[-.]?(?:so\.)?(\d+)", os.path.basename(path))
            version = int(m.group(1)) if m else 0
            if version > best_version and os.path.isfile(path):
                best, best_version = path, version
    return best


def mitsuba(variant_name: str | None = None):
    """Imports Mitsuba once, selecting ``llvm_ad_rgb`` (vectorised, differentiable) when libLLVM is found,
    else ``scalar_rgb`` with a message on stderr. ``$RAYTRACER_MITSUBA_VARIANT`` overrides the choice."""
    global _mi
    if _mi is not None:
        return _mi
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        lib = _find_libllvm()
        if lib is not None:
            os.environ.setdefault("DRJIT_LIBLLVM_PATH", lib)
    import mitsuba as mi

    wanted = variant_name or os.environ.get("RAYTRACER_MITSUBA_VARIANT") or "llvm_ad_rgb"
    try:
        mi.set_variant(wanted)
    except Exception as e:  # noqa: BLE001 - drjit raises plain exceptions when LLVM is missing
        print(f"validation.mitsuba: variant {wanted!r} unavailable ({e}); falling back to 'scalar_rgb' "
              "(slow: one ray at a time). Install libLLVM (Debian: libllvm19) or set DRJIT_LIBLLVM_PATH.",
              file=sys.stderr)
        mi.set_variant("scalar_rgb")
    _register_integrator(mi)
    _mi = mi
    return mi


def variant() -> str:
    """The Mitsuba variant in use (imports Mitsuba)."""
    return mitsuba().variant()


# --------------------------------------------------------------------------------------------------
# the Whitted integrator


def _register_integrator(mi):
    import drjit as dr

    class PovWhittedIntegrator(mi.SamplingIntegrator):
        """POV-Ray's recursion with Mitsuba's intersection, BSDFs and emitters (see the module doc)."""

        def __init__(self, props):
            super().__init__(props)
            self.max_depth = int(props.get("max_depth", 5))
            self.shadow_crossings = int(props.get("shadow_crossings", 8))

        def _lights(self, scene):
            return [e for e in scene.emitters() if "Directional" in type(e).__name__
                    or "directional" in str(e).split("[")[0].lower()]

        def _visibility(self, scene, si, direction, active):
            # shadow ray that passes through clear dielectrics (POV: glass with filter/transmit 1 is
            # shadow-transparent), blocked by anything else
            ray = si.spawn_ray(direction)
            visible = mi.Bool(active)
            going = mi.Bool(active)
            for _ in range(self.shadow_crossings):
                ssi = scene.ray_intersect(ray, going)
                hit = going & ssi.is_valid()
                flags = ssi.bsdf().flags()
                clear = mi.has_flag(flags, mi.BSDFFlags.DeltaTransmission)
                visible &= ~(hit & ~clear)
                going = hit & clear
                ray = ssi.spawn_ray(ray.d)
            visible &= ~going  # still crossing glass after the budget: count it as blocked
            return visible

        def sample(self, scene, sampler, ray, medium=None, active=True):
            ray = mi.Ray3f(ray)
            active = mi.Bool(active)
            result = mi.Spectrum(0.0)
            throughput = mi.Spectrum(1.0)
            env = scene.environment()
            lights = self._lights(scene)
            ctx = mi.BSDFContext()
            for depth in range(self.max_depth):
                si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=(depth == 0),
                                         active=active)
                miss = active & ~si.is_valid()
                if env is not None:
                    result += dr.select(miss, throughput * env.eval(si, miss), 0.0)
                active &= si.is_valid()
                emitter = si.emitter(scene, active)
                result += dr.select(active, throughput * emitter.eval(si, active), 0.0)
                bsdf = si.bsdf(ray)
                for light in lights:
                    ds, irradiance = light.sample_direction(si, mi.Point2f(0.5, 0.5), active)
                    lit = active & (ds.pdf > 0)
                    visible = self._visibility(scene, si, ds.d, lit)
                    value = bsdf.eval(ctx, si, si.to_local(ds.d), visible)
                    result += dr.select(visible, throughput * value * irradiance, 0.0)
                if depth + 1 == self.max_depth:
                    break
                bs, weight = bsdf.sample(ctx, si, sampler.next_1d(active), sampler.next_2d(active), active)
                active &= mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta) & (dr.max(weight) > 0)
                throughput *= weight
                ray = si.spawn_ray(si.to_world(bs.wo))
            return result, mi.Bool(True), []

        def aov_names(self):
            return []

        def to_string(self):
            return f"PovWhittedIntegrator[max_depth={self.max_depth}]"

    mi.register_integrator("pov_whitted", lambda props: PovWhittedIntegrator(props))


# --------------------------------------------------------------------------------------------------
# conversion helpers (plain numpy)


def _np(x) -> np.ndarray:
    return np.asarray(x, dtype=np.float64)


def _norm(v) -> float:
    return float(np.linalg.norm(v))


_unit, _frame, _affine = unit, frame, affine


def _matrix(transform) -> np.ndarray:
    return np.eye(4) if transform is None else _np(transform.matrix)


def _compose(outer, inner) -> np.ndarray:
    """world_from_object of an object with ``inner`` inside a parent with ``outer``."""
    return outer @ inner


def _rgb(v) -> dict:
    return {"type": "rgb", "value": [float(x) for x in np.broadcast_to(_np(v), (3,))]}


# --------------------------------------------------------------------------------------------------
# the converter


class _Converter:
    def __init__(self, scene, width: int, height: int):
        self.scene = scene
        self.width, self.height = int(width), int(height)
        self.out = MitsubaDict(type="scene")
        self.count = 0
        self.has_specular = False
        self.has_glass = False
        self.settings = scene.settings
        self.ambient_light = _np(scene.settings.ambient_light)
        self.camera_origin = None

    # camera ------------------------------------------------------------------------------------
    def camera(self):
        mi = mitsuba()
        cam = self.scene.camera
        if cam.projection != "perspective":
            raise NotMatchable(f"{cam.projection} camera")
        origin, d, r, u = (_np(v) for v in cam.frame())
        self.camera_origin = origin
        ld, lr, lu = _norm(d), _norm(r), _norm(u)
        if min(ld, lr, lu) <= 0:
            raise NotMatchable("degenerate camera")
        cosines = (np.dot(d, r) / (ld * lr), np.dot(d, u) / (ld * lu), np.dot(r, u) / (lr * lu))
        if max(abs(c) for c in cosines) > 1e-6:
            raise NotMatchable("skewed camera", "direction, right and up are not orthogonal")
        if abs((lu / lr) - self.height / self.width) > 1e-6 * (lu / lr):
            raise NotMatchable("non-square pixels", f"|up|/|right| = {lu / lr:.6g}, image H/W = "
                               f"{self.height / self.width:.6g}; write `right x*image_width/image_height`")
        fov = math.degrees(2.0 * math.atan(0.5 * lr / ld))
        to_world = mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=(origin + d).tolist(),
                                                  up=u.tolist())
        if np.dot(np.cross(u, d), r) > 0:  # POV's right = up × dir; Mitsuba's image right = dir × up
            to_world = to_world @ mi.ScalarTransform4f().scale([-1.0, 1.0, 1.0])
        self.out["sensor"] = {
            "type": "perspective", "fov": fov, "fov_axis": "x", "near_clip": 1e-3, "far_clip": FAR_CLIP,
            "to_world": to_world,
            "film": {"type": "hdrfilm", "width": self.width, "height": self.height, "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 1},
        }

    # lights ------------------------------------------------------------------------------------
    def lights(self):
        for k, light in enumerate(self.scene.lights):
            if not light.parallel:
                raise NotMatchable("point light", "Mitsuba's point light has 1/r² falloff, POV's has none")
            if light.spot is not None:
                raise NotMatchable("spotlight")
            if light.area is not None:
                raise NotMatchable("area light")
            if light.shadowless:
                raise NotMatchable("shadowless light")
            fading = light.fade_power is not None and light.fade_distance is not None
            if fading and float(light.fade_power) > 0:
                raise NotMatchable("light fade")
            direction = _np(light.point_at) - _np(light.position)
            if _norm(direction) == 0:
                raise NotMatchable("parallel light with point_at at its position")
            self.out[f"light_{k}"] = {"type": "directional", "direction": direction.tolist(),
                                      "irradiance": _rgb(math.pi * _np(light.color))}

    def background(self):
        bg = _np(self.scene.background)
        if np.any(bg != 0):
            self.out["background"] = {"type": "constant", "radiance": _rgb(bg)}

    # objects -----------------------------------------------------------------------------------
    def objects(self):
        for obj in self.scene.objects:
            self.object(obj, np.eye(4), None, None)

    def object(self, obj, parent_matrix, parent_texture, parent_interior):
        from raytracer.scene import CSG

        for flag in ("inverse", "no_shadow", "no_image", "no_reflection", "double_illuminate"):
            if flag != "inverse" and getattr(obj, flag):
                raise NotMatchable(f"object flag {flag}")
        if obj.clipped_by:
            raise NotMatchable("clipped_by")
        m = _compose(parent_matrix, _matrix(obj.transform))
        texture = obj.texture if obj.texture is not None else parent_texture
        interior = obj.interior if obj.interior is not None else parent_interior
        if isinstance(obj, CSG):
            if obj.operation != "union":
                raise NotMatchable(f"CSG {obj.operation}")
            for child in obj.children:
                self.object(child, m, texture, interior)
            return
        self.shape(obj.shape, m, texture, interior, obj.inverse)

    def _name(self, kind: str) -> str:
        self.count += 1
        return f"{kind}_{self.count}"

    def shape(self, shape, m, texture, interior, inverse):
        """The shape's own Mitsuba equivalent (``AbstractShape.to_mitsuba``) with its material;
        the two requests a shape may make (a triangle mesh, an infinite plane) are built here."""
        try:
            geo = shape.to_mitsuba(m, self.camera_origin)
        except NoEquivalent as e:
            raise NotMatchable(e.feature, e.detail) from None
        uv = None
        entries = []
        for entry in geo.entries:
            if entry["type"] == "_plane":
                rect, uv = self._plane(entry["point"], entry["normal"], texture)
                entries.append(rect)
            elif entry["type"] == "_mesh":
                entries.append({"_mesh": True, "name": self._name("mesh"), "vertices": entry["vertices"],
                                "normals": entry["normals"]})
            elif "to_world" in entry:
                entries.append({**entry, "to_world": mitsuba().ScalarTransform4f(entry["to_world"])})
            else:
                entries.append(entry)
        self._material(entries, texture, interior, closed=geo.closed, planar=geo.planar, uv=uv)

    def _plane(self, p_world, n_world, texture):
        """A rectangle standing in for the infinite plane through ``p_world`` with unit normal
        ``n_world``, centred under the camera, and the checker's uv when the pigment is one."""
        mi = mitsuba()
        height = float(np.dot(self.camera_origin - p_world, n_world))
        if height < 0:
            self._inside_plane = True
        facing = n_world if height >= 0 else -n_world
        half = PLANE_HALF_SIZE * max(1.0, abs(height))
        centre = self.camera_origin - height * n_world  # centred under the camera
        uv = None
        pigment = texture.layers[0].pigment if texture is not None else None
        if pigment is not None and pigment.pattern == "checker":
            axes, uv = self._checker_frame(pigment, n_world, centre, half)
        else:
            f = _frame(facing)
            axes = (f[:, 0], f[:, 1])
        e1, e2 = axes
        # e1/e2 carry the checker's uv; the third column (the normal Mitsuba uses, whatever the
        # determinant) faces the camera, because area emitters (POV's ambient) are one-sided
        linear = np.stack([e1 * half, e2 * half, facing], axis=1)
        return {"type": "rectangle", "to_world": mi.ScalarTransform4f(_affine(linear, centre))}, uv

    def _checker_frame(self, pigment, n_world, centre, half):
        """Rectangle axes and the ``to_uv`` that reproduce POV's checker on an axis-aligned plane.

        POV: colour 0 when ``floor(x)+floor(y)+floor(z)`` (pattern space) is even. Mitsuba's
        checkerboard gives ``color0`` when ``frac(u') > ½`` equals ``frac(v') > ½``; with
        ``u' = q_i/2`` that is ``floor(q_i)`` odd, so ``color0`` ⇔ ``floor(q_i)+floor(q_j)`` even.
        """
        mi = mitsuba()
        pm = _matrix(pigment.transform)  # world_from_pattern
        a = pm[:3, :3]
        scale = np.diag(a)
        if not np.allclose(a, np.diag(scale), atol=1e-12) or np.any(scale <= 0):
            raise NotMatchable("checker with a rotated or mirrored pattern transform")
        k = int(np.argmax(np.abs(n_world)))
        if abs(abs(n_world[k]) - 1.0) > 1e-9:
            raise NotMatchable("checker on a plane that is not axis-aligned")
        i, j = [ax for ax in range(3) if ax != k]
        b = pm[:3, 3]
        e1, e2 = np.eye(3)[i], np.eye(3)[j]
        q_k = (centre[k] - b[k]) / scale[k]
        parity = int(math.floor(q_k + 1e-10)) % 2
        # local x ∈ [-1, 1] ↦ world centre_i + half·x; Mitsuba u = (x + 1)/2
        rows = []
        for ax in (i, j):
            gain = half / scale[ax]  # dq/du / 2 … u' = q/2 = (centre + half(2u − 1) − b)/(2 s)
            rows.append((gain, (centre[ax] - half - b[ax]) / (2.0 * scale[ax])))
        to_uv = np.array([[rows[0][0], 0.0, rows[0][1]], [0.0, rows[1][0], rows[1][1]], [0.0, 0.0, 1.0]])
        return (e1, e2), {"to_uv": mi.ScalarTransform3f(to_uv), "swap": parity == 1}

    def _build_mesh(self, entry, bsdf, emitter):
        mi = mitsuba()
        world, normals = entry["vertices"], entry["normals"]
        n_faces = len(world)
        props = mi.Properties()
        props["bsdf"] = mi.load_dict(bsdf)
        if emitter is not None:
            props["emitter"] = mi.load_dict(emitter)
        mesh = mi.Mesh(entry["name"], 3 * n_faces, n_faces, props=props,
                       has_vertex_normals=normals is not None)
        params = mi.traverse(mesh)
        params["vertex_positions"] = world.astype(np.float32).ravel()
        params["faces"] = np.arange(3 * n_faces, dtype=np.uint32)
        if normals is not None:
            params["vertex_normals"] = normals.astype(np.float32).ravel()
        params.update()
        return mesh

    # materials ---------------------------------------------------------------------------------
    def _material(self, entries, texture, interior, *, closed, planar, uv):
        from raytracer.scene import Texture

        if texture is None:
            texture = Texture()  # POV default: black pigment, default finish
        if texture.patterned:
            raise NotMatchable("patterned texture")
        if len(texture.layers) != 1:
            raise NotMatchable("layered texture")
        pigment, finish = texture.layers[0].pigment, texture.layers[0].finish
        if pigment.pattern not in ("solid", "checker"):
            raise NotMatchable(f"{pigment.pattern} pattern")
        if pigment.pattern == "checker" and uv is None:
            raise NotMatchable("checker on a non-planar or non-plane surface")
        if pigment.turbulence is not None:
            raise NotMatchable("turbulence")
        colors = _np(pigment.colors)
        if pigment.pattern == "solid":
            colors = colors[:1]
        ft = colors[:, 3:]
        att = 1.0 - ft[:, 0] - ft[:, 1]
        for name in ("phong", "specular", "metallic"):
            v = getattr(finish, name)
            if v is not None and float(v) != 0.0:
                raise NotMatchable(name)
        if float(finish.brilliance) != 1.0:
            raise NotMatchable("brilliance ≠ 1")
        diffuse = float(finish.diffuse)
        local_glow = _np(finish.ambient) * self.ambient_light + _np(finish.emission)  # (3,)
        rho = diffuse * colors[:, :3] * att[:, None]  # (M, 3)
        glow = local_glow[None, :] * colors[:, :3] * att[:, None]
        refl = finish.reflection
        transparent = bool(np.any(ft != 0))
        bsdf = None
        stochastic = False
        if transparent:
            bsdf = self._glass(colors, finish, interior)
            stochastic = True
        elif refl is not None:
            if refl.fresnel:
                raise NotMatchable("fresnel reflection on an opaque surface")
            rmin, rmax = _np(refl.min), _np(refl.max)
            if not np.allclose(rmin, rmax):
                raise NotMatchable("reflection with min ≠ max (falloff)")
            if float(refl.exponent) != 1.0:
                raise NotMatchable("reflection exponent")
            if refl.metallic is not None and float(refl.metallic) != 0.0:
                raise NotMatchable("reflection metallic")
            if np.any(rmax > 0):
                self.has_specular = True
                mirror = {"type": "conductor", "material": "none", "specular_reflectance": _rgb(rmax)}
                if np.any(rho > 0):
                    if np.any(2 * rho > 1) or np.any(2 * rmax > 1):
                        raise NotMatchable("reflection + diffuse with 2·diffuse·P or 2·reflection > 1")
                    mirror["specular_reflectance"] = _rgb(2 * rmax)
                    bsdf = {"type": "blendbsdf", "weight": 0.5,
                            "bsdf_0": {"type": "diffuse", "reflectance": self._texture(2 * rho, uv)},
                            "bsdf_1": mirror}
                    stochastic = True
                else:
                    bsdf = mirror
        if interior is not None and interior.fade_power is not None and transparent:
            raise NotMatchable("interior fade")
        if bsdf is None:
            bsdf = {"type": "diffuse", "reflectance": self._texture(rho, uv)}
        if bsdf["type"] != "dielectric":
            bsdf = {"type": "twosided", "material": bsdf}
        emitter = None
        if np.any(glow > 0):
            one_sided = "Mitsuba's area emitters are one-sided"
            if not closed and not planar:
                raise NotMatchable("ambient/emission on an open surface", one_sided)
            if entries and entries[0].get("_mesh"):
                raise NotMatchable("ambient/emission on a triangle or mesh", one_sided)
            emitter = {"type": "area", "radiance": self._texture(glow, uv)}
        self.out.stochastic = self.out.stochastic or stochastic
        for entry in entries:
            if entry.get("_mesh"):
                self.out[entry["name"]] = self._build_mesh(entry, bsdf, emitter)
                continue
            entry = dict(entry)
            entry["bsdf"] = bsdf
            if emitter is not None:
                entry["emitter"] = emitter
            self.out[self._name(entry["type"])] = entry

    def _texture(self, values, uv):
        values = np.asarray(values)
        if uv is None:
            return _rgb(values[0])
        c0, c1 = values[0], values[1]
        if uv["swap"]:
            c0, c1 = c1, c0
        return {"type": "checkerboard", "color0": _rgb(c0), "color1": _rgb(c1), "to_uv": uv["to_uv"]}

    def _glass(self, colors, finish, interior):
        if len(colors) != 1:
            raise NotMatchable("patterned transparency")
        f, t = colors[0, 3], colors[0, 4]
        filcol = f * colors[0, :3] + t
        if not np.allclose(filcol, 1.0) or abs(f + t - 1.0) > 1e-9:
            raise NotMatchable("filter/transmit other than clear glass", f"filter·P + transmit = {filcol}")
        refl = finish.reflection
        if (refl is None or not refl.fresnel or not np.allclose(_np(refl.min), 0.0)
                or not np.allclose(_np(refl.max), 1.0) or float(refl.exponent) != 1.0
                or (refl.metallic is not None and float(refl.metallic) != 0.0)):
            raise NotMatchable("refraction without reflection{0, 1 fresnel on}")
        if not finish.conserve_energy:
            raise NotMatchable("glass without conserve_energy")
        if interior is None or interior.ior is None or float(interior.ior) == 1.0:
            raise NotMatchable("transparent surface with ior 1 (straight transmission)")
        self.has_specular = True
        self.has_glass = True
        return {"type": "dielectric", "int_ior": float(interior.ior), "ext_ior": 1.0}

    # all ---------------------------------------------------------------------------------------
    def convert(self) -> MitsubaDict:
        self._inside_plane = False
        self.camera()
        self.lights()
        self.background()
        self.objects()
        if self.has_specular and float(self.settings.adc_bailout) > 0:
            raise NotMatchable("adc_bailout > 0 with reflection or refraction", "use adc_bailout 0")
        if self.has_glass and self._inside_plane:
            raise NotMatchable("camera inside a plane's half-space with refraction",
                               "POV's ComputeRelativeIOR quirk gives F = 0 at exits (semantics §2.7)")
        self.out["integrator"] = {"type": "pov_whitted", "max_depth": int(self.settings.max_trace_level)}
        return self.out


def to_mitsuba(scene, width: int, height: int) -> MitsubaDict:
    """Converts a ``raytracer.Scene`` to an ``mi.load_dict`` dictionary (see the module doc).

    Raises:
        NotMatchable: the scene uses a feature without an exact Mitsuba equivalent.
    """
    mitsuba()
    return _Converter(scene, width, height).convert()


def load(scene_or_dict, width: int | None = None, height: int | None = None):
    """An ``mi.Scene`` from a ``raytracer.Scene`` (needs width/height), a dict, or an ``mi.Scene``."""
    mi = mitsuba()
    if isinstance(scene_or_dict, mi.Scene):
        return scene_or_dict
    if not isinstance(scene_or_dict, dict):
        if width is None or height is None:
            raise ValueError("width and height are needed to convert a raytracer scene")
        scene_or_dict = to_mitsuba(scene_or_dict, width, height)
    return mi.load_dict(dict(scene_or_dict))


def _film_size(mi_scene) -> tuple[int, int]:
    size = mi_scene.sensors()[0].film().size()
    return int(size[0]), int(size[1])


def render_mitsuba_centres(scene, width: int | None = None, height: int | None = None, spp: int = 1, *,
                           seed: int = 0, integrator=None, max_lanes: int = 1 << 23,
                           sampler_type: str = "stratified") -> np.ndarray:
    """Renders with every ray through a pixel centre, as POV-Ray ``-A`` and our ``spp=1`` do (semantics §6.1).

    Each pixel averages ``spp`` estimates along the same centre ray (only useful for Monte Carlo
    materials such as glass). ``integrator`` (an ``mi.Integrator`` or a dict) replaces the scene's.

    Returns:
        (H, W, 3) float32 linear RGB, row 0 at the top.
    """
    mi = mitsuba()
    import drjit as dr

    s = load(scene, width, height)
    w, h = _film_size(s)
    if integrator is None:
        integ = s.integrator()
    else:
        integ = integrator if isinstance(integrator, mi.Integrator) else mi.load_dict(integrator)
    sensor = s.sensors()[0]
    if mi.variant().startswith("scalar"):
        return _centres_scalar(mi, s, sensor, integ, w, h, spp, seed)
    n_pix = w * h
    total = np.zeros((n_pix, 3))
    per_batch = max(1, min(spp, max_lanes // n_pix))
    done, batch = 0, 0
    while done < spp:
        k = min(per_batch, spp - done)
        n = n_pix * k
        # low-discrepancy samples per pixel: the R-vs-T choice at glass is a step function, for which
        # stratification converges far faster than independent samples
        sampler = mi.load_dict({"type": sampler_type, "sample_count": k})
        sampler.seed(seed * 7919 + batch, n)
        idx = dr.arange(mi.UInt32, n)
        pix = idx // k
        x = mi.Float(pix % w) + 0.5
        y = mi.Float(pix // w) + 0.5
        ray, ray_weight = sensor.sample_ray(0.0, 0.5, mi.Point2f(x / w, y / h), mi.Point2f(0.5, 0.5))
        value, _, _ = integ.sample(s, sampler, ray)
        value = value * ray_weight
        arr = np.stack([np.array(value[c]) for c in range(3)], axis=-1).reshape(n_pix, k, 3)
        total += arr.sum(axis=1)
        done += k
        batch += 1
    return (total / spp).reshape(h, w, 3).astype(np.float32)


def _centres_scalar(mi, s, sensor, integ, w, h, spp, seed):
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed)
    out = np.zeros((h, w, 3))
    for j in range(h):
        for i in range(w):
            acc = np.zeros(3)
            for _ in range(spp):
                ray, weight = sensor.sample_ray(0.0, 0.5, mi.Point2f((i + 0.5) / w, (j + 0.5) / h),
                                                mi.Point2f(0.5, 0.5))
                value, _, _ = integ.sample(s, sampler, ray)
                acc += np.array(value * weight, dtype=np.float64).ravel()[:3]
                sampler.advance()
            out[j, i] = acc / spp
    return out.astype(np.float32)


def render_mitsuba_film(scene, width: int | None = None, height: int | None = None, spp: int = 256, *,
                        seed: int = 0) -> np.ndarray:
    """Renders to Mitsuba's film with the box filter (pixel-area average), ``spp`` samples per pixel.

    Compare with POV-Ray ``+A0.0 +AM1 +R8 -J`` or our k×k supersampled render.
    """
    mi = mitsuba()
    s = load(scene, width, height)
    image = mi.render(s, spp=int(spp), seed=int(seed))
    return np.asarray(image, dtype=np.float32)[..., :3]
