"""The box: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np

from raytracer.shapes import Box

from ._case import Case


def _box_case():
    c1, c2 = np.array([1.0, 0.5, 0.8]), np.array([-0.7, -1.0, -0.6])
    mid, half = (c1 + c2) / 2, np.abs(c1 - c2) / 2
    return Case("box", Box, (c1, c2), lambda p: np.max(np.abs(p - mid) - half), mid, 1.0)


CASES = [_box_case()]
