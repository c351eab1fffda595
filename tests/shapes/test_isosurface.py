"""The isosurface and the function language it reads: functions compiled from the scene language
against their closed forms (numpy), a sphere cut by its box container crossed where the sphere and
the box say (float64 closed forms, the wall's normals), ``open``, the threshold's side, functions
that are not compiled left out at their place, and the test cases (the cut sphere, a wavy sheet in
a sphere) whose distance functions feed the generic shape tests."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.patterns._expression import evaluate
from raytracer.sdl import load_scene
from raytracer.shapes import Isosurface

from ._case import Case

HEAD = "camera { location <0, 0, -5> look_at 0 }\n"
SPHERE = (("-", ("call", "sqrt", ("+", ("+", ("pow", ("arg", 0), 2), ("pow", ("arg", 1), 2)),
                                  ("pow", ("arg", 2), 2))), ("const", 0)))
WAVE = ("-", ("arg", 1), ("*", ("const", 0), ("call", "sin", ("*", ("const", 1), ("arg", 0)))))


def _sphere_in_box(r, half):
    return Isosurface(constants=np.array([r]), threshold=0.0,
                      container=np.array([[-half] * 3, [half] * 3]), expression=SPHERE)


def _case_cut_sphere():
    def make(constants, threshold, container):
        return Isosurface(constants=constants, threshold=threshold, container=container, expression=SPHERE)

    def distance(p):  # the sphere of radius 0.8 cut by the box |p|∞ ≤ 0.6
        return max(np.linalg.norm(p) - 0.8, np.max(np.abs(p)) - 0.6)

    params = (np.array([0.8]), np.array(0.0), np.array([[-0.6] * 3, [0.6] * 3]))
    return Case("isosurface cut sphere", make, params, distance, np.zeros(3), 1.0)


def _case_wave():
    def make(constants, threshold, container):
        return Isosurface(constants=constants, threshold=threshold, container=container, expression=WAVE,
                          sphere=True, max_gradient=1.6, slots=4)

    def distance(p):  # below the sheet y = 0.2 + 0.3 sin(2x), within the unit sphere
        sheet = (p[1] - 0.2 - 0.3 * np.sin(2 * p[0])) / np.sqrt(1 + (0.6 * np.cos(2 * p[0])) ** 2)
        return max(sheet, np.linalg.norm(p) - 1.0)

    params = (np.array([0.3, 2.0]), np.array(0.2), np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    return Case("isosurface wave in a sphere", make, params, distance, np.zeros(3), 1.0, convex=False)


CASES = [_case_cut_sphere(), _case_wave()]


def _compiled(body, declares=""):
    scene = load_scene(HEAD + declares + f"isosurface {{ function {{ {body} }} }}")
    assert scene.warnings == ()
    (obj,) = scene.objects
    return obj.shape


@pytest.mark.parametrize("body, expected", [
    ("2 + 3 * x^2 - -y", lambda x, y, z: 2 + 3 * x ** 2 + y),
    ("(x < y) + 2 * (x >= 0 & y != 0) + 4 * (x = z | !(y > 0))",
     lambda x, y, z: (x < y) + 2 * ((x >= 0) & (y != 0)) + 4 * ((x == z) | ~(y > 0))),
    ("x > 0 ? y * 2 : z - 1", lambda x, y, z: np.where(x > 0, y * 2, z - 1)),
    ("select(x, 1, 2) + select(y, 3, 4, 5) * 10", lambda x, y, z: np.where(x < 0, 1, 2)
     + 10 * np.where(y < 0, 3, np.where(y == 0, 4, 5))),
    ("mod(x * 7, 2) + min(x, y, z) - max(y, 3 * z) + abs(z)",
     lambda x, y, z: np.fmod(x * 7, 2) + np.minimum(np.minimum(x, y), z) - np.maximum(y, 3 * z) + np.abs(z)),
    ("pow(x, 3) + x^-2 + pow(abs(y) + 1, 0.5) + exp(z) + ln(2 + y) + log(10 + x)",
     lambda x, y, z: x ** 3 + x ** -2.0 + np.sqrt(np.abs(y) + 1) + np.exp(z) + np.log(2 + y)
     + np.log10(10 + x)),
    ("F(y, x) + K * G(z) + u * v + V.y * z", lambda x, y, z: (y - 2 * x) + 1.5 * z * z + x * y + 2 * z),
    ("atan2(y, x) + sin(x) * cos(y) + tan(z / 4) + sqrt(x * x + 1) + floor(y * 3) + ceil(z * 3)"
     " + int(-x * 3)",
     lambda x, y, z: np.arctan2(y, x) + np.sin(x) * np.cos(y) + np.tan(z / 4) + np.sqrt(x * x + 1)
     + np.floor(y * 3) + np.ceil(z * 3) + np.trunc(-x * 3)),
])
def test_functions_compile_to_their_closed_forms(body, expected):
    """POV-Ray's precedence (``^`` above unary minus and ``*``), comparisons, ``&``, ``|``, ``!``,
    ``?:``, the built-ins, user functions with their own parameters inlined, declared floats and a
    declared vector's component, ``u``/``v`` as ``x``/``y``; a written whole power of a negative
    number is defined."""
    declares = ("#declare K = 1.5;\n#declare V = <1, 2, 3>;\n#declare F = function(a, b) { a - 2 * b }\n"
                "#declare G = function(s) { s * s }\n")
    shape = _compiled(body, declares)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.9, 0.9, size=(64, 3))
    pts[0] = (0.5, 0.5, 0.5)  # ties of the comparisons
    pts[1] = (0.25, 0.0, -0.3)
    with jax.enable_x64(True):
        got = np.asarray(jax.jit(lambda c, q: evaluate(shape.expression, c, tuple(q.T)))(
            jnp.asarray(shape.constants, jnp.float64), jnp.asarray(pts)))
    want = expected(*pts.T.astype(np.float64))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_a_functions_numbers_are_its_parameters():
    shape = _compiled("sqrt(x*x + y*y + z*z) - R", "#declare R = 0.75;\n")
    square = [("*", ("arg", k), ("arg", k)) for k in range(3)]
    total = ("+", ("+", square[0], square[1]), square[2])
    assert shape.expression == ("-", ("call", "sqrt", total), ("const", 0))
    np.testing.assert_array_equal(np.asarray(shape.constants), [0.75])


def test_a_sphere_cut_by_its_box_is_crossed_where_the_sphere_and_the_box_are(x64):
    """Radius 0.8 in the box |p|∞ ≤ 0.6: a line enters where it is inside both (the later entry of
    the sphere's and the box's, float64 closed forms) and leaves at the earlier exit; a crossing
    on a box face has the face's normal, one on the sphere the radial normal."""
    shape = _sphere_in_box(0.8, 0.6)
    rng = np.random.default_rng(4)
    o = rng.normal(size=(200, 3)) * 3
    o *= (2.5 / np.linalg.norm(o, axis=1))[:, None]
    d = rng.uniform(-0.5, 0.5, size=(200, 3)) - o
    t, n = jax.jit(jax.vmap(shape.hits))(jnp.asarray(o), jnp.asarray(d))
    t, n = np.asarray(t), np.asarray(n)
    seen = 0
    for i in range(len(o)):
        a, b, c = d[i] @ d[i], o[i] @ d[i], o[i] @ o[i] - 0.64
        disc = b * b - a * c
        with np.errstate(divide="ignore"):
            slab = np.sort(np.stack([(-0.6 - o[i]) / d[i], (0.6 - o[i]) / d[i]]), axis=0)
        enter, leave = slab[0].max(), slab[1].min()
        if disc > 0:
            enter = max(enter, (-b - np.sqrt(disc)) / a)
            leave = min(leave, (-b + np.sqrt(disc)) / a)
        if disc <= 0 or enter >= leave:
            assert not np.isfinite(t[i]).any(), i
            continue
        seen += 1
        np.testing.assert_allclose(t[i], [enter, leave], rtol=1e-9, atol=1e-9)
        for tt, nn in zip(t[i], n[i], strict=True):
            p = o[i] + tt * d[i]
            on_face = np.isclose(np.abs(p).max(), 0.6, atol=1e-9)
            want = np.sign(p) * (np.abs(p) == np.abs(p).max()) if on_face else p / np.linalg.norm(p)
            np.testing.assert_allclose(nn, want, atol=1e-6)
    assert seen > 50


def test_open_removes_the_wall_and_the_threshold_is_the_level():
    """``open``: a line through the cut sees only the sphere's own crossings inside the box; the
    threshold moves the level (F < T is inside: ``F = |p|`` at ``T = 0.5`` is the sphere 0.5)."""
    text = HEAD + ("isosurface { function { sqrt(x*x + y*y + z*z) } threshold 0.5 open "
                   "contained_by { box { -1, 1 } } }\n"
                   "isosurface { function { sqrt(x*x + y*y + z*z) - 1.2 } contained_by { box { -1, 1 } }"
                   " open }")
    small, cut = (o.shape for o in load_scene(text).objects)
    assert small.open and cut.open
    o, d = jnp.array([0.0, 0.0, -3.0]), jnp.array([0.0, 0.0, 1.0])
    t, _ = small.hits(o, d)
    np.testing.assert_allclose(np.sort(np.asarray(t)), [2.5, 3.5], atol=1e-5)
    assert bool(small.inside(jnp.array([0.1, 0.2, 0.3])))
    assert not bool(small.inside(jnp.array([0.6, 0.0, 0.0])))
    t, _ = cut.hits(o, d)  # the sphere of 1.2 is outside the box along z: nothing but the walls, gone
    assert not np.isfinite(np.asarray(t)).any()


def test_what_is_not_compiled_leaves_the_isosurface_out_where_it_is_used(tmp_path):
    path = tmp_path / "s.pov"
    path.write_text(HEAD + "#declare f_x = function { internal(12) }\n"
                    "isosurface { function { f_x(x, y, z) + 1 } }\nsphere { 0, 1 }\n")
    scene = load_scene(path)
    assert [o.shape.kind for o in scene.objects] == ["sphere"]
    (w,) = scene.warnings
    assert "internal function 12" in str(w) and f"{path}:3:" in str(w)


def test_povrays_internal_functions_have_povrays_values():
    """``functions.inc``'s f_r, f_sphere, f_torus and f_rounded_box against the values POV-Ray 3.7
    prints for them (``#debug str(f_…(…), 0, 6)`` at parse time, these four points); f_noise3d is
    our noise (semantics §5.4), in [0, 1], and f_snoise3d, declared from it, is 2·f_noise3d − 1."""
    points = np.array([(0.3, 0.4, 0.2), (1.2, -0.5, 0.7), (0.05, 0.9, -0.3), (2.0, 0.1, 0.1)])
    povray = {"f_sphere(x, y, z, 0.7)": [-0.161484, 0.776482, 0.250000, 1.304994],
              "f_r(x, y, z)": [0.538516, 1.476482, 0.950000, 2.004994],
              "f_torus(x, y, z, 1.0, 0.3)": [0.454248, 0.333649, 0.837640, 0.707474],
              "f_rounded_box(x, y, z, 0.1, 0.5, 0.6, 0.7)": [-0.100001, 0.706225, 0.299999, 1.499999]}
    include = '#include "functions.inc"\n'
    for body, want in povray.items():
        shape = _compiled(body, include)
        got = jax.jit(lambda c, q, s=shape: evaluate(s.expression, c, tuple(q.T)))(shape.constants, points)
        np.testing.assert_allclose(np.asarray(got), want, atol=2e-6, err_msg=body)
    noise = _compiled("f_noise3d(x, y, z)", include)
    snoise = _compiled("f_snoise3d(x, y, z)", include)
    many = np.random.default_rng(2).uniform(-5, 5, size=(256, 3))
    n, s = (np.asarray(jax.jit(lambda c, q, sh=sh: evaluate(sh.expression, c, tuple(q.T)))(
        sh.constants, many)) for sh in (noise, snoise))
    assert 0 <= n.min() and n.max() <= 1 and n.std() > 0.05
    np.testing.assert_allclose(s, 2 * n - 1, atol=1e-6)


@pytest.mark.parametrize("body, message, col", [
    ("x + ", "expected a value, found the end of the function body", 27),
    ("x + ) y", "expected a value in the function body, found ')'", 29),
    ("x y", "expected the end of the function body, found 'y'", 27),
    ("Nope(x)", "undeclared identifier 'Nope'", 25),
    ("min()", "expected 1 to 64 arguments to min(), found 0", 25),
    ("G(x, y)", "expected 1 arguments to the function, found 2", 25),
])
def test_a_body_that_is_not_a_function_is_an_error_at_its_place(body, message, col):
    from raytracer.sdl import SceneError

    with pytest.raises(SceneError, match=message.replace("(", r"\(").replace(")", r"\)")) as e:
        load_scene(HEAD + "#declare G = function(s) { s * s }\n" + f"isosurface {{ function {{ {body} }} }}")
    assert (e.value.location.line, e.value.location.col) == (3, col)


def test_a_ray_marches_the_isosurfaces_whose_containers_it_enters_first(monkeypatch):
    """A group of more isosurfaces than ``CULL_TO`` (twelve balls in a row, shuffled in the scene):
    every ray's crossings are those of all twelve where it enters at most ``CULL_TO`` containers;
    along the row, the first eight balls' (the nearest crossing is among them: a ball nearly fills
    its container)."""
    import jax

    from raytracer import plan as make_plan
    from raytracer.shading._geometry import all_crossings, pack_geometry
    from raytracer.shapes._isosurface import CULL_TO

    order = np.random.default_rng(3).permutation(12)
    ball = "isosurface { function { sqrt(x*x + y*y + z*z) - 0.4 } contained_by { sphere { 0, 0.45 } }"
    balls = "\n".join(f"{ball} translate <{i - 5.5}, 0, 0> }}" for i in order)
    scene = load_scene(HEAD + balls)
    geo = pack_geometry(make_plan(scene), jnp.float32)
    rng = np.random.default_rng(0)
    o = np.stack([rng.uniform(-8, 8, 64), rng.uniform(-0.3, 0.3, 64), np.full(64, -3.0)], axis=1)
    o[:8] = (-9.0, 0.05, 0.0)  # along the row: twelve containers
    d = np.stack([rng.uniform(-0.3, 0.3, 64), rng.uniform(-0.05, 0.05, 64), np.ones(64)], axis=1)
    d[:8] = 0.0
    d[:8, 0], d[:8, 1] = 1.0, rng.uniform(-0.005, 0.005, 8)
    def crossings():  # a new program each time: cull_to is read as it is traced
        return np.asarray(jax.jit(jax.vmap(lambda oo, dd: all_crossings(geo, oo, dd)[0]))(
            jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)))

    culled = crossings()
    monkeypatch.setattr(Isosurface, "cull_to", None)
    every = crossings()
    np.testing.assert_array_equal(culled.min(axis=1), every.min(axis=1))
    assert np.isfinite(every[:8]).sum(axis=1).min() == 24  # twelve balls, two crossings each
    assert np.isfinite(culled[:8]).sum(axis=1).max() == 2 * CULL_TO
    few = np.isfinite(every[8:]).sum(axis=1) <= 2 * CULL_TO
    np.testing.assert_array_equal(culled[8:][few], every[8:][few])
