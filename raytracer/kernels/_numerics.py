"""Numerically stable building blocks shared by every intersection kernel.

Every function here returns finite values AND finite gradients for every finite input. The pattern is
the "double where" (JAX FAQ, "Gradients contain NaN where using where"; JAX-MD's ``util.safe_mask``):
first replace the *input* of a partial function (sqrt, division, arccos, pow) by a harmless placeholder
where it is out of domain, then select the *output*. Selecting the output alone is not enough, because
the untaken branch is still differentiated and ``0 * inf = nan`` poisons the cotangent.

Roots that do not exist are ``+inf`` (Mitsuba's convention); callers test ``jnp.isfinite``.

No function here hard-codes a float64 constant: Python scalars are weakly typed, and tolerances are taken
from ``jnp.finfo`` of the input dtype, so float32 stays float32 and float64 stays float64.
"""

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, ArrayLike, Bool, Float

from ._common import vecmat

__all__ = [
    "as_float_arrays",
    "differentiable_root",
    "eps_of",
    "safe_arccos",
    "safe_div",
    "safe_mask",
    "safe_normalize",
    "safe_pow",
    "safe_sqrt",
    "solve_linear",
    "solve_quadratic",
    "solve_quartic",
    "world_normal",
]


def as_float_arrays(*xs: ArrayLike) -> tuple[Array, ...]:
    """Converts the inputs to arrays of one common floating dtype.

    Python floats follow the default dtype (float32, or float64 under ``jax_enable_x64``); an explicit
    float32 or float64 array decides the dtype; integer-only inputs become the default float.
    """
    arrays = [jnp.asarray(x) for x in xs]
    dtype = jnp.result_type(*arrays)
    if not jnp.issubdtype(dtype, jnp.floating):
        dtype = jnp.result_type(float)
    return tuple(a.astype(dtype) for a in arrays)


def eps_of(x: ArrayLike) -> Array:
    """Machine epsilon of ``x``'s floating dtype, as a scalar of that dtype."""
    dtype = jnp.result_type(x)
    return jnp.asarray(jnp.finfo(dtype).eps, dtype)


def _tiny_of(x: ArrayLike) -> Array:
    dtype = jnp.result_type(x)
    return jnp.asarray(jnp.finfo(dtype).tiny, dtype)


def safe_mask(
    mask: ArrayLike,
    fn: Callable[[Array], Array],
    operand: ArrayLike,
    placeholder: ArrayLike = 1.0,
    fallback: ArrayLike = 0.0,
) -> Array:
    """The named "double where": ``fn(operand)`` where ``mask``, else ``fallback``.

    ``fn`` only ever sees ``operand`` where ``mask`` holds and ``placeholder`` elsewhere, so its value
    and its derivative are evaluated at a point of its domain everywhere.

    Args:
        mask: bool, broadcastable to ``operand``: where ``fn`` may be evaluated.
        fn: elementwise function, e.g. ``jnp.sqrt``.
        operand: the input of ``fn``.
        placeholder: a value inside ``fn``'s domain, used where ``mask`` is False.
        fallback: the output where ``mask`` is False.
    """
    guarded = jnp.where(mask, operand, placeholder)
    return jnp.where(mask, fn(guarded), fallback)


def safe_sqrt(x: ArrayLike) -> Array:
    """``sqrt(x)`` for ``x > 0``, else 0; the gradient is 0 (not inf) at and below 0."""
    return safe_mask(x > 0, jnp.sqrt, x)


def safe_div(num: ArrayLike, den: ArrayLike, fallback: ArrayLike = 0.0) -> Array:
    """``num / den`` where ``den != 0``, else ``fallback``; gradients finite everywhere."""
    ok = den != 0
    return jnp.where(ok, num / jnp.where(ok, den, 1.0), fallback)


def safe_normalize(v: Float[Array, "... 3"], fallback: ArrayLike | None = None) -> Float[Array, "... 3"]:
    """``v / |v|`` along the last axis; ``fallback`` (default ``+z``) where ``|v|`` is 0 or denormal.

    ``jnp.linalg.norm`` has a NaN gradient at 0; this does not.
    """
    v = jnp.asarray(v)
    norm_sq = jnp.sum(v * v, axis=-1, keepdims=True)
    ok = norm_sq > _tiny_of(v)
    if fallback is None:
        fallback = jnp.zeros_like(v).at[..., -1].set(1.0)
    return jnp.where(ok, v * lax.rsqrt(jnp.where(ok, norm_sq, 1.0)), fallback)


def safe_arccos(x: ArrayLike) -> Array:
    """``arccos`` of ``x`` clipped to [-1, 1]; the gradient is 0 (not inf) at and beyond +-1."""
    x = jnp.asarray(x)
    interior = jnp.abs(x) < 1
    edge = jnp.where(x > 0, 0.0, jnp.pi).astype(x.dtype)
    return safe_mask(interior, jnp.arccos, x, placeholder=0.0, fallback=edge)


def safe_pow(x: ArrayLike, p: ArrayLike) -> Array:
    """``x ** p`` for ``x > 0``; for ``x <= 0`` it is 0 (1 when ``p == 0``). Gradients finite."""
    ok = x > 0
    powered = jnp.exp(p * jnp.log(jnp.where(ok, x, 1.0)))
    return jnp.where(ok, powered, jnp.where(p == 0, 1.0, 0.0))


def world_normal(n: Float[Array, "... 3"], ofw: Float[Array, "4 4"]) -> Float[Array, "... 3"]:
    """The unit world normal of the object normal ``n`` of a primitive whose ``object_from_world``
    is ``ofw`` (its upper 3×3 is enough): normals transform with the inverse transpose."""
    return safe_normalize(vecmat(n, ofw[:3, :3]))


def solve_linear(a: ArrayLike, b: ArrayLike) -> tuple[Array, Array]:
    """The root of ``a t + b = 0``.

    A root with ``|t| >= 1 / eps`` is treated as no root: there the line is parallel to the surface to
    working precision (float32: ``|t| > 8.4e6``, which is also about POV-Ray's ``MAX_DISTANCE`` of 1e7),
    and the derivative ``dt/da = -t/a`` would overflow.

    Returns:
        ``(t, ok)``: ``t`` is ``-b/a`` where ``ok``, ``+inf`` elsewhere.
    """
    a, b = jnp.asarray(a), jnp.asarray(b)
    ok = jnp.abs(a) > eps_of(a) * jnp.abs(b)
    t = safe_mask(ok, lambda den: -b / den, a, fallback=jnp.inf)
    return t, ok


def _two_sum(a: Array, b: Array) -> tuple[Array, Array]:
    """``a + b`` as ``s + e`` exactly (Knuth's TwoSum: ``s`` the rounded sum, ``e`` its error)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _two_square(a: Array) -> tuple[Array, Array]:
    """``a²`` as ``p + e`` exactly (Dekker's product with Veltkamp's split; no FMA needed)."""
    split = 4097.0 if a.dtype == jnp.float32 else 134217729.0  # 2^ceil(p/2) + 1
    t = split * a
    hi = t - (t - a)
    lo = a - hi
    p = a * a
    return p, ((hi * hi - p) + 2.0 * hi * lo) + lo * lo


def offset_sq_minus(o: Float[Array, "3"], center: Float[Array, "3"], radius: ArrayLike) -> Array:
    """``|o - center|² - radius²`` to the working precision of its result, where the plain formula
    cancels: a ray near a huge sphere (a "ground sphere" ``<0, -1e6-1, 0>, 1e6``) gives
    ``|o - center|² ≈ radius² ≈ 1e12``, whose float32 rounding (~6e4) exceeds the answer (~2e6).

    ``o - center`` is kept with its rounding error (TwoSum), the squares with theirs (Dekker), and
    the terms are added in order of size. Only the value is compensated: the derivative is the plain
    formula's, ``2 (o - center)·d(o - center) - 2 radius·d radius``."""
    radius = jnp.asarray(radius, o.dtype)
    l = o - center
    plain = jnp.dot(l, l) - radius * radius
    hi, lo = _two_sum(o, -center)
    p, e = _two_square(hi)
    pr, er = _two_square(radius)
    total, err = _two_sum(p[0], -pr)
    for x in (p[1], p[2]):
        total, e2 = _two_sum(total, x)
        err = err + e2
    exact = total + (err + jnp.sum(e) - er + jnp.sum(2.0 * hi * lo + lo * lo))
    return plain + jax.lax.stop_gradient(exact - plain)


def solve_quadratic(
    a: ArrayLike, b: ArrayLike, c: ArrayLike, disc: ArrayLike | None = None
) -> tuple[Array, Array, Array]:
    """Real roots of ``a t² + b t + c = 0``, without cancellation.

    Stable form, as Mitsuba's ``math::solve_quadratic`` and pbrt-v4's ``Quadratic``:
    ``q = -(b + copysign(sqrt(b² - 4ac), b)) / 2``, roots ``q / a`` and ``c / q``. The two roots are
    never computed by subtracting nearly equal numbers. When ``a`` is negligible (``|q / a| >= 1/eps``)
    the far root ``q / a`` is dropped and ``c / q`` is the linear root ``-c / b``; this covers ``a == 0``.

    Args:
        a, b, c: coefficients, any broadcastable shapes.
        disc: optionally ``b² - 4ac`` computed by the caller in a better conditioned way (the sphere and
            cylinder pass ``4 (r² |d|² - |d × l|²)``, which does not cancel for distant rays).

    Returns:
        ``(t0, t1, ok)``: ``t0 <= t1`` where both exist; a missing root is ``+inf`` (so a single linear
        root is ``t0``); ``ok`` is True where at least one root exists. A tangent gives ``t0 == t1``.
    """
    a, b, c = jnp.asarray(a), jnp.asarray(b), jnp.asarray(c)
    if disc is None:
        disc = b * b - 4.0 * a * c
    real = disc >= 0
    sq = safe_sqrt(disc)
    q = -0.5 * (b + jnp.where(b < 0, -sq, sq))
    far_ok = real & (jnp.abs(a) > eps_of(a) * jnp.abs(q))
    near_ok = real & (q != 0)
    t_far = safe_mask(far_ok, lambda den: q / den, a, fallback=jnp.inf)
    t_near = safe_mask(near_ok, lambda den: c / den, q, fallback=jnp.inf)
    # q == 0 with a != 0 means b == 0 and c == 0: a double root at t = 0, which q / a already gives.
    t_near = jnp.where(near_ok, t_near, t_far)
    # A missing root is +inf, so min/max sort two roots and put a lone linear root first.
    t0 = jnp.minimum(t_near, t_far)
    t1 = jnp.maximum(t_near, t_far)
    return t0, t1, jnp.isfinite(t0)


def _bisect(f: Callable[[Array], Array], lo: Array, hi: Array, iterations: int) -> tuple[Array, Array]:
    """Bisection of ``f`` on each bracket ``[lo_k, hi_k]`` (all brackets at once).

    Returns ``(root, has_root)``; ``has_root`` is True where ``f`` changes sign (or vanishes) on the bracket.
    A fixed number of iterations in a ``fori_loop`` (never ``while_loop``), so it vmaps and never blocks AD;
    it is meant to run on stop-gradient inputs.
    """
    f_lo, f_hi = f(lo), f(hi)
    has_root = (f_lo <= 0) != (f_hi < 0)
    neg_lo = f_lo < 0

    def body(_, bracket):
        lo, hi = bracket
        mid = 0.5 * (lo + hi)
        same_side = (f(mid) < 0) == neg_lo
        return jnp.where(same_side, mid, lo), jnp.where(same_side, hi, mid)

    lo0, hi0 = lo, hi
    lo, hi = lax.fori_loop(0, iterations, body, (lo, hi))
    # a root at an end is that end (the loop moves the brackets away from a zero there)
    root = jnp.where(f_lo == 0, lo0, jnp.where(f_hi == 0, hi0, 0.5 * (lo + hi)))
    return root, has_root


def _horner(coeffs: Float[Array, " n"], s: Array) -> Array:
    """Polynomial with coefficients highest degree first, at ``s``."""
    acc = jnp.zeros_like(s)
    for k in range(coeffs.shape[0]):
        acc = acc * s + coeffs[k]
    return acc


def solve_quartic(
    coeffs: Float[Array, "5"],
    lo: ArrayLike,
    hi: ArrayLike,
    f: Callable[[Array], Array] | None = None,
) -> tuple[Float[Array, "4"], Bool[Array, "4"]]:
    """All real roots in ``[lo, hi]`` of ``c4 s⁴ + c3 s³ + c2 s² + c1 s + c0`` (``coeffs`` = c4..c0).

    Method (derivative bracketing, no closed form): the roots of the quadratic ``p''`` split
    ``[lo, hi]`` into 3 pieces where ``p'`` is monotone; bisection finds ``p'``'s roots there, which
    split ``[lo, hi]`` into 4 pieces where ``p`` is monotone, each holding at most one root, found by
    bisection. Unlike Ferrari's formula this does not lose the small roots to cancellation in float32;
    each root is as accurate as ``p`` can be evaluated. The iteration count is fixed by the dtype
    (mantissa bits + 4), so the solve is branch-free and vmaps.

    The result carries NO gradient (inputs are stop-gradient'ed): make it differentiable with
    :func:`differentiable_root` on the caller's implicit function.

    Args:
        coeffs: (5,) highest degree first. Any c4 (including 0) is fine, but the roots must lie in [lo, hi].
        lo, hi: scalar bracket; the caller knows a bound (the torus: its bounding sphere).
        f: optional better-conditioned evaluation of the same polynomial (only its sign is used).

    Returns:
        ``(roots, ok)``: (4,) roots ascending, ``+inf`` where a monotone piece has no root.
    """
    coeffs = lax.stop_gradient(jnp.asarray(coeffs))
    lo = lax.stop_gradient(jnp.asarray(lo, coeffs.dtype))
    hi = lax.stop_gradient(jnp.asarray(hi, coeffs.dtype))
    iterations = jnp.finfo(coeffs.dtype).nmant + 4
    f0 = (lambda s: _horner(coeffs, s)) if f is None else f
    crit = quartic_turns(coeffs, lo, hi)
    splits = jnp.concatenate([lo[None], crit, hi[None]])
    roots, has_root = _bisect(f0, splits[:-1], splits[1:], iterations)
    return jnp.where(has_root, roots, jnp.inf), has_root


def quartic_turns(coeffs: Float[Array, "5"], lo: ArrayLike, hi: ArrayLike) -> Float[Array, "3"]:
    """Three points of ``[lo, hi]`` ascending that split it into four pieces on which the quartic
    (``coeffs`` highest first) is monotone: its turning points there, and where it has fewer, the
    start of a piece on which it has none (:func:`solve_quartic`'s method). No gradient."""
    coeffs = lax.stop_gradient(jnp.asarray(coeffs))
    lo = lax.stop_gradient(jnp.asarray(lo, coeffs.dtype))
    hi = lax.stop_gradient(jnp.asarray(hi, coeffs.dtype))
    iterations = jnp.finfo(coeffs.dtype).nmant + 4
    degree = jnp.arange(4, 0, -1).astype(coeffs.dtype)
    d1 = coeffs[:4] * degree  # p'  (cubic)
    d2 = d1[:3] * degree[1:]  # p'' (quadratic)
    x0, x1, _ = solve_quadratic(d2[0], d2[1], d2[2])
    # Unused splits collapse onto hi, leaving empty pieces that cannot hold a sign change of p'.
    x0, x1 = jnp.clip(x0, lo, hi), jnp.clip(x1, lo, hi)
    cubic_lo = jnp.stack([lo, x0, x1])
    cubic_hi = jnp.stack([x0, x1, hi])
    crit, has_crit = _bisect(lambda s: _horner(d1, s), cubic_lo, cubic_hi, iterations)
    # Where p' keeps its sign on a piece, p is monotone across it and the piece's start serves as a split.
    return jnp.where(has_crit, crit, cubic_lo)


def centred_line(o: Array, d: Array):
    """The line ``o + t d`` for a root search: ``(moving, inv_len, d_hat, t_c, o_c)``, whether
    ``|d|`` is above the tiniest normal number, ``1/|d|``, the unit direction, and the point
    ``o_c = o + t_c d`` of the line closest to the origin: a well-scaled origin, whatever the
    distance of the ray (``t = t_c + s / |d|`` for ``s`` along ``d_hat``)."""
    d_len_sq = jnp.dot(d, d)
    moving = d_len_sq > jnp.finfo(d.dtype).tiny
    inv_len = safe_mask(moving, lax.rsqrt, d_len_sq)
    d_hat = d * inv_len
    t_c = -jnp.dot(o, d_hat) * inv_len
    return moving, inv_len, d_hat, t_c, o + t_c * d


def differentiable_root(f: Callable[[Array], Array], t_star: ArrayLike) -> Array:
    """Attaches implicit-function-theorem derivatives to a root found without gradients.

    ``t_star`` (treated as a constant) is a root of the scalar function ``f``, which closes over the
    differentiable parameters. Two Newton steps on ``g(t) = f(t) - f(t_star)`` return exactly
    ``t_star`` in value (``g(t_star) == 0`` bit for bit), while their derivatives are those of the root:
    ``dt/dθ = -(∂f/∂θ)/(∂f/∂t)`` after the first step, and second derivatives are exact after the second
    (Newton's error is quadratic, so its derivatives vanish to one order more per step).
    Where ``∂f/∂t == 0`` (a double root) the step is 0, so values and gradients stay finite.

    Args:
        f: scalar -> scalar, differentiable in the parameters it closes over.
        t_star: scalar root of ``f``, e.g. from :func:`solve_quartic`.
    """
    t_star = lax.stop_gradient(jnp.asarray(t_star))
    level = lax.stop_gradient(f(t_star))

    def newton_step(t):
        value, slope = jax.value_and_grad(f)(t)
        return t - safe_div(value - level, slope)

    return newton_step(newton_step(t_star))
