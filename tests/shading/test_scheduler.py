"""The ray scheduler on its own: toy shading functions whose trees have closed-form colours.

Each toy ray sees a local colour and spawns ``branch`` children with a fixed coefficient until its
level reaches the depth, so the root's colour is a geometric sum, independent of how the scheduler
lays out pools, skips chunks or compacts.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer.shading._model import Child, Rays, Shading, camera_rays
from raytracer.shading._scheduler import slots_per_ray, trace_tree


def toy_shader(branch: int, depth: int, local: float, coef: float, power: float | None = None):
    def shade_one(ray: Rays) -> Shading:
        child = Rays(origin=ray.origin, direction=ray.direction, weight=ray.weight * coef,
                     alive=ray.alive & (ray.level < depth), reflection=ray.reflection, level=ray.level + 1,
                     media=ray.media)
        p = None if power is None else jnp.asarray(power, ray.weight.dtype)
        children = tuple(Child(ray=child, coef=jnp.full(3, coef, ray.weight.dtype), power=p)
                         for _ in range(branch))
        return Shading(local=jnp.where(ray.alive, local, 0.0) * jnp.ones(3, ray.weight.dtype),
                       children=children)

    return jax.vmap(shade_one)


def roots(n: int) -> Rays:
    origin = jnp.zeros((n, 3), jnp.float32)
    direction = jnp.broadcast_to(jnp.asarray([0.0, 0.0, 1.0], jnp.float32), (n, 3))
    return camera_rays(origin, direction)


@pytest.mark.parametrize("capacity", [None, 2, 8])
@pytest.mark.parametrize("chunk", [2, 8])
def test_binary_tree_sums_local_colour_over_every_level(capacity, chunk):
    # local 1, two children of coefficient ½ per ray: each level adds 2^k · ½^k · 1 = 1. Half the
    # roots are dead, so 2 slots per root (compacted) hold every live ray of the widest level
    depth, n = 3, 8
    rays = roots(n)._replace(alive=jnp.arange(n) % 2 == 0)
    colour, dropped = trace_tree(toy_shader(2, depth, 1.0, 0.5), rays, depth=depth, branch=2,
                                 chunk=chunk, capacity=capacity)
    expected = np.where(np.arange(n) % 2 == 0, float(depth), 0.0)[:, None] * np.ones(3)
    np.testing.assert_allclose(np.asarray(colour), expected, rtol=1e-6)
    assert int(dropped) == 0


def test_children_beyond_the_capacity_are_dropped_and_counted():
    # depth 3, branch 2: level 3 holds 4 rays per root; with 3 slots per root one in four is dropped
    depth, n = 3, 8
    assert slots_per_ray(2, depth) == 4 and slots_per_ray(2, depth, 3) == 3
    colour, dropped = trace_tree(toy_shader(2, depth, 1.0, 0.5), roots(n), depth=depth, branch=2,
                                 chunk=n, capacity=3)
    assert int(dropped) == n
    assert float(jnp.sum(colour[:, 0])) == pytest.approx(n * depth - n * 0.25, rel=1e-6)


def test_a_tree_deeper_than_the_full_width_allows_is_compacted_not_refused():
    # advanced/pawns.pov: 111 levels (straight passes), whose full width 2^110 slots_per_ray
    # refuses without a capacity; with one the tree is compacted and only the room is asked for
    depth, n = 111, 4
    with pytest.raises(ValueError, match="cannot be held"):
        slots_per_ray(2, depth)
    # one child of weight ½ per ray, the other never alive: a chain of 111 levels in 2 slots per root
    colour, dropped = trace_tree(toy_shader(1, depth, 1.0, 0.5), roots(n), depth=depth, branch=1,
                                 chunk=n, capacity=2)
    np.testing.assert_allclose(np.asarray(colour[:, 0]), 2.0 * (1 - 0.5 ** depth), rtol=1e-6)
    colour, dropped = trace_tree(toy_shader(2, 24, 1.0, 0.5), roots(n), depth=24, branch=2,
                                 chunk=n, capacity=2)  # 2^23 > MAX_FULL_WIDTH: compacted
    assert int(dropped) > 0 and np.isfinite(np.asarray(colour)).all()


def test_dead_roots_see_black_and_chunks_of_them_are_skipped():
    depth, n = 4, 16
    rays = roots(n)
    rays = rays._replace(alive=jnp.arange(n) < 3)  # one live chunk of four, three dead ones
    colour, _ = trace_tree(toy_shader(1, depth, 1.0, 0.5), rays, depth=depth, branch=1, chunk=4)
    expected = np.where(np.arange(n) < 3, 1 + 0.5 + 0.25 + 0.125, 0.0)
    np.testing.assert_allclose(np.asarray(colour[:, 1]), expected, rtol=1e-6)


def test_child_colour_is_raised_to_its_power():
    # root: 0.5 + 1 · child^2 with child = 0.5 (a leaf) → 0.75
    colour, _ = trace_tree(toy_shader(1, 2, 0.5, 1.0, power=2.0), roots(4), depth=2, branch=1, chunk=4)
    np.testing.assert_allclose(np.asarray(colour), np.full((4, 3), 0.75), rtol=1e-6)


def test_partition_puts_live_rays_first_in_order_and_returns_the_inverse():
    """``_partition`` (which the chunked shading relies on) against numpy's stable partition."""
    from raytracer.shading._chunks import partition as _partition

    rng = np.random.default_rng(3)
    for n, p in [(1, 0.5), (7, 0.0), (7, 1.0), (1000, 0.3)]:
        alive = rng.random(n) < p
        order, pos = (np.asarray(x) for x in _partition(jnp.asarray(alive)))
        expected = np.concatenate([np.flatnonzero(alive), np.flatnonzero(~alive)])
        np.testing.assert_array_equal(order, expected)
        np.testing.assert_array_equal(pos[order], np.arange(n))


@pytest.mark.parametrize("in_place", [True, False])
def test_reverse_mode_of_a_chunked_map_keeps_the_chunks_inputs_not_every_intermediate(in_place):
    """A chunk loop's reverse mode stores, per chunk, what the shading needs to run again (its
    inputs), not every intermediate of it: ten intermediates per item stored per chunk made the
    demo scene's forward + backward 10-18 times its forward (one small copy per intermediate
    and chunk), against 3-4 times with the chunk recomputed. The gradient is the closed form's."""
    from raytracer.shading._chunks import map_in_place, map_live

    def fn(x):  # ten nonlinear stages, each of whose outputs reverse mode would otherwise keep
        for k in range(10):
            x = jnp.sin(x) * (1.0 + 0.1 * k) + jnp.exp(-x * x)
        return x

    n, chunk = 64, 8
    x = jnp.linspace(-1.0, 1.0, n)
    alive = jnp.arange(n) < 40  # five live chunks of eight
    run = map_in_place if in_place else map_live
    out, vjp = jax.vjp(lambda v: run(fn, v, alive, chunk), x)
    kept = sum(np.size(leaf) for leaf in jax.tree_util.tree_leaves(vjp))
    assert kept <= 4 * n, kept  # the inputs, the live flags, a permutation: not 10·n
    (grad,) = vjp(jnp.ones(n))
    want = np.where(np.asarray(alive), np.asarray(jax.vmap(jax.grad(fn))(x)), 0.0)
    np.testing.assert_allclose(np.asarray(out)[:40], np.asarray(fn(x))[:40], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(grad), want, rtol=1e-5, atol=1e-6)



def test_a_forward_chunk_loop_stops_at_the_last_live_chunk_and_differentiates_as_the_scan():
    """Not differentiated, ``map_in_place`` is a ``while_loop`` over the chunks up to the last live
    one (the dead chunks behind it take no loop step); its values, a dead chunk before the last
    live one included (zeros), and its forward- and reverse-mode derivatives are the closed
    form's, through the scan that a ``while_loop`` lacks in reverse mode."""
    from raytracer.shading._chunks import map_in_place

    n, chunk = 64, 8
    x = jnp.linspace(-1.0, 1.0, n)
    alive = (jnp.arange(n) < 40) & ((jnp.arange(n) < 16) | (jnp.arange(n) >= 24))  # chunk 2 dead
    computed = np.asarray(jnp.any(alive.reshape(-1, chunk), axis=1).repeat(chunk))

    def run(w):
        return map_in_place(lambda v: {"y": jnp.sin(w * v) * v}, x, alive, chunk)["y"]

    from jax.extend.core import jaxprs_in_params

    def primitives(jaxpr):
        return {name for e in jaxpr.eqns for name in
                {e.primitive.name}.union(*(primitives(j) for j in jaxprs_in_params(e.params)))}

    forward = primitives(jax.make_jaxpr(run)(1.5).jaxpr)
    assert "while" in forward and "scan" not in forward
    xs = np.asarray(x)
    np.testing.assert_allclose(np.asarray(run(1.5)), np.where(computed, np.sin(1.5 * xs) * xs, 0.0),
                               rtol=1e-6, atol=1e-7)
    want = np.where(computed, np.cos(1.5 * xs) * xs * xs, 0.0)  # d/dw
    _, tangent = jax.jvp(run, (1.5,), (1.0,))
    np.testing.assert_allclose(np.asarray(tangent), want, rtol=1e-5, atol=1e-7)
    grad = jax.grad(lambda w: jnp.sum(run(w)))(1.5)
    np.testing.assert_allclose(float(grad), want.sum(), rtol=1e-5)


def test_a_compacted_tree_traced_forward_follows_its_live_rays_and_differentiates_as_the_scan():
    """A compacted tree shaded in chunks is, forward, ``while_loop``s over the levels with a live
    ray and the chunks up to the last live one (no ``scan``), each chunk appending its children
    to the next pool. Its colours, its dropped count and its forward- and reverse-mode derivatives
    are the closed form's (through the scan, which JAX can reverse). Roots: 12 of 16 live; each
    ray sees ``theta·level`` and spawns two children of coefficient ½ down to level 3, so a live
    root sees θ·(1 + 2·½·2 + 4·¼·3) = 6θ. With 3 slots per root every ray fits (level 3: 48 rays in
    48 slots); with 2, level 3 keeps 32 and drops 16."""
    n, depth = 16, 3

    def shader(theta):
        def shade_one(ray: Rays) -> Shading:
            child = ray._replace(weight=ray.weight * 0.5, alive=ray.alive & (ray.level < depth),
                                 level=ray.level + 1)
            local = jnp.where(ray.alive, theta * ray.level, 0.0) * jnp.ones(3)
            return Shading(local=local, children=tuple(Child(ray=child, coef=jnp.full(3, 0.5), power=None)
                                                       for _ in range(2)))
        return jax.vmap(shade_one)

    live = jnp.arange(n) % 4 != 1

    def tree(theta, capacity):
        rays = roots(n)._replace(alive=live)
        return trace_tree(shader(theta), rays, depth=depth, branch=2, chunk=4, capacity=capacity)

    from jax.extend.core import jaxprs_in_params

    def primitives(jaxpr):
        return {name for e in jaxpr.eqns for name in
                {e.primitive.name}.union(*(primitives(j) for j in jaxprs_in_params(e.params)))}

    forward = primitives(jax.make_jaxpr(lambda t: tree(t, 3))(1.0).jaxpr)
    assert "while" in forward and "scan" not in forward
    colour, dropped = tree(0.7, 3)
    want = np.where(np.asarray(live), 6 * 0.7, 0.0)
    np.testing.assert_allclose(np.asarray(colour[:, 0]), want, rtol=1e-6)
    assert int(dropped) == 0
    _, dropped = tree(0.7, 2)
    assert int(dropped) == 16
    _, tangent = jax.jvp(lambda t: tree(t, 3)[0], (0.7,), (1.0,))
    np.testing.assert_allclose(np.asarray(tangent[:, 1]), want / 0.7, rtol=1e-6)
    grad = jax.grad(lambda t: jnp.sum(tree(t, 3)[0]))(0.7)
    np.testing.assert_allclose(float(grad), 3 * want.sum() / 0.7, rtol=1e-6)


def test_derivatives_may_shade_whole_pools_where_the_forward_tree_shades_chunks():
    """``grad_chunk``: forward, the live tree shades ``chunk`` rays at a time; differentiated, the
    scan shades ``grad_chunk`` (here whole pools of 48 slots: a reverse-mode program without a loop
    over chunks compiles faster). The shading is traced at each batch size it runs at, and the
    colours and tangents are the closed form's (6θ per live root, as above)."""
    n, depth = 16, 3
    sizes = []

    def shader(theta):
        def shade(rays: Rays) -> Shading:
            sizes.append(rays.alive.shape[0])
            child = rays._replace(weight=rays.weight * 0.5, alive=rays.alive & (rays.level < depth),
                                  level=rays.level + 1)
            local = jnp.where(rays.alive, theta * rays.level, 0.0)[:, None] * jnp.ones((1, 3))
            return Shading(local=local, children=tuple(
                Child(ray=child, coef=jnp.full((rays.alive.shape[0], 3), 0.5), power=None) for _ in range(2)))
        return shade

    live = jnp.arange(n) % 4 != 1
    want = np.where(np.asarray(live), 6.0, 0.0)

    def tree(theta):
        return trace_tree(shader(theta), roots(n)._replace(alive=live), depth=depth, branch=2, chunk=4,
                          capacity=3, grad_chunk=48)[0]

    np.testing.assert_allclose(np.asarray(tree(0.7)[:, 0]), 0.7 * want, rtol=1e-6)
    assert set(sizes) == {4}
    colour, tangent = jax.jvp(tree, (0.7,), (1.0,))
    assert 48 in sizes
    np.testing.assert_allclose(np.asarray(colour[:, 0]), 0.7 * want, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(tangent[:, 2]), want, rtol=1e-6)
    np.testing.assert_allclose(float(jax.grad(lambda t: jnp.sum(tree(t)))(0.7)), 3 * want.sum(), rtol=1e-6)
    # a grad_chunk past the pool is the pool (it was traced at 1,000 rays and called with 48)
    _, tangent = jax.jvp(lambda t: trace_tree(shader(t), roots(n)._replace(alive=live), depth=depth, branch=2,
                                              chunk=4, capacity=3, grad_chunk=1000)[0], (0.7,), (1.0,))
    np.testing.assert_allclose(np.asarray(tangent[:, 2]), want, rtol=1e-6)


def test_with_too_little_room_the_forward_tree_and_its_derivative_keep_the_same_children():
    """Roots 0…15 (every fourth dead) each see θ·(1 + x), x its id, and spawn two children
    (coefficient ½; the second adds 100 to x) down to level 3: a whole tree sees θ·(153 + 3·id).
    With 2 slots per root level 3 has room for 32 of its 48 children. Both the forward program and
    the one its derivatives come from fill a pool chunk by chunk (4 parents), in a chunk every first
    child before any second: level 2 is [f0 f2 f3 s0 s2 s3][f4 f6 f7 s4 s6 s7]…, and level 3 keeps the
    children of its first 16 slots; roots 10 and 11 lose those of their second child
    (¼·θ·(302 + 2·id)), roots 12, 14 and 15 all four grandchildren (θ·(101 + id)). The forward image,
    its dropped count and the derivative's image and tangent are all that (they differed)."""
    n, depth = 16, 3

    def shader(theta):
        def one(ray: Rays) -> Shading:
            kids = tuple(Child(ray=ray._replace(origin=ray.origin.at[0].add(100.0 * s),
                                                weight=ray.weight * 0.5, level=ray.level + 1,
                                                alive=ray.alive & (ray.level < depth)),
                               coef=jnp.full(3, 0.5), power=None) for s in range(2))
            return Shading(local=jnp.where(ray.alive, theta * (1 + ray.origin[0]), 0.0) * jnp.ones(3),
                           children=kids)
        return jax.vmap(one)

    ids = np.arange(n)
    live = ids % 4 != 1

    def tree(theta):
        rays = roots(n)
        rays = rays._replace(alive=jnp.asarray(live),
                             origin=rays.origin.at[:, 0].set(jnp.asarray(ids, jnp.float32)))
        return trace_tree(shader(theta), rays, depth=depth, branch=2, chunk=4, capacity=2)

    want = 153.0 + 3 * ids
    want[[10, 11]] -= 0.25 * (302 + 2 * ids[[10, 11]])
    want[[12, 14, 15]] -= 101 + ids[[12, 14, 15]]
    want = np.where(live, want, 0.0)
    colour, dropped = jax.jit(tree)(0.5)
    np.testing.assert_allclose(np.asarray(colour[:, 0]), 0.5 * want, rtol=1e-6)
    assert int(dropped) == 16
    (primal, dropped), (tangent, _) = jax.jvp(tree, (0.5,), (1.0,))
    np.testing.assert_allclose(np.asarray(primal[:, 0]), 0.5 * want, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(tangent[:, 0]), want, rtol=1e-6)
    assert int(dropped) == 16


def test_a_compacted_tree_in_float64_differentiates_through_jit():
    """float64: the live tree's primal and the scan's (its derivative rule) agree in dtype, dropped
    count included (int64 from the scan made ``jax.jvp`` of a jitted render raise), and the
    tangent is the closed form's: each live root sees θ·(1 + 2·½·2 + 4·¼·3) = 6θ at depth 3."""
    n, depth = 16, 3
    live = jnp.arange(n) % 4 != 1

    def shade_one(theta, ray: Rays) -> Shading:
        child = ray._replace(weight=ray.weight * 0.5, alive=ray.alive & (ray.level < depth),
                             level=ray.level + 1)
        local = jnp.where(ray.alive, theta * ray.level, 0.0) * jnp.ones(3, theta.dtype)
        return Shading(local=local, children=tuple(Child(ray=child, coef=jnp.full(3, 0.5, theta.dtype),
                                                         power=None) for _ in range(2)))

    with jax.enable_x64(True):
        def tree(theta):
            rays = camera_rays(jnp.zeros((n, 3)), jnp.broadcast_to(jnp.asarray([0.0, 0.0, 1.0]), (n, 3)))
            colour, dropped = trace_tree(jax.vmap(lambda r: shade_one(theta, r)), rays._replace(alive=live),
                                         depth=depth, branch=2, chunk=4, capacity=3)
            return colour, dropped

        (colour, dropped), (tangent, _) = jax.jvp(jax.jit(tree), (jnp.float64(0.7),), (jnp.float64(1.0),))
        assert colour.dtype == jnp.float64 and int(dropped) == 0
        want = np.where(np.asarray(live), 6.0, 0.0)
        np.testing.assert_allclose(np.asarray(colour[:, 0]), 0.7 * want, rtol=1e-14)
        np.testing.assert_allclose(np.asarray(tangent[:, 2]), want, rtol=1e-14)


def test_reverse_mode_of_a_deep_tree_with_costly_shading_keeps_each_levels_rays_not_its_intermediates(
        monkeypatch):
    """A pool shaded in one call keeps, per level of the scan, every intermediate reverse mode needs
    of its shading: a deep tree of costly shading (a glass scene with noise-textured shadows, 49
    levels) kept 9.8 GB. Past ``LEVEL_RESIDUAL_BUDGET`` bytes over the levels (measured by
    ``intermediate_bytes``, an upper bound of those residuals) the level runs again in the
    backward pass instead, and keeps only its rays. The gradient is the closed form's either way."""
    from raytracer.shading import _scheduler
    from raytracer.shading._chunks import intermediate_bytes

    depth, n, width, coef = 6, 8, 32, 0.5

    def stages(x):  # ten nonlinear stages, each of whose outputs reverse mode would otherwise keep
        for k in range(10):
            x = x + 0.3 * jnp.sin(x * (1.0 + 0.1 * k))
        return x

    def shader(theta):
        def shade_one(ray: Rays) -> Shading:
            x = stages(theta + ray.level + jnp.linspace(0.0, 1.0, width))  # `width` values per ray
            child = ray._replace(weight=ray.weight * coef, alive=ray.alive & (ray.level < depth),
                                 level=ray.level + 1)
            return Shading(local=jnp.where(ray.alive, jnp.mean(x), 0.0) * jnp.ones(3),
                           children=(Child(ray=child, coef=jnp.full(3, coef), power=None),))
        return jax.vmap(shade_one)

    def colour(theta):
        out, _ = trace_tree(shader(theta), roots(n), depth=depth, branch=1, chunk=n, capacity=1)
        return jnp.sum(out[:, 0])

    def kept_and_grad(budget):
        monkeypatch.setattr(_scheduler, "LEVEL_RESIDUAL_BUDGET", budget)
        _, vjp = jax.vjp(colour, jnp.float32(0.3))
        kept = sum(np.size(leaf) * np.asarray(leaf).itemsize for leaf in jax.tree_util.tree_leaves(vjp))
        return kept, float(vjp(jnp.float32(1.0))[0])

    def per_level(theta):  # Σ_k coef^k · mean(stages(θ + level + s)) of one root ray (level k + 1)
        return sum(coef ** k * jnp.mean(stages(theta + k + 1 + jnp.linspace(0.0, 1.0, width)))
                   for k in range(depth))

    want = n * float(jax.grad(per_level)(jnp.float32(0.3)))
    kept_all, grad_all = kept_and_grad(1 << 60)
    kept_rays, grad_rays = kept_and_grad(0)
    level_bound = intermediate_bytes(jax.make_jaxpr(shader(jnp.float32(0.3)))(roots(n)))
    assert kept_all <= depth * level_bound, (kept_all, level_bound)  # the budget's measure bounds it
    assert kept_rays * 5 < kept_all, (kept_rays, kept_all)  # 10 stages × 32 values per ray, not kept
    np.testing.assert_allclose(grad_all, want, rtol=1e-4)
    np.testing.assert_allclose(grad_rays, want, rtol=1e-4)
