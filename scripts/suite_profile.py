"""Where the test suite's time goes: sums the per-test records that ``tests/conftest.py`` writes
when ``$RAYTRACER_TEST_PROFILE`` names a folder, by file and by test.

    RAYTRACER_TEST_PROFILE=out/profile .venv/bin/python -m pytest -q -n 3 --dist worksteal -p no:cacheprovider
    .venv/bin/python scripts/suite_profile.py out/profile [--top 40]

Each record is one test's wall time in its worker and its JAX programs' cost: tracing, lowering to
StableHLO and XLA's compile (seconds summed, and counted), and the persistent cache's hits.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

KEYS = ("wall", "trace", "lower", "compile")


def load(folder: Path) -> list[dict]:
    lines = [line for f in sorted(folder.glob("*.jsonl")) for line in f.read_text().splitlines()]
    return [json.loads(line) for line in lines if line]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--top", type=int, default=30)
    args = ap.parse_args()
    rows = load(args.folder)
    total = {k: sum(r.get(k, 0.0) for r in rows) for k in KEYS}
    n_compile = sum(r.get("compile_n", 0) for r in rows)
    hits = sum(r.get("cache_hits", 0) for r in rows)
    print(f"{len(rows)} tests, {total['wall']:.0f} worker-s: trace {total['trace']:.0f} s, "
          f"lower {total['lower']:.0f} s, "
          f"XLA compile {total['compile']:.0f} s ({n_compile} programs, {hits} persistent-cache hits)")
    by_file: dict[str, dict] = defaultdict(lambda: defaultdict(float))
    for r in rows:
        acc = by_file[r["test"].split("::")[0]]
        for k in (*KEYS, "compile_n"):
            acc[k] += r.get(k, 0.0)
        acc["tests"] += 1
    heads = ("tests", "wall", "trace", "lower", "compile", "progs")
    print(f"\n{'file':58s} " + " ".join(f"{h:>7s}" for h in heads))
    for name, acc in sorted(by_file.items(), key=lambda kv: -kv[1]["wall"])[: args.top]:
        print(f"{name:58s} {acc['tests']:5.0f} {acc['wall']:7.1f} {acc['trace']:7.1f} {acc['lower']:7.1f} "
              f"{acc['compile']:7.1f} {acc['compile_n']:6.0f}")
    print(f"\n{'test':90s} {'wall':>6s} {'trace':>6s} {'lower':>6s} {'comp':>6s} {'progs':>5s}")
    for r in sorted(rows, key=lambda r: -r["wall"])[: args.top]:
        print(f"{r['test'][:90]:90s} {r['wall']:6.1f} {r.get('trace', 0):6.1f} {r.get('lower', 0):6.1f} "
              f"{r.get('compile', 0):6.1f} {r.get('compile_n', 0):5d}")


if __name__ == "__main__":
    main()
