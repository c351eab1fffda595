"""Writes ``tests/slow_tests.txt``: the tests that took at least ``THRESHOLD_S`` in a full run (in
any of the runs whose reports are given: a shared machine's times vary).

``make test-fast`` leaves out the tests marked ``slow``. Besides the tests marked in their files,
``tests/conftest.py`` marks those listed in ``tests/slow_tests.txt``, which this script makes from
the JUnit report of a full run (``make slow-list`` runs both), so the fast loop is chosen by
measurement rather than by guess:

    .venv/bin/python -m pytest -q -n 2 --dist worksteal -p no:cacheprovider --junitxml=out/junit.xml
    .venv/bin/python scripts/slow_tests.py out/junit.xml [older-run.xml ...]

A test's time is its own (set-up, call and tear-down), measured with two workers on two cores:
almost all of it is tracing and compiling its JAX programs.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path

THRESHOLD_S = 0.5
ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "slow_tests.txt"


def node_id(classname: str, name: str) -> str:
    """pytest's node id from JUnit's ``classname`` (dotted module, then classes) and ``name``."""
    parts = classname.split(".")
    for k in range(len(parts), 0, -1):
        path = Path(*parts[:k]).with_suffix(".py")
        if (ROOT / path).is_file():
            return "::".join([path.as_posix(), *parts[k:], name])
    raise ValueError(f"no test file for {classname}")


def main(argv: list[str]) -> int:
    if not argv or any(a.startswith("-") for a in argv):
        print(__doc__, file=sys.stderr)
        return 2
    # each test of the first (newest) report, with its longest time over the reports given
    longest: dict[str, float] = {}
    for k, report in enumerate(argv):
        try:
            cases = list(ET.parse(report).iter("testcase"))
        except (OSError, ET.ParseError) as e:
            print(f"slow_tests.py: {report}: not a readable JUnit report ({e})", file=sys.stderr)
            return 2
        for case in cases:
            nid = node_id(case.get("classname"), case.get("name"))
            if case.find("skipped") is None and (k == 0 or nid in longest):
                longest[nid] = max(longest.get(nid, 0.0), float(case.get("time", 0.0)))
    rows = [(t, nid) for nid, t in longest.items()]
    slow = sorted(nid for t, nid in rows if t >= THRESHOLD_S)
    total = sum(t for t, _ in rows)
    fast = sum(t for t, _ in rows if t < THRESHOLD_S)
    header = [
        f"# Tests that took at least {THRESHOLD_S} s in one of {len(argv)} full runs ({len(rows)} tests, "
        f"{total / 60:.1f} CPU-min; the {len(rows) - len(slow)} others: {fast / 60:.1f} CPU-min).",
        "# tests/conftest.py marks them slow (make test-fast leaves them out). Made by",
        "# scripts/slow_tests.py from the runs' JUnit reports; do not edit by hand.",
    ]
    OUT.write_text("\n".join(header + slow) + "\n")
    print(f"{OUT}: {len(slow)} of {len(rows)} tests", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
