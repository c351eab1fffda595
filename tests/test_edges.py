"""The boundary term of a pixel's derivative (``render(…, edges=True)``, ``raytracer/_edges.py``):
against outlines integrated per pixel in closed form (``validation/edges.py``, float64 NumPy), against
converged finite differences where two objects occlude and cross each other, and as a linear map
(reverse mode is the transpose of forward mode)."""

import json
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer._edges import boundary_term
from validation.edges import (
    brick_floor_term,
    checker_floor_term,
    cone_shadow_conic,
    convex_outline_term,
    ellipse_area,
    ellipse_outline_term,
    hexagon_floor_term,
    open_tube_outline_term,
    plane_point,
    project,
    shadow_conic,
    sphere_conic,
    sphere_through_slab,
    star_outline_term,
    stripe_floor_term,
)

# every test here compiles a render's derivative with the boundary term (5–25 s): not in make test-fast
pytestmark = pytest.mark.slow

FLAT = "finish { ambient 1 diffuse 0 }"
HEAD = "#version 3.7; global_settings { assumed_gamma 1.0 }\n"


def _jvp(scene, params, tangent, width, height, spp, edges=True):
    def image(p):
        return rt.render(rt.params.replace(scene, {**params, **p}), width=width, height=height, spp=spp,
                         edges=edges)

    primal = {name: params[name] for name in tangent}
    return [np.asarray(x) for x in jax.jvp(image, (primal,), (tangent,))]


def _term(scene, tangent, width, height, k):
    """The boundary term alone (``_edges.Edges``) along ``tangent`` at k×k samples a pixel."""
    import equinox as eqx

    dynamic, static = eqx.partition(scene, eqx.is_inexact_array)
    zero = jax.tree.map(lambda x: jnp.zeros_like(x) if eqx.is_inexact_array(x) else x, scene)
    along = eqx.partition(rt.params.replace(zero, tangent), eqx.is_inexact_array)[0]
    return boundary_term(dynamic, along, static, width, height, k)


def _moving_camera(scene, direction=(1.0, 0.4, -0.3)):
    """``(tangent, frame_at)``: the camera's place moved along ``direction``, and its frame (float64
    NumPy) at a step s along it."""
    params = rt.params.parameters(scene)
    direction = np.asarray(direction, np.float64)
    location = np.asarray(params["camera.location"], np.float64)

    def frame_at(s):
        moved = rt.params.replace(scene, {**params, "camera.location": jnp.asarray(location + s * direction)})
        return [np.asarray(x, np.float64) for x in moved.camera.frame()]

    return {"camera.location": jnp.asarray(direction)}, frame_at


def _rel_l2(value, reference):
    mask = np.abs(reference).max(-1) > 0
    return np.linalg.norm((value - reference)[mask]) / np.linalg.norm(reference[mask])


def _margins(scene, params, tangent, margin_of, eps=1e-6):
    """``(Q, Q_θ, Q at ±eps)``: the closed-form margin ``margin_of(scene)`` of a curve of the image,
    and its derivative along the tangent by central differences of the closed form (smooth in θ)."""
    def at(step):
        return margin_of(rt.params.replace(scene, {**params, **{n: params[n] + step * t
                                                                  for n, t in tangent.items()}}))

    q, plus, minus = at(0.0), at(eps), at(-eps)
    return q, lambda u, v: (plus(u, v) - minus(u, v)) / (2 * eps), plus, minus


def test_a_spheres_outline_term_is_its_outline_integral_and_converges_with_the_lattice(x64):
    """A flat-coloured sphere over black seen in perspective: its outline is an ellipse of the image,
    integrated per pixel exactly. Along a tangent of its centre, its radius and the camera's place,
    the boundary term equals it to 0.5 % at 4×4 samples a pixel, four times closer at 8×8 (the
    lattice's second order), and its sum is the derivative of the ellipse's area."""
    width, height = 24, 18
    colour = np.array([1.0, 0.5, 0.25])
    scene = rt.load_scene(HEAD + "camera { location <0.4, 0.5, -4> look_at <0, 0, 0> angle 40 }\n"
                          f"sphere {{ <0.3, 0.1, 0>, 0.8 pigment {{ rgb <1, 0.5, 0.25> }} {FLAT} }}")
    params = rt.params.parameters(scene)
    tangent = {"objects[0].shape.center": jnp.array([0.7, -0.4, 0.5]),
               "objects[0].shape.radius": jnp.asarray(0.3), "camera.location": jnp.array([0.2, 0.3, -0.6])}

    q, q_theta, plus, minus = _margins(scene, params, tangent, lambda moved: sphere_conic(
        [np.asarray(x) for x in moved.camera.frame()], np.asarray(moved.objects[0].shape.center),
        float(moved.objects[0].shape.radius), width, height)[0])
    outline = ellipse_outline_term(q, q_theta, width, height)
    reference = outline[..., None] * colour
    area_rate = (ellipse_area(plus) - ellipse_area(minus)) / 2e-6
    assert outline.sum() == pytest.approx(area_rate, rel=1e-6)  # the oracle against the closed form
    errors = []
    for spp in (16, 64):
        _, d_image = _jvp(scene, params, tangent, width, height, spp)
        errors.append(_rel_l2(d_image, reference))
        assert d_image.sum() / colour.sum() == pytest.approx(area_rate, rel=2e-3)
    assert errors[0] < 5e-3 and errors[1] < errors[0] / 3, errors
    _, plain = _jvp(scene, params, tangent, width, height, 16, edges=False)
    assert np.all(plain == 0)  # what the term adds: without it, nothing


def test_a_boxs_outline_term_is_the_integral_over_its_projected_hull():
    """A flat box seen from above a corner (float32): its outline is the convex hull of its eight
    projected corners, whose edges move as their ends do. Along a tangent of its corners the term
    is within 0.5 % of the hull's integral at 4×4 samples a pixel and 0.25 % at 8×8 (measured 0.10 %
    and 0.04 %), its sum within 0.1 %: each vertex, where the outline turns between two lattice
    lines, is where the tangent lines of the crossings on either side meet (``_edges._extents``;
    with a band of ±h/2 for each crossing, 3.6 % and 1.8 %, first order)."""
    width, height = 24, 18
    c1, c2 = np.array([-0.9, -0.6, -0.5]), np.array([0.7, 0.5, 0.6])
    box = f"box {{ <{c1[0]}, {c1[1]}, {c1[2]}>, <{c2[0]}, {c2[1]}, {c2[2]}> pigment {{ rgb 1 }} {FLAT} }}"
    scene = rt.load_scene(HEAD + "camera { location <0.8, 1.2, -4> look_at <0, 0, 0> angle 40 }\n" + box)
    params = rt.params.parameters(scene)
    t1, t2 = np.array([0.3, -0.8, 0.5]), np.array([-0.2, 0.4, 0.6])
    tangent = {"objects[0].shape.corner1": jnp.asarray(t1, jnp.float32),
               "objects[0].shape.corner2": jnp.asarray(t2, jnp.float32)}
    frame = [np.asarray(x, np.float64) for x in scene.camera.frame()]

    def corners(a, b):
        return np.array([[x, y, z] for x in (a[0], b[0]) for y in (a[1], b[1]) for z in (a[2], b[2])])

    eps = 1e-6
    points = project(frame, width, height, corners(c1, c2))
    motion = (project(frame, width, height, corners(c1 + eps * t1, c2 + eps * t2))
              - project(frame, width, height, corners(c1 - eps * t1, c2 - eps * t2))) / (2 * eps)
    reference = convex_outline_term(points, motion, width, height)[..., None] * np.ones(3)
    _, d_image = _jvp(scene, params, tangent, width, height, 16)
    assert _rel_l2(d_image, reference) < 0.005
    assert d_image.sum() == pytest.approx(reference.sum(), rel=1e-3)
    _, d_image = _jvp(scene, params, tangent, width, height, 64)
    assert _rel_l2(d_image, reference) < 0.0025


# a box's eight corners (index 4x + 2y + z of which corner each coordinate takes) and its six faces
BOX_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))


def _box_corners(c1, c2):
    return np.array([[(c1, c2)[(i >> (2 - a)) & 1][a] for a in range(3)] for i in range(8)])


def _lit_faces_term(frame, points, motion, light, width, height):
    """(H, W, 3): the boundary term of a convex box of corners ``points`` (8, 3) moving at ``motion``
    (8, 3; faces kept planar), diffuse in the parallel light towards ``light`` (unit): each face the
    camera sees is a projected quadrilateral of constant radiance, so the term is the sum of their
    outline integrals weighted by that radiance."""
    eps, centre, out = 1e-6, points.mean(axis=0), np.zeros((height, width))
    for quad in BOX_QUADS:
        corners = points[list(quad)]
        normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
        normal *= np.sign(normal @ (corners[0] - centre)) / np.linalg.norm(normal)
        if normal @ (frame[0] - corners[0]) <= 0:
            continue  # faces away from the camera
        velocity = (project(frame, width, height, corners + eps * motion[list(quad)])
                    - project(frame, width, height, corners - eps * motion[list(quad)])) / (2 * eps)
        outline = convex_outline_term(project(frame, width, height, corners), velocity, width, height)
        out += max(normal @ light, 0.0) * outline
    return out[..., None] * np.ones(3)


LIT_BOX = ("camera { location <2.2, 2, -3.5> look_at <0, 0, 0> angle 45 }\n"
           "light_source { <2, 5, -3> color rgb 1 parallel point_at <0, 0, 0> }\n")


def test_a_lit_boxs_creases_move_as_its_faces_projections_do():
    """The same box in a parallel light, diffuse: each face it shows has one radiance (the light's
    cosine there), so the image is three projected quadrilaterals of constant radiance, and the
    term is the sum of their outline integrals, each weighted by its face's radiance — the creases
    between two faces move with the jump between them (``AbstractShape.face``, ``face_distance``).
    Along a tangent of its corners: within 0.5 % at 4×4 samples a pixel (measured 0.135 %; 0.065 % at
    8×8: where a crease ends on the outline, the crease's crossings find the outline's as the edge
    that ends theirs). The faces' radiance does not move, so the derivative is the term alone."""
    width, height = 24, 18
    c1, c2 = np.array([-0.9, -0.6, -0.5]), np.array([0.7, 0.5, 0.6])
    box = (f"box {{ <{c1[0]}, {c1[1]}, {c1[2]}>, <{c2[0]}, {c2[1]}, {c2[2]}> pigment {{ rgb 1 }} "
           "finish { ambient 0 diffuse 1 } }")
    scene = rt.load_scene(HEAD + LIT_BOX + box)
    t1, t2 = np.array([0.3, -0.8, 0.5]), np.array([-0.2, 0.4, 0.6])
    tangent = {"objects[0].shape.corner1": jnp.asarray(t1, jnp.float32),
               "objects[0].shape.corner2": jnp.asarray(t2, jnp.float32)}
    frame = [np.asarray(x, np.float64) for x in scene.camera.frame()]
    light = np.array([2.0, 5.0, -3.0]) / np.linalg.norm([2.0, 5.0, -3.0])
    reference = _lit_faces_term(frame, _box_corners(c1, c2), _box_corners(t1, t2), light, width, height)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 4).tangent), reference) < 0.005


def test_a_flat_meshs_outline_and_creases_are_its_triangles_edges_moving_with_its_vertices():
    """The lit box as a mesh of twelve triangles (flat: each shades with its own normal), moved by a
    tangent of every vertex (the box test's corners' motion): its outline is the edge of the
    triangle each ray saw last (``Mesh.item_margin``, ``Hit.sub``), a crease is where the triangle
    seen changes between two faces (``Mesh.items_are_faces``), and the diagonal between a face's
    two triangles is no edge (``Mesh.one_face``). The term is the faces' outline integrals weighted
    by their radiance, as for the box: within 1 % at 4×4 samples a pixel (measured 0.43 %, the
    box 0.135 %; 44 % with the creases left out, 6.8 % where a face's diagonal hides a crease beside
    it within one lattice step)."""
    width, height = 24, 18
    points = _box_corners(np.array([-0.9, -0.6, -0.5]), np.array([0.7, 0.5, 0.6]))
    faces = [(q[0], q[1], q[2]) for q in BOX_QUADS] + [(q[0], q[2], q[3]) for q in BOX_QUADS]
    text = " ".join("triangle { " + ", ".join("<{}, {}, {}>".format(*points[i]) for i in f) + " }"
                    for f in faces)
    scene = rt.load_scene(HEAD + LIT_BOX + f"mesh {{ {text} pigment {{ rgb 1 }} "
                          "finish { ambient 0 diffuse 1 } }")
    motion = _box_corners(np.array([0.3, -0.8, 0.5]), np.array([-0.2, 0.4, 0.6]))  # the box test's
    tangent = {"objects[0].shape.triangles": jnp.asarray(np.stack([motion[list(f)] for f in faces]),
                                                         jnp.float32)}
    frame = [np.asarray(x, np.float64) for x in scene.camera.frame()]
    light = np.array([2.0, 5.0, -3.0]) / np.linalg.norm([2.0, 5.0, -3.0])
    reference = _lit_faces_term(frame, points, motion, light, width, height)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 4).tangent), reference) < 0.01


def test_a_checker_floors_cell_edges_move_with_the_camera_as_their_projections_do(x64):
    """A flat checker floor seen by a moving camera (float64): every cell edge is a straight segment
    of the image whose ends move as their projections (``validation.edges.checker_floor_term``).
    Within 0.5 % at 8×8 samples a pixel (measured 0.28 %; 0.48 % at 4×4): the corners
    where an edge runs into another are located, and the lattice reaches half a spacing past the
    image's border, so that the edges along it are crossed."""
    width, height = 32, 24
    scene = rt.load_scene(HEAD + "camera { location <0, 3, -3> look_at <0, 0, 0> angle 50 }\n"
                          "plane { y, -0.5 pigment { checker rgb 0.9 rgb 0.15 scale 1.3 "
                          f"translate <0.37, 0, 0.21> }} {FLAT} }}")
    tangent, frame_at = _moving_camera(scene)

    reference = checker_floor_term(frame_at, (0.37, 0.21), 1.3, -0.5, (0.9, 0.15), width, height)
    reference = reference[..., None] * np.ones(3)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 8).tangent), reference) < 0.005


def test_a_hexagon_floors_cell_edges_move_as_their_projections_do(x64):
    """The hexagon pattern's cells are its centres' nearest-point cells, so the face between two is
    the plane halfway between their centres (``patterns._tilings.hexagon_face``). A flat hexagon
    floor seen from above by a moving camera: every cell edge is a straight image segment whose
    ends move as their projections (``validation.edges.hexagon_floor_term``); the term is within
    0.5 % at 8×8 samples a pixel (measured 0.27 %; 0.69 % at 4×4: the three-way corners are where an
    edge runs into others)."""
    width, height = 32, 24
    scene = rt.load_scene(HEAD + "camera { location <0.2, 4, -1.5> look_at <0, 0, 0> angle 50 }\n"
                          "plane { y, -0.5 pigment { hexagon rgb 0.9 rgb 0.15 rgb 0.5 scale 0.8 } "
                          f"{FLAT} }}")
    tangent, frame_at = _moving_camera(scene)

    colours = (0.9, 0.15, 0.5)
    reference = hexagon_floor_term(frame_at, 0.8, -0.5, colours, width, height)[..., None] * np.ones(3)
    # (flat cells: the render's own tangent is 0, the term is the whole)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 8).tangent), reference) < 0.005


def test_a_brick_floors_mortar_edges_move_as_their_projections_do(x64):
    """Brick's faces are planes square to its axes: the term finds the one between two points by
    probing the pattern (``patterns._tilings.axis_face``). A flat brick floor seen from above by a moving
    camera: every brick is a rectangle of mortar edges (``validation.edges.brick_floor_term``),
    within 0.1 % at 8×8 samples a pixel (measured 0.023 %; 0.080 % at 4×4: the mortar is one pixel
    wide, four lattice steps there; each T-junction is where a turn search meets the edge that ends
    the other, up to two lattice steps on)."""
    width, height = 32, 24
    scene = rt.load_scene(HEAD + "camera { location <0.2, 4, -1.5> look_at <0, 0, 0> angle 50 }\n"
                          f"plane {{ y, -0.5 pigment {{ brick rgb 0.9 rgb 0.2 scale 0.25 }} {FLAT} }}")
    tangent, frame_at = _moving_camera(scene)

    reference = brick_floor_term(frame_at, 0.25, -0.5, (0.9, 0.2), width, height)[..., None] * np.ones(3)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 8).tangent), reference) < 0.001


def test_a_striped_floors_colour_map_steps_and_wraps_move_as_their_projections_do(x64):
    """A continuous pattern's colour jumps where its value crosses a step of the colour map (two
    entries at one position) and where the value wraps from 1 to 0 between entries of different
    colours: ``gradient x`` with ``[0 A] [0.5 A] [0.5 B] [1 B]`` paints stripes, each edge a
    straight line of the floor (``validation.edges.stripe_floor_term``). The margin is the value
    less the level it crosses (``_edges._level_cell``, ``_face``'s step), read from the map. Moving
    camera: within 0.5 % at 4×4 samples a pixel (measured 0.092 %; before: no term)."""
    width, height = 24, 18
    scene = rt.load_scene(HEAD + "camera { location <0, 3, -3> look_at <0, 0, 0> angle 50 }\n"
                          "plane { y, -0.5 pigment { gradient x color_map { [0 rgb 0.9] [0.5 rgb 0.9] "
                          "[0.5 rgb 0.15] [1 rgb 0.15] } scale 1.3 translate <-10.37, 0, 0> } "
                          f"{FLAT} }}")
    tangent, frame_at = _moving_camera(scene)
    reference = stripe_floor_term(frame_at, 10.37, 1.3, -0.5, (0.9, 0.15), width, height)
    reference = reference[..., None] * np.ones(3)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 4).tangent), reference) < 0.005
    # the step's place in the map is a parameter too: moving it moves every other edge (measured:
    # the image's sum within 0.04 % of central differences of 64×64-sample renders)
    name = "objects[0].texture.layers[0].pigment.values"
    params = rt.params.parameters(scene)
    step = jnp.asarray([0.0, 1.0, 1.0, 0.0])
    term = np.asarray(_term(scene, {name: step}, width, height, 4).tangent)

    def image(s):
        moved = rt.params.replace(scene, {**params, name: params[name] + s * step})
        return np.asarray(rt.render(moved, width=width, height=height, spp=64 * 64))

    assert term.sum() == pytest.approx(((image(0.01) - image(-0.01)) / 0.02).sum(), rel=0.005)


def test_a_spheres_shadow_outline_term_is_its_outline_integral(x64):
    """The shadow of a sphere the camera does not see (``no_image``) on a lit plane, in a parallel
    light: its outline is a conic of the image (``validation.edges.shadow_conic``) with a constant
    jump (the plane's diffuse term), integrated per pixel exactly. Along a tangent of the sphere's
    centre and radius, the light's place (turned about the vertical, so that the plane's lighting
    does not change: the term is the whole derivative) and the camera's: within 0.4 % at 8×8
    samples a pixel (measured 0.19 %; 1.6 % at 4×4), and nothing away from the outline."""
    width, height = 24, 18
    scene = rt.load_scene(HEAD + "camera { location <0, 3, -3.5> look_at <0.2, -0.4, 0.4> angle 50 }\n"
                          "light_source { <-2, 6, -1.5> color rgb 1 parallel point_at <0, 0, 0> }\n"
                          "plane { y, -0.5 pigment { rgb 0.8 } finish { ambient 0.1 diffuse 0.9 } }\n"
                          "sphere { <0.1, 0.4, 0.3>, 0.45 pigment { rgb 1 } no_image }")
    params = rt.params.parameters(scene)
    tangent = {"objects[1].shape.center": jnp.array([0.7, -0.3, 0.5]),
               "objects[1].shape.radius": jnp.asarray(0.2), "lights[0].position": jnp.array([1.5, 0.0, -2.0]),
               "camera.location": jnp.array([0.2, 0.3, -0.4])}

    q, q_theta, _, _ = _margins(scene, params, tangent, lambda moved: shadow_conic(
        [np.asarray(x) for x in moved.camera.frame()], np.asarray(moved.objects[1].shape.center),
        float(moved.objects[1].shape.radius),
        np.asarray(moved.lights[0].position) - np.asarray(moved.lights[0].point_at), -0.5, width, height))
    towards = np.array([-2.0, 6.0, -1.5]) / np.linalg.norm([-2.0, 6.0, -1.5])
    jump = -0.9 * 0.8 * towards[1]  # in the shadow minus lit: the plane's diffuse term
    reference = ellipse_outline_term(q, q_theta, width, height)[..., None] * jump * np.ones(3)
    d_image = np.asarray(_term(scene, tangent, width, height, 8).tangent)
    assert _rel_l2(d_image, reference) < 0.004
    assert np.all(d_image[np.abs(reference).max(-1) == 0] == 0)


def test_a_meshs_shadow_outline_is_its_triangles_edges_moving_with_its_vertices():
    """The shadow of a box-shaped mesh the camera does not see on a lit plane, in a parallel light:
    the hull of its corners cast along the light onto the plane, then projected into the image,
    with the plane's diffuse term as its jump. The shadow ray's first caster carries the triangle
    it crosses (``_edges._first_caster``), whose edge is the outline (``Mesh.item_margin``). Along
    a tangent of every vertex: within 1 % at 4×4 samples a pixel (measured 0.31 %, float32 and
    float64 alike; before: no term, every crossing unresolved)."""
    width, height = 24, 18
    points = _box_corners(np.array([-0.4, 0.2, 0.0]), np.array([0.35, 0.6, 0.5]))
    faces = [(q[0], q[1], q[2]) for q in BOX_QUADS] + [(q[0], q[2], q[3]) for q in BOX_QUADS]
    text = " ".join("triangle { " + ", ".join("<{}, {}, {}>".format(*points[i]) for i in f) + " }"
                    for f in faces)
    towards = np.array([-3.0, 6.0, -3.0])  # the light, from the origin it points at
    scene = rt.load_scene(HEAD + "camera { location <0, 3, -3.5> look_at <0.2, -0.4, 0.4> angle 50 }\n"
                          "light_source { <-3, 6, -3> color rgb 1 parallel point_at <0, 0, 0> }\n"
                          "plane { y, -0.5 pigment { rgb 0.8 } finish { ambient 0.1 diffuse 0.9 } }\n"
                          f"mesh {{ {text} pigment {{ rgb 1 }} no_image }}")
    motion = _box_corners(np.array([0.3, -0.8, 0.5]), np.array([-0.2, 0.4, 0.6]))
    tangent = {"objects[1].shape.triangles": jnp.asarray(np.stack([motion[list(f)] for f in faces]),
                                                         jnp.float32)}
    frame = [np.asarray(x, np.float64) for x in scene.camera.frame()]

    def shadow(p):  # cast along the light onto the plane y = −0.5
        return p - ((p[:, 1] + 0.5) / towards[1])[:, None] * towards[None, :]

    eps = 1e-6
    velocity = (project(frame, width, height, shadow(points + eps * motion))
                - project(frame, width, height, shadow(points - eps * motion))) / (2 * eps)
    jump = -0.9 * 0.8 * towards[1] / np.linalg.norm(towards)  # in the shadow minus lit
    reference = convex_outline_term(project(frame, width, height, shadow(points)), velocity, width, height)
    reference = reference[..., None] * jump * np.ones(3)
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 4).tangent), reference) < 0.01


def test_an_area_lights_penumbra_is_the_outlines_of_its_samples_shadows(x64):
    """The shadow of a sphere the camera does not see on a lit plane, in an area light of 3×2
    samples: the penumbra is six point-light shadows, each a cone's conic of the image
    (``validation.edges.cone_shadow_conic``) whose jump is its sample's weight (POV-Ray's ¼ ½ ¼ ×
    ½ ½) times the plane's diffuse term, lit from the light's centre (only the shadow is sampled).
    The six outlines, integrated per pixel exactly, are the boundary term along a tangent of the
    sphere, the light's place, one of its axes and the camera's: within 0.33 % at 8×8 samples a
    pixel (measured 0.15 %; 0.62 % at 4×4), and nothing away from the outlines."""
    width, height = 24, 18
    centre = np.array([-1.0, 5.0, -1.0])  # the light's
    text = (HEAD + "camera { location <0, 3, -3.5> look_at <0.2, -0.4, 0.4> angle 50 }\n"
            "light_source { <-1, 5, -1> color rgb 1 area_light <2.4, 0, 0>, <0, 0, 1.6>, 3, 2 }\n"
            "plane { y, -0.5 pigment { rgb 0.8 } finish { ambient 0.1 diffuse 0.9 } }\n"
            "sphere { <0.1, 0.4, 0.3>, 0.45 pigment { rgb 1 } no_image }")
    scene = rt.load_scene(text)
    params = rt.params.parameters(scene)
    tangent = {"objects[1].shape.center": jnp.array([0.7, -0.3, 0.5]),
               "objects[1].shape.radius": jnp.asarray(0.2), "lights[0].position": jnp.array([0.5, 0.3, -0.4]),
               "lights[0].area.axis1": jnp.array([0.6, 0.0, 0.8]),
               "camera.location": jnp.array([0.2, 0.3, -0.4])}
    weights = np.outer([0.25, 0.5, 0.25], [0.5, 0.5])
    frame = [np.asarray(x) for x in scene.camera.frame()]
    on_plane = plane_point(frame, -0.5, width, height)

    def jump(weight):
        def inside_minus_outside(u, v):
            to_light = centre[None, :] - on_plane(u, v)
            return -weight * 0.9 * 0.8 * to_light[:, 1] / np.linalg.norm(to_light, axis=-1)
        return inside_minus_outside

    reference = 0.0
    for i, f1 in enumerate((-0.5, 0.0, 0.5)):
        for j, f2 in enumerate((-0.5, 0.5)):
            def sample_conic(moved, f1=f1, f2=f2):
                light = moved.lights[0]
                target = (np.asarray(light.position) + f1 * np.asarray(light.area.axis1)
                          + f2 * np.asarray(light.area.axis2))
                return cone_shadow_conic([np.asarray(x) for x in moved.camera.frame()],
                                         np.asarray(moved.objects[1].shape.center),
                                         float(moved.objects[1].shape.radius), target, -0.5, width, height)

            q, q_theta, _, _ = _margins(scene, params, tangent, sample_conic)
            reference = reference + ellipse_outline_term(q, q_theta, width, height, jump=jump(weights[i, j]))
    reference = reference[..., None] * np.ones(3)
    edges = _term(scene, tangent, width, height, 8)  # the term alone: moving the light also shades
    d_image = np.asarray(edges.tangent)               # the plane anew everywhere
    assert _rel_l2(d_image, reference) < 0.0033
    assert np.all(d_image[np.abs(reference).max(-1) == 0] == 0)
    assert int(edges.unresolved) == 0 and int(edges.overflow) == 0
    adaptive = rt.load_scene(text.replace("3, 2 }", "3, 2 adaptive 0 }"))
    with pytest.warns(RuntimeWarning, match="no boundary term for the shadows of area lights with adaptive"):
        jax.eval_shape(lambda: _term(adaptive, tangent, width, height, 4))


def test_a_spheres_outline_in_a_plane_mirror_is_its_mirror_images_outline(x64):
    """A sphere the camera sees only in a plane mirror (``no_image``): what the mirror shows is the
    outline of the sphere reflected in the plane, a conic of the image. Along a tangent of the
    sphere, the mirror's place and the camera's (flat colours: the term is the whole derivative):
    within 0.33 % at 8×8 samples a pixel (measured 0.14 %; 0.53 % at 4×4)."""
    width, height = 24, 18
    colour = np.array([1.0, 0.5, 0.25])
    scene = rt.load_scene(HEAD.replace("assumed_gamma 1.0", "assumed_gamma 1.0 max_trace_level 2")
                          + "camera { location <0, 1.5, -4> look_at <0, -0.8, 0> angle 45 }\n"
                          "plane { y, -0.6 pigment { rgb 0 } finish { ambient 0 diffuse 0 reflection 1 } }\n"
                          f"sphere {{ <0.2, 0.1, 0.4>, 0.5 pigment {{ rgb <1, 0.5, 0.25> }} {FLAT} "
                          "no_image }")
    params = rt.params.parameters(scene)
    tangent = {"objects[1].shape.center": jnp.array([0.7, -0.3, 0.5]),
               "objects[1].shape.radius": jnp.asarray(0.2), "objects[0].shape.distance": jnp.asarray(0.5),
               "camera.location": jnp.array([0.2, 0.3, -0.4])}

    def mirror_image(moved):  # the sphere reflected in the plane y = distance
        image_centre = np.array(moved.objects[1].shape.center, np.float64)
        image_centre[1] = 2 * float(moved.objects[0].shape.distance) - image_centre[1]
        return sphere_conic([np.asarray(x) for x in moved.camera.frame()], image_centre,
                            float(moved.objects[1].shape.radius), width, height)[0]

    q, q_theta, _, _ = _margins(scene, params, tangent, mirror_image)
    reference = ellipse_outline_term(q, q_theta, width, height)[..., None] * colour
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 8).tangent), reference) < 0.0033


def test_a_sphere_seen_through_a_glass_slab_moves_as_its_refracted_outline(x64):
    """A sphere behind a glass slab (ior 1.5): the rays that see its outline refract into the slab
    and out again parallel to themselves, shifted (``validation.edges.sphere_through_slab``, a
    star-shaped region integrated per pixel). Along a tangent of the sphere, the slab's index of
    refraction and the camera's place (flat colours: the term is the whole derivative): within
    0.33 % at 8×8 samples a pixel (measured 0.09 %; 0.31 % at 4×4)."""
    width, height = 24, 18
    colour = np.array([1.0, 0.5, 0.25])
    scene = rt.load_scene(HEAD.replace("assumed_gamma 1.0", "assumed_gamma 1.0 max_trace_level 3")
                          + "camera { location <0.3, 0.4, -4> look_at <0, 0, 0> angle 40 }\n"
                          "box { <-5, -5, -1.2>, <5, 5, -0.5> pigment { rgbf 1 } "
                          "finish { ambient 0 diffuse 0 } interior { ior 1.5 } }\n"
                          f"sphere {{ <0.2, 0.1, 0.4>, 0.6 pigment {{ rgb <1, 0.5, 0.25> }} {FLAT} }}")
    params = rt.params.parameters(scene)
    tangent = {"objects[1].shape.center": jnp.array([0.7, -0.3, 0.5]),
               "objects[1].shape.radius": jnp.asarray(0.2), "objects[0].interior.ior": jnp.asarray(0.5),
               "camera.location": jnp.array([0.2, 0.3, -0.4])}

    q, q_theta, _, _ = _margins(scene, params, tangent, lambda moved: sphere_through_slab(
        [np.asarray(x) for x in moved.camera.frame()], np.asarray(moved.objects[1].shape.center),
        float(moved.objects[1].shape.radius), -1.2, -0.5, float(moved.objects[0].interior.ior), width,
        height))
    reference = star_outline_term(q, q_theta, (12.0, 9.0), 20.0, width, height)[..., None] * colour
    assert _rel_l2(np.asarray(_term(scene, tangent, width, height, 8).tangent), reference) < 0.0033


def test_occluding_and_interpenetrating_objects_match_converged_finite_differences(x64):
    """A small sphere in front of a large one and half inside it, over a box that cuts the large
    one: moving the small sphere moves its outline over the large one, their seam where they
    cross, and its outline over the black. Against central differences of 128×128-sample renders
    (steps moving the edges ~0.03 px) on the pixels the edges cross."""
    width, height = 16, 12
    scene = rt.load_scene(HEAD + "camera { location <0, 0.5, -4> look_at <0, 0, 0> angle 40 }\n"
                          f"sphere {{ <0.3, 0.1, 0>, 0.8 pigment {{ rgb <1, 0.5, 0.25> }} {FLAT} }}\n"
                          "box { <-0.5, -0.3, -1>, <0.5, 0.3, 0.2> pigment { rgb <0.2, 0.4, 1> } "
                          f"{FLAT} }}\n"
                          f"sphere {{ <-0.6, 0.5, -0.5>, 0.4 pigment {{ rgb <0.3, 1, 0.3> }} {FLAT} }}")
    params = rt.params.parameters(scene)
    name, direction = "objects[2].shape.center", np.array([1.0, -0.5, 0.3])
    x = np.asarray(params[name])

    def image(p, spp):
        return np.asarray(rt.render(rt.params.replace(scene, {**params, name: jnp.asarray(p)}),
                                    width=width, height=height, spp=spp))

    step = 0.003
    reference = (image(x + step * direction, 16384) - image(x - step * direction, 16384)) / (2 * step)
    _, d_image = _jvp(scene, params, {name: jnp.asarray(direction)}, width, height, 64)
    mask = np.abs(reference).max(-1) > 0.02 * np.abs(reference).max()
    assert np.linalg.norm((d_image - reference)[mask]) / np.linalg.norm(reference[mask]) < 0.03


def test_a_csg_differences_cut_moves_as_the_rim_where_its_operands_meet(x64):
    """A sphere with a bite taken out of its front by another (``difference``), each flat-coloured,
    seen along the axis through both centres by an orthographic camera: the cut's rim, where the
    subtracted sphere's far side (seen inside the bite) meets the first's front, is a circle of
    radius² 1 − z₀², z₀ = (1 − r² + b²)/2b. Along a tangent of the bite's centre b and radius r the
    term is the circle's outline integral within 0.5 % at 4×4 samples a pixel, with every crossing
    resolved: each side's primitive is crossed nearest the distance seen there, not first."""
    width, height = 24, 18
    red, blue = np.array([1.0, 0.3, 0.2]), np.array([0.2, 0.4, 1.0])
    scene = rt.load_scene(HEAD + "camera { orthographic location <0, 0, -10> look_at <0, 0, 0> "
                          "right x*4 up y*3 }\n"
                          f"difference {{ sphere {{ 0, 1 pigment {{ rgb <1, 0.3, 0.2> }} {FLAT} }} "
                          f"sphere {{ <0, 0, -1>, 0.6 pigment {{ rgb <0.2, 0.4, 1> }} {FLAT} }} }}")
    tangent = {"objects[0].children[1].shape.center": jnp.array([0.0, 0.0, 0.3]),
               "objects[0].children[1].shape.radius": jnp.asarray(0.2)}

    def disc(s):  # the rim's disc in the image at a step s along the tangent
        b, r = -1.0 + 0.3 * s, 0.6 + 0.2 * s
        z0 = (1 - r * r + b * b) / (2 * b)
        return lambda u, v: 1 - z0 * z0 - ((u / width - 0.5) * 4) ** 2 - ((0.5 - v / height) * 3) ** 2

    rate = lambda u, v: (disc(1e-6)(u, v) - disc(-1e-6)(u, v)) / 2e-6  # noqa: E731
    reference = ellipse_outline_term(disc(0.0), rate, width, height)[..., None] * (blue - red)
    edges = _term(scene, tangent, width, height, 4)
    assert _rel_l2(np.asarray(edges.tangent), reference) < 0.005
    assert int(edges.unresolved) == 0 and int(edges.crossings) > 0


def test_an_open_tubes_rim_over_its_own_inside_moves_as_central_differences_say(x64):
    """A lit open cylinder seen from above: past its top rim's near side the bore's far wall is
    seen, the same primitive from inside (the lattice tells the sides apart, and the rim's margin
    is the shape's own, ``AbstractShape.rim_margin``). Along its radius, the derivative (the
    render's own and the term) against central differences of 128×128-sample renders at 8×8
    samples a pixel: measured 12 % rel. L2, nearly all of it in the pixels where the rim meets the
    outline tangentially (a crossing there stands for both: the bowl's case), and 40 % without the
    rim's term; the image's sum within 1.5 % (0.5 %)."""
    width, height = 16, 12
    scene = rt.load_scene(HEAD + "camera { location <0, 2.6, -3> look_at <0, -0.1, 0> angle 40 }\n"
                          "light_source { <-3, 6, -4> color rgb 1 shadowless }\n"
                          "cylinder { <0, -0.5, 0>, <0, 0.5, 0>, 0.8 open pigment { rgb <1, 0.6, 0.3> } "
                          "finish { ambient 0.1 diffuse 0.9 } }")
    params = rt.params.parameters(scene)
    name, step = "objects[0].shape.radius", 0.02

    def image(s):
        moved = rt.params.replace(scene, {**params, name: params[name] + s})
        return np.asarray(rt.render(moved, width=width, height=height, spp=16384))

    reference = (image(step) - image(-step)) / (2 * step)
    _, d_image = _jvp(scene, params, {name: jnp.asarray(1.0)}, width, height, 64)
    mask = np.abs(reference).max(-1) > 0.02 * np.abs(reference).max()
    assert np.linalg.norm((d_image - reference)[mask]) / np.linalg.norm(reference[mask]) < 0.15
    assert d_image.sum() == pytest.approx(reference.sum(), rel=0.015)


def test_a_clipped_spheres_rim_moves_with_its_clipping_plane(x64):
    """A flat sphere clipped by a plane across its front (``clipped_by``), seen along the plane's
    normal by an orthographic camera: past the rim, where the sphere's front meets the plane, both
    its crossings are cut and nothing is seen, so the image is the disc of radius² r² − c². The
    rim's margin is the gap between the sphere's crossing and the plane's nearest it along the ray
    (``_edges._condition_leaves``). Along the plane's distance and the radius: within 0.5 % of the
    disc's outline integral at 4×4 samples a pixel (measured 0.28 %; before: no term, every
    crossing unresolved)."""
    width, height = 24, 18
    red = np.array([1.0, 0.3, 0.2])
    scene = rt.load_scene(HEAD + "camera { orthographic location <0, 0, -10> look_at <0, 0, 0> "
                          "right x*4 up y*3 }\n"
                          f"sphere {{ 0, 1 pigment {{ rgb <1, 0.3, 0.2> }} {FLAT} "
                          "clipped_by { plane { z, -0.3 } } }")
    tangent = {"objects[0].clipped_by[0].shape.distance": jnp.asarray(0.4),
               "objects[0].shape.radius": jnp.asarray(0.1)}

    def disc(s):  # the rim's disc in the image at a step s along the tangent
        c, r = -0.3 + 0.4 * s, 1.0 + 0.1 * s
        return lambda u, v: r * r - c * c - ((u / width - 0.5) * 4) ** 2 - ((0.5 - v / height) * 3) ** 2

    rate = lambda u, v: (disc(1e-6)(u, v) - disc(-1e-6)(u, v)) / 2e-6  # noqa: E731
    reference = ellipse_outline_term(disc(0.0), rate, width, height)[..., None] * red
    edges = _term(scene, tangent, width, height, 4)
    assert _rel_l2(np.asarray(edges.tangent), reference) < 0.005
    assert int(edges.unresolved) == 0


def test_a_bowls_rim_over_its_own_inside_matches_converged_finite_differences(x64):
    """A sphere whose cap is clipped off, lit (shadowless), seen from above: past the rim's near
    side the sphere's inside is seen, the same primitive from its other side (the lattice tells the
    two sides apart: ``_edges.LEAVING``). Moving the clipping plane moves only the rim, so the
    derivative is the term alone: within 3 % of central differences of 128×128-sample renders at
    8×8 samples a pixel (measured 2.2 %, 6.8 % at 4×4: the rim meets the outline tangentially, where
    a crossing stands for its band of the lattice), the image's sum within 1.5 %."""
    width, height = 16, 12
    scene = rt.load_scene(HEAD + "camera { location <0, 2.5, -3> look_at <0, -0.2, 0> angle 45 }\n"
                          "light_source { <2, 5, -3> color rgb 1 parallel point_at <0, 0, 0> shadowless }\n"
                          "sphere { 0, 1 pigment { rgb <1, 0.6, 0.3> } finish { ambient 0.2 diffuse 0.8 } "
                          "clipped_by { plane { y, 0.2 } } }")
    params = rt.params.parameters(scene)
    name = "objects[0].clipped_by[0].shape.distance"

    def image(step):
        moved = rt.params.replace(scene, {**params, name: params[name] + step})
        return np.asarray(rt.render(moved, width=width, height=height, spp=16384))

    reference = (image(0.01) - image(-0.01)) / 0.02
    term = np.asarray(_term(scene, {name: jnp.asarray(1.0)}, width, height, 8).tangent)
    mask = np.abs(reference).max(-1) > 0.02 * np.abs(reference).max()
    assert np.linalg.norm((term - reference)[mask]) / np.linalg.norm(reference[mask]) < 0.03
    assert term.sum() == pytest.approx(reference.sum(), rel=0.015)


def test_reverse_mode_is_the_transpose_of_forward_mode_and_the_image_is_unchanged(x64):
    """⟨w, J t⟩ = ⟨Jᵀ w, t⟩ with the boundary term, for a sphere, a box and the horizon of a ground
    plane (float64); the image is the one without it."""
    width, height = 12, 9
    scene = rt.load_scene(HEAD + "camera { location <0, 0.5, -4> look_at <0, 0, 0> angle 40 }\n"
                          f"plane {{ y, -0.8 pigment {{ rgb 0.6 }} {FLAT} }}\n"
                          f"sphere {{ <0.3, 0.1, 0>, 0.8 pigment {{ rgb <1, 0.5, 0.25> }} {FLAT} }}\n"
                          "box { <-1.6, -0.8, 0.5>, <-0.6, 0.4, 1.2> pigment { rgb <0.2, 0.4, 1> } "
                          f"{FLAT} }}")
    params = rt.params.parameters(scene)
    names = ("objects[1].shape.center", "objects[1].shape.radius", "objects[2].shape.corner2",
             "camera.location")
    primal = {n: params[n] for n in names}
    rng = np.random.default_rng(5)
    tangent = {n: jnp.asarray(rng.normal(size=np.shape(params[n]))) for n in names}
    weights = jnp.asarray(rng.normal(size=(height, width, 3)))

    def image(p):
        return rt.render(rt.params.replace(scene, {**params, **p}), width=width, height=height, spp=4,
                         edges=True)

    value, d_image = jax.jvp(image, (primal,), (tangent,))
    _, pullback = jax.vjp(image, primal)
    (cotangent,) = pullback(weights)
    forward = float(jnp.sum(weights * d_image))
    reverse = sum(float(jnp.sum(cotangent[n] * tangent[n])) for n in names)
    assert reverse == pytest.approx(forward, rel=1e-9)
    plain = rt.render(scene, width=width, height=height, spp=4)
    np.testing.assert_array_equal(np.asarray(value), np.asarray(plain))


def test_a_torus_a_quadric_and_an_open_tube_outline_as_their_closed_forms(x64):
    """Seen along z by an orthographic camera, a torus about z is an annulus of radii R ± r (its
    margin a line's distance from the core circle, minimised over the circle), a quadric
    sphere a disc (the discriminant), and a tilted open cylinder the hull of its rims' ellipses less
    their overlap, where a line passes through both openings (its margin: the side's discriminant,
    and the height of the line's crossings with the side within the ends; ``open_tube_outline_
    term``). Along a tangent of R, r, the quadric's constant and the tube's radius and place the
    term is the closed forms' outline integrals within 1 % at 4×4 samples a pixel. A polynomial
    has no margin: its outline's crossings are counted as unresolved and get no term, not a
    guess, and a warning names it; adaptive anti-aliasing has no lattice. (The term alone,
    ``boundary_term``: the radiance is flat, so the render's own tangent is zero.)"""
    width, height, colour = 24, 18, np.array([1.0, 0.5, 0.25])
    pig = f"pigment {{ rgb <1, 0.5, 0.25> }} {FLAT}"
    base, cap = np.array([1.4, -1.9, -1.0]), np.array([2.0, -1.9, 1.0])
    scene = rt.load_scene(HEAD + "camera { orthographic location <0, 0, -10> look_at <0, 0, 0> "
                          "right x*8 up y*6 }\n"
                          f"torus {{ 1, 0.35 rotate x*90 translate <-1.5, 0.4, 0> {pig} }}\n"
                          "quadric { <1, 1, 1>, <0, 0, 0>, <0, 0, 0>, -0.64 "
                          f"translate <1.9, 0.9, 0> {pig} }}\n"
                          f"cylinder {{ <1.4, -1.9, -1>, <2.0, -1.9, 1>, 0.75 open {pig} }}\n"
                          "polynomial { 4, xyz(4, 0, 0): 1, xyz(0, 4, 0): 1, xyz(0, 0, 4): 1, "
                          "xyz(0, 0, 0): -0.2 translate <-2.8, -2, 0> pigment { rgb 1 } }")
    tangent = {"objects[0].shape.major": jnp.asarray(0.3), "objects[0].shape.minor": jnp.asarray(-0.2),
               "objects[1].shape.coeffs": jnp.zeros(10).at[9].set(1.0),
               "objects[2].shape.radius": jnp.asarray(0.5),
               "objects[2].shape.base": jnp.array([0.3, -0.2, 0.0]),
               "objects[2].shape.cap": jnp.array([0.3, -0.2, 0.0])}

    def disc(cx, cy, radius):  # the disc about (cx, cy) of the plane z = 0, in image points (u, v)
        return lambda u, v: (radius ** 2 - ((u / width - 0.5) * 8 - cx) ** 2
                             - ((0.5 - v / height) * 6 - cy) ** 2)

    def term(make):  # make(s): the disc at a step s along the tangent
        rate = lambda u, v: (make(1e-6)(u, v) - make(-1e-6)(u, v)) / 2e-6  # noqa: E731
        return ellipse_outline_term(make(0.0), rate, width, height)

    reference = (term(lambda s: disc(-1.5, 0.4, 1.35 + 0.1 * s))
                 - term(lambda s: disc(-1.5, 0.4, 0.65 + 0.5 * s))
                 + term(lambda s: disc(1.9, 0.9, np.sqrt(0.64 - s)))
                 + open_tube_outline_term(base, cap, 0.75, 0.5, [0.3, -0.2], (8, 6), width, height)
                 )[..., None] * colour
    with pytest.warns(RuntimeWarning, match="no boundary term for the outlines of poly"):
        edges = _term(scene, tangent, width, height, 4)
    assert _rel_l2(np.asarray(edges.tangent), reference) < 0.01
    assert int(edges.unresolved) > 0 and int(edges.overflow) == 0 and int(edges.dropped) == 0
    with pytest.raises(ValueError, match="adaptive"):
        rt.render(scene, width=width, height=height, adaptive=(0.3, 2), edges=True)


def test_a_dense_area_lights_penumbra_takes_each_samples_jump_alone(x64):
    """A sphere over a plane in an area light of 8×8 samples: the penumbra holds ~64 outlines a few
    pixels wide, a few hundredths of a pixel apart. Each crossing's jump is that of its own
    sample's shadow (the two rays either side lie closer together than the outlines do): the
    term's sum over the plane's pixels is the central difference of the plane's image (12×12
    samples a pixel) within 1.5 % (rays 2e-3 px apart took in their neighbours' jumps: 4.7 %)."""
    from validation.edge_gradients import penumbra_scene_text, sphere_pixels

    width, height, step = 24, 18, 0.02
    plane = ~sphere_pixels(width, height)  # (the sphere's own pixels, and those beside them, left out)
    scene = rt.load_scene(penumbra_scene_text(8))
    params = rt.params.parameters(scene)
    centre = np.asarray(params["objects[1].shape.center"])

    def plane_sum(dz):
        moved = rt.params.replace(scene, {**params,
                                          "objects[1].shape.center": jnp.asarray(centre + [0, 0, dz])})
        return np.asarray(rt.render(moved, width=width, height=height, spp=144))[plane].sum()

    central = (plane_sum(step) - plane_sum(-step)) / (2 * step)
    edges = _term(scene, {"objects[1].shape.center": jnp.array([0.0, 0.0, 1.0])}, width, height, 4)
    term = np.asarray(edges.tangent)[plane].sum()
    assert int(edges.overflow) == 0 and central > 10
    assert abs(term - central) < 0.015 * central, (term, central)


def test_a_spheres_own_shadow_in_an_area_light_moves_as_central_differences_say():
    """A lit sphere seen whole in an area light of 4×4 samples (float32, as users render): near its
    terminator the samples beyond its horizon are shadowed by the sphere itself while the light's
    centre, which shades it, is not, a band of 16 edges. Each is found by the shadow ray's outline
    margin from just off the surface (the line through the point seen grazes the sphere only there,
    a double zero), and its jump by rays either side of the flicker of a float32 shadow that grazes
    the surface it leaves (~5e-4 px here: rays 2e-4 px apart saw one side for ~40 % of these edges).
    The derivative along the light's place, the term and the render's own, is the central difference
    of 16×16-sample renders within 8 % (measured 5.0 %; 34 % without these edges' terms, 20 % with
    the flicker's jumps lost) and its sum within 2 % (0.7 %). Where the light's centre stops
    lighting the sphere, its samples' shadows change but nothing it adds does: no crossing is left
    unresolved (they were 43 % of the crossings)."""
    width, height = 24, 18
    scene = rt.load_scene(HEAD + "camera { location <0, 0.5, -4> look_at <0, 0, 0> angle 40 }\n"
                          "light_source { <-3, 3, -1> color rgb 1 "
                          "area_light <2.5, 0, 0>, <0, 0, 2.5>, 4, 4 }\n"
                          "sphere { <0, 0, 0>, 1 pigment { rgb 1 } finish { ambient 0 diffuse 1 } }")
    params = rt.params.parameters(scene)
    name, direction, step = "lights[0].position", np.array([0.5, -0.4, 0.3], np.float32), 0.01

    def image(p, spp):
        return np.asarray(rt.render(rt.params.replace(scene, {**params, name: jnp.asarray(p)}), width=width,
                                    height=height, spp=spp), np.float64)

    x = np.asarray(params[name])
    central = (image(x + step * direction, 256) - image(x - step * direction, 256)) / (2 * step)
    _, own = _jvp(scene, params, {name: jnp.asarray(direction)}, width, height, 16, edges=False)
    edges = _term(scene, {name: jnp.asarray(direction)}, width, height, 4)
    d_image = own + np.asarray(edges.tangent)
    assert np.linalg.norm(d_image - central) < 0.08 * np.linalg.norm(central)
    assert d_image.sum() == pytest.approx(central.sum(), rel=0.02)
    assert int(edges.unresolved) == 0 and int(edges.crossings) > 0


def test_the_onset_of_total_internal_reflection_moves_as_central_differences_say():
    """Snell's window: a camera inside a glass box (ior 1.33) looking up at its top face sees the
    sky through a disc of the face and, past the critical angle, the face's total internal
    reflection: an edge of the path's branch alone (one primitive, one face, refracted on one
    side and mirrored on the other), whose margin is refraction's discriminant 1 + η²(c² − 1) at
    the crossing. Flat colours: the term is the whole derivative. Along the ior, within 8 % of
    central differences of 16×16-sample renders (measured 5.5 %; all 122 crossings unresolved and
    the derivative 0 without this margin), its sum within 1 % (0.14 %)."""
    width, height = 24, 18
    scene = rt.load_scene(HEAD.replace("assumed_gamma 1.0", "assumed_gamma 1.0 max_trace_level 4")
                          + "camera { location <0, 0, 0> look_at <0, 1, 1> angle 60 }\n"
                          "background { rgb <0.2, 0.4, 1> }\n"
                          "box { <-20, -5, -20>, <20, 1, 20> pigment { rgbf 1 } "
                          "finish { ambient 0 diffuse 0 } interior { ior 1.33 } }\n"
                          f"plane {{ y, -6 pigment {{ rgb <1, 0.5, 0.2> }} {FLAT} }}")
    params = rt.params.parameters(scene)
    name, step = "objects[0].interior.ior", 0.005
    x = float(params[name])

    def image(ior):
        moved = rt.params.replace(scene, {**params, name: jnp.asarray(ior, jnp.float32)})
        return np.asarray(rt.render(moved, width=width, height=height, spp=256), np.float64)

    central = (image(x + step) - image(x - step)) / (2 * step)
    edges = _term(scene, {name: jnp.asarray(1.0, jnp.float32)}, width, height, 4)
    term = np.asarray(edges.tangent)
    assert int(edges.unresolved) == 0 and int(edges.crossings) > 0
    assert np.linalg.norm(term - central) < 0.08 * np.linalg.norm(central)
    assert term.sum() == pytest.approx(central.sum(), rel=0.01)


TWO_DEVICES = """
import json, sys
import equinox as eqx, jax, jax.numpy as jnp, numpy as np
import raytracer as rt
from raytracer._edges import boundary_term
scene = rt.load_scene(open(sys.argv[1]).read())
tangent = {"objects[1].shape.center": jnp.array([0.7, -0.3, 0.5]),
           "camera.location": jnp.array([0.2, 0.3, -0.4])}
dynamic, static = eqx.partition(scene, eqx.is_inexact_array)
zero = jax.tree.map(lambda x: jnp.zeros_like(x) if eqx.is_inexact_array(x) else x, scene)
along = eqx.partition(rt.params.replace(zero, tangent), eqx.is_inexact_array)[0]
term = jax.jit(lambda d, a: boundary_term(d, a, static, 24, 18, 4))
program = term.lower(dynamic, along).as_text()
edges = term(dynamic, along)
# the scene's values on both devices, as a fit's are after its first step (outputs of a program
# split over them): the program reads them as arguments, not as values closed over
mesh = jax.make_mesh((2,), ("tiles",), axis_types=(jax.sharding.AxisType.Auto,))
placed = jax.device_put(dynamic, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec()))
again = term(placed, along)
json.dump({"devices": len(jax.local_devices()), "split": program.count("manual_computation"),
           "image": np.asarray(edges.tangent).tolist(), "crossings": int(edges.crossings),
           "placed": np.asarray(again.tangent).tolist()}, open(sys.argv[2], "w"))
"""


def test_the_term_split_over_two_devices_is_the_term_of_one(tmp_path, x64, two_device_env):
    """With two devices the lattice's rows and the crossings' chunks are split over both (a program
    of two manual computations) and the term is the one-device term (a penumbra: each area-light
    sample's shadow outline a channel of its own), also for a scene whose values are already
    placed on both devices."""
    text = (HEAD + "camera { location <0, 3, -3.5> look_at <0.2, -0.4, 0.4> angle 50 }\n"
            "light_source { <-1, 5, -1> color rgb 1 area_light <2.4, 0, 0>, <0, 0, 1.6>, 3, 2 }\n"
            "plane { y, -0.5 pigment { rgb 0.8 } finish { ambient 0.1 diffuse 0.9 } }\n"
            "sphere { <0.1, 0.4, 0.3>, 0.45 pigment { rgb 1 } }")
    path = tmp_path / "penumbra.pov"
    path.write_text(text)
    env = {**two_device_env, "JAX_ENABLE_X64": "1"}
    run = subprocess.run([sys.executable, "-c", TWO_DEVICES, str(path), str(tmp_path / "out.json")], env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads((tmp_path / "out.json").read_text())
    assert got["devices"] == 2 and got["split"] >= 2
    scene = rt.load_scene(text)
    tangent = {"objects[1].shape.center": jnp.array([0.7, -0.3, 0.5]),
               "camera.location": jnp.array([0.2, 0.3, -0.4])}
    want = _term(scene, tangent, 24, 18, 4)
    assert got["crossings"] == int(want.crossings) > 0
    image = np.asarray(want.tangent)
    assert np.abs(image).max() > 0
    np.testing.assert_allclose(np.asarray(got["image"]), image, rtol=1e-9, atol=1e-12 * np.abs(image).max())
    np.testing.assert_allclose(np.asarray(got["placed"]), image, rtol=1e-9, atol=1e-12 * np.abs(image).max())


def test_pigment_maps_image_maps_and_normals_are_said_to_have_no_term():
    # their pattern edges are not among the lattice's jumps: the warning names each (static: from the
    # packed scene, no program traced)
    from raytracer._edges import _left_out
    from raytracer._packed import pack
    from raytracer._plan import make_plan
    from raytracer.scene import environment_of
    from raytracer.shading._model import make_context

    scene = rt.load_scene("camera { location -5*z look_at 0 } light_source { <0, 5, -5> rgb 1 }\n"
                          "sphere { 0, 1 pigment { checker pigment { rgb 1 } pigment { bozo } } "
                          "normal { onion 0.5 } }")
    plan = make_plan(scene)
    packed = pack(scene, plan)
    ctx = make_context(plan, packed.geo, packed.mats, scene.lights, scene.settings, scene.background,
                       jnp.float32, environment_of(scene))
    said = _left_out(plan, packed.mats, ctx, False)
    assert said == ["the pattern edges of pigment maps and pigment lists",
                    "the pattern edges of normal {} perturbations"]
