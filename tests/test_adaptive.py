"""Adaptive anti-aliasing (``render(…, adaptive=(threshold, depth))``, POV-Ray's method 1): the
pixels it refines, their values, its gradient, and POV-Ray's own adaptive image."""

import importlib
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import load_scene, render

SEED = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "seed.pov"
W, H = 40, 30

SCENE = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 1.5, -5> look_at <0, 0.5, 0> right x*image_width/image_height angle 45 }
light_source { <-4, 6, -5> rgb 1 }
plane { y, 0 pigment { checker rgb 1 rgb 0.2 } }
sphere { <0, 0.8, 0>, 0.8 pigment { rgb <0.9, 0.3, 0.2> } finish { phong 0.6 } }
"""


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "aa.pov"
    path.write_text(SCENE)
    return load_scene(path)


def _expected(scene, threshold, n, W=W, H=H):
    """Independently: centre samples, the n×n grid of every pixel (two whole-image renders),
    POV-Ray's rule as a loop over the pixels in scan order (each centre compared with its left
    and upper neighbours' values as they are then, colours raised to 1/2.5; a difference refines
    both), and POV-Ray's (centre + Σ grid) / (n² + 1) where refined."""
    centre = np.asarray(render(scene, width=W, height=H), np.float64)
    grid = np.asarray(render(scene, width=W, height=H, spp=n * n), np.float64)
    refined = (centre + n * n * grid) / (n * n + 1)
    value, flag = centre.copy(), np.zeros((H, W), bool)

    def seen(x):
        return np.maximum(x, 0) ** (1 / 2.5)  # POV-Ray's Antialias_Gamma

    for y in range(H):
        for x in range(W):
            for ny, nx in ((y, x - 1), (y - 1, x)):
                if min(ny, nx) >= 0 and np.abs(seen(centre[y, x]) - seen(value[ny, nx])).sum() >= threshold:
                    for py, px in ((y, x), (ny, nx)):
                        flag[py, px] = True
                        value[py, px] = refined[py, px]
    return value, flag


@pytest.mark.slow  # ~4 s: two whole-image renders and the loop over every pixel
def test_refines_in_scan_order_as_povray_does_with_its_weights(scene):
    want, flag = _expected(scene, 0.3, 3)
    assert 0.02 < flag.mean() < 0.8  # edges of the sphere and the checker: some pixels, not all
    got = np.asarray(render(scene, width=W, height=H, adaptive=(0.3, 3)))
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
    # threshold 0 refines every pixel: the POV-Ray +A0.0 image
    everything, flag0 = _expected(scene, 0.0, 2)
    assert flag0.all()
    np.testing.assert_allclose(np.asarray(render(scene, width=W, height=H, adaptive=(0.0, 2))), everything,
                               rtol=1e-5, atol=1e-6)


@pytest.mark.slow  # ~5 s: three programs for each of two sizes
@pytest.mark.parametrize("size", [(1, 12), (12, 1)], ids=["one column", "one row"])
def test_an_image_one_pixel_wide_or_high(scene, size):
    """An image one pixel wide or high, every pixel refined and some (the same program: the
    threshold is an argument): a render one pixel wide hung (the chain neighbours, two to the
    right and one below, were shifted into flags wider than the image)."""
    for threshold in (0.0, 0.3):
        want, flag = _expected(scene, threshold, 2, *size)
        assert flag.all() == (threshold == 0.0)
        got = np.asarray(render(scene, width=size[0], height=size[1], adaptive=(threshold, 2)))
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)


def test_under_jit_every_pixel_is_refined_and_the_flagged_ones_kept(scene):
    eager = np.asarray(render(scene, width=W, height=H, adaptive=(0.3, 3)))
    jitted = np.asarray(jax.jit(lambda s: render(s, width=W, height=H, adaptive=(0.3, 3)))(scene))
    np.testing.assert_allclose(jitted, eager, rtol=1e-5, atol=1e-6)


TWO_DEVICES = """
import importlib, json, sys
import equinox as eqx, jax, jax.numpy as jnp, numpy as np
from raytracer import load_scene, render
R = importlib.import_module("raytracer._tiles")
pack = importlib.import_module("raytracer._packed").pack
scene = load_scene(sys.argv[1])
image = render(scene, width={W}, height={H}, adaptive=(0.3, 3))
every = render(scene, width={W}, height={H}, adaptive=(0.0, 3))  # every pixel: a pass split over both
devices = len(jax.local_devices())  # enough pixels of 9 rays to be split: MIN_SHARD_RAYS a device
quantum = 4 * devices
pixels = jnp.arange(-(-devices * R.MIN_SHARD_RAYS // (9 * quantum)) * quantum, dtype=jnp.int32)
program = R._render_pixels.lower(pack(scene), {W}, {H}, 3, pixels, 2).as_text()
large = render(scene, width=128, height=96)  # two tiles: sharded over both devices, committed
mixed = float(jnp.sum(large[:{H}, :{W}] + image))  # raised "incompatible devices" when the adaptive
                                                   # image was committed to the first device only
def mean_at(c):  # at 128×96 the centres are sharded over both devices, the refined pixels not
    lit = eqx.tree_at(lambda s: s.lights[0].color, scene, c)
    return jnp.mean(render(lit, width=128, height=96, adaptive=(0.3, 2)))
c0 = jnp.asarray(scene.lights[0].color)
grad = jax.grad(mean_at)(c0)  # raised "incompatible devices": centres on two, refined pixels on one
fd = [float(mean_at(c0.at[i].add(1e-3)) - mean_at(c0.at[i].add(-1e-3))) / 2e-3 for i in range(3)]
json.dump({{"devices": len(jax.local_devices()), "sharded": "manual_computation" in program,
           "large_devices": len(large.devices()), "mixed": mixed,
           "split": R._pixel_devices({W} * {H}, 9), "image": np.asarray(image).tolist(),
           "every": np.asarray(every).tolist(), "grad": np.asarray(grad).tolist(), "fd": fd}},
          open(sys.argv[2], "w"))
"""


@pytest.mark.slow
def test_refined_pixels_are_split_over_the_devices_with_the_image_of_one(scene, tmp_path, two_device_env):
    """With two devices the refined pixels are traced on both, the image is the one-device image,
    it combines with an image sharded over both devices, and its gradient is finite differences'."""
    path = tmp_path / "aa.pov"
    path.write_text(SCENE)
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(TWO_DEVICES.format(W=W, H=H)), str(path),
                          str(tmp_path / "out.json")], env=two_device_env, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads((tmp_path / "out.json").read_text())
    assert got["devices"] == 2 and got["sharded"] and got["large_devices"] == 2 and np.isfinite(got["mixed"])
    want = render(scene, width=W, height=H, adaptive=(0.3, 3))  # this process: one device
    np.testing.assert_allclose(np.asarray(got["image"]), np.asarray(want), rtol=1e-5, atol=1e-6)
    # threshold 0 refines every pixel in one pass, traced on both devices (a pass on one device
    # is one program with its update; one on several, two)
    assert got["split"] == 2
    every = render(scene, width=W, height=H, adaptive=(0.0, 3))
    np.testing.assert_allclose(np.asarray(got["every"]), np.asarray(every), rtol=1e-5, atol=1e-6)
    # the image's mean is linear in the light's colour for the pixels refined (float32: rtol 1e-3)
    assert np.all(np.asarray(got["grad"]) > 0)
    np.testing.assert_allclose(got["grad"], got["fd"], rtol=1e-3)


@pytest.mark.slow
def test_gradient_holds_the_choice_of_pixels_fixed(tmp_path, x64):
    """d/dθ of the adaptive image's mean = that of the same pixel-wise combination of the two
    renders with the refined pixels held fixed (the choice is piecewise constant, like a hit)."""
    path = tmp_path / "aa.pov"
    path.write_text(SCENE)
    scene = load_scene(path)  # float64 under the x64 fixture
    _, flag = _expected(scene, 0.3, 2)

    def lit(c):
        return eqx.tree_at(lambda s: s.lights[0].color, scene, c)

    def adaptive(c):
        return jnp.mean(render(lit(c), width=W, height=H, adaptive=(0.3, 2)))

    def fixed(c):
        centre, grid = render(lit(c), width=W, height=H), render(lit(c), width=W, height=H, spp=4)
        return jnp.mean(jnp.where(flag[..., None], (centre + 4 * grid) / 5, centre))

    c0 = jnp.asarray(scene.lights[0].color)
    g = jax.grad(adaptive)(c0)
    assert np.all(np.asarray(g) > 0)
    np.testing.assert_allclose(np.asarray(g), np.asarray(jax.grad(fixed)(c0)), rtol=1e-10)
    eps = 1e-6  # and central differences (no pixel changes its flag for this step)
    fd = [(adaptive(c0.at[i].add(eps)) - adaptive(c0.at[i].add(-eps))) / (2 * eps) for i in range(3)]
    np.testing.assert_allclose(np.asarray(g), np.asarray(fd), rtol=1e-6)


@pytest.mark.povray
def test_matches_povray_adaptive_image_of_the_seed_scene():
    from validation.metrics import psnr
    from validation.povray import run_povray

    scene = load_scene(SEED, width=160, height=120)
    pov = run_povray(SEED, 160, 120, antialias=(0.3, 3)).image
    centres = run_povray(SEED, 160, 120).image
    ours = np.asarray(render(scene, width=160, height=120, adaptive=(0.3, 3)))
    # with POV-Ray's scan-order rule (render._scan_flags) the same pixels are refined: 88 dB
    # (the rule of both sides of a difference of centres: 49.6 dB, of plain sums: 47.6 dB); its
    # centre samples alone are 37.8 dB from its adaptive image
    assert psnr(ours, pov) > 80.0
    assert psnr(ours, pov) > psnr(centres, pov) + 40.0


STEP = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, -10> direction z up y*2 right x*8 }}
box {{ <-10, -10, 0>, <0.25, 10, 1> pigment {{ rgb {a} }} finish {{ ambient 1 diffuse 0 }} }}
box {{ <0.25, -10, 0>, <10, 10, 1> pigment {{ rgb {b} }} finish {{ ambient 1 diffuse 0 }} }}
"""


@pytest.mark.povray
@pytest.mark.slow  # ~2 s: four renders, two of them POV-Ray's
def test_colours_are_compared_as_povray_compares_them(tmp_path):
    """Grey a left of grey b, the step a quarter into the pixel right of the centre line: that
    pixel is refined (its grid sees a) when 3·(b^(1/2.5) − a^(1/2.5)) ≥ 0.3, POV-Ray's rule
    (Antialias_Gamma 2.5), not when the plain sum 3·(b − a) is: each pair falls on opposite
    sides of the two rules, one each way. POV-Ray's image decides too."""
    from validation.povray import run_povray

    for a, b in [(0.5, 0.66), (0.05, 0.11)]:
        want = 3 * (b ** 0.4 - a ** 0.4) >= 0.3
        assert want != (3 * (b - a) >= 0.3)
        path = tmp_path / f"step{a}_{b}.pov"
        path.write_text(STEP.format(a=a, b=b))
        ours = np.asarray(render(load_scene(path), width=8, height=2, adaptive=(0.3, 3)))[0, 4, 0]
        pov = run_povray(path, 8, 2, antialias=(0.3, 3)).image[0, 4, 0]
        assert (abs(ours - b) > 1e-3) == want, (a, b, ours)
        assert (abs(pov - b) > 1e-3) == want, (a, b, pov)


def test_native_and_jax_rules_are_the_plain_loop():
    """The rule on random colours (flat patches, edges, refined values that differ from their
    centres; a dozen images of 1×1 to 19×13; thresholds 0 to 0.6): the native loop
    (``_native/antialias.cc``, under jit as in a pass's program) and the JAX program both flag what
    a loop over the pixels in scan order flags."""
    adaptive = importlib.import_module("raytracer._adaptive")
    rng = np.random.default_rng(27)

    def plain(c, a, threshold):
        h, w = c.shape[:2]
        flag = np.zeros((h, w), bool)
        for y in range(h):
            for x in range(w):
                for ny, nx in ((y, x - 1), (y - 1, x)):
                    if min(ny, nx) >= 0:
                        value = a[ny, nx] if flag[ny, nx] else c[ny, nx]
                        if np.abs(c[y, x] - value).sum() >= threshold:
                            flag[y, x] = flag[ny, nx] = True
        return flag

    flagged = 0
    rule = jax.jit(adaptive._rule, static_argnames="native")
    for k in range(12):
        h, w = ((1, 1), (7, 5), (19, 13), (12, 17))[k % 4]  # a program per size for the JAX rule
        patches = np.round(rng.random((h, w, 3)) * 4) / 4  # flat colours: equal neighbours
        c = (patches * (rng.random((h, w, 1)) > rng.random())).astype(np.float32)
        a = np.where(rng.random((h, w, 1)) > 0.5, rng.random((h, w, 3)), c).astype(np.float32)
        threshold = float(rng.choice([0.0, 0.1, 0.3, 0.6]))
        want = plain(np.float64(c), np.float64(a), threshold)
        flagged += want.sum()
        for native in (True, False):
            got = np.asarray(rule(c, a, threshold, native=native))
            np.testing.assert_array_equal(got, want, err_msg=f"native={native}")
    assert flagged > 150  # the cases flag pixels (and leave others)


@pytest.mark.parametrize("gamma", [0, -1.0, float("inf"), "2"])
def test_a_bad_gamma_is_refused(scene, gamma):
    with pytest.raises(ValueError, match="gamma"):
        render(scene, width=W, height=H, adaptive=(0.3, 2, gamma))
