"""Run-time warnings of compiled programs (``raytracer/_notice.py``)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from raytracer import _native

# in a process with two devices: the glass sphere of tests/test_scale.py drops rays with one slot a
# camera ray. The count of an eager render (known from values) against the count each compiled form
# reports when it runs: jit over both devices, the same program serialised and loaded again, the
# JAX host-callback fallback; then a warning filter that makes the warning an error
RUN = r"""
import json, sys, warnings
import equinox as eqx, jax
import raytracer as rt
from raytracer import _notice
from jax.experimental.serialize_executable import serialize, deserialize_and_load

scene = rt.load_scene('''#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 adc_bailout 0 }
camera { location <0, 0, -1.6> look_at 0 angle 40 }
light_source { <-5, 10, -8> color rgb 1 }
plane { y, -2 pigment { checker rgb 0.9, rgb 0.1 } }
sphere { 0, 1 pigment { rgbf <1, 1, 1, 0.9> } finish { reflection { 0, 1 fresnel on } conserve_energy }
  interior { ior 1.5 } }''', width=8, height=6)
params, rest = eqx.partition(scene, eqx.is_inexact_array)
params = rt.params.placed(params)  # where the compiled program takes them (both devices)
image = lambda p: rt.render(eqx.combine(p, rest), width=8, height=6, capacity=1)

def messages(run):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        jax.block_until_ready(run())
        jax.effects_barrier()
    return [str(w.message) for w in seen if "did not fit" in str(w.message)]

out = {"devices": len(jax.local_devices()), "eager": messages(lambda: image(params))}
compiled = jax.jit(image).lower(params).compile()
out["jit"] = messages(lambda: compiled(params))
payload, in_tree, out_tree = serialize(compiled)
loaded = deserialize_and_load(payload, in_tree, out_tree)
out["loaded"] = messages(lambda: loaded(params))
_notice._native_sink.cache_clear()
native = _notice._native_sink
_notice._native_sink = lambda: False
out["fallback"] = messages(lambda: jax.jit(lambda p: image(p) + 0)(params))
_notice._native_sink = native
with warnings.catch_warnings():
    warnings.simplefilter("error")
    try:
        jax.block_until_ready(compiled(params))
        out["error"] = None
    except Exception as e:
        out["error"] = str(e)
json.dump(out, open(sys.argv[1], "w"))
"""


@pytest.mark.slow  # a two-device subprocess that compiles a render
@pytest.mark.skipif(_native.library()[0] is None, reason="the native library is not built")
def test_a_dropped_ray_count_is_reported_once_a_run_by_a_program_that_serialises(tmp_path, two_device_env):
    run = subprocess.run([sys.executable, "-c", RUN, str(tmp_path / "out.json")],
                         env={**two_device_env, "RAYTRACER_CACHE_DIR": "off"},
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads((tmp_path / "out.json").read_text())
    assert got["devices"] == 2
    (eager,) = got["eager"]  # the count from values
    assert "rays of the ray tree did not fit the compiled room of 1 slots" in eager
    # the whole image's count, once a run (not once a device), by each compiled form
    assert got["jit"] == got["loaded"] == got["fallback"] == [eager]
    assert "did not fit the compiled room" in got["error"]
