"""POV-Ray's options (``raytracer.sdl._options``): switches and INI keys as POV-Ray's manual and
``man povray`` define them, read in order with the last winning, and what is not followed named."""

import pytest

from raytracer.errors import SceneError
from raytracer.sdl._options import read_ini, read_options


@pytest.mark.parametrize("words, want", [
    (["+W640", "+H480"], {"width": 640, "height": 480}),
    (["-w320", "Height=200"], {"width": 320, "height": 200}),  # + and - alike for values, any case
    (["+Iscene.pov", "+Oout"], {"input": "scene.pov", "output": "out"}),
    (["+A"], {"antialias": True, "threshold": None}),
    (["+A0.2", "+R4", "+AG1"], {"antialias": True, "threshold": 0.2, "depth": 4, "aa_gamma": 1.0}),
    (["+A0.2", "-A"], {"antialias": False, "threshold": 0.2}),  # the last wins
    (["Antialias=On", "Antialias_Threshold=0.1", "Antialias_Depth=2"],
     {"antialias": True, "threshold": 0.1, "depth": 2}),
    (["+FN16"], {"output_type": "N", "bits": 16}),
    (["+FE"], {"output_type": "E", "bits": None}),
    (["Output_File_Type=c", "Bits_Per_Color=8"], {"output_type": "C", "bits": 8}),
    (["+L/a", "Library_Path=/b", "+L/c"], {"library_paths": ["/a", "/b", "/c"]}),  # adds up
    (["+KFI2", "+KFF9", "+KI0.5", "+KF1.5", "+KC"],
     {"initial_frame": 2, "final_frame": 9, "initial_clock": 0.5, "final_clock": 1.5, "cyclic": True}),
    (["+K0.25"], {"clock": 0.25}),
    (["+SF3", "+EF5"], {"subset_start": 3, "subset_end": 5}),
    # no preview window, no pause, no effect on the image: accepted without a word
    (["-D", "-P", "+V", "+X", "+X100", "Pause_When_Done=on", "Work_Threads=4", "+Q9", "+AM1", "-J"],
     {"ignored": []}),
    # they would change the image (or the run) and are not followed: named once each, in order
    (["+D", "+SR10", "Start_Row=10", "+J0.5", "+UA", "+Q3", "+AM2", "-F", "Fancy_Option=1", "+Zz"],
     {"ignored": ["Display", "Start_Row", "Jitter", "Output_Alpha", "Quality", "Sampling_Method",
                  "Output_to_File", "Fancy_Option", "+Zz"]}),
])
def test_switches_and_keys_set_what_povray_sets(words, want):
    opts = read_options(words)
    assert {k: getattr(opts, k) for k in want} == want


@pytest.mark.parametrize("word, fragment", [
    ("+W0", "+W0: expected a whole number ≥ 1, found '0'"),
    ("+Wide", "expected a whole number ≥ 1, found 'ide'"),
    ("+H", "expected a value after +H"),
    ("+A-1", "expected a number ≥ 0, found '-1'"),
    ("+FH", "output type H (Radiance HDR) is not written here"),
    ("+P3", "expected nothing after +P, found '3'"),
    ("Antialias=maybe", "expected on or off, found 'maybe'"),
])
def test_a_bad_switch_is_named_in_a_one_line_error(word, fragment):
    with pytest.raises(SceneError) as e:
        read_options([word])
    assert fragment in str(e.value) and "\n" not in str(e.value)


def test_an_ini_file_reads_its_lines_sections_and_the_files_it_names(tmp_path):
    (tmp_path / "base.ini").write_text("Width=100\nLibrary_Path=/lib1\n")
    (tmp_path / "scene.ini").write_text(
        "; a comment\n// another\nbase.ini\nInput_File_Name=\"my scene.pov\" ; quoted\n"
        "+h50 +A0.4\nWidth=120\n\n[small]\nWidth=20\n+H15\n[big]\nWidth=2000\n")
    opts = read_options([str(tmp_path / "scene.ini")])
    # before the first section only; base.ini read where it is named; the later Width wins
    assert (opts.width, opts.height, opts.threshold, opts.input) == (120, 50, 0.4, "my scene.pov")
    assert opts.library_paths == ["/lib1"] and opts.input_base == str(tmp_path)
    opts = read_options([str(tmp_path / "scene.ini") + "[small]", "+W30"])
    assert (opts.width, opts.height) == (30, 15)  # the section, then the command line's +W30
    opts = read_options([str(tmp_path / "scene.ini") + "[BIG]"])
    assert opts.width == 2000  # section labels are not case sensitive


def test_a_bad_value_or_a_binary_file_in_an_ini_has_its_location(tmp_path):
    ini = tmp_path / "bad.ini"
    ini.write_text("Width=100\n  Height = tall\n")
    with pytest.raises(SceneError) as e:
        read_ini(ini, read_options([]))
    assert (e.value.location.line, e.value.location.col) == (2, 12)
    assert "expected a whole number ≥ 1, found 'tall'" in str(e.value)
    ini.write_text("+W100 +Hx\n")
    with pytest.raises(SceneError) as e:
        read_ini(ini, read_options([]))
    assert (e.value.location.line, e.value.location.col) == (1, 7)
    binary = tmp_path / "image.ini"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR")
    with pytest.raises(SceneError, match="not an INI file"):
        read_options([str(binary)])
    loop = tmp_path / "loop.ini"
    loop.write_text("loop.ini\n")
    with pytest.raises(SceneError, match="more than 16 deep"):
        read_options([str(loop)])
