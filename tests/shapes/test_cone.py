"""The cylinder and cone: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import functools

import numpy as np

from raytracer.shapes import Cone, Cylinder

from ._case import Case


def _frustum_distance(base, r0, cap, r1, with_caps):
    axis = cap - base
    length = np.linalg.norm(axis)
    a_hat = axis / length
    slope = (r1 - r0) / length

    def distance(p):
        h = (p - base) @ a_hat
        radial = np.linalg.norm(p - base - h * a_hat)
        side = (radial - (r0 + slope * h)) / np.sqrt(1 + slope**2)
        return max(side, -h, h - length) if with_caps else side

    def on_patch(p):
        h = (p - base) @ a_hat
        return -1e-4 <= h <= length + 1e-4

    return distance, on_patch


def _cylinder_case(open_):
    base, cap, r = np.array([0.1, -1.0, 0.2]), np.array([0.3, 1.2, -0.1]), 0.7
    distance, on_patch = _frustum_distance(base, r, cap, r, not open_)
    return Case(
        "open_cylinder" if open_ else "cylinder",
        functools.partial(Cylinder, open=open_),
        (base, cap, r),
        distance,
        (base + cap) / 2,
        1.2,
        convex=not open_,
        on_patch=on_patch,
    )


def _cone_case(cap_radius):
    base, r0, cap = np.array([0.0, -1.0, 0.0]), 1.0, np.array([0.2, 1.0, 0.1])
    distance, on_patch = _frustum_distance(base, r0, cap, cap_radius, True)
    return Case(
        "cone" if cap_radius == 0 else "frustum",
        Cone,
        (base, r0, cap, cap_radius),
        distance,
        (base + cap) / 2,
        1.2,
        on_patch=on_patch,
    )


CASES = [_cylinder_case(False), _cylinder_case(True), _cone_case(0.0), _cone_case(0.4)]
