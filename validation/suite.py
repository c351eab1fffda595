"""The validation suite: scenes, the references each is compared with, and the pass thresholds.

Every scene is a ``.pov`` file (one source of truth): POV-Ray renders it, our parser loads it, and
the Mitsuba reference is converted from the parsed scene. Our image is ``raytracer.render(…, spp=1)``
(one ray through each pixel centre), compared with

* ``povray``:  POV-Ray 3.7 ``-A`` (also one ray through each pixel centre), and
* ``mitsuba``: Mitsuba 3 with rays through the same pixel centres (``spp`` estimates per centre:
  1 for deterministic scenes, more for glass, whose Fresnel split is sampled).

Thresholds are the measured agreement with a margin (see the comment next to each entry): PSNR in
dB with peak 1.0 linear, and the fraction of pixels whose largest channel error is within ``tol``.
Edge pixels, where a pixel centre falls within float precision of a silhouette, shadow edge or
checker edge, make up the non-matching fraction of deterministic scenes.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from pathlib import Path

import numpy as np

from . import metrics
from .metrics import Thresholds

ROOT = Path(__file__).resolve().parent
SUITE_DIR = ROOT / "scenes"
EXAMPLES_DIR = ROOT.parent / "examples" / "scenes"
WIDTH, HEIGHT = 160, 120
REFERENCES = ("mitsuba", "povray")


@dataclasses.dataclass(frozen=True)
class SuiteScene:
    """One scene of the suite.

    Attributes:
        name:        short unique name (``python -m validation NAME``).
        path:        the ``.pov`` file.
        povray:      thresholds against POV-Ray, or None if not compared.
        mitsuba:     thresholds against Mitsuba, or None (the scene is not Mitsuba-matchable).
        mitsuba_spp: estimates per pixel centre in Mitsuba (> 1 only for Monte Carlo materials).
    """

    name: str
    path: Path
    povray: Thresholds | None = None
    mitsuba: Thresholds | None = None
    mitsuba_spp: int = 1

    @property
    def checks(self) -> str:
        """The scene's one-line ``// checks:`` statement."""
        for line in self.path.read_text().splitlines():
            if line.startswith("// checks:"):
                return line[len("// checks:"):].strip()
        return ""

    def thresholds(self, reference: str) -> Thresholds | None:
        return {"povray": self.povray, "mitsuba": self.mitsuba}[reference]


def _mi(frac: float) -> Thresholds:
    """Deterministic Mitsuba comparison: all but ``1 − frac`` of the pixels within 0.01, p99 ≤ 1e-3.

    Mitsuba (float32) and POV-Ray (float64, half-float EXR) agree to ~1e-4 (p99 8e-5…1.2e-4)
    except where a pixel centre lies within float precision of a silhouette, shadow or checker
    edge, where one of them sees the other side (errors up to 0.9). PSNR is dominated by those few
    pixels, so it is reported but not used as the criterion here.
    """
    return Thresholds(tol=0.01, min_frac_within=frac, max_p99=1e-3)


# Monte Carlo glass in Mitsuba (256 estimates per centre; the Fresnel split is sampled): measured
# vs POV-Ray, 98.9 % (sphere) / 99.1 % (box) of pixels within 0.05, p99 0.043 / 0.028.
GLASS_MI = Thresholds(tol=0.05, min_frac_within=0.975, max_p99=0.08)
# Our renderer vs POV-Ray: the bar of 40 dB PSNR and 99 % of pixels within 0.01. Measured where
# our renderer works: 61–94 dB, ≥ 99.78 % within 0.01.
POV_BAR = Thresholds(min_psnr=40.0, tol=0.01, min_frac_within=0.99)


def _suite(name: str, **kw) -> SuiteScene:
    return SuiteScene(name=name, path=SUITE_DIR / f"{name}.pov", **kw)


def _example(name: str, **kw) -> SuiteScene:
    return SuiteScene(name=f"pov/{name}", path=EXAMPLES_DIR / f"{name}.pov", **kw)


# The comment after each Mitsuba scene is the MEASURED Mitsuba-vs-POV-Ray agreement at 160×120,
# pixel centres (fraction of pixels within 0.01; p99 abs error); the threshold leaves a margin.
SCENES: tuple[SuiteScene, ...] = (
    # --- Mitsuba-matchable (validation/scenes), each also against POV-Ray -----------------------------
    _suite("lambert_sphere", mitsuba=_mi(0.995), povray=POV_BAR),  # 0.9990; 8.9e-5
    _suite("two_lights", mitsuba=_mi(0.998), povray=POV_BAR),  # 0.9999; 1.2e-4
    _suite("ambient_background", mitsuba=_mi(0.998), povray=POV_BAR),  # 1.0000; 2.0e-4
    _suite("mirror_sphere", mitsuba=_mi(0.985), povray=POV_BAR),  # 0.9923; 1.2e-4 (aliased checkers)
    _suite("mirror_corridor", mitsuba=_mi(0.995), povray=POV_BAR),  # 0.9986; 9.3e-5
    _suite("trace_depth", mitsuba=_mi(0.995), povray=POV_BAR),  # 0.9986; 1.2e-4
    _suite("glass_sphere", mitsuba=GLASS_MI, mitsuba_spp=256, povray=POV_BAR),  # 0.9892 within 0.05
    _suite("glass_box", mitsuba=GLASS_MI, mitsuba_spp=256, povray=POV_BAR),  # 0.9914 within 0.05
    _suite("checker_planes", mitsuba=_mi(0.980), povray=POV_BAR),  # 0.9908; 3.4e-5
    _suite("boxes_transforms", mitsuba=_mi(0.998), povray=POV_BAR),  # 0.9999; 1.1e-4
    _suite("cylinders_discs", mitsuba=_mi(0.998), povray=POV_BAR),  # 0.9999; 1.1e-4
    _suite("mesh_triangles", mitsuba=_mi(0.998), povray=POV_BAR),  # 0.9998; 8.3e-5
    _suite("union_transforms", mitsuba=_mi(0.998), povray=POV_BAR),  # 1.0000; 6.9e-5
    _suite("scaled_spheres", mitsuba=_mi(0.995), povray=POV_BAR),  # 0.9985; 1.2e-4
    # --- POV-Ray only (examples/scenes): what only POV-Ray defines ------------------------------------
    _example("sphere", povray=POV_BAR),
    _example("plane", povray=POV_BAR),
    _example("box", povray=POV_BAR),
    _example("cylinder", povray=POV_BAR),
    _example("cone", povray=POV_BAR),
    _example("quadric", povray=POV_BAR),
    _example("polygon", povray=POV_BAR),
    _example("triangle", povray=POV_BAR),
    _example("disc", povray=POV_BAR),
    _example("torus", povray=POV_BAR),
    _example("superellipsoid", povray=POV_BAR),
    _example("poly", povray=POV_BAR),
    _example("mesh", povray=POV_BAR),
    _example("csg_union_merge", povray=POV_BAR),
    _example("csg_intersection_difference", povray=POV_BAR),
    _example("csg_clipped_inverse", povray=POV_BAR),
    _example("csg_hollow_glass", povray=POV_BAR),
    _example("brilliance", povray=POV_BAR),
    _example("phong_specular", povray=POV_BAR),
    _example("metallic", povray=POV_BAR),
    _example("reflection", povray=POV_BAR),
    _example("glass", povray=POV_BAR),
    _example("filter_transmit", povray=POV_BAR),
    _example("point_light_fade", povray=POV_BAR),
    _example("shadowless", povray=POV_BAR),
    _example("patterns", povray=POV_BAR),
    _example("ambient_background", povray=POV_BAR),
    _example("spotlight", povray=POV_BAR),
    _example("area_light", povray=POV_BAR),
    _example("layered_texture", povray=POV_BAR),
    _example("straight_transmission", povray=POV_BAR),
    _example("normals", povray=POV_BAR),
    _example("pigment_maps", povray=POV_BAR),
    _example("image_map", povray=POV_BAR),
    _example("prism", povray=POV_BAR),
    _example("text", povray=POV_BAR),
    _example("texture_map", povray=POV_BAR),
    _example("lathe", povray=POV_BAR),
    _example("isosurface", povray=POV_BAR),
    _example("blob", povray=POV_BAR),
)


def scene_named(name: str) -> SuiteScene:
    for s in SCENES:
        if s.name == name or s.name == f"pov/{name}":
            return s
    raise KeyError(f"no suite scene named {name!r}; known: {', '.join(s.name for s in SCENES)}")


# --------------------------------------------------------------------------------------------------
# running


@dataclasses.dataclass
class Result:
    """One scene × reference comparison."""

    scene: SuiteScene
    reference: str
    metrics: metrics.Metrics | None = None
    failures: list[str] = dataclasses.field(default_factory=list)
    error: str | None = None
    ours: np.ndarray | None = None
    ref: np.ndarray | None = None
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        return self.error is None and not self.failures

    @property
    def status(self) -> str:
        return "PASS" if self.passed else ("ERROR" if self.error else "FAIL")

    def line(self) -> str:
        name = f"{self.scene.name:38s} {self.reference:8s}"
        if self.metrics is None:
            return f"{name} {'':>8s} {'':>9s} {'':>7s} {'':>8s}  {self.status}  {self.error}"
        m = self.metrics
        extra = "; ".join(self.failures)
        return (f"{name} {m.psnr:7.2f}dB {m.rmse:9.2e} {m.max_abs:7.3f} {m.frac_within:8.4f}  {self.status}"
                + (f"  {extra}" if extra else ""))


HEADER = (f"{'scene':38s} {'ref':8s} {'PSNR':>9s} {'RMSE':>9s} {'max':>7s} {'in tol':>8s}  result")


def load_ours(scene: SuiteScene, width: int = WIDTH, height: int = HEIGHT):
    """Parses the scene with our parser (the same file POV-Ray reads)."""
    from raytracer.sdl import load_scene

    return load_scene(scene.path, width=width, height=height)


def render_ours(parsed, width: int = WIDTH, height: int = HEIGHT, spp: int = 1) -> np.ndarray:
    import raytracer

    return np.asarray(raytracer.render(parsed, width=width, height=height, spp=spp), dtype=np.float32)


REFERENCE_CACHE_ENV = "RAYTRACER_REFERENCE_CACHE"


def _cached_reference(key: tuple, make) -> np.ndarray:
    """``make()``, kept in ``$RAYTRACER_REFERENCE_CACHE`` (when set) under a hash of ``key``: the test
    session sets it to a folder of its own, so a reference two tests (or two workers) need is
    rendered once per run (a lock per image: a worker that needs an image another is rendering
    waits for it). Written atomically; never shared between runs."""
    import fcntl

    folder = os.environ.get(REFERENCE_CACHE_ENV)
    if not folder:
        return make()
    path = Path(folder) / (hashlib.sha256(repr(key).encode()).hexdigest() + ".npy")
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if path.is_file():
            return np.load(path)
        image = make()
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npy")
        np.save(tmp, image)
        os.replace(tmp, path)
        return image


def render_reference(scene: SuiteScene, reference: str, parsed=None, width: int = WIDTH,
                     height: int = HEIGHT, *, parsed_is_default: bool = False) -> np.ndarray:
    """The reference image of ``scene`` (POV-Ray ``-A`` or Mitsuba pixel centres). ``parsed`` is
    ``load_ours(scene, width, height)`` when ``parsed_is_default`` (the image may then be cached)."""
    if (parsed is None or parsed_is_default) and reference in REFERENCES:
        key = (reference, str(scene.path), hashlib.sha256(scene.path.read_bytes()).hexdigest(), width,
               height, scene.mitsuba_spp)
        return _cached_reference(key, lambda: _render_reference(scene, reference, parsed, width, height))
    return _render_reference(scene, reference, parsed, width, height)


def _render_reference(scene: SuiteScene, reference: str, parsed, width: int, height: int) -> np.ndarray:
    if reference == "povray":
        from .povray import render_povray

        return render_povray(scene.path, width, height)
    if reference == "mitsuba":
        from . import mitsuba as vm

        if parsed is None:
            parsed = load_ours(scene, width, height)
        return vm.render_mitsuba_centres(vm.to_mitsuba(parsed, width, height), spp=scene.mitsuba_spp)
    raise ValueError(f"unknown reference {reference!r}")


def run(scenes, references=REFERENCES, *, render=None, width: int = WIDTH, height: int = HEIGHT,
        on_result=None) -> list[Result]:
    """Compares every scene with every reference it has thresholds for.

    Args:
        scenes:     :class:`SuiteScene` entries.
        references: subset of ``("mitsuba", "povray")``.
        render:     ``f(parsed_scene, width, height) -> image`` replacing our renderer (tests use it
                    to prove the suite catches a broken renderer).
        on_result:  called with each :class:`Result` as soon as it is ready.
    """
    render = render or render_ours
    results = []
    for scene in scenes:
        wanted = [r for r in references if scene.thresholds(r) is not None]
        if not wanted:
            continue
        parsed, ours, setup_error = None, None, None
        t0 = time.perf_counter()
        try:
            parsed = load_ours(scene, width, height)
            ours = render(parsed, width, height)
        except Exception as e:  # noqa: BLE001 - a failing scene must not stop the suite
            setup_error = f"ours: {type(e).__name__}: {e}".splitlines()[0]
        t_ours = time.perf_counter() - t0
        for reference in wanted:
            result = Result(scene=scene, reference=reference)
            t1 = time.perf_counter()
            try:
                if setup_error is not None:
                    raise RuntimeError(setup_error)
                ref = render_reference(scene, reference, parsed, width, height, parsed_is_default=True)
                th = scene.thresholds(reference)
                result.metrics = metrics.compare(ours, ref, tol=th.tol)
                result.failures = th.failures(result.metrics)
                result.ours, result.ref = ours, ref
            except Exception as e:  # noqa: BLE001
                msg = str(e).splitlines()[0] if str(e) else type(e).__name__
                result.error = msg if msg.startswith("ours:") else f"{type(e).__name__}: {msg}"
                result.ours = ours
            result.seconds = t_ours + time.perf_counter() - t1
            results.append(result)
            if on_result is not None:
                on_result(result)
    return results
