"""Smoke tests of the benchmark entry points: they run on a tiny setting and write well-formed files.

Nothing here checks a time: speed is measured by ``benchmarks/``, never asserted in a test.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from benchmarks import accuracy, sample_renders, scaling, speed
from benchmarks._common import SCENES, md_table, scene_variant


def test_benchmark_scenes_exist_and_load():
    from raytracer import load_scene

    for name, path in SCENES.items():
        assert path.is_file(), name
        scene = load_scene(path, width=16, height=12)
        assert scene.objects, name


def test_scene_variant_rewrites_depth_and_area_samples(tmp_path):
    whitted = scene_variant(SCENES["whitted"], tmp_path, max_trace_level=7)
    assert "max_trace_level 7" in whitted.read_text()
    assert whitted.parent == tmp_path
    area = scene_variant(SCENES["area"], tmp_path, area_samples=4)
    assert ", 4, 4 adaptive" in area.read_text()
    assert scene_variant(SCENES["seed"], tmp_path) == SCENES["seed"]  # nothing to rewrite: the file itself
    with pytest.raises(ValueError, match="area_light"):
        scene_variant(SCENES["seed"], tmp_path, area_samples=3)


def test_povray_times_on_its_millisecond_clock_give_the_durations_median():
    """A duration d read as the difference of two readings of a clock of 1 ms ticks reads ⌊d⌋ or
    ⌈d⌉ ms as the phase falls: the grouped-data median recovers d to 0.09 of a tick (plus sampling
    noise; the readings' plain median is a whole tick, up to half a tick off); a reading off the
    grid (a finer clock) gives the plain median."""
    from benchmarks._worker import quantized_median

    assert quantized_median([0.002] * 7 + [0.003] * 4) == pytest.approx(0.0015 + 5.5 / 7 * 1e-3)
    rng = np.random.default_rng(0)
    for d in (0.7, 1.3, 2.36, 2.7, 5.5):
        phase = rng.uniform(0, 1, 4001)
        readings = (np.floor(phase + d) - np.floor(phase)) * 1e-3
        assert abs(np.median(readings) * 1e3 - d) > 0.25  # a whole tick: off by a quarter tick or more
        assert quantized_median(readings.tolist()) * 1e3 == pytest.approx(d, abs=0.12)
    assert quantized_median([0.0] * 3) == 0.0
    assert quantized_median([0.0123, 0.0456, 0.02]) == 0.02


def test_markdown_table_has_one_row_per_entry():
    table = md_table(["a", "b"], [[1, 0.000123], ["x", None]])
    lines = table.splitlines()
    assert len(lines) == 4
    assert lines[2] == "| 1 | 0.000123 |"
    assert lines[3] == "| x | – |"


def _fake_row(renderer, scene, time_s, rmse):
    err = {"rmse": rmse, "max_err": 10 * rmse}
    return {
        "renderer": renderer,
        "scene": scene,
        "setting": f"spp {int(time_s * 10)}",
        "params": {},
        "width": 16,
        "height": 12,
        "compile_s": 1.0,
        "time_s": time_s,
        "peak_mb": 100.0,
        "reference": "converged",
        "rmse": rmse,
        "max_err": 10 * rmse,
        "errors": {"converged": err, "povray_aa65": err},
        "cpu_s": time_s,
        "runs": 3,
        "reference_floor": {"converged": {"rmse": 0.0, "max_err": 0.0}, "povray_aa65": err},
    }


def test_plot_and_tables_from_rows(tmp_path):
    rows = [
        _fake_row(r, s, t, e)
        for s in ("seed", "lambert")
        for r in ("ours", "povray", "mitsuba")
        for t, e in ((0.1, 1e-2), (0.4, 3e-3), (1.6, 0.0))
    ]
    accuracy.plot(rows, tmp_path / "a.png")
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = accuracy.tables(rows)
    assert "### seed (16×12)" in md and "### lambert (16×12)" in md
    assert md.count("| ours |") == 6


def test_reverse_compile_entry_point_times_each_scene(tmp_path):
    from benchmarks import reverse_compile

    scene = tmp_path / "s.pov"
    scene.write_text("camera { location <0, 0, -3> look_at 0 } light_source { <1, 2, -3> rgb 1 } "
                     "sphere { 0, 1 pigment { rgb 0.5 } }")
    out = tmp_path / "table.md"
    assert reverse_compile.main([str(scene), "--size", "2", "2", "--out", str(out)]) == 0
    (row,) = [line for line in out.read_text().splitlines() if line.startswith("| s |")]
    lower_s, compile_s, total_s = (float(x) for x in row.strip("|").split("|")[1:])
    assert lower_s > 0 and compile_s > 0 and abs(total_s - lower_s - compile_s) <= 0.11
    # the summary line counts the scenes over the 10 s aim (a count, not a timing the test asserts:
    # the machine may be busy)
    over = 1 if total_s > 10 else 0
    assert f"{over} of 1 over 10 s" in out.read_text()


@pytest.mark.povray
def test_speed_entry_point_writes_json_and_markdown(tmp_path):
    assert speed.main(["--out", str(tmp_path), "--scenes", "seed", "--scale", "0.05", "--repeats", "1"]) == 0
    doc = json.loads((tmp_path / "speed.json").read_text())
    (result,) = doc["results"]
    assert result["scene"] == "seed" and (result["width"], result["height"]) == (32, 24)
    for key in ("parse_s", "compile_s", "time_s", "peak_mb"):
        assert result["ours"][key] > 0
    assert result["povray"]["time_s"] >= 0 and result["povray"]["peak_mb"] > 0
    assert result["ratio_warm_to_trace"] is None or result["ratio_warm_to_trace"] > 0
    assert "| seed | 32×24 |" in (tmp_path / "speed.md").read_text()


@pytest.mark.povray
def test_accuracy_entry_point_writes_json_markdown_and_plot(tmp_path):
    assert accuracy.main(["--tiny", "--scenes", "seed", "--repeats", "1", "--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "accuracy.json").read_text())
    assert not doc["failures"]
    rows = doc["rows"]
    assert {r["renderer"] for r in rows} >= {"ours", "povray"}
    for row in rows:
        for key in ("renderer", "scene", "setting", "compile_s", "time_s", "peak_mb", "rmse", "max_err"):
            assert key in row, key
        assert row["scene"] == "seed"
        assert np.isfinite(row["rmse"]) and row["rmse"] >= 0 and row["max_err"] >= row["rmse"]
    assert (tmp_path / "accuracy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "### seed" in (tmp_path / "accuracy.md").read_text()


def test_scaling_scene_files_parse_with_the_expected_geometry(tmp_path):
    from raytracer import Mesh, Sphere, load_scene

    spheres_file = tmp_path / "spheres.pov"
    spheres_file.write_text(scaling.spheres_scene(10))
    scene = load_scene(spheres_file, width=16, height=12)
    assert sum(isinstance(o.shape, Sphere) for o in scene.objects) == 10
    assert len(scene.objects) == 11  # and the checker plane

    mesh_file = tmp_path / "mesh.pov"
    mesh_file.write_text(scaling.mesh_scene(200))
    (mesh,) = load_scene(mesh_file, width=16, height=12).objects
    assert isinstance(mesh.shape, Mesh) and mesh.shape.triangles.shape == (200, 3, 3)

    copies_file = tmp_path / "copies.pov"
    copies_file.write_text(scaling.mesh_scene(200, copies=4))
    copies = load_scene(copies_file, width=16, height=12).objects
    assert [o.shape.triangles.shape[0] for o in copies] == [200] * 4


def _sample_record(scene, psnr, features=None, ours="ok", povray="ok", compile_s=1.0):
    done = ours == "ok" and povray == "ok"
    return {
        "scene": scene,
        "width": 16,
        "height": 12,
        "status": ours,
        "ours": {
            "status": ours,
            "parse_s": 0.1,
            "compile_s": compile_s,
            "time_s": 0.5,
            "first_image_s": 4.0,
            "peak_mb": 300.0,
            "warnings": sum((features or {}).values()),
            "warning_features": features or {},
            "warning_examples": {f: f"{f} is not supported" for f in features or {}},
        },
        "povray": {"status": povray, "parse_s": 0.0, "time_s": 0.1, "wall_s": 0.5},
        "ratio_warm_to_trace": 5.0 if done else None,
        "ratio_process": 8.0 if done else None,
        "psnr_vs_povray": psnr if done else None,
        "image": None,
    }


def test_sample_renders_subset_is_deterministic_and_summary_statistics_are_right(tmp_path):
    for name in ("a/one.pov", "a/two.pov", "b/three.pov", "b/c/four.pov", "five.pov", "six.pov", "a/x.inc"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    everything = sample_renders.select(tmp_path)
    assert everything == sorted(everything) and len(everything) == 6  # .pov files only
    three = sample_renders.select(tmp_path, limit=3, seed=1)
    assert three == sample_renders.select(tmp_path, limit=3, seed=1)
    assert sample_renders.select(tmp_path, limit=5, seed=1)[:3] == three  # a larger limit keeps them
    assert sorted(sample_renders.select(tmp_path, limit=6, seed=2)) == everything
    assert sample_renders.select(tmp_path, ["a/*.pov"]) == ["a/one.pov", "a/two.pov"]
    listed = tmp_path / "list.txt"
    listed.write_text("# chosen\nfive.pov\n\nb/c/four.pov  # nested\n")
    assert sample_renders.select(tmp_path, ["a/one.pov"], listed) == ["a/one.pov", "b/c/four.pov", "five.pov"]

    records = [
        _sample_record("s1", 10.0, {"fog": 2}, compile_s=9.0),
        _sample_record("s2", 20.0, {"fog": 1, "text": 3}),
        _sample_record("s3", 30.0, {"text": 1}, compile_s=5.0),
        _sample_record("s4", 40.0),
        _sample_record("s5", math.inf),  # identical images
        _sample_record("s6", None, {"media": 1}, ours="parse_error"),
        _sample_record("s7", None, ours="ok", povray="error"),
    ]
    s = sample_renders.summarize(records)
    assert (s["tried"], s["finished_by_both"], s["scored"]) == (7, 5, 5)
    assert s["ours"] == {"ok": 6, "parse_error": 1} and s["povray"] == {"ok": 6, "error": 1}
    assert s["stats"]["psnr_db"] == {"n": 5, "q1": 20.0, "median": 30.0, "q3": 40.0}
    assert s["stats"]["warm_over_trace"]["median"] == 5.0 and s["stats"]["process_over_process"]["n"] == 5
    assert s["worst_psnr"] == ["s1", "s2", "s3", "s4", "s5"]
    assert s["slowest_compiles"][:2] == ["s1", "s3"]
    text, fog, media = s["warnings"]  # most scenes first, then most occurrences
    assert (text["feature"], text["scenes"], text["occurrences"]) == ("text", 2, 4)
    assert (text["median_psnr_with"], text["delta_db"], text["median_psnr_alone"]) == (25.0, -15.0, 30.0)
    assert (fog["feature"], fog["scenes"], fog["occurrences"], fog["median_psnr_with"]) == ("fog", 2, 3, 15.0)
    assert fog["median_psnr_without"] == 40.0 and fog["delta_db"] == -25.0  # without: 30, 40, inf
    assert (fog["alone_scored"], fog["median_psnr_alone"]) == (1, 10.0)
    assert (media["feature"], media["scored"], media["median_psnr_with"]) == ("media", 0, None)
    assert sample_renders.main_warning(records[1]) == ("text", 3)
    md = sample_renders.markdown(records, None, None)
    assert "finished by both renderers: **5**" in md
    assert "| s1 | 10 | 2 | fog ×2: fog is not supported |" in md


def test_first_image_reads_the_commands_stage_times(tmp_path, monkeypatch, capsys):
    """``benchmarks/first_image.py`` splits a process's time by the stage times the command prints:
    the line must keep the form it reads (parse, compile, render, in that order)."""
    from benchmarks import first_image
    from raytracer.cli import main

    monkeypatch.setenv("RAYTRACER_CACHE_DIR", "off")
    assert main(["render", str(SCENES["seed"]), "-o", str(tmp_path / "seed.png"), "-W", "8", "-H", "6"]) == 0
    times = first_image.TIMES.search(capsys.readouterr().out)
    assert times is not None and all(float(x) >= 0 for x in times.groups())
