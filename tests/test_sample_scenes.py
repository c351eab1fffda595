"""The regression guard on POV-Ray's own sample scenes (``benchmarks/sample_scenes.py``): each scene
whose baseline load takes under ``SUITE_SECONDS`` loads now as it did when the baseline was written
(status, warnings by feature, plan). ``python -m benchmarks.sample_scenes --check`` runs the slow
ones too; ``--write`` makes an intended change the baseline."""

import pytest

from benchmarks import sample_scenes as guard

_BASELINE = guard.load_baseline()["scenes"] if guard.BASELINE.is_file() else {}
_SUITE = sorted(n for n, r in _BASELINE.items() if r["load_s"] < guard.SUITE_SECONDS)
_CHUNK = 24  # scenes per test: the workers share them out


def test_the_baseline_covers_every_sample_scene_and_the_suite_most_of_them():
    if not guard.SCENES.is_dir():
        pytest.skip("povray-examples is not installed")
    assert set(_BASELINE) == set(guard.scene_names())
    assert len(_SUITE) >= 0.85 * len(_BASELINE)
    # every scene POV-Ray parses loads (the ones it refuses, listed, may fail for us too)
    refused = {n for n, r in _BASELINE.items() if r["status"] != "ok"}
    assert refused <= set(guard.POVRAY_REJECTS), refused - set(guard.POVRAY_REJECTS)


@pytest.mark.parametrize("first", range(0, len(_SUITE), _CHUNK),
                         ids=lambda i: _SUITE[i].replace("/", ".") if i < len(_SUITE) else str(i))
def test_sample_scenes_load_as_in_the_baseline(first):
    if not guard.SCENES.is_dir():
        pytest.skip("povray-examples is not installed")
    names = _SUITE[first:first + _CHUNK]
    records = {n: guard.record(guard.SCENES / n) for n in names}
    regressions, changes = guard.compare(records, _BASELINE)
    assert not regressions and not changes, guard.report(regressions, changes)


def test_the_guard_sees_a_scene_that_no_longer_loads_and_a_warning_that_grows():
    """``compare`` on records made up from one of the baseline's: what a broken parser would give."""
    base = {"a.pov": {"status": "ok", "warnings": {"normal": 2}, "plan": "p", "load_s": 0.1},
            "b.pov": {"status": "ok", "warnings": {}, "plan": "p", "load_s": 0.1},
            "c.pov": {"status": "scene_error", "error": "x", "load_s": 0.1}}
    now = {"a.pov": {"status": "ok", "warnings": {"normal": 3, "text": 1}, "plan": "p", "load_s": 0.1},
           "b.pov": {"status": "scene_error", "error": "expected a fog", "load_s": 0.1},
           "c.pov": {"status": "ok", "warnings": {}, "plan": "q", "load_s": 0.1}}
    regressions, changes = guard.compare(now, base)
    assert regressions == ["a.pov: 3 warnings about 'normal', 2 in the baseline",
                           "a.pov: 1 warnings about 'text', 0 in the baseline",
                           "b.pov: loaded, now scene_error: expected a fog"]
    assert changes == ["c.pov: scene_error -> loads"]
    assert guard.compare(base, base) == ([], [])
