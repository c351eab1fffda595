"""The mesh: its test case for the generic shape tests, and the mesh as its triangles."""

import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.shapes import Mesh, Triangle

from ._case import Case

# a tetrahedron: a closed, convex triangle mesh
_VERTICES = np.array([[0.1, -0.6, -0.5], [0.9, -0.5, 0.6], [-0.8, -0.4, 0.4], [0.0, 0.9, 0.1]])
_FACES = ((0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0))


def _tetrahedron_case():
    tris = _VERTICES[np.array(_FACES)]
    centroid = _VERTICES.mean(axis=0)
    planes = []
    for a, b, c in tris:
        n = np.cross(b - a, c - a)
        n = n / np.linalg.norm(n)
        if n @ (centroid - a) > 0:
            n = -n  # outward
        planes.append((n, n @ a))

    def distance(p):  # a convex polytope: the largest signed distance to its face planes
        return max(n @ p - off for n, off in planes)

    return Case("mesh", Mesh, (tris,), distance, centroid, 1.0, solid=False, signed_normal=False)


CASES = [_tetrahedron_case()]


def test_mesh_crossings_are_its_triangles_crossings():
    tris = _VERTICES[np.array(_FACES)]
    o, d = jnp.array([0.05, 0.0, -3.0]), jnp.array([0.02, 0.01, 1.0])
    t, n = Mesh(tris).hits(o, d)
    for i, tri in enumerate(tris):
        ti, ni = Triangle(*tri).hits(o, d)
        np.testing.assert_allclose(t[i], ti[0], rtol=1e-6)
        if np.isfinite(ti[0]):
            np.testing.assert_allclose(n[i], ni[0], atol=1e-6)
    assert np.sum(np.isfinite(np.asarray(t))) == 2  # a line through a closed convex mesh: in and out


@pytest.mark.parametrize("faces", ["<0,1,-1>", "<0,1,3>"])
def test_mesh2_indices_outside_the_vertex_list_are_scene_errors(tmp_path, faces):
    scene = tmp_path / "m.pov"
    scene.write_text("mesh2 {\n vertex_vectors { 3, <0,0,0>, <1,0,0>, <0,1,0> }\n"
                     f" face_indices {{ 1, {faces} }}\n}}\n")
    with pytest.raises(rt.SceneError, match="face_indices from 0 to 2") as e:
        rt.load_scene(scene)
    assert e.value.location.line == 2


def test_mesh2_builds_the_triangles_it_indexes(tmp_path):
    scene = tmp_path / "m.pov"
    scene.write_text("mesh2 { vertex_vectors { 4, <0,0,0>, <1,0,0>, <0,1,0>, <0,0,1> }\n"
                     " face_indices { 2, <0,1,2>, <0,2,3> } }\n")
    shape = rt.load_scene(scene).objects[0].shape
    np.testing.assert_array_equal(shape.triangles, [[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                                                    [[0, 0, 0], [0, 1, 0], [0, 0, 1]]])
