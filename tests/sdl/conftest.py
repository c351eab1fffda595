"""Helpers for the SDL tests: run SDL text and look at the interpreter's symbols."""

from __future__ import annotations

import pytest

from raytracer.sdl._interpreter import Interpreter
from raytracer.sdl._lexer import tokenize


def run_sdl(text: str, **kwargs) -> Interpreter:
    """Runs SDL text (no lowering) and returns the interpreter, for reading declared values."""
    p = Interpreter(**kwargs)
    p.push_main(tokenize(text, "t.pov"), None)
    p.run()
    return p


def value(text: str, name: str = "R", **kwargs):
    """The value of identifier ``name`` after running ``text``; floats and vectors as Python."""
    v = run_sdl(text, **kwargs).lookup(name)
    if hasattr(v, "c"):
        return v.c
    return v


@pytest.fixture
def sdl_value():
    return value
