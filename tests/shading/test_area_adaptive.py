"""Area lights as POV-Ray samples them (semantics §2.5): the recursion over the sample grid, its
adaptive form (split N times, then only where a block's corners differ), and ``circular``.

The closed forms below are one shading point straight below a 5×1 light, with a small occluder in
the way of the shadow ray to one sample: the pixel is the light's colour times the shadow filter,
so each rule of the recursion gives a different, hand-computed value. POV-Ray gives the same
values (the ``povray`` test), and the same images of a scene with soft shadows through opaque and
transparent objects.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer.scene._lights import area_blocks, area_weights

# The shading point is the origin of a white diffuse plane; the light's centre is straight above
# it (n·l = 1), its samples at x = -2, -1, 0, 1, 2 (u = 0…4) at height 4. A small disc (one
# surface: one crossing filters once) sits halfway along the shadow ray to one sample and misses
# the rays to the others.
ONE_POINT = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 10, 0> look_at 0 sky z angle 1 }}
light_source {{ <0, 4, 0> color rgb {colour} area_light <4, 0, 0>, <0, 0, 1>, 5, 1 {adaptive} }}
plane {{ y, 0 pigment {{ rgb 1 }} finish {{ ambient 0 diffuse 1 }} }}
disc {{ <{x}, 2, 0>, y, 0.1 pigment {{ rgbt <1, 1, 1, {transmit}> }} no_image }}
"""

# (adaptive, colour, the disc's sample, transmit) → shadow filter. Per-axis weights of 5 samples:
# ⅛ ¼ ¼ ¼ ⅛ (full subdivision).
CASES = {
    # a disc in front of sample 1 only: full subdivision loses its weight ¼
    "full": ("", 1.0, 1, 0.0, 0.75),
    # adaptive 0: the corners 0 and 4 agree, so the light is their mean: the disc is never seen
    "adaptive 0 misses a disc between corners": ("adaptive 0", 1.0, 1, 0.0, 1.0),
    # adaptive 1 traces 0, 2, 4: the blocks [0,2] and [2,4] have equal corners: missed again
    "adaptive 1 misses it too": ("adaptive 1", 1.0, 1, 0.0, 1.0),
    # adaptive 2 splits down to the leaves: as full
    "adaptive 2 is full subdivision here": ("adaptive 2", 1.0, 1, 0.0, 0.75),
    # a disc in front of corner 0: 3·(1 − 0.98) = 0.06 ≤ 0.1, no split: mean of the corners
    # (0.98 + 0.98 + 1 + 1)/4, not full subdivision's 1 − 0.02/8
    "faint filter below the threshold": ("adaptive 0", 1.0, 0, 0.98, 0.99),
    # 3·0.05 > 0.1: split down to the leaves where the corners differ: as full, 1 − 0.05/8
    "filter above the threshold": ("adaptive 0", 1.0, 0, 0.95, 0.99375),
    # an opaque disc at corner 0 under a dim light: 3·0.03 ≤ 0.1 compares the arriving colours, so
    # no split: half the light (full subdivision: ⅞)
    "dim light below the threshold": ("adaptive 0", 0.03, 0, 0.0, 0.5),
}


def _one_point(adaptive, colour, bar, transmit):
    return ONE_POINT.format(colour=colour, adaptive=adaptive, x=(bar - 2) / 2, transmit=transmit)


def test_the_full_recursion_gives_povrays_weights():
    """Fully split, the blocks' corner means give the product of the per-axis weights, which are
    ¼ ½ ¼ for 3 samples, ⅛ ¼ ¼ ¼ ⅛ for 5 and uniform for 4 (semantics §2.5)."""
    np.testing.assert_allclose(area_weights(3), [1 / 4, 1 / 2, 1 / 4])
    np.testing.assert_allclose(area_weights(5), [1 / 8, 1 / 4, 1 / 4, 1 / 4, 1 / 8])
    np.testing.assert_allclose(area_weights(4), [1 / 4] * 4)
    for n1, n2 in [(1, 1), (1, 5), (2, 3), (3, 3), (4, 4), (5, 5), (5, 2), (6, 7), (9, 9)]:
        w = np.zeros(n1 * n2)

        def spread(b, weight, w=w):
            if not b.children:
                for k in b.corners:
                    w[k] += weight / 4
            for c in b.children:
                spread(c, weight / len(b.children), w)

        spread(area_blocks(n1, n2), 1.0)
        np.testing.assert_allclose(w, np.outer(area_weights(n1), area_weights(n2)).ravel(), atol=1e-15)


@pytest.mark.slow  # seven small programs
@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_adaptive_sampling_follows_the_closed_forms(case):
    adaptive, colour, bar, transmit, expected = CASES[case]
    scene = rt.load_scene(_one_point(adaptive, colour, bar, transmit))
    pixel = np.asarray(rt.render(scene, width=1, height=1))
    np.testing.assert_allclose(pixel[0, 0], colour * expected, rtol=1e-5)


@pytest.mark.povray
def test_povray_gives_the_closed_forms():
    from validation.povray import render_povray

    got = {case: render_povray(_one_point(*values[:4]), 1, 1)[0, 0, 0] for case, values in CASES.items()}
    want = {case: values[1] * values[4] for case, values in CASES.items()}
    for case in CASES:  # POV-Ray's EXR is half-float
        assert abs(got[case] - want[case]) <= 2e-3 * max(want[case], 0.1), (case, got[case], want[case])


PENUMBRA = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 6, -8> look_at <0, 0, 0> }}
light_source {{ <0, 8, 0> color rgb 1 area_light <6, 0, 0>, <0, 0, 6>, 5, 5 {options} }}
plane {{ y, 0 pigment {{ rgb 1 }} finish {{ ambient 0 diffuse 1 }} }}
sphere {{ <0, 2, 0>, 1 pigment {{ rgb <1, 0.3, 0.3> }} finish {{ ambient 0.1 diffuse 0.7 }} }}
box {{ <1.5, 0, -1>, <2.5, 3, 1> pigment {{ rgbt <0.5, 1, 0.5, 0.5> }} }}
cylinder {{ <-2.5, 0, 1>, <-2.5, 3, 1>, 0.15 pigment {{ rgb 0.5 }} }}
"""


@pytest.mark.povray
@pytest.mark.slow
@pytest.mark.parametrize("options, full_was", [
    # a sphere, a transparent box and a thin post: adaptive 0 misses the post's shadow where it
    # falls between the corners, and stops at faint filtered differences (58.0 dB; rendered fully
    # subdivided, as before: 36.7 dB)
    ("adaptive 0", 36.7),
    # circular: the grid pulled onto a disc, shifted by 0.002 (62.9 dB; as a square grid: 34.7 dB)
    ("circular adaptive 1", 34.7),
])
def test_soft_shadows_match_povray(options, full_was):
    from validation.metrics import psnr
    from validation.povray import render_povray

    text = PENUMBRA.format(options=options)
    pov = render_povray(text, 160, 120)
    ours = np.asarray(rt.render(rt.load_scene(text), width=160, height=120))
    assert psnr(ours, pov) >= 55.0
    # the rule matters here: the plain grid is far from POV-Ray's image
    plain = np.asarray(rt.render(rt.load_scene(PENUMBRA.format(options="")), width=160, height=120))
    assert psnr(plain, pov) <= full_was + 1.0


@pytest.mark.slow  # a reverse-mode program and a few forward ones
def test_adaptive_shadows_differentiate_like_their_samples():
    """Which blocks split is piecewise constant; the samples' filters and the means are smooth. So
    the gradient is finite everywhere, and a light-colour JVP (which moves no shadow edge) equals
    central differences away from the few pixels whose split decisions sit at the threshold."""
    scene = rt.load_scene(PENUMBRA.format(options="adaptive 0"))
    w, h = 32, 24
    p, rest = eqx.partition(scene, eqx.is_inexact_array)
    g = jax.jit(jax.grad(lambda p: jnp.mean(rt.render(eqx.combine(p, rest), width=w, height=h) ** 2)))(p)
    assert all(bool(jnp.isfinite(x).all()) for x in jax.tree.leaves(g))
    assert float(jnp.abs(g.lights[0].position).max()) > 0  # the soft shadow moves with the light

    def image(c):
        return rt.render(eqx.tree_at(lambda s: s.lights[0].color, scene, c), width=w, height=h)

    c0 = scene.lights[0].color
    tangent = jnp.asarray([0.3, -0.2, 0.5], c0.dtype)
    _, jvp = jax.jvp(image, (c0,), (tangent,))
    eps = 1e-3
    fd = (image(c0 + eps * tangent) - image(c0 - eps * tangent)) / (2 * eps)
    err = np.abs(np.asarray(jvp) - np.asarray(fd)).max(axis=-1)
    assert (err <= 2e-3).mean() >= 0.99, np.sort(err.ravel())[-5:]


def test_circular_grid_points_sit_where_povray_puts_them():
    """Sample points of ``circular`` lights located one by one in POV-Ray 3.7 renders (a tiny
    occluder scanned across each point's shadow ray; ±2e-4 world units), against ours: the square
    grid shifted by 0.002 and pulled radially onto the disc (semantics §2.5)."""
    from raytracer.scene._lights import _area_samples

    def point(n1, n2, a1, a2, u, v):
        light = rt.Light(position=(0.0, 0.0, 0.0),
                         area=rt.AreaLight(a1, a2, n1, n2, circular=True))
        positions, _ = _area_samples(light, jnp.float32)
        return np.asarray(positions)[u * n2 + v][[0, 2]]

    x, z = (4.0, 0.0, 0.0), (0.0, 0.0, 4.0)
    # (grid, axes, index) → measured (x, z); a 7×7 grid's (u, v) = (6, 4) is (a, b) = (1, 1/3)
    measured = [((7, 7, x, z, 6, 4), (1.90042, 0.63601)),
                ((7, 7, x, z, 5, 4), (1.19562, 0.59962)),
                ((7, 7, x, z, 6, 5), (1.66681, 1.11241)),
                ((7, 7, x, z, 1, 2), (-1.18971, -0.59306)),
                ((4, 4, x, z, 2, 3), (0.63600, 1.90040))]
    for args, where in measured:
        np.testing.assert_allclose(point(*args), where, atol=3e-4)
    # oblique axes: (a, b) = (0.5, 1) on a 5×5 light with a2 = <2, 0, 3>
    np.testing.assert_allclose(point(5, 5, x, (2.0, 0.0, 3.0), 3, 4), (1.79360, 1.34360), atol=3e-4)


def test_block_means_follow_the_recursion():
    """The final means, computed one depth at a time over the plan's tables, against the recursion
    written out over the blocks (a split block: its children's mean; any other: its corners')
    for random filters and random split tables, on grids with one-wide and odd axes."""
    from raytracer.shading._model import _adaptive_plan, _block_means

    rng = np.random.default_rng(3)
    for n1, n2 in [(5, 1), (4, 4), (6, 7), (17, 17)]:
        plan = _adaptive_plan(n1, n2, 0)
        root = area_blocks(n1, n2)
        every, frontier = [], [root]
        while frontier:  # breadth first, the plan's block order
            every += frontier
            frontier = [c for b in frontier for c in b.children]
        index = {id(b): j for j, b in enumerate(every)}
        cols = rng.random((3, n1 * n2, 3))
        split = rng.random((3, len(every) + 2)) < 0.6

        def value(b, i, cols=cols, split=split, index=index):
            if b.children and split[i, index[id(b)]]:
                return sum(value(c, i) for c in b.children) / len(b.children)
            return sum(cols[i, k] for k in b.corners) / 4

        want = np.stack([value(root, i) for i in range(3)])
        np.testing.assert_allclose(_block_means(plan, jnp.asarray(cols), jnp.asarray(split)), want,
                                   rtol=1e-6)


def test_area_lights_share_a_shadow_test_and_add_up():
    """Adaptive lights, two with one grid and one with another, are sampled by one traced shadow
    test per phase over (point, sample) pairs, and an area light without ``adaptive`` by the first
    phase's. Light adds up: with no ambient, the image lit by all four is the sum of the images lit
    by each alone, which fails if a pair's samples or filters came from another light or grid."""
    lights = ["light_source { <-3, 8, 1> color rgb 0.6 area_light <6, 0, 0>, <0, 0, 6>, 5, 5 adaptive 0 }",
              "light_source { <4, 6, -2> color rgb <0.3, 0.5, 0.9> area_light <4, 0, 0>, <0, 0, 4>, 5, 5 "
              "adaptive 0 circular }",
              "light_source { <1, 7, -4> color rgb <0.7, 0.4, 0.2> area_light <3, 0, 0>, <0, 0, 3>, 4, 4 "
              "adaptive 0 }",
              "light_source { <-2, 9, -3> color rgb <0.2, 0.6, 0.3> area_light <2, 0, 0>, <0, 0, 2>, 3, 3 }"]
    scene = [line for line in PENUMBRA.format(options="").splitlines() if not line.startswith("light_source")]
    scene.insert(2, "#default { finish { ambient 0 } }")  # after #version and global_settings
    body = "\n".join([*scene, ""]).replace("ambient 0.1", "ambient 0")
    every, *alone = (np.asarray(rt.render(rt.load_scene(body + "\n".join(ls) + "\n"), width=40, height=30))
                     for ls in (lights, *([light] for light in lights)))
    np.testing.assert_allclose(every, sum(alone), rtol=1e-5, atol=1e-6)
    assert min(np.abs(a - b).max() for i, a in enumerate(alone) for b in alone[:i]) > 0.1  # shadows differ


def test_area_lights_without_adaptive_give_the_per_ray_image_in_the_batch(monkeypatch):
    """An area light without ``adaptive`` is sampled by the batch's shadow test, its (point,
    sample) pairs traced only where it lights a hit: the image (penumbra, a transparent caster) is
    the one of every ray tracing every sample (``shade`` per ray)."""
    import jax

    from raytracer.shading import _model

    scene = rt.load_scene(PENUMBRA.format(options=""))
    batched = np.asarray(rt.render(scene, width=40, height=30))
    monkeypatch.setattr(_model, "_sampled", lambda ctx, light: False)
    jax.clear_caches()
    per_ray = np.asarray(rt.render(scene, width=40, height=30))
    np.testing.assert_allclose(batched, per_ray, rtol=1e-6, atol=1e-6)
    grey = batched[..., 1]
    assert ((grey > 0.05) & (grey < 0.6)).sum() > 20  # a penumbra between light and shadow
