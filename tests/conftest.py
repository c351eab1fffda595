"""Shared test configuration: strict JAX numerics, CPU only, one compilation cache per test run, the
float64 fixture, and the ``povray`` marker's skip.

* ``x64``: float64 for the duration of one test (parameters created inside it are float64).
* ``slow``: besides the tests marked in their files, those listed in ``tests/slow_tests.txt``
  (measured in a full run by ``scripts/slow_tests.py``); ``make test-fast`` leaves them out.
* ``@pytest.mark.povray``: the test runs the ``povray`` binary; it is skipped where POV-Ray is not
  installed (``validation.povray.povray_executable``, which honours ``$POVRAY``).
* XLA compiles for compile time, not run time (``FAST_COMPILE_XLA_FLAGS``): the suite's images are
  tiny and its programs many, so LLVM's optimisations and the fusion emitters cost far more than
  they save (a glass scene's reverse-mode program: 30 s of compile without, 9.5 s with). The
  arithmetic is IEEE either way; ``make validate`` and the benchmarks use XLA's defaults. The
  flags every user of ``import raytracer`` gets (``raytracer/_xla.py``) are added too. The module
  is generated as one part (``parallel_codegen_split_count=1``), not 32 compiled on a thread pool:
  the xdist workers (three for ``make test``, two for ``make test-fast``) keep both cores busy
  already, and splitting costs more than it saves (``tests/shapes/test_gradients.py``: XLA's
  compile 49–51 → 41 CPU-s).
* Reference images (POV-Ray, Mitsuba) of the validation suite are kept for the run in a folder of
  its own (``$RAYTRACER_REFERENCE_CACHE``), so a reference two tests need is rendered once.
* ``$RAYTRACER_TEST_PROFILE=folder``: each worker writes one JSON line a test to a file in that
  folder: its wall time and what its JAX programs cost (tracing, lowering, XLA's compile, each
  summed and counted, and the persistent cache's hits). ``scripts/suite_profile.py`` sums them by
  file and by test. Off unless asked.
* JAX's persistent compilation cache points at a folder made for this run and shared by its xdist
  workers (``$RAYTRACER_TEST_JAX_CACHE`` overrides it and is then kept), so a program that two
  workers or two tests build compiles once. A fresh clone starts with an empty cache. The
  renderer's own kept programs (``raytracer/_programs.py``, ``$RAYTRACER_CACHE_DIR``) are off, and
  never in the user's ``~/.cache``.
"""

import os
import shutil
import tempfile

os.environ.setdefault("JAX_PLATFORMS", "cpu")
FAST_COMPILE_XLA_FLAGS = ("--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true "
                          "--xla_cpu_use_fusion_emitters=false --xla_cpu_parallel_codegen_split_count=1")
# read when the CPU backend starts (the first computation), so before any test; subprocesses inherit it
if FAST_COMPILE_XLA_FLAGS not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {FAST_COMPILE_XLA_FLAGS}".strip()

# one CPU device a worker, as the suite was measured (``import raytracer`` splits the CPU into one
# device per core otherwise, ``raytracer/_xla.split_cpu``; tests that shard set their own count)
os.environ.setdefault("RAYTRACER_CPU_DEVICES", "1")

import jax  # noqa: E402
import pytest  # noqa: E402

import raytracer  # noqa: E402, F401  (adds raytracer/_xla.py's flags, as for users, before a backend starts)

jax.config.update("jax_numpy_rank_promotion", "raise")

_CACHE_ENV = "RAYTRACER_TEST_JAX_CACHE"
_REFERENCE_ENV = "RAYTRACER_REFERENCE_CACHE"


def pytest_configure(config):
    # The controller (or a run without xdist) makes the folders; xdist workers, started after this
    # hook, inherit the variables. A folder given from outside is left in place at the end.
    config._raytracer_owned = []
    for env, prefix in ((_CACHE_ENV, "raytracer-jax-cache-"), (_REFERENCE_ENV, "raytracer-references-")):
        if env not in os.environ:
            os.environ[env] = tempfile.mkdtemp(prefix=prefix)
            config._raytracer_owned.append(env)
    jax.config.update("jax_compilation_cache_dir", os.environ[_CACHE_ENV])
    # no kept programs on disk (tests/test_programs.py gives its own folder): a program kept by one
    # test would be loaded by another that monkeypatched what its trace reads
    os.environ["RAYTRACER_CACHE_DIR"] = "off"
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def pytest_unconfigure(config):
    for env in getattr(config, "_raytracer_owned", ()):
        shutil.rmtree(os.environ.pop(env), ignore_errors=True)


_PROFILE_ENV = "RAYTRACER_TEST_PROFILE"
_PROFILED_EVENTS = {"/jax/core/compile/jaxpr_trace_duration": "trace",
                    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
                    "/jax/core/compile/backend_compile_duration": "compile"}
_profile_now: dict = {}


def _on_duration(event: str, seconds: float, **_) -> None:
    key = _PROFILED_EVENTS.get(event)
    if key is not None and _profile_now:
        _profile_now[key] = _profile_now.get(key, 0.0) + seconds
        _profile_now[key + "_n"] = _profile_now.get(key + "_n", 0) + 1


def _on_event(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits" and _profile_now:
        _profile_now["cache_hits"] = _profile_now.get("cache_hits", 0) + 1


if os.environ.get(_PROFILE_ENV):
    jax.monitoring.register_event_duration_secs_listener(_on_duration)
    jax.monitoring.register_event_listener(_on_event)

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        import json
        import time

        _profile_now.clear()
        _profile_now["test"] = item.nodeid
        start = time.perf_counter()
        yield
        _profile_now["wall"] = time.perf_counter() - start
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        os.makedirs(os.environ[_PROFILE_ENV], exist_ok=True)
        with open(os.path.join(os.environ[_PROFILE_ENV], f"{worker}.jsonl"), "a") as f:
            f.write(json.dumps(_profile_now) + "\n")
        _profile_now.clear()


_SLOW_LIST = os.path.join(os.path.dirname(__file__), "slow_tests.txt")


def _measured_slow() -> set[str]:
    """Node ids measured slow in a full run (``scripts/slow_tests.py`` writes the list)."""
    try:
        with open(_SLOW_LIST) as f:
            return {line.strip() for line in f if line.strip() and not line.startswith("#")}
    except FileNotFoundError:
        return set()


def pytest_collection_modifyitems(config, items):
    from validation.povray import povray_executable

    slow = _measured_slow()
    for item in items:
        if item.nodeid in slow:
            item.add_marker(pytest.mark.slow)

    if povray_executable() is None:
        skip = pytest.mark.skip(reason="povray is not installed")
        for item in items:
            if item.get_closest_marker("povray") is not None:
                item.add_marker(skip)


@pytest.fixture
def x64():
    """Float64 for the duration of one test (parameters created inside it are float64)."""
    with jax.enable_x64(True):
        yield


@pytest.fixture
def two_device_env():
    """The environment of a subprocess with two CPU devices: this run's XLA flags kept (the fast
    compile of ``FAST_COMPILE_XLA_FLAGS``: without them its programs compile twice as long)."""
    flags = [f for f in os.environ.get("XLA_FLAGS", "").split()
             if not f.startswith("--xla_force_host_platform_device_count")]
    return {**os.environ, "XLA_FLAGS": " ".join([*flags, "--xla_force_host_platform_device_count=2"]),
            "JAX_PLATFORMS": "cpu"}
