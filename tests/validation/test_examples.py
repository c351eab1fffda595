"""Every example scene says what it checks, and every one is compared with POV-Ray exactly once: by
its ``pov/<name>`` entry of the validation suite (``test_suite.py::test_our_renderer_passes_the_suite``),
at the bar of ≥ 40 dB at 160×120 (spp = 1) and 99 % of the pixels within 0.01."""

from pathlib import Path

from validation import suite

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"
MIN_PSNR = 40.0


def test_every_example_starts_with_a_checks_line():
    for path in SCENES.glob("*.pov"):
        if path.stem != "seed":
            assert path.read_text().startswith("// checks: "), path.name


def test_every_example_is_compared_with_povray_by_the_suite_at_40_db_or_better():
    """Replaces the former per-example POV-Ray test (the same render, size and spp, PSNR ≥ 40 dB),
    which repeated the suite's ``pov/`` comparisons: a new example scene fails here until it has
    its suite entry. ``seed`` is owned and tested by the parser/renderer tests."""
    examples = {p.stem for p in suite.EXAMPLES_DIR.glob("*.pov")} - {"seed"}
    entries = {s.path.stem: s for s in suite.SCENES if s.path.parent == suite.EXAMPLES_DIR}
    assert set(entries) == examples
    assert (suite.WIDTH, suite.HEIGHT) == (160, 120)
    for name, s in entries.items():
        assert s.name == f"pov/{name}"
        assert s.povray is not None and s.povray.min_psnr is not None and s.povray.min_psnr >= MIN_PSNR, name
