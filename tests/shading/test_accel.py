"""The native hierarchy (``shading/_accel.py``) only chooses the hit: images and gradients must be
those of the candidate path, which tests every primitive (the reference here)."""

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import load_scene, render
from raytracer._plan import make_plan
from raytracer.shading import _accel
from raytracer.shading._geometry import hierarchy_choice, pack_geometry
from raytracer.shading._materials import pack_materials
from raytracer.shapes._base import AbstractShape
from raytracer.shapes._cone import frustum_form_hits

# the hierarchy under test: the native one, or its JAX twin when the run has RAYTRACER_ACCEL=jax
ACCEL = "jax" if os.environ.get("RAYTRACER_ACCEL", "").strip().lower() == "jax" else "native"

pytestmark = pytest.mark.skipif(ACCEL == "native" and _accel.unavailable_reason() is not None,
                                reason=str(_accel.unavailable_reason()))

# every kind the hierarchy holds, transformed, next to what it must leave to the candidates
# (a plane, a CSG, a glass sphere) and objects that only some rays see
SCENE = """
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 4 }
camera { location <0, 6, -12> look_at <0, 0.5, 0> angle 55 }
light_source { <-8, 14, -9> color rgb 1 }
light_source { <9, 6, -4> color rgb 0.4 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
#declare R = seed(7);
#for (i, 0, 69)
  #declare P = <rand(R) * 10 - 5, rand(R) * 1.5, rand(R) * 8 - 3>;
  #switch (mod(i, 7))
  #case (0) sphere { 0, 0.2 + 0.3 * rand(R) scale <1, 0.5 + rand(R), 1> rotate <0, 0, 40 * rand(R)>
                     translate P pigment { rgb <rand(R), 0.5, 0.7> } finish { phong 0.6 } } #break
  #case (1) box { -0.3, <0.2, 0.5, 0.3> rotate <30 * rand(R), 60 * rand(R), 0> translate P
                  pigment { rgb <0.9, rand(R), 0.2> } } #break
  #case (2) triangle { <-0.5, 0, 0>, <0.5, 0, 0.2>, <0, 0.8, -0.1> rotate <0, 90 * rand(R), 0>
                       translate P pigment { rgb <0.2, 0.8, rand(R)> } } #break
  #case (4) cylinder { <0, -0.3, 0>, <0.2, 0.4, 0.1>, 0.15 + 0.2 * rand(R) #if (mod(i, 2)) open #end
                       rotate <50 * rand(R), 0, 0> translate P pigment { rgb <0.5, 0.2, rand(R)> } } #break
  #case (5) cone { <0, -0.3, 0>, 0.4 * rand(R), <0, 0.4, 0.2>, 0.3 #if (mod(i, 2)) open #end
                   scale <1, 1.5, 1> translate P pigment { rgb <rand(R), 1, 0.4> } } #break
  #case (6) disc { P, <rand(R), 1, rand(R) - 0.5>, 0.5, 0.2 * rand(R)
                   pigment { rgb <1, 0.4, rand(R)> } } #break
  #case (3) smooth_triangle { <-0.4, 0, 0>, <0, 0, -1>, <0.4, 0, 0>, <1, 0, -1>, <0, 0.7, 0>, <-1, 1, -1>
                          translate P pigment { rgb 0.8 } }
  #end
#end
mesh2 { vertex_vectors { 4, <-1, 0, 0>, <1, 0, 0>, <0, 1.5, 0>, <0, 0.5, -1> }
        face_indices { 3, <0, 1, 2>, <0, 1, 3>, <1, 2, 3> }
        pigment { rgb <1, 0.6, 0.2> } translate <3, 0.2, -2> }
sphere { <-2, 1, -3>, 0.8 pigment { rgb 0.9 } finish { reflection 0.7 } }
sphere { <0, 1, -4>, 0.7 pigment { rgbf <1, 1, 1, 0.9> } interior { ior 1.3 } }
mesh { triangle { <-3, 0.1, -2>, <3, 0.1, -2>, <0, 3, -1.5> }
       triangle { <-3, 0.1, -2.3>, <3, 0.1, -2.3>, <0, 2.5, -3> }
       pigment { rgbf <1, 0.3, 0.2, 0.8> } }
difference { box { -0.6, 0.6 } sphere { 0, 0.75 } pigment { rgb <0.3, 0.3, 1> } translate <2, 0.6, -5> }
sphere { <-3.5, 0.5, -5>, 0.5 pigment { rgb 1 } no_shadow }
sphere { <-2.9, 0.5, -5.5>, 0.4 pigment { rgb <1, 0, 0> } no_image }
sphere { <-1.9, 2.5, -3.4>, 0.3 pigment { rgb <0, 1, 0> } no_reflection }
torus { 0.6, 0.15 rotate <70, 20, 0> translate <1.2, 0.8, -3.5> pigment { rgb <0.9, 0.8, 0.1> } }
torus { 0.4, 0.2 scale <1, 2, 1> translate <-1, 0.4, -1.5> pigment { rgb <0.1, 0.7, 0.7> } }
"""


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "accel.pov"
    path.write_text(SCENE)
    return load_scene(path, width=48, height=36)


def _tangent(scene, seed=0):
    """A random direction of every floating-point parameter of the scene (float0 for the rest)."""
    rng = np.random.default_rng(seed)
    leaves, treedef = jax.tree_util.tree_flatten(scene)

    def one(x):
        x = np.asarray(x)
        if np.issubdtype(x.dtype, np.floating):
            return rng.normal(size=x.shape).astype(x.dtype)
        return np.zeros(x.shape, jax.dtypes.float0)

    return treedef.unflatten([one(x) for x in leaves])


def test_hierarchy_holds_only_what_it_may(scene, monkeypatch):
    monkeypatch.setenv("RAYTRACER_ACCEL", ACCEL)
    monkeypatch.setattr(_accel, "MIN_FILTER_ITEMS", 1)  # the scene's 3 transparent items: held
    plan = make_plan(scene)
    geo = pack_geometry(plan, jnp.float32)
    held = {p for g in geo.groups if g.accelerated for p in g.prims}
    kinds = {plan.prims[i].kind for i in held}
    kinds_twin = {"sphere", "box", "triangle", "smooth_triangle", "cylinder", "cone", "disc", "mesh"}
    assert kinds == (kinds_twin | {"torus"} if ACCEL == "native" else kinds_twin)
    # the loop's 70, the mesh2's 3 triangles, the mirror sphere and the three flagged spheres, the
    # tori (native only); the transparent glass sphere and mesh filter shadows, which only the
    # native hierarchy can ask; the difference, one item and its two members (native only)
    native = 1 + 2 + 2 + 3 if ACCEL == "native" else 0
    assert geo.accel.n_items == 70 + 3 + 4 + native
    left = [plan.prims[i] for i in range(len(plan.prims)) if i not in held]
    # the plane (unbounded) (and with the JAX twin the transparent sphere and mesh, the tori, and
    # the box and sphere of the difference)
    extra = [] if ACCEL == "native" else ["mesh", "sphere", "torus", "torus", "box", "sphere"]
    assert sorted(p.kind for p in left) == sorted(["plane"] + extra)
    assert sum(bool(p.conditions) for p in left) == (0 if ACCEL == "native" else 2)
    # the queries evaluate one frustum kernel for the cylinders and cones, open or not
    frustums = [s for kernel, s in _accel._alike(geo.accel, geo.shapes, range(len(geo.accel.groups)))
                if kernel is frustum_form_hits]
    assert len(frustums) == 1 and len(frustums[0]) == 4  # cylinder, open cylinder, cone, open cone


def test_the_hierarchy_gives_the_candidate_paths_image_and_derivatives(scene, monkeypatch):
    """Every pixel and its derivative along a random direction of every scene parameter (forward
    mode: one program per path, where reverse mode's pair of programs cost 2.5 minutes of the
    suite), with the hierarchy and with every primitive a candidate."""
    monkeypatch.setattr(_accel, "MIN_FILTER_ITEMS", 1)  # its transparent sphere and mesh: held
    tangent = _tangent(scene)
    out = {}
    for mode in (ACCEL, "none"):
        monkeypatch.setenv("RAYTRACER_ACCEL", mode)
        jax.clear_caches()
        image, d_image = jax.jvp(lambda s: render(s, width=48, height=36), (scene,), (tangent,))
        out[mode] = np.asarray(image), np.asarray(d_image)
    (ours, d_ours), (reference, d_reference) = out[ACCEL], out["none"]
    assert np.isfinite(ours).all() and np.isfinite(d_ours).all()
    diff = np.abs(ours - reference).max(axis=-1)
    # the same hits to float32 rounding; a pixel may differ where two surfaces are within
    # rounding of each other along its ray (none in this scene at this size)
    assert np.count_nonzero(diff > 1e-4) == 0, np.argwhere(diff > 1e-4)
    assert np.abs(d_reference).max() > 1.0  # the direction moves the image
    np.testing.assert_allclose(d_ours, d_reference, rtol=1e-4, atol=1e-4)


SUPERELLIPSOIDS = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 1.5, -5> look_at <0, 0.5, 0> angle 50 }
light_source { <-8, 14, -9> color rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
superellipsoid { <0.3, 0.8> scale 0.5 rotate <20, 40, 0> translate <-1, 0.6, 0> pigment { rgb 0.8 } }
superellipsoid { <2.5, 2.5> scale <0.5, 0.4, 0.5> translate <0.6, 1.2, 0.5> pigment { rgb 0.5 } }
difference { superellipsoid { <0.5, 0.5> } sphere { <0, 0.6, -0.5>, 0.7 } scale 0.5 rotate 30 * y
             translate <1.2, 0.5, -0.5> pigment { rgb <0.9, 0.9, 0.3> } finish { phong 0.5 } }
"""


@pytest.mark.skipif(ACCEL != "native", reason="the superellipsoid kernel is the native hierarchy's")
def test_superellipsoids_in_the_hierarchy_give_the_candidate_paths_image(tmp_path, monkeypatch):
    """Superellipsoids (convex, concave, a CSG member) held by the hierarchy: the candidate path's
    pixels (their hits are the native solver's crossings refined by ``near_hit``)."""
    path = tmp_path / "se.pov"
    path.write_text(SUPERELLIPSOIDS)
    scene = load_scene(path, width=32, height=24)
    monkeypatch.setattr(_accel, "MIN_ITEMS", 1)
    out = {}
    for mode in ("none", "native"):
        monkeypatch.setenv("RAYTRACER_ACCEL", mode)
        out[mode] = np.asarray(render(scene, width=32, height=24))
    geo = pack_geometry(make_plan(scene), jnp.float32)
    assert sum(g.kind == "superellipsoid" and g.accelerated for g in geo.groups) >= 2  # items, member
    assert (np.abs(out["native"] - out["none"]).max(axis=-1) > 1e-4).sum() == 0


def test_a_superellipsoid_refines_a_given_crossing_with_the_kernels_derivatives(x64):
    """``near_hit`` (the crossing the hierarchy's query found, two Newton steps) has the value and
    the derivatives along random directions of (e, n, o, d) of the first crossing the shape's own
    kernel finds, for random rays through convex, concave and mixed superellipsoids (float64)."""
    from raytracer.shapes import Superellipsoid

    rng = np.random.default_rng(5)

    def first(e, n, o, d):
        t, _ = jax.vmap(Superellipsoid(e=e, n=n).hits)(o, d)
        return jnp.where(jnp.isfinite(t[:, 0]), t[:, 0], 0.0)

    def near(t0, e, n, o, d):
        t, _ = jax.vmap(lambda o, d, t0: Superellipsoid(e=e, n=n).near_hit(o, d, t0))(o, d, t0)
        return t[:, 0]

    first_jvp = jax.jit(lambda args, tangent: jax.jvp(first, args, tangent))
    near_jvp = jax.jit(lambda t0, args, tangent: jax.jvp(lambda *a: near(t0, *a), args, tangent))
    for e, n in ((0.3, 0.8), (2.5, 2.5), (0.4, 3.0)):
        o = jnp.asarray(rng.uniform(-3, 3, (16, 3)))
        d = jnp.asarray(rng.normal(scale=0.3, size=(16, 3))) - o
        args = (jnp.float64(e), jnp.float64(n), o, d)
        tangent = tuple(jnp.asarray(rng.normal(size=np.shape(x))) for x in args)
        t0, dt0 = first_jvp(args, tangent)
        hit = np.asarray(t0) != 0.0
        assert hit.sum() >= 3
        t1, dt1 = near_jvp(t0, args, tangent)
        np.testing.assert_allclose(np.asarray(t1)[hit], np.asarray(t0)[hit], rtol=1e-12)
        np.testing.assert_allclose(np.asarray(dt1)[hit], np.asarray(dt0)[hit], rtol=1e-8, atol=1e-10)


def test_closest_and_any_hit_queries_in_float64(x64, monkeypatch):
    """The query's distances against a brute-force minimum over the same items (float64)."""
    monkeypatch.setenv("RAYTRACER_ACCEL", ACCEL)
    build, closest_query, any_query = _accel._hierarchy()
    rng = np.random.default_rng(3)
    n = 300
    centres = rng.uniform(-5, 5, (n, 3))
    radii = rng.uniform(0.05, 0.5, n)
    eye = np.broadcast_to(np.eye(4)[:3].reshape(12), (n, 12))
    params = np.concatenate([eye, centres, radii[:, None], np.zeros((n, 8))], axis=1)
    boxes = np.concatenate([centres - radii[:, None], centres + radii[:, None]], axis=1)
    node_box, node_info, order = build(jnp.asarray(boxes))
    tables = (node_box, node_info, order, jnp.zeros(n, jnp.int32), jnp.full(n, 7, jnp.int32),
              jnp.asarray(params), *map(jnp.asarray, _accel.one_unit(n, params.dtype)))
    o = rng.uniform(-6, 6, (500, 3))
    d = rng.normal(size=(500, 3))
    item, t = closest_query(tables, jnp.asarray(o), jnp.asarray(d), jnp.zeros(500),
                            jnp.full(500, 1e7), jnp.ones(500, jnp.int32))
    # brute force: the smaller positive root of every sphere
    oc = o[:, None, :] - centres[None]
    a = np.sum(d * d, axis=1)[:, None]
    b = np.einsum("ri,rni->rn", d, oc)
    c = np.sum(oc * oc, axis=2) - radii[None] ** 2
    disc = b * b - a * c
    sq = np.sqrt(np.where(disc >= 0, disc, 0))
    roots = np.stack([(-b - sq) / a, (-b + sq) / a])
    roots = np.where((disc >= 0)[None] & (roots > 0), roots, np.inf).min(axis=0)
    want_item = np.where(np.isfinite(roots.min(axis=1)), roots.argmin(axis=1), -1)
    np.testing.assert_array_equal(np.asarray(item), want_item)
    hit = want_item >= 0
    np.testing.assert_allclose(np.asarray(t)[hit], roots.min(axis=1)[hit], rtol=1e-12)
    blocked, _ = any_query(tables, jnp.asarray(o), jnp.asarray(d), jnp.zeros(500), jnp.full(500, 1e7),
                           jnp.ones(500, jnp.int32))
    np.testing.assert_array_equal(np.asarray(blocked) >= 0, hit)


def test_auto_mode_picks_the_native_hierarchy_on_a_cpu_and_the_jax_one_elsewhere(monkeypatch):
    monkeypatch.setenv("RAYTRACER_ACCEL", "auto")
    assert _accel.mode() == "native"
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert _accel.mode() == "jax"
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    with pytest.raises(_accel.AccelUnavailable, match="default device is gpu"):
        _accel.mode()
    monkeypatch.setenv("RAYTRACER_ACCEL", "none")
    assert _accel.mode() == "none"


@pytest.mark.skipif(ACCEL != "native", reason="the all-crossings query is the native hierarchy's")
def test_all_crossings_query_keeps_the_nearest_items_in_order(x64):
    """Filtered shadows ask for every item on a segment: the nearest ``FILTER_ITEMS`` by their first
    crossing, ascending, with that crossing, and how many there were, against brute force (float64)."""
    build, _, _ = _accel._hierarchy()
    rng = np.random.default_rng(5)
    n, rays = 1500, 300
    centres = rng.uniform(-3, 3, (n, 3))
    radii = rng.uniform(0.2, 0.9, n)
    eye = np.broadcast_to(np.eye(4)[:3].reshape(12), (n, 12))
    params = np.concatenate([eye, centres, radii[:, None], np.zeros((n, 8))], axis=1)
    boxes = np.concatenate([centres - radii[:, None], centres + radii[:, None]], axis=1)
    mask = np.where(rng.uniform(size=n) < 0.7, _accel.MASK_FILTER, _accel.MASK_SHADOW).astype(np.int32)
    tables = (*build(jnp.asarray(boxes)), jnp.zeros(n, jnp.int32), jnp.asarray(mask), jnp.asarray(params),
              *map(jnp.asarray, _accel.one_unit(n, params.dtype)))
    o = rng.uniform(-3, 3, (rays, 3))
    d = rng.normal(size=(rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tmin, tmax = rng.uniform(0, 1, rays), rng.uniform(1, 14, rays)
    item, count, t = _accel._all_query(tables, jnp.asarray(o), jnp.asarray(d), jnp.asarray(tmin),
                                    jnp.asarray(tmax), jnp.full(rays, _accel.MASK_FILTER, jnp.int32))
    oc = o[:, None, :] - centres[None]
    b = np.einsum("ri,rni->rn", d, oc)
    c = np.sum(oc * oc, axis=2) - radii[None] ** 2
    disc = b * b - c
    sq = np.sqrt(np.where(disc >= 0, disc, 0))
    lo, hi = tmin[:, None], tmax[:, None]
    near, far = -b - sq, -b + sq
    first = np.where((near > lo) & (near < hi), near, np.where((far > lo) & (far < hi), far, np.inf))
    first = np.where((disc >= 0) & (mask == _accel.MASK_FILTER)[None], first, np.inf)
    k = _accel.FILTER_ITEMS
    np.testing.assert_array_equal(np.asarray(count), np.isfinite(first).sum(axis=1))
    want = np.argsort(first, axis=1, kind="stable")[:, :k]
    want = np.where(np.isfinite(np.take_along_axis(first, want, axis=1)), want, -1)
    np.testing.assert_array_equal(np.asarray(item), want)
    np.testing.assert_allclose(np.asarray(t), np.sort(first, axis=1)[:, :k], rtol=1e-12)
    assert 0.2 < (np.asarray(count) > k).mean() < 0.8  # segments with fewer and more than k items


@pytest.mark.skipif(ACCEL != "native", reason="the tie rule is the native hierarchy's")
def test_closest_query_breaks_ties_as_povray_tests_objects(x64):
    """Coincident faces (semantics §4.4): the item of the unit whose box the ray enters first wins,
    else the item of the earlier unit, in whatever order the items were given; within one unit,
    the nearer crossing."""
    from raytracer.shapes._base import NATIVE_BOX, NATIVE_SPHERE

    eye = np.eye(4)[:3].reshape(12)

    def item(kind, q):
        return np.concatenate([eye, q, np.zeros(12 - len(q))])

    # items 0 and 1: boxes whose front faces coincide at z = -1; item 2: a sphere far to the side
    params = np.stack([item(NATIVE_BOX, [-1, -1, -1, 1, 1, 1]), item(NATIVE_BOX, [-1, -1, -1, 1, 1, 3]),
                       item(NATIVE_SPHERE, [9, 9, 9, 0.5])])
    kind = np.array([NATIVE_BOX, NATIVE_BOX, NATIVE_SPHERE], np.int32)
    boxes = np.array([[-1, -1, -1, 1, 1, 1], [-1, -1, -1, 1, 1, 3], [8.5, 8.5, 8.5, 9.5, 9.5, 9.5]], float)
    o, d = jnp.asarray([[0.2, 0.1, -5.0]]), jnp.asarray([[0.0, 0.0, 1.0]])

    def chosen(item_unit, unit_box, swap=False):
        perm = np.array([1, 0, 2]) if swap else np.arange(3)
        node_box, node_info, order = _accel._build(jnp.asarray(boxes[perm]))
        tables = (node_box, node_info, order, jnp.asarray(kind[perm]), jnp.full(3, 7, jnp.int32),
                  jnp.asarray(params[perm]), jnp.asarray(np.asarray(item_unit, np.int32)[perm]),
                  jnp.asarray(np.asarray(unit_box, float)), jnp.zeros(1, jnp.int32))
        it, t = _accel._closest_query(tables, o, d, jnp.zeros(1), jnp.full(1, 1e7), jnp.ones(1, jnp.int32))
        assert float(t[0]) == 4.0
        return int(perm[int(it[0])])

    far = [9, 9, 9, 9, 9, 9]
    for swap in (False, True):
        # equal entries (both boxes begin at z = -1 on this ray): the earlier unit
        assert chosen([0, 1, 2], [[-1, -1, -1, 1, 1, 1], [-1, -1, -1, 1, 1, 3], far], swap) == 0
        assert chosen([1, 0, 2], [[-1, -1, -1, 1, 1, 3], [-1, -1, -1, 1, 1, 1], far], swap) == 1
        # the second unit's box begins at z = -3 (a unit holding more than this box): it is entered first
        assert chosen([0, 1, 2], [[-1, -1, -1, 1, 1, 1], [-1, -1, -3, 1, 1, 3], far], swap) == 1
        # an unbounded unit box is entered at -inf: it wins every tie
        inf = np.inf
        assert chosen([0, 1, 2], [[-1, -1, -1, 1, 1, 1], [-inf, -inf, -inf, inf, inf, inf], far], swap) == 1


@pytest.mark.skipif(ACCEL != "native", reason="the torus kernel is the native hierarchy's")
def test_closest_query_finds_the_first_torus_crossing(x64):
    """The native torus kernel (a monotonic split of its quartic, bisection) against the torus's
    own JAX kernel in float64: the same first item and distance for rays aimed at randomly placed,
    turned and scaled tori (some start inside a tube)."""
    from raytracer.shapes import Torus
    from raytracer.shapes._base import NATIVE_TORUS

    rng = np.random.default_rng(11)
    n, rays = 40, 600
    major = rng.uniform(0.3, 1.0, n)
    minor = rng.uniform(0.05, 0.4, n) * major
    maps, boxes = [], []
    for i in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = q * rng.uniform(0.5, 1.5), rng.uniform(-3, 3, 3)
        half = np.array([major[i] + minor[i], minor[i], major[i] + minor[i]])
        corners = np.array([[(-half, half)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
        world = corners @ m[:3, :3].T + m[:3, 3]
        boxes.append(np.concatenate([world.min(0), world.max(0)]))
        maps.append(np.linalg.inv(m))
    maps = np.array(maps)
    params = np.concatenate([maps[:, :3].reshape(n, 12), major[:, None], minor[:, None],
                             np.zeros((n, 10))], axis=1)
    units = tuple(map(jnp.asarray, _accel.one_unit(n, np.float64)))
    tables = (*_accel._build(jnp.asarray(np.array(boxes))), jnp.full(n, NATIVE_TORUS, jnp.int32),
              jnp.full(n, 7, jnp.int32), jnp.asarray(params), *units)
    o = rng.uniform(-4, 4, (rays, 3))
    aim = np.linalg.inv(maps)[rng.integers(0, n, rays), :3, 3] + rng.normal(scale=0.3, size=(rays, 3))
    d = aim - o
    _assert_closest_is_the_first_crossing(tables, o, d, lambda a, b: Torus(major=a, minor=b), major, minor,
                                          maps)


def _assert_closest_is_the_first_crossing(tables, o, d, shape_of, a, b, maps):
    """The native closest-hit query's item and distance are those of the first positive crossing
    of the shapes ``shape_of(a[i], b[i])`` placed by ``maps`` (object from world), by their own
    JAX kernel, for the rays ``o + t d`` (float64); a third of the rays at least hit one."""
    rays = len(o)
    item, t = _accel._closest_query(tables, jnp.asarray(o), jnp.asarray(d), jnp.zeros(rays),
                                    jnp.full(rays, 1e7), jnp.ones(rays, jnp.int32))

    def crossings(a, b, m, o, d):
        return shape_of(a, b).hits(m[:3, :3] @ o + m[:3, 3], m[:3, :3] @ d)[0]

    every = jax.vmap(jax.vmap(crossings, in_axes=(0, 0, 0, None, None)), in_axes=(None, None, None, 0, 0))
    tt = np.asarray(jax.jit(every)(jnp.asarray(a), jnp.asarray(b), jnp.asarray(maps), jnp.asarray(o),
                                   jnp.asarray(d)))
    first = np.where(tt > 0, tt, np.inf).min(axis=2)
    want = np.where(np.isfinite(first.min(axis=1)), first.argmin(axis=1), -1)
    assert (want >= 0).sum() > rays // 3  # the rays do hit them
    np.testing.assert_array_equal(np.asarray(item), want)
    hit = want >= 0
    np.testing.assert_allclose(np.asarray(t)[hit], first.min(axis=1)[hit], rtol=1e-9)


@pytest.mark.skipif(ACCEL != "native", reason="the superellipsoid kernel is the native hierarchy's")
@pytest.mark.parametrize("exponents", [(0.05, 2.0), (2.0, 6.0), (0.3, 5.0)],
                         ids=["convex", "concave", "mixed"])
def test_closest_query_finds_the_first_superellipsoid_crossing(x64, exponents):
    """The native superellipsoid kernel (Newton's method on the convex norm; elsewhere pieces split
    at their extrema, bisection) against the shape's own JAX kernel in float64: the same first item
    and distance for rays aimed at randomly placed, turned and scaled superellipsoids of exponents
    e, n drawn from the range (some rays start inside one)."""
    from raytracer.shapes import Superellipsoid
    from raytracer.shapes._base import NATIVE_SUPERELLIPSOID

    rng = np.random.default_rng(12)
    n, rays = 30, 500
    e, nn = rng.uniform(*exponents, n), rng.uniform(*exponents, n)
    maps, boxes = [], []
    for _ in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = q * rng.uniform(0.3, 0.8, 3), rng.uniform(-3, 3, 3)
        corners = np.array([[(-1, 1)[(k >> a) & 1] for a in range(3)] for k in range(8)], float)
        world = corners @ m[:3, :3].T + m[:3, 3]
        boxes.append(np.concatenate([world.min(0), world.max(0)]))
        maps.append(np.linalg.inv(m))
    maps = np.array(maps)
    params = np.concatenate([maps[:, :3].reshape(n, 12), e[:, None], nn[:, None], np.zeros((n, 10))], axis=1)
    units = tuple(map(jnp.asarray, _accel.one_unit(n, np.float64)))
    tables = (*_accel._build(jnp.asarray(np.array(boxes))), jnp.full(n, NATIVE_SUPERELLIPSOID, jnp.int32),
              jnp.full(n, 7, jnp.int32), jnp.asarray(params), *units)
    o = rng.uniform(-4, 4, (rays, 3))
    centres = np.linalg.inv(maps)[:, :3, 3]
    o[:40] = centres[rng.integers(0, n, 40)]  # inside one
    d = centres[rng.integers(0, n, rays)] + rng.normal(scale=0.3, size=(rays, 3)) - o
    _assert_closest_is_the_first_crossing(tables, o, d, lambda a, b: Superellipsoid(e=a, n=b), e, nn, maps)


NO_TWIN_CSG = "the native hierarchy evaluates CSG objects; its JAX twin does not"

# CSG objects the native hierarchy holds as one item each (``_geometry.csg_units``; an ``inverse``
# one too), next to those it must leave to the candidates: a transparent shadow caster, a kind
# without a native kernel
CSG_SCENE = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 6, -12> look_at <0, 0.5, 0> angle 50 }
light_source { <-8, 14, -9> color rgb 1 }
light_source { <9, 6, -4> color rgb 0.4 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
#declare R = seed(3);
#for (i, 0, 9)
  #declare P = <rand(R) * 10 - 5, 0.2 + rand(R) * 1.5, rand(R) * 8 - 3>;
  #switch (mod(i, 5))
  #case (0) difference { box { -0.4, 0.4 } cylinder { -y, y, 0.25 } rotate <30 * rand(R), 60 * rand(R), 0>
                         translate P pigment { rgb <0.9, rand(R), 0.2> } } #break
  #case (1) intersection { sphere { 0, 0.5 } plane { <rand(R) - 0.5, 1, 0.2>, 0.1 } translate P
                           pigment { rgbf <0.2, 0.8, rand(R), 0.6> } } #break
  #case (2) merge { sphere { 0, 0.35 } cone { -0.5 * y, 0.3, 0.5 * y, 0 } rotate 40 * x translate P
                    pigment { rgb <rand(R), 0.5, 0.7> } finish { phong 0.6 } } #break
  #case (3) sphere { 0, 0.5 clipped_by { box { -1, <1, 0.2, 1> } } translate P
                    pigment { rgb <1, 0.4, rand(R)> } } #break
  #case (4) difference { torus { 0.5, 0.2 } box { <0, -1, -1>, <1, 1, 1> } rotate <70, 20 * rand(R), 0>
                         translate P pigment { rgb <0.1, 0.7, rand(R)> } } #break
  #end
#end
union { sphere { 0, 0.6 } box { <-1, -0.2, -0.2>, <1, 0.2, 0.2> } clipped_by { plane { x, 0.5 } }
        pigment { rgb <0.8, 0.8, 0.3> } translate <-3, 1, -5> }
difference { intersection { box { -0.6, 0.6 } sphere { 0, 0.8 } } cylinder { -z, z, 0.3 }
             sphere { <0, 0.6, 0>, 0.3 no_shadow } pigment { rgb <0.3, 0.3, 1> } translate <2, 0.7, -5> }
difference { sphere { 0, 1 } sphere { 0, 0.9 } plane { -z, 0 } pigment { rgb <1, 0.2, 0.2> }
             translate <-0.5, 1, -4> }
difference { box { -0.3, 0.3 } sphere { 0, 0.4 } inverse pigment { rgb 0.7 } translate <0, 0.3, -6> }
intersection { sphere { 0, 0.5 } box { -0.4, 0.4 } pigment { rgbf <1, 0.5, 0.5, 0.7> }
               translate <1, 0.5, -6.5> }
intersection { quadric { <1, -1, 1>, 0, 0, -0.04 } box { -0.5, 0.5 } rotate <20, 0, 30>
               pigment { rgb <0.9, 0.6, 0.3> } translate <-4, 0.6, -2> }
intersection { quadric { <1, 1, 1>, 0, 0, -0.25 } box { -0.4, 0.4 } pigment { rgb 0.6 }
               translate <3, 0.5, -3> }
box { <-0.3, 0, -0.3>, <0.3, 0.6, 0.3> pigment { rgbf <0.6, 1, 0.6, 0.7> } translate <-2, 0, -6> }
sphere { <2.5, 0.5, -7>, 0.4 pigment { rgbf <0.6, 0.6, 1, 0.8> } }
"""


@pytest.mark.slow  # two forward-mode programs
@pytest.mark.skipif(ACCEL != "native", reason=NO_TWIN_CSG)
def test_csg_objects_in_the_hierarchy_give_the_candidate_paths_image_and_derivatives(tmp_path, monkeypatch):
    """A CSG object is one item: the native query finds the first crossing of a member that the
    object's conditions count (bvh.cc's programs, in float64), the member's kernel computes the hit
    again. Pixels and derivatives are the candidate path's, shadows included, filtered ones too
    (a transparent box and sphere of their own among the transparent CSG members: one kernel
    evaluation serves the groups of one shape variant, ``_accel._alike``)."""
    path = tmp_path / "csg.pov"
    path.write_text(CSG_SCENE)
    scene = load_scene(path, width=48, height=36)
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    monkeypatch.setattr(_accel, "MIN_FILTER_ITEMS", 1)  # its few transparent objects through the hierarchy
    plan = make_plan(scene)
    geo = pack_geometry(plan, jnp.float32)
    left = sorted(plan.prims[i].kind for g in geo.groups if not g.accelerated for i in g.prims)
    # the floor (the quadrics' intersections are held, bounded by their boxes, as the inverse
    # difference is: its surface is the difference's, inside the difference's box; the transparent ones filter
    # shadows through the all-crossings query, one entry per counted crossing)
    assert left == ["plane"]
    csg_items = int(np.count_nonzero(np.asarray(geo.accel.tables[3]) == _accel.KIND_CSG))
    assert csg_items == 10 + 7
    # the transparent box and sphere of their own share a kernel evaluation with CSG members, in
    # the closest-hit and the filtering query alike
    for groups in (range(len(geo.accel.groups)), [g for g, ag in enumerate(geo.accel.groups) if ag.filters]):
        mixed = [s for _, s in _accel._alike(geo.accel, geo.shapes, groups)
                 if len({geo.accel.groups[g].csg for g in s}) == 2]
        assert len(mixed) == 2, mixed
    _assert_native_jvp_is_the_candidate_paths(scene, (48, 36), _tangent(scene, seed=1), monkeypatch, 1e-4)


def _assert_native_jvp_is_the_candidate_paths(scene, size, tangent, monkeypatch, tol):
    """The image (``size``) and its derivative along ``tangent`` through the native hierarchy are
    those of the candidate path (pixels to 1e-4, derivatives to ``tol``), finite, not all flat."""
    width, height = size
    out = {}
    for mode in ("native", "none"):
        monkeypatch.setenv("RAYTRACER_ACCEL", mode)
        jax.clear_caches()
        image, d_image = jax.jvp(lambda s: render(s, width=width, height=height), (scene,), (tangent,))
        out[mode] = np.asarray(image), np.asarray(d_image)
    (ours, d_ours), (reference, d_reference) = out["native"], out["none"]
    assert np.isfinite(ours).all() and np.isfinite(d_ours).all()
    diff = np.abs(ours - reference).max(axis=-1)
    assert np.count_nonzero(diff > 1e-4) == 0, np.argwhere(diff > 1e-4)
    assert np.abs(d_reference).max() > 1.0
    np.testing.assert_allclose(d_ours, d_reference, rtol=tol, atol=tol)


@pytest.mark.povray
@pytest.mark.slow  # two programs and a POV-Ray render
@pytest.mark.skipif(ACCEL != "native", reason=NO_TWIN_CSG)
def test_a_csg_object_is_seen_only_within_povrays_box_of_it(tmp_path, monkeypatch):
    """POV-Ray bounds an intersection by the overlap of its bounded parts' boxes and shows nothing
    outside it: a disc's box is flat, so of an intersection with a disc only the face on the disc
    is seen, not the half cylinder below it (semantics §4.4). The hierarchy's item is that box."""
    from validation.metrics import psnr
    from validation.povray import render_povray

    text = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0.3, 0.8, -3> look_at <0, -0.1, 0> angle 40 }
light_source { <-8, 14, -9> color rgb 1 }
background { rgb <0.1, 0.2, 0.3> }
intersection { cylinder { -x, x, 0.3 } disc { 0, y, 2 } box { -0.5, 0.5 } pigment { rgb 0.8 } }
#for (i, 0, 7) sphere { <-1.4 + 0.4 * i, 0.9, 1>, 0.1 pigment { rgb <1, 0.5, 0.2> } } #end
"""
    pov = render_povray(text, 80, 60)
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    ours = np.asarray(render(load_scene(text), width=80, height=60))
    assert psnr(ours, pov) >= 60.0
    # every primitive a candidate: the half cylinder is drawn (the candidate path has no boxes)
    monkeypatch.setenv("RAYTRACER_ACCEL", "none")
    jax.clear_caches()
    assert psnr(np.asarray(render(load_scene(text), width=80, height=60)), pov) < 40.0


# polynomials in every way the hierarchy holds them: a CSG member (pawns.pov's collar cut from a
# cylinder), parts of a union bounded by a cylinder (seen by the rays that cross it), one on its own
# (a box of everything), one clipped by planes and a quadric (no box either), a transparent one
TORUS = ("1, 0, 0, 0, 2, 0, 0, 2, 0, -2.5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, "
         "1, 0, 0, 2, 0, 1.5, 0, 0, 0, 0, 1, 0, -2.5, 0, 0.5625")  # R = 1, r = 0.5
POLY_SCENE = f"""
#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 5, -11> look_at <0, 0.8, 0> angle 50 }}
light_source {{ <-8, 14, -9> color rgb 1 }}
light_source {{ <9, 6, -4> color rgb 0.4 }}
plane {{ y, 0 pigment {{ checker rgb 1 rgb 0.3 }} }}
difference {{ cylinder {{ -0.3 * y, 0.3 * y, 1.2 }} quartic {{ <{TORUS}> }} translate <-3, 0.3, 0>
             pigment {{ rgb <0.9, 0.5, 0.2> }} finish {{ phong 0.5 }} }}
union {{ quartic {{ <{TORUS}> scale 0.5 translate 1.2 * y }} sphere {{ 0.5 * y, 0.4 }}
        bounded_by {{ cylinder {{ 0, 2 * y, 0.6 }} }} translate <0, 0, 1> pigment {{ rgb <0.3, 0.6, 0.9> }} }}
quartic {{ <{TORUS}> rotate 70 * x translate <3, 1.2, 0> pigment {{ rgb <0.8, 0.8, 0.2> }} }}
quartic {{ <0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, -0.1666, 0, 1, 0,
           0, 0, 0, 0, 0, 0, 0, 0.5, 0, -1, 0, 0, 0, 0, 0>
          clipped_by {{ quadric {{ <1, 1, 0>, 0, 0, -1 }} plane {{ z, 1.4 }} plane {{ -z, 0 }} }}
          rotate -90 * x translate <1.5, 0, -3> pigment {{ rgb <0.2, 0.8, 0.4> }} }}
intersection {{ quartic {{ <{TORUS}> }} sphere {{ 0, 1.2 }} scale 0.8 translate <-1.5, 0.8, -3>
               pigment {{ rgbf <1, 0.6, 0.6, 0.7> }} }}
"""


@pytest.mark.slow  # two forward-mode programs
@pytest.mark.skipif(ACCEL != "native", reason=NO_TWIN_CSG)
def test_polynomials_in_the_hierarchy_give_the_candidate_paths_image_and_derivatives(tmp_path, monkeypatch):
    """Polynomials are members of the hierarchy's CSG objects (bvh.cc's polynomial kernel chooses,
    ``near_hit`` refines the choice): the candidate path's pixels and derivatives, shadows through
    the transparent one included; every polynomial is held, the floor alone left to candidates."""
    path = tmp_path / "poly.pov"
    path.write_text(POLY_SCENE)
    scene = load_scene(path, width=40, height=30)
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    monkeypatch.setattr(_accel, "MIN_FILTER_ITEMS", 1)
    plan = make_plan(scene)
    geo = pack_geometry(plan, jnp.float32)
    assert sorted(plan.prims[i].kind for g in geo.groups if not g.accelerated for i in g.prims) == ["plane"]
    _assert_native_jvp_is_the_candidate_paths(scene, (40, 30), _tangent(scene, seed=3), monkeypatch, 1e-3)


FADING_SCENE = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 5, -9> look_at <0, 0.5, 0> angle 50 }
light_source { <-3, 12, -4> color rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.4 } }
#declare Glass = material { texture { pigment { rgbf <0.9, 1, 0.8, 0.9> } finish { ambient 0.1 diffuse 0.2 } }
                            interior { ior 1 fade_distance 0.4 fade_power 2 fade_color <0.2, 0.5, 0.9> } }
#declare R = seed(11);
#for (i, 0, 7)
  sphere { <rand(R) * 6 - 3, 0.6 + rand(R), rand(R) * 4 - 1>, 0.3 + 0.3 * rand(R) material { Glass } }
#end
box { <-0.5, 0, -0.5>, <0.5, 1.4, 0.5> rotate 30 * y translate <2, 0, -2> material { Glass } }
difference { sphere { 0, 0.8 } sphere { 0, 0.6 } translate <-2, 1.2, -2.5> material { Glass } }
sphere { <0.5, 1.5, -1>, 0.5 pigment { rgbf <1, 0.6, 0.6, 0.8> } }
sphere { <-0.5, 0.5, -3>, 0.4 pigment { rgb <0.2, 0.7, 0.3> } }
"""


@pytest.mark.slow  # two forward programs
@pytest.mark.skipif(ACCEL != "native", reason="the JAX twin has no all-crossings query: transparent "
                    "objects stay candidates")
def test_fading_transparent_objects_in_the_hierarchy_give_the_candidate_paths_shadows(tmp_path, monkeypatch):
    """A fading interior attenuates a shadow at each exit over the depth since the previous crossing,
    the hierarchy's crossings and the candidates' together: glass spheres, a box and a hollow CSG
    sphere with fading interiors (and one without) cast the candidate path's shadows."""
    path = tmp_path / "fading.pov"
    path.write_text(FADING_SCENE)
    scene = load_scene(path, width=48, height=36)
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    plan = make_plan(scene)
    fading = {i for i, p in enumerate(plan.prims) if p.transparent and p.fades}
    assert len(fading) == 11
    # twelve transparent shadow casters are fewer than MIN_FILTER_ITEMS: cheaper as candidates
    held = {i for g in pack_geometry(plan, jnp.float32).groups if g.accelerated for i in g.prims}
    assert not fading & held
    monkeypatch.setattr(_accel, "MIN_FILTER_ITEMS", 1)
    held = {i for g in pack_geometry(plan, jnp.float32).groups if g.accelerated for i in g.prims}
    assert fading <= held
    _assert_native_image_is_the_candidate_paths(scene, monkeypatch)


def _assert_native_image_is_the_candidate_paths(scene, monkeypatch, size=(48, 36)):
    """The image (``size``) through the native hierarchy is the candidate path's (pixels to 1e-4);
    returns the candidate path's."""
    images = {}
    for mode in ("native", "none"):
        monkeypatch.setenv("RAYTRACER_ACCEL", mode)
        jax.clear_caches()
        images[mode] = np.asarray(render(scene, width=size[0], height=size[1]))
    diff = np.abs(images["native"] - images["none"]).max(axis=-1)
    assert np.count_nonzero(diff > 1e-4) == 0, np.argwhere(diff > 1e-4)
    return images["none"]


FILTER_SCENE = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 5, -9> look_at <0, 0.6, 0> angle 50 }
light_source { <-6, 12, -7> color rgb 1 }
light_source { <8, 6, -3> color rgb 0.5 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
box { <-3, 0, 2>, <3, 2, 2.5> texture { pigment { rgb 0.8 } }
      texture { pigment { checker rgbt <1, 0, 0, 0.5> rgbt 1 scale 0.3 } }
      texture { pigment { gradient x color_map { [0 rgbt <0, 0, 1, 0.7>] [1 rgbt 1] } } } }
#for (i, 0, 3)
  cylinder { <-2.4 + 1.5 * i, 0, 0>, <-2.4 + 1.5 * i, 1.6, 0.3>, 0.45 #if (mod(i, 2)) open #end
             pigment { rgbf <1, 0.6 + 0.1 * i, 0.3, 0.8> } }
  cone { <-2 + 1.4 * i, 1.9, -1.5>, 0.4, <-2 + 1.4 * i, 2.6, -1.5>, 0.1
         texture { pigment { rgbf <0.3, 1, 0.5, 0.7> } } texture { pigment { rgbt <1, 1, 1, 0.5> } } }
#end
sphere { <0, 0.5, -2.5>, 0.5 pigment { rgbf <0.6, 0.6, 1, 0.9> } }
"""


@pytest.mark.slow  # two programs
@pytest.mark.skipif(ACCEL != "native", reason="the all-crossings query is the native hierarchy's")
def test_filter_requests_have_a_lines_crossings_and_the_filters_own_layers(monkeypatch):
    """The hierarchy's transparent items ask a shadow ray for as many crossings as a line can have
    with them (a cylinder's kernel has 4 slots, a line crosses it twice) and as many texture layers
    as the most a transparent item has (2, where the scene's most is 3): every slot is an entry of
    every shadow ray's pigment requests. Open and closed cylinders, cones of two layers and a sphere
    filter the candidate path's shadows."""
    from raytracer.shading import _model

    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    monkeypatch.setattr(_accel, "MIN_FILTER_ITEMS", 1)
    scene = load_scene(FILTER_SCENE)
    plan = make_plan(scene)
    geo = jax.tree.map(jnp.asarray, pack_geometry(plan, jnp.float32))  # (traced lookups need arrays)
    mats = pack_materials(plan, jnp.float32)
    ctx = _model.make_context(plan, geo, mats, scene.lights, scene.settings, jnp.zeros(3), jnp.float32)
    assert mats.n_layers == 3 and ctx.accel_filter_layers == 2
    ray = jax.ShapeDtypeStruct((3,), jnp.float32)
    _, (rows, _, _), crossed = jax.eval_shape(lambda o, d: _model._accel_filter(ctx, o, d, 1e-4, 10.0),
                                              ray, ray)
    assert crossed.t.shape == (_accel.FILTER_ITEMS, 2) and rows.shape == (_accel.FILTER_ITEMS * 2 * 2,)
    reference = _assert_native_image_is_the_candidate_paths(load_scene(FILTER_SCENE), monkeypatch)
    assert np.abs(reference - reference[:, ::-1]).max() > 0.1  # (not a blank image)


@pytest.mark.slow  # two programs
@pytest.mark.skipif(ACCEL != "native", reason=NO_TWIN_CSG)
def test_one_csg_object_or_torus_is_enough_for_the_hierarchy(monkeypatch):
    """A CSG object pays for the hierarchy's query alone (as candidates every ray computes each
    member's crossings and the inside tests of the others): a scene whose only item is a difference
    is accelerated, a hierarchy of one item, with the candidate path's image; so is a lone torus;
    a scene of a few plain spheres, fewer than ``MIN_ITEMS`` items, is not."""
    text = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 2, -6> look_at <0, 0.8, 0> angle 50 }
light_source { <-5, 8, -6> color rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }
difference { box { <-2, 0, -1>, <2, 2, 1> } cylinder { <0, -1, -2>, <0, 3, -2>, 1.2 }
             cylinder { <-1.5, 1, -2>, <-1.5, 1, 2>, 0.4 } pigment { rgb <0.9, 0.6, 0.3> } }
"""
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    scene = load_scene(text)
    held, csg = hierarchy_choice(make_plan(scene))
    assert len(csg) == 1 and not any(held)
    ours = np.asarray(render(scene, width=32, height=24))
    spheres = load_scene(text.split("plane")[0]
                         + "sphere { 0, 1 pigment { rgb 1 } } sphere { x, 0.5 pigment { rgb 1 } }")
    assert hierarchy_choice(make_plan(spheres)) == ([False, False], ())
    # nor is a torus, whose quartic as a candidate costs every ray more than the query
    torus = load_scene(text.split("plane")[0] + "torus { 1, 0.3 pigment { rgb 1 } }")
    assert hierarchy_choice(make_plan(torus)) == ([True], ())
    monkeypatch.setenv("RAYTRACER_ACCEL", "none")
    jax.clear_caches()
    reference = np.asarray(render(load_scene(text), width=32, height=24))
    assert reference[10:14, 12:20].max() > 0.3 and reference[10:14, 12:20].std() > 0.05  # the notch is seen
    np.testing.assert_allclose(ours, reference, atol=1e-4)


@pytest.mark.slow  # two programs
@pytest.mark.skipif(ACCEL != "native", reason=NO_TWIN_CSG)
def test_a_csg_object_of_one_part_is_an_item_of_its_own(monkeypatch):
    """A CSG object whose other parts are left out (``difference { A B }`` with B a shape we do not
    render: POV-Ray's ``advanced/pawns``) is its one part: its unit is not a CSG object of the
    hierarchy, whose programs would name a member that is an item of its own (a KeyError when
    packing). The image is the candidate path's."""
    text = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 2, -6> look_at <0, 0.5, 0> }
light_source { <-8, 14, -9> color rgb 1 }
#for (i, 0, 9) sphere { <-2.7 + 0.6 * i, 1.8, 1>, 0.25 pigment { rgb <1, 0.5, 0.2> } } #end
difference { cylinder { 0, y, 0.6 } pigment { rgb 0.8 } }
"""
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    scene = load_scene(text)
    geo = pack_geometry(make_plan(scene), jnp.float32)
    assert all(g.accelerated and not g.csg_member for g in geo.groups)
    assert not np.any(np.asarray(geo.accel.tables[3]) == _accel.KIND_CSG)
    ours = np.asarray(render(scene, width=32, height=24))
    monkeypatch.setenv("RAYTRACER_ACCEL", "none")
    jax.clear_caches()
    reference = np.asarray(render(load_scene(text), width=32, height=24))
    assert reference[12, 16].max() > 0.1  # the cylinder is seen
    np.testing.assert_allclose(ours, reference, atol=1e-5)


def test_groups_of_any_size_compute_their_items_with_one_program(monkeypatch):
    """A concrete group of one-item shapes computes its items in chunks of ``ITEMS_CHUNK`` shapes,
    so a shape variant compiles one items program whatever its group's size (each size compiled
    its own: ~0.1-0.2 s a group on a cold start). The items are those of one call over the whole
    group, bit for bit, for a group shorter than a chunk and one of several chunks."""
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    monkeypatch.setattr(_accel, "ITEMS_CHUNK", 16)
    monkeypatch.setattr(_accel, "NUMPY_ITEMS_MAX", 0)  # the compiled chunks, not the host
    before = _accel._group_items._cache_size()
    groups = []
    for n in (9, 16, 41):
        text = "camera { location <0, 2, -9> look_at 0 }\n" + "".join(
            f"sphere {{ <{0.3 * i - 6}, {np.sin(i)}, {0.1 * i}>, {0.1 + 0.01 * i} }}\n" for i in range(n))
        geo = pack_geometry(make_plan(load_scene(text)), jnp.float32)
        assert geo.accel.n_items == n and len(geo.groups) == 1
        groups.append((geo.shapes[0], np.asarray(geo.object_from_world[0])))
    # one program for the three sizes (none if an earlier test compiled that chunk; one per size
    # before the chunks)
    assert _accel._group_items._cache_size() - before <= 1
    for shape, ofw in groups:
        wfo = np.linalg.inv(ofw)
        whole = _accel._group_items(jax.tree_util.tree_map(jax.lax.stop_gradient, shape), ofw, wfo)
        for a, b in zip(whole, _accel._items(shape, ofw, wfo), strict=True):
            np.testing.assert_array_equal(np.asarray(a), b)


def test_small_groups_compute_their_items_on_the_host(scene, tmp_path, monkeypatch):
    """A concrete group of at most ``NUMPY_ITEMS_MAX`` one-item shapes computes its items with
    numpy, shape by shape (no compiled program: ~60 ms a shape variant on a cold start): the
    compiled program's items, for every kind the hierarchy holds (boxes, spheres, cylinders and
    cones, discs, tori, superellipsoids, triangles, the differences' members)."""
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    monkeypatch.setattr(_accel, "MIN_ITEMS", 1)
    path = tmp_path / "se.pov"
    path.write_text(SUPERELLIPSOIDS)
    kinds = set()
    for s in (scene, load_scene(path)):
        geo = pack_geometry(make_plan(s), jnp.float32)
        for group, shape, ofw in zip(geo.groups, geo.shapes, geo.object_from_world, strict=True):
            if not group.accelerated or type(shape).n_native_items is not AbstractShape.n_native_items:
                continue
            kinds.add(group.kind)
            host = jax.tree_util.tree_map(np.asarray, (shape, ofw, np.linalg.inv(np.asarray(ofw))))
            for a, b in zip(_accel._group_items(*host), _accel._host_items(*host), strict=True):
                np.testing.assert_allclose(np.asarray(a), b, rtol=1e-6, atol=1e-6)
    assert {"box", "sphere", "cylinder", "cone", "disc", "torus", "superellipsoid", "triangle"} <= kinds


PRISMS_AND_TEXT = """
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <1.5, 1.5, -4> look_at <1.2, 0.2, 0> angle 50 }
light_source { <-8, 14, -9> color rgb 1 }
plane { y, -0.3 pigment { checker rgb 1 rgb 0.3 } }
text { ttf "timrom.ttf" "Ag" 0.3, 0 pigment { rgb 0.8 } }
prism { conic_sweep cubic_spline 0.5, 1, 8, <0,-1>, <0,0>, <1,0>, <1,1>, <0,1>, <0,0>, <1,0>, <0,1>
        rotate 180*x translate <2.2, 0.8, 0.2> pigment { rgb <0.9, 0.6, 0.3> } }
difference { box { <-0.3, -0.3, -1.2>, <2.8, 0, -0.5> }
             text { ttf "cyrvetic" "cut" 0.3, 0 scale 0.5 rotate 90*x translate <0.1, 0.05, -1.0> }
             lathe { linear_spline 5, <0.1, -0.1>, <0.25, -0.1>, <0.25, 0.2>, <0.1, 0.2>, <0.1, -0.1>
                     translate <2.3, 0, -0.85> }
             pigment { rgb <0.4, 0.7, 0.9> } }
lathe { cubic_spline 8, <0, -0.5>, <0, 0>, <0.5, 0.2>, <0.2, 0.5>, <0.45, 0.9>, <0.1, 1.1>, <0, 1.2>, <0, 1.5>
        translate <0.7, -0.3, 0.7> pigment { rgb <0.3, 0.9, 0.4> } }
blob { threshold 0.5 sphere { 0, 0.5, 1.5 scale <1, 1.4, 1> }
       cylinder { <-0.5, 0, 0>, <0.4, 0.3, 0>, 0.25, 1 } sphere { <0.1, 0.2, -0.2>, 0.3, -1 }
       translate <2.7, 0.2, 0.6> pigment { rgb <0.9, 0.3, 0.8> } }
difference { box { <-0.9, -0.3, -0.2>, <-0.2, 0.4, 0.5> }
             blob { threshold 0.4 sphere { 0, 0.4, 1 } cylinder { <0, 0, 0>, <0, 0.6, 0>, 0.15, 1 }
                    translate <-0.55, 0.35, 0.1> }
             pigment { rgb <0.9, 0.9, 0.3> } }
"""


@pytest.mark.skipif(ACCEL != "native", reason="the prism kernel is the native hierarchy's")
def test_prisms_text_lathes_and_blobs_in_the_hierarchy_give_the_candidate_paths_image(tmp_path, monkeypatch):
    """Text, a conic cubic prism, a cubic lathe, a blob, and text, a lathe and a blob cut from boxes
    by CSG (the native prism, lathe and blob kernels: walls, caps, the inside test of a CSG
    member), chosen by the hierarchy: the candidate path's pixels."""
    path = tmp_path / "pt.pov"
    path.write_text(PRISMS_AND_TEXT)
    scene = load_scene(path, width=32, height=24)
    out = {}
    for mode in ("none", "native"):
        monkeypatch.setenv("RAYTRACER_ACCEL", mode)
        out[mode] = np.asarray(render(scene, width=32, height=24))
    geo = pack_geometry(make_plan(scene), jnp.float32)
    assert sum(g.kind in ("prism", "text") and g.accelerated for g in geo.groups) >= 2
    assert any(g.kind == "lathe" and g.accelerated for g in geo.groups)
    assert any(g.kind == "blob" and g.accelerated for g in geo.groups)
    assert np.abs(out["none"]).max() > 0.1
    assert (np.abs(out["native"] - out["none"]).max(axis=-1) > 1e-4).sum() == 0
