"""Our boundary term (``render(…, edges=True)``) against Mitsuba 3's projective sampling.

``python -m validation --against edges`` renders the derivative image of an object's motion — a
translation, a growth — both ways and compares them where the outline passes:

* ours: ``jax.jvp`` of ``render(…, spp=16, edges=True)`` (float64), the box-filtered pixel's
  derivative with the boundary term computed on the 4×4 sub-pixel lattice;
* Mitsuba's: ``render_forward`` of ``direct_projective`` (``llvm_ad_rgb``) on the scene that
  ``validation.mitsuba`` converts (the same camera, pixel grid and box filter; POV's ``ambient 1``
  surface is an area emitter over black), the shape's ``to_world`` moved by a traced parameter, the
  mean over ``seeds`` independent renders. Its estimate is unbiased and noisy; its standard error
  is reported with it, and a few of its samples are NaN (dropped, counted).

Scenes (flat radiance over black: the image's derivative is the boundary term alone):

* ``sphere``: a sphere moved along x, y and z, and its radius grown.
* ``box``: a box turned so that three faces show, moved along x — the case of mitsuba3 issue 1895,
  where ``prb_projective``'s primary term was reported about 2.7× too large. Mitsuba's ``cube``
  gives each face its own four vertices, so that each edge of the box is also an open boundary of
  two faces, and its term is twice the truth in both integrators (printed, not held); the box is
  compared as a PLY mesh whose faces share its corners. Ours is also checked in
  ``tests/test_edges.py`` against a box's outline integrated in closed form.

* ``penumbra``: a diffuse sphere over a diffuse plane, lit by a square light overhead, the sphere
  moved along x and z; compared on the plane's pixels (the sphere's own, and a pixel around them,
  are left out: its shading under the two lights' models differs). POV-Ray's area light is a grid
  of point lights without falloff, each weighed by the trapezoid rule over the square (¼ ½ … ½ ¼
  along each axis; ours at :data:`PENUMBRA_GRID`² samples, jitter off), Mitsuba's a ``rectangle``
  emitter of radiance ``π C r² / (A cos θₑ)`` at the penumbra's centre, where the two lights' plane
  irradiance agrees (``r``, ``θₑ``: the distance and the emitter's angle there, ``A`` its area).
  Away from that point they differ by the change of ``r²/cos θₑ`` over the light and the plane,
  under 2 % here, and the grid's steps: ``PENUMBRA_GRID``² outlines where the rectangle's
  penumbra is smooth.

A comparison passes when the relative L2 difference over the pixels the outline crosses is within
:data:`MAX_REL_L2` (the penumbra: :data:`MAX_REL_L2_PENUMBRA`) beyond Mitsuba's own relative
standard error, and the image sums agree within two of its standard errors (or 1 % of the sum's
scale; the penumbra: within that tolerance of the sum of the derivative's magnitudes, since a
sideways motion's sum is the small difference of its leading and trailing sides).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import mitsuba as vm

WIDTH, HEIGHT, SPP = 48, 36, 64
SEEDS = 64
MAX_REL_L2 = 0.03
MAX_REL_L2_PENUMBRA = 0.10
PENUMBRA_GRID = 16
HEAD = "#version 3.7; global_settings { assumed_gamma 1.0 }\n"
CAMERA = "camera { location <0, 0.5, -5> look_at <0, 0, 0> angle 40 right x*4/3 }\n"
FLAT = "finish { ambient 1 diffuse 0 }"

def _x_shift() -> np.ndarray:
    """The tangent of a world-from-object matrix (column vectors) moving the object along x."""
    out = np.zeros((4, 4))
    out[0, 3] = 1.0
    return out


# name: (objects, [(label, our parameter, its tangent, Mitsuba's transform of θ: (mi, θ, base) → to_world)])
SCENES = {
    "sphere": (f"sphere {{ <0.2, 0.1, 0.3>, 0.9 pigment {{ rgb <1, 0.5, 0.25> }} {FLAT} }}", [
        ("centre x", "objects[0].shape.center", (1.0, 0.0, 0.0),
         lambda mi, t, base: mi.Transform4f().translate(mi.Vector3f(t, 0.0, 0.0)) @ base),
        ("centre y", "objects[0].shape.center", (0.0, 1.0, 0.0),
         lambda mi, t, base: mi.Transform4f().translate(mi.Vector3f(0.0, t, 0.0)) @ base),
        ("centre z", "objects[0].shape.center", (0.0, 0.0, 1.0),
         lambda mi, t, base: mi.Transform4f().translate(mi.Vector3f(0.0, 0.0, t)) @ base),
        ("radius", "objects[0].shape.radius", 1.0,  # about the centre: to_world's scale grows by θ/r
         lambda mi, t, base: base @ mi.Transform4f().scale(1.0 + t / 0.9)),
    ]),
    "box": (f"box {{ <-0.6, -0.5, -0.7>, <0.7, 0.6, 0.5> pigment {{ rgb <0.3, 0.6, 1> }} {FLAT} "
            "rotate <-20, 35, 0> }", [
        ("translate x", "objects[0].transform.matrix", _x_shift(),
         lambda mi, t, base: mi.Transform4f().translate(mi.Vector3f(t, 0.0, 0.0)) @ base),
    ]),
}


@dataclasses.dataclass(frozen=True)
class EdgeResult:
    scene: str
    tangent: str
    integrator: str  # Mitsuba's, and its shape where it is not the converter's
    rel_l2: float  # over the outline's pixels, ours against Mitsuba's mean
    noise: float  # Mitsuba's relative standard error there
    ours_sum: float
    mitsuba_sum: float
    mitsuba_sum_error: float  # its standard error
    nans: int  # Mitsuba's NaN samples (dropped)
    mitsuba_to_ours: float  # the least-squares ratio of Mitsuba's image to ours
    tolerance: float = MAX_REL_L2  # of the relative L2 difference beyond Mitsuba's noise
    abs_sum: float = 0.0  # the sum of the magnitudes of Mitsuba's mean image over the pixels compared

    @property
    def passed(self) -> bool:
        slack = 2 * self.mitsuba_sum_error
        if self.tolerance > MAX_REL_L2:  # (the penumbra: two lights' models, within the tolerance of
            # the derivative's magnitude: a sideways motion's sum is a small difference of two sides)
            slack += self.tolerance * self.abs_sum
        near = abs(self.ours_sum - self.mitsuba_sum) <= slack
        return self.rel_l2 <= self.tolerance + self.noise and near

    def line(self) -> str:
        return (f"{self.scene:7s} {self.tangent:12s} {self.integrator:30s} rel L2 {100 * self.rel_l2:6.2f} % "
                f"(Mitsuba's noise {100 * self.noise:5.2f} %)  sum ours {self.ours_sum:+.5f} Mitsuba "
                f"{self.mitsuba_sum:+.5f} ± {self.mitsuba_sum_error:.5f} (of |·| {self.abs_sum:.3f})  "
                f"ratio {self.mitsuba_to_ours:.3f}  "
                f"NaN {self.nans}  {self.status}")

    @property
    def status(self) -> str:
        if self.integrator.endswith("Mitsuba's cube"):  # printed for mitsuba3 issue 1895
            return "(not held: Mitsuba's cube)"
        return "ok" if self.passed else "FAIL"


def our_tangent_image(scene, name: str, direction, width: int, height: int, spp: int = 16) -> np.ndarray:
    """(H, W, 3): ``jax.jvp`` of the linear render with the boundary term along one parameter."""
    import jax
    import jax.numpy as jnp

    import raytracer as rt

    value = rt.params.get(scene, name)

    def image(x):
        return rt.render(rt.params.replace(scene, {name: x}), width=width, height=height, spp=spp, edges=True)

    tangent = jnp.broadcast_to(jnp.asarray(direction, value.dtype), value.shape)
    return np.asarray(jax.jvp(image, (value,), (tangent,))[1], np.float64)


def _welded_cube(mi, cube: dict, folder: str) -> dict:
    """Mitsuba's ``cube`` entry as a PLY mesh of the same eight corners shared by its twelve
    triangles (wound outwards: area emitters are one-sided). Mitsuba's own cube gives each face
    its own four vertices, so that every edge of the box is also an open boundary of two faces."""
    import os

    m = np.asarray(cube["to_world"].matrix, np.float64)
    unit = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    corners = unit @ m[:3, :3].T + m[:3, 3]
    faces = []
    for axis in range(3):
        for side in (-1, 1):
            quad = [i for i in range(8) if unit[i, axis] == side]  # four corners, in bit order
            a, b, c, d = quad[0], quad[1], quad[3], quad[2]  # around the face
            for tri in ((a, b, c), (a, c, d)):
                p = corners[list(tri)]
                outward = np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p.mean(0) - corners.mean(0)) > 0
                faces.append(tri if outward else tri[::-1])
    path = os.path.join(folder, "welded_cube.ply")
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
                "property float z\nelement face 12\nproperty list uchar int vertex_indices\nend_header\n")
        f.writelines(f"{x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in corners)
        f.writelines(f"3 {a} {b} {c}\n" for a, b, c in faces)
    return {"type": "ply", "filename": path, "face_normals": True,
            **{k: v for k, v in cube.items() if k in ("bsdf", "emitter")}}


def mitsuba_tangent_images(scene, transform, width: int, height: int, *,
                           integrator: str = "direct_projective", spp: int = SPP, seeds: int = SEEDS,
                           welded: bool = False, edit=None, shadows: bool = False) -> tuple[np.ndarray, int]:
    """``(images (seeds, H, W, 3), NaN samples)``: Mitsuba's forward-mode derivative images of the
    converted scene's one shape with ``to_world = transform(mi, θ, to_world)`` at θ = 0 (a mesh's
    vertices moved by ``transform(mi, θ, identity)``). ``welded``: a box as a mesh whose faces share
    its corners (:func:`_welded_cube`), not Mitsuba's ``cube``. ``edit``: ``(mi, dict) → (dict,
    key of the shape moved)``, the converted scene changed before it is loaded. ``shadows``: the
    boundary term of what the surfaces see too (Mitsuba's ``sppi``), not only the camera's."""
    import tempfile

    mi = vm.mitsuba()
    import drjit as dr

    if not mi.variant().startswith(("llvm_ad", "cuda_ad")):
        raise RuntimeError(f"Mitsuba variant {mi.variant()!r} has no AD (needs llvm_ad_rgb)")
    d = dict(vm.to_mitsuba(scene, width, height))
    moved = None
    if edit is not None:
        d, moved = edit(mi, d)
    # (``sppi``: the samples of the boundary term of what surfaces see, shadows included; none where
    # only what the camera sees moves)
    sppi = {} if shadows else {"sppi": 0}
    d["integrator"] = {"type": integrator, **sppi} if integrator == "direct_projective" else {
        "type": integrator, "max_depth": 2, **sppi}
    with tempfile.TemporaryDirectory() as folder:
        if welded:
            d = {k: _welded_cube(mi, v, folder) if k.startswith("cube") else v for k, v in d.items()}
        mi_scene = mi.load_dict(d)
    params = mi.traverse(mi_scene)
    # the shape's to_world, or a mesh's vertices (Mitsuba's cube), moved by the transform
    key = next(k for k in params.keys() if k.endswith((".to_world", ".vertex_positions"))
               and not k.startswith("sensor") and (moved is None or k.startswith(moved + ".")))
    mesh = key.endswith(".vertex_positions")
    base = dr.unravel(mi.Point3f, params[key]) if mesh else mi.Transform4f(params[key])
    integ = mi_scene.integrator()
    images, nans = [], 0
    for seed in range(seeds):  # the derivative's graph is used up by each render: built again
        theta = mi.Float(0.0)
        dr.enable_grad(theta)
        if mesh:
            params[key] = dr.ravel(transform(mi, theta, mi.Transform4f()) @ base)
        else:
            params[key] = transform(mi, theta, base)
        params.update()
        dr.forward(theta, dr.ADFlag.ClearEdges)  # θ's unit tangent into the scene's parameters
        g = np.asarray(integ.render_forward(mi_scene, params=params, spp=spp, seed=seed), np.float64)[..., :3]
        nans += int(np.isnan(g).sum())
        images.append(g)
    return np.stack(images), nans


def compare(name: str, *, integrator: str = "direct_projective", welded: bool = True, width: int = WIDTH,
            height: int = HEIGHT, spp: int = SPP, seeds: int = SEEDS, tangents=None) -> list[EdgeResult]:
    """Ours against Mitsuba's ``integrator`` for every tangent of scene ``name`` (``welded``: a box
    as a mesh whose faces share its corners, else Mitsuba's ``cube``; ``tangents``: their labels, or
    None for all)."""
    import jax

    import raytracer as rt

    body, every = SCENES[name]
    chosen = [t for t in every if tangents is None or t[0] in tangents]
    results = []
    with jax.enable_x64(True):
        scene = rt.load_scene(HEAD + CAMERA + body)
        for label, param, direction, transform in chosen:
            ours = our_tangent_image(scene, param, direction, width, height)
            theirs, nans = mitsuba_tangent_images(scene, transform, width, height, integrator=integrator,
                                                  spp=spp, seeds=seeds, welded=welded)
            own_cube = not welded and name == "box"  # (the converter's cube, faces unshared)
            results.append(_result(name, label, integrator + (", Mitsuba's cube" if own_cube else ""), ours,
                                   theirs, nans, np.abs(ours).max(-1) > 0))
    return results


def _result(name: str, label: str, integrator: str, ours, theirs, nans: int, mask,
            tolerance: float = MAX_REL_L2) -> EdgeResult:
    """Ours (H, W, 3) against Mitsuba's seed images (seeds, H, W, 3) over the pixels ``mask``; the
    sums are over the whole image (zero it outside the pixels compared where only they count)."""
    mean = np.nanmean(theirs, axis=0)
    error = np.nanstd(theirs, axis=0) / np.sqrt(np.sum(np.isfinite(theirs), axis=0))
    scale = np.linalg.norm(mean[mask])
    # a NaN sample counts as its pixel's mean (dropped, it would bias the sum towards 0)
    sums = np.where(np.isnan(theirs), mean[None], theirs).sum(axis=(1, 2, 3))
    return EdgeResult(
        scene=name, tangent=label, integrator=integrator,
        rel_l2=float(np.linalg.norm((ours - mean)[mask]) / scale),
        noise=float(np.linalg.norm(error[mask]) / scale), ours_sum=float(ours.sum()),
        mitsuba_sum=float(sums.mean()), mitsuba_sum_error=float(sums.std() / np.sqrt(len(sums))),
        nans=nans, mitsuba_to_ours=float(np.sum(mean[mask] * ours[mask]) / np.sum(ours[mask] ** 2)),
        tolerance=tolerance, abs_sum=float(np.abs(mean[mask]).sum()))


PENUMBRA_CAMERA = "camera { location <0, 3.2, -3.2> look_at <0, -0.4, 0.3> angle 45 right x*4/3 }\n"
# the light's centre and its two axes (the square's sides)
PENUMBRA_LIGHT = (np.array([0.3, 6.0, 0.6]), np.array([2.0, 0.0, 0.6]), np.array([-0.6, 0.0, 2.0]))
PENUMBRA_SPHERE = (np.array([0.0, 0.4, 0.4]), 0.45)
PENUMBRA_PLANE = -0.5
PENUMBRA_TANGENTS = (("centre x", (1.0, 0.0, 0.0)), ("centre z", (0.0, 0.0, 1.0)))


def _vec(x) -> str:
    return "<" + ", ".join(f"{float(c):.9g}" for c in x) + ">"


def penumbra_scene_text(grid: int = PENUMBRA_GRID, light: str | None = None) -> str:
    """The penumbra scene; ``light`` in place of its area light of ``grid``² samples."""
    c, a1, a2 = PENUMBRA_LIGHT
    centre, radius = PENUMBRA_SPHERE
    light = light or f"light_source {{ {_vec(c)} rgb 1 area_light {_vec(a1)}, {_vec(a2)}, {grid}, {grid} }}"
    return (HEAD + PENUMBRA_CAMERA + light + "\n"
            f"plane {{ y, {PENUMBRA_PLANE:g} pigment {{ rgb 0.8 }} finish {{ ambient 0 diffuse 1 }} }}\n"
            f"sphere {{ {_vec(centre)}, {radius:g} pigment {{ rgb <1, 0.7, 0.4> }} "
            "finish { ambient 0 diffuse 1 } }")


def rectangle_light(mi) -> dict:
    """Mitsuba's square emitter in place of the area light: the same square, facing down, its
    radiance ``π C r² / (A cos θₑ)`` so that its irradiance on the plane at the penumbra's centre
    (the sphere's centre projected from the light's) is POV-Ray's ``C cos θ``."""
    c, a1, a2 = PENUMBRA_LIGHT
    centre, _ = PENUMBRA_SPHERE
    q = c + (c[1] - PENUMBRA_PLANE) / (c[1] - centre[1]) * (centre - c)
    r = np.linalg.norm(c - q)
    normal = np.cross(a1, a2)
    area = np.linalg.norm(normal)
    normal = normal / area
    cos_e = np.dot(q - c, normal) / r
    if cos_e <= 0:
        raise ValueError("the light does not face the plane")
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = a1 / 2, a2 / 2, normal, c
    radiance = math.pi * r * r / (area * cos_e)
    return {"type": "rectangle", "to_world": mi.ScalarTransform4f(m.tolist()),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}}}


def _with_rectangle_light(mi, d: dict) -> tuple[dict, str]:
    """The converted penumbra scene (its light a stand-in) with :func:`rectangle_light` in place of
    its light, and the key of its sphere."""
    d = {k: v for k, v in d.items() if not k.startswith("light_")}
    d["penumbra_light"] = rectangle_light(mi)
    sphere = next(k for k, v in d.items() if isinstance(v, dict) and v.get("type") == "sphere")
    return d, sphere


def sphere_pixels(width: int, height: int) -> np.ndarray:
    """(H, W) bool: the pixels the penumbra scene's sphere covers any part of, and those beside them."""
    import raytracer as rt

    centre, radius = PENUMBRA_SPHERE
    flat = rt.load_scene(HEAD + PENUMBRA_CAMERA + f"sphere {{ {_vec(centre)}, {radius:g} pigment {{ rgb 1 }} "
                         f"{FLAT} }}")
    seen = np.asarray(rt.render(flat, width=width, height=height, spp=16)).max(-1) > 0
    grown = seen.copy()
    grown[1:] |= seen[:-1]
    grown[:-1] |= seen[1:]
    grown[:, 1:] |= grown[:, :-1].copy()
    grown[:, :-1] |= grown[:, 1:].copy()
    return grown


def compare_penumbra(*, integrator: str = "direct_projective", grid: int = PENUMBRA_GRID, width: int = WIDTH,
                     height: int = HEIGHT, spp: int = SPP, seeds: int = SEEDS,
                     tangents=None) -> list[EdgeResult]:
    """Ours (an area light of ``grid``² samples) against Mitsuba's ``integrator`` (a rectangle
    emitter) on the plane's pixels, for the sphere moved along each of :data:`PENUMBRA_TANGENTS`."""
    import jax

    import raytracer as rt

    results = []
    with jax.enable_x64(True):
        scene = rt.load_scene(penumbra_scene_text(grid))
        # (the converter refuses area lights: it converts the scene with a stand-in, replaced)
        stand_in = rt.load_scene(penumbra_scene_text(
            light="light_source { <0, 6, 0> rgb 1 parallel point_at 0 }"))
        mask_out = sphere_pixels(width, height)
        for label, direction in PENUMBRA_TANGENTS:
            if tangents is not None and label not in tangents:
                continue
            ours = our_tangent_image(scene, "objects[1].shape.center", direction, width, height)
            theirs, nans = mitsuba_tangent_images(
                stand_in, lambda mi, t, base, a=direction: mi.Transform4f().translate(
                    mi.Vector3f(a[0] * t, a[1] * t, a[2] * t)) @ base,
                width, height, integrator=integrator, spp=spp, seeds=seeds, edit=_with_rectangle_light,
                shadows=True)
            plane = ~mask_out[..., None]  # (the plane's pixels only, sums included)
            ours, theirs = ours * plane, np.where(plane[None], theirs, 0.0)
            results.append(_result("penumbra", label, integrator + f", {grid}² grid", ours, theirs, nans,
                                   np.abs(ours).max(-1) > 0, MAX_REL_L2_PENUMBRA))
    return results


# (scene, Mitsuba's integrator, a welded box): the first three are held to the thresholds; Mitsuba's
# own cube is printed for mitsuba3 issue 1895
RUNS = (("sphere", "direct_projective", True), ("box", "direct_projective", True),
        ("box", "prb_projective", True), ("box", "direct_projective", False),
        ("box", "prb_projective", False))


def run():
    """Every comparison of :data:`RUNS`, as each is made."""
    for name, integrator, welded in RUNS:
        yield from compare(name, integrator=integrator, welded=welded)
    yield from compare_penumbra()


def main() -> int:
    results = []
    for r in run():
        print(r.line(), flush=True)
        results.append(r)
    held = [r for r in results if not r.integrator.endswith("Mitsuba's cube")]
    bad = [r for r in held if not r.passed]
    print(f"edges: {len(held) - len(bad)} of {len(held)} derivative images within {100 * MAX_REL_L2:g} % "
          f"(penumbrae {100 * MAX_REL_L2_PENUMBRA:g} %; beyond Mitsuba's noise) of Mitsuba's projective "
          f"sampling; {len(bad)} fail")
    return 1 if bad else 0
