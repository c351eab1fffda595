"""Polygon: Newell plane, even-odd fill with holes, static edge lists."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shapes import Polygon

from ._case import Case, unit
from ._case import jitted_kernels as k

# A 4x4 square with a 2x2 square hole, both in z = 0, loops closed by their edge lists.
SQUARE_WITH_HOLE = jnp.array(
    [[-2.0, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0], [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
)
SQUARE_WITH_HOLE_EDGES = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4))
PLUS_Z = jnp.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize(
    ("x", "y", "filled"),
    [(1.5, 0.3, True), (-1.5, -1.7, True), (0.0, 0.0, False), (0.5, -0.5, False), (2.5, 0.0, False)],
)
def test_polygon_hole_is_empty_by_even_odd_rule(x, y, filled):
    t, n = k.polygon_hits(SQUARE_WITH_HOLE, SQUARE_WITH_HOLE_EDGES, jnp.array([x, y, -5.0]), PLUS_Z)
    assert bool(jnp.isfinite(t[0])) == filled
    if filled:
        np.testing.assert_allclose(t, [5.0], rtol=1e-6)
        np.testing.assert_allclose(np.abs(n[0]), [0.0, 0.0, 1.0], atol=1e-6)


def test_polygon_hole_wound_either_way_gives_the_same_fill():
    reversed_hole = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 7), (7, 6), (6, 5), (5, 4))
    for x in (1.5, 0.0):
        a, _ = k.polygon_hits(SQUARE_WITH_HOLE, SQUARE_WITH_HOLE_EDGES, jnp.array([x, 0.2, -5.0]), PLUS_Z)
        b, _ = k.polygon_hits(SQUARE_WITH_HOLE, reversed_hole, jnp.array([x, 0.2, -5.0]), PLUS_Z)
        np.testing.assert_array_equal(a, b)


def test_tilted_concave_polygon_hits_in_its_plane():
    # An L-shape in the plane x + y + z = 1 (points built from an in-plane basis).
    u = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    w = np.array([1.0, 1.0, -2.0]) / np.sqrt(6)
    c = np.ones(3) / 3
    shape_2d = [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]
    verts = jnp.array([c + a * u + b * w for a, b in shape_2d])
    edges = tuple((i, (i + 1) % 6) for i in range(6))
    normal = np.ones(3) / np.sqrt(3)
    for (a, b), filled in [((0.5, 1.5), True), ((1.5, 0.5), True), ((1.5, 1.5), False)]:
        target = c + a * u + b * w
        o = target + 3.0 * normal
        t, n = k.polygon_hits(verts, edges, jnp.asarray(o), jnp.asarray(-normal))
        assert bool(jnp.isfinite(t[0])) == filled
        if filled:
            np.testing.assert_allclose(t, [3.0], rtol=1e-5)
            np.testing.assert_allclose(np.abs(np.dot(n[0], normal)), 1.0, rtol=1e-6)


def test_collinear_polygon_is_degenerate_and_misses_with_finite_gradient():
    verts = jnp.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    edges = ((0, 1), (1, 2), (2, 0))
    o, d = jnp.array([0.5, 0.0, -1.0]), PLUS_Z
    t, n = k.polygon_hits(verts, edges, o, d)
    assert np.isinf(t[0]) and np.all(np.isfinite(np.asarray(n)))
    g = jax.grad(lambda v: jnp.sum(k.polygon_hits(v, edges, o, d)[1]))(verts)
    assert np.all(np.isfinite(np.asarray(g)))


def test_polygon_has_no_inside():
    assert not bool(Polygon(vertices=SQUARE_WITH_HOLE, edges=SQUARE_WITH_HOLE_EDGES).inside(jnp.zeros(3)))


# ---------------------------------------------------------------- the generic test case
def _polygon_case():
    # A square with a square hole in the plane through (0.1, 0.2, 0.3) spanned by u, w.
    u, w = unit([1.0, 0.2, -0.1]), unit(np.cross([1.0, 0.2, -0.1], [0.1, 1.0, 0.4]))
    o = np.array([0.1, 0.2, 0.3])
    square = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    verts = np.array([o + a * u + b * w for a, b in square] + [o + 0.4 * (a * u + b * w) for a, b in square])
    edges = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4))
    n_hat = unit(np.cross(u, w))

    def on_patch(p):
        a, b = (p - o) @ u, (p - o) @ w
        return max(abs(a), abs(b)) <= 1 + 1e-4 and max(abs(a), abs(b)) >= 0.4 - 1e-4

    return Case(
        "polygon",
        lambda v: Polygon(vertices=v, edges=edges),
        (verts,),
        lambda p: n_hat @ (p - o),
        o,
        1.0,
        solid=False,
        signed_normal=False,
        on_patch=on_patch,
    )


CASES = [_polygon_case()]
