"""``raytracer compare``: one's own scene against POV-Ray, the side-by-side image, the worst region."""

import numpy as np
import pytest

import raytracer as rt
from raytracer.cli import main
from validation.compare import worst_region


def test_the_worst_region_is_the_block_of_largest_mean_difference():
    ours = np.zeros((20, 30, 3))
    reference = ours.copy()
    reference[17, 25] = 0.5  # in the partial block x 24–29, y 16–19
    reference[2, 2] = 0.4
    assert worst_region(ours, reference) == (24, 29, 16, 19, pytest.approx(0.5 / 24))


@pytest.mark.povray
def test_compare_renders_both_and_writes_ours_the_reference_and_the_difference(tmp_path, capsys):
    scene = tmp_path / "ball.pov"
    scene.write_text("#version 3.7; global_settings { assumed_gamma 1.0 }\n"
                     "camera { location <0, 0, -4> look_at 0 }\nlight_source { <2, 3, -5> rgb 1 }\n"
                     "sphere { 0, 1 pigment { rgb <1, 0.5, 0.2> } }\n")
    out = tmp_path / "side.png"
    assert main(["compare", str(scene), "-W", "16", "-H", "12", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    psnr = float(text.split("PSNR ")[1].split(" dB")[0])
    assert psnr > 40 and "worst region: x " in text and "POV-Ray: parse" in text
    side = rt.read_image(out)
    assert side.shape == (12, 3 * 16 + 2, 3)
    ours = np.asarray(rt.render(rt.load_scene(scene, width=16, height=12), width=16, height=12))
    np.testing.assert_allclose(side[:, :16], ours, atol=3e-3)  # ours on the left (8-bit sRGB)
    assert main(["compare", str(tmp_path / "missing.pov"), "-o", str(out)]) == 2
    assert "missing.pov" in capsys.readouterr().err
