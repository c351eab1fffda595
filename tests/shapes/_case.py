"""The test case of a shape: a generic instance of a registered shape with an implicit function
written independently of its kernels (numpy, float64), used by the property, gradient, bounds and
batching tests. Each shape's test module (``test_<shape>.py``) defines ``CASES``; ``_cases.py``
collects them, and ``test_registry.py`` checks every registered shape has one.
"""

import dataclasses
import functools
from collections.abc import Callable

import numpy as np

from raytracer import shapes
from raytracer.shapes import AbstractShape


@dataclasses.dataclass(frozen=True)
class Case:
    """A primitive instance: ``make(*params)`` is the registered shape.

    ``distance(p)`` is zero on the surface and distance-like near it (negative inside for solids);
    ``on_patch(p)`` says whether a point of the implicit surface belongs to the bounded patch
    (discs, triangles, open cylinders). ``aim`` and ``size`` say where rays should go.
    """

    name: str
    make: Callable[..., AbstractShape]
    params: tuple
    distance: Callable[[np.ndarray], float]
    aim: np.ndarray
    size: float
    solid: bool = True  # the inside test is meaningful along the normal
    convex: bool = True  # or planar: a ray leaving along the outward hemisphere never comes back
    geometric_normal: bool = True  # n is the gradient of distance (not an interpolated normal)
    signed_normal: bool = True  # n points out; False: either side (triangles, polygons)
    on_patch: Callable[[np.ndarray], bool] = lambda p: True

    @property
    def kind(self) -> str:
        return self.make(*self.params).kind

    def hits(self, *args):
        """``hits(*params, o, d)``: the shape's own ``hits`` (the record the renderer calls)."""
        *params, o, d = args
        return self.make(*params).hits(o, d)

    def inside(self, *args):
        """``inside(*params, p)``: the shape's own inside test."""
        *params, p = args
        return self.make(*params).inside(p)


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def numeric_gradient(f, p, h=1e-6):
    return np.array([(f(p + h * e) - f(p - h * e)) / (2 * h) for e in np.eye(3)])


def random_rays(case: Case, seed: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` rays from around the shape towards points of its bounding region; non-unit directions."""
    rng = np.random.default_rng(seed)
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    o = case.aim + direction * case.size * rng.uniform(1.5, 4.0, size=(count, 1))
    target = case.aim + rng.uniform(-1.0, 1.0, size=(count, 3)) * case.size
    d = (target - o) * rng.uniform(0.3, 3.0, size=(count, 1))
    return o, d


@functools.cache
def _jit(fn):
    import inspect

    import jax

    static = [name for name in ("open", "edges") if name in inspect.signature(fn).parameters]
    return jax.jit(fn, static_argnames=static)


class _JittedKernels:
    """The kernels of ``raytracer.shapes`` with every function jit-compiled (static ``open`` / ``edges``).

    Eager dispatch compiles each primitive op separately, which costs far more than one jit of a kernel.
    """

    def __getattr__(self, name):
        attr = getattr(shapes, name)
        return _jit(attr) if callable(attr) else attr


jitted_kernels = _JittedKernels()


def assert_refined_crossing_is_the_kernels(make, controls, o, d):
    """``make(controls).near_hit`` at the first crossing the whole kernel finds of each line
    ``o + t d`` (those that cross) gives that crossing, its normal and its derivatives along the
    controls (float64): the native hierarchy's choice, refined, is the kernel's own."""
    import jax
    import jax.numpy as jnp

    def first(c, o_, d_):
        t, n = make(c).hits(o_, d_)
        k = jnp.argmin(jnp.where(t > 0, t, jnp.inf))
        return t[k], n[k]

    def near(c, o_, d_, t0):
        t, n = make(c).near_hit(o_, d_, t0)
        return t[0], n[0]

    c0, o, d = jnp.asarray(controls, jnp.float64), jnp.asarray(o), jnp.asarray(d)
    t_all, n_all = jax.jit(jax.vmap(first, (None, 0, 0)))(c0, o, d)
    hit = np.isfinite(np.asarray(t_all))
    assert hit.sum() > 20
    t_near, n_near = jax.jit(jax.vmap(near, (None, 0, 0, 0)))(c0, o[hit], d[hit], t_all[hit])
    np.testing.assert_allclose(t_near, t_all[hit], rtol=1e-12)
    np.testing.assert_allclose(n_near, n_all[hit], atol=1e-12)
    grad_all = jax.grad(lambda c, o_, d_: first(c, o_, d_)[0])
    grad_near = jax.grad(lambda c, o_, d_, t0: near(c, o_, d_, t0)[0])
    g_all = jax.jit(jax.vmap(grad_all, (None, 0, 0)))(c0, o[hit], d[hit])
    g_near = jax.jit(jax.vmap(grad_near, (None, 0, 0, 0)))(c0, o[hit], d[hit], t_all[hit])
    np.testing.assert_allclose(g_near, g_all, rtol=1e-9, atol=1e-12)
