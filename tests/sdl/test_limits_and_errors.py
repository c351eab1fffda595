"""Errors carry exact locations; runaway scenes stop with a SceneError."""

import pytest

from raytracer.errors import SceneError, SourceLoc
from raytracer.sdl import Limits, load_scene


def error_of(text, **kwargs) -> SceneError:
    with pytest.raises(SceneError) as e:
        load_scene(text, **kwargs)
    return e.value


@pytest.mark.parametrize("text, line, col, fragment", [
    ("sphere { <0,0,0>, 1\n  pigment { color Nope } }", 2, 19, "undeclared identifier 'Nope'"),
    ("sphere { 0, 1 \n bogus }", 2, 2, "expected an object modifier, found 'bogus'"),
    ("sphere { 0, 1", 1, 14, "expected '}' to close the object, found end of file"),
    ("#declare A = <1, 2;", 1, 19, "expected a value, found ';'"),
    ("#if (1)\nsphere{0,1}\n", 3, 1, "expected '#end'"),
    ("#end", 1, 2, "'#end' without an open"),
    ("camera { location 0 fly }", 1, 21, "expected a camera item, found 'fly'"),
    ("#declare A = sin(1, 2);", 1, 14, "expected 1 arguments to sin, found 2"),
    ("#declare A = \"s\" + 1;", 1, 18, "expected a float or vector, found string"),
    ("plane { 0, 1 }", 1, 9, "non-zero plane normal"),
    ("#foo", 1, 2, "expected a directive, found '#foo'"),
])
def test_error_messages_and_locations(text, line, col, fragment):
    e = error_of(text)
    assert e.location == SourceLoc("<string>", line, col)
    assert fragment in str(e)
    assert str(e).startswith(f"<string>:{line}:{col}: ")


def test_error_in_include_reports_the_include_chain(tmp_path):
    (tmp_path / "bad.inc").write_text("#declare A = 1;\n#declare B = A +;\n")
    main = tmp_path / "main.pov"
    main.write_text('\n#include "bad.inc"\n')
    e = error_of(str(main))
    assert e.location == SourceLoc(str(tmp_path / "bad.inc"), 2, 17)
    assert e.include_chain == (SourceLoc(str(main), 2, 2),)
    assert "included from" in str(e)


def test_runaway_while_is_stopped():
    e = error_of("#while (1) #end", limits=Limits(max_loop_iterations=1000))
    assert "1000 iterations" in str(e)
    assert e.location == SourceLoc("<string>", 1, 2)


def test_deep_recursion_is_stopped():
    e = error_of("#macro M(N) M(N + 1) #end M(0)", limits=Limits(max_macro_depth=50))
    assert "nested deeper than 50" in str(e)


def test_recursion_in_an_expression_is_stopped_without_recursion_error():
    e = error_of("#macro M(N) (1 + M(N + 1)) #end #declare A = M(0);")
    assert "nested deeper" in str(e)


def test_include_cycle_is_stopped(tmp_path):
    (tmp_path / "a.inc").write_text('#include "b.inc"\n')
    (tmp_path / "b.inc").write_text('#include "a.inc"\n')
    main = tmp_path / "main.pov"
    main.write_text('#include "a.inc"\n')
    e = error_of(str(main))
    assert "include cycle" in str(e)


def test_unsupported_feature_warns_and_strict_raises():
    text = "sphere { 0, 1 normal { bumps 0.5 } }\nfog { distance 3 }\n" \
           "text { ttf \"timrom.ttf\" \"Hi\" 1, 0 }"
    s = load_scene(text)
    assert [w.feature for w in s.warnings] == ["normal", "fog", "text"]
    assert [w.location.line for w in s.warnings] == [1, 2, 3]
    assert len(s.objects) == 1
    e = error_of(text, strict=True)
    assert e.location == SourceLoc("<string>", 1, 15)


def test_warnings_of_a_declared_value_wait_until_it_is_used():
    declare = ("#declare Bumpy = texture { pigment { rgb 1 } normal { bumps 0.5 } }\n"
               "#declare Copy = Bumpy\n")
    s = load_scene(declare + "sphere { 0, 1 }")
    assert s.warnings == ()  # declared, never used: nothing of it reaches the scene
    load_scene(declare + "sphere { 0, 1 }", strict=True)
    s = load_scene(declare + "sphere { 0, 1 texture { Copy } }\nbox { 0, 1 texture { Bumpy } }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [("normal", 1)]  # once, at its source
    e = error_of(declare + "sphere { 0, 1 texture { Copy } }", strict=True)
    assert e.location == SourceLoc("<string>", 1, 46)


def test_a_macro_local_value_reports_its_warning_when_returned_and_forgets_it_otherwise():
    text = """#macro Bumpy(Used)
        #local T = texture { pigment { rgb 1 } normal { bumps 0.5 } }
        #if (Used) T #else texture { pigment { rgb 1 } } #end
    #end
    #declare I = 0; #while (I < 50) #declare Unused = Bumpy(0); #declare I = I + 1; #end
    """
    s = load_scene(text + "sphere { 0, 1 texture { Unused } }")
    assert s.warnings == ()
    s = load_scene(text + "sphere { 0, 1 texture { Bumpy(1) } }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [("normal", 2)]


def test_standard_textures_include_is_quiet_until_a_bumpy_texture_is_used():
    s = load_scene('#include "textures.inc"\nsphere { 0, 1 pigment { Jade } }')
    assert s.warnings == ()
    s = load_scene('#include "textures.inc"\nsphere { 0, 1 texture { Brushed_Aluminum } }')
    assert {w.feature for w in s.warnings} == {"normal"}


def test_nonexistent_path_is_a_scene_error():
    e = error_of("/no/such/scene.pov")
    assert "no file" in str(e)
