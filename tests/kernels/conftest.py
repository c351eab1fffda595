"""Strict JAX settings for the kernel tests, as Equinox's test suite: no implicit rank promotion."""

import jax
import pytest


@pytest.fixture(autouse=True)
def _strict_rank_promotion():
    with jax.numpy_rank_promotion("raise"):
        yield


@pytest.fixture
def x64():
    """Runs the test with float64 enabled and restores the previous setting afterwards."""
    with jax.enable_x64(True):
        yield
