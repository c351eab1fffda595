"""POV-Ray's ``text``: a string's TrueType glyph outlines in the x-y plane, extruded along +z from 0
to the thickness (a :class:`~raytracer.shapes._prism.Prism` swept along z).

Glyphs are read with fontTools (composite glyphs drawn through their components); their outlines
are quadratic B-splines, so every segment is a quadratic Bézier (lines get their middle as the
control point). A font unit is ``1 / unitsPerEm``: the text is about one unit per em. The first
character's left edge (its left side bearing) is at the object's origin; each next one starts at
the previous one's advance width plus the font's kerning of the pair (its ``kern`` table) plus
``Offset``. Measured against
``povray`` in docs/semantics.md §4.1.
"""

from __future__ import annotations

import functools
import io
import logging
import struct
from typing import ClassVar

import numpy as np

from ._prism import Prism, prism_from_segments

# POV-Ray 3.7's ``internal`` fonts, by number (its manual's list); a number out of range is 0
INTERNAL_FONTS = ("povlogo.ttf", "timrom.ttf", "cyrvetic.ttf", "crystal.ttf")


class FontError(ValueError):
    """A font file that cannot be read as a TrueType outline font."""


@functools.lru_cache(maxsize=16)
def _font(path: str):
    from fontTools.ttLib import TTFont, TTLibError

    logging.getLogger("fontTools").setLevel(logging.ERROR)  # its notes on odd timestamps
    try:
        with open(path, "rb") as f:  # read whole: a font that fails to parse leaves no file open
            data = io.BytesIO(f.read())
        font = TTFont(data, fontNumber=0, lazy=True)
        if "glyf" not in font:
            raise FontError("not a TrueType outline font (no glyf table)")
        # a loca table longer than its glyphs (POV-Ray's timrom.ttf has one more, zero, offset)
        loca, count = font["loca"], font["maxp"].numGlyphs
        if len(loca.locations) > count + 1:
            loca.locations = loca.locations[: count + 1]
        cmap = font.getBestCmap() or {}
        kern = {}
        if "kern" in font:
            for table in getattr(font["kern"], "kernTables", []):
                kern.update(getattr(table, "kernTable", {}) or {})
        return font, cmap, kern, float(font["head"].unitsPerEm)
    except (TTLibError, OSError, KeyError, AssertionError, struct.error) as e:
        raise FontError(str(e) or type(e).__name__) from None


@functools.lru_cache(maxsize=4096)
def _glyph(path: str, name: str) -> np.ndarray:
    """(S, 3, 2) quadratic Bézier segments of a glyph in font units."""
    from fontTools.pens.basePen import BasePen

    font, _, _, _ = _font(path)
    glyphs = font.getGlyphSet()
    segments: list = []

    class _Pen(BasePen):
        def _moveTo(self, p):
            self._start = p

        def _lineTo(self, p):
            a = self._getCurrentPoint()
            segments.append((a, (0.5 * (a[0] + p[0]), 0.5 * (a[1] + p[1])), p))

        def _qCurveToOne(self, p1, p2):
            segments.append((self._getCurrentPoint(), p1, p2))

        def _curveToOne(self, p1, p2, p3):  # not in glyf outlines; a quadratic through the ends
            a = self._getCurrentPoint()
            c = (0.25 * (3 * p1[0] + 3 * p2[0] - a[0] - p3[0]), 0.25 * (3 * p1[1] + 3 * p2[1] - a[1] - p3[1]))
            segments.append((a, c, p3))

        def _closePath(self):
            a = self._getCurrentPoint()
            if a is not None and getattr(self, "_start", None) is not None and a != self._start:
                self._lineTo(self._start)

        _endPath = _closePath

    glyphs[name].draw(_Pen(glyphs))
    return np.asarray(segments, np.float64).reshape(-1, 3, 2)


def text_segments(path: str, string: str, offset=(0.0, 0.0)) -> np.ndarray:
    """(S, 3, 2): the outlines of ``string`` set in the font at ``path``, in units of one em."""
    font, cmap, kern, em = _font(path)
    order = font.getGlyphOrder()
    metrics = font["hmtx"].metrics
    x = y = 0.0
    out, previous = [], None
    for i, ch in enumerate(string):
        name = cmap.get(ord(ch), order[0])
        if i == 0:  # the first glyph's left edge at the origin (measured)
            x = -metrics[name][1] / em
        if previous is not None:
            x += kern.get((previous, name), 0) / em
        seg = _glyph(path, name)
        if len(seg):
            out.append(seg / em + np.array([x, y]))
        x += metrics[name][0] / em + float(offset[0])
        y += float(offset[1])
        previous = name
    return np.concatenate(out) if out else np.zeros((0, 3, 2))


def _font_file(args, name: str) -> str:
    """The font file ``name`` names, searched as an include file is; as POV-Ray, a name without a
    suffix is tried with ``.ttf`` too."""
    try:
        return args.find_file(name, "a font file")
    except Exception:
        if "." in name.rsplit("/", 1)[-1]:
            raise
        return args.find_file(name + ".ttf", "a font file")


class Text(Prism):
    """``text { ttf "font" "string" thickness, offset }``: the string's glyphs, filled by the
    even-odd rule, from z = 0 to z = ``height2`` (the thickness)."""

    kind: ClassVar[str] = "text"
    sdl_keywords: ClassVar[tuple[str, ...]] = ("text",)
    sdl_flags: ClassVar[tuple[str, ...]] = ()
    axis: ClassVar[int] = 2

    @classmethod
    def parse_sdl(cls, keyword, args):
        loc = args.loc
        if args.keyword("internal") is not None:
            number = int(args.float())
            font = INTERNAL_FONTS[number] if 0 <= number < len(INTERNAL_FONTS) else INTERNAL_FONTS[0]
        elif args.keyword("ttf") is not None:
            font = args.expr()
            if not isinstance(font, str):
                raise args.error("expected a font file name after ttf", loc)
        else:
            raise args.error(f"expected ttf or internal in text, found {args.describe_next()}")
        args.comma()
        path = _font_file(args, font)
        s_loc = args.loc
        string = args.expr()
        if not isinstance(string, str):
            raise args.error("expected the text's string", s_loc)
        args.comma()
        thickness = args.float()
        args.comma()
        offset = args.vector()
        try:
            segments = text_segments(path, string, offset[:2])
        except FontError as e:
            raise args.error(f'cannot read the font "{font}": {e}', loc) from None
        if not len(segments):
            args.leave_out(f'text "{string}" has no outline')
        return {"segments": segments, "thickness": thickness}

    @classmethod
    def from_sdl(cls, fields):
        return prism_from_segments(fields["segments"], 0.0, fields["thickness"], cls=cls)
