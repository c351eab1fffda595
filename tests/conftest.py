"""Shared test configuration: strict JAX numerics, CPU only, and an opt-in float64 fixture."""

import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_numpy_rank_promotion", "raise")


@pytest.fixture
def x64():
    """Float64 for the duration of one test (parameters created inside it are float64)."""
    with jax.enable_x64(True):
        yield
