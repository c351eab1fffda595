"""Pattern values: hand-computed points, POV-Ray renders (exact for the deterministic patterns, by
statistics for the noise family), finite gradients, dtypes and vmap consistency.

POV-Ray comparisons render a plane z = 0 (or y = 0) seen straight on by an orthographic camera, with
the pattern through a black→white colour map, ``ambient 1 diffuse 0``: pixel (i, j) then shows the
pattern at the pixel centre, which we evaluate directly and push through POV's chain (semantics §5.2).
"""

from __future__ import annotations

import math

import jax
import jax.extend
import jax.numpy as jnp
import numpy as np
import pytest
from shapes._derivatives import assert_derivatives_match_fd

import raytracer.patterns as P

GREY_MAP = "color_map { [0 rgb 0] [1 rgb 1] }"
EXR_FLOOR = 5e-4  # half-float EXR precision, semantics §3.2


def value(name, p, vector=(1.0, 0.0, 0.0), turbulence=None, octaves=6, **kw):
    return float(P.pattern_value(name, jnp.asarray(p, jnp.float32), jnp.asarray(vector, jnp.float32),
                                 turbulence, octaves, 0.5, 2.0, **kw))


# --------------------------------------------------------------------------------------------------
# Hand-computed values


@pytest.mark.parametrize(("p", "expected"), [
    ((0.5, 0.5, 0.5), 0.0),
    ((1.5, 0.5, 0.5), 1.0),
    ((-0.5, 0.5, 0.5), 1.0),  # floor(-0.5) = -1: odd
    ((-0.5, -0.5, 0.5), 0.0),
    ((1.0, 0.0, 0.0), 1.0),  # an integer face belongs to the upper cell
    ((-1e-12, 0.5, 0.5), 0.0),  # the 1e-10 nudge moves a hair below 0 into cell 0
])
def test_checker_parity_of_the_cell_sum(p, expected):
    assert value("checker", p) == expected


def test_gradient_normalises_the_vector_and_wraps_only_above_one():
    assert value("gradient", (0.25, 9.0, 9.0), vector=(2.0, 0.0, 0.0)) == pytest.approx(0.25)
    assert value("gradient", (2.75, 0.0, 0.0), vector=(3.0, 0.0, 0.0)) == pytest.approx(0.75, abs=1e-6)
    assert value("gradient", (-0.25, 0.0, 0.0)) == pytest.approx(-0.25)  # the caller's fmod wraps it
    diagonal = value("gradient", (1.0, 1.0, 0.0), vector=(1.0, 1.0, 0.0))
    assert diagonal == pytest.approx(math.sqrt(2) - 1, abs=1e-6)


@pytest.mark.parametrize(("p", "expected"), [
    ((1.0, 0.0, 0.0), 0.0), ((0.0, 0.0, -1.0), 0.25), ((-1.0, 0.0, 0.0), 0.5), ((0.0, 5.0, 1.0), 0.75),
    ((1.0, 0.0, -1.0), 0.125),
])
def test_radial_turns_from_plus_x_through_minus_z(p, expected):
    # POV-Ray manual, Radial Pattern: 0 at +x, 0.25 at -z, 0.5 at -x, 0.75 at +z.
    assert value("radial", p) == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize(("name", "p", "expected"), [
    ("onion", (3.0, 4.0, 0.0), 0.0),  # |p| = 5
    ("onion", (0.0, 1.2, 0.0), 0.2),
    ("spherical", (0.3, 0.0, 0.4), 0.5),
    ("spherical", (3.0, 0.0, 0.0), 0.0),
    ("cylindrical", (0.3, 100.0, 0.4), 0.5),
    ("planar", (7.0, -0.25, 7.0), 0.75),
    ("boxed", (0.1, -0.6, 0.3), 0.4),
    ("leopard", (math.pi / 2, math.pi / 2, math.pi / 2), 1.0),  # ((1 + 1 + 1)/3)²
    ("leopard", (math.pi / 2, 0.0, 0.0), 1.0 / 9.0),
])
def test_closed_form_patterns(name, p, expected):
    assert value(name, p) == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize(("x", "z", "expected"), [
    (0.0, 0.0, 0), (0.9, 0.0, 0), (0.0, 0.8, 0),
    (0.0, math.sqrt(3), 1),  # COLOR_2 in +z
    # the six neighbours alternate COLOR_2 / COLOR_3 going round: +z 1, then clockwise 2, 1, 2, 1, 2
    (1.5, math.sqrt(3) / 2, 2), (1.5, -math.sqrt(3) / 2, 1), (0.0, -math.sqrt(3), 2),
    (-1.5, -math.sqrt(3) / 2, 1), (-1.5, math.sqrt(3) / 2, 2),
    (3.0, 0.0, 0), (4.5, math.sqrt(3) / 2, 2),  # further out the lattice repeats with period 3
])
def test_hexagon_colour_index(x, z, expected):
    for y in (0.0, -17.5):  # rods along y
        assert value("hexagon", (x, y, z)) == expected


@pytest.mark.parametrize(("p", "expected"), [
    ((1.0, 1.0, 1.0), 1.0),  # row 0: z shifted by 2.25 -> 3.25, inside the brick
    ((7.7, 1.0, 1.0), 0.0),  # x in the last 0.5 of the 8-unit cell
    ((1.0, 2.7, 1.0), 0.0),  # y in the mortar between rows
    ((1.0, 1.0, 1.9), 0.0),  # z + 2.25 = 4.15 in the last 0.5 of 4.5
    ((3.7, 4.0, 0.0), 0.0),  # row 1: x shifted by 4 -> 7.7
    ((7.7, 4.0, 0.0), 1.0),
    ((-0.2, 1.0, 1.0), 0.0),  # x mod 8 = 7.8
])
def test_brick_mortar_is_the_last_half_unit_of_each_cell(p, expected):
    assert value("brick", p) == expected


@pytest.mark.parametrize(("wave", "v", "expected"), [
    ("ramp", 0.3, 0.3), ("triangle", 0.25, 0.5), ("triangle", 0.75, 0.5), ("sine", 0.25, 1.0),
    ("sine", 0.0, 0.5), ("scallop", 0.5, 1.0), ("cubic", 0.5, 0.5), ("cubic", 0.25, 0.15625),
    ("poly", 0.5, 0.5),
])
def test_wave_functions(wave, v, expected):
    assert float(P.apply_wave(jnp.float32(v), wave)) == pytest.approx(expected, abs=1e-6)


def test_poly_wave_exponent():
    assert float(P.apply_wave(jnp.float32(0.5), "poly", exponent=2.0)) == pytest.approx(0.25)


def test_registry_names_the_discrete_and_triangle_patterns():
    assert {"checker", "hexagon", "brick"} == P.DISCRETE
    assert P.REGISTRY["marble"].default_wave == P.REGISTRY["wood"].default_wave == "triangle"
    assert P.REGISTRY["gradient"].default_wave == P.REGISTRY["bozo"].default_wave == "ramp"
    assert P.DISCRETE <= P.RENDERED <= set(P.REGISTRY)


def test_marble_and_wood_without_turbulence_are_plain_distances():
    assert value("marble", (0.3, 5.0, 5.0)) == pytest.approx(0.3)
    assert value("wood", (3.0, 4.0, 9.0)) == pytest.approx(5.0)  # rings round the z axis


def test_turbulence_warps_ordinary_patterns():
    p, t = jnp.array([0.3, 0.2, 0.1]), jnp.array([0.5, 0.5, 0.5])
    warped = p + jax.jit(P.dturbulence, static_argnums=1)(p, 2, 0.5, 2.0) * t
    got = jax.jit(lambda p, t: P.pattern_value("spherical", p, jnp.zeros(3), t, 2, 0.5, 2.0))(p, t)
    assert float(got) == pytest.approx(1.0 - float(jnp.linalg.norm(warped)), abs=1e-6)


# --------------------------------------------------------------------------------------------------
# Noise: range, statistics, smoothness


def _random_points(n, seed=0, scale=50.0):
    return jnp.asarray(np.random.default_rng(seed).uniform(-scale, scale, size=(n, 3)), jnp.float32)


def test_noise_range_and_moments_match_povray_measurements():
    # POV-Ray 3.7 bozo (generator 2), measured on a 640×480 render: mean 0.506, std 0.117, range
    # [0.108, 0.955]; see test_noise_patterns_match_povray_statistics for the live comparison.
    n = np.asarray(jax.jit(jax.vmap(P.noise))(_random_points(20000)))
    assert n.min() >= 0.0 and n.max() <= 1.0
    assert n.mean() == pytest.approx(0.506, abs=0.01)
    assert n.std() == pytest.approx(0.117, rel=0.08)
    assert n.min() < 0.2 and n.max() > 0.8


def test_dnoise_components_are_centred_with_povray_spread():
    # POV's DNoise, measured through a gradient + turbulence warp: std 0.242 per component.
    d = np.asarray(jax.jit(jax.vmap(P.dnoise))(_random_points(20000, seed=1)))
    assert np.abs(d).max() < 1.2
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.02)
    np.testing.assert_allclose(d.std(axis=0), 0.242, rtol=0.1)
    assert abs(np.corrcoef(d.T)[0, 1]) < 0.05  # independent components


def test_noise_is_deterministic_and_continuous_across_cell_faces():
    """Both sides of cell faces, the coordinate planes (where the lattice index changes sign) and the
    lattice's period among them: the noise and its vector twin differ by the slope times the step."""
    with jax.enable_x64(True):
        both = jax.jit(jax.vmap(lambda q: jnp.concatenate([P.noise(q)[None], P.dnoise(q)])))
        faces = jnp.array([[3.0, -2.0, 7.0], [0.0, 0.3, 0.7], [0.3, 0.0, 0.7], [0.3, 0.7, 0.0],
                           [0.0, 0.0, 0.0], [-65536.0, 0.3, 0.7], [65536.0, 0.3, 0.7]])
        for step in (1e-9, 1e-6):
            e = step * jnp.eye(3)
            for p in faces:
                plus, minus, again = both(p[None, :] + e), both(p[None, :] - e), both(p[None, :] + e)
                np.testing.assert_array_equal(plus, again)
                np.testing.assert_allclose(plus, minus, atol=20 * step, err_msg=str(p))


def test_turbulence_with_one_octave_is_the_clamped_noise():
    @jax.jit
    def parts(p):
        return (P.noise(p), P.noise(2.0 * p), P.turbulence(p, 1, 0.5, 2.0), P.turbulence(p, 2, 0.5, 2.0),
                P.dturbulence(p, 1, 0.5, 2.0), P.dnoise(p))

    n1, n2, t1, t2, dt1, dn = parts(jnp.array([0.7, 1.3, -2.2]))
    expected = float(jnp.clip(2.0 * n1 - 0.5, 0.0, 1.0))
    assert float(t1) == pytest.approx(expected)
    np.testing.assert_allclose(dt1, dn)
    # a second octave adds ω·(2N(λp) - 0.5)
    assert float(t2) == pytest.approx(expected + 0.5 * (2.0 * float(n2) - 0.5), abs=1e-6)


def _equations(jaxpr) -> int:
    return sum(1 + sum(_equations(j) for j in jax.extend.core.jaxprs_in_params(e.params)) for e in jaxpr.eqns)


def test_turbulence_sums_its_octaves_and_traces_the_noise_once(x64):
    """Σ ωⁱ (2N(λⁱp) - 0.5) and Σ ωⁱ DNoise(λⁱp) (first scalar term clamped), against the noise
    evaluated octave by octave, for ω and λ that are not powers of two; and the program does not
    hold a copy of the lattice per octave (POV-Ray's 6 octaves made 6 copies)."""
    p = jnp.array([0.37, -1.21, 2.05])
    omega, lam = 0.63, 2.3
    noise = [float(P.noise(lam ** i * p)) for i in range(6)]
    dnoise = [np.asarray(P.dnoise(lam ** i * p)) for i in range(6)]
    scalar = float(np.clip(2 * noise[0] - 0.5, 0, 1))
    scalar += sum(omega ** i * (2 * noise[i] - 0.5) for i in range(1, 6))
    assert float(P.turbulence(p, 6, omega, lam)) == pytest.approx(scalar, rel=1e-12)
    np.testing.assert_allclose(P.dturbulence(p, 6, omega, lam), sum(omega ** i * dnoise[i] for i in range(6)),
                               rtol=1e-12)

    def size(fn, octaves):
        return _equations(jax.make_jaxpr(lambda q: fn(q, octaves, omega, lam))(p).jaxpr)

    one_octave = _equations(jax.make_jaxpr(P.dnoise)(p).jaxpr)
    for fn in (P.turbulence, P.dturbulence):
        assert size(fn, 8) - size(fn, 2) < one_octave  # six more octaves: less than one more lattice


# --------------------------------------------------------------------------------------------------
# Numerics: finite gradients, dtypes, vmap

DEGENERATE_POINTS = jnp.asarray([(0.0, 0.0, 0.0), (1.0, 2.0, -3.0), (0.0, 5.0, 0.0), (1.0, 0.0, 0.0),
                                 (0.5, 0.5, 0.5), (1e-30, 0.0, -1e-30)], jnp.float32)
DEGENERATE_VECTORS = jnp.asarray([(1.0, 0.0, 0.0), (0.0, 0.0, 0.0)] * 3, jnp.float32)  # incl. zero


def _values_and_gradients(names, turbulence):
    """Values and gradients (w.r.t. p and vector) of several patterns at degenerate points; one jit."""
    t = None if turbulence is None else jnp.asarray(turbulence, jnp.float32)

    def one(p, vector):
        fs = [lambda p, v, n=n: P.pattern_value(n, p, v, t, 2, 0.5, 2.0) for n in names]
        return jnp.stack([jnp.stack([f(p, vector), *jax.grad(f, argnums=(0, 1))(p, vector)[0],
                                     *jax.grad(f, argnums=(0, 1))(p, vector)[1]]) for f in fs])

    return np.asarray(jax.jit(jax.vmap(one))(DEGENERATE_POINTS, DEGENERATE_VECTORS))


def test_values_and_gradients_are_finite_at_degenerate_points():
    # origin (sqrt, atan2, norms), lattice points, integer faces, a zero gradient vector
    names = sorted(P.RENDERED - {"granite", "wrinkles", "agate", "dents", "spotted", "bumps", "waves"})
    out = _values_and_gradients(names, None)
    bad = [n for n, ok in zip(names, np.isfinite(out).all(axis=(0, 2)), strict=True) if not ok]
    assert not bad


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(P.RENDERED))
@pytest.mark.parametrize("turbulence", [None, (0.4, 0.3, 0.2)])
def test_values_and_gradients_are_finite_for_every_pattern_and_turbulence(name, turbulence):
    assert np.isfinite(_values_and_gradients([name], turbulence)).all()


FD_FAST = ["spherical", "leopard", "radial", "gradient"]
FD_SLOW = ["wood", "cylindrical", "onion", "bozo", "granite", "marble", "agate", "wrinkles", "ripples",
           "waves", "crackle"]


@pytest.mark.parametrize("name", FD_FAST + [pytest.param(n, marks=pytest.mark.slow) for n in FD_SLOW])
def test_gradients_match_finite_differences_in_float64(name):
    with jax.enable_x64(True):
        turb = jnp.array([0.3, 0.2, 0.1]) if name in ("marble", "wood", "bozo") else None
        octaves = 1 if name == "wood" else 2

        def f(p, vector):
            return P.pattern_value(name, p, vector, turb, octaves, 0.5, 2.0)

        p = jnp.array([0.37, 0.21, -0.43])
        assert_derivatives_match_fd(f, (p, jnp.array([0.6, 0.3, 0.2])), h=1e-6, atol=1e-4, rtol=1e-4)


def test_float32_stays_float32_and_vmap_matches_the_loop():
    pts = _random_points(4, seed=3, scale=3.0)
    vec = jnp.array([1.0, 2.0, 0.5], jnp.float32)
    names = sorted(P.RENDERED - {"granite", "wrinkles", "agate"})

    def f(p):
        return jnp.stack([P.pattern_value(n, p, vec, None, 2, 0.5, 2.0) for n in names])

    batched = jax.jit(jax.vmap(f))(pts)
    assert batched.dtype == jnp.float32
    looped = np.stack([np.asarray(jax.jit(f)(q)) for q in pts])
    np.testing.assert_allclose(batched, looped, rtol=1e-6, atol=1e-6)


def test_float64_stays_float64():
    with jax.enable_x64(True):
        assert P.pattern_value("granite", jnp.array([0.1, 0.2, 0.3]), jnp.ones(3), None).dtype == jnp.float64
        assert P.dnoise(jnp.array([0.1, 0.2, 0.3])).dtype == jnp.float64


# --------------------------------------------------------------------------------------------------
# POV-Ray renders


def _povray_plane(pigment, *, plane, cx, cy, w, h, width, height):
    """POV render of ``pigment`` on the plane z = 0 ("xy") or y = 0 ("xz"); returns the red channel."""
    from validation.povray import render_povray

    if plane == "xy":
        camera = f"camera {{ orthographic location <{cx},{cy},-10> direction z right x*{w} up y*{h} }}"
        obj = "plane { z, 0"
    else:
        camera = f"camera {{ orthographic location <{cx},10,{cy}> direction -y right x*{w} up z*{h} }}"
        obj = "plane { y, 0"
    scene = f"""#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
{camera}
{obj} texture {{ pigment {{ {pigment} }} finish {{ ambient 1 diffuse 0 }} }} }}
"""
    return np.asarray(render_povray(scene, width, height)[..., 0], np.float64)


def _pixel_points(*, plane, cx, cy, w, h, width, height, dx=0.0, dy=0.0):
    """The plane point each pixel centre sees (semantics §1.2), optionally shifted by (dx, dy) pixels."""
    x = cx + ((np.arange(width) + 0.5 + dx) / width - 0.5) * w
    y = cy + (0.5 - (np.arange(height) + 0.5 + dy) / height) * h
    gx, gy = np.meshgrid(x, y)
    zero = np.zeros_like(gx)
    return np.stack([gx, gy, zero] if plane == "xy" else [gx, zero, gy], axis=-1)


def _pov_chain(v, frequency=1.0, phase=0.0, wave="ramp"):
    """POV's map chain (semantics §5.2) for a black→white colour map."""
    v = np.fmod(v * frequency + phase, 1.00001)
    v = np.where(v < 0, v - np.floor(v), v)
    return np.clip(np.asarray(P.apply_wave(jnp.asarray(v), wave)), 0.0, 1.0)


# name, POV pigment, plane, centre, vector, chain (None = discrete with n colours rgb 0 .. 1)
EXACT_CASES = [
    ("checker", "checker rgb 0, rgb 1", "xy", (0.3, 0.2), None, 2),
    ("gradient", f"gradient <1, 2, 0.5> {GREY_MAP}", "xy", (0.1, -0.3), (1.0, 2.0, 0.5), {}),
    ("gradient", f"gradient y {GREY_MAP} frequency 2 phase 0.3 sine_wave", "xy", (0.1, -0.3), (0.0, 1.0, 0.0),
     dict(frequency=2.0, phase=0.3, wave="sine")),
    ("radial", f"radial {GREY_MAP} frequency 3 phase 0.2", "xz", (0.05, 0.1), None,
     dict(frequency=3.0, phase=0.2)),
    ("onion", f"onion {GREY_MAP}", "xy", (0.3, 0.2), None, {}),
    ("spherical", f"spherical {GREY_MAP} triangle_wave", "xy", (0.1, 0.05), None, dict(wave="triangle")),
    ("cylindrical", f"cylindrical {GREY_MAP}", "xz", (0.1, 0.05), None, {}),
    ("planar", f"planar {GREY_MAP} cubic_wave", "xy", (0.1, 0.05), None, dict(wave="cubic")),
    ("boxed", f"boxed {GREY_MAP} scallop_wave", "xy", (0.1, 0.05), None, dict(wave="scallop")),
    ("leopard", f"leopard {GREY_MAP}", "xz", (3.1, -2.05), None, {}),
    ("hexagon", "hexagon rgb 0, rgb 0.5, rgb 1", "xz", (0.13, 0.21), None, 3),
    ("brick", "brick rgb 0, rgb 1", "xy", (0.3, 0.2), None, 2),
    ("brick", "brick rgb 0, rgb 1", "xz", (-1.1, 0.7), None, 2),
]


@pytest.mark.povray
@pytest.mark.parametrize(("name", "pigment", "plane", "centre", "vector", "chain"), EXACT_CASES,
                         ids=[f"{c[0]}-{i}" for i, c in enumerate(EXACT_CASES)])
def test_deterministic_patterns_match_povray_renders(name, pigment, plane, centre, vector, chain):
    view = dict(plane=plane, cx=centre[0], cy=centre[1], w=16.0, h=12.0, width=160, height=120)
    pov = _povray_plane(pigment, **view)
    vec = jnp.asarray(vector or (1.0, 0.0, 0.0))

    def ours(dx=0.0, dy=0.0):
        with jax.enable_x64(True):
            pts = jnp.asarray(_pixel_points(**view, dx=dx, dy=dy).reshape(-1, 3))
            v = np.asarray(jax.jit(jax.vmap(lambda q: P.pattern_value(name, q, vec, None)))(pts))
        v = v.reshape(pov.shape)
        return v / (chain - 1) if isinstance(chain, int) else _pov_chain(v, **chain)

    got = ours()
    err = np.abs(got - pov)
    # A pixel may straddle a discontinuity (cell edge, wrap of fmod): excuse pixels where the mapped
    # value jumps by more than 0.1 within ±0.05 pixel of the centre; POV and we may round differently.
    near = np.stack([ours(dx, dy) for dx, dy in ((-0.05, 0), (0.05, 0), (0, -0.05), (0, 0.05))])
    jump = (near.max(axis=0) - near.min(axis=0)) > 0.1
    assert jump.mean() < 0.08  # only cell edges are excused, never a whole region
    assert err[~jump].max() < EXR_FLOOR, f"{name}: max error {err[~jump].max():.2e}"


def _stats(v, step):
    v = np.asarray(v, np.float64)
    vc = v - v.mean()
    lag = int(round(0.5 / step))
    return dict(mean=v.mean(), std=v.std(), ac_half=(vc[:, lag:] * vc[:, :-lag]).mean() / vc.var())


# name, POV pigment (black→white map, ramp wave so the raw value shows), our turbulence,
# tolerances (mean abs, std rel, autocorrelation at ½ unit abs).
STAT_CASES = [
    ("bozo", "bozo", None, (0.02, 0.10, 0.06)),
    ("granite", "granite", None, (0.03, 0.10, 0.06)),
    ("dents", "dents", None, (0.02, 0.10, 0.06)),
    ("wrinkles", "wrinkles", None, (0.02, 0.10, 0.06)),
    ("agate", "agate", None, (0.03, 0.10, 0.08)),
    ("marble", "marble turbulence 0.6 ramp_wave", (0.6, 0.6, 0.6), (0.03, 0.10, 0.10)),
    ("wood", "wood turbulence 0.08 ramp_wave", (0.08, 0.08, 0.08), (0.03, 0.10, 0.15)),
    # POV-Ray's turbulent bozo decorrelates faster than ours: autocorrelation at ½ unit 0.37 against
    # 0.45, the same in four regions (around the origin and 100-1,000 units away), although the warp
    # alone (gradient x turbulence, 1-6 octaves) matches POV-Ray's spread and correlation; open
    ("bozo", "bozo turbulence 0.8", (0.8, 0.8, 0.8), (0.02, 0.10, 0.10)),
    ("ripples", "ripples", None, (0.02, 0.10, 0.15)),
    ("waves", "waves", None, (0.02, 0.15, 0.15)),
    # one random point per unit cube (ours) gives POV-Ray's Voronoi distances: at 320×240 mean 0.191
    # against 0.186, std 0.152 against 0.147
    ("crackle", "crackle", None, (0.02, 0.10, 0.06)),
    ("cells", "cells", None, (0.03, 0.10, 0.10)),
]


@pytest.mark.povray
@pytest.mark.slow
@pytest.mark.parametrize(("name", "pigment", "turb", "tol"), STAT_CASES, ids=[c[1] for c in STAT_CASES])
def test_noise_patterns_match_povray_statistics(name, pigment, turb, tol):
    """Our noise is not POV's (AGPL rule): compare mean, spread and correlation length, not pixels."""
    # 32 × 24 units at 0.1 unit per pixel, on the plane z = 0.37 (off the noise lattice).
    view = dict(plane="xy", cx=0.31, cy=0.17, w=32.0, h=24.0, width=320, height=240)
    pov = _povray_plane(f"{pigment} {GREY_MAP} translate <0, 0, -0.37>", **view)
    pts = _pixel_points(**view).reshape(-1, 3) + np.array([0.0, 0.0, 0.37])
    t = None if turb is None else jnp.asarray(turb, jnp.float32)
    v = jax.jit(jax.vmap(lambda q: P.pattern_value(name, q, jnp.ones(3), t)))(jnp.asarray(pts, jnp.float32))
    ours = _pov_chain(np.asarray(v, np.float64).reshape(pov.shape))
    s_pov, s_ours = _stats(pov, 0.1), _stats(ours, 0.1)
    assert s_ours["mean"] == pytest.approx(s_pov["mean"], abs=tol[0]), (s_ours, s_pov)
    assert s_ours["std"] == pytest.approx(s_pov["std"], rel=tol[1]), (s_ours, s_pov)
    assert s_ours["ac_half"] == pytest.approx(s_pov["ac_half"], abs=tol[2]), (s_ours, s_pov)


# --------------------------------------------------------------------------------------------------
# Discrete patterns choose a list entry


DISCRETE_WALL = """
camera { orthographic location <0, 0, -5> look_at 0 right x*6 up y*4 }
box { <-3, -2, 0>, <-1, 2, 1> pigment { checker rgb <0.9, 0.2, 0.1>, rgb <0.1, 0.3, 0.8> scale 0.7 }
      finish { ambient 1 diffuse 0 } }
box { <-1, -2, 0>, <1, 2, 1> pigment { hexagon rgb <0.2, 0.8, 0.3>, rgb <0.7, 0.6, 0.1>,
                                       rgb <0.5, 0.1, 0.6> rotate -90*x scale 0.6 }
      finish { ambient 1 diffuse 0 } }
box { <1, -2, 0>, <3, 2, 1> pigment { brick rgb <0.8, 0.8, 0.7>, rgb <0.6, 0.2, 0.1> scale 0.15 }
      finish { ambient 1 diffuse 0 } }
"""


def test_discrete_pattern_colour_has_no_derivative_through_map_positions(x64):
    # checker, hexagon and brick pick their list entry by integer index; their
    # colour was a colour map over positions that were parameters, with a kink at them, so a JVP
    # moving the positions disagreed with central differences on every pixel of the pattern
    import equinox as eqx

    import raytracer as rt
    from raytracer import params

    scene = rt.load_scene(DISCRETE_WALL)
    p, rest = eqx.partition(scene, eqx.is_inexact_array)

    def image(q):
        return rt.render(eqx.combine(q, rest), width=6, height=4)

    names = [n for n in params.parameters(p) if n.endswith((".pigment.values", ".pigment.colors"))]
    assert len(names) == 6
    t = params.random_tangent(p, jax.random.PRNGKey(0), names)
    run = jax.jit(lambda q, t: jax.jvp(image, (q,), (t,)))
    _, jvp = run(p, t)

    def shifted(h):
        return run(jax.tree_util.tree_map(lambda a, b: a + h * b, p, t), t)[0]

    h = 1e-6
    fd = (np.asarray(shifted(h)) - np.asarray(shifted(-h))) / (2 * h)
    assert np.abs(jvp).max(axis=-1).min() > 0.05  # every pixel is a pattern pixel
    np.testing.assert_allclose(np.asarray(jvp), fd, atol=1e-7)
