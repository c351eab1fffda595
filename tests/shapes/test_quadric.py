"""The quadric: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np

from raytracer.shapes import Quadric

from ._case import Case, numeric_gradient


def quadric_polynomial(coeffs, p):
    """POV-Ray's quadric, written term by term."""
    A, B, C, D, E, F, G, H, I, J = coeffs
    x, y, z = p
    return A * x * x + B * y * y + C * z * z + D * x * y + E * x * z + F * y * z + G * x + H * y + I * z + J


def _quadric_case(name, coeffs, convex):
    coeffs = np.asarray(coeffs, np.float64)

    def distance(p):  # first-order distance Q / |∇Q|
        q = lambda x: quadric_polynomial(coeffs, x)  # noqa: E731
        return q(p) / np.linalg.norm(numeric_gradient(q, p))

    return Case(name, Quadric, (coeffs,), distance, np.zeros(3), 1.0, convex=convex)


CASES = [
    _quadric_case("ellipsoid_quadric", [1.0, 2.0, 0.5, 0.3, 0.0, 0.1, 0.1, 0.0, -0.2, -1.0], True),
    _quadric_case("hyperboloid_quadric", [1.0, -1.0, 1.0, 0, 0, 0, 0, 0, 0, -0.5], False),
]
