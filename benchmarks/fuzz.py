"""A grammar-aware fuzz campaign of the scene loader: mutated scenes must end as a scene,
or as a ``SceneError`` that says where, and must not read outside the folders a scene may read.

    python -m benchmarks.fuzz [--cases N] [--minutes M] [--seed S] [--corpus examples|samples|all]
                              [--render-every K] [--workers W] [--out docs/fuzz.json]

**Seeds.** The bundled example scenes, ``benchmarks/fuzz_seed.pov`` (the interpreter's directives:
macros, loops, arrays, strings, files, functions) and, with ``--corpus samples``, POV-Ray's own
sample scenes up to 16 kB (``povray-examples``).

**Mutations.** Made on a token stream of the scene's text that keeps every token's source span, so
a mutant is the original text with a few tokens changed, and still reads as POV-Ray scene language:

  * a number → an extreme (0, -0, -1, 1e308, 1e309, 1e-320, 2147483648, 4294967297, 1e15, 0.5);
  * an identifier → a keyword, a directive, or another identifier of the scene;
  * a string → a hostile path (``/etc/passwd``, ``../../../../etc/passwd``, ``/proc/self/environ``,
    a folder, an empty string, a 100 kB string);
  * delete, duplicate or swap tokens; duplicate a ``{ … }`` block; cut the text at a token;
  * insert a bracket, an operator, a directive, a non-ASCII letter or a control character.

The mutation plan (which seed, which mutations, where) is drawn from Hypothesis strategies, so a
case is reproducible from its seed and the campaign is a ``@given`` run without shrinking.

**Outcomes**, one per case:

  * ``scene``: loaded; ``error``: a ``SceneError`` with ``file:line:col``;
  * ``error_unlocated``: a ``SceneError`` without a location (a defect: item 9);
  * ``internal``: an ``InternalError`` (the parser's own bug, caught and reported as one);
  * ``escaped``: any other exception out of ``load_scene`` (a defect);
  * ``hang``: the case ran past the parse limit's backstop (3× ``Limits.max_parse_seconds`` of the
    process's CPU time);
  * ``read_outside``: the loader opened a file outside the scene's folder, the ``-L`` folders and
    POV-Ray's include folder (whose links, the fonts Debian keeps in /usr/share/fonts, are the
    package's) (seen by a ``sys.addaudithook`` hook on ``open``, independently of the loader's own
    check).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SEED_SCENE = Path(__file__).resolve().parent / "fuzz_seed.pov"
POVRAY_INCLUDE = Path("/usr/share/povray-3.7/include")
DEFECTS = ("error_unlocated", "internal", "escaped", "hang", "read_outside", "render_escaped", "nonfinite")

# ------------------------------------------------------------------ a span-keeping token stream
_TOKEN = re.compile(r'''
    (?P<space>\s+|//[^\n]*|/\*.*?\*/)
  | (?P<str>"(?:[^"\\\n]|\\.)*")
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<id>[A-Za-z_]\w*)
  | (?P<hash>\#\s*[A-Za-z_]\w*)
  | (?P<op><=|>=|!=|[{}()\[\]<>,;=+\-*/?:.!&|^])
  | (?P<other>.)
''', re.VERBOSE | re.DOTALL)


@dataclass(frozen=True)
class Tok:
    kind: str  # str, num, id, hash, op, other
    text: str
    before: str  # the whitespace and comments before it


def tokens(text: str) -> list[Tok]:
    """``text`` as tokens that keep their spacing: ``"".join(t.before + t.text) == text`` (up to a
    trailing comment)."""
    out, pending = [], ""
    for m in _TOKEN.finditer(text):
        kind = m.lastgroup
        if kind == "space":
            pending += m.group()
        else:
            out.append(Tok(kind, m.group(), pending))
            pending = ""
    return out


def join(toks: list[Tok]) -> str:
    return "".join(t.before + t.text for t in toks)


# ------------------------------------------------------------------ mutations
EXTREME_NUMBERS = ("0", "-0", "-1", "1e308", "1e309", "1e-320", "2147483648", "4294967297", "1e15",
                   "0.5", "-2147483649", "9" * 400)
HOSTILE_STRINGS = ('"/etc/passwd"', '"../../../../etc/passwd"', '"/proc/self/environ"', '"/"',
                   '""', '"."', '"' + "A" * 100_000 + '"', '"colors.inc"', '"\\"', '"%s%n"')
DIRECTIVES = ("#declare", "#local", "#macro", "#end", "#if", "#else", "#while", "#for", "#include",
              "#fopen", "#read", "#write", "#undef", "#switch", "#case", "#break", "#default",
              "#version", "#error", "#debug")
KEYWORDS = ("sphere", "box", "union", "difference", "mesh", "mesh2", "pigment", "texture", "finish",
            "interior", "ior", "rgb", "rgbft", "color_map", "checker", "translate", "scale", "rotate",
            "matrix", "array", "function", "str", "concat", "chr", "pow", "sqrt", "int", "vlength",
            "image_map", "height_field", "text", "ttf", "clipped_by", "inverse", "max_trace_level",
            "light_source", "camera", "area_light", "spotlight", "blob", "isosurface", "torus")
INSERTS = ("{", "}", "(", ")", "<", ">", "[", "]", ",", ";", "=", "#", "Ø", "٣", "\x00", "\x07", "é",
           "1/0", "-", "*", "1e309")
MUTATIONS = ("number", "identifier", "string", "delete", "duplicate", "swap", "block", "cut", "insert")


def mutate(toks: list[Tok], plan: list[tuple[str, int, int, int]]) -> list[Tok]:
    """``toks`` with the mutations of ``plan`` applied in order. Each entry is ``(kind, a, b, c)``
    with ``a``, ``b``, ``c`` non-negative integers that pick positions and replacements (taken
    modulo what is there, so every plan applies to every scene)."""
    toks = list(toks)
    for kind, a, b, c in plan:
        if not toks:
            break
        i = a % len(toks)
        if kind == "number":
            nums = [k for k, t in enumerate(toks) if t.kind == "num"] or [i]
            k = nums[b % len(nums)]
            toks[k] = Tok("num", EXTREME_NUMBERS[c % len(EXTREME_NUMBERS)], toks[k].before)
        elif kind == "identifier":
            ids = [k for k, t in enumerate(toks) if t.kind == "id"] or [i]
            k = ids[b % len(ids)]
            pool = KEYWORDS + DIRECTIVES + tuple(toks[j].text for j in ids[:50])
            toks[k] = Tok("id", pool[c % len(pool)], toks[k].before or " ")
        elif kind == "string":
            strs = [k for k, t in enumerate(toks) if t.kind == "str"] or [i]
            k = strs[b % len(strs)]
            toks[k] = Tok("str", HOSTILE_STRINGS[c % len(HOSTILE_STRINGS)], toks[k].before)
        elif kind == "delete":
            del toks[i:i + 1 + b % 3]
        elif kind == "duplicate":
            toks[i:i] = toks[i:i + 1 + b % 4]
        elif kind == "swap":
            j = b % len(toks)
            toks[i], toks[j] = toks[j], toks[i]
        elif kind == "block":
            opens = [k for k, t in enumerate(toks) if t.text == "{"]
            if opens:
                start = opens[b % len(opens)]
                depth, end = 0, start
                for end in range(start, len(toks)):
                    depth += {"{": 1, "}": -1}.get(toks[end].text, 0)
                    if depth == 0:
                        break
                # the block's keyword (the token before "{") and the block, once more after it
                toks[end + 1:end + 1] = toks[max(0, start - 1):end + 1]
        elif kind == "cut":
            del toks[i:]
        elif kind == "insert":
            pool = INSERTS + DIRECTIVES + KEYWORDS
            toks.insert(i, Tok("other", pool[c % len(pool)], " "))
    return toks


def case_strategy(n_seeds: int):
    """Hypothesis: ``(seed index, [(mutation, a, b, c), …])`` with 1–4 mutations."""
    from hypothesis import strategies as st

    index = st.integers(0, 1 << 20)
    one = st.tuples(st.sampled_from(MUTATIONS), index, index, index)
    return st.tuples(st.integers(0, n_seeds - 1), st.lists(one, min_size=1, max_size=4))


# ------------------------------------------------------------------ seeds
SAMPLES = Path("/usr/share/povray-3.7/scenes")


def seed_files(corpus: str) -> list[Path]:
    files = sorted((ROOT / "examples" / "scenes").glob("*.pov")) + [SEED_SCENE]
    if corpus in ("samples", "all"):
        files += sorted(p for p in SAMPLES.rglob("*.pov") if p.stat().st_size <= 16_384)
    return files


# ------------------------------------------------------------------ one case
class _Backstop(Exception):
    pass


class _OutOfTime(Exception):
    """Raised out of the Hypothesis run when ``--minutes`` are up (it has no other way to stop)."""


def _alarm(signum, frame):
    raise _Backstop()


class OpenWatch:
    """Records every file the process opens (``sys.addaudithook``; a hook cannot be removed, so it
    does nothing unless ``active``)."""

    installed: OpenWatch | None = None

    def __init__(self):
        self.active = False
        self.opened: list[str] = []

    @classmethod
    def get(cls) -> OpenWatch:
        if cls.installed is None:
            cls.installed = OpenWatch()
            sys.addaudithook(cls.installed._hook)
        return cls.installed

    def _hook(self, event, args):
        if self.active and event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
            self.opened.append(os.fsdecode(args[0]))


def _program_files() -> list[Path]:
    """Where the loader's own code and data live (Python, the venv, this repository) and JAX's
    persistent compilation cache (a parse-time ``trace()`` compiles a program, and JAX looks it up
    there once ``render`` has turned the cache on: the renderer's data, not the scene's)."""
    import jax

    places = {sys.prefix, sys.base_prefix, sys.exec_prefix, str(ROOT)}
    if jax.config.jax_compilation_cache_dir:
        places.add(str(jax.config.jax_compilation_cache_dir))
    return [Path(p).resolve() for p in places]


def _inside(path: str, folders: list[Path]) -> bool:
    try:
        p = Path(path).resolve()
        # the package's links in POV-Ray's include folder (Debian's fonts live in /usr/share/fonts)
        if Path(path).parent.resolve() == POVRAY_INCLUDE.resolve():
            return True
    except (OSError, RuntimeError, ValueError):
        return False
    return any(p == f or f in p.parents for f in folders)


def run_case(text: str, folder: Path, *, parse_seconds: float = 5.0, render: bool = False) -> tuple[str, str]:
    """Loads ``text`` as ``folder/case.pov`` (and renders it at 8×6 if ``render`` and it loads);
    returns ``(outcome, detail)``."""
    from raytracer.errors import InternalError, SceneError
    from raytracer.sdl import Limits, load_scene

    path = folder / "case.pov"
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    allowed = [folder.resolve(), POVRAY_INCLUDE.resolve(), *_program_files()]
    watch = OpenWatch.get()
    watch.opened.clear()
    backstop = max(1, int(3 * parse_seconds))
    # the backstop counts this process's CPU time, not the wall clock: a campaign that runs beside
    # other work (niced, stopped, starved) would otherwise take a slow case for a hang
    old = signal.signal(signal.SIGPROF, _alarm)
    signal.setitimer(signal.ITIMER_PROF, backstop)
    watch.active = True
    scene = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load_scene(path, width=32, height=24, limits=Limits(max_parse_seconds=parse_seconds))
        outcome, detail = "scene", ""
    except _Backstop:
        outcome, detail = "hang", f"still parsing after {backstop} s of CPU time"
    except SceneError as e:
        outcome = "error" if e.location is not None else "error_unlocated"
        detail = str(e).splitlines()[0][:300]
    except InternalError as e:
        if isinstance(e.__cause__, _Backstop):  # the loader reports what escapes it as its own bug
            outcome, detail = "hang", f"still parsing after {backstop} s of CPU time"
        else:
            outcome, detail = "internal", str(e).splitlines()[0][:300]
    except RecursionError as e:
        outcome, detail = "escaped", f"RecursionError: {e}"[:300]
    except Exception as e:  # noqa: BLE001 - the point is to catch what escapes
        outcome, detail = "escaped", f"{type(e).__name__}: {e}"[:300]
    finally:
        watch.active = False
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old)
    outside = [p for p in watch.opened if not _inside(p, allowed)]
    if outside:
        return "read_outside", outside[0]
    if scene is not None and render:
        return _render_case(scene)
    return outcome, detail


def _render_case(scene) -> tuple[str, str]:
    """An 8×6 render of a loaded mutant: its image must be finite."""
    import numpy as np

    from raytracer import render

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            image = np.asarray(render(scene, width=8, height=6))
    except Exception as e:  # noqa: BLE001
        return "render_escaped", f"{type(e).__name__}: {e}"[:300]
    if not np.all(np.isfinite(image)):
        return "nonfinite", f"{int(np.sum(~np.isfinite(image)))} non-finite values"
    return "rendered", ""


# ------------------------------------------------------------------ a campaign
def campaign(cases: int, seed: int, corpus: str, folder: Path, minutes: float | None = None,
             parse_seconds: float = 5.0, render_every: int = 0, on_case=None,
             defect_log: Path | None = None) -> dict:
    """``cases`` mutated scenes (or as many as fit in ``minutes``) drawn by Hypothesis from ``seed``;
    every ``render_every``-th case that loads is also rendered at 8×6 (0: none). Each defect is
    also appended to ``defect_log`` (JSON lines) when it happens, so a stopped campaign keeps them."""
    import logging

    from hypothesis import HealthCheck, Phase, given, settings

    logging.getLogger("raytracer").setLevel(logging.ERROR)  # the mutants' warnings are expected
    import jax

    # JAX finds its devices on first use (reading /sys/bus/pci/devices/*/vendor to look for
    # accelerators): done here, before any case is watched, as a parse-time trace() would otherwise
    # do it under the watch and count the renderer's own reads as the scene's
    jax.devices()
    files = seed_files(corpus)
    streams = [tokens(f.read_text(encoding="utf-8", errors="replace")) for f in files]
    # the seeds' own include files: a mutant in its own folder still finds them
    for f in files:
        for inc in f.parent.glob("*.inc"):
            target = folder / inc.name
            if not target.exists():
                target.write_bytes(inc.read_bytes())
    counts: collections.Counter = collections.Counter()
    examples: dict[str, list] = collections.defaultdict(list)
    per_outcome_s: collections.Counter = collections.Counter()
    deadline = None if minutes is None else time.monotonic() + 60 * minutes
    t_start = time.perf_counter()

    @settings(max_examples=cases, deadline=None, database=None, derandomize=False,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(case_strategy(len(files)))
    def one(case):
        if deadline is not None and time.monotonic() > deadline:
            raise _OutOfTime()
        index, plan = case
        text = join(mutate(streams[index], plan))
        t0 = time.perf_counter()
        # renders only of mutants of the small seeds (examples, fuzz_seed.pov): the sample scenes'
        # layered CSG can take minutes and gigabytes to compile, which is not this test
        small = SAMPLES not in files[index].parents
        render = small and render_every > 0 and counts["scene"] % render_every == render_every - 1
        outcome, detail = run_case(text, folder, parse_seconds=parse_seconds, render=render)
        if outcome == "rendered":
            counts["scene"] += 1
        per_outcome_s[outcome] += time.perf_counter() - t0
        counts[outcome] += 1
        if outcome in DEFECTS:
            record = {"outcome": outcome, "seed": str(files[index].name), "plan": plan, "detail": detail,
                      "text": text if len(text) < 4000 else None}
            if len(examples[outcome]) < 20:
                examples[outcome].append(record)
            if defect_log is not None:
                with open(defect_log, "a", encoding="utf-8") as f:
                    f.write(json.dumps(record) + "\n")
        if on_case is not None:
            on_case(sum(counts.values()) - counts["rendered"], counts)

    # Hypothesis draws from its own seed: fixed here, so a campaign repeats exactly
    from hypothesis import seed as hseed

    try:
        hseed(seed)(one)()
    except _OutOfTime:
        pass
    total = sum(counts.values()) - counts["rendered"]  # a rendered case also counts as a scene
    return {
        "cases": total,
        "seed": seed,
        "corpus": corpus,
        "seeds": len(files),
        "parse_limit_s": parse_seconds,
        "render_every": render_every,
        "wall_s": time.perf_counter() - t_start,
        "outcomes": dict(counts),
        "mean_s": {k: per_outcome_s[k] / counts[k] for k in counts},
        "defects": sum(counts[k] for k in DEFECTS),
        "examples": dict(examples),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--minutes", type=float, default=None, help="stop drawing cases after this long")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--corpus", choices=("examples", "samples", "all"), default="all")
    ap.add_argument("--parse-seconds", type=float, default=5.0)
    ap.add_argument("--render-every", type=int, default=0,
                    help="render every K-th scene that loads at 8×6 and check it is finite (0: none)")
    ap.add_argument("--workers", type=int, default=1, help="processes, each with seed + its index")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "fuzz.json")
    args = ap.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if args.workers > 1:
        return _parallel(args)
    import tempfile

    with tempfile.TemporaryDirectory(prefix="fuzz-") as tmp:
        last = [time.monotonic()]

        def report(n, counts):
            if time.monotonic() - last[0] > 30:
                last[0] = time.monotonic()
                print(f"{n} cases: {dict(counts)}", file=sys.stderr, flush=True)

        res = campaign(args.cases, args.seed, args.corpus, Path(tmp), args.minutes, args.parse_seconds,
                       args.render_every, on_case=report, defect_log=args.out.with_suffix(".defects.jsonl"))
    args.out.write_text(json.dumps(res, indent=1))
    print(json.dumps({k: v for k, v in res.items() if k != "examples"}, indent=1))
    return 0 if res["defects"] == 0 else 1


def _parallel(args) -> int:
    """``--workers`` processes with seeds ``seed, seed + 1, …``, merged into one result."""
    procs, outs = [], []
    for w in range(args.workers):
        out = args.out.with_name(f"{args.out.stem}.w{w}.json")
        outs.append(out)
        cmd = [sys.executable, "-m", "benchmarks.fuzz", "--cases", str(-(-args.cases // args.workers)),
               "--seed", str(args.seed + w), "--corpus", args.corpus, "--parse-seconds",
               str(args.parse_seconds), "--render-every", str(args.render_every), "--out", str(out)]
        if args.minutes is not None:
            cmd += ["--minutes", str(args.minutes)]
        procs.append(subprocess.Popen(cmd, cwd=ROOT))
    for p in procs:
        p.wait()
    parts = [json.loads(o.read_text()) for o in outs]
    merged = {"cases": sum(p["cases"] for p in parts), "seed": args.seed, "workers": args.workers,
              "corpus": args.corpus, "seeds": parts[0]["seeds"], "parse_limit_s": args.parse_seconds,
              "render_every": args.render_every,
              "wall_s": max(p["wall_s"] for p in parts), "outcomes": {}, "defects": 0, "examples": {}}
    for p in parts:
        for k, v in p["outcomes"].items():
            merged["outcomes"][k] = merged["outcomes"].get(k, 0) + v
        merged["defects"] += p["defects"]
        for k, v in p["examples"].items():
            merged["examples"].setdefault(k, []).extend(v)
    args.out.write_text(json.dumps(merged, indent=1))
    for o in outs:
        o.unlink()
    print(json.dumps({k: v for k, v in merged.items() if k != "examples"}, indent=1))
    return 0 if merged["defects"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
