"""One generic instance of every primitive kind, with an implicit function written independently of
the kernels (numpy, float64), used by the property, gradient and batching tests."""

import dataclasses
import functools
from collections.abc import Callable

import numpy as np

from raytracer import shapes as k


@dataclasses.dataclass(frozen=True)
class Case:
    """A primitive instance.

    ``distance(p)`` is zero on the surface and distance-like near it (negative inside for solids);
    ``on_patch(p)`` says whether a point of the implicit surface belongs to the bounded patch
    (discs, triangles, open cylinders). ``aim`` and ``size`` say where rays should go.
    """

    name: str
    params: tuple
    hits: Callable
    inside: Callable | None
    distance: Callable[[np.ndarray], float]
    aim: np.ndarray
    size: float
    solid: bool = True  # the inside test is meaningful along the normal
    convex: bool = True  # or planar: a ray leaving along the outward hemisphere never comes back
    geometric_normal: bool = True  # n is the gradient of distance (not an interpolated normal)
    signed_normal: bool = True  # n points out; False: either side (triangles, polygons)
    on_patch: Callable[[np.ndarray], bool] = lambda p: True


def triangle_inside(p1, p2, p3, p):
    """The registered shape's inside test (a triangle has none: always False)."""
    return k.Triangle(p1, p2, p3).inside(p)


def smooth_triangle_inside(p1, p2, p3, n1, n2, n3, p):
    return k.SmoothTriangle(p1, p2, p3, n1, n2, n3).inside(p)


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _sphere_case():
    c, r = np.array([0.3, -0.2, 0.1]), 1.2
    return Case("sphere", (c, r), k.sphere_hits, k.sphere_inside, lambda p: np.linalg.norm(p - c) - r, c, r)


def _plane_case():
    normal, dist = np.array([0.3, 1.0, -0.2]), 0.4
    n_hat = _unit(normal)
    return Case(
        "plane", (normal, dist), k.plane_hits, k.plane_inside, lambda p: n_hat @ p - dist, dist * n_hat, 2.0
    )


def _box_case():
    c1, c2 = np.array([1.0, 0.5, 0.8]), np.array([-0.7, -1.0, -0.6])
    mid, half = (c1 + c2) / 2, np.abs(c1 - c2) / 2
    return Case("box", (c1, c2), k.box_hits, k.box_inside, lambda p: np.max(np.abs(p - mid) - half), mid, 1.0)


def _frustum_distance(base, r0, cap, r1, with_caps):
    axis = cap - base
    length = np.linalg.norm(axis)
    a_hat = axis / length
    slope = (r1 - r0) / length

    def distance(p):
        h = (p - base) @ a_hat
        radial = np.linalg.norm(p - base - h * a_hat)
        side = (radial - (r0 + slope * h)) / np.sqrt(1 + slope**2)
        return max(side, -h, h - length) if with_caps else side

    def on_patch(p):
        h = (p - base) @ a_hat
        return -1e-4 <= h <= length + 1e-4

    return distance, on_patch


def _cylinder_case(open_):
    base, cap, r = np.array([0.1, -1.0, 0.2]), np.array([0.3, 1.2, -0.1]), 0.7
    distance, on_patch = _frustum_distance(base, r, cap, r, not open_)
    return Case(
        "open_cylinder" if open_ else "cylinder",
        (base, cap, r),
        functools.partial(k.cylinder_hits, open=open_),
        k.cylinder_inside,
        distance,
        (base + cap) / 2,
        1.2,
        convex=not open_,
        on_patch=on_patch,
    )


def _cone_case(cap_radius):
    base, r0, cap = np.array([0.0, -1.0, 0.0]), 1.0, np.array([0.2, 1.0, 0.1])
    distance, on_patch = _frustum_distance(base, r0, cap, cap_radius, True)
    return Case(
        "cone" if cap_radius == 0 else "frustum",
        (base, r0, cap, cap_radius),
        k.cone_hits,
        k.cone_inside,
        distance,
        (base + cap) / 2,
        1.2,
        on_patch=on_patch,
    )


def quadric_polynomial(coeffs, p):
    """POV-Ray's quadric, written term by term."""
    A, B, C, D, E, F, G, H, I, J = coeffs
    x, y, z = p
    return A * x * x + B * y * y + C * z * z + D * x * y + E * x * z + F * y * z + G * x + H * y + I * z + J


def _numeric_gradient(f, p, h=1e-6):
    return np.array([(f(p + h * e) - f(p - h * e)) / (2 * h) for e in np.eye(3)])


def _quadric_case(name, coeffs, convex):
    coeffs = np.asarray(coeffs, np.float64)

    def distance(p):  # first-order distance Q / |∇Q|
        q = lambda x: quadric_polynomial(coeffs, x)  # noqa: E731
        return q(p) / np.linalg.norm(_numeric_gradient(q, p))

    return Case(name, (coeffs,), k.quadric_hits, k.quadric_inside, distance, np.zeros(3), 1.0, convex=convex)


def _torus_case():
    major, minor = 1.5, 0.4

    def distance(p):
        return np.hypot(np.hypot(p[0], p[2]) - major, p[1]) - minor

    return Case(
        "torus", (major, minor), k.torus_hits, k.torus_inside, distance, np.zeros(3), 1.9, convex=False
    )


def _disc_case():
    c, normal, r, hole = np.array([0.1, 0.2, 0.3]), np.array([0.2, 1.0, 0.3]), 1.3, 0.4
    n_hat = _unit(normal)
    return Case(
        "disc",
        (c, normal, r, hole),
        k.disc_hits,
        k.disc_inside,
        lambda p: n_hat @ (p - c),
        c,
        1.3,
        on_patch=lambda p: hole - 1e-4 <= np.linalg.norm(p - c) <= r + 1e-4,
    )


def _in_triangle(p1, p2, p3):
    def on_patch(p):
        # Barycentric weights from sub-triangle areas, signed along the triangle normal.
        n = np.cross(p2 - p1, p3 - p1)
        w1 = np.cross(p3 - p2, p - p2) @ n / (n @ n)
        w2 = np.cross(p1 - p3, p - p3) @ n / (n @ n)
        return min(w1, w2, 1 - w1 - w2) >= -1e-4

    return on_patch


def _triangle_case(smooth):
    p1, p2, p3 = np.array([0.0, 0.0, 0.2]), np.array([1.5, 0.1, 0.0]), np.array([0.2, 1.3, -0.3])
    n_hat = _unit(np.cross(p2 - p1, p3 - p1))
    if smooth:
        normals = (n_hat + [0.3, 0, 0], n_hat + [0, 0.3, 0], n_hat + [0, 0, -0.3])
        params, hits, inside = (p1, p2, p3, *normals), k.smooth_triangle_hits, smooth_triangle_inside
    else:
        params, hits, inside = (p1, p2, p3), k.triangle_hits, triangle_inside
    return Case(
        "smooth_triangle" if smooth else "triangle",
        params,
        hits,
        inside,
        lambda p: n_hat @ (p - p1),
        (p1 + p2 + p3) / 3,
        0.7,
        solid=False,
        geometric_normal=not smooth,
        signed_normal=False,
        on_patch=_in_triangle(p1, p2, p3),
    )


def _polygon_case():
    # A square with a square hole in the plane through (0.1, 0.2, 0.3) spanned by u, w.
    u, w = _unit([1.0, 0.2, -0.1]), _unit(np.cross([1.0, 0.2, -0.1], [0.1, 1.0, 0.4]))
    o = np.array([0.1, 0.2, 0.3])
    square = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    verts = np.array([o + a * u + b * w for a, b in square] + [o + 0.4 * (a * u + b * w) for a, b in square])
    edges = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4))
    n_hat = _unit(np.cross(u, w))

    def on_patch(p):
        a, b = (p - o) @ u, (p - o) @ w
        return max(abs(a), abs(b)) <= 1 + 1e-4 and max(abs(a), abs(b)) >= 0.4 - 1e-4

    return Case(
        "polygon",
        (verts,),
        lambda v, o_, d_: k.polygon_hits(v, edges, o_, d_),
        lambda v, p: k.Polygon(vertices=v, edges=edges).inside(p),
        lambda p: n_hat @ (p - o),
        o,
        1.0,
        solid=False,
        signed_normal=False,
        on_patch=on_patch,
    )


CASES = [
    _sphere_case(),
    _plane_case(),
    _box_case(),
    _cylinder_case(False),
    _cylinder_case(True),
    _cone_case(0.0),
    _cone_case(0.4),
    _quadric_case("ellipsoid_quadric", [1.0, 2.0, 0.5, 0.3, 0.0, 0.1, 0.1, 0.0, -0.2, -1.0], True),
    _quadric_case("hyperboloid_quadric", [1.0, -1.0, 1.0, 0, 0, 0, 0, 0, 0, -0.5], False),
    _torus_case(),
    _disc_case(),
    _triangle_case(False),
    _triangle_case(True),
    _polygon_case(),
]
CASE_IDS = [c.name for c in CASES]


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
        attr = getattr(k, name)
        return _jit(attr) if callable(attr) else attr


jitted_kernels = _JittedKernels()
