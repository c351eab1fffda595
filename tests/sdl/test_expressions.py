"""Expression evaluation: precedence, vectors, colours and the built-in functions."""

import math

import numpy as np
import pytest

from raytracer.errors import SceneError

from .conftest import run_sdl, value


@pytest.mark.parametrize("expr, expected", [
    ("1 + 2 * 3", 7.0),
    ("(1 + 2) * 3", 9.0),
    ("-2 * 3 + 10 / 4", -3.5),
    ("2 - 3 - 4", -5.0),
    ("8 / 2 / 2", 2.0),
    ("1 + 2 < 4", 1.0),
    ("(1 < 2) & (3 > 4)", 0.0),
    ("(1 < 2) | (3 > 4)", 1.0),
    ("!0 + 1", 2.0),
    ("1 ? 5 : 6", 5.0),
    ("0 ? 5 : 1 ? 7 : 8", 7.0),
    ("1 + 1 = 2", 1.0),
    ("3 != 3", 0.0),
    ("2 >= 2", 1.0),
])
def test_precedence(expr, expected):
    # comparisons, & | and ?: are only allowed inside parentheses (manual 3.3.1.5.3)
    assert value(f"#declare R = ({expr});") == pytest.approx(expected)


def test_top_level_less_than_starts_a_vector():
    from raytracer.sdl import load_scene

    (box,) = load_scene("box { <-1, -1, -1> <1, 2, 3> }").objects
    assert [float(v) for v in box.shape.corner2] == [1.0, 2.0, 3.0]


def test_vector_arithmetic_promotes_floats():
    assert value("#declare R = <1, 2, 3> * 2 + 1;") == (3.0, 5.0, 7.0)
    assert value("#declare R = 2 * x - y;") == (2.0, -1.0, 0.0)


def test_vectors_of_different_length_pad_with_zero():
    assert value("#declare R = <1, 2> + <1, 1, 1>;") == (2.0, 3.0, 1.0)


def test_comparison_inside_vector_needs_parentheses():
    assert value("#declare R = <1, (2 > 1), 3>;") == (1.0, 1.0, 3.0)


def test_dot_access_of_vectors_and_colours():
    assert value("#declare R = <4, 5, 6>.y;") == 5.0
    assert value("#declare R = (rgbft <.1, .2, .3, .4, .5>).transmit;") == pytest.approx(0.5)
    assert value("#declare C = rgb <1, 0, 0>; #declare R = C.red + C.filter;") == 1.0
    assert value("#declare R = <1,2,3,4>.t;") == 4.0


def test_gray_is_the_luminance_weighting():
    assert value("#declare R = (rgb <1, 0, 0>).gray;") == pytest.approx(0.297)


@pytest.mark.parametrize("expr, expected", [
    ("abs(-2)", 2.0), ("ceil(1.2)", 2.0), ("floor(-1.2)", -2.0), ("int(-1.7)", -1.0),
    ("mod(7, 3)", 1.0), ("mod(-7, 3)", -1.0), ("div(7, 2)", 3.0), ("pow(2, 10)", 1024.0),
    ("sqrt(16)", 4.0), ("exp(0)", 1.0), ("log(100)", 2.0), ("ln(1)", 0.0),
    ("min(3, 1, 2)", 1.0), ("max(3, 1, 2)", 3.0), ("degrees(pi)", 180.0), ("radians(180)", math.pi),
    ("sin(pi/2)", 1.0), ("atan2(1, 1)", math.pi / 4), ("select(-1, 10, 20)", 10.0),
    ("select(0, 10, 20)", 20.0), ("select(0, 10, 20, 30)", 20.0), ("select(1, 10, 20, 30)", 30.0),
    ("vlength(<3, 4, 0>)", 5.0), ("vdot(x, y)", 0.0), ("strlen(\"abc\")", 3.0),
    ("val(\"2.5e1\")", 25.0), ("asc(\"A\")", 65.0), ("bitwise_and(12, 10)", 8.0),
    ("bitwise_or(12, 10)", 14.0), ("bitwise_xor(12, 10)", 6.0), ("file_exists(\"x\")", 0.0),
    ("true + yes + on", 3.0), ("false + no + off", 0.0), ("clock", 0.0),
])
def test_float_builtins(expr, expected):
    assert value(f"#declare R = {expr};") == pytest.approx(expected)


def test_vector_builtins():
    assert value("#declare R = vcross(x, y);") == (0.0, 0.0, 1.0)
    assert value("#declare R = vnormalize(<0, 3, 4>);") == pytest.approx((0.0, 0.6, 0.8))
    # rotate x by 90° about z: POV's left-handed rule takes +x to +y (semantics §4.3)
    assert value("#declare R = vrotate(x, <0, 0, 90>);") == pytest.approx((0.0, 1.0, 0.0))
    assert value("#declare R = vaxis_rotate(x, z, 90);") == pytest.approx((0.0, 1.0, 0.0))


def test_string_builtins():
    assert value('#declare R = concat("a", str(1.5, 0, 2), chr(66));') == "a1.50B"
    assert value('#declare R = substr("hello", 2, 3);') == "ell"
    assert value('#declare R = strupr("aB");') == "AB"
    assert value('#declare R = strlwr("aB");') == "ab"
    assert value('#declare R = str(3, -4, 0);') == "0003"
    # vstr(N, A, S, L, P): the component count comes first (povray 3.7 rejects the other order)
    assert value('#declare R = vstr(3, <1, 2.5, -3>, ", ", 0, 1);') == "1.0, 2.5, -3.0"
    assert value('#declare R = vstr(2, <1, 2, 3>, "/", 0, 0);') == "1/2"


def test_image_size_and_version_constants():
    assert value("#declare R = image_width / image_height;", width=200, height=100) == 2.0
    assert value("#version 3.6; #declare R = version;") == pytest.approx(3.6)


@pytest.mark.parametrize("seed, expected", [
    # POV-Ray 3.7's #debug of str(rand(S), 0, 12), three values a seed
    ("0", (0.000002874294, 0.466563684509, 0.249070228834)),
    ("3", (0.265972876983, 0.528236225603, 0.499548188993)),
    ("-3", (0.734032871838, 0.404891143414)),
    ("-2.5", (0.156022872579, 0.425448657113)),  # truncated towards 0
    ("1e10", (0.500002874411, 0.966563684625)),  # beyond 32 bits: -2^31
    ("123456789", (0.498219878063, 0.096967906481)),
])
def test_rand_is_povrays_sequence(seed, expected):
    calls = ", ".join(["rand(S)"] * len(expected))
    got = value(f"#declare S = seed({seed}); #declare R = array[{len(expected)}] {{ {calls} }};")
    np.testing.assert_allclose(got.data, expected, atol=1e-12)


def test_defined_and_arrays():
    text = """
    #declare A = array[2][3] { {1, 2, 3}, {4, 5, 6} };
    #declare A[1][0] = 40;
    #declare R = <A[0][2], A[1][0], dimension_size(A, 2), dimensions(A), defined(A) + defined(B)>;
    """
    assert value(text) == (3.0, 40.0, 3.0, 2.0, 1.0)


def test_uninitialised_array_element_is_an_error():
    with pytest.raises(SceneError, match="never initialised"):
        value("#declare A = array[2]; #declare R = A[1];")


def test_user_function_is_evaluated():
    assert value("#declare F = function(a, b) { a * b + 1 }; #declare R = F(2, 3);") == 7.0
    assert value("#declare F = function { x + y * z }; #declare R = F(1, 2, 3);") == 7.0


def test_sum_and_prod_in_a_function_body_run_their_index_over_whole_steps():
    # POV-Ray 3.7 prints 12 and 24 for these two (#debug), and refuses sum() outside a function
    assert value("#declare F = function(x) { sum(i, 0, 3, x*i) } #declare R = F(2);") == 12.0
    assert value("#declare F = function(x) { prod(i, 1, 4, x + i) } #declare R = F(0);") == 24.0
    nested = ("#declare F = function { sum(j, 1, 3, prod(k, 1, j, k)) + sum(i, 2, 1, 9) }"
              "#declare R = F(0, 0, 0);")
    assert value(nested) == 1.0 + 2.0 + 6.0  # 1! + 2! + 3!; an empty range adds nothing
    with pytest.raises(SceneError, match=r"t.pov:1:14: sum\(\) can only be used in a function body"):
        value("#declare R = sum(i, 1, 4, i);")


def test_datetime_and_now_count_days_from_2000():
    assert value("#declare R = datetime(0);") == "2000-01-01 00:00:00Z"  # POV-Ray's default format
    assert value('#declare R = datetime(1.5, "%Y-%m-%d %H:%M");') == "2000-01-02 12:00"
    assert value("#declare R = now;") > 9800.0  # days since 2000-01-01: after 2026-10-30


def test_linear_spline_interpolates():
    text = "#declare S = spline { linear_spline 0, <0,0,0> 1, <2,4,6> }; #declare R = S(0.5);"
    assert value(text) == (1.0, 2.0, 3.0)


def test_division_by_zero_is_a_scene_error():
    with pytest.raises(SceneError, match="t.pov:1:16: division by zero"):
        value("#declare R = 1 / 0;")


# A vector literal of plain numbers is read in one step (Stream.literal_components); anything else
# token by token. Each case: its value, read with the fast path and without it, and the tokens the
# whole scene read (the token budget counts them the same).
VECTOR_LITERALS = [
    ("<1, 2, 3>", (1.0, 2.0, 3.0)),
    ("<-1, +2, -3.5e1>", (-1.0, 2.0, -35.0)),
    ("<1, 2, 3, 4, 5>", (1.0, 2.0, 3.0, 4.0, 5.0)),
    ("<1, 2>", (1.0, 2.0)),
    ("<1, 2,>", (1.0, 2.0)),  # a trailing comma
    ("<1 2 3>", (1.0, 2.0, 3.0)),  # commas are optional
    ("<1, 2, 3> * 2", (2.0, 4.0, 6.0)),
    ("<1, 2, 3>.y", 2.0),
    ("<1, 2, 3> + <1, 1, 1>.x", (2.0, 3.0, 4.0)),
    ("<1, 2 + 1, 3>", (1.0, 3.0, 3.0)),
    ("<1, (2 > 1), 3>", (1.0, 1.0, 3.0)),
    ("<- -1, 2, 3>", (1.0, 2.0, 3.0)),
    ("<1, 2, 3 > 2>", None),  # '>' closes the vector: then '2 >' is not an expression
    ("<1, 2, 3, 4, 5, 6>", None),  # six components
]


@pytest.mark.parametrize("text, expected", VECTOR_LITERALS)
def test_a_vector_of_plain_numbers_read_at_once_is_the_one_read_token_by_token(monkeypatch, text, expected):
    """As a value, and as a shape's vector argument followed by ',' (a sphere's centre) or '}' (the
    last of a mesh2's vertices), where Stream.literal_vector reads the whole argument at once."""
    from raytracer.sdl._stream import Stream

    def read(fast: bool):
        if not fast:
            monkeypatch.setattr(Stream, "literal_components", lambda self: None)
            monkeypatch.setattr(Stream, "literal_vector", lambda self: None)
        try:
            p = run_sdl(f"#macro M() {text} #end\n#declare R = M();\n#declare S = {text};\n"
                        f"#declare B = sphere {{ {text}, 1 }}\n"
                        f"#declare T = mesh2 {{ vertex_vectors {{ 3, 0, x, {text} }}"
                        " face_indices { 1, <0, 1, 2> } }")
        except SceneError as e:
            return ("error", e.bare_message, e.location)
        finally:
            monkeypatch.undo()
        got = [p.lookup(n) for n in ("R", "S")]
        return ([v.c if hasattr(v, "c") else v for v in got], p.lookup("B").shape["center"],
                p.lookup("T").shape["triangles"][0, 2].tolist(), p.tokens_read)

    fast, slow = read(True), read(False)
    assert fast == slow
    if expected is None:
        assert fast[0] == "error"
    else:
        assert fast[0] == [pytest.approx(expected)] * 2
        as_point = (tuple(expected) + (0.0,) * 3)[:3] if isinstance(expected, tuple) else (expected,) * 3
        assert fast[1] == pytest.approx(as_point) and fast[2] == pytest.approx(as_point)
