"""Primitive shapes in their object space (parameters as POV-Ray writes them, reference §4.1).

Each shape is plain data; its intersection, normal and inside test are in ``raytracer.kernels``.
``kind`` (a class variable) names the kernel family the renderer packs it into.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import numpy as np
from jaxtyping import Array, Float

from .._dtype import as_float


class AbstractShape(eqx.Module):
    kind: ClassVar[str]
    solid: ClassVar[bool] = True  # has an inside (usable in CSG)


class Sphere(AbstractShape):
    """``sphere { center, radius }``."""

    kind: ClassVar[str] = "sphere"
    center: Float[Array, "3"] = eqx.field(converter=as_float)
    radius: Float[Array, ""] = eqx.field(converter=as_float)


class Plane(AbstractShape):
    """``plane { normal, distance }``: the surface ``n̂·p = distance``; inside is ``n̂·p < distance``."""

    kind: ClassVar[str] = "plane"
    normal: Float[Array, "3"] = eqx.field(converter=as_float)
    distance: Float[Array, ""] = eqx.field(converter=as_float)


class Box(AbstractShape):
    """``box { corner1, corner2 }`` (axis-aligned in object space)."""

    kind: ClassVar[str] = "box"
    corner1: Float[Array, "3"] = eqx.field(converter=as_float)
    corner2: Float[Array, "3"] = eqx.field(converter=as_float)


class Cylinder(AbstractShape):
    """``cylinder { base, cap, radius [open] }``."""

    kind: ClassVar[str] = "cylinder"
    base: Float[Array, "3"] = eqx.field(converter=as_float)
    cap: Float[Array, "3"] = eqx.field(converter=as_float)
    radius: Float[Array, ""] = eqx.field(converter=as_float)
    open: bool = eqx.field(static=True, default=False)


class Cone(AbstractShape):
    """``cone { base, base_radius, cap, cap_radius [open] }`` (a frustum)."""

    kind: ClassVar[str] = "cone"
    base: Float[Array, "3"] = eqx.field(converter=as_float)
    base_radius: Float[Array, ""] = eqx.field(converter=as_float)
    cap: Float[Array, "3"] = eqx.field(converter=as_float)
    cap_radius: Float[Array, ""] = eqx.field(converter=as_float)
    open: bool = eqx.field(static=True, default=False)


class Quadric(AbstractShape):
    """``quadric { <A,B,C>, <D,E,F>, <G,H,I>, J }``:
    ``A x² + B y² + C z² + D xy + E xz + F yz + G x + H y + I z + J = 0``, inside < 0."""

    kind: ClassVar[str] = "quadric"
    coeffs: Float[Array, "10"] = eqx.field(converter=as_float)


class Torus(AbstractShape):
    """``torus { major, minor }`` in the x–z plane, the y axis through the hole."""

    kind: ClassVar[str] = "torus"
    major: Float[Array, ""] = eqx.field(converter=as_float)
    minor: Float[Array, ""] = eqx.field(converter=as_float)


class Disc(AbstractShape):
    """``disc { center, normal, radius [, hole_radius] }``; its inside is its plane's half-space."""

    kind: ClassVar[str] = "disc"
    center: Float[Array, "3"] = eqx.field(converter=as_float)
    normal: Float[Array, "3"] = eqx.field(converter=as_float)
    radius: Float[Array, ""] = eqx.field(converter=as_float)
    hole_radius: Float[Array, ""] = eqx.field(converter=as_float, default=0.0)


class Triangle(AbstractShape):
    """``triangle { p1, p2, p3 }`` (no inside)."""

    kind: ClassVar[str] = "triangle"
    solid: ClassVar[bool] = False
    p1: Float[Array, "3"] = eqx.field(converter=as_float)
    p2: Float[Array, "3"] = eqx.field(converter=as_float)
    p3: Float[Array, "3"] = eqx.field(converter=as_float)


class SmoothTriangle(AbstractShape):
    """``smooth_triangle { p1, n1, p2, n2, p3, n3 }``: normals interpolated barycentrically."""

    kind: ClassVar[str] = "smooth_triangle"
    solid: ClassVar[bool] = False
    p1: Float[Array, "3"] = eqx.field(converter=as_float)
    p2: Float[Array, "3"] = eqx.field(converter=as_float)
    p3: Float[Array, "3"] = eqx.field(converter=as_float)
    n1: Float[Array, "3"] = eqx.field(converter=as_float)
    n2: Float[Array, "3"] = eqx.field(converter=as_float)
    n3: Float[Array, "3"] = eqx.field(converter=as_float)


class Polygon(AbstractShape):
    """``polygon { n, P1, …, Pn }``: planar, even-odd rule, sub-polygons make holes.

    Attributes:
        vertices: (V, 3) points (2-D points get z = 0 in the parser).
        edges:    static tuple of ``(i, j)`` vertex index pairs, the closed outlines.
    """

    kind: ClassVar[str] = "polygon"
    solid: ClassVar[bool] = False
    vertices: Float[Array, "V 3"] = eqx.field(converter=as_float)
    edges: tuple[tuple[int, int], ...] = eqx.field(static=True)


class Mesh(AbstractShape):
    """``mesh``/``mesh2``: triangles (rendered as individual triangles; no inside).

    Attributes:
        triangles: (F, 3, 3) vertex positions per face.
        normals:   (F, 3, 3) per-vertex normals for smooth faces, or None for flat faces.
    """

    kind: ClassVar[str] = "mesh"
    solid: ClassVar[bool] = False
    triangles: Float[Array, "F 3 3"] = eqx.field(converter=as_float)
    normals: Float[Array, "F 3 3"] | None = eqx.field(
        converter=lambda x: None if x is None else as_float(x), default=None)


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
