"""The ray's list of the interiors it is inside (semantics §2.7): where camera rays start, and how a
transmitted ray enters and leaves media. The images are compared with POV-Ray in
``tests/test_render.py::test_the_ray_keeps_the_list_of_interiors_it_is_inside_as_povray_does``."""

import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import load_scene
from raytracer.render import pack, plan
from raytracer.shading._model import (
    _media_with,
    _media_without,
    initial_media,
    make_context,
)

SCENE = """camera {{ location {eye} look_at <0, 0, 1> }}
plane {{ z, 3 pigment {{ rgb 1 }} }}
difference {{ sphere {{ 0, 2 }} sphere {{ 0, 1 }} pigment {{ rgbf 1 }} interior {{ ior 1.5 }} }}
sphere {{ <5, 0, 0>, 1 pigment {{ rgbf 1 }} interior {{ ior 1.3 }} }}
"""


def _media_at(eye: str) -> list[int]:
    scene = load_scene(SCENE.format(eye=eye))
    p, packed = plan(scene), pack(scene)
    ctx = make_context(p, packed.geo, packed.mats, scene.lights, scene.settings, scene.background,
                       jnp.float32)
    media = np.asarray(initial_media(ctx, scene.camera.frame()[0]))
    return media[media >= 0].tolist()  # medium ids are prim indices


@pytest.mark.parametrize("eye, expected", [
    ("<0, 0, -5>", [0]),  # inside the plane's half-space z < 3 only
    ("<0, 0, -1.5>", [0, 1]),  # in the glass wall: the difference's one medium (prims 1 and 2)
    ("<0, 0, 0>", [0]),  # in the cavity: the difference does not contain it
    ("<5, 0, 0>", [0, 3]),  # in the other sphere
    ("<0, 0, 5>", []),  # behind the plane, outside everything
])
def test_camera_rays_start_inside_every_object_that_contains_the_camera(eye, expected):
    assert _media_at(eye) == expected


def test_entering_appends_and_leaving_removes_the_last_entry_of_a_medium():
    empty = jnp.full(4, -1, jnp.int32)
    m = _media_with(_media_with(_media_with(empty, 7), 2), 7)
    np.testing.assert_array_equal(m, [7, 2, 7, -1])
    np.testing.assert_array_equal(_media_without(m, 7), [7, 2, -1, -1])  # still inside the first 7
    np.testing.assert_array_equal(_media_without(m, 5), m)  # not inside 5: nothing changes
    np.testing.assert_array_equal(_media_without(m, 2), [7, 7, -1, -1])  # the later entries move down
    np.testing.assert_array_equal(_media_without(jnp.asarray([1, 2, 3, 4], jnp.int32), 1), [2, 3, 4, -1])
    full = jnp.asarray([1, 2, 3, 4], jnp.int32)
    np.testing.assert_array_equal(_media_with(full, 9), [2, 3, 4, 9])  # the oldest is forgotten


@pytest.mark.parametrize("mode", ["native", "none"])
def test_objects_of_the_hierarchy_that_contain_the_camera_start_its_rays_inside_them(monkeypatch, mode):
    """The hierarchy's objects are tested at the eye as arrays (one vmap per padded group), the
    others through the inside circuit (``RAYTRACER_ACCEL=none``: every one): either way the
    camera starts inside the plane's half-space, the two glass spheres around it and the inverted
    sphere it is outside of, in scene order, and not inside the inverted union of a sphere around
    it (whose two spheres the hierarchy holds)."""
    from raytracer.shading import _accel

    if mode == "native" and _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    monkeypatch.setenv("RAYTRACER_ACCEL", mode)
    glass = "pigment {{ rgbf 1 }} interior {{ ior 1.3 }}"
    rows = [f"sphere {{{{ <{3 * i}, 0, 10>, 1 {glass} }}}}" for i in range(20)]
    rows[4] = f"sphere {{{{ <0, 0, -5>, 2 {glass} }}}}"
    rows[7] = f"sphere {{{{ <0.5, 0, -5>, 3 {glass} }}}}"
    rows[9] = f"sphere {{{{ <30, 0, 30>, 1 {glass} inverse }}}}"
    # an object of several primitives: the eye in one of an inverted union's spheres is outside it
    rows[11] = ("union {{ sphere {{ <-0.5, 0, -5>, 1 }} sphere {{ <40, 0, 40>, 1 }} inverse "
                "pigment {{ rgbf 1 }} interior {{ ior 1.3 }} }}")
    text = ("camera {{ location <0, 0, -5> look_at <0, 0, 1> }}\nplane {{ z, 3 pigment {{ rgb 1 }} }}\n"
            + "\n".join(rows)).format()
    scene = load_scene(text)
    p, packed = plan(scene), pack(scene)
    assert (packed.geo.accel is not None) == (mode == "native")
    ctx = make_context(p, packed.geo, packed.mats, scene.lights, scene.settings, scene.background,
                       jnp.float32)
    media = np.asarray(initial_media(ctx, scene.camera.frame()[0]))
    assert media[media >= 0].tolist() == [0, 1 + 4, 1 + 7, 1 + 9]  # medium ids are prim indices
    if mode == "native":  # (the union's spheres are the hierarchy's)
        union = [i for i, p_ in enumerate(p.prims) if p_.inverse and p_.interior is not None][-2:]
        assert all(packed.geo.where[i][0] in [a.group for a in packed.geo.accel.groups] for i in union)
