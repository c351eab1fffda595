"""``docs/coverage.md``: what we render of POV-Ray's 396 sample scenes, beside POV-Ray, at one commit.

    python -m benchmarks.coverage                      # render every scene with both, write the doc
    python -m benchmarks.coverage --from-jsonl F       # only write the doc from a finished run

The run is ``benchmarks.sample_renders`` over every scene at 160×120 into a fresh folder
(``out/benchmarks/coverage``: its images, POV-Ray | ours | difference, stay out of the
repository), its records copied to ``benchmarks/results/sample_renders.jsonl``. The doc says, per
scene, both renderers' status, the PSNR of our linear image against POV-Ray's and the features we
warned about (parsed, not rendered); and per feature, in how many scenes it is warned about and the
median PSNR of the scenes where it is the only one (what that missing feature costs on its own).
"""

from __future__ import annotations

import argparse
import datetime
import json
import shutil
import sys
from pathlib import Path

from ._common import fmt, md_table
from .sample_renders import both_ok, quantile, summarize
from .sample_renders import main as sample_renders_main

ROOT = Path(__file__).resolve().parent.parent
RECORDS = ROOT / "benchmarks" / "results" / "sample_renders.jsonl"
DOC = ROOT / "docs" / "coverage.md"
RUN = ROOT / "out" / "benchmarks" / "coverage"


def _features(r: dict) -> str:
    features = r["ours"].get("warning_features") or {}
    return ", ".join(f"{k} ×{v}" if v > 1 else k for k, v in sorted(features.items())) or "–"


def _status(r: dict) -> str:
    ours, pov = r["ours"]["status"], r["povray"]["status"]
    return "ok" if ours == pov == "ok" else f"ours {ours}, POV-Ray {pov}"


def markdown(records: list[dict], note: str | None = None) -> str:
    s = summarize(records)
    commits = sorted({r.get("commit") or "?" for r in records})
    finished = [r for r in records if both_ok(r)]
    scored = [r for r in finished if r.get("psnr_vs_povray") is not None]
    clean = [r["psnr_vs_povray"] for r in scored if not r["ours"].get("warning_features")]
    first = min((r.get("finished_at") or "" for r in records), default="")
    q = s["stats"]
    md = [
        "# Coverage: POV-Ray's sample scenes, rendered by POV-Ray 3.7 and by us",
        "",
        f"All {s['tried']} scenes of Debian's `povray-examples` at 160×120, one ray per pixel centre "
        "(POV-Ray `-A`, ours spp 1, float32), both renderers in the same run, one scene at a time; "
        f"commit {', '.join(commits)}, run started {first[:10] or '?'}. Regenerate with "
        "`python -m benchmarks.coverage` (two to three hours on 2 cores); the records are "
        "`benchmarks/results/sample_renders.jsonl`. PSNR: our linear image against POV-Ray's `+FE` "
        "EXR, peak 1. *Warned*: features we parse but do not render, each said at its place in the "
        "scene (`raytracer render` prints them).",
        *(["", note] if note else []),
        "",
        "## Summary",
        "",
        f"- Finished by both renderers: **{s['finished_by_both']}** of {s['tried']} (ours: "
        + ", ".join(f"{k} {v}" for k, v in sorted(s["ours"].items(), key=lambda kv: -kv[1]))
        + "; POV-Ray: "
        + ", ".join(f"{k} {v}" for k, v in sorted(s["povray"].items(), key=lambda kv: -kv[1]))
        + ").",
        f"- PSNR over the {q['psnr_db']['n']} scenes both finished: median "
        f"**{fmt(q['psnr_db']['median'])} dB** "
        f"(quartiles {fmt(q['psnr_db']['q1'])}, {fmt(q['psnr_db']['q3'])}); over the {len(clean)} "
        f"scenes with no warning: median **{fmt(quantile(clean, 0.5))} dB**.",
        f"- Time: our warm render over POV-Ray's trace time, median {fmt(q['warm_over_trace']['median'])}× "
        f"(quartiles {fmt(q['warm_over_trace']['q1'])}, {fmt(q['warm_over_trace']['q3'])}); a whole "
        f"process to the first image over POV-Ray's, median {fmt(q['process_over_process']['median'])}× "
        "(the first image pays for imports and compiling the program).",
        "",
        "## Missing features, by the scenes they hold back",
        "",
        "In how many scenes a feature is warned about, and the median PSNR of the scenes where it is "
        "the only feature warned about.",
        "",
    ]
    rows = [[w["feature"], w["scenes"], w["occurrences"],
             f"{fmt(w['median_psnr_alone'])} ({w['alone_scored']})" if w["alone_scored"] else "–"]
            for w in s["warnings"]]
    md += [md_table(["feature", "scenes", "occurrences", "only gap: median PSNR dB (scenes)"], rows), ""]
    md += ["## Every scene", ""]
    rows = []
    for r in sorted(records, key=lambda r: r["scene"]):
        ratio = r.get("ratio_warm_to_trace")
        rows.append([r["scene"], _status(r), r.get("psnr_vs_povray"),
                     None if ratio is None else f"{ratio:.2f}×", _features(r)])
    md += [md_table(["scene", "status", "PSNR dB", "warm / POV trace", "warned"], rows), ""]
    return "\n".join(md)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from-jsonl", type=Path, metavar="F", help="write the doc from this finished run")
    ap.add_argument("--note", help="a line about how the run was made (the machine's load, a split run)")
    args = ap.parse_args(argv)
    if args.from_jsonl is None:
        shutil.rmtree(RUN, ignore_errors=True)  # one commit's run, never appended to
        status = sample_renders_main(["--out", str(RUN)])
        if status:
            return status
        src = RUN / "sample_renders.jsonl"
    else:
        src = args.from_jsonl
    records = [json.loads(line) for line in src.read_text().splitlines() if line.strip()]
    if src.resolve() != RECORDS.resolve():
        RECORDS.write_text("".join(json.dumps(r, sort_keys=True) + "\n" for r in records))
    DOC.write_text(markdown(records, args.note))
    print(f"wrote {DOC} ({len(records)} scenes) at {datetime.datetime.now():%Y-%m-%d %H:%M}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
