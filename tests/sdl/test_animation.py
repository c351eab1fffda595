"""Animation: the clock and frame_number a scene sees, from arguments or a POV-Ray INI file."""

import pytest

from raytracer.errors import SceneError
from raytracer.sdl import Animation, load_scene

from .conftest import value

NAMES = ("clock", "clock_delta", "clock_on", "frame_number", "initial_frame", "final_frame",
         "initial_clock", "final_clock")


def seen(animation):
    text = "".join(f"#declare V_{n} = {n};\n" for n in NAMES)
    return {n: value(text, f"V_{n}", animation=animation) for n in NAMES}


def test_without_animation_the_clock_is_zero_and_off():
    assert seen(None) == {n: 0.0 for n in NAMES}


def test_clock_of_a_frame_is_linear_between_the_first_and_last_frames():
    a = Animation(frame=3, initial_frame=1, final_frame=5, initial_clock=0.0, final_clock=2.0)
    assert seen(a) == {"clock": 1.0, "clock_delta": 0.5, "clock_on": 1.0, "frame_number": 3.0,
                       "initial_frame": 1.0, "final_frame": 5.0, "initial_clock": 0.0,
                       "final_clock": 2.0}
    # cyclic: the last frame stops one step short of the first frame's clock again
    cyc = Animation(frame=5, initial_frame=1, final_frame=5, final_clock=1.0, cyclic=True)
    assert cyc.clock == pytest.approx(0.8) and cyc.clock_delta == pytest.approx(0.2)


def test_from_ini_reads_key_value_lines_and_switches(tmp_path):
    ini = tmp_path / "a.ini"
    ini.write_text("; comment\nAntialias=On\n+w200\nInitial_Frame=2 ; first\nFinal_Frame=6\n"
                   "Initial_Clock=1\nFinal_Clock=3\n")
    a = Animation.from_ini(ini)
    assert (a.frame, a.initial_frame, a.final_frame, a.clock) == (2, 2, 6, 1.0)
    assert Animation.from_ini(ini, frame=4).clock == 2.0
    ini.write_text("+KFI0 +KFF10 +KI0 +KF5 +KC\n")
    a = Animation.from_ini(ini, frame=10)
    assert (a.initial_frame, a.final_frame, a.cyclic, a.clock) == (0, 10, True, pytest.approx(50 / 11))


def test_a_bad_number_in_the_ini_has_its_location(tmp_path):
    ini = tmp_path / "bad.ini"
    ini.write_text("Initial_Frame=1\nFinal_Frame=ten\n")
    with pytest.raises(SceneError) as e:
        Animation.from_ini(ini)
    assert (e.value.location.line, e.value.location.col) == (2, 13)


def test_an_animated_scene_indexes_its_arrays_with_frame_number():
    text = "#declare R = array[3] {1, 2, 3}\nsphere { 0, R[frame_number - 1] }"
    with pytest.raises(SceneError, match="expected an array index from 0 to 2, found -1"):
        load_scene(text)  # as in povray without its INI: frame_number is 0
    s = load_scene(text, animation=Animation(frame=3, initial_frame=1, final_frame=3))
    assert float(s.objects[0].shape.radius) == 3.0
