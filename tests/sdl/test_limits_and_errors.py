"""Errors carry exact locations; runaway scenes stop with a SceneError."""

import re

import pytest

from raytracer.errors import InternalError, SceneError, SourceLoc
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


def test_a_guarded_self_include_recurses_and_an_unguarded_cycle_stops_at_the_depth(tmp_path):
    """POV-Ray's recursion idiom: a file that includes itself while a counter allows it; a cycle
    without a guard stops at the include depth bound, named."""
    (tmp_path / "rec.pov").write_text(
        '#ifndef (Depth) #declare Depth = 0; #end\n'
        '#if (Depth < 3) #declare Depth = Depth + 1; sphere { Depth * x, 0.3 } #include "rec.pov" #end\n')
    assert len(load_scene(tmp_path / "rec.pov").objects) == 3
    (tmp_path / "a.inc").write_text('#include "b.inc"\n')
    (tmp_path / "b.inc").write_text('#include "a.inc"\n')
    main = tmp_path / "main.pov"
    main.write_text('#include "a.inc"\n')
    e = error_of(str(main))
    assert "include depth exceeds 64" in str(e) and "a cycle without a guard?" in str(e)


def test_unsupported_feature_warns_and_strict_raises():
    text = "sphere { 0, 1 normal { quilted 0.5 } }\nrainbow { angle 42 width 5 }\n" \
           "sor { 4, <0, 0>, <1, 1>, <1, 2>, <0, 3> }"
    s = load_scene(text)
    assert [w.feature for w in s.warnings] == ["quilted", "rainbow", "sor"]
    assert [w.location.line for w in s.warnings] == [1, 2, 3]
    assert len(s.objects) == 1
    e = error_of(text, strict=True)
    assert e.location == SourceLoc("<string>", 1, 24)


def test_warnings_of_a_declared_value_wait_until_it_is_used():
    declare = ("#declare Bumpy = texture { pigment { rgb 1 } normal { quilted 0.5 } }\n"
               "#declare Copy = Bumpy\n")
    s = load_scene(declare + "sphere { 0, 1 }")
    assert s.warnings == ()  # declared, never used: nothing of it reaches the scene
    load_scene(declare + "sphere { 0, 1 }", strict=True)
    s = load_scene(declare + "sphere { 0, 1 texture { Copy } }\nbox { 0, 1 texture { Bumpy } }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [("quilted", 1)]  # once, at its source
    e = error_of(declare + "sphere { 0, 1 texture { Copy } }", strict=True)
    assert e.location == SourceLoc("<string>", 1, 55)


def test_a_warning_read_into_a_value_never_used_is_reported_where_its_source_is_used():
    """``#declare P = f(Land)`` holds Land's warnings for P; when P is never used and Land is,
    they are reported once, at their source (``language/trace2.pov`` lost its isosurface's)."""
    text = ("#declare Bumpy = texture { pigment { rgb 1 } normal { quilted 0.5 } }\n"
            "#declare Unused = texture { Bumpy }\n"
            "#declare Also = texture { Bumpy }\n")
    s = load_scene(text + "sphere { 0, 1 texture { Bumpy } }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [("quilted", 1)]
    s = load_scene(text + "sphere { 0, 1 texture { Unused } } box { 0, 1 texture { Bumpy } }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [("quilted", 1)]  # once


def test_a_macro_local_value_reports_its_warning_when_returned_and_forgets_it_otherwise():
    text = """#macro Bumpy(Used)
        #local T = texture { pigment { rgb 1 } normal { quilted 0.5 } }
        #if (Used) T #else texture { pigment { rgb 1 } } #end
    #end
    #declare I = 0; #while (I < 50) #declare Unused = Bumpy(0); #declare I = I + 1; #end
    """
    s = load_scene(text + "sphere { 0, 1 texture { Unused } }")
    assert s.warnings == ()
    s = load_scene(text + "sphere { 0, 1 texture { Bumpy(1) } }")
    assert [(w.feature, w.location.line) for w in s.warnings] == [("quilted", 2)]


def test_standard_textures_include_is_quiet_until_a_texture_with_a_missing_feature_is_used():
    s = load_scene('#include "textures.inc"\nsphere { 0, 1 pigment { Jade } }')
    assert s.warnings == ()
    s = load_scene('#include "textures.inc"\nsphere { 0, 1 texture { EMBWood1 } }')
    assert {w.feature for w in s.warnings} == {"crand"}


def test_nonexistent_path_is_a_scene_error():
    e = error_of("/no/such/scene.pov")
    assert "no file" in str(e)


@pytest.mark.parametrize("text, col, fragment", [
    # letters and digits outside ASCII (str.isalpha/isdigit accept them, SDL does not)
    ("sphere{0,1 Ø}", 12, "expected a token, found character 'Ø'"),
    ("#declare A = 1٣;", 15, "expected a token, found character '٣'"),
    # counts and sizes that were infinite, or too large for an index
    ("global_settings { max_trace_level 1e309 }", 35, "expected a number within the float range"),
    ("#declare A = array[1e309];", 20, "expected a number within the float range (up to 1.8e308), "
                                       "found 1e309"),
    ("light_source { 0, 1 area_light x,z,1e309,2 }", 36, "expected a number within the float range"),
    ("mesh2 { vertex_vectors { 1e309, <0,0,0> } face_indices { 1, <0,0,0> } }", 26,
     "expected a number within the float range"),
    ("#declare S = str(1,1e309,0);", 20, "expected a number within the float range"),
    ("light_source { 0, 1 area_light x,z,1e300,2 }", 36, "expected an area_light size from -4096 to 4096"),
    ("global_settings { max_trace_level 1e300 }", 35, "expected max_trace_level from"),
    ("polygon { 1e300, <0,0>, <1,0>, <0,1> }", 11, "expected a number of polygon points from 0 to 10000000"),
    ("mesh2 { vertex_vectors { -1, <0,0,0> } face_indices { 1, <0,0,0> } }", 26,
     "expected a number of vertex_vectors entries from 0 to 10000000, found -1"),
    ("#declare A = array[1e308];", 20, "expected an array size from 1 to 2147483647, found 1e+308"),
    ("#declare A = array[100000][100000];", 14,
     "expected at most 16777216 array elements (Limits.max_array_elements), found 10000000000"),
    ("#declare A = array[2];\n#declare B = A[1e300];", 16,
     "expected an array index from 0 to 1, found 1e+300"),
    ("#declare S = chr(1114112);", 14, "expected a Unicode code point in chr() from 0 to 1114111, "
                                       "found 1114112"),
    ("#declare S = str(1, 1e308, 0);", 14, "expected a width in str() from -1000 to 1000, found 1e+308"),
    ("#declare S = str(5, -2147483649, 2);", 14, "expected a width in str() from -1000 to 1000"),
    ('#declare S = substr("abc", 2, 3);', 14, "expected a length in substr() from 0 to 2, found 3"),
    # arithmetic and built-ins that leave the float range (a later count would be infinite)
    ("#declare B = 1e300 * 1e300;", 20, "1e+300 * 1e+300 is outside the float range"),
    ("#declare D = degrees(1e308);", 14, "the result of degrees() is outside the float range"),
    ('#declare D = val("1e400");', 14, "the result of val() is outside the float range"),
])
def test_hostile_numbers_and_characters_are_scene_errors_with_their_location(text, col, fragment):
    e = error_of(text)
    line = text.count("\n") + 1
    assert e.location == SourceLoc("<string>", line, col)
    assert fragment in str(e)


def test_a_count_is_truncated_toward_zero_and_checked_after_truncation(sdl_value):
    assert sdl_value("#declare A = array[1.9]\n#declare R = dimension_size(A, 1);") == 1.0
    assert sdl_value('#declare R = concat(str(7, -2.5, 0.9), chr(65.7));') == "07A"  # str(7, -2, 0), chr(65)
    assert sdl_value("#declare A = array[2] {1, 2}\n#declare R = A[0.9999999999];") == 2.0  # a hair below 1
    e = error_of("#declare A = array[0.5];")
    assert "expected an array size from 1 to 2147483647, found 0.5" in str(e)


def test_messages_shorten_long_integers_and_long_call_chains():
    e = SceneError(f"array index {10**300} out of range", SourceLoc("f.pov", 1, 2))
    assert "array index 1.000e+300 out of range" in str(e)
    assert not re.search(r"\d{21}", str(e))
    e = error_of("#macro M(N)\n  M(N + 1)\n#end\nM(0)")
    lines = str(e).splitlines()
    assert lines[0] == "<string>:2:3: macro calls nested deeper than 150 (runaway recursion in M?)"
    assert lines[1:5] == ["  included from <string>:2:3"] * 4  # the innermost calls
    assert lines[5] == f"  … {len(e.include_chain) - 8} more …"
    assert lines[-1] == "  included from <string>:4:1"  # the outermost: the call in the file
    assert len(lines) == 10 and len(e.include_chain) >= 150


def test_an_internal_failure_is_an_internal_error_with_the_scene_location(monkeypatch):
    import raytracer.sdl._interpreter as interpreter

    def broken_camera_builder(p, t):
        raise TypeError("unsupported operand type(s) for +: 'NoneType' and 'float'")

    monkeypatch.setattr(interpreter, "parse_camera", broken_camera_builder)
    with pytest.raises(InternalError) as e:
        load_scene("sphere { 0, 1 }\ncamera { location -5*z }")
    assert not isinstance(e.value, SceneError)
    assert isinstance(e.value.__cause__, TypeError)  # chained: the traceback is the bug's own
    assert e.value.location == SourceLoc("<string>", 2, 1)
    assert str(e.value).startswith("<string>:2:1: internal error (a bug in raytracer, not in the scene): "
                                   "TypeError: unsupported operand")


def test_include_outside_the_scene_folders_is_refused_without_reading_it(tmp_path):
    # includes are read from the scene's folder, -L folders and POV-Ray's include folder only
    secret = tmp_path / "private" / "secret.inc"
    secret.parent.mkdir()
    secret.write_text("#declare TOP_SECRET = 42;\n")
    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    (scene_dir / "link.inc").symlink_to(secret)
    for include in (str(secret), "../private/secret.inc", "link.inc", "/etc/passwd"):
        main = scene_dir / "main.pov"
        main.write_text(f'\n#include "{include}"\n')
        with pytest.raises(SceneError) as e:
            load_scene(main)
        message = str(e.value)
        assert "outside the folders a scene may read" in message and "-L" in message
        assert f"{main}:2:" in message and "TOP_SECRET" not in message and "root:" not in message
    # -L widens it; a file in the scene's folder or a sub-folder of it is always allowed
    main.write_text('#include "secret.inc"\n#include "sub/ok.inc"\n')
    (scene_dir / "sub").mkdir()
    (scene_dir / "sub" / "ok.inc").write_text("#declare OK = 1;\n")
    load_scene(main, include_paths=[secret.parent])


def test_runaway_strings_and_written_files_stop_at_their_limits():
    # doubling a string 34 times reached 6.4 GB; a written file has its own,
    # larger limit (POV-Ray's meshcam_persp_demo.pov writes 17 M characters at 640×480)
    assert Limits().max_written_chars > 17_000_000
    limits = Limits(max_string_length=4096, max_written_chars=4096)
    e = error_of('#declare S = "ab";\n#for (I, 1, 34) #declare S = concat(S, S); #end', limits=limits)
    assert "Limits.max_string_length" in str(e) and "concat() would make 8192" in str(e)
    assert e.location.line == 2
    e = error_of('#fopen F "out.inc" write\n#for (I, 1, 1000) #write (F, "0123456789") #end', limits=limits)
    assert '#write to "out.inc" would make 4100' in str(e) and "Limits.max_written_chars" in str(e)
    assert e.location.line == 2
    # a string at the limit is fine, and reopening a file for writing starts it again
    load_scene('#declare S = "ab"; #for (I, 1, 11) #declare S = concat(S, S); #end\n'  # 4096 characters
               '#fopen F "o.inc" write #write (F, S) #fclose F\n'
               '#fopen F "o.inc" write #write (F, S) #fclose F', limits=limits)


def test_a_parse_past_its_time_limit_stops_with_a_located_error():
    # a loop that is legal but slow (10^6 iterations, each a few tokens) stops at
    # the clock, wherever it is, with the limit named
    e = error_of("#declare I = 0;\n#while (I < 1000000) #declare I = I + 1; #end",
                 limits=Limits(max_parse_seconds=0.2))
    assert "more than 0.2 s to parse" in str(e) and "--parse-timeout" in str(e)
    assert e.location.line == 2


def test_a_parse_that_accumulates_memory_stops_with_a_located_error():
    # every value within its own limit (strings of 131,072 characters), but 3,000
    # of them kept in an array: the growth of resident memory is checked with the clock
    text = ('#declare S = "ab"; #for (I, 1, 16) #declare S = concat(S, S); #end\n'
            '#declare A = array[3000];\n#for (J, 0, 2999) #declare A[J] = concat(S, str(J, 0, 0)); #end')
    e = error_of(text, limits=Limits(max_parse_memory_mb=64))
    assert "grew memory by more than 64 MB" in str(e) and "Limits.max_parse_memory_mb" in str(e)
    assert e.location.line == 3
    # a few tokens that ask for much: each array is checked as it is made, the one past the bound
    # named (8 MB of list slots each: the fifth reaches 40 MB of a 36 MB bound)
    many = "\n".join(f"#declare A{i} = array[1000000];" for i in range(8))
    e = error_of(many, limits=Limits(max_parse_memory_mb=36))
    assert "would grow memory by more than 36 MB here (8 MB more asked" in str(e)
    assert e.location.line <= 5


@pytest.mark.parametrize("text, line, fragment", [
    # found by benchmarks/fuzz.py: values beyond float32 are located at their statement, not at
    # objects and the camera only (global_settings { adc_bailout 1e308 } was an internal error)
    ("global_settings {\n adc_bailout 1e308 }", 1, "float32's range"),  # at the statement
    ("camera { location -5*z look_at 0 }\nbackground { rgb 1e308 }", 2, "float32's range"),
    # location <0, 0, -1e-320> differs from look_at 0 in float64 (the parser's check passed) but is 0
    # in float32: the camera model's ValueError was an internal error
    ("\ncamera { location <0, 0, -1e-320> look_at <0, 0, 0> }", 2, "look_at equals its location"),
])
def test_a_value_float32_cannot_tell_apart_is_an_error_at_its_statement(text, line, fragment):
    import jax

    if jax.config.jax_enable_x64:
        pytest.skip("float64 holds these values")
    e = error_of(text)
    assert fragment in str(e) and "--x64" in str(e) and e.location.line == line


def test_a_file_name_too_long_for_the_system_is_a_located_error_of_bounded_length(tmp_path):
    # found by benchmarks/fuzz.py: Path.is_file raised OSError (ENAMETOOLONG) out of the include
    # search, an internal error; and the message echoed all 5,000 characters of the name
    main = tmp_path / "main.pov"
    main.write_text('\n#include "' + "A" * 5000 + '"\n')
    with pytest.raises(SceneError) as e:
        load_scene(main)
    assert e.value.location.line == 2 and "characters left out" in str(e.value)
    assert len(str(e.value)) < 1200


@pytest.mark.parametrize("text, line, fragment", [
    # found by benchmarks/fuzz.py; POV-Ray 3.7 refuses both: "Must have at least one color in color
    # map" (we raised an IndexError while building), "gamma value must be positive" (we rendered
    # infinities: img ** -2147483649)
    ("sphere { 0, 1\n pigment { gradient y color_map { } } }", 2, "at least one [value colour] entry"),
    ("global_settings {\n assumed_gamma -2147483649 }", 2, "expected a positive assumed_gamma"),
    # POV-Ray: "Must have at least one entry in map" (we accepted them with the "approximated" warning)
    ("sphere { 0, 1\n pigment { gradient y pigment_map { } } }", 2, "one [value …] entry in pigment_map"),
    ("sphere { 0, 1 normal {\n gradient y normal_map { } } }", 2, "one [value …] entry in normal_map"),
    ("sphere { 0, 1 texture {\n gradient y texture_map { } } }", 2, "one [value …] entry in texture_map"),
    # POV-Ray: "Camera location and look_at point must be different" (we raised a ValueError)
    ("\ncamera { location <0, 1, 0> look_at <0, 1, 0> }", 2, "look_at point different from its location"),
])
def test_scenes_povray_refuses_are_located_errors_not_internal_ones(text, line, fragment):
    e = error_of(text)
    assert fragment in str(e) and e.location.line == line


def test_a_value_beyond_float32_is_an_error_at_its_object_not_an_infinite_image():
    # found by benchmarks/fuzz.py: finish { ambient 1e308 } became inf when cast to float32 and
    # the image was infinite; POV-Ray computes in float64. In float32 it is refused where it is
    # used, naming float64 as the way to load it
    import jax

    text = "camera { location <0, 1, -5> look_at 0 }\n\nsphere { 0, 1 finish { ambient 1e308 } }"
    if not jax.config.jax_enable_x64:
        e = error_of(text)
        assert e.location.line == 3 and "float32's range" in str(e) and "--x64" in str(e)
    with jax.enable_x64(True):
        assert load_scene(text).objects[0].texture.layers[0].finish.ambient[0] == 1e308


@pytest.mark.parametrize("text, fragment, col", [
    # POV-Ray 3.7: "Viewing angle has to be smaller than 180 degrees."
    ("camera { location -5*z look_at 0 angle 180 }", "viewing angle below 180 degrees, found 180", 40),
    # POV-Ray 3.7: "Your scene file requires POV-Ray version 3.71 or later!"
    ("#version 3.71;", "expected a #version of at most 3.7", 2),
])
def test_what_povray_refuses_is_refused_where_it_is_written(text, fragment, col):
    e = error_of(text)
    assert fragment in str(e) and e.location.col == col


def test_a_max_trace_level_above_256_is_warned_and_held_at_256_as_povray_does():
    s = load_scene("global_settings { max_trace_level 1e6 }\nsphere { 0, 1 }")
    assert [w.feature for w in s.warnings] == ["max_trace_level"]
    assert "256 but 1000000 was specified" in s.warnings[0].message
    assert int(s.settings.max_trace_level) == 256


def test_csg_nested_past_its_bound_is_a_located_error_written_or_built_by_a_loop():
    deep = "union { " * 6 + "sphere { 0, 1 }" + " sphere { x, 1 } }" * 6
    assert load_scene(deep, limits=Limits(max_csg_depth=6)).objects
    e = error_of(deep, limits=Limits(max_csg_depth=5))
    assert "CSG objects nested deeper than 5" in str(e) and e.location.col == 1  # the outermost union
    looped = ("#declare U = sphere { 0, 1 }\n"
              "#for (I, 1, 300) #declare U = intersection { object { U } sphere { 0, 2 } } #end")
    e = error_of(looped)
    assert "nested deeper than 256" in str(e) and e.location.line == 2


def test_a_matrix_is_mended_or_refused_as_povray_does():
    """Found by rendering with POV-Ray 3.7: a zero column of the 3×3 gets a 1 on its diagonal, with
    POV-Ray's warning (the image is then POV-Ray's); a matrix still singular is refused."""
    s = load_scene("sphere { 0, 1 matrix <1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0> }")
    assert [w.feature for w in s.warnings] == ["matrix"]
    e = error_of("sphere { 0, 1 matrix <1, 0, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0> }")
    assert "expected an invertible matrix" in str(e) and e.location.col == 15


def test_a_single_word_names_a_file_and_a_bad_render_size_says_what_it_takes():
    """``load_scene("myscene")`` is a missing file, not an undeclared identifier; scene text has more
    than one word (or braces). ``render(width=2.5)`` names the argument."""
    import raytracer as rt

    with pytest.raises(SceneError, match='found no file "myscene"'):
        load_scene("myscene")
    assert len(load_scene("sphere{0,1}").objects) == 1
    with pytest.raises(ValueError, match="width must be a positive int, got 2.5"):
        rt.render(load_scene("sphere { 0, 1 }"), width=2.5, height=3)


_SCALED = ("#declare S = {};\ncamera {{ location <0, 0, -8> * S look_at 0 }}\nsphere {{ 0, 2 * S }}\n"
           "box {{ -2 * S, <2, 0.2, 2> * S rotate <-20, 30, 0> }}\n")
_AROUND = "camera { location <0, 1, -5> look_at 0 }\nsphere { 0, 1 }\nsphere { <0, %s, 0>, 1e6 }\n"


@pytest.mark.parametrize("text, fragment", [
    (_SCALED.format(1e-3), "the objects span 0.0094 units: float32 is too coarse below 0.02"),
    (_SCALED.format(1.0), None),
    (_SCALED.format(1e5), None),  # 60 dB from float64: not worth a word
    (_SCALED.format(1e6), "objects lie 6e+06 units from the camera"),
    (_AROUND % "-1e6", "the camera is 1 units from an object whose numbers reach 3.5e+06"),  # a ground
    (_AROUND % "0", None),  # a sky dome around the camera: seen from as far as it is large
])
def test_a_scene_float32_cannot_hold_is_warned_with_the_fix(text, fragment, x64):
    """The thresholds measured in ``raytracer/scene/_precision.py``; float64 never warns."""
    import jax

    with jax.enable_x64(False):
        found = [w.message for w in load_scene(text).warnings if w.feature == "precision"]
    assert len(found) == (fragment is not None), found
    assert fragment is None or (fragment in found[0] and "--x64" in found[0])
    assert not [w for w in load_scene(text).warnings if w.feature == "precision"]  # float64
