"""The triangle and smooth triangle: test cases for the generic shape tests (properties, gradients,
bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import numpy as np
import pytest

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


DEGENERATE_SMOOTH_TRIANGLE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 0, -4> look_at 0 }}
light_source {{ <2, 4, -5> rgb 1 }}
background {{ rgb <0.1, 0.2, 0.3> }}
smooth_triangle {{ <-1,-1,0>, {}, <1,-1,0>, {}, <0,1,0>, {} pigment {{ rgb <1,0.5,0.2> }} }}
plane {{ z, 1 pigment {{ rgb 0.6 }} }}
"""


@pytest.mark.povray
@pytest.mark.parametrize("normals", [
    ("<0,0,0>", "<0,0,0>", "<0,0,0>"),  # all zero
    ("<1,0,0>", "<0,0,-1>", "<0,0,-1>"),  # one in the triangle's plane
    ("<0,0,-1>", "<0,0,1e-9>", "<0,0,-1>"),  # one on the other side
], ids=["all-zero", "one-in-plane", "one-on-the-other-side"])
def test_smooth_triangle_with_normals_not_on_one_side_is_left_out_as_povray_does(tmp_path, normals):
    # POV-Ray 3.7 warns "Degenerate triangle. Please remove." and draws nothing
    # unless the three normals point strictly to one side of the triangle (measured)
    import raytracer as rt
    from validation import metrics
    from validation.povray import render_povray

    path = tmp_path / "degenerate.pov"
    path.write_text(DEGENERATE_SMOOTH_TRIANGLE.format(*normals))
    scene = rt.load_scene(path)
    assert [w.feature for w in scene.warnings] == ["smooth_triangle"]
    assert len(scene.objects) == 1  # the plane
    ours = np.asarray(rt.render(scene, width=32, height=24))
    assert metrics.psnr(ours, render_povray(path, 32, 24)) >= 40.0  # measured 83 dB at 80×60
