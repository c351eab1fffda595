"""Planar polygon with any number of sub-polygons, filled by the even-odd (Jordan) rule, so overlaps
and nested loops make holes, as POV-Ray's ``polygon``.

The plane comes from Newell's normal (the vector area ``Σ a × b`` over the edges, taken about the
centroid to avoid cancellation), which is robust to nearly collinear vertices. The point-in-polygon
test counts crossings of a ray in the plane with the (static) edge list, all edges at once.
"""

from collections.abc import Sequence
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._dtype import as_float
from ..kernels._common import masked_hits, points_at
from ..kernels._numerics import as_float_arrays, eps_of, safe_div, safe_normalize, solve_linear
from ._base import AbstractShape

POLYGON_K = 1


def _plane_basis(n: Float[Array, "3"]) -> tuple[Float[Array, "3"], Float[Array, "3"]]:
    """Two unit vectors spanning the plane of unit ``n``, branch-free.

    Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (JCGT 6(1)).
    """
    sign = jnp.copysign(1.0, n[2]).astype(n.dtype)
    a = -1.0 / (sign + n[2])  # |sign + n_z| >= 1
    b = n[0] * n[1] * a
    u = jnp.stack([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    w = jnp.stack([b, sign + n[1] * n[1] * a, -n[1]])
    return u, w


def _even_odd(px, py, ax, ay, bx, by) -> Array:
    """Parity of the crossings of the ray from (px, py) towards +x with the edges a -> b (2-D)."""
    # Half-open straddle test: a vertex exactly at height py counts for one of its two edges only.
    straddle = (ay > py) != (by > py)
    x_at_py = ax + safe_div((py - ay) * (bx - ax), by - ay)
    crossings = jnp.sum(straddle & (px < x_at_py))
    return crossings % 2 == 1


def polygon_hits(
    vertices: Float[ArrayLike, "V 3"],
    edges: Sequence[tuple[int, int]],
    o: Float[ArrayLike, "3"],
    d: Float[ArrayLike, "3"],
) -> tuple[Float[Array, "1"], Float[Array, "1 3"]]:
    """The crossing of the line ``o + t d`` with the filled polygon.

    Args:
        vertices: (V, 3) coplanar points.
        edges: static sequence of ``(i, j)`` vertex index pairs; each sub-polygon is a closed loop of
            edges (orientation of each loop is free, the fill is even-odd).
        o: (3,) ray origin.
        d: (3,) ray direction, any length.

    Returns:
        ``(t, n)``: t (1,), ``+inf`` on a miss, a parallel ray or a degenerate (zero-area) polygon;
        n (1, 3) the unit Newell normal (its sign follows the winding of the loops; may face either way).
    """
    vertices, o, d = as_float_arrays(vertices, o, d)
    index = np.asarray(edges, dtype=np.int32).reshape(-1, 2)
    centroid = jnp.mean(vertices, axis=0)
    a = vertices[index[:, 0]] - centroid[None, :]
    b = vertices[index[:, 1]] - centroid[None, :]
    area = jnp.sum(jnp.cross(a, b), axis=0)  # Newell: twice the vector area
    scale = jnp.sum(a * a) + jnp.sum(b * b)
    eps = eps_of(scale)
    proper = jnp.dot(area, area) > (eps * scale) ** 2
    n_hat = safe_normalize(area)
    l = o - centroid
    t, ok = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, l))
    q = points_at(l, d, t[None])[0]
    u, w = _plane_basis(n_hat)
    inside = _even_odd(jnp.dot(q, u), jnp.dot(q, w), a @ u, a @ w, b @ u, b @ w)
    return masked_hits(t[None], n_hat[None], (ok & proper & inside)[None])


def polygon_margin(vertices, edges, o, d):
    """The polygon's silhouette margin (``AbstractShape.silhouette_margin``): where the line crosses
    its plane, the distance to the nearest edge, positive inside (even-odd) and negative outside.
    Across an edge it is that edge's signed perpendicular distance (linear: smooth), oriented by
    the inside test where it is evaluated (both flip together at the edge)."""
    vertices, o, d = as_float_arrays(vertices, o, d)
    index = np.asarray(edges, dtype=np.int32).reshape(-1, 2)
    centroid = jnp.mean(vertices, axis=0)
    a = vertices[index[:, 0]] - centroid[None, :]
    b = vertices[index[:, 1]] - centroid[None, :]
    n_hat = safe_normalize(jnp.sum(jnp.cross(a, b), axis=0))
    l = o - centroid
    t, _ = solve_linear(jnp.dot(n_hat, d), jnp.dot(n_hat, l))
    q = l + jnp.where(jnp.isfinite(t), t, 0.0) * d
    u, w = _plane_basis(n_hat)
    px, py, ax, ay, bx, by = jnp.dot(q, u), jnp.dot(q, w), a @ u, a @ w, b @ u, b @ w
    inside = _even_odd(px, py, ax, ay, bx, by)
    ex, ey = bx - ax, by - ay
    length_sq = ex * ex + ey * ey
    s = jnp.clip(safe_div((px - ax) * ex + (py - ay) * ey, length_sq), 0.0, 1.0)
    gap_sq = (px - ax - s * ex) ** 2 + (py - ay - s * ey) ** 2
    k = jnp.argmin(jnp.where(length_sq > 0, gap_sq, jnp.inf))
    # within the nearest edge's span: its perpendicular distance, signed by its direction, turned
    # to be positive inside; at a vertex: the distance to it (a kink only on the vertex itself)
    perp = safe_div(ex[k] * (py - ay[k]) - ey[k] * (px - ax[k]), jnp.sqrt(length_sq[k]))
    facing = jnp.where(inside == (perp > 0), 1.0, -1.0)
    at_vertex = (s[k] <= 0) | (s[k] >= 1)
    corner = jnp.where(inside, 1.0, -1.0) * jnp.sqrt(jnp.maximum(gap_sq[k], jnp.finfo(q.dtype).tiny))
    return jnp.where(at_vertex, corner, facing * perp)


# ---------------------------------------------------------------- the record
class Polygon(AbstractShape):
    """``polygon { n, P1, …, Pn }``: planar, even-odd rule, sub-polygons make holes.

    Attributes:
        vertices: (V, 3) points (2-D points get z = 0 in the parser).
        edges:    static tuple of ``(i, j)`` vertex index pairs, the closed outlines.
    """

    kind: ClassVar[str] = "polygon"
    crossings: ClassVar[int] = POLYGON_K
    solid: ClassVar[bool] = False
    sdl_keywords: ClassVar[tuple[str, ...]] = ("polygon",)
    pov_bounds_margin: ClassVar[float] = 1e-3
    vertices: Float[Array, "V 3"] = eqx.field(converter=as_float)
    edges: tuple[tuple[int, int], ...] = eqx.field(static=True)

    def hits(self, o, d):
        return polygon_hits(self.vertices, self.edges, o, d)

    def silhouette_margin(self, o, d):
        return polygon_margin(self.vertices, self.edges, o, d)

    def bounds(self):
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    @classmethod
    def parse_sdl(cls, keyword, args):
        loc = args.loc
        n = args.count("polygon points")
        pts = []
        for _ in range(n):
            args.comma()
            pts.append(args.vector(allow_2d=True))
        if n < 3:
            raise args.error(f"expected at least 3 polygon points, found {n}", loc)
        return {"points": pts}

    @classmethod
    def from_sdl(cls, fields):
        return polygon_from_points(fields["points"])


def polygon_from_points(points) -> Polygon:
    """Builds a POV polygon from its point list: an outline closes when its first point repeats."""
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape[-1] == 2:
        pts = np.concatenate([pts, np.zeros((len(pts), 1))], axis=1)
    edges, start, i = [], 0, 1
    while i < len(pts):
        edges.append((i - 1, i))
        if np.array_equal(pts[i], pts[start]) and i > start:
            start = i + 1
            i += 2
            continue
        i += 1
    if start < len(pts) and not np.array_equal(pts[-1], pts[start]):
        edges.append((len(pts) - 1, start))  # POV closes an open last outline (with a warning)
    return Polygon(vertices=pts, edges=tuple(edges))
