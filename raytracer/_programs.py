"""Compiled programs kept on disk by what their trace reads, so that a new process renders a scene
of a structure compiled before without tracing, lowering or compiling anything.

JAX's persistent compilation cache keeps XLA's executables, but is keyed by the lowered program: a
process still traces and lowers the render before it can ask (``incdemo/screen.pov`` at 160×120:
2.7 s of a warm-cache render's 6.2 s). Here the key is computed from the program's inputs alone —
the function, the static half of its arguments (the packed scene's skeleton and static tables,
pickled; ``_packing.Frozen`` values by the key the jit cache already compares them by), the
shapes, dtypes and placements of its arrays — and from everything else a trace reads: this
package's source files and native library, the versions of JAX, jaxlib, Equinox and NumPy, JAX's
configuration, the ``RAYTRACER_*``, ``JAX_*`` and ``XLA_*`` environment and the devices. A hit
loads the serialised executable (``jax.experimental.serialize_executable``). A static value that
does not pickle, a program that does not serialise (a JAX host callback), or an unreadable entry falls
back to compiling, which is always right; an entry that fails to load is removed.

Where: ``$RAYTRACER_CACHE_DIR/programs`` (default ``~/.cache/raytracer/xla/programs``; ``off``
turns this off with JAX's cache), at most ``PROGRAM_CACHE_BYTES`` (``$RAYTRACER_PROGRAM_CACHE_MB``),
the least recently used entries removed first. The entries are pickles: trust the folder as you
trust JAX's own cache (it holds executables too).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import io
import os
import pickle
import sys
import tempfile
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import equinox as eqx
import jax

from ._packing import Frozen, is_traced

PROGRAM_CACHE_BYTES = 2 << 30
FORMAT = 1  # of an entry; a change of it, like one of the source, makes every older key miss


def cache_root() -> Path | None:
    """``$RAYTRACER_CACHE_DIR`` (default ``~/.cache/raytracer/xla``): JAX's persistent cache
    (``render.use_compilation_cache``), and the kept programs in ``programs/``; None for ``off``."""
    root = os.environ.get("RAYTRACER_CACHE_DIR", str(Path.home() / ".cache" / "raytracer" / "xla"))
    if not root or root.strip().lower() == "off":
        return None
    return Path(root)


def cache_folder() -> Path | None:
    """The folder of kept programs, or None when the cache is off."""
    root = cache_root()
    return None if root is None else root / "programs"


@functools.cache
def _code_digest() -> str:
    """This package's source and native library, and the libraries that trace and compile."""
    h = hashlib.sha256(str(FORMAT).encode())
    package = Path(__file__).resolve().parent
    for path in sorted(package.rglob("*")):
        if path.suffix in (".py", ".so", ".h") and path.is_file():
            h.update(str(path.relative_to(package)).encode())
            h.update(path.read_bytes())
    for dist in ("jax", "jaxlib", "equinox", "numpy", "ml_dtypes"):
        try:
            h.update(f"{dist}={version(dist)}".encode())
        except PackageNotFoundError:
            h.update(f"{dist}=none".encode())
    h.update(sys.version.encode())
    return h.hexdigest()


def _environment() -> tuple:
    """What a trace or a compile reads besides its arguments and the code."""
    skip = ("cache", "log", "explain", "traceback", "pjrt_client")
    config = tuple(sorted((k, repr(v)) for k, v in jax.config.values.items()
                          if not any(s in k for s in skip)))
    env = tuple(sorted((k, v) for k, v in os.environ.items()
                       if k.startswith(("RAYTRACER_", "JAX_", "XLA_")) and "CACHE" not in k))
    devices = tuple((d.platform, d.device_kind, d.id) for d in jax.local_devices())
    return config, env, devices, jax.process_count()


class _KeyPickler(pickle.Pickler):
    """Pickles a program's static inputs for its key: a ``Frozen`` value by its key, sets in a
    fixed order."""

    def reducer_override(self, obj):
        if isinstance(obj, Frozen):
            return Frozen, (None, obj._key)
        if isinstance(obj, (set, frozenset)):
            return type(obj), (sorted(obj, key=repr),)
        return NotImplemented


def _abstract(x) -> tuple:
    """An array argument as the program sees it: shape, dtype, weak type, placement."""
    if isinstance(x, jax.Array):
        return x.shape, str(x.dtype), x.weak_type, repr(x.sharding)
    return x.shape, str(x.dtype), False, None  # NumPy's: copied to the default device by a call


def key_of(name: str, args: tuple) -> str | None:
    """The key of program ``name`` of ``args`` (arrays and static values), or None when a static
    value does not pickle."""
    return _key(name, *eqx.partition(args, eqx.is_array))


def _key(name: str, dynamic, static) -> str | None:
    arrays = [_abstract(x) for x in jax.tree.leaves(dynamic)]
    buffer = io.BytesIO()
    try:
        _KeyPickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump((name, static, arrays, _environment()))
    except (pickle.PicklingError, TypeError, AttributeError):
        return None
    h = hashlib.sha256(_code_digest().encode())
    h.update(buffer.getvalue())
    return h.hexdigest()


class Program:
    """A compiled program of ``fn(*args)``'s structure: call it with arguments of that structure
    (the same static values; arrays of the same shapes, dtypes and placements). ``loaded`` says
    whether it came from the disk."""

    def __init__(self, compiled, loaded: bool):
        self._compiled, self.loaded = compiled, loaded

    def __call__(self, *args):
        dynamic, _ = eqx.partition(args, eqx.is_array)
        return self._compiled(dynamic)


def compiled(name: str, fn, *args) -> Program:
    """``fn(*args)`` compiled (``fn`` a JAX-traceable function; static values among ``args`` are
    held fixed), or loaded from the folder of kept programs when a process compiled the same
    structure before; a program compiled here is kept there (with the folder off, ``cache_folder``,
    neither). The last ``LIVE_PROGRAMS`` stay loaded in the process: asked again, one is returned
    as it is."""
    return _program(name, fn, *eqx.partition(args, eqx.is_array))


def run(name: str, fn, *args):
    """``fn(*args)`` (``fn`` jit-compiled) by the program :func:`compiled` gives, the arguments split
    once, where its arguments hold values and the folder is on; else ``fn(*args)`` itself: under a
    transform (``jit``, ``vmap``, ``grad``, ``jvp``) it is part of the caller's program, and with the
    folder off its own jit cache keeps it."""
    dynamic, static = eqx.partition(args, eqx.is_array)
    if cache_folder() is None or is_traced(dynamic):
        return fn(*args)
    return _program(name, fn, dynamic, static)._compiled(dynamic)


def _program(name: str, fn, dynamic, static) -> Program:
    fast = _fast_key(name, fn, dynamic, static)
    key = _FAST.get(fast) if fast is not None else None
    if key is None:
        key = _key(name, dynamic, static)
        if fast is not None and key is not None:
            _FAST[fast] = key
            while len(_FAST) > 4 * LIVE_PROGRAMS:
                _FAST.pop(next(iter(_FAST)))
    live = None if key is None else _LIVE.pop(key, None)
    if live is not None:  # this process has it: the most recently used again
        _LIVE[key] = live
        return live
    folder = None if key is None else cache_folder()
    if folder is not None:
        program = _load(folder / key, dynamic)
        if program is not None:
            return _live(key, Program(program, loaded=True))
    lowered = jax.jit(lambda dyn: fn(*eqx.combine(dyn, static))).lower(dynamic)
    if folder is None:
        program = Program(lowered.compile(), loaded=False)
        return program if key is None else _live(key, program)
    with _without_jax_cache():
        program = lowered.compile()
    _store(folder, key, program)
    return _live(key, Program(program, loaded=False))


LIVE_PROGRAMS = 8  # the programs a process keeps loaded (several scenes, frames, re-renders on change)
_LIVE: dict[str, Program] = {}
# this process's keys by what ``jax.jit`` compares (the static values by hash, the arrays' avals and
# placements, JAX's trace context) and the environment: a render of a structure asked for before
# finds its key in ~0.1 ms, not the ~0.4 ms of pickling and hashing it (seed.pov at 160×120 renders
# in ~2.6 ms warm)
_FAST: dict[tuple, str] = {}


def _fast_key(name: str, fn, dynamic, static) -> tuple | None:
    try:
        from jax._src.config import trace_context
        context = trace_context()
    except ImportError:  # a JAX without it: the full key each call
        return None
    arrays = tuple((x.shape, x.dtype, getattr(x, "weak_type", False), getattr(x, "sharding", None))
                   for x in jax.tree.leaves(dynamic))
    env = tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith(("RAYTRACER_", "JAX_", "XLA_"))))
    fast = (name, fn, jax.tree.structure(static), tuple(jax.tree.leaves(static)), arrays, context, env)
    try:
        hash(fast)
    except TypeError:  # a static value without a hash: the full key each call
        return None
    return fast


def _live(key: str, program: Program) -> Program:
    _LIVE[key] = program
    while len(_LIVE) > LIVE_PROGRAMS:
        _LIVE.pop(next(iter(_LIVE)))
    return program


@contextlib.contextmanager
def _without_jax_cache():
    """JAX's persistent compilation cache off: a program kept here is compiled here. (An
    executable that JAX's cache gives serialises without its functions — jaxlib 0.10.2: the copy
    loaded later fails with "NOT_FOUND: Function … not found" — and one kept in both places would
    take the disk twice.) JAX decides once whether its cache is used: reset around the change."""
    from jax.experimental.compilation_cache.compilation_cache import reset_cache

    folder = jax.config.jax_compilation_cache_dir
    if folder is None:
        yield
        return
    reset_cache()
    jax.config.update("jax_compilation_cache_dir", None)
    try:
        yield
    finally:
        reset_cache()
        jax.config.update("jax_compilation_cache_dir", folder)


def _load(path: Path, dynamic):
    from jax.experimental.serialize_executable import deserialize_and_load

    from . import _native

    _native.library()  # its FFI targets (a program's run-time warnings among them) resolve on load
    try:
        blob = path.read_bytes()
    except OSError:
        return None
    try:
        payload, skeleton, n_devices = pickle.loads(blob)
        in_tree = jax.tree.structure(((dynamic,), {}))
        out_tree = jax.tree.structure(skeleton)
        program = deserialize_and_load(payload, in_tree, out_tree,
                                       execution_devices=jax.local_devices()[:n_devices])
    except Exception:  # written by another version, cut short, or not ours: compile instead
        with contextlib.suppress(OSError):
            path.unlink()
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # recently used
    return program


def _store(folder: Path, key: str, program) -> None:
    from jax.experimental.serialize_executable import serialize

    try:
        payload, _, out_tree = serialize(program)
    except (ValueError, NotImplementedError, TypeError):
        return  # a host callback, constants the format cannot hold: compiled each time
    n_devices = len(program.runtime_executable().local_devices())
    skeleton = jax.tree.unflatten(out_tree, [0] * out_tree.num_leaves)
    tmp = None
    try:
        blob = pickle.dumps((payload, skeleton, n_devices), protocol=pickle.HIGHEST_PROTOCOL)
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-")
        with os.fdopen(fd, "wb") as f:
            f.write(blob)
        os.replace(tmp, folder / key)  # whole or not at all: a reader never sees half an entry
    except (OSError, pickle.PicklingError):
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        return
    _trim(folder)


def _limit() -> int:
    try:
        return int(float(os.environ["RAYTRACER_PROGRAM_CACHE_MB"]) * (1 << 20))
    except (KeyError, ValueError):
        return PROGRAM_CACHE_BYTES


def _trim(folder: Path) -> None:
    """Removes the least recently used entries beyond the size limit (and stale temporaries)."""
    entries = []
    for path in folder.iterdir():
        try:
            st = path.stat()
        except OSError:
            continue
        if path.name.startswith(".tmp-"):
            if st.st_mtime < time.time() - 3600:  # a writer that died
                with contextlib.suppress(OSError):
                    path.unlink()
            continue
        entries.append((st.st_mtime, st.st_size, path))
    total, limit = sum(e[1] for e in entries), _limit()
    for _, size, path in sorted(entries):
        if total <= limit:
            break
        with contextlib.suppress(OSError):
            path.unlink()
        total -= size


