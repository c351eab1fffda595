"""The compiled program does not grow with the number of objects (issue 11 item 2): the scene is
packed before the jit boundary, so 20 and 200 spheres give programs of the same operations and a
handful of arguments, not ~16 per object."""

import re
from collections import Counter

import jax.numpy as jnp
import pytest

from raytracer import load_scene
from raytracer.render import _render_part, pack
from raytracer.shading import _accel


def _spheres(n: int) -> str:
    rows = [f"sphere {{ <{i % 20 - 10}, 0.5, {i // 20}>, 0.4 pigment {{ rgb <{i % 7 / 7}, 0.5, 0.5> }} }}"
            for i in range(n)]
    return ("camera { location <0, 5, -12> look_at <0, 0, 3> }\nlight_source { <-5, 9, -9> color rgb 1 }\n"
            "plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }\n" + "\n".join(rows))


@pytest.mark.parametrize("mode", ["native", "none"])
def test_program_has_the_same_operations_for_20_and_200_spheres(tmp_path, monkeypatch, mode):
    if mode == "native" and _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    monkeypatch.setenv("RAYTRACER_ACCEL", mode)
    programs = []
    for n in (20, 200):
        path = tmp_path / f"s{n}.pov"
        path.write_text(_spheres(n))
        scene = load_scene(path, width=16, height=12)
        text = _render_part.lower(pack(scene), 16, 12, 1, 1, jnp.asarray(0), 4).as_text()
        ops = Counter(re.findall(r"= (\"?[a-z_]+\.[a-z_]+)", text))
        ops.pop("stablehlo.constant", None)  # the per-primitive tables are constants
        main = text[text.index("func.func public @main"):]
        programs.append((ops, main[:main.index("{")].count("%arg")))
    (ops20, args20), (ops200, args200) = programs
    assert ops20 == ops200
    assert args20 == args200 < 100
