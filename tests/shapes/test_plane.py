"""The plane: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np

from raytracer.shapes import Plane

from ._case import Case, unit


def _plane_case():
    normal, dist = np.array([0.3, 1.0, -0.2]), 0.4
    n_hat = unit(normal)
    return Case(
        "plane", Plane, (normal, dist), lambda p: n_hat @ p - dist, dist * n_hat, 2.0
    )


CASES = [_plane_case()]
