"""Our renderer against POV-Ray on every example scene (issue 3's bar: ≥ 40 dB at 160×120, spp=1)."""

from pathlib import Path

import numpy as np
import pytest

from validation import metrics
from validation.povray import povray_executable, render_povray

pytestmark = [pytest.mark.povray, pytest.mark.slow,
              pytest.mark.skipif(povray_executable() is None, reason="povray is not installed")]

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"
W, H = 160, 120
MIN_PSNR = 40.0

# Measured failures of our renderer, as {scene stem: reason naming the missing feature}; each
# becomes a strict xfail, so fixing the feature forces the entry out. Empty since e9b7544.
KNOWN_FAILURES: dict[str, str] = {}


def _cases():
    for path in sorted(SCENES.glob("*.pov")):
        if path.stem == "seed":
            continue  # owned and tested by the parser/renderer work
        marks = ()
        if path.stem in KNOWN_FAILURES:
            marks = (pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[path.stem]),)
        yield pytest.param(path, id=path.stem, marks=marks)


def test_every_example_starts_with_a_checks_line():
    for path in SCENES.glob("*.pov"):
        if path.stem != "seed":
            assert path.read_text().startswith("// checks: "), path.name


@pytest.mark.parametrize("path", _cases())
def test_example_matches_povray(path):
    import raytracer
    from raytracer.sdl import load_scene

    scene = load_scene(path, width=W, height=H)
    ours = np.asarray(raytracer.render(scene, width=W, height=H, spp=1))
    ref = render_povray(path, W, H)
    m = metrics.compare(ours, ref)
    assert m.psnr >= MIN_PSNR, f"{path.name}: {m}"
