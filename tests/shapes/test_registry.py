"""The shape registry is the one source: every registered shape has its test case, SDL syntax,
bounds that hold its surface, and stacks and batches like the renderer uses it."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.shapes import REGISTRY, SDL_KEYWORDS, world_bounds

from ._cases import CASE_IDS, CASES, random_rays


def test_every_registered_shape_has_a_test_case():
    assert {case.kind for case in CASES} == set(REGISTRY)


def test_sdl_keywords_are_the_registry_and_the_interpreter_knows_them():
    from raytracer.sdl._objects import OBJECT_KEYWORDS

    assert set(SDL_KEYWORDS) >= set(REGISTRY) - {"mesh"} | {"mesh", "mesh2"}
    assert set(SDL_KEYWORDS) <= set(OBJECT_KEYWORDS)
    for kw, cls in SDL_KEYWORDS.items():
        assert kw in cls.sdl_keywords


def test_records_declare_crossings_consistent_with_their_kernels():
    for case in CASES:
        shape = case.make(*case.params)
        # shapes only: traced, never compiled (run eagerly, every primitive was a program of its own)
        t, n = jax.eval_shape(shape.hits, jnp.asarray(case.aim) - jnp.array([0.0, 0.0, 5.0]),
                              jnp.array([0.0, 0.0, 1.0]))
        assert t.shape == (shape.n_crossings(),) and n.shape == (shape.n_crossings(), 3), case.name
        assert shape.line_crossings <= shape.n_crossings() or shape.kind == "mesh", case.name


def _random_similarity(seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    m = np.eye(4)
    m[:3, :3] = q @ np.diag(rng.uniform(0.3, 3.0, 3))
    m[:3, 3] = rng.normal(size=3) * 5
    return m


@pytest.mark.parametrize("index", range(len(CASES)), ids=CASE_IDS)
def test_bounds_hold_every_hit_in_object_and_world_space(index):
    case = CASES[index]
    shape = case.make(*case.params)
    # ``bounded`` (what the plan's boxes and ``bounded_by`` go by) says whether ``bounds`` is None
    assert type(shape).bounded == (shape.bounds() is not None), case.name
    if shape.bounds() is None:
        assert shape.kind in ("plane", "quadric", "poly"), "only unbounded shapes may omit their bounds"
        return
    o, d = random_rays(case, 5, 256)
    t, _ = jax.jit(jax.vmap(shape.hits))(jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    t = np.asarray(t, np.float64)
    ray, slot = np.nonzero(np.isfinite(t))
    assert ray.size > 0, case.name
    p = o[ray] + t[ray, slot][:, None] * d[ray]
    tol = 1e-4 * case.size
    lo, hi = (np.asarray(b, np.float64) for b in shape.bounds())
    assert np.all(p >= lo - tol) and np.all(p <= hi + tol), case.name
    m = _random_similarity(index)
    wlo, whi = (np.asarray(b, np.float64) for b in world_bounds(shape, m))
    pw = p @ m[:3, :3].T + m[:3, 3]
    tol_w = tol * np.abs(m[:3, :3]).sum()
    assert np.all(pw >= wlo - tol_w) and np.all(pw <= whi + tol_w), case.name


def test_renderer_groups_shapes_by_static_variant_and_vmaps_their_own_kernels():
    from raytracer._plan import make_plan
    from raytracer.shading._geometry import all_crossings, pack_geometry

    objects = (rt.Object(rt.Cylinder((0, -1, 0), (0, 1, 0), 0.5)),
               rt.Object(rt.Cylinder((2, -1, 0), (2, 1, 0), 0.5, open=True)),
               rt.Object(rt.Sphere((0, 0, 3), 1.0)), rt.Object(rt.Sphere((0, 0, 6), 1.0)))
    plan = make_plan(rt.Scene(camera=rt.Camera(), objects=objects))
    geo = pack_geometry(plan, jnp.float32)
    groups = sorted((g.kind, len(g.prims)) for g in geo.groups)
    assert groups == [("cylinder", 1), ("cylinder", 1), ("sphere", 2)]
    o, d = jnp.array([0.0, 0.0, -5.0]), jnp.array([0.0, 0.0, 1.0])
    t, _ = eqx.filter_jit(all_crossings)(geo, o, d)
    expected = {0: sorted(np.asarray(jax.jit(objects[0].shape.hits)(o, d)[0]).tolist()),
                2: [7.0, 9.0], 3: [10.0, 12.0]}
    for prim, want in expected.items():
        got = sorted(np.asarray(t)[geo.cand_prim == prim].tolist())
        np.testing.assert_allclose(got, want, rtol=1e-6)


# shapes whose outline has no margin yet: no boundary term where their outline moves
# (``raytracer/_edges.py`` counts those crossings as unresolved). A new shape brings its margin, or
# joins this list and the list in docs/gradients.md.
WITHOUT_MARGIN = {"poly", "prism", "text", "lathe", "isosurface"}


_CREASED = [i for i, c in enumerate(CASES) if type(c.make(*c.params)).faces > 1]


def test_box_cylinder_and_cone_have_faces():
    """The shapes whose normal jumps across an edge of their surface declare its faces (creases,
    ``edges=True``): the box's six, the cylinder's and the cone's side and two discs."""
    assert {CASES[i].kind for i in _CREASED} == {"box", "cylinder", "cone"}


@pytest.mark.parametrize("index", _CREASED, ids=[CASES[i].name for i in _CREASED])
def test_a_crossings_face_surface_holds_the_crossing(index, x64):
    """At every crossing of random lines, the face the point lies on (``face``) has its whole
    surface crossed there (``face_distance`` near the crossing gives it back to 1e-9), and the
    crossings together reach several faces (one: an open variant's side)."""
    case = CASES[index]
    shape = case.make(*(jnp.asarray(p, jnp.float64) for p in case.params))
    o, d = random_rays(case, 5, 512)
    o, d = jnp.asarray(o, jnp.float64), jnp.asarray(d, jnp.float64)
    t, _ = jax.jit(jax.vmap(shape.hits))(o, d)
    hit = np.isfinite(np.asarray(t))
    at = jnp.where(hit, t, 0.0)
    faces = jax.jit(jax.vmap(jax.vmap(shape.face)))(o[:, None, :] + at[..., None] * d[:, None, :])
    again = jax.jit(jax.vmap(jax.vmap(shape.face_distance, in_axes=(None, None, 0, 0))))(o, d, faces, at)
    np.testing.assert_allclose(np.asarray(again)[hit], np.asarray(t)[hit], rtol=1e-9, atol=1e-9 * case.size)
    seen = set(np.asarray(faces)[hit].tolist())
    if getattr(shape, "open", False):
        assert seen == {0}, case.name
    else:
        assert len(seen) > 1 and seen <= set(range(type(shape).faces)), case.name


def test_every_shape_gives_its_outline_margin_or_is_listed_without_one():
    for case in CASES:
        assert type(case.make(*case.params)).has_margin() == (case.kind not in WITHOUT_MARGIN), case.name


_MARGINS = [i for i, c in enumerate(CASES) if c.kind not in WITHOUT_MARGIN]


@pytest.mark.parametrize("index", _MARGINS, ids=[CASES[i].name for i in _MARGINS])
def test_a_margin_is_positive_where_the_line_crosses_the_shape_and_crosses_zero_smoothly(index, x64):
    """The sign of ``silhouette_margin`` is the kernel's hit or miss of the line (float64; a plane's
    crossing counts ahead of the origin only), and its derivative along the line's offset is its
    central difference where it is small (the outline, where the boundary term reads it). A mesh's
    margin is its triangles' (``item_margin``, against ``sub_hits``): here its first one's."""
    case = CASES[index]
    shape = case.make(*(jnp.asarray(p, jnp.float64) for p in case.params))
    o, d = random_rays(case, 11, 512)
    o, d = jnp.asarray(o, jnp.float64), jnp.asarray(d, jnp.float64)
    item = 0
    margin_of = lambda oo, dd: shape.item_margin(oo, dd, item)  # noqa: E731
    margin = np.asarray(jax.jit(jax.vmap(margin_of))(o, d))
    t, _ = jax.jit(jax.vmap(lambda oo, dd: shape.sub_hits(oo, dd, item)))(o, d)
    t = np.asarray(t)
    crosses = np.any(np.isfinite(t) & ((t > 0) if case.kind == "plane" else True), axis=1)
    clear = np.abs(margin) > 1e-9 * case.size ** 2
    assert np.all((margin > 0)[clear] == crosses[clear]), case.name
    assert crosses.any() and not crosses.all(), case.name
    # along an offset of the origin: forward-mode derivative against central differences
    offset = jnp.asarray(np.random.default_rng(3).normal(size=3))
    step = 1e-6 * case.size

    @jax.jit  # one program (run eagerly, every primitive of the kernel was a program of its own)
    def slope_and_central(o, d):
        slope = jax.vmap(lambda oo, dd: jax.jvp(lambda s: margin_of(oo + s * offset, dd),
                                                (0.0,), (1.0,))[1])(o, d)
        central = (jax.vmap(margin_of)(o + step * offset[None, :], d)
                   - jax.vmap(margin_of)(o - step * offset[None, :], d)) / (2 * step)
        return slope, central

    slope, central = slope_and_central(o, d)
    near = np.argsort(np.abs(margin))[:64]
    np.testing.assert_allclose(np.asarray(slope)[near], np.asarray(central)[near], rtol=1e-5,
                               atol=1e-7 * float(np.max(np.abs(central))))
