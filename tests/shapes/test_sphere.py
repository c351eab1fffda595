"""The sphere: its test case for the generic shape tests (properties, gradients, bounds).

Closed forms for it are in ``test_closed_forms.py``."""

import jax.numpy as jnp
import numpy as np

import raytracer as rt
from raytracer.shapes import Sphere

from ._case import Case


def _sphere_case():
    c, r = np.array([0.3, -0.2, 0.1]), 1.2
    return Case("sphere", Sphere, (c, r), lambda p: np.linalg.norm(p - c) - r, c, r)


CASES = [_sphere_case()]


def test_a_sphere_of_radius_zero_or_less_has_no_surface_as_in_povray():
    """POV-Ray renders ``sphere { c, -1 }`` as nothing (its image without the sphere, 86 dB): no
    crossing, no inside, a negative margin, and the hierarchy's kernel agrees (a box behind it,
    among nine others so that the hierarchy holds them, is seen)."""
    for r in (-1.0, 0.0):
        s = Sphere(jnp.zeros(3), jnp.asarray(r))
        t, _ = s.hits(jnp.array([0.0, 0.0, -5.0]), jnp.array([0.0, 0.0, 1.0]))
        assert not np.isfinite(np.asarray(t)).any() and not bool(s.inside(jnp.zeros(3)))
        assert float(s.silhouette_margin(jnp.array([0.0, 0.0, -5.0]), jnp.array([0.0, 0.0, 1.0]))) <= 0
    head = "camera { location <0, 1, -5> look_at 0 } light_source { <1, 2, -3> rgb 1 }\n" + "".join(
        f"box {{ <{i} - 0.2, -0.2, 2>, <{i} + 0.2, 0.2, 2.4> }}\n" for i in range(-4, 5))
    behind = "box { -0.3, 0.3 translate z * 3 pigment { rgb <0, 1, 0> } }"
    images = [np.asarray(rt.render(rt.load_scene(head + extra + behind), width=32, height=24))
              for extra in ("sphere { 0, -1 pigment { rgb <1, 0, 0> } }\n", "")]
    np.testing.assert_array_equal(images[0], images[1])
