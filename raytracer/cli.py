"""The ``raytracer`` command: ``render``, ``info`` and ``validate``.

Scene errors print ``file:line:col: message`` on stderr and exit with status 2 (no traceback).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections import Counter
from pathlib import Path

from .errors import SceneError

EXIT_SCENE_ERROR = 2


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="raytracer",
        description="A differentiable Whitted ray tracer in JAX for POV-Ray scenes.")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a .pov scene to an image",
                       description="Render a POV-Ray scene to a linear EXR or an sRGB PNG.")
    r.add_argument("scene", help="the .pov file")
    r.add_argument("-o", "--output", required=True, help="output image: .exr (linear float32) or .png (sRGB)")
    r.add_argument("-W", "--width", type=int, default=640, help="image width in pixels (default 640)")
    r.add_argument("-H", "--height", type=int, default=480, help="image height in pixels (default 480)")
    r.add_argument("--spp", type=int, default=1,
                   help="samples per pixel: 1 = pixel centres (as POV-Ray -A), k*k = a k×k grid (default 1)")
    r.add_argument("--png16", action="store_true", help="write a 16-bit PNG instead of 8-bit")
    _common(r)

    i = sub.add_parser("info", help="load a scene and print its objects, lights, camera and render plan",
                       description="Load a scene and print what the renderer will simulate.")
    i.add_argument("scene", help="the .pov file")
    i.add_argument("-W", "--width", type=int, default=640, help="image_width seen by the scene")
    i.add_argument("-H", "--height", type=int, default=480, help="image_height seen by the scene")
    _common(i)

    v = sub.add_parser("validate", help="run the validation suite (same as python -m validation)",
                       description="Compare renders with Mitsuba 3 and POV-Ray (see validation/).")
    v.add_argument("args", nargs=argparse.REMAINDER, help="arguments for python -m validation")
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
    # (compiled programs are cached in $RAYTRACER_CACHE_DIR, default ~/.cache/raytracer/xla; "off" disables)
    p.add_argument("--cpu-devices", type=int, default=None, metavar="N",
                   help="split the CPU into N JAX devices and shard tiles over them "
                        "(sets --xla_force_host_platform_device_count; default: JAX's default, 1)")


def _configure_jax(args) -> None:
    import jax

    if args.x64:
        jax.config.update("jax_enable_x64", True)
    # run CPU programs on the calling thread: parse-time trace() makes ~10^5 tiny calls, where
    # the hand-off to XLA's dispatch thread costs ~30 µs each (42 -> 13 µs a call); renders are a
    # few large calls we wait for anyway. Only takes effect before JAX's CPU client exists.
    jax.config.update("jax_cpu_enable_async_dispatch", False)
    # a second render of the same scene structure reuses the compiled program from disk
    cache = os.environ.get("RAYTRACER_CACHE_DIR", str(Path.home() / ".cache" / "raytracer" / "xla"))
    if cache and cache.lower() != "off":
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


def _load(args):
    _configure_jax(args)
    from .sdl import Animation, load_scene

    if not Path(args.scene).is_file():
        raise SceneError(f"cannot open scene file {args.scene!r}")
    animation = None
    if args.ini is not None:
        animation = Animation.from_ini(args.ini, frame=args.frame)
    elif args.frame is not None:
        animation = Animation(frame=args.frame, initial_frame=args.frame, final_frame=args.frame)
    t0 = time.perf_counter()
    scene = load_scene(args.scene, include_paths=tuple(args.include_path), strict=args.strict,
                       width=args.width, height=args.height, animation=animation)
    return scene, time.perf_counter() - t0


def _summary(scene) -> list[str]:
    from .render import plan

    p = plan(scene)
    kinds = Counter(prim.kind for prim in p.prims if prim.rendered)
    loc, d, r, u = (v.tolist() for v in scene.camera.frame())
    lines = [
        "objects: " + (", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"),
        f"lights: {len(scene.lights)}"
        + "".join(f"\n  {_light_text(light)}" for light in scene.lights),
        f"camera: {scene.camera.projection} at {_vec(loc)} direction {_vec(d)} right {_vec(r)} up {_vec(u)}",
        f"plan: {p.effects.describe()}",
        f"warnings: {len(p.warnings)}",
    ]
    lines += [f"  {w}" for w in p.warnings]
    return lines


def _vec(v) -> str:
    return "<" + ", ".join(f"{float(x) + 0.0:.4g}" for x in v) + ">"  # + 0.0: no "-0"


def _light_text(light) -> str:
    kind = "parallel" if light.parallel else "spotlight" if light.spot is not None else "point"
    extra = []
    if light.area is not None:
        extra.append(f"area {light.area.size1}x{light.area.size2}")
    if light.shadowless:
        extra.append("shadowless")
    if light.fade_distance is not None:
        extra.append("fade")
    return f"{kind} at {_vec(light.position.tolist())} colour {_vec(light.color.tolist())}" + (
        f" ({', '.join(extra)})" if extra else "")


class _Progress:
    """A one-line progress bar on stderr, shown only for renders that take more than a second."""

    def __init__(self):
        self.start = time.perf_counter()
        self.shown = False

    def __call__(self, done: int, total: int) -> None:
        elapsed = time.perf_counter() - self.start
        if not self.shown and elapsed < 1.0 and done < total:
            return
        if not sys.stderr.isatty() and done < total:
            return
        self.shown = True
        width = 30
        filled = width * done // total
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} {elapsed:5.1f} s")
        if done == total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _render(args) -> int:
    import jax

    from .imageio import write_image
    from .render import compile_render

    out = Path(args.output)
    if out.suffix.lower() not in (".exr", ".png"):
        print(f"raytracer: unsupported output format {out.suffix!r}: use .exr or .png", file=sys.stderr)
        return EXIT_SCENE_ERROR
    if not out.parent.exists():
        print(f"raytracer: output folder {str(out.parent)!r} does not exist", file=sys.stderr)
        return EXIT_SCENE_ERROR
    scene, t_parse = _load(args)
    for line in _summary(scene):
        print(line)
    if math.isqrt(args.spp) ** 2 != args.spp or args.spp < 1:
        print(f"raytracer: --spp must be a perfect square (1, 4, 9, 16, …), got {args.spp}", file=sys.stderr)
        return EXIT_SCENE_ERROR
    t0 = time.perf_counter()
    progress = _Progress()
    run = compile_render(scene, width=args.width, height=args.height, spp=args.spp, progress=progress)
    t_compile = time.perf_counter() - t0
    progress.start = time.perf_counter()
    t1 = time.perf_counter()
    image = jax.block_until_ready(run(scene))
    t_render = time.perf_counter() - t1
    write_image(out, image, bits=16 if args.png16 else 8)
    print(f"resolution: {args.width}x{args.height}, {args.spp} spp, "
          f"{'float64' if jax.config.jax_enable_x64 else 'float32'}, devices: {len(jax.devices())}")
    print(f"times: parse {t_parse:.2f} s, compile {t_compile:.2f} s, render {t_render:.2f} s")
    print(f"wrote {out}")
    return 0


def _info(args) -> int:
    scene, t_parse = _load(args)
    print(f"scene: {args.scene} (parsed in {t_parse:.2f} s)")
    for line in _summary(scene):
        print(line)
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["validate"]:  # every option goes to python -m validation unchanged
        from validation.__main__ import main as validate_main

        return validate_main(argv[1:])
    args = _parser().parse_args(argv)
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    if getattr(args, "cpu_devices", None):  # must precede the first import of jax
        flag = f"--xla_force_host_platform_device_count={args.cpu_devices}"
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + flag).strip()
    try:
        if args.command == "render":
            return _render(args)
        if args.command == "info":
            return _info(args)
        if args.command == "validate":
            from validation.__main__ import main as validate_main

            return validate_main(args.args)
    except SceneError as e:
        print(f"raytracer: {e}", file=sys.stderr)
        return EXIT_SCENE_ERROR
    except KeyboardInterrupt:
        print("raytracer: interrupted", file=sys.stderr)
        return 130
    return 1


if __name__ == "__main__":
    sys.exit(main())
