"""The blob: its field against a numpy one written from the manual's formula, crossings against the
closed forms of one sphere and one cylinder component (float64), a line through more pieces than
one search window holds against a dense float64 root search, what the scene language reads (the
three component forms, transforms, the threshold, per-part textures, errors at their place), and
the test case whose distance feeds the generic shape tests."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.sdl import SceneError, load_scene
from raytracer.shapes import Blob
from raytracer.shapes._blob import SLOTS, WINDOW, blob_of

from ._case import Case


def numpy_field(p, strength, radius, ends, placement):
    """The manual's field at points ``p`` (..., 3): each component adds ``s (1 − δ²/r²)²`` within
    ``r`` of its centre or axis segment, in its own space (``placement`` maps it into the blob's)."""
    p = np.asarray(p, np.float64)
    total = np.zeros(p.shape[:-1])
    for s, r, (a, b), m in zip(strength, radius, ends, placement, strict=True):
        q = (p - m[:, 3]) @ np.linalg.inv(m[:, :3]).T
        axis = b - a
        u = 0.0 if not axis.any() else np.clip((q - a) @ axis / np.dot(axis, axis), 0.0, 1.0)
        delta_sq = np.sum((q - a - np.asarray(u)[..., None] * axis) ** 2, -1)
        total += np.where(delta_sq < r * r, s * (1.0 - delta_sq / (r * r)) ** 2, 0.0)
    return total


STRENGTH = np.array([2.0, 1.5, 1.0, -0.8])
RADIUS = np.array([1.0, 0.8, 0.45, 0.5])
ENDS = np.array([[[-0.6, 0.0, 0.0]] * 2, [[0.7, 0.1, 0.0]] * 2,
                 [[0.0, -0.9, 0.0], [0.0, 0.9, 0.0]], [[0.2, 0.5, -0.4]] * 2])
PLACEMENT = np.array([np.eye(4)[:3], np.diag([1.0, 1.4, 1.0, 1.0])[:3],
                      np.array([[0.8660254, -0.5, 0.0, 0.1], [0.5, 0.8660254, 0.0, 0.0],
                                [0.0, 0.0, 1.0, 0.0]]), np.eye(4)[:3]])
THRESHOLD = 0.5


def _case():
    # a sphere component's one parameter is its centre (both ends): moving one end alone makes it a
    # capsule, where the field is not differentiable in that end
    def make(strength, radius, centres, cylinder_ends, placement, threshold):
        ends = jnp.stack([jnp.stack([centres[0]] * 2), jnp.stack([centres[1]] * 2), cylinder_ends,
                          jnp.stack([centres[2]] * 2)])
        return Blob(strength=strength, radius=radius, ends=ends, placement=placement, threshold=threshold,
                    cylinders=True)

    def field(p):
        return numpy_field(p, STRENGTH, RADIUS, ENDS, PLACEMENT)

    def distance(p):  # first order: (T − F) / |∇F| is the distance at the surface
        h = 1e-6
        grad = np.array([(field(p + h * e) - field(p - h * e)) / (2 * h) for e in np.eye(3)])
        return (THRESHOLD - field(p)) / max(np.linalg.norm(grad), 1e-9)

    params = (STRENGTH, RADIUS, ENDS[[0, 1, 3], 0], ENDS[2], PLACEMENT, np.array(THRESHOLD))
    return Case("blob of spheres, a turned cylinder and a negative one", make, params, distance,
                np.zeros(3), 1.5, convex=False)


CASES = [_case()]
HEAD = "camera { location <0, 0, -5> look_at 0 }\n"


def test_the_field_is_the_manuals_sum(x64):
    shape = CASES[0].make(*CASES[0].params)
    points = np.random.default_rng(3).uniform(-1.0, 1.0, (64, 3))
    ours = np.asarray(jax.jit(jax.vmap(shape.field))(jnp.asarray(points)))
    expected = numpy_field(points, STRENGTH, RADIUS, ENDS, PLACEMENT)
    np.testing.assert_allclose(ours, expected, rtol=1e-12, atol=1e-12)
    assert 8 < np.sum(ours > THRESHOLD) < 56  # the points straddle the surface


def test_one_component_is_a_sphere_or_a_capsule_of_the_closed_form_radius(x64):
    """Alone, a component's surface lies where ``s (1 − δ²/r²)² = T``: ``δ = r √(1 − √(T/s))``."""
    s, r, t = 2.0, 1.5, 0.5
    rad = r * np.sqrt(1 - np.sqrt(t / s))
    sphere = blob_of([s], [r], [((0.2, 0.0, 0.0), (0.2, 0.0, 0.0))], [np.eye(4)[:3]], t)
    capsule = blob_of([s], [r], [((0.0, -1.0, 0.0), (0.0, 1.0, 0.0))], [np.eye(4)[:3]], t)
    o = jnp.array([[0.5, 0.2, -5.0], [0.0, 0.3, -5.0], [0.0, 6.0, 0.1]])
    d = jnp.array([[0.0, 0.0, 2.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    t_sphere, n_sphere = jax.jit(jax.vmap(sphere.hits))(o[:1], d[:1])
    half = np.sqrt(rad**2 - 0.3**2 - 0.2**2)
    np.testing.assert_allclose(t_sphere[0, :2], [(5 - half) / 2, (5 + half) / 2], rtol=1e-12)
    assert np.all(np.isinf(t_sphere[0, 2:]))
    p = o[0] + t_sphere[0, 0] * d[0]
    np.testing.assert_allclose(n_sphere[0, 0], (p - np.array([0.2, 0, 0])) / rad, atol=1e-12)
    t_caps, _ = jax.jit(jax.vmap(capsule.hits))(o[1:], d[1:])
    body = np.sqrt(rad**2 - 0.3**2 * 0)  # the body's crossing at x = 0, y = 0.3
    np.testing.assert_allclose(t_caps[0, :2], [5 - body, 5 + body], rtol=1e-12)
    cap = np.sqrt(rad**2 - 0.1**2)  # along the axis, 0.1 off it: the caps' spheres
    np.testing.assert_allclose(t_caps[1, :2], [6 - 1 - cap, 6 + 1 + cap], rtol=1e-12)


def _dense_roots(field, o, d, t_max, threshold, n=200_001):
    ts = np.linspace(0.0, t_max, n)
    values = field(o + ts[:, None] * d) - threshold
    roots = []
    for i in np.nonzero(np.sign(values[:-1]) != np.sign(values[1:]))[0]:
        lo, hi = ts[i], ts[i + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if np.sign(field(o + mid * d) - threshold) == np.sign(values[i]):
                lo = mid
            else:
                hi = mid
        roots.append(0.5 * (lo + hi))
    return np.array(roots)


def test_crossings_past_the_first_windows_are_the_fields_roots(x64):
    """40 spheres in a row, the first 30 too weak to reach the threshold alone: the first crossings
    ahead lie in the third window of pieces; against a dense float64 search of the same field."""
    n = 40
    centres = np.stack([np.arange(n) * 0.55, np.zeros(n), np.zeros(n)], -1)
    strength = np.where(np.arange(n) < 30, 0.25, 1.0)
    radius = np.full(n, 0.5)
    ends = np.stack([centres, centres], 1)
    placement = np.broadcast_to(np.eye(4)[:3], (n, 3, 4))
    blob = blob_of(strength, radius, ends, placement, 0.6)
    assert n > 2 * WINDOW
    o, d = np.array([-1.0, 0.21, 0.05]), np.array([1.0, 0.0, 0.0])
    t, _ = jax.jit(blob.hits)(jnp.asarray(o), jnp.asarray(d))
    expected = _dense_roots(lambda p: numpy_field(p, strength, radius, ends, placement), o, d, 25.0, 0.6)
    assert len(expected) >= SLOTS and expected[0] > 30 * 0.55
    np.testing.assert_allclose(np.asarray(t), expected[:SLOTS], rtol=1e-9)


def _blob(body, warnings=0):
    scene = load_scene(HEAD + body)
    assert len(scene.warnings) == warnings, scene.warnings
    (obj,) = scene.objects
    return obj


def test_the_scene_language_reads_components_transforms_and_the_threshold():
    obj = _blob("blob { threshold 0.6 sphere { <1, 0, 0>, 2, strength 3 scale <1, 2, 1> translate x }\n"
                "cylinder { 0, y, 0.5, -1 } component 0.5, 1.5, <0, 0, 2> }")
    shape = obj.shape
    assert isinstance(shape, Blob) and shape.cylinders
    assert shape.strength.shape == (4,)  # three components padded to four
    np.testing.assert_allclose(shape.strength, [3.0, -1.0, 0.5, 0.0])
    np.testing.assert_allclose(shape.radius[:3], [2.0, 0.5, 1.5])
    np.testing.assert_allclose(shape.threshold, 0.6)
    np.testing.assert_allclose(shape.ends[1], [[0, 0, 0], [0, 1, 0]])
    np.testing.assert_allclose(shape.ends[2], [[0, 0, 2], [0, 0, 2]])
    np.testing.assert_allclose(shape.placement[0], [[1, 0, 0, 1], [0, 2, 0, 0], [0, 0, 1, 0]])
    np.testing.assert_allclose(shape.placement[1], np.eye(4)[:3])


def test_a_components_texture_is_the_blobs_with_a_warning():
    scene = load_scene(HEAD + "blob { sphere { 0, 1, 1 pigment { rgb <1, 0, 0> } } "
                       "sphere { x, 1, 1 texture { pigment { rgb <0, 1, 0> } } } }")
    assert [w.feature for w in scene.warnings] == ["blob texture"]
    assert "per-part blob textures" in scene.warnings[0].message


@pytest.mark.parametrize("body, message, col", [
    ("blob { pigment { rgb 1 } }", "expected a blob component", 8),
    ("blob { sphere { 0, 1, 1 finish { phong 1 } bumpy } }", "blob sphere modifier", 44),
])
def test_bad_blobs_are_errors_at_their_place(body, message, col):
    with pytest.raises(SceneError) as err:
        load_scene(HEAD + body)
    assert message in str(err.value)
    assert f":2:{col}" in str(err.value), str(err.value)
