"""Golden token lists and lexer errors."""

import pytest

from raytracer.errors import SceneError, SourceLoc
from raytracer.sdl._lexer import tokenize


def kinds_values(text):
    return [(t.kind, t.value) for t in tokenize(text)]


def test_golden_tokens_of_a_declaration():
    assert kinds_values('#declare A = <1, -2.5>;') == [
        ("op", "#"), ("id", "declare"), ("id", "A"), ("op", "="), ("op", "<"), ("num", 1.0),
        ("op", ","), ("op", "-"), ("num", 2.5), ("op", ">"), ("op", ";"), ("eof", None)]


def test_numbers_in_every_spelling():
    assert [v for k, v in kinds_values("1. .5 1e-3 2E+2 7 0.25e1") if k == "num"] == [
        1.0, 0.5, 0.001, 200.0, 7.0, 2.5]


def test_two_character_operators_and_dot_access():
    assert kinds_values("a<=b>=c!=d V.x") == [
        ("id", "a"), ("op", "<="), ("id", "b"), ("op", ">="), ("id", "c"), ("op", "!="),
        ("id", "d"), ("id", "V"), ("op", "."), ("id", "x"), ("eof", None)]


def test_comments_nest_and_are_dropped():
    assert kinds_values("a /* x /* y */ z */ b // c\nd") == [
        ("id", "a"), ("id", "b"), ("id", "d"), ("eof", None)]


def test_string_escapes():
    (tok, _) = tokenize(r'"a\nb\"c\\d\t"')
    assert tok.value == 'a\nb"c\\d\t'


def test_every_token_has_its_line_and_column():
    toks = tokenize("sphere {\n  <0,0,0>, 1\n}", "f.pov")
    assert toks[0].loc == SourceLoc("f.pov", 1, 1)
    assert toks[2].loc == SourceLoc("f.pov", 2, 3)
    assert toks[-2].loc == SourceLoc("f.pov", 3, 1)


def test_unterminated_comment_is_located_at_its_start():
    with pytest.raises(SceneError) as e:
        tokenize("a\n  /* never closed", "f.pov")
    assert e.value.location == SourceLoc("f.pov", 2, 3)
    assert "expected '*/'" in str(e.value)


def test_unterminated_string_is_located_at_its_start():
    with pytest.raises(SceneError) as e:
        tokenize('x "abc\n', "f.pov")
    assert e.value.location == SourceLoc("f.pov", 1, 3)


def test_stray_character_is_an_error_with_location():
    with pytest.raises(SceneError) as e:
        tokenize("a @", "f.pov")
    assert str(e.value).startswith("f.pov:1:3: expected a token, found character '@'")


def test_a_location_found_from_an_offset_is_the_location_written_out():
    import pickle

    text = 'a\n\n  "é"\n/* x\n y */ c'  # a non-ASCII line: offsets count characters, not bytes
    toks = tokenize(text, "f.pov")
    want = [SourceLoc("f.pov", 1, 1), SourceLoc("f.pov", 3, 3), SourceLoc("f.pov", 5, 7),
            SourceLoc("f.pov", 5, 8)]
    got = [t.loc for t in toks]
    assert got == want
    assert [hash(g) for g in got] == [hash(w) for w in want]
    assert [str(g) for g in got] == ["f.pov:1:1", "f.pov:3:3", "f.pov:5:7", "f.pov:5:8"]
    assert pickle.loads(pickle.dumps(got)) == want
    assert repr(tokenize(text, "f.pov")[1].loc) == "SourceLoc(file='f.pov', line=3, col=3)"
    assert SourceLoc("f.pov", 1, 1) != SourceLoc("f.pov", 1, 2)
