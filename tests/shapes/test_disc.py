"""The disc: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np

from raytracer.shapes import Disc

from ._case import Case, unit


def _disc_case():
    c, normal, r, hole = np.array([0.1, 0.2, 0.3]), np.array([0.2, 1.0, 0.3]), 1.3, 0.4
    n_hat = unit(normal)
    return Case(
        "disc",
        Disc,
        (c, normal, r, hole),
        lambda p: n_hat @ (p - c),
        c,
        1.3,
        on_patch=lambda p: hole - 1e-4 <= np.linalg.norm(p - c) <= r + 1e-4,
    )


CASES = [_disc_case()]
