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


MESH_NORMALS = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -4> look_at 0 }
light_source { <2, 4, -5> rgb 1 }
background { rgb <0.1, 0.2, 0.3> }
mesh {
  smooth_triangle { <-1.93,0.11,0>, <0,0,0>, <-0.13,0.17,0>, <0,0,0>, <-1.07,1.41,0>, <0,0,0> }
  smooth_triangle { <0.07,0.13,0>, <0.5,0,-1>, <1.91,0.09,0>, <1,0,-2>, <1.03,1.37,0>, <0.5,0,-1> }
  smooth_triangle { <-1.91,-1.43,0>, <0,0,0>, <-0.11,-1.39,0>, <0.3,0.2,-1>, <-1.03,-0.13,0>, <0,0,-1> }
  pigment { rgb <1,0.5,0.2> }
}
mesh2 {
  vertex_vectors { 3, <0.09,-1.41,0>, <1.93,-1.37,0>, <1.01,-0.11,0> }
  normal_vectors { 2, <0,0,0>, <0.2,-0.3,-1> }
  face_indices { 1, <0,1,2> }
  normal_indices { 1, <0,0,1> }
  pigment { rgb <0.3,0.6,1> }
}
plane { z, 1 pigment { rgb 0.6 } }
"""


@pytest.mark.povray
def test_mesh_normals_are_kept_as_povray_keeps_them(tmp_path):
    # measured with povray 3.7: in a mesh a zero normal becomes <1,0,0> ("Normal
    # vector in mesh cannot be zero"), and a face whose unit normals agree is flat (top left: all
    # zero; top right: parallel); the rest stay smooth (we used to leave the whole mesh out)
    from validation import metrics
    from validation.povray import render_povray

    path = tmp_path / "mesh_normals.pov"
    path.write_text(MESH_NORMALS)
    scene = rt.load_scene(path)
    assert {w.feature for w in scene.warnings} == {"mesh normal"}
    ours = np.asarray(rt.render(scene, width=32, height=24))
    assert metrics.psnr(ours, render_povray(path, 32, 24)) >= 40.0  # measured 48 dB (19 dB before)


def test_mesh2_faces_past_its_normal_indices_are_flat_and_extra_indices_ignored(tmp_path):
    # measured with povray 3.7: a mesh2 whose normal_indices list is shorter than its faces
    # renders, with no message, the same image as the one whose missing entries are <0,0,0>
    # (three equal normals: a flat face); entries past the faces change nothing
    def normals(indices):
        scene = tmp_path / "m.pov"
        scene.write_text(
            "mesh2 { vertex_vectors { 4, <0,0,0>, <1,0,0>, <0,1,0>, <2,1,0> }\n"
            " normal_vectors { 3, <0.5,0,-1>, <1,0.3,-1>, <0,0,-1> }\n"
            f" face_indices {{ 2, <0,1,2>, <1,3,2> }} normal_indices {{ {indices} }} }}\n")
        return np.asarray(rt.load_scene(scene).objects[0].shape.normals)

    short = normals("1, <0,1,0>")
    np.testing.assert_array_equal(short, normals("2, <0,1,0>, <0,0,0>"))
    np.testing.assert_array_equal(short, normals("3, <0,1,0>, <0,0,0>, <1,2,1>"))
    assert np.all(short[1] == short[1, 0]) and np.any(short[0] != short[0, 0])  # face 1 flat, 0 smooth
