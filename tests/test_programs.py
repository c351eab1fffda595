"""Compiled programs kept on disk (``raytracer/_programs.py``): a structure compiled once is loaded,
not traced, by a later render; keys are the same in every process and change with the structure,
not the values; a bad entry is replaced; the folder keeps to its size."""

import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer import _adaptive, _programs, _tiles
from raytracer._packed import pack
from raytracer._plan import make_plan
from raytracer.render import compile_render

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 1, -4> look_at 0 }}
light_source {{ <3, 5, -4> rgb 1 }}
{extra}
sphere {{ 0, {radius} pigment {{ rgb <1, 0.5, 0.2> }} finish {{ phong 0.5 }} }}
plane {{ y, -1 pigment {{ checker rgb 1 rgb 0.2 }} }}
"""


def scene(radius=1.0, extra=""):
    return rt.load_scene(SCENE.format(radius=radius, extra=extra))


def key(s, width=8, height=6):
    return _programs.key_of("render", (pack(s, make_plan(s)), width, height, 1, 16))


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYTRACER_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(_programs, "_LIVE", {})  # the process's loaded programs: none yet
    monkeypatch.setattr(_programs, "_FAST", {})
    return tmp_path / "programs"


def test_a_kept_program_renders_a_later_scene_of_its_structure_without_a_trace(folder, monkeypatch):
    """The second ``compile_render`` of the same structure (another radius), in a process that has
    not loaded it, loads the program the first kept: the render's body is not traced again, and
    the image is that of a program compiled for it (bit for bit: the same executable)."""
    traces = []
    body = _tiles._render_tiles
    monkeypatch.setattr(_tiles, "_render_tiles", lambda *a, **k: traces.append(1) or body(*a, **k))
    first = compile_render(scene(), width=8, height=6)
    assert len(traces) == 1 and len(list(folder.iterdir())) == 1
    _programs._LIVE.clear()  # as a new process
    later = scene(radius=0.8)
    loaded = np.asarray(compile_render(later, width=8, height=6)(later))
    assert len(traces) == 1
    np.testing.assert_array_equal(loaded, np.asarray(first(later)))


def test_render_with_values_loads_kept_programs_and_under_jvp_keeps_none(folder, monkeypatch):
    """``rt.render`` of a scene with values, plain and adaptive, keeps its program as the command
    line's are kept: a later process (the loaded programs and JAX's in-memory caches cleared)
    renders a scene of the same structure without tracing the render again, to the same image. A
    render under ``jax.jvp`` is part of the caller's program: it keeps nothing."""
    traces = []
    body = _tiles._render_tiles
    counting = lambda *a, **k: traces.append(1) or body(*a, **k)  # noqa: E731
    monkeypatch.setattr(_tiles, "_render_tiles", counting)
    monkeypatch.setattr(_adaptive, "_render_tiles", counting)
    s = scene()
    jax.jvp(lambda r: rt.render(rt.params.replace(s, {"objects[0].shape.radius": r}), width=8, height=6),
            (jnp.asarray(1.0),), (jnp.asarray(1.0),))
    assert not folder.exists()
    for options in ({}, {"adaptive": (0.1, 2)}):
        rt.render(s, width=8, height=6, **options)
        kept, count = set(folder.iterdir()) if folder.exists() else set(), len(traces)
        assert kept, options
        _programs._LIVE.clear()
        _programs._FAST.clear()
        jax.clear_caches()  # as a new process
        later = scene(radius=0.8)
        image = np.asarray(rt.render(later, width=8, height=6, **options))
        assert len(traces) == count and set(folder.iterdir()) == kept, options
        monkeypatch.setenv("RAYTRACER_CACHE_DIR", "off")  # compiled here, as before kept programs
        np.testing.assert_array_equal(image, np.asarray(rt.render(later, width=8, height=6, **options)))
        assert len(traces) > count
        monkeypatch.setenv("RAYTRACER_CACHE_DIR", str(folder.parent))


def test_keys_are_the_same_in_every_process_and_follow_the_structure_not_the_values(folder):
    """Two processes of other string hash seeds key the scene alike (a key built from Python's
    ``hash`` of a string or bytes would differ: no program would ever be found; this process's
    key differs from theirs, its JAX configuration being the test suite's); another light is
    another program, another radius the same one, another image size another."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        from test_programs import key, scene
        print(key(scene()))""")
    keys = {subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONHASHSEED": seed},
                           capture_output=True, text=True, check=True).stdout.strip() for seed in ("1", "2")}
    assert len(keys) == 1 and len(keys.pop()) == 64
    assert key(scene(radius=0.5)) == key(scene())
    assert key(scene(extra="light_source { <-3, 5, -4> rgb 0.5 }")) != key(scene())
    assert key(scene(), width=16) != key(scene())


def test_an_unreadable_entry_is_removed_and_the_program_compiled_and_kept_again(folder):
    s = scene()
    args = (pack(s, make_plan(s)), 7, 5, 1, 16)
    folder.mkdir()
    (folder / _programs.key_of("render", args)).write_bytes(b"not a program")
    program = _programs.compiled("render", _tiles._render_packed, *args)
    assert not program.loaded and (folder / _programs.key_of("render", args)).read_bytes() != b"not a program"
    assert _programs.compiled("render", _tiles._render_packed, *args) is program  # loaded in this process
    _programs._LIVE.clear()
    again = _programs.compiled("render", _tiles._render_packed, *args)
    assert again.loaded
    np.testing.assert_array_equal(np.asarray(again(*args)[0]), np.asarray(program(*args)[0]))


def test_the_folder_keeps_to_its_size_the_least_recently_used_leaving_first(tmp_path, monkeypatch):
    for i, name in enumerate(["old", "mid", "new"]):
        (tmp_path / name).write_bytes(b"x" * 400_000)
        os.utime(tmp_path / name, (1000 + i, 1000 + i))
    monkeypatch.setenv("RAYTRACER_PROGRAM_CACHE_MB", "1")  # room for two
    _programs._trim(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mid", "new"]
