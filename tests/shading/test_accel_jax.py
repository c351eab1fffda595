"""The pure-JAX hierarchy (``shading/_accel_jax.py``): its build makes a valid tree in ``bvh.cc``'s
layout, and its traversal, the native traversal on its tree and it on the native tree all choose
what a brute-force NumPy minimum over every item chooses."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shading import _accel
from raytracer.shading import _accel_jax as J

NATIVE = _accel.unavailable_reason() is None
needs_native = pytest.mark.skipif(not NATIVE, reason=str(_accel.unavailable_reason()))


# ---------------------------------------------------------------- the build
def check_tree(boxes, node_box, node_info, order):
    """Every item in exactly one leaf, every node reached once from the root, every box holding
    its children's boxes and its items' boxes; the depth."""
    boxes, node_box, node_info, order = (np.asarray(x) for x in (boxes, node_box, node_info, order))
    n = boxes.shape[0]
    assert node_box.shape == (2 * n - 1, 6) and node_info.shape == (2 * n - 1, 4)
    assert sorted(order.tolist()) == list(range(n))
    held = np.zeros(n, int)
    reached = np.zeros(2 * n - 1, int)
    stack, depth = [(0, 0)], 0
    while stack:
        node, level = stack.pop()
        reached[node] += 1
        depth = max(depth, level)
        first, count, right, axis = node_info[node]
        lo, hi = node_box[node, :3], node_box[node, 3:]
        if count > 0:
            assert (right, axis) == (0, 0)
            for it in order[first:first + count]:
                held[it] += 1
                assert (lo <= boxes[it, :3]).all() and (hi >= boxes[it, 3:]).all(), (node, it)
        else:
            assert 0 <= axis < 3
            for child in (first, right):
                assert 0 < child < 2 * n - 1
                assert (lo <= node_box[child, :3]).all() and (hi >= node_box[child, 3:]).all()
                stack.append((child, level + 1))
    assert (held == 1).all()
    assert (reached == 1).all()
    return depth


def random_boxes(rng, n, duplicates=False):
    centres = rng.uniform(-5, 5, (n, 3))
    half = rng.uniform(0.01, 0.6, (n, 3))
    boxes = np.concatenate([centres - half, centres + half], axis=1)
    if duplicates:
        boxes[: n // 3] = boxes[0]  # a third of the items on one box
        boxes[n // 3: n // 2] = boxes[n // 3][None] + rng.uniform(0, 1e-7, (n // 2 - n // 3, 6))
    return boxes.astype(np.float32)


@pytest.mark.parametrize("n", [1, 2, 3, 7, 64, 1000])
@pytest.mark.parametrize("duplicates", [False, True])
def test_jax_build_makes_a_valid_tree(n, duplicates):
    boxes = random_boxes(np.random.default_rng(n), n, duplicates)
    tree = jax.jit(J.build)(jnp.asarray(boxes))
    depth = check_tree(boxes, *tree)
    assert depth <= 30 + n.bit_length()  # the radix tree's keys: 30 Morton bits, then the index
    info = np.asarray(tree[1])
    assert (info[:, 1] <= 1).all()  # one item per leaf
    if n > 1:
        assert (info[: n - 1, 1] == 0).all() and (info[n - 1:, 1] == 1).all()


def test_jax_build_of_points_on_one_spot_and_empty_boxes():
    boxes = np.zeros((50, 6), np.float32)  # 50 points at the origin: every Morton code equal
    boxes[10:20] = [1, 1, 1, -1, -1, -1]  # empty: points at 0, as bvh.cc makes them
    boxes[20:25, 0] = np.nan
    node_box, node_info, order = jax.jit(J.build)(jnp.asarray(boxes))
    sane = np.where(np.isnan(boxes), 0, boxes)
    sane[10:25] = 0
    depth = check_tree(sane, node_box, node_info, order)
    assert depth <= 7  # equal codes: split by index, a balanced tree


# ---------------------------------------------------------------- items and a brute-force reference
def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _corners(lo, hi):
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def random_items(rng, n):
    """(kind (n,), params (n, 24) float64, world boxes (n, 6)): spheres, boxes, triangles,
    cylinders and cones (open and closed), discs (some with a hole); half of them under a random
    affine map (object_from_world), all in [-5, 5]^3."""
    kinds = rng.integers(0, 5, n)
    params = np.zeros((n, 24))
    boxes = np.zeros((n, 6))
    for i, kind in enumerate(kinds):
        q = np.zeros(12)
        c = rng.uniform(-0.5, 0.5, 3)
        if kind == J.KIND_SPHERE:
            q[:4] = [*c, rng.uniform(0.05, 0.5)]
            corners = _corners(c - q[3], c + q[3])
        elif kind == J.KIND_BOX:
            a, b = c - rng.uniform(0.05, 0.5, 3), c + rng.uniform(0.05, 0.5, 3)
            q[:6] = [*b, *a] if rng.random() < 0.5 else [*a, *b]  # either corner first
            corners = _corners(a, b)
        elif kind == J.KIND_TRIANGLE:
            corners = c + rng.uniform(-0.6, 0.6, (3, 3))
            q[:9] = corners.reshape(9)
        elif kind == J.KIND_FRUSTUM:
            base, cap = c, c + rng.uniform(-0.6, 0.6, 3)
            rb = rng.uniform(0.05, 0.4)
            rc = rb if rng.random() < 0.5 else rng.uniform(0.0, 0.4)  # cylinder or cone
            q[:9] = [*base, rb, *cap, rc, float(rng.random() < 0.5)]
            r = max(rb, rc)
            lo, hi = np.minimum(base, cap) - r, np.maximum(base, cap) + r
            corners = _corners(lo, hi)
        else:
            r = rng.uniform(0.1, 0.5)
            q[:8] = [*c, *rng.normal(size=3), r, rng.uniform(0, 0.8 * r) if rng.random() < 0.5 else 0.0]
            corners = _corners(c - r, c + r)
        # world_from_object: a rotation, scales and a shift (identity for half the items)
        linear = _rotation(rng) @ np.diag(rng.uniform(0.5, 2.0, 3)) if rng.random() < 0.5 else np.eye(3)
        shift = rng.uniform(-4.5, 4.5, 3)
        inverse = np.linalg.inv(linear)
        params[i, :12] = np.concatenate([inverse, (-inverse @ shift)[:, None]], axis=1).reshape(12)
        params[i, 12:] = q
        world = corners @ linear.T + shift
        boxes[i] = [*world.min(axis=0), *world.max(axis=0)]
    return kinds.astype(np.int32), params, boxes


def reference_crossings(kind, params, o, d, tmin, tmax):
    """Brute force, float64: (R, n) the first crossing of every item in (tmin, tmax), +inf if none
    (each kind solved on its own terms, not bvh.cc's formulation)."""
    best = np.full((o.shape[0], params.shape[0]), np.inf)
    for k, solve in _REFERENCE.items():
        cols = np.flatnonzero(kind == k)
        if not len(cols):
            continue
        m = params[cols, :12].reshape(-1, 3, 4)
        ro = np.einsum("nij,rj->rni", m[:, :, :3], o) + m[None, :, :, 3]
        rd = np.einsum("nij,rj->rni", m[:, :, :3], d)
        with np.errstate(all="ignore"):
            here = np.full(ro.shape[:2], np.inf)
            for ok, t in solve(params[None, cols, 12:], ro, rd):
                here = np.where(ok & (t > tmin[:, None]) & (t < tmax[:, None]) & (t < here), t, here)
        best[:, cols] = here
    return best


def _ref_sphere(q, ro, rd):
    """|ro + t rd - c|^2 = r^2"""
    oc = ro - q[..., 0:3]
    a, b = np.sum(rd * rd, -1), np.sum(oc * rd, -1)
    disc = b * b - a * (np.sum(oc * oc, -1) - q[..., 3] ** 2)
    return [(disc >= 0, (-b + sign * np.sqrt(disc)) / a) for sign in (-1, 1)]


def _ref_box(q, ro, rd):
    """The entry and exit of the slabs."""
    lo, hi = np.minimum(q[..., 0:3], q[..., 3:6]), np.maximum(q[..., 0:3], q[..., 3:6])
    ta, tb = (lo - ro) / rd, (hi - ro) / rd
    near = np.max(np.where(rd == 0, -np.inf, np.minimum(ta, tb)), -1)
    far = np.min(np.where(rd == 0, np.inf, np.maximum(ta, tb)), -1)
    ok = ~np.any((rd == 0) & ((ro < lo) | (ro > hi)), -1) & (near <= far)
    return [(ok, near), (ok, far)]


def _ref_triangle(q, ro, rd):
    """o + t d = p1 + u e1 + v e2, a 3x3 linear system."""
    p1, e1, e2 = q[..., 0:3], q[..., 3:6] - q[..., 0:3], q[..., 6:9] - q[..., 0:3]
    mat = np.stack([-rd, np.broadcast_to(e1, rd.shape), np.broadcast_to(e2, rd.shape)], -1)
    ok = np.abs(np.linalg.det(mat)) > 1e-300
    sol = np.linalg.solve(np.where(ok[..., None, None], mat, np.eye(3)), (ro - p1)[..., None])[..., 0]
    t, u, v = sol[..., 0], sol[..., 1], sol[..., 2]
    return [(ok & (u >= 0) & (v >= 0) & (u + v <= 1), t)]


def _ref_disc(q, ro, rd):
    """The plane, then the ring between the hole and the radius."""
    nrm = q[..., 3:6]
    t = np.sum(nrm * (q[..., 0:3] - ro), -1) / np.sum(nrm * rd, -1)
    rho2 = np.sum((ro + t[..., None] * rd - q[..., 0:3]) ** 2, -1)
    return [((rho2 <= q[..., 6] ** 2) & (rho2 >= q[..., 7] ** 2), t)]


def _ref_frustum(q, ro, rd):
    """In a frame (u, v, w) with w along the axis: x^2 + y^2 = (rb + k z)^2, 0 <= z <= L; the caps."""
    base, cap, rb, rc = q[..., 0:3], q[..., 4:7], q[..., 3], q[..., 7]
    axis = cap - base
    length = np.linalg.norm(axis, axis=-1)
    w = axis / length[..., None]
    helper = np.where(np.abs(w[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    u_ax = np.cross(w, helper)
    u_ax /= np.linalg.norm(u_ax, axis=-1)[..., None]
    v_ax = np.cross(w, u_ax)
    rel = ro - base
    x0, y0, z0 = (np.sum(rel * e, -1) for e in (u_ax, v_ax, w))
    xd, yd, zd = (np.sum(rd * e, -1) for e in (u_ax, v_ax, w))
    k = (rc - rb) / length
    qa = xd ** 2 + yd ** 2 - (k * zd) ** 2
    qb = 2 * (x0 * xd + y0 * yd - k * zd * (rb + k * z0))
    qc = x0 ** 2 + y0 ** 2 - (rb + k * z0) ** 2
    dq = qb * qb - 4 * qa * qc
    out = []
    for sign in (-1, 1):
        t = (-qb + sign * np.sqrt(dq)) / (2 * qa)
        z = z0 + t * zd
        out.append(((dq >= 0) & (z >= 0) & (z <= length), t))
    closed = q[..., 8] == 0
    for z_end, radius in ((0.0, rb), (length, rc)):
        t = (z_end - z0) / zd
        out.append((closed & ((x0 + t * xd) ** 2 + (y0 + t * yd) ** 2 <= radius ** 2), t))
    return out


_REFERENCE = {J.KIND_SPHERE: _ref_sphere, J.KIND_BOX: _ref_box, J.KIND_TRIANGLE: _ref_triangle,
              J.KIND_FRUSTUM: _ref_frustum, J.KIND_DISC: _ref_disc}


def random_rays(rng, count):
    o = rng.uniform(-7, 7, (count, 3))
    d = rng.normal(size=(count, 3))
    d[: count // 10, 1] = 0.0  # some rays parallel to a slab
    tmin = np.where(rng.random(count) < 0.3, rng.uniform(0, 3, count), 0.0)
    tmax = np.where(rng.random(count) < 0.3, rng.uniform(2, 8, count), 1e7)
    return o, d, tmin, tmax


def _scene(seed, n, rays, dtype):
    """Items and rays; the reference's crossings (R, n), best item and distance, and how far
    rounding errors of the dtype's size in the rays move the best distance (``spread``; ``shaky``
    where they change the best item: grazing rays, near ties)."""
    rng = np.random.default_rng(seed)
    kind, params, boxes = random_items(rng, n)
    mask = rng.integers(1, 8, n).astype(np.int32)
    o, d, tmin, tmax = random_rays(rng, rays)
    want = rng.choice(np.array([1, 2, 4, 7], np.int32), rays)
    # the reference sees the numbers the queries see (rounded to dtype), in float64
    params, o, d, tmin, tmax = (np.asarray(x, dtype).astype(np.float64) for x in (params, o, d, tmin, tmax))
    visible = (mask[None] & want[:, None]) != 0

    def reference(o, d):
        ref = np.where(visible, reference_crossings(kind, params, o, d, tmin, tmax), np.inf)
        best_t = ref.min(axis=1)
        return ref, np.where(np.isfinite(best_t), ref.argmin(axis=1), -1), best_t

    ref, best_item, best_t = reference(o, d)
    spread, shaky = np.zeros(rays), np.zeros(rays, bool)
    scale = 16 * float(jnp.finfo(dtype).eps)
    for _ in range(2):
        wobble = lambda x: x + scale * (1 + np.abs(x)) * rng.choice([-1.0, 1.0], x.shape)  # noqa: E731
        _, item_p, t_p = reference(wobble(o), wobble(d))
        shaky |= item_p != best_item
        same = (item_p == best_item) & (best_item >= 0)
        spread = np.maximum(spread, np.abs(np.where(same, t_p, 0) - np.where(same, best_t, 0)))
    cast = lambda x: jnp.asarray(x, dtype)  # noqa: E731
    tail = (jnp.asarray(kind), jnp.asarray(mask), cast(params), *map(jnp.asarray, _accel.one_unit(n, dtype)))
    rays_ = (cast(o), cast(d), cast(tmin), cast(tmax), jnp.asarray(want))
    return cast(boxes), tail, rays_, ref, (best_item, best_t, spread, shaky)


def _agree(item, t, want, rtol, atol):
    """The queries' answer is the reference's, to rounding (``rtol``, ``atol``, and the spread of
    the reference under rounding-sized changes of the ray); where that spread changes the best item
    the ray is skipped (it must be a handful)."""
    best_item, best_t, spread, shaky = want
    item, t = np.asarray(item), np.asarray(t)
    assert shaky.sum() <= len(shaky) // 200
    np.testing.assert_array_equal(item[~shaky], best_item[~shaky])
    hit = (best_item >= 0) & ~shaky
    assert hit.sum() > len(hit) // 10  # the rays do hit things
    assert (np.abs(t[hit] - best_t[hit]) <= rtol * best_t[hit] + atol + 4 * spread[hit]).all(), \
        np.max(np.abs(t[hit] - best_t[hit]) / best_t[hit])
    assert np.isinf(t[(best_item < 0) & ~shaky]).all()


def _check_queries(boxes, tail, rays, ref, want, rtol, atol):
    trees = {"jax": tuple(J.build(boxes)) + tail}
    if NATIVE:
        trees["native"] = tuple(_accel._build(boxes)) + tail
    queries = {"jax": jax.jit(J.closest_query)}
    if NATIVE:
        queries["native"] = jax.jit(_accel._closest_query)
    for tree_name, tables in trees.items():
        for query_name, query in queries.items():
            if tree_name == query_name == "native":
                continue  # test_accel's business
            item, t = query(tables, *rays)
            try:
                _agree(item, t, want, rtol, atol)
            except AssertionError as e:
                raise AssertionError(f"{query_name} traversal on the {tree_name} tree") from e
    # any hit: found exactly where the closest hit is found, and what it finds is a crossing
    tables = trees["jax"]
    any_item, any_t = jax.jit(J.any_query)(tables, *rays)
    any_item, any_t = np.asarray(any_item), np.asarray(any_t)
    best_item, _, spread, shaky = want
    np.testing.assert_array_equal((any_item >= 0)[~shaky], (best_item >= 0)[~shaky])
    hit = np.flatnonzero((any_item >= 0) & ~shaky)
    np.testing.assert_allclose(any_t[hit], ref[hit, any_item[hit]], rtol=rtol,
                               atol=atol + 4 * spread[hit].max())


def test_closest_and_any_hit_agree_with_brute_force_in_float32():
    # atol: a crossing close to the ray's origin, in a scene of size ~10, is known to ~1e-6 of 10
    _check_queries(*_scene(11, 400, 2000, jnp.float32), rtol=1e-5, atol=1e-5)


def test_closest_and_any_hit_agree_with_brute_force_in_float64(x64):
    _check_queries(*_scene(12, 300, 1500, jnp.float64), rtol=1e-10, atol=1e-12)


@needs_native
def test_native_traversal_accepts_the_jax_tree_with_duplicates():
    """Many items on one spot (a deep run of equal Morton codes): both traversals agree."""
    rng = np.random.default_rng(5)
    n = 200
    centres = np.where(rng.random((n, 1)) < 0.5, 1.0, rng.uniform(-3, 3, (n, 3)))
    radii = rng.uniform(0.1, 0.5, n)
    eye = np.broadcast_to(np.eye(4)[:3].reshape(12), (n, 12))
    params = np.concatenate([eye, centres, radii[:, None], np.zeros((n, 8))], axis=1).astype(np.float32)
    boxes = np.concatenate([centres - radii[:, None], centres + radii[:, None]], axis=1).astype(np.float32)
    units = tuple(map(jnp.asarray, _accel.one_unit(n, np.float32)))
    tables = tuple(jax.jit(J.build)(jnp.asarray(boxes))) + (jnp.zeros(n, jnp.int32), jnp.ones(n, jnp.int32),
                                                 jnp.asarray(params), *units)
    o = jnp.asarray(rng.uniform(-6, 6, (1000, 3)), jnp.float32)
    d = jnp.asarray(rng.normal(size=(1000, 3)), jnp.float32)
    args = (o, d, jnp.zeros(1000), jnp.full(1000, 1e7), jnp.ones(1000, jnp.int32))
    ours, native = jax.jit(J.closest_query)(tables, *args), jax.jit(_accel._closest_query)(tables, *args)
    # equal spheres on one spot tie: the same distance, maybe another of them
    np.testing.assert_array_equal(np.asarray(ours[0]) >= 0, np.asarray(native[0]) >= 0)
    np.testing.assert_allclose(np.asarray(ours[1]), np.asarray(native[1]), rtol=1e-5, atol=1e-6)


# ---------------------------------------------------------------- under transformations
@pytest.fixture(scope="module")
def small_scene():
    boxes, tail, rays, _, expected = _scene(13, 300, 256, jnp.float32)
    return tuple(J.build(boxes)) + tail, rays, expected


def test_query_under_vmap_and_jit(small_scene):
    tables, rays, expected = small_scene
    o, d = rays[:2]
    # one ray at a time under vmap (the renderer's way): one query of all of them
    item, t = jax.jit(jax.vmap(lambda o, d, a, b, w: J.closest_query(tables, o, d, a, b, w)))(*rays)
    _agree(item, t, expected, 1e-5, 1e-5)
    # nested vmaps, scalar arguments left unbatched
    grid = jax.jit(jax.vmap(jax.vmap(lambda o, d: J.closest_query(tables, o, d, 0.0, 1e7, 7))))(
        o.reshape(16, 16, 3), d.reshape(16, 16, 3))
    flat = jax.jit(J.closest_query)(tables, o, d, jnp.zeros(256), jnp.full(256, 1e7), jnp.full(256, 7))
    np.testing.assert_array_equal(np.asarray(grid[0]).reshape(-1), np.asarray(flat[0]))


def test_query_batched_over_scenes(small_scene):
    """Unlike the native query, a batch of scenes: each scene's own answer."""
    tables, rays, expected = small_scene
    moved = tables[:5] + (tables[5].at[:, 3].add(100.0),) + tables[6:]  # every item out of the rays' way
    two = jax.tree_util.tree_map(lambda a, b: jnp.stack([a, b]), tables, moved)
    both = jax.jit(jax.vmap(J.closest_query, in_axes=(0, None, None, None, None, None)))(two, *rays)
    np.testing.assert_array_equal(np.asarray(both[0][0])[~expected[3]], expected[0][~expected[3]])
    assert (np.asarray(both[0][1]) == -1).all()


def test_build_and_query_inside_a_gradient(small_scene):
    """They only choose: no gradient reaches the boxes, the rest of the function differentiates."""
    tables, (o, d, tmin, tmax, want), _ = small_scene
    boxes = tables[0][tables[0].shape[0] // 2:]  # some boxes (the leaves')

    def loss(boxes, o):
        tab = tuple(J.build(boxes)) + tables[3:]
        item, t = J.closest_query(tab, o, d, tmin, tmax, want)
        return jnp.sum(jnp.where(item >= 0, t, 0.0)) + jnp.sum(o)

    g_boxes, g_o = jax.jit(jax.grad(loss, argnums=(0, 1)))(boxes, o)
    assert not np.asarray(g_boxes).any()
    np.testing.assert_array_equal(np.asarray(g_o), 1.0)
