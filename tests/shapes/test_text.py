"""Text: glyph outlines from the font set as POV-Ray sets them (measured against ``povray``:
the first glyph's left edge at the origin, advance widths, the font's kerning and the offset), its
test case (a glyph with a hole) with an implicit function of its own, and the SDL."""

import os

import numpy as np
import pytest

from raytracer.shapes import Text
from raytracer.shapes._prism import prism_from_segments
from raytracer.shapes._text import text_segments

from ._case import Case
from .test_prism import outline_distance

TIMROM = "/usr/share/povray-3.7/include/timrom.ttf"
needs_fonts = pytest.mark.skipif(not os.path.exists(TIMROM), reason="povray-includes is not installed")


def _dot_case():
    if not os.path.exists(TIMROM):  # the generic tests need a case: a square ring in its place
        ring = [[(0, 0), (0.5, 0), (1, 0)], [(1, 0), (1, 0.5), (1, 1)], [(1, 1), (0.5, 1), (0, 1)],
                [(0, 1), (0, 0.5), (0, 0)]]
        segments = np.array(ring, float)
    else:
        # a round dot of eight curves (cheap to check), five times its size (the second-order finite
        # differences' step is absolute)
        segments = 5.0 * text_segments(TIMROM, ".")
    shape = prism_from_segments(segments, 0.0, 0.3, cls=Text)
    lo, hi = segments.reshape(-1, 2).min(0), segments.reshape(-1, 2).max(0)
    sense = np.asarray(shape.sense)

    def distance(p):  # text: the outline in x-y, extruded along z from 0 to 0.3
        return max(abs(p[2] - 0.15) - 0.15, outline_distance(segments, p[0], p[1]))

    return Case("text dot", lambda c, h2: Text(controls=c, sense=sense, height1=0.0, height2=h2),
                (np.asarray(shape.controls, np.float64), np.float64(0.3)), distance,
                np.array([*(lo + hi) / 2, 0.15]), 0.4, convex=False)


CASES = [_dot_case()]


@needs_fonts
def test_glyphs_are_set_by_advance_kerning_and_offset_from_the_first_ones_left_edge():
    """timrom.ttf (1000 units an em): 'A' has a left side bearing of 6 and an advance of 750, the
    pair A-V a kerning of −187; so 'V' starts 0.750 − 0.187 − 0.006 = 0.557 to the right of 'A''s
    start (and 0.1 further with an offset of 0.1 x), and 'A''s left edge is at x = 0."""
    from raytracer.shapes._text import _font

    glyf = _font(TIMROM)[0]["glyf"]
    a_min, v_min = glyf["A"].xMin / 1000, glyf["V"].xMin / 1000
    for offset, extra in (((0.0, 0.0), 0.0), ((0.1, 0.05), 0.1)):
        segs = text_segments(TIMROM, "AV", offset)
        a_only = text_segments(TIMROM, "A")
        v_part = segs[len(a_only):]
        assert np.isclose(segs[:len(a_only), :, 0].min(), 0.0, atol=1e-12)
        assert np.isclose(a_min, 0.006)
        np.testing.assert_allclose(v_part[:, :, 0].min(), 0.750 - 0.187 - 0.006 + extra + v_min, atol=1e-12)
        np.testing.assert_allclose(v_part[:, :, 1].min() - segs[:len(a_only), :, 1].min(),
                                   glyf["V"].yMin / 1000 - glyf["A"].yMin / 1000 + offset[1], atol=1e-12)


@needs_fonts
def test_the_sdl_reads_ttf_and_internal_fonts_and_locates_a_missing_font(tmp_path):
    from raytracer.sdl import SceneError, load_scene

    head = "camera { location <0, 1, -5> look_at 0 } light_source { <0, 9, -9> rgb 1 }\n"
    path = tmp_path / "t.pov"
    path.write_text(head + 'text { ttf "timrom.ttf" "Ab" 0.5, 0 }\n#declare S = "x";\n'
                    "text { internal 1 S 1, <0.1, 0, 0> }\n")
    scene = load_scene(path)
    a, b = (o.shape for o in scene.objects)
    assert type(a) is Text and float(a.height2) == 0.5 and float(b.height2) == 1.0
    np.testing.assert_allclose(np.asarray(b.controls)[np.asarray(b.sense) != 0],
                               text_segments(TIMROM, "x"), atol=1e-6)
    path.write_text(head + 'text { ttf "nofont.ttf" "Ab" 0.5, 0 }\n')
    with pytest.raises(SceneError, match=r't\.pov:2:\d+: .*nofont\.ttf'):
        load_scene(path)
    (tmp_path / "bad.ttf").write_bytes(b"not a font")
    path.write_text(head + 'text { ttf "bad.ttf" "Ab" 0.5, 0 }\n')
    with pytest.raises(SceneError, match=r't\.pov:2:\d+: cannot read the font "bad\.ttf"'):
        load_scene(path)
