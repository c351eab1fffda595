"""The validation suite: its scenes and thresholds, the references agreeing with each other, our
renderer against both, and a deliberately broken renderer that the suite must catch."""

import importlib

import pytest

from validation import suite

# Measured failures of our renderer, as {suite name: reason}; strict xfails (remove an entry when
# its cause is fixed). Empty since e9b7544 (checker on planes, polygon and CSG cylinder fixes).
KNOWN_FAILURES: dict[str, str] = {}


def test_suite_has_at_least_twelve_scenes_per_reference():
    mitsuba = [s for s in suite.SCENES if s.mitsuba is not None]
    povray = [s for s in suite.SCENES if s.povray is not None]
    assert len(mitsuba) >= 12 and len(povray) >= 12
    assert len({s.name for s in suite.SCENES}) == len(suite.SCENES)


def test_every_scene_exists_and_says_what_it_checks():
    for s in suite.SCENES:
        assert s.path.is_file(), s.path
        assert len(s.checks) > 10, s.name


def test_cli_lists_scenes_and_rejects_unknown_names(capsys):
    from validation.__main__ import main

    assert main(["--list"]) == 0
    assert "lambert_sphere" in capsys.readouterr().out
    assert main(["no_such_scene"]) == 2


MITSUBA_SCENES = [pytest.param(s, id=s.name) for s in suite.SCENES if s.mitsuba is not None]


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.povray
@pytest.mark.parametrize("scene", MITSUBA_SCENES)
def test_mitsuba_reference_agrees_with_povray_within_the_scene_thresholds(scene):
    """The two references agree with each other, so the harness itself is right (no code of ours
    renders here except the parser feeding the Mitsuba conversion)."""
    from validation import metrics
    mi_img = suite.render_reference(scene, "mitsuba")
    pov = suite.render_reference(scene, "povray")
    assert scene.mitsuba.failures(metrics.compare(mi_img, pov, tol=scene.mitsuba.tol)) == []


def _our_cases():
    for s in suite.SCENES:
        for reference in suite.REFERENCES:
            if s.thresholds(reference) is None:
                continue
            marks = [pytest.mark.slow, pytest.mark.povray]
            if reference == "mitsuba":
                marks.append(pytest.mark.mitsuba)
            if s.name in KNOWN_FAILURES:
                marks.append(pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[s.name]))
            yield pytest.param(s, reference, id=f"{s.name}-{reference}", marks=marks)


@pytest.mark.povray
@pytest.mark.parametrize("scene, reference", list(_our_cases()))
def test_our_renderer_passes_the_suite(scene, reference):
    (result,) = suite.run([scene], (reference,))
    assert result.passed, result.line()


@pytest.fixture
def fresh_jit():
    import jax

    jax.clear_caches()
    yield
    jax.clear_caches()


@pytest.mark.povray
@pytest.mark.slow
@pytest.mark.mitsuba
def test_a_mirrored_camera_makes_the_suite_fail(monkeypatch, fresh_jit):
    """Proof that the suite catches a real bug: the seed formula's v×u (mirrored image, semantics §1.3)."""
    tiles = importlib.import_module("raytracer._tiles")  # where camera rays are made for a render
    names = ["two_lights", "boxes_transforms"]
    scenes = [suite.scene_named(n) for n in names]
    healthy = suite.run(scenes, ("mitsuba", "povray"))
    assert all(r.passed for r in healthy), [r.line() for r in healthy]

    original = tiles.camera_rays

    def mirrored_camera_rays(camera, x0, y0):
        return original(camera, -x0, y0)

    monkeypatch.setattr(tiles, "camera_rays", mirrored_camera_rays)
    import jax

    jax.clear_caches()
    broken = suite.run(scenes, ("mitsuba", "povray"))
    assert len(broken) == 4
    assert not any(r.passed for r in broken), [r.line() for r in broken]
