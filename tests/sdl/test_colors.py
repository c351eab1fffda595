"""Colour expressions and promotion (semantics §2.2)."""

import pytest

from .conftest import run_sdl


def color(text):
    v = run_sdl(f"#declare R = {text};").lookup("R")
    return v.c, v.ft


@pytest.mark.parametrize("text, expected, ft", [
    ("rgb <1, 0.5, 0>", (1, 0.5, 0, 0, 0), False),
    ("rgb 0.5", (0.5, 0.5, 0.5, 0, 0), False),
    ("rgbf <1, 1, 1, 0.3>", (1, 1, 1, 0.3, 0), True),
    ("rgbt <1, 1, 1, 0.3>", (1, 1, 1, 0, 0.3), True),
    ("rgbft <1, 1, 1, 0.3, 0.4>", (1, 1, 1, 0.3, 0.4), True),
    ("color red 1 green 0.5", (1, 0.5, 0, 0, 0), False),
    ("colour blue 1 filter 0.2", (0, 0, 1, 0.2, 0), True),
    ("color rgb <1, 0, 0> transmit 0.5", (1, 0, 0, 0, 0.5), True),
    ("color 0.5", (0.5, 0.5, 0.5, 0.5, 0.5), True),
    ("color <0.2, 0.4, 0.6>", (0.2, 0.4, 0.6, 0, 0), False),
    ("rgb <1, 1, 1> * 0.5", (0.5, 0.5, 0.5, 0, 0), False),
    ("rgbf 1", (1, 1, 1, 1, 0), True),
])
def test_colour_spellings(text, expected, ft):
    c, has_ft = color(text)
    assert c == pytest.approx(expected)
    assert has_ft is ft


def test_colour_arithmetic_is_per_channel_on_five_channels():
    c, _ = color("rgbft <1, 1, 1, 0.5, 0.5> * rgbft <0.5, 1, 0, 0.5, 1>")
    assert c == pytest.approx((0.5, 1, 0, 0.25, 0.5))


def test_colors_inc_identifiers():
    p = run_sdl('#include "colors.inc"\n#declare R = Red; #declare C = Clear;')
    assert p.lookup("R").c == (1, 0, 0, 0, 0)
    assert p.lookup("C").c == (1, 1, 1, 1, 0)


def test_srgb_decodes_to_linear_with_gamma_one():
    c, _ = color("srgb <1, 0.5, 0>")
    assert c[0] == pytest.approx(1.0)
    assert c[1] == pytest.approx(((0.5 + 0.055) / 1.055) ** 2.4)
    assert c[2] == 0.0


def test_srgb_goes_to_the_gamma_encoded_working_space():
    p = run_sdl("global_settings { assumed_gamma 2.2 } #declare R = srgbf <0.5, 0.5, 0.5, 0.5>;")
    lin = ((0.5 + 0.055) / 1.055) ** 2.4
    assert p.lookup("R").c == pytest.approx((lin ** (1 / 2.2),) * 3 + (0.5, 0.0))
