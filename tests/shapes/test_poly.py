"""Polynomial surfaces (``quartic``, ``cubic``, ``poly``, ``polynomial``): crossings against the torus
kernel and numpy's companion-matrix roots of the polynomial along the ray (float64), POV-Ray's order of
coefficients written out by hand, and the four syntaxes."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer._plan import make_plan
from raytracer.errors import SceneError
from raytracer.shading import _accel
from raytracer.shading._geometry import pack_geometry
from raytracer.shapes import REGISTRY, Poly, Torus
from raytracer.shapes._poly import TERMS, poly_hits, quartic_coefficients

from ._case import Case, numeric_gradient


def torus_quartic(major, minor):
    """POV-Ray's 35 coefficients of ``(x² + y² + z² + R² - r²)² - 4R² (x² + z²)`` (pawns.pov's form),
    written out by hand in the manual's order (A1 = x⁴, A5 = x²y², A8 = x²z², A10 = x², A21 = y⁴,
    A24 = y²z², A26 = y², A31 = z⁴, A33 = z², A35 = 1)."""
    e = major**2 - minor**2
    a = np.zeros(35)
    a[[0, 20, 30]] = 1.0
    a[[4, 7, 23]] = 2.0
    a[9] = a[32] = 2 * e - 4 * major**2
    a[25] = 2 * e
    a[34] = e * e
    return a


def numpy_value(coeffs, p):
    """The polynomial at p, term by term from the exponents of each coefficient (float64)."""
    x, y, z = np.asarray(p, np.float64)
    return sum(c * x**i * y**j * z**k for c, (i, j, k) in zip(coeffs, TERMS, strict=True))


def numpy_roots(coeffs, o, d):
    """Real roots in t of P(o + t d): the polynomial along the ray expanded in numpy (float64)."""
    o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
    # (o_a + t d_a)^p for each axis a and power p ≤ 4, highest power of t first, padded to 5
    powers = np.zeros((3, 5, 5))
    powers[:, 0, 4] = 1
    for p in range(1, 5):
        powers[:, p, :4] = powers[:, p - 1, 1:] * d[:, None]
        powers[:, p] += powers[:, p - 1] * o[:, None]
    total = np.zeros(5)
    for c, (i, j, k) in zip(coeffs, TERMS, strict=True):
        if c:
            total += c * np.convolve(np.convolve(powers[0, i], powers[1, j]), powers[2, k])[-5:]
    total = np.trim_zeros(total, "f")
    roots = np.roots(total) if len(total) > 1 else np.array([])
    real = np.sort(roots[np.abs(roots.imag) < 1e-9].real)
    others = roots[np.abs(roots.imag) >= 1e-9]
    separated = len(real) < 2 or np.min(np.diff(real)) > 1e-3
    return real, bool(separated and np.all(np.abs(others.imag) > 1e-3))


@functools.cache
def _batched():
    return jax.jit(jax.vmap(poly_hits, in_axes=(None, 0, 0)))


def _finite_sorted(t):
    return [np.sort(row[np.isfinite(row)]) for row in np.asarray(t, np.float64)]


def test_the_manuals_order_of_terms():
    assert len(TERMS) == 35 and TERMS[:4] == ((4, 0, 0), (3, 1, 0), (3, 0, 1), (3, 0, 0))
    assert TERMS[9] == (2, 0, 0) and TERMS[20] == (0, 4, 0) and TERMS[34] == (0, 0, 0)
    # a cubic's A4 is x² and A11 y³ (its 20 terms); an order-2 poly's A10 is the constant
    for order, a, term in ((3, 3, (2, 0, 0)), (3, 10, (0, 3, 0)), (2, 9, (0, 0, 0))):
        one = quartic_coefficients(order, np.eye(10 if order == 2 else 20)[a])
        np.testing.assert_array_equal(np.flatnonzero(one), [TERMS.index(term)])


def test_a_quartic_torus_is_crossed_where_the_torus_is(x64):
    """pawns.pov's torus as a quartic: the crossings and normals of the torus kernel, for random rays
    (the two kernels share nothing but ``solve_quartic``'s bracketing)."""
    rng = np.random.default_rng(2)
    o = rng.normal(size=(200, 3)) * 60
    d = rng.uniform(-1, 1, size=(200, 3)) * 27 - o
    t, n = _batched()(jnp.asarray(torus_quartic(15.0, 12.0)), jnp.asarray(o), jnp.asarray(d))
    t_ref, n_ref = jax.jit(jax.vmap(Torus(15.0, 12.0).hits))(jnp.asarray(o), jnp.asarray(d))
    order, order_ref = np.argsort(np.asarray(t), axis=1), np.argsort(np.asarray(t_ref), axis=1)
    t = np.take_along_axis(np.asarray(t), order, 1)
    t_ref = np.take_along_axis(np.asarray(t_ref), order_ref, 1)
    np.testing.assert_array_equal(np.isfinite(t), np.isfinite(t_ref))
    assert np.isfinite(t).sum() > 200
    hit = np.isfinite(t)
    np.testing.assert_allclose(t[hit], t_ref[hit], rtol=1e-10)
    n = np.take_along_axis(np.asarray(n), order[..., None], 1)
    n_ref = np.take_along_axis(np.asarray(n_ref), order_ref[..., None], 1)
    np.testing.assert_allclose(n[hit], n_ref[hit], atol=1e-9)


@pytest.mark.parametrize("order", [4, 3, 2])
def test_crossings_are_the_roots_along_the_ray(order, x64):
    """Random polynomials of each order (random coefficients of every term; bounded or not), random
    rays: every real root of the polynomial along the ray (numpy, float64) is a crossing."""
    rng = np.random.default_rng(order)
    checked = 0
    for _ in range(12):
        values = rng.normal(size=len([t for t in TERMS if sum(t) <= order]))
        coeffs = quartic_coefficients(order, values)
        o = rng.normal(size=(32, 3)) * 3
        d = rng.normal(size=(32, 3)) * rng.uniform(0.3, 3, size=(32, 1))
        t, _ = _batched()(jnp.asarray(coeffs), jnp.asarray(o), jnp.asarray(d))
        for got, oi, di in zip(_finite_sorted(t), o, d, strict=True):
            want, clean = numpy_roots(coeffs, oi, di)
            if not clean or np.any(np.abs(want) > 1e5):
                continue
            assert len(got) == len(want), (order, values, oi, di, got, want)
            np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-9)
            checked += 1
    assert checked > 250


def test_float32_crossings_lie_on_the_surface():
    """In float32 a crossing of the rounded cube ``x⁴ + y⁴ + z⁴ = 1`` and of the torus is on the
    surface to float32's resolution (|P| / |∇P| small), from rays of far and near origins."""
    rng = np.random.default_rng(4)
    for coeffs in (quartic_coefficients(4, [1.0] + [0] * 19 + [1.0] + [0] * 9 + [1.0] + [0] * 3 + [-1.0]),
                   torus_quartic(1.5, 0.5)):
        o = rng.normal(size=(256, 3)) * rng.choice([3.0, 30.0], size=(256, 1))
        d = rng.uniform(-1.5, 1.5, size=(256, 3)) - o
        t, _ = _batched()(jnp.asarray(coeffs, jnp.float32), jnp.asarray(o, jnp.float32),
                          jnp.asarray(d, jnp.float32))
        t = np.asarray(t, np.float64)
        hits = [(oi + ti * di) for oi, di, row in zip(o, d, t, strict=True) for ti in row[np.isfinite(row)]]
        assert len(hits) > 100
        value_at = functools.partial(numpy_value, coeffs)
        for p in hits:
            value = value_at(p)
            grad = numeric_gradient(value_at, p)
            assert abs(value) / np.linalg.norm(grad) < 5e-5 * (1 + np.linalg.norm(p)), p


def test_the_four_syntaxes_give_one_surface_and_higher_orders_are_left_out(tmp_path):
    """quartic, poly 4 and polynomial 4 (any order of entries) write the same torus; cubic, poly 3
    and polynomial 3 the same saddle; ``sturm`` is accepted; an order above 4 is left out with a
    warning; a wrong number of coefficients is an error at its line and column."""
    torus = ", ".join(f"{v:g}" for v in torus_quartic(2.0, 0.5))
    saddle = "1, 0, 0, 0, 0, 0, 0, 0, 0, 0, -1, 0, 0, 0, 0, 0, 0, 0, -1, 0"  # x³ - y³ - z
    text = f"""camera {{ location <0, 0, -9> look_at 0 }}
quartic {{ <{torus}> sturm }}
poly {{ 4, <{torus}> }}
polynomial {{ 4, xyz(0, 0, 0): 14.0625, xyz(4, 0, 0): 1, xyz(0, 4, 0): 1, xyz(0, 0, 4): 1,
  xyz(2, 2, 0): 2, xyz(2, 0, 2): 2, xyz(0, 2, 2): 2, xyz(2, 0, 0): -8.5, xyz(0, 0, 2): -8.5,
  xyz(0, 2, 0): 7.5 sturm }}
cubic {{ <{saddle}> }}
poly {{ 3, <{saddle}> }}
polynomial {{ 3, xyz(3, 0, 0): 1, xyz(0, 3, 0): -1, xyz(0, 0, 1): -1 }}
poly {{ 5, <{", ".join(["1"] * 56)}> }}
"""
    scene = rt.load_scene(text)
    assert REGISTRY["poly"] is Poly and all(isinstance(o.shape, Poly) for o in scene.objects)
    coeffs = [np.asarray(o.shape.coeffs, np.float64) for o in scene.objects]
    assert len(coeffs) == 6  # the order-5 poly is left out
    for c in coeffs[1:3]:
        np.testing.assert_allclose(c, torus_quartic(2.0, 0.5), rtol=1e-6)
    np.testing.assert_allclose(coeffs[0], torus_quartic(2.0, 0.5), rtol=1e-6)
    np.testing.assert_allclose(coeffs[4], coeffs[3])
    np.testing.assert_allclose(coeffs[5], coeffs[3])
    assert [w.feature for w in scene.warnings] == ["poly"]
    path = tmp_path / "short.pov"
    path.write_text("camera { location <0, 0, -9> look_at 0 }\nquartic { <1, 2, 3> }\n")
    with pytest.raises(SceneError, match=r"short\.pov:2:11: expected 35 coefficients, found 3"):
        rt.load_scene(path)


@pytest.mark.skipif(_accel.unavailable_reason() is not None, reason=str(_accel.unavailable_reason()))
def test_the_hierarchys_solver_finds_the_first_root_of_every_polynomial(x64):
    """The native hierarchy's polynomial kernel (the polynomial along the ray expanded from its 35
    coefficients, its roots isolated between those of its derivatives; two rows of parameters a
    polynomial, each an object of its own with a box of everything): the closest-hit query names
    the polynomial whose first positive root (numpy, float64) is nearest, at that root, for random
    polynomials of orders 2–4 placed by translations and random rays."""
    rng = np.random.default_rng(8)
    shapes, places = [], []
    for i in range(9):
        order = 2 + i % 3
        values = rng.normal(size=len([t for t in TERMS if sum(t) <= order]))
        shapes.append(quartic_coefficients(order, values))
        places.append(rng.uniform(-3, 3, 3))
        numbers, place = ", ".join(f"{v:.17g}" for v in values), ", ".join(map(str, places[-1]))
        shapes[-1] = (shapes[-1], f"poly {{ {order}, <{numbers}> translate <{place}> }}")
    scene = rt.load_scene("camera { location <0, 0, -9> look_at 0 }\n" + "\n".join(s for _, s in shapes))
    geo = pack_geometry(make_plan(scene), jnp.float64)
    assert geo.accel is not None and not any(not g.accelerated for g in geo.groups)  # all held
    rays = 400
    o = rng.normal(size=(rays, 3)) * 4
    d = rng.normal(size=(rays, 3)) * rng.uniform(0.3, 3, size=(rays, 1))
    item, t = _accel._closest_query(geo.accel.tables, jnp.asarray(o), jnp.asarray(d), jnp.zeros(rays),
                                    jnp.full(rays, 1e7), jnp.ones(rays, jnp.int32))
    item = np.asarray(item)
    prim = np.where(item >= 0, np.asarray(geo.accel.item_prim)[np.maximum(item, 0)], -1)
    checked = 0
    for r in range(rays):
        firsts, clean = [], True
        for (coeffs, _), place in zip(shapes, places, strict=True):
            roots, ok = numpy_roots(coeffs, o[r] - place, d[r])
            clean &= ok and not np.any(np.abs(roots) > 1e5)
            positive = roots[roots > 1e-9]
            firsts.append(positive.min() if positive.size else np.inf)
        if not clean:
            continue
        checked += 1
        want = int(np.argmin(firsts)) if np.isfinite(min(firsts)) else -1
        assert prim[r] == want, (r, prim[r], want, firsts)
        if want >= 0:
            np.testing.assert_allclose(float(t[r]), firsts[want], rtol=1e-9)
    assert checked > 250


def test_a_polynomial_refines_a_given_crossing_with_the_kernels_derivatives(x64):
    """``near_hit`` (the hierarchy's crossing with two Newton steps) has the value, the normal and
    the derivatives along random directions of (coefficients, o, d) of the first crossing of the
    shape's own kernel, for random rays through a quartic torus (float64)."""
    rng = np.random.default_rng(6)
    coeffs = jnp.asarray(torus_quartic(1.5, 0.5))

    def first(c, o, d):
        t, n = jax.vmap(Poly(coeffs=c).hits)(o, d)
        return jnp.where(jnp.isfinite(t[:, 0]), t[:, 0], 0.0), n[:, 0]

    def near(t0, c, o, d):
        t, n = jax.vmap(lambda o, d, t0: Poly(coeffs=c).near_hit(o, d, t0))(o, d, t0)
        return t[:, 0], n[:, 0]

    o = jnp.asarray(rng.uniform(-4, 4, (24, 3)))
    d = jnp.asarray(rng.uniform(-1.5, 1.5, (24, 3))) - o
    args = (coeffs, o, d)
    tangent = tuple(jnp.asarray(rng.normal(size=np.shape(x))) for x in args)
    (t0, n0), (dt0, dn0) = jax.jit(lambda a, v: jax.jvp(first, a, v))(args, tangent)
    hit = np.asarray(t0) != 0.0
    assert hit.sum() >= 8
    (t1, n1), (dt1, dn1) = jax.jit(lambda t0, a, v: jax.jvp(lambda *x: near(t0, *x), a, v))(t0, args, tangent)
    np.testing.assert_allclose(np.asarray(t1)[hit], np.asarray(t0)[hit], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(n1)[hit], np.asarray(n0)[hit], atol=1e-9)
    np.testing.assert_allclose(np.asarray(dt1)[hit], np.asarray(dt0)[hit], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(np.asarray(dn1)[hit], np.asarray(dn0)[hit], rtol=1e-6, atol=1e-8)


# ---------------------------------------------------------------- the generic test case
def _torus_case(name, major, minor):
    coeffs = torus_quartic(major, minor)

    def distance(p):  # first-order distance P / |∇P|
        value = lambda q: numpy_value(coeffs, q)  # noqa: E731
        return value(p) / np.linalg.norm(numeric_gradient(value, p))

    return Case(name, Poly, (coeffs,), distance, np.zeros(3), major + minor, convex=False)


# One generic case (each costs a compile of the kernel per generic test): the torus written as a
# quartic, non-convex (four crossings, rays through the hole).
CASES = [_torus_case("quartic torus", 1.5, 0.5)]
