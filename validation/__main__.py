"""Compare our renders with Mitsuba 3 and POV-Ray: ``raytracer validate`` is the same command.

``python -m validation [--against mitsuba|povray|all] [--report DIR] [SCENE…]``
``python -m validation --against gradients``: our gradients vs Mitsuba prb (``validation.gradients``)
``python -m validation --against edges``: our boundary term vs Mitsuba's projective sampling
(``validation.edge_gradients``)

Prints one line per scene × reference and exits with status 1 if any comparison fails.
"""

from __future__ import annotations

import argparse
import sys

from . import suite


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation", description=__doc__.splitlines()[0])
    p.add_argument("--against", choices=("mitsuba", "povray", "all", "gradients", "edges"), default="all",
                   help="which reference renderer(s) to compare with (default: all)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report with images into DIR")
    p.add_argument("--list", action="store_true", help="list the scenes and what each checks")
    p.add_argument("scenes", nargs="*", metavar="SCENE", help="scene names (default: the whole suite)")
    args = p.parse_args(argv)

    if args.against == "gradients":
        from . import gradients

        return gradients.main()
    if args.against == "edges":
        from . import edge_gradients

        return edge_gradients.main()
    if args.list:
        for s in suite.SCENES:
            refs = ",".join(r for r in suite.REFERENCES if s.thresholds(r) is not None)
            print(f"{s.name:38s} {refs:15s} {s.checks}")
        return 0
    try:
        scenes = [suite.scene_named(n) for n in args.scenes] if args.scenes else list(suite.SCENES)
    except KeyError as e:
        print(f"python -m validation: {e.args[0]}", file=sys.stderr)
        return 2
    references = suite.REFERENCES if args.against == "all" else (args.against,)
    print(suite.HEADER, flush=True)
    results = suite.run(scenes, references, on_result=lambda r: print(r.line(), flush=True))
    bad = [r for r in results if not r.passed]
    print(f"{len(results) - len(bad)} of {len(results)} comparisons pass; {len(bad)} fail")
    if args.report:
        from .report import write_report

        page = write_report(results, args.report)
        print(f"report: {page}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
