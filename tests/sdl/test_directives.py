"""Directives: declarations, conditionals, loops, switch, macros, includes, messages."""

import logging

import pytest

from raytracer.errors import SceneError

from .conftest import run_sdl, value


def test_if_elseif_else():
    text = "#declare A = {}; #if (A = 1) #declare R = 10; #elseif (A = 2) #declare R = 20; " \
           "#else #declare R = 30; #end"
    assert [value(text.format(a)) for a in (1, 2, 3)] == [10.0, 20.0, 30.0]


def test_nested_if_in_a_skipped_branch_is_skipped_whole():
    text = "#if (0) #if (1) #declare R = 1; #else #declare R = 2; #end #else #declare R = 3; #end"
    assert value(text) == 3.0


def test_ifdef_ifndef_and_undef():
    text = """#declare A = 1; #ifdef (A) #declare R = 1; #end #undef A
              #ifndef (A) #declare R = R + 10; #end"""
    assert value(text) == 11.0


def test_while_loop():
    assert value("#declare R = 0; #declare I = 0; #while (I < 5) #declare R = R + I; "
                 "#declare I = I + 1; #end") == 10.0


def test_for_loop_with_step():
    assert value("#declare R = 0; #for (I, 10, 0, -2) #declare R = R + I; #end") == 30.0


def test_break_leaves_the_innermost_loop():
    assert value("#declare R = 0; #while (1) #declare R = R + 1; #if (R = 3) #break #end #end") == 3.0


def test_switch_case_range_and_fall_through():
    text = """#declare R = 0;
    #switch ({})
      #case (1) #declare R = 1; #break
      #range (2, 4) #declare R = 2;
      #case (3) #declare R = R + 10; #break
      #else #declare R = 99;
    #end"""
    # manual 3.3.2.6.4: without #break, parsing falls through to the next clause, whose condition
    # is evaluated (false for 2, so it skips on to #else, which matches anything)
    assert [value(text.format(v)) for v in (1, 2, 3, 7)] == [1.0, 99.0, 12.0, 99.0]


def test_missing_semicolon_does_not_run_the_next_directive_early():
    assert value("#declare A = 1 #declare R = A + 1") == 2.0


def test_macro_returns_a_value_and_recurses():
    text = """#macro Fact(N) #if (N <= 1) 1 #else N * Fact(N - 1) #end #end
              #declare R = Fact(5);"""
    assert value(text) == 120.0


def test_macro_locals_vanish_and_declare_reaches_global():
    text = """#declare G = 0;
    #macro M(A) #local L = A * 2; #declare G = L; #end
    M(21)
    #ifdef (L) #declare R = -1; #else #declare R = G; #end"""
    assert value(text) == 42.0


def test_macro_parameter_passed_by_reference_is_modified():
    text = "#macro Inc(V) #declare V = V + 1; #end #declare R = 1; Inc(R) Inc(R)"
    assert value(text) == 3.0


def test_local_inside_macro_shadows_caller_variable():
    text = "#declare R = 5; #macro M() #local R = 7; #end M()"
    assert value(text) == 5.0


def test_declare_updates_the_local_of_an_enclosing_include(tmp_path):
    (tmp_path / "inc.inc").write_text(
        "#local D = 1;\n#macro Bump() #declare D = D + 1; #end\nBump()\n#declare R = D;\n")
    main = tmp_path / "main.pov"
    main.write_text('#include "inc.inc"\n#ifdef (D) #declare R = -1; #end\n')
    p = run_sdl(main.read_text(), include_paths=[tmp_path])
    assert p.lookup("R") == 2.0  # the include's local D was incremented, then vanished


def test_local_in_main_file_is_global():
    assert value("#local R = 3;") == 3.0


def test_macro_returning_an_object_builds_it():
    p = run_sdl("#macro Ball(R) sphere { 0, R } #end object { Ball(2) } Ball(3)")
    assert [rec.shape["radius"] for rec in p.items] == [2.0, 3.0]


def test_version_directive_changes_version_mid_file():
    text = ("#declare V0 = version; #version 3.5; #declare V1 = version; #version V0;"
            "#declare R = <V1, version>;")
    assert value(text) == pytest.approx((3.5, 3.7))


def test_debug_and_warning_go_to_the_logger(caplog):
    with caplog.at_level(logging.INFO, logger="raytracer.sdl"):
        run_sdl('#debug "hello\\n" #warning "careful"')
    records = [(r.getMessage(), r.levelno) for r in caplog.records]
    assert any("hello" in m for m, _ in records)
    assert any("careful" in m and level == logging.WARNING for m, level in records)


def test_error_directive_raises_with_location():
    with pytest.raises(SceneError) as e:
        run_sdl('sphere { 0, 1 }\n  #error "stop here"')
    assert str(e.value).startswith("t.pov:2:4: #error: stop here")


def test_reading_files_from_disk_is_refused(tmp_path):
    data = tmp_path / "data.txt"
    data.write_text("1, 2, 3")
    with pytest.raises(SceneError, match="refused"):
        run_sdl(f'#fopen F "{data}" read')


@pytest.mark.parametrize("directive", ['#read (F, A)', '#write (F, "x")'])
def test_file_io_needs_an_open_file(directive):
    with pytest.raises(SceneError, match="not an open file"):
        run_sdl(directive)


def test_written_files_live_in_memory_and_can_be_included_and_read(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = run_sdl('#fopen F "gen.inc" write\n'
                '#write (F, "#declare N = ", 7, ";\\n", "#declare V = ", <1, 2, 3>, ";\\n")\n'
                '#fclose F\n#include "gen.inc"\n'
                '#fopen F "nums.txt" write\n#write (F, 4, ",", 5)\n#fclose F\n'
                '#fopen G "nums.txt" read\n#read (G, A, B)\n#fclose G\n')
    assert p.lookup("N") == 7
    assert tuple(p.lookup("V").c[:3]) == (1, 2, 3)
    assert (p.lookup("A"), p.lookup("B")) == (4, 5)
    assert list(tmp_path.iterdir()) == []  # nothing touched the file system


def test_include_search_order(tmp_path, monkeypatch):
    own, extra, env = (tmp_path / d for d in ("own", "extra", "env"))
    for d in (own, extra, env):
        d.mkdir()
    (extra / "a.inc").write_text("#declare A = 2;")
    (env / "a.inc").write_text("#declare A = 3;")
    (env / "b.inc").write_text("#declare B = 3;")
    main = own / "main.pov"
    main.write_text('#include "a.inc"\n#include "b.inc"\n#include "colors.inc"\n')
    monkeypatch.setenv("RAYTRACER_INCLUDE_PATH", str(env))
    from raytracer.sdl._interpreter import Interpreter

    def symbols():
        p = Interpreter(include_paths=[extra])
        p.push_main(p.file_tokens(str(main)), str(main))
        p.run()
        return p.lookup("A"), p.lookup("B"), p.lookup("Red") is not None

    assert symbols() == (2.0, 3.0, True)  # include_paths before the env var, POV folder last
    (own / "a.inc").write_text("#declare A = 1;")
    assert symbols()[0] == 1.0  # the including file's folder comes first


def test_missing_include_is_an_error_with_location():
    with pytest.raises(SceneError) as e:
        run_sdl('\n #include "no_such_file.inc"')
    assert e.value.location.line == 2 and e.value.location.col == 3
    assert "no_such_file.inc" in str(e.value)


def test_default_texture_applies_to_later_objects():
    from raytracer.sdl import load_scene

    s = load_scene("#default { finish { ambient 0.5 } } sphere { 0, 1 }")
    assert float(s.objects[0].texture.layers[0].finish.ambient[0]) == pytest.approx(0.5)


DEFAULT_AT_PLACEMENT = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -6> look_at 0 right x*4/3 }
light_source { <2, 4, -5> rgb 1 }
background { rgb <0.1, 0.2, 0.3> }
#declare Bare = sphere { <-2, 1, 0>, 0.9 }
#declare FinishOnly = sphere { <0, 1, 0>, 0.9 finish { ambient 0.5 diffuse 0.3 } }
#default { texture { pigment { rgb <1, 0, 0> } } }
#declare InUnion = union { object { Bare translate -2*y } sphere { <0, -1, 0>, 0.9 } }
#default { texture { pigment { rgb <0, 1, 0> } finish { ambient 0.3 } } }
object { Bare }
object { FinishOnly }
object { InUnion }
union {
  sphere { <2, 1, 0>, 0.9 }
  #default { texture { pigment { rgb <0, 0, 1> } } }
  sphere { <2, -1, 0>, 0.9 }
}
"""


@pytest.mark.povray
def test_default_texture_is_the_one_current_when_the_object_is_placed(tmp_path):
    # measured with povray 3.7: an object without texture takes the #default of
    # the end of its top-level statement (Bare and InUnion green, the last union's spheres both
    # blue); a partial texture is completed from the #default of when it was written
    # (FinishOnly black)
    import numpy as np

    import raytracer as rt
    from validation import metrics
    from validation.povray import render_povray

    path = tmp_path / "default.pov"
    path.write_text(DEFAULT_AT_PLACEMENT)
    ours = np.asarray(rt.render(rt.load_scene(path), width=32, height=24))
    assert metrics.psnr(ours, render_povray(path, 32, 24)) >= 40.0  # measured 86 dB (12 dB before)


def test_conditional_inside_a_declaration():
    assert value("#declare R = #if (0) 1 #else 2 #end;") == 2.0


def test_loop_end_after_a_declaration_without_semicolon_runs_after_it():
    assert value("#declare R = 0; #while (R < 3) #declare R = R + 1 #end") == 3.0


def test_write_items_need_no_commas_and_ifdef_takes_array_elements(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = run_sdl('#declare A = array[3]\n#declare A[1] = 5;\n'
                '#ifdef (A[1]) #declare One = 1; #end\n#ifdef (A[2]) #declare Two = 1; #end\n'
                '#fopen F "g.inc" write\n#write (F "#declare W = " 3 ";")\n#fclose F\n'
                '#include "g.inc"\n')
    assert p.lookup("One") == 1 and p.lookup("W") == 3
    assert p.lookup("Two") is None


def test_included_files_are_lexed_once_per_text(tmp_path):
    """Parses share the tokens of an unchanged include file; a file rewritten with text of the
    same size within the file system's clock tick is lexed again (the key is its text)."""
    from raytracer.sdl import _stream

    inc, main = tmp_path / "a.inc", tmp_path / "main.pov"
    inc.write_text("#declare A = 1;")
    main.write_text('#include "a.inc"\n')

    def load():
        from raytracer.sdl._interpreter import Interpreter

        p = Interpreter()
        p.push_main(p.file_tokens(str(main)), str(main))
        p.run()
        return p.lookup("A"), p.file_tokens(str(inc))

    a1, toks1 = load()
    a2, toks2 = load()
    assert (a1, a2) == (1.0, 1.0) and toks1 is toks2  # the same list: not lexed again
    inc.write_text("#declare A = 2;")  # same size, same mtime tick most likely
    a3, toks3 = load()
    assert a3 == 2.0 and toks3 is not toks1
    assert len(_stream._LEXED) >= 2
