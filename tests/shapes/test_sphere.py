"""The sphere: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np

from raytracer.shapes import Sphere

from ._case import Case


def _sphere_case():
    c, r = np.array([0.3, -0.2, 0.1]), 1.2
    return Case("sphere", Sphere, (c, r), lambda p: np.linalg.norm(p - c) - r, c, r)


CASES = [_sphere_case()]
