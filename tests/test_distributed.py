"""Two processes on localhost render one image and compute one gradient together
(``raytracer.distributed`` over ``jax.distributed``): both must equal one process's ``render`` and
``jax.grad``. Each process has two CPU devices, over which it shards its tiles (``render``'s
``shard_map`` path, which the CLI takes by default on a machine with several cores)."""

import json
import socket
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import load_scene, render

SCENE = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 2, -6> look_at <0, 0.6, 0> angle 50 }
light_source { <4, 8, -5> rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
sphere { <-0.8, 0.7, 0>, 0.7 pigment { rgb <0.9, 0.4, 0.2> } finish { phong 0.5 } }
sphere { <0.9, 0.5, -0.5>, 0.5 pigment { rgb <0.6, 0.9, 1> } }
"""  # no secondary rays: a small program (the gradient of one compiles in seconds)
W, H = 20, 14  # the gradient's image
BIG = (208, 164)  # 34,112 rays: five tiles of 8,192, so each process shards its part over its two devices

WORKER = """
import json, sys
import jax
jax.config.update("jax_enable_x64", True)
jax.distributed.initialize(coordinator_address=sys.argv[1], num_processes=2, process_id=int(sys.argv[2]))
import jax.numpy as jnp
import numpy as np
from raytracer import distributed, load_scene
scene = load_scene(sys.argv[3])
image = distributed.render(scene, width={BIG[0]}, height={BIG[1]})
value, grad = distributed.value_and_grad(lambda im: jnp.mean(im ** 2), scene, width={W}, height={H})
leaves = [np.asarray(x).tolist() for x in jax.tree_util.tree_leaves(grad)
          if x.dtype != jax.dtypes.float0]
json.dump({{"devices": jax.device_count(), "image": np.asarray(image).tolist(), "value": float(value),
           "grad": leaves, "frames": distributed.frames(5)}}, open(sys.argv[4], "w"))
jax.distributed.shutdown()
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_two_processes_render_and_differentiate_like_one(tmp_path, x64, two_device_env):
    path = tmp_path / "scene.pov"
    path.write_text(SCENE)
    address = f"127.0.0.1:{_free_port()}"
    script = textwrap.dedent(WORKER.format(W=W, H=H, BIG=BIG))
    procs = [subprocess.Popen([sys.executable, "-c", script, address, str(i), str(path),
                               str(tmp_path / f"{i}.json")],
                              env=two_device_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for i in range(2)]
    for p in procs:
        out, _ = p.communicate(timeout=600)
        assert p.returncode == 0, out[-3000:]
    results = [json.loads((tmp_path / f"{i}.json").read_text()) for i in range(2)]
    assert [r["devices"] for r in results] == [4, 4]  # two CPU devices each, four in the cluster
    assert results[0]["frames"] == [0, 2, 4] and results[1]["frames"] == [1, 3]

    scene = load_scene(path)
    want_image = np.asarray(render(scene, width=BIG[0], height=BIG[1]))  # this process: one device

    def loss(s):
        return jnp.mean(render(s, width=W, height=H) ** 2)

    want_value, want_grad = jax.value_and_grad(loss)(scene)
    want_leaves = [np.asarray(x) for x in jax.tree_util.tree_leaves(want_grad)
                   if x.dtype != jax.dtypes.float0]
    assert any(np.any(x != 0) for x in want_leaves)
    for r in results:  # every process holds the whole image and the whole gradient
        np.testing.assert_allclose(np.asarray(r["image"]), want_image, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(r["value"], float(want_value), rtol=1e-12)
        assert len(r["grad"]) == len(want_leaves)
        for got, want in zip(r["grad"], want_leaves, strict=True):
            np.testing.assert_allclose(np.asarray(got), want, rtol=1e-9, atol=1e-13)
