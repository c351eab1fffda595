"""The ``raytracer`` command: ``render``, ``info`` and ``validate``.

Exit status: 0 done; 2 an error in the scene or on the command line (``file:line:col: message`` or
the option at fault, one line on stderr); 70 an internal error (a bug in raytracer: one line, the
traceback with ``--debug``); 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import time
import traceback
from collections import Counter
from pathlib import Path

from ._xla import split_cpu, tune_xla_flags
from .errors import InternalError, SceneError, short_numbers

EXIT_SCENE_ERROR = 2  # also a bad command line, as argparse
EXIT_INTERNAL_ERROR = 70  # EX_SOFTWARE of sysexits.h: the program failed, not its input
EXIT_INTERRUPTED = 130


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (``raytracer render: -W: expected …``), status 2."""

    def error(self, message: str):
        self.exit(EXIT_SCENE_ERROR, f"{self.prog}: {message} (see {self.prog} --help)\n")


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("raytracer")
    except PackageNotFoundError:  # run from a checkout that is not installed
        return "unknown"


def _positive_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        x = float("nan")
    if not (0 < x < float("inf")):
        raise argparse.ArgumentTypeError(
            f"expected a positive number of seconds, found {short_numbers(repr(text))}")
    return x


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
        text = repr(text)
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, found {short_numbers(text)}")
    return n


def _threshold(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        x = float("nan")
    if not (0 <= x < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a threshold ≥ 0, found {short_numbers(repr(text))}")
    return x


def _samples_per_pixel(text: str) -> int:
    n = _positive_int(text)
    if math.isqrt(n) ** 2 != n:
        raise argparse.ArgumentTypeError(f"expected a perfect square (1, 4, 9, 16, …), found {n}")
    return n


_POVRAY_EPILOG = ("POV-Ray's options read here: Input_File_Name (+I), Output_File_Name (+O), "
                  "Width (+W), Height (+H), Output_File_Type (+F: N, E, T, C, P, J, B; N16 16-bit), "
                  "Bits_Per_Color, Antialias (+A), Antialias_Threshold, Antialias_Depth (+R), "
                  "Antialias_Gamma (+AG), Library_Path (+L), Initial_Frame (+KFI), Final_Frame "
                  "(+KFF), Initial_Clock (+KI), Final_Clock (+KF), Cyclic_Animation (+KC), Clock (+K), "
                  "Subset_Start_Frame (+SF), Subset_End_Frame (+EF). Accepted without effect (no "
                  "preview window, no effect on the image): Display off (-D), Pause_When_Done, "
                  "Verbose, Test_Abort, tile order, bounding and thread options.")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="raytracer",
        description="A differentiable Whitted ray tracer in JAX for POV-Ray scenes.")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a .pov scene to an image",
                       description="Render a POV-Ray scene to a linear EXR or an sRGB PNG. "
                                   "POV-Ray's own options work too, in the order given, the last "
                                   "winning: switches (+W640 +H480 +Iscene.pov +Oout.png +A0.3 +R3 "
                                   "+FN16 +FE +L/dir +KFI1 +KFF20 …), Key=Value words and INI files "
                                   "(Width=640, scene.ini, scene.ini[section]); the options below "
                                   "win over them. An INI file or switches that declare an "
                                   "animation render each of its frames (Subset_Start_Frame … "
                                   "honoured). Options that would change the image and are not "
                                   "followed here are named in one warning.",
                       epilog=_POVRAY_EPILOG)
    r.add_argument("inputs", nargs="*", metavar="SCENE | OPTION",
                   help="the .pov file (or several: rendered one after the other in this process, "
                        "scenes of one structure by one compiled program; -o names a folder), "
                        "POV-Ray switches, Key=Value options and .ini files")
    r.add_argument("-o", "--output", default=None,
                   help="output image: .exr (linear float32), .png (sRGB), or .tga .ppm .jpg .bmp "
                        "(8-bit sRGB; default: the scene's name with the output type's suffix, "
                        "as POV-Ray names it)")
    r.add_argument("-W", "--width", type=_positive_int, default=None,
                   help="image width in pixels (default 640)")
    r.add_argument("-H", "--height", type=_positive_int, default=None,
                   help="image height in pixels (default 480)")
    r.add_argument("--spp", type=_samples_per_pixel, default=1,
                   help="samples per pixel: 1 = pixel centres (as POV-Ray -A), k*k = a k×k grid (default 1)")
    r.add_argument("--png16", action="store_true", help="write a 16-bit PNG instead of 8-bit")
    r.add_argument("--aa", type=_threshold, default=None, metavar="THRESHOLD",
                   help="adaptive anti-aliasing as POV-Ray's +A THRESHOLD +AM1 -J: pixels on either "
                        "side of a colour difference of at least THRESHOLD get --aa-depth² more rays")
    r.add_argument("--aa-depth", type=_positive_int, default=None, metavar="N",
                   help="the grid of a refined pixel, N×N rays (POV-Ray's +R; default 3)")
    r.add_argument("--aa-gamma", type=_positive_float, default=None, metavar="G",
                   help="colours are compared raised to 1/G (POV-Ray's +AG, Antialias_Gamma; default 2.5)")
    r.add_argument("--watch", action="store_true",
                   help="keep running: render again, with the programs already compiled, whenever the "
                        "scene or a file it includes changes (Ctrl-C stops)")
    r.add_argument("--all-frames", action="store_true",
                   help="render every frame of the --ini animation, to OUTPUT with the frame number "
                        "before its suffix (out.png: out01.png, out02.png, … as POV-Ray names them)")
    d = r.add_argument_group(
        "several processes or machines (jax.distributed; start one command per process)",
        "Every process renders part of each image's tiles and process 0 writes it; with "
        "--all-frames each process renders whole frames instead (the k-th frame on process k mod N).")
    d.add_argument("--coordinator", metavar="HOST:PORT", help="address of process 0")
    d.add_argument("--num-processes", type=_positive_int, metavar="N", help="how many processes take part")
    d.add_argument("--process-id", type=int, metavar="I", help="this process's index, 0 … N-1")
    _common(r)

    i = sub.add_parser("info", help="load a scene and print its objects, lights, camera and render plan",
                       description="Load a scene and print what the renderer will simulate (POV-Ray's "
                                   "options and INI files as for render).")
    i.add_argument("inputs", nargs="*", metavar="SCENE | OPTION",
                   help="the .pov file, POV-Ray switches, Key=Value options and .ini files")
    i.add_argument("-W", "--width", type=_positive_int, default=None, help="image_width seen by the scene")
    i.add_argument("-H", "--height", type=_positive_int, default=None, help="image_height seen by the scene")
    _common(i)

    v = sub.add_parser("validate", help="run the validation suite (same as python -m validation)",
                       description="Compare renders with Mitsuba 3 and POV-Ray (see validation/).")
    v.add_argument("args", nargs=argparse.REMAINDER, help="arguments for python -m validation")
    c = sub.add_parser("compare", help="render a scene with us and with POV-Ray (or Mitsuba) side by side",
                       description="Render one's own scene with us and with POV-Ray or Mitsuba 3 at the "
                                   "same pixel centres: PSNR, the worst region, a side-by-side PNG "
                                   "(raytracer compare --help for its options).")
    c.add_argument("args", nargs=argparse.REMAINDER, help="the scene and its options")
    return p


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("-L", "--include-path", action="append", default=[], metavar="DIR",
                   help="extra folder to search for #include files (repeatable)")
    p.add_argument("--strict", action="store_true",
                   help="treat unsupported features as errors instead of warnings")
    p.add_argument("--ini", metavar="FILE",
                   help="POV-Ray INI whose animation options (Initial_Frame … Final_Clock) apply")
    p.add_argument("--frame", type=int, default=None, metavar="N",
                   help="animation frame to load (sets clock and frame_number; default: the "
                        "INI's first frame, or no animation)")
    p.add_argument("--x64", action="store_true", help="render in float64 (jax_enable_x64)")
    p.add_argument("--parse-timeout", type=_positive_float, default=None, metavar="SECONDS",
                   help="stop parsing a scene after this many seconds (default 600)")
    p.add_argument("--debug", action="store_true",
                   help="print the Python traceback of an error (for reporting an internal error)")
    # (compiled programs are kept in $RAYTRACER_CACHE_DIR, default ~/.cache/raytracer/xla: XLA's
    # cache, and in programs/ the renders' whole programs, raytracer/_programs.py; "off" disables)
    p.add_argument("--cpu-devices", type=_positive_int, default=None, metavar="N",
                   help="split the CPU into N JAX devices and shard tiles over them "
                        "(sets --xla_force_host_platform_device_count; default: the cores this "
                        "process may use, unless XLA_FLAGS sets it)")


def _configure_jax(args) -> None:
    import jax

    if args.x64:
        jax.config.update("jax_enable_x64", True)
    # run CPU programs on the calling thread: parse-time trace() makes ~10^5 tiny calls, where
    # the hand-off to XLA's dispatch thread costs ~30 µs each (42 -> 13 µs a call); renders are a
    # few large calls we wait for anyway. Only takes effect before JAX's CPU client exists.
    jax.config.update("jax_cpu_enable_async_dispatch", False)
    # a second render of the same scene structure reuses the compiled program from disk
    from .render import use_compilation_cache

    use_compilation_cache()


def _povray_options(args, argv: list[str], extras: list[str]) -> None:
    """POV-Ray's switches, ``Key=Value`` words and INI files among the command's words, read in
    their order (``raytracer.sdl._options``), into ``args``: the scene, the library paths, the
    size, the output file and type, anti-aliasing and the animation (``args.pov``); the command's
    own options win over them."""
    from .sdl._options import OUTPUT_TYPES, read_options

    position = {}
    for i, word in enumerate(argv):
        position.setdefault(word, i)
    words = sorted([*args.inputs, *extras], key=lambda w: position.get(w, len(argv)))
    opts = read_options(words)
    args.pov = opts
    if opts.input is None:
        raise _CommandLineError("no scene: name a .pov file (or +I<file>, Input_File_Name=<file>)")
    args.scene = str(_find_scene(opts))
    args.include_path = [*opts.library_paths, *args.include_path]
    args.width = args.width or opts.width or 640
    args.height = args.height or opts.height or 480
    if opts.ignored:
        print("raytracer: warning: POV-Ray options not followed here: " + ", ".join(opts.ignored),
              file=sys.stderr)
    if args.command != "render":
        return
    suffix = OUTPUT_TYPES[opts.output_type or "N"]
    out = args.output if args.output is not None else opts.output
    if out == "-":
        raise _CommandLineError("the image is not written to standard output: name a file")
    name = Path(args.scene).stem + suffix
    if out is None:
        out = name
    elif out.endswith(("/", os.sep)):  # a folder, as POV-Ray reads a trailing separator
        out = str(Path(out) / name)
    elif not Path(out).suffix:
        out += suffix  # POV-Ray adds the type's suffix to a name without one
    args.output = out
    args.bits = 16 if args.png16 or (opts.bits or 8) > 8 else 8
    args.rle = opts.output_type == "C"
    if args.aa is None and opts.antialias:
        args.aa = 0.3 if opts.threshold is None else opts.threshold  # POV-Ray's default threshold
    args.aa_depth = args.aa_depth or opts.depth or 3
    args.aa_gamma = args.aa_gamma or opts.aa_gamma or 2.5


def _find_scene(opts) -> Path:
    """The scene file POV-Ray would read: as named, next to the INI file that named it, or in a
    library path; ``.pov`` added to a name without a suffix."""
    name = Path(opts.input)
    names = [name] if name.suffix else [name.with_suffix(".pov"), name]
    folders = [Path("."), *([Path(opts.input_base)] if opts.input_base else []),
               *(Path(p) for p in opts.library_paths)]
    for n in names:
        for folder in ([Path(".")] if n.is_absolute() else folders):
            if (folder / n).is_file():
                return folder / n
    raise SceneError(f"cannot open scene file {opts.input!r}")


def _animation(args, frame: int | None):
    """The animation of ``--ini``, or of POV-Ray's options on the command line (None: none)."""
    from .sdl import Animation

    if args.ini is not None:
        return Animation.from_ini(args.ini, frame=frame)
    opts = getattr(args, "pov", None)
    if opts is not None and (opts.animated or opts.clock is not None):
        return Animation.from_options(opts, frame=frame)
    if frame is not None:
        return Animation(frame=frame, initial_frame=frame, final_frame=frame)
    return None


def _harmless(text: str) -> str:
    """``text`` with its control characters (but newline and tab) shown as escapes: a scene's
    message cannot move the cursor, recolour or clear the terminal."""
    return "".join(c if c in "\n\t" or not (ord(c) < 32 or 127 <= ord(c) < 160) else f"\\x{ord(c):02x}"
                   for c in text)


class _SceneMessages(logging.Handler):
    """A scene's ``#debug``, ``#render`` and ``#statistics`` text on stderr as POV-Ray prints it
    (as written, no line added), its ``#warning`` as ``file:line:col: warning: text``; escapes made
    harmless. The scene's own warnings are left to the summary that lists them."""

    def emit(self, record):
        kind = getattr(record, "directive", None)
        if kind is None:
            return
        text = _harmless(record.text)
        if kind == "warning":
            sys.stderr.write(f"{record.location}: warning: {text.rstrip(chr(10))}\n")
        else:
            sys.stderr.write(text)
        sys.stderr.flush()


def _show_scene_messages() -> None:
    sdl_logger = logging.getLogger("raytracer.sdl")
    if not any(isinstance(h, _SceneMessages) for h in sdl_logger.handlers):
        sdl_logger.addHandler(_SceneMessages(logging.DEBUG))
        sdl_logger.setLevel(logging.DEBUG)


def _load(args):
    _configure_jax(args)
    _show_scene_messages()
    from .sdl import Limits, load_scene

    animation = _animation(args, args.frame)
    t0 = time.perf_counter()
    limits = None if args.parse_timeout is None else Limits(max_parse_seconds=args.parse_timeout)
    # an image, not a gradient: a filter or transmit written as 0 is opaque, as POV-Ray renders it
    with _Phase("parse"):
        scene = load_scene(args.scene, include_paths=tuple(args.include_path), strict=args.strict,
                           width=args.width, height=args.height, animation=animation, limits=limits,
                           fit_zero_terms=False, files=getattr(args, "files", None))
    return scene, time.perf_counter() - t0


def _summary(scene) -> list[str]:
    from .render import plan

    p = plan(scene)
    kinds = Counter(prim.kind for prim in p.prims if prim.rendered)
    loc, d, r, u = (v.tolist() for v in scene.camera.frame())
    lights = [_light_text(light) for light in scene.lights]
    light_kinds = Counter(text.split(" at ", 1)[0] for text in lights)
    features = Counter(w.feature for w in p.warnings)
    lines = [
        "objects: " + (", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"),
        f"lights: {len(lights)}" + _counts(light_kinds, len(lights)) + _listed(lights),
        f"camera: {scene.camera.projection} at {_vec(loc)} direction {_vec(d)} right {_vec(r)} up {_vec(u)}",
        f"plan: {p.effects.describe()}",
        _acceleration_text(p),
        f"warnings: {len(p.warnings)}" + _counts(features, len(p.warnings)) + _listed(p.warnings),
    ]
    return lines


SUMMARY_ITEMS = 8  # a longer list of lights or warnings is counted by kind and shown in part


def _counts(counter: Counter, total: int) -> str:
    if total <= SUMMARY_ITEMS:
        return ""
    return " (" + ", ".join(f"{n} {k}" for k, n in counter.most_common()) + f"), the first {SUMMARY_ITEMS}:"


def _listed(items) -> str:
    shown = "".join(f"\n  {item}" for item in list(items)[:SUMMARY_ITEMS])
    more = len(items) - SUMMARY_ITEMS
    return shown + (f"\n  … {more} more" if more > 0 else "")


def _acceleration_text(p) -> str:
    from .shading import _accel
    from .shading._geometry import hierarchy_choice, native_items

    if _accel.mode() == "none":
        why = _accel.unavailable_reason() or "RAYTRACER_ACCEL=none"
        return f"acceleration: none ({why}): every ray tests every primitive"
    held, csg = hierarchy_choice(p)
    in_csg = set(csg)
    members = sum(1 for u in p.prim_unit if u in in_csg)
    n = sum(held) + members
    if not n:
        return (f"acceleration: none (fewer than {_accel.MIN_ITEMS} primitives or triangles it can hold, "
                "none of them a CSG object, torus, superellipsoid or polynomial): "
                "every ray tests every primitive")
    items = len(csg) + sum(native_items(prim.obj.shape) for prim, ok in zip(p.prims, held, strict=True) if ok)
    objects = f", {len(csg)} of them CSG objects of {members} primitives" if csg else ""
    return (f"acceleration: {_accel.mode()} BVH over {n} of {len(p.prims)} primitives "
            f"({items} items{objects}); every ray tests the other {len(p.prims) - n}")


def _vec(v) -> str:
    return "<" + ", ".join(f"{float(x) + 0.0:.4g}" for x in v) + ">"  # + 0.0: no "-0"


def _light_text(light) -> str:
    from .scene._lights import light_types
    types = light_types(light)
    kind = next(t.name for t in types if not t.modifier)
    extra = [t.describe(light) if t.describe else t.name for t in types if t.modifier]
    return f"{kind} at {_vec(light.position.tolist())} colour {_vec(light.color.tolist())}" + (
        f" ({', '.join(extra)})" if extra else "")


PROGRESS_MIN_RAYS = 320 * 240  # an image of fewer camera rays renders without a progress bar


class _Progress:
    """The trace's parts as a tqdm bar with its ETA on stderr, shown only on a terminal and only for
    a render that takes more than a second."""

    def __init__(self):
        self.bar = None
        self.start = time.time()  # the render's start: the first part's time counts

    def __call__(self, done: int, total: int) -> None:
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="trace", unit="part", file=sys.stderr, delay=1.0,
                            disable=not sys.stderr.isatty(), leave=False)
            self.bar.start_t = self.start
        self.bar.update(done - self.bar.n)
        if done == total:
            self.bar.close()


class _Phase:
    """A phase whose length nothing inside can report (the parse, XLA's compile): its elapsed time
    on stderr while it runs (a tqdm counter refreshed from a thread), only on a terminal and only
    after a second."""

    def __init__(self, name: str):
        self.name = name
        self.thread = None

    def __enter__(self):
        if not sys.stderr.isatty():
            return self
        import threading

        self.stop = threading.Event()
        start = time.time()

        def tick():
            if self.stop.wait(1.0):
                return
            from tqdm import tqdm

            with tqdm(desc=self.name, bar_format="{desc}: {elapsed}", file=sys.stderr, leave=False) as bar:
                bar.start_t = start  # the phase's time, not the bar's
                while not self.stop.wait(0.25):
                    bar.refresh()

        self.thread = threading.Thread(target=tick, daemon=True)
        self.thread.start()
        return self

    def __exit__(self, *exc):
        if self.thread is not None:
            self.stop.set()
            self.thread.join()
        return False


def _distributed(args) -> bool:
    """Starts ``jax.distributed`` when the command line asks for several processes."""
    given = [args.coordinator is not None, args.num_processes is not None, args.process_id is not None]
    if not any(given):
        return False
    if not all(given):
        raise _CommandLineError("--coordinator, --num-processes and --process-id go together")
    if not 0 <= args.process_id < args.num_processes:
        raise _CommandLineError(
            f"--process-id must be in 0 … {args.num_processes - 1}, found {args.process_id}")
    _configure_jax(args)
    from .distributed import initialize

    initialize(args.coordinator, args.num_processes, args.process_id)
    return True


class _CommandLineError(Exception):
    pass


def _frame_output(out: Path, frame: int, final: int) -> Path:
    """POV-Ray's animation file names: the frame number, zero-padded to the final frame's digits,
    before the suffix."""
    return out.with_name(f"{out.stem}{frame:0{len(str(final))}d}{out.suffix}")


def _render(args) -> int:
    out = Path(args.output)
    problem = _output_problem(out)
    if problem is not None:
        print(f"raytracer: cannot write {str(out)!r}: {problem}", file=sys.stderr)
        return EXIT_SCENE_ERROR
    try:
        from ._limits import check_render_memory

        check_render_memory(args.width, args.height, 8 if args.x64 else 4)  # before the scene is read
    except SceneError as e:
        print(f"raytracer: {e}", file=sys.stderr)
        return EXIT_SCENE_ERROR
    anim = _animation(args, None)
    try:
        if args.all_frames and anim is None:
            raise _CommandLineError("--all-frames needs an animation (--ini, or POV-Ray's frame options)")
        if args.all_frames and args.frame is not None:
            raise _CommandLineError("--all-frames and --frame exclude each other")
        if args.aa is not None and args.spp != 1:
            raise _CommandLineError("--aa starts from one ray per pixel centre: leave --spp at 1")
        if args.aa is not None and args.coordinator is not None and not args.all_frames:
            raise _CommandLineError("--aa is not split across processes (use it with --all-frames, "
                                    "or in one process)")
        distributed = _distributed(args)
    except _CommandLineError as e:
        print(f"raytracer render: {e} (see raytracer render --help)", file=sys.stderr)
        return EXIT_SCENE_ERROR
    # POV-Ray's options that declare frames render them all, as POV-Ray does (--ini: with --all-frames)
    several = anim is not None and anim.final_frame > anim.initial_frame
    frames = args.all_frames or (several and args.ini is None and args.frame is None)
    if args.watch:
        if frames or distributed:
            print("raytracer render: --watch renders one image in one process (not with several "
                  "frames or processes) (see raytracer render --help)", file=sys.stderr)
            return EXIT_SCENE_ERROR
        return _watch(args, out)
    if not frames:
        return _render_frame(args, out, distributed)
    import jax

    _configure_jax(args)
    start, end = args.pov.subset_start, args.pov.subset_end
    frames = [f for f in range(anim.initial_frame, anim.final_frame + 1)
              if (start is None or f >= start) and (end is None or f <= end)]
    if distributed:  # whole frames per process: no collective per frame
        frames = frames[jax.process_index()::jax.process_count()]
    for frame in frames:
        args.frame = frame
        status = _render_frame(args, _frame_output(out, frame, anim.final_frame), distributed=False)
        if status:
            return status
    return 0


_sleep = time.sleep  # (a test's clock)
WATCH_POLL_S = 0.25


def _stamps(files) -> dict:
    """Each file's modification time and size (None: gone)."""
    out = {}
    for f in files:
        try:
            st = os.stat(f)
            out[f] = (st.st_mtime_ns, st.st_size)
        except OSError:
            out[f] = None
    return out


def _watch(args, out: Path) -> int:
    """Renders the scene, then again whenever it or a file it includes changes, in this process:
    the programs compiled stay loaded (``raytracer/_programs.py``), so a re-render of an edit that
    keeps the structure pays for the parse and the render only. A scene that fails to load is
    reported and watched on. Ctrl-C stops (status 0)."""
    try:
        while True:
            args.files = set()
            try:
                status = _render_frame(args, out, distributed=False)
            except SceneError as e:
                print(f"raytracer: {_harmless(str(e))}", file=sys.stderr)
                status = EXIT_SCENE_ERROR
            files = args.files or {args.scene}
            seen = _stamps(files)
            print(f"raytracer: watching {len(files)} file{'s' if len(files) != 1 else ''} "
                  f"(status {status}; Ctrl-C stops)", flush=True)
            while _stamps(files) == seen:
                _sleep(WATCH_POLL_S)
            print("raytracer: changed: rendering again", flush=True)
    except KeyboardInterrupt:
        print("raytracer: stopped watching", file=sys.stderr)
        return 0


class _InterruptAnywhere:
    """Ctrl-C ends the process at once while XLA compiles or runs (C++ that does not return to
    Python, where a KeyboardInterrupt would wait for it): SIGINT's default action, status 130 as the
    shell reports it. Nothing is written in these phases, so there is nothing to clean up; the
    image is written after, with Python's handler back (an atomic write removes its temporary)."""

    def __enter__(self):
        import signal
        import threading

        self.old = None
        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, signal.SIG_DFL)
        return self

    def __exit__(self, *exc):
        import signal

        if self.old is not None:
            signal.signal(signal.SIGINT, self.old)
        return False


def _compute(args, scene, distributed: bool):
    """The image (compiled with a progress bar, adaptive, or split across the processes of
    ``jax.distributed``) and the compile and render times."""
    import jax

    from .render import compile_render

    t0 = time.perf_counter()
    if distributed:
        from .distributed import render

        image = jax.block_until_ready(render(scene, width=args.width, height=args.height, spp=args.spp))
        t_compile, t_render = 0.0, time.perf_counter() - t0
    elif args.aa is not None:
        from .render import render

        with _Phase("compile and trace"):
            image = jax.block_until_ready(render(scene, width=args.width, height=args.height,
                                                 adaptive=(args.aa, args.aa_depth, args.aa_gamma)))
        t_compile, t_render = 0.0, time.perf_counter() - t0
    else:
        # the parts of a progress bar only where one can be shown and the image is large: in parts
        # the render costs a call and a sync a part, and the parts are assembled by a program of
        # their own, compiled in each process (incdemo/texture1.pov at 160×120, warm cache: render
        # 0.37–0.44 s in 16 parts, the whole image in one program 0.16 s)
        rays = args.width * args.height * args.spp
        progress = _Progress() if sys.stderr.isatty() and rays >= PROGRESS_MIN_RAYS else None
        with _Phase("compile"):
            run = compile_render(scene, width=args.width, height=args.height, spp=args.spp,
                                 progress=progress)
        t_compile = time.perf_counter() - t0
        if progress is not None:
            progress.start = time.time()
        t1 = time.perf_counter()
        image = jax.block_until_ready(run(scene))
        t_render = time.perf_counter() - t1
    return image, t_compile, t_render


def _render_frame(args, out: Path, distributed: bool) -> int:
    """One image: compiled with a progress bar, or split across the processes of ``jax.distributed``
    (process 0 writes it)."""
    import jax

    from .imageio import ImageClampWarning, write_image

    scene, t_parse = _load(args)
    lead = not distributed or jax.process_index() == 0
    if lead:
        for line in _summary(scene):
            print(line)
    with _InterruptAnywhere():
        image, t_compile, t_render = _compute(args, scene, distributed)
    if not lead:
        return 0
    import warnings

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ImageClampWarning)
            write_image(out, image, bits=args.bits, rle=args.rle)
        for w in caught:
            print(f"raytracer: warning: {w.message}", file=sys.stderr)
    except OSError as e:  # the folder changed since the check, or the disk is full
        print(f"raytracer: cannot write {str(out)!r}: {e.strerror or e}", file=sys.stderr)
        return EXIT_SCENE_ERROR
    where = (f"processes: {jax.process_count()}, devices: {jax.device_count()}" if distributed
             else f"devices: {len(jax.devices())}")
    print(f"resolution: {args.width}x{args.height}, {args.spp} spp, "
          f"{'float64' if jax.config.jax_enable_x64 else 'float32'}, {where}")
    together = distributed or args.aa is not None
    times = (f"parse {t_parse:.2f} s, compile and render {t_render:.2f} s" if together
             else f"parse {t_parse:.2f} s, compile {t_compile:.2f} s, render {t_render:.2f} s")
    print(f"times: {times}")
    print(f"wrote {out}")
    return 0


def _output_problem(out: Path) -> str | None:
    """Why the image cannot be written to ``out`` (checked before the scene is parsed), or None."""
    from .imageio import WRITTEN_SUFFIXES

    if out.suffix.lower() not in WRITTEN_SUFFIXES:
        return f"unsupported output format {out.suffix!r}: use one of {', '.join(WRITTEN_SUFFIXES)}"
    if out.is_dir():
        return "it is a folder; name the image file"
    folder = out.parent
    if not folder.exists():
        return f"the output folder {str(folder)!r} does not exist"
    if not folder.is_dir():
        return f"{str(folder)!r} is not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"the output folder {str(folder)!r} is not writable"
    if out.exists() and not os.access(out, os.W_OK):
        return "the file exists and is not writable"
    return None


def _info(args) -> int:
    scene, t_parse = _load(args)
    print(f"scene: {args.scene} (parsed in {t_parse:.2f} s)")
    for line in _summary(scene):
        print(line)
    return 0


def _split_cpu(devices: int | None) -> None:
    """The XLA flags the renderer was measured with (``raytracer/_xla.py``) and one JAX device per
    core, or ``devices`` (``--cpu-devices``): tiles are sharded over the devices (a 640×480 render
    of the Whitted benchmark scene took 1.22 s on 2 devices against 1.9 s on one, 2 cores;
    ``benchmarks/distributed.py``). XLA_FLAGS naming a device count wins over the default."""
    tune_xla_flags()
    split_cpu(devices)


def _plugin(name: str):
    """The ``raytracer.commands`` entry point ``name`` (``validate`` is ``validation``'s main, declared
    in pyproject.toml): the package never imports ``validation``, which sits above it."""
    from importlib.metadata import entry_points

    found = list(entry_points(group="raytracer.commands", name=name))
    if not found:
        raise SystemExit(f"raytracer: the {name} command is not installed (pip install -e '.[validation]')")
    return found[0].load()


def _scene_words(args) -> list[str]:
    """The ``.pov`` files among the render command's words."""
    return [w for w in args.inputs if w.lower().endswith(".pov") and not w.startswith(("+", "-"))]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] in (["validate"], ["compare"]):  # every option goes to the plugin unchanged
        os.environ.setdefault("JAX_PLATFORMS", "cpu")
        return _plugin(argv[0])(argv[1:])
    parser = _parser()
    args, extras = parser.parse_known_args(argv)
    scenes = _scene_words(args) if args.command == "render" else []
    if len(scenes) > 1:  # one after the other, in this process: one compiled program per structure
        if args.output is not None and not args.output.endswith(("/", os.sep)):
            parser.error(f"{len(scenes)} scenes: -o names a folder (ending in /), where each image "
                         "takes its scene's name")
        if args.watch:
            parser.error("--watch watches one scene")
        status = 0
        for scene in scenes:
            status = max(status, _main([w for w in argv if w == scene or w not in scenes]))
        return status
    return _main(argv, parser, args, extras)


def _main(argv: list[str], parser=None, args=None, extras=None) -> int:
    if parser is None:
        parser = _parser()
        args, extras = parser.parse_known_args(argv)
    if args.command not in ("render", "info") and extras or any(x.startswith("--") for x in extras):
        parser.error(f"unrecognized arguments: {' '.join(extras)}")
    if args.command in ("render", "info"):
        try:
            _povray_options(args, argv, extras)
        except _CommandLineError as e:
            print(f"raytracer {args.command}: {e} (see raytracer {args.command} --help)", file=sys.stderr)
            return EXIT_SCENE_ERROR
        except SceneError as e:
            print(f"raytracer: {e}", file=sys.stderr)
            return EXIT_SCENE_ERROR
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    if args.command == "render":  # must precede the first import of jax
        _split_cpu(args.cpu_devices)
    debug = getattr(args, "debug", False)
    try:
        if args.command == "render":
            return _render(args)
        if args.command == "info":
            return _info(args)
        if args.command in ("validate", "compare"):
            return _plugin(args.command)(args.args)
    except SceneError as e:
        if debug:
            traceback.print_exc()
        print(f"raytracer: {_harmless(str(e))}", file=sys.stderr)  # an #error's text is the scene's
        return EXIT_SCENE_ERROR
    except KeyboardInterrupt:
        print("raytracer: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:  # a bug (InternalError from the parser, anything from the renderer)
        if debug:
            traceback.print_exc()
        text = str(e) if isinstance(e, InternalError) else \
            f"internal error (a bug in raytracer, not in the scene): {type(e).__name__}: {e}"
        hint = "" if debug else " (run with --debug for the traceback)"
        print(f"raytracer: {text.splitlines()[0] if text else type(e).__name__}{hint}", file=sys.stderr)
        return EXIT_INTERNAL_ERROR
    return 1


if __name__ == "__main__":
    sys.exit(main())
