"""The triangle and smooth triangle: test cases for the generic shape tests (properties, gradients,
bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np

from raytracer.shapes import SmoothTriangle, Triangle

from ._case import Case, unit


def _in_triangle(p1, p2, p3):
    def on_patch(p):
        # Barycentric weights from sub-triangle areas, signed along the triangle normal.
        n = np.cross(p2 - p1, p3 - p1)
        w1 = np.cross(p3 - p2, p - p2) @ n / (n @ n)
        w2 = np.cross(p1 - p3, p - p3) @ n / (n @ n)
        return min(w1, w2, 1 - w1 - w2) >= -1e-4

    return on_patch


def _triangle_case(smooth):
    p1, p2, p3 = np.array([0.0, 0.0, 0.2]), np.array([1.5, 0.1, 0.0]), np.array([0.2, 1.3, -0.3])
    n_hat = unit(np.cross(p2 - p1, p3 - p1))
    if smooth:
        normals = (n_hat + [0.3, 0, 0], n_hat + [0, 0.3, 0], n_hat + [0, 0, -0.3])
        make, params = SmoothTriangle, (p1, p2, p3, *normals)
    else:
        make, params = Triangle, (p1, p2, p3)
    return Case(
        "smooth_triangle" if smooth else "triangle",
        make,
        params,
        lambda p: n_hat @ (p - p1),
        (p1 + p2 + p3) / 3,
        0.7,
        solid=False,
        geometric_normal=not smooth,
        signed_normal=False,
        on_patch=_in_triangle(p1, p2, p3),
    )


CASES = [_triangle_case(False), _triangle_case(True)]
