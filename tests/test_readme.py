"""The README's Python blocks run as written, in order, in one namespace (as a reader pastes them
into one session), from a folder holding the repository's examples."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"

pytestmark = pytest.mark.slow  # a render and a reverse-mode program of the README's glass scene


def test_the_readmes_python_blocks_run_as_written(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.DOTALL)
    assert len(blocks) >= 2
    (tmp_path / "examples").symlink_to(README.parent / "examples")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)  # noqa: S102
    assert (tmp_path / "scene.png").is_file()
    import numpy as np

    ior = float(np.asarray(namespace["rt"].params.get(namespace["grads"], "objects[1].interior.ior")))
    assert np.isfinite(ior) and ior != 0.0  # the gradient block's printed value: a real derivative
    assert "objects[1].interior.ior" in capsys.readouterr().out
