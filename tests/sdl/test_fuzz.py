"""A bounded run of the fuzz campaign (``benchmarks/fuzz.py``): mutated scenes end as a
scene or as a located ``SceneError``, never as an internal error, an escaped exception, a hang, a
read outside the scene's folders, or a non-finite image. Long campaigns: ``python -m benchmarks.fuzz``."""

import pytest

from benchmarks import fuzz


def test_span_keeping_tokens_rebuild_the_text_and_mutations_apply_to_any_scene():
    text = '#declare A = 1.5e3; // c\nsphere { <0, A, 0>, 1 pigment { rgb "x" } }\n'
    toks = fuzz.tokens(text)
    assert fuzz.join(toks) == text.rstrip("\n")
    assert [t.kind for t in toks[:3]] == ["hash", "id", "op"]
    mutant = fuzz.join(fuzz.mutate(toks, [("number", 0, 1, 4), ("string", 0, 0, 0)]))
    assert "1e309" in mutant and '"/etc/passwd"' in mutant  # number #1 → EXTREME_NUMBERS[4]
    assert fuzz.mutate([], [("cut", 1, 2, 3)]) == []


@pytest.mark.slow  # ~7 s: 600 parses and an 8×6 render
def test_a_bounded_fuzz_campaign_finds_no_defect(tmp_path):
    res = fuzz.campaign(600, seed=13, corpus="examples", folder=tmp_path, render_every=150)
    assert res["cases"] >= 600
    assert res["outcomes"].get("scene", 0) > 50 and res["outcomes"].get("error", 0) > 50
    assert res["defects"] == 0, res["examples"]
