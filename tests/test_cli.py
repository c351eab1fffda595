"""The raytracer command: exit codes, messages with file:line:col, images written."""

import os
from pathlib import Path

import numpy as np
import pytest

import raytracer as rt
from raytracer.cli import main

SEED = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "seed.pov"


@pytest.fixture(autouse=True)
def no_compilation_cache(monkeypatch):
    """The CLI turns on JAX's persistent cache in ~/.cache; tests write only under tmp_path."""
    monkeypatch.setenv("RAYTRACER_CACHE_DIR", "off")


def test_info_prints_objects_lights_and_the_plan(capsys):
    assert main(["info", str(SEED)]) == 0
    out = capsys.readouterr().out
    assert "objects: 1 box, 1 sphere" in out
    assert "plan: primitives: box, sphere; effects: shadows, highlights" in out
    assert "depth: 1" in out


def test_the_command_renders_a_filter_written_as_zero_as_opaque(tmp_path, capsys):
    """``load_scene(…, fit_zero_terms=False)``: a sphere written ``rgbf <…, 0>`` plans no
    transmission (the API's default would, so that the 0 can be fitted)."""
    scene = tmp_path / "zero.pov"
    scene.write_text("camera { location -5 * z look_at 0 }\nlight_source { <2, 4, -3> rgb 1 }\n"
                     "sphere { 0, 1 pigment { rgbf <1, 0.5, 0.2, 0> } }\n")
    assert rt.plan(rt.load_scene(scene)).effects.transmission
    assert main(["info", str(scene)]) == 0
    out = capsys.readouterr().out
    assert "plan: primitives: sphere; effects: shadows" in out and "transmission" not in out


def test_info_says_which_csg_objects_the_hierarchy_holds(tmp_path, capsys, monkeypatch):
    from raytracer.shading import _accel

    if _accel.unavailable_reason() is not None:
        pytest.skip(str(_accel.unavailable_reason()))
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    scene = tmp_path / "csg.pov"
    scene.write_text("camera { location -5 * z look_at 0 }\nplane { y, -1 pigment { rgb 1 } }\n"
                     "#for (i, 0, 8) difference { box { -0.4, 0.4 } sphere { 0, 0.5 } translate i * x }\n"
                     "#end\n"
                     "intersection { sphere { 0, 1 } quadric { <1, 1, 0>, 0, 0, -0.5 } }\n")
    assert main(["info", str(scene)]) == 0
    out = capsys.readouterr().out
    # 9 differences of 2 primitives and the quadric's intersection (bounded by its sphere): one
    # item each; the plane stays
    assert "BVH over 20 of 21 primitives (10 items, 10 of them CSG objects of 20 primitives)" in out
    assert "every ray tests the other 1" in out


def test_scene_error_exits_2_with_location_and_no_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.pov"
    bad.write_text("sphere { <0, 0, 0>, 1\n  pigment { color rgb <1, 0, 0> }\n")
    assert main(["info", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:3:1:" in err and "expected" in err
    assert "Traceback" not in err


def test_render_writes_the_image_and_a_summary(tmp_path, capsys):
    out = tmp_path / "seed.exr"
    assert main(["render", str(SEED), "-o", str(out), "-W", "32", "-H", "24"]) == 0
    text = capsys.readouterr().out
    assert "resolution: 32x24" in text and "times: parse" in text
    image = rt.read_image(out)
    assert image.shape == (24, 32, 3)
    # the same render through the Python API (EXR stores float32 exactly); the CLI renders in parts
    # for its progress bar, another program whose float32 rounding differs by ~1e-5 relative
    expected = rt.render(rt.load_scene(SEED, width=32, height=24), width=32, height=24)
    np.testing.assert_allclose(image, np.asarray(expected), rtol=1e-4, atol=1e-6)


def test_unsupported_output_format_is_refused_before_rendering(tmp_path, capsys):
    assert main(["render", str(SEED), "-o", str(tmp_path / "x.gif")]) == 2
    assert "unsupported output format" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_validate_forwards_its_options(capsys):
    assert main(["validate", "--list"]) == 0
    assert "lambert_sphere" in capsys.readouterr().out


def test_info_takes_the_animation_frame_from_an_ini(tmp_path, capsys):
    scene = tmp_path / "anim.pov"
    scene.write_text("#declare N = array[2] {1, 2}\nsphere { 0, N[frame_number - 1] }\n"
                     "#if (frame_number = 2) box { 0, 1 } #end\n")
    ini = tmp_path / "anim.ini"
    ini.write_text("Initial_Frame=1\nFinal_Frame=2\n")
    assert main(["info", str(scene)]) == 2  # frame_number 0 without animation, as in povray
    assert "expected an array index from 0 to 1, found -1" in capsys.readouterr().err
    assert main(["info", str(scene), "--ini", str(ini)]) == 0
    assert "objects: 1 sphere" in capsys.readouterr().out
    assert main(["info", str(scene), "--ini", str(ini), "--frame", "2"]) == 0
    assert "objects: 1 box, 1 sphere" in capsys.readouterr().out


@pytest.mark.parametrize("options, fragment", [
    (["-W", "0"], "-W/--width: expected a positive integer, found 0"),
    (["-W", "-5"], "-W/--width: expected a positive integer, found -5"),
    (["-H", "0"], "-H/--height: expected a positive integer, found 0"),
    (["--spp", "-4"], "--spp: expected a positive integer, found -4"),
    (["--spp", "3"], "--spp: expected a perfect square (1, 4, 9, 16, …), found 3"),
    (["--parse-timeout", "0"], "--parse-timeout: expected a positive number of seconds, found '0'"),
    (["-H", "-" + "9" * 300], "-H/--height: expected a positive integer, found -9.999e+299"),
    (["--aa", "-1"], "--aa: expected a threshold ≥ 0, found '-1'"),
])
def test_bad_numbers_on_the_command_line_are_one_line_errors(options, fragment, tmp_path, capsys):
    code = _exit_code(["render", str(SEED), "-o", str(tmp_path / "x.png"), *options])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and fragment in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def _exit_code(argv) -> int:
    try:
        return main(argv)
    except SystemExit as e:  # argparse exits
        return e.code


@pytest.mark.parametrize("output, fragment", [
    ("folder.png", "it is a folder"),  # -o naming an existing folder
    ("a_file.txt/x.png", "is not a folder"),  # a folder that cannot hold it
    ("missing/x.png", "does not exist"),
])
def test_an_output_that_cannot_be_written_is_refused_before_parsing(output, fragment, tmp_path, capsys):
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "a_file.txt").write_text("not a folder")
    before = sorted(tmp_path.rglob("*"))
    scene = tmp_path / "never_parsed.pov"  # a scene error would show the scene was read first
    scene.write_text("sphere {")
    assert main(["render", str(scene), "-o", str(tmp_path / output)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and fragment in err and "Traceback" not in err
    assert sorted(p for p in tmp_path.rglob("*") if p != scene) == before


def test_an_internal_error_exits_70_in_one_line_and_shows_the_traceback_with_debug(monkeypatch, capsys):
    import raytracer.sdl._interpreter as interpreter

    def broken_camera_builder(p, t):
        raise TypeError("a bug")

    monkeypatch.setattr(interpreter, "parse_camera", broken_camera_builder)
    assert main(["info", str(SEED)]) == 70
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"raytracer: {SEED}:" in err and "internal error" in err and "TypeError: a bug" in err
    assert "--debug" in err
    assert main(["info", str(SEED), "--debug"]) == 70
    err = capsys.readouterr().err
    assert "Traceback" in err and "broken_camera_builder" in err
    assert err.splitlines()[-1].startswith(f"raytracer: {SEED}:")


@pytest.mark.parametrize("suffix", [".png", ".exr"])
def test_written_images_follow_the_umask_not_0600(tmp_path, suffix):
    # the atomic write's temporary file is 0600; the image must be 0666 & ~umask
    import os

    old = os.umask(0o027)
    try:
        rt.write_image(tmp_path / f"img{suffix}", np.full((2, 3, 3), 0.5, np.float32))
    finally:
        os.umask(old)
    assert (tmp_path / f"img{suffix}").stat().st_mode & 0o777 == 0o640
    assert [p.name for p in tmp_path.iterdir()] == [f"img{suffix}"]  # no temporary left behind


def test_all_frames_renders_each_frame_of_the_ini_under_povray_names(tmp_path, capsys):
    scene = tmp_path / "anim.pov"
    # the sphere's brightness follows the clock: each frame is its own image
    scene.write_text("#version 3.7; global_settings { assumed_gamma 1.0 }\n"
                     "camera { location <0, 0, -4> look_at 0 }\n"
                     "light_source { <0, 0, -10> rgb 1 }\n"
                     "sphere { 0, 1 pigment { rgb clock } finish { ambient 0 diffuse 1 } }\n")
    ini = tmp_path / "anim.ini"
    ini.write_text("Initial_Frame=8\nFinal_Frame=10\nInitial_Clock=0\nFinal_Clock=1\n")
    out = tmp_path / "frame.exr"
    assert main(["render", str(scene), "-o", str(out), "-W", "8", "-H", "6", "--ini", str(ini),
                 "--all-frames"]) == 0
    written = sorted(p.name for p in tmp_path.glob("frame*.exr"))
    assert written == ["frame08.exr", "frame09.exr", "frame10.exr"]  # padded to the last frame's digits
    centre = [rt.read_image(tmp_path / name)[3, 4] for name in written]
    # diffuse 1, no ambient: a pixel is the clock (0, 0.5, 1) times the same n·l in every frame
    red = np.array([c[0] for c in centre])
    assert red[2] > 0.5
    np.testing.assert_allclose(red, [0.0, 0.5 * red[2], red[2]], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("options, fragment", [
    (["--all-frames"], "--all-frames needs an animation (--ini, or POV-Ray's frame options)"),
    (["--coordinator", "localhost:1234"], "go together"),
    (["--coordinator", "localhost:1234", "--num-processes", "2", "--process-id", "2"], "must be in 0 … 1"),
])
def test_bad_animation_or_process_options_are_one_line_errors(options, fragment, tmp_path, capsys):
    assert main(["render", str(SEED), "-o", str(tmp_path / "x.png"), *options]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err and err.count("\n") == 1


def test_adaptive_antialiasing_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "seed.exr"
    assert main(["render", str(SEED), "-o", str(out), "-W", "32", "-H", "24", "--aa", "0.3",
                 "--aa-depth", "2"]) == 0
    scene = rt.load_scene(SEED, width=32, height=24)
    want = rt.render(scene, width=32, height=24, adaptive=(0.3, 2))
    np.testing.assert_allclose(rt.read_image(out), np.asarray(want), atol=1e-6)
    assert "times: parse" in capsys.readouterr().out
    # POV-Ray's +AG: a plain sum of differences (gamma 1) refines other pixels of this image
    assert main(["render", str(SEED), "-o", str(out), "-W", "32", "-H", "24", "--aa", "0.3",
                 "--aa-depth", "2", "--aa-gamma", "1"]) == 0
    linear = np.asarray(rt.render(scene, width=32, height=24, adaptive=(0.3, 2, 1.0)))
    assert np.abs(linear - np.asarray(want)).max() > 1e-3
    np.testing.assert_allclose(rt.read_image(out), linear, atol=1e-6)


def test_render_command_sets_one_device_per_core_and_the_tuned_xla_flags(monkeypatch):
    """Before JAX starts, ``raytracer render`` asks XLA for one CPU device per core and, for the
    jaxlib they were measured with, the flags of ``raytracer/_xla.py``; XLA_FLAGS that name a flag
    win, and ``RAYTRACER_TUNE_XLA=0`` adds none."""
    from raytracer import _xla, cli

    monkeypatch.setattr(_xla, "_backends_started", lambda: False)  # this process's backend is running
    monkeypatch.setenv("XLA_FLAGS", "")
    monkeypatch.delenv(_xla.DEVICES_ENV, raising=False)  # (the suite's one device a worker)
    cli._split_cpu(None)
    flags = os.environ["XLA_FLAGS"].split()
    assert f"--xla_force_host_platform_device_count={len(os.sched_getaffinity(0))}" in flags
    known = _xla._jaxlib_version() in _xla.TUNED_JAXLIB
    for name, value in _xla.TUNED_FLAGS.items():
        assert (f"--{name}={value}" in flags) == known
    mine = "--xla_force_host_platform_device_count=3 --xla_cpu_use_fusion_emitters=true"
    monkeypatch.setenv("XLA_FLAGS", mine)
    cli._split_cpu(None)
    assert os.environ["XLA_FLAGS"].startswith(mine)
    assert "--xla_cpu_use_fusion_emitters=false" not in os.environ["XLA_FLAGS"]
    cli._split_cpu(5)  # --cpu-devices 5: replaces the count, keeps the rest
    flags = os.environ["XLA_FLAGS"].split()
    assert "--xla_force_host_platform_device_count=5" in flags
    assert "--xla_cpu_use_fusion_emitters=true" in flags
    assert sum("device_count" in f for f in flags) == 1
    monkeypatch.setenv("XLA_FLAGS", "")
    monkeypatch.setenv("RAYTRACER_TUNE_XLA", "0")
    _xla.tune_xla_flags()
    assert os.environ["XLA_FLAGS"] == ""
    monkeypatch.setenv("RAYTRACER_TUNE_XLA", "1")
    monkeypatch.setattr(_xla, "_backends_started", lambda: True)  # too late: XLA read its flags
    _xla.tune_xla_flags()
    assert os.environ["XLA_FLAGS"] == ""


def test_a_backend_started_without_the_tuned_flags_is_warned_once(monkeypatch):
    """JAX started before ``import raytracer`` (so XLA read no tuned flag): one warning that says
    what to set, for the jaxlib the flags were measured with; none after ``RAYTRACER_TUNE_XLA=0``."""
    import warnings

    from raytracer import _xla

    monkeypatch.setattr(_xla, "_jaxlib_version", lambda: _xla.TUNED_JAXLIB[0])
    monkeypatch.setattr(_xla, "_WARNED", [])
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=false")
    with pytest.warns(RuntimeWarning, match="xla_cpu_experimental_ynn_fusion_type=") as caught:
        _xla.warn_if_untuned()
        _xla.warn_if_untuned()
    assert len(caught) == 1 and "fusion_emitters" not in str(caught[0].message)
    monkeypatch.setattr(_xla, "_WARNED", [])
    monkeypatch.setenv("RAYTRACER_TUNE_XLA", "0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _xla.warn_if_untuned()


def test_povray_switches_render_as_povray_reads_them(tmp_path, capsys, monkeypatch):
    """``raytracer render +W8 +H6 +I… +O… +FE +A0.3 +R2 -D``: the image of the same render, under
    the name given; the options that do not change the image pass without a word."""
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "ball.pov"
    scene.write_text("#version 3.7; global_settings { assumed_gamma 1.0 }\n"
                     "camera { location <0, 0, -4> look_at 0 }\nlight_source { <2, 3, -5> rgb 1 }\n"
                     "sphere { 0, 1 pigment { rgb <1, 0.5, 0.2> } }\n")
    assert main(["render", "+W8", "+H6", "+Iball", "+Oimage", "+FE", "+A0.3", "+R2", "-D", "+V"]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err and "wrote image.exr" in captured.out
    want = rt.render(rt.load_scene(scene, width=8, height=6), width=8, height=6, adaptive=(0.3, 2))
    np.testing.assert_allclose(rt.read_image(tmp_path / "image.exr"), np.asarray(want), atol=1e-6)
    # no output named: the scene's name with the type's suffix, in the current folder
    assert main(["render", "ball.pov", "Width=8", "Height=6", "+FC", "+UA", "+SR2"]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("warning") == 1  # one line, naming each option not followed
    assert "POV-Ray options not followed here: Output_Alpha, Start_Row" in captured.err
    from PIL import Image

    with Image.open(tmp_path / "ball.tga") as tga:
        assert tga.size == (8, 6) and tga.info.get("compression") == "tga_rle"


def test_an_ini_renders_its_animation_frames_under_povray_names(tmp_path, capsys, monkeypatch):
    """``raytracer render anim.ini`` as ``povray anim.ini`` (the layout of POV-Ray's sample INI
    files): the scene named next to the INI, every frame of the subset, the output named by
    ``Output_File_Name`` with the frame number."""
    folder = tmp_path / "anim"
    folder.mkdir()
    (folder / "clocked.pov").write_text(
        "#version 3.7; global_settings { assumed_gamma 1.0 }\ncamera { location <0, 0, -4> look_at 0 }\n"
        "sphere { 0, 1 pigment { rgb clock } finish { ambient 1 diffuse 0 } }\n")
    (folder / "clocked.ini").write_text(
        "Antialias=Off\nInput_File_Name=clocked.pov\nOutput_File_Name=frame\n+w8\n+h6\n"
        "Output_File_Type=N\nInitial_Frame=1\nFinal_Frame=12\nInitial_Clock=0\nFinal_Clock=1.1\n"
        "Subset_Start_Frame=10\nCyclic_Animation=off\nPause_when_Done=off\n")
    monkeypatch.chdir(tmp_path)
    assert main(["render", str(folder / "clocked.ini")]) == 0
    assert "warning" not in capsys.readouterr().err
    written = sorted(p.name for p in tmp_path.glob("frame*.png"))
    assert written == ["frame10.png", "frame11.png", "frame12.png"]
    red = [rt.read_image(tmp_path / name)[3, 4, 0] for name in written]
    np.testing.assert_allclose(red, [0.9, 1.0, 1.0], atol=5e-3)  # clock 0.9, 1.0, 1.1 clipped (8-bit)


def test_version_is_the_installed_packages(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"raytracer {version('raytracer')}"


def test_debug_and_warning_directives_are_shown_with_their_escapes_made_harmless(tmp_path, capsys):
    """``#debug`` and ``#render`` text as POV-Ray prints it, ``#warning`` with its place; a control
    character a scene writes (ESC here) is shown as an escape, not sent to the terminal."""
    scene = tmp_path / "talk.pov"
    scene.write_text('#debug "hello\\n"\n#warning concat("warn ", chr(27), "[31mred")\n'
                     '#render "done\\n"\ncamera { location -3 * z look_at 0 }\nsphere { 0, 1 }\n')
    assert main(["info", str(scene)]) == 0
    err = capsys.readouterr().err
    assert err == f"hello\n{scene}:2:2: warning: warn \\x1b[31mred\ndone\n"
    scene.write_text('#error concat("stop ", chr(27), "[2J")\n')  # ESC [2J would clear the screen
    assert main(["info", str(scene)]) == 2
    err = capsys.readouterr().err
    assert "#error: stop \\x1b[2J" in err and "\x1b" not in err


def test_replacing_an_image_keeps_its_mode_and_its_symbolic_link(tmp_path):
    image = np.full((2, 3, 3), 0.5, np.float32)
    target = tmp_path / "kept.png"
    rt.write_image(target, image)
    target.chmod(0o604)
    link = tmp_path / "link.png"
    link.symlink_to(target)
    rt.write_image(link, np.zeros((2, 3, 3), np.float32))
    assert link.is_symlink() and target.stat().st_mode & 0o777 == 0o604
    assert rt.read_image(target).max() == 0.0  # the link's target was replaced
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.png", "link.png"]


def test_an_image_beyond_float32_is_clamped_with_a_warning_and_nan_is_refused(tmp_path):
    """A float64 render of a colour of 1e90 overflows float32: written as its largest value, the
    pixels counted in a warning; NaN is a bug, and nothing is written."""
    from raytracer.imageio import ImageClampWarning

    image = np.full((2, 3, 3), 0.5)
    image[0, 0] = 1e90
    image[1, 2, 1] = -np.inf
    with pytest.warns(ImageClampWarning, match="2 pixels beyond the largest float32"):
        rt.write_image(tmp_path / "big.exr", image)
    back = rt.read_image(tmp_path / "big.exr")
    assert np.isfinite(back).all() and back[0, 0, 0] == np.finfo(np.float32).max
    image[1, 1, 2] = np.nan
    with pytest.raises(ValueError, match="1 NaN pixels: not written"):
        rt.write_image(tmp_path / "nan.png", image)
    assert not (tmp_path / "nan.png").exists()


def test_a_render_past_the_memory_bound_is_refused_before_the_scene_is_read(tmp_path, capsys, monkeypatch):
    """The estimate (``raytracer/_limits.py``: a base and 7 copies of the image) against
    ``$RAYTRACER_MAX_MEMORY_MB``: 2000×2000 in float32 needs 512 MB + 336 MB; the scene (broken)
    is never parsed, nothing is written; the API refuses it the same way."""
    monkeypatch.setenv("RAYTRACER_MAX_MEMORY_MB", "800")
    scene = tmp_path / "never_parsed.pov"
    scene.write_text("sphere {")
    assert main(["render", str(scene), "-o", str(tmp_path / "big.png"), "-W", "2000", "-H", "2000"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a 2000×2000 render needs about 0.8 GB" in err
    assert "more than 0.8 GB ($RAYTRACER_MAX_MEMORY_MB)" in err and "-W/-H" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["never_parsed.pov"]
    with pytest.raises(rt.SceneError, match="render needs about"):
        rt.render(rt.load_scene(SEED), width=2000, height=2000)
    assert main(["render", str(SEED), "-o", str(tmp_path / "small.png"), "-W", "8", "-H", "6"]) == 0


def test_long_lists_of_lights_and_warnings_are_counted_by_kind_and_shown_in_part(tmp_path, capsys):
    scene = tmp_path / "many.pov"
    scene.write_text("camera { location -5 * z look_at 0 }\n"
                     + "".join(f"light_source {{ <{i}, 5, -5> rgb 0.1 }}\n" for i in range(10))
                     + "sphere { 0, 1 normal { quilted 0.5 } }\n" * 3)
    assert main(["info", str(scene)]) == 0
    out = capsys.readouterr().out
    assert "lights: 10 (10 point), the first 8:\n" in out and "\n  … 2 more\n" in out
    assert out.count("\n  point at") == 8
    assert "warnings: 3\n" in out and out.count("[quilted]") == 3  # a short list: whole


def test_progress_shows_each_phases_time_and_the_traces_eta_only_on_a_terminal(monkeypatch):
    import io
    import sys
    import time

    from raytracer.cli import _Phase, _Progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    for stream, shown in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        with _Phase("parse"):
            time.sleep(1.4)  # shown after a second, with the phase's own elapsed time
        progress = _Progress()
        for done in range(1, 5):
            time.sleep(0.3)
            progress(done, 4)
        out = stream.getvalue()
        assert ("parse: 00:01" in out and "trace" in out and "4/4" in out) == shown, out
        assert shown or out == ""


def test_ctrl_c_ends_a_render_while_xla_compiles(tmp_path):
    """SIGINT during the compile (C++ that does not return to Python) ends the process at once, as
    SIGINT's default action does, and leaves no file."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "never.png"
    env = {**os.environ, "RAYTRACER_CACHE_DIR": "off", "RAYTRACER_TEST_JAX_CACHE": ""}
    proc = subprocess.Popen([sys.executable, "-m", "raytracer.cli", "render", str(SEED), "-o", str(out),
                             "-W", "64", "-H", "48", "--x64"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, env=env)
    try:
        for line in proc.stdout:  # the summary is printed when the compile starts
            if line.startswith("warnings:"):
                break
        time.sleep(0.3)
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == -signal.SIGINT
        assert time.monotonic() - sent < 2.0
    finally:
        proc.kill()
        proc.stdout.close()
    assert list(tmp_path.iterdir()) == []


def test_an_exr_that_cannot_be_written_is_an_io_error_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    """OpenEXR reports a full disk as a RuntimeError (seen on a 64 kB tmpfs: "No space left on
    device"): an I/O error, one line, exit 2, no temporary file left."""
    import OpenEXR

    class Full:
        def __init__(self, *args):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            raise RuntimeError(f'Failed to write pixel data to image file "{path}". No space left on device.')

    monkeypatch.setattr(OpenEXR, "File", Full)
    with pytest.raises(OSError, match="No space left on device"):
        rt.write_image(tmp_path / "a.exr", np.zeros((2, 3, 3), np.float32))
    assert main(["render", str(SEED), "-o", str(tmp_path / "b.exr"), "-W", "8", "-H", "6"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write" in err and "No space left on device" in err
    assert list(tmp_path.iterdir()) == []


FLAT = ("#version 3.7;\nglobal_settings {{ assumed_gamma 1.0 }}\ncamera {{ location -3 * z look_at 0 }}\n"
        "light_source {{ <0, 3, -3> rgb 1 }}\n"
        "sphere {{ 0, 5 pigment {{ rgb {colour} }} finish {{ ambient 1 diffuse 0 }} hollow }}\n")


def _programs_used(monkeypatch) -> list:
    """The compiled programs the renders use, in a process with none loaded yet."""
    from raytracer import _programs

    monkeypatch.setattr(_programs, "_LIVE", {})
    used = []
    made = _programs.compiled
    monkeypatch.setattr(_programs, "compiled", lambda *a: used.append(made(*a)) or used[-1])
    return used


def test_several_scenes_render_in_one_process_into_a_folder_by_one_program(tmp_path, monkeypatch):
    """Two scenes of one structure: each image in the folder under its scene's name, the second
    rendered by the program compiled for the first. The camera is inside a sphere lit by its
    ambient term alone: every pixel is its pigment."""
    used = _programs_used(monkeypatch)
    a, b = tmp_path / "a.pov", tmp_path / "b.pov"
    a.write_text(FLAT.format(colour="<0.2, 0.4, 0.6>"))
    b.write_text(FLAT.format(colour="<0.5, 0.25, 0.125>"))
    out = tmp_path / "out"
    out.mkdir()
    assert main(["render", str(a), str(b), "-o", f"{out}/", "-W", "8", "-H", "6", "+FE"]) == 0
    np.testing.assert_allclose(rt.read_image(out / "a.exr"), np.broadcast_to([0.2, 0.4, 0.6], (6, 8, 3)),
                               rtol=1e-6)
    np.testing.assert_allclose(rt.read_image(out / "b.exr"), np.broadcast_to([0.5, 0.25, 0.125], (6, 8, 3)),
                               rtol=1e-6)
    assert len(used) == 2 and used[0] is used[1]
    with pytest.raises(SystemExit) as stop:  # one file for two images
        main(["render", str(a), str(b), "-o", str(out / "x.png")])
    assert stop.value.code == 2


def test_watch_renders_again_when_the_scene_changes_without_compiling_again(tmp_path, monkeypatch, capsys):
    from raytracer import cli

    used = _programs_used(monkeypatch)
    scene, out = tmp_path / "s.pov", tmp_path / "s.exr"
    scene.write_text(FLAT.format(colour="<0.2, 0.4, 0.6>"))
    polls = []

    def sleep(_):
        polls.append(1)
        if len(polls) == 1:  # an edit that keeps the structure
            scene.write_text(FLAT.format(colour="<0.7, 0.1, 0.3>") + "// edited\n")
        elif len(polls) > 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_sleep", sleep)
    assert main(["render", "--watch", str(scene), "-o", str(out), "-W", "8", "-H", "6"]) == 0
    np.testing.assert_allclose(rt.read_image(out), np.broadcast_to([0.7, 0.1, 0.3], (6, 8, 3)), rtol=1e-6)
    text = capsys.readouterr()
    assert text.out.count("rendering again") == 1 and "watching 1 file" in text.out
    assert "stopped watching" in text.err and len(used) == 2 and used[0] is used[1]
