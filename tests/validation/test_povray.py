"""The POV-Ray runner against values POV-Ray must produce by definition."""

import numpy as np
import pytest

from validation.povray import PovrayError, PovrayUnavailable, render_povray, run_povray

# a sphere that only glows (ambient 1, diffuse 0) covers the centre; the background fills the corners
GLOW = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -5> look_at <0, 0, 0> right x*image_width/image_height angle 30 }
background { rgb <0.25, 0.5, 0.125> }
sphere { <0, 0, 0>, 1 pigment { rgb <0.75, 0.375, 0.5> } finish { ambient 1 diffuse 0 } }
"""


@pytest.mark.povray
def test_glowing_sphere_and_background_are_exact_linear_values():
    r = run_povray(GLOW, 32, 24)
    assert r.image.shape == (24, 32, 3) and r.image.dtype == np.float32
    np.testing.assert_array_equal(r.image[12, 16], [0.75, 0.375, 0.5])  # exactly representable in half
    np.testing.assert_array_equal(r.image[0, 0], [0.25, 0.5, 0.125])
    assert r.trace_seconds is not None and r.trace_seconds >= 0.0
    assert "-A" in r.command and "+FE" in r.command


@pytest.mark.povray
def test_scene_file_with_an_include_from_its_own_folder(tmp_path):
    (tmp_path / "colours.inc").write_text("#declare Glow = rgb <0.5, 0.25, 1>;\n")
    scene = tmp_path / "scene.pov"
    scene.write_text(GLOW.replace("rgb <0.75, 0.375, 0.5>", "Glow").replace(
        "#version 3.7;", '#version 3.7;\n#include "colours.inc"'))
    image = render_povray(scene, 32, 24)
    np.testing.assert_array_equal(image[12, 16], [0.5, 0.25, 1.0])


@pytest.mark.povray
def test_supersampling_averages_centre_and_grid_at_a_silhouette():
    aliased = render_povray(GLOW, 32, 24)
    smooth = run_povray(GLOW, 32, 24, antialias=(0.0, 3))
    assert "+AM1" in smooth.command and "-J" in smooth.command
    # interior pixels are unchanged, silhouette pixels become mixtures of sphere and background
    np.testing.assert_array_equal(smooth.image[12, 16], aliased[12, 16])
    assert np.any(np.abs(smooth.image - aliased).max(axis=-1) > 0.01)


@pytest.mark.povray
def test_parse_error_raises_with_povray_message():
    with pytest.raises(PovrayError, match="Parse Error"):
        render_povray("#version 3.7;\nsphere { 0, 1 \n", 8, 8)


def test_missing_binary_raises_povray_unavailable(monkeypatch, tmp_path):
    monkeypatch.setenv("POVRAY", str(tmp_path / "no-such-povray"))
    with pytest.raises(PovrayUnavailable):
        render_povray(GLOW, 8, 8)
