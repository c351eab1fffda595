"""``mesh`` / ``mesh2``: a triangle list, rendered as its individual triangles (no inside).

One crossing slot per triangle (K = F). Flat faces use the triangle kernel, smooth ones the
smooth-triangle kernel (one or the other for the whole mesh: a smooth mesh gives its flat faces
their face normal at every vertex, which interpolates to the same flat normal).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._build import build
from .._dtype import as_float
from ._base import NATIVE_TRIANGLE, AbstractShape, MitsubaShape, mesh_entry, read_arguments
from ._triangle import smooth_triangle_hits, triangle_hits

_MESH2_SECTIONS = ("vertex_vectors", "normal_vectors", "uv_vectors", "texture_list", "face_indices",
                   "normal_indices", "uv_indices")


class Mesh(AbstractShape):
    """``mesh``/``mesh2``: triangles (rendered as individual triangles; no inside).

    Attributes:
        triangles: (F, 3, 3) vertex positions per face.
        normals:   (F, 3, 3) per-vertex normals for smooth faces, or None for flat faces.
    """

    kind: ClassVar[str] = "mesh"
    crossings: ClassVar[int] = 1  # per triangle: see n_crossings
    # a cap, not a bound: a closed mesh is usually crossed twice, and every straight pass allowed
    # is a trace level in the compiled program
    line_crossings: ClassVar[int] = 4
    solid: ClassVar[bool] = False
    sdl_keywords: ClassVar[tuple[str, ...]] = ("mesh", "mesh2")
    triangles: Float[Array, "F 3 3"] = eqx.field(converter=as_float)
    normals: Float[Array, "F 3 3"] | None = eqx.field(
        converter=lambda x: None if x is None else as_float(x), default=None)

    def n_crossings(self) -> int:
        return int(self.triangles.shape[0])

    def hits(self, o, d):
        if self.normals is None:
            t, n = jax.vmap(lambda tri: triangle_hits(tri[0], tri[1], tri[2], o, d))(self.triangles)
        else:
            t, n = jax.vmap(lambda tri, nn: smooth_triangle_hits(tri[0], tri[1], tri[2], nn[0], nn[1], nn[2],
                                                                 o, d))(self.triangles, self.normals)
        return t[:, 0], n[:, 0]

    def bounds(self):
        v = self.triangles.reshape(-1, 3)
        return v.min(axis=0), v.max(axis=0)

    native_kernel: ClassVar[int] = NATIVE_TRIANGLE

    def native_items(self):
        f = self.triangles.shape[0]
        return jnp.pad(self.triangles.reshape(f, 9), ((0, 0), (0, 3))), self.triangles

    def n_native_items(self) -> int:
        return int(self.triangles.shape[0])

    def sub_hits(self, o, d, sub):
        tri = self.triangles[sub]
        if self.normals is None:
            return triangle_hits(tri[0], tri[1], tri[2], o, d)
        nn = self.normals[sub]
        return smooth_triangle_hits(tri[0], tri[1], tri[2], nn[0], nn[1], nn[2], o, d)

    @classmethod
    def parse_sdl(cls, keyword, args):
        return _parse_mesh(args) if keyword == "mesh" else _parse_mesh2(args)

    @classmethod
    def from_sdl(cls, fields):
        return build(cls, triangles=fields["triangles"], normals=fields["normals"])

    def to_mitsuba(self, m, camera_origin):
        normals = None if self.normals is None else np.asarray(self.normals, np.float64)
        return MitsubaShape([mesh_entry(self.triangles, normals, m)], closed=False, planar=True)


def _parse_mesh(args) -> dict:
    from ._triangle import SmoothTriangle, Triangle

    tris, norms, smooth = [], [], False
    while (kw := args.keyword("triangle", "smooth_triangle")) is not None:
        args.expect("{", f"'{{' after {kw}")
        # a mesh keeps a smooth triangle that alone would be degenerate (_mesh_fields)
        s = read_arguments(Triangle if kw == "triangle" else SmoothTriangle, args)
        tris.append((s["p1"], s["p2"], s["p3"]))
        if kw == "smooth_triangle":
            smooth = True
            norms.append((s["n1"], s["n2"], s["n3"]))
        else:
            norms.append(None)
        while not args.accept("}"):
            if args.keyword("texture") is not None:
                args.texture()
            elif args.keyword("uv_vectors") is not None:
                for i in range(3):
                    if i:
                        args.comma()
                    args.expr()
            else:
                raise args.error(f"expected '}}' after the mesh triangle, found {args.describe_next()}")
    return _mesh_fields(args, tris, norms, smooth)


def _count_list(args, name: str, size: int | None) -> list:
    """``{ n, item, … }``: vectors of ``size`` components (any values when None: read, unused)."""
    args.expect("{", f"'{{' after {name}")
    n = args.count(f"{name} entries")
    items = []
    for _ in range(n):
        args.comma()
        items.append(args.expr() if size is None else args.vector(size))
    args.comma()
    args.expect("}", f"'}}' to close {name} ({n} entries)")
    return items


def _face_list(args) -> list:
    args.expect("{", "'{' after face_indices")
    n = args.count("face_indices entries")
    faces = []
    for _ in range(n):
        args.comma()
        faces.append(tuple(int(c) for c in args.vector(3)))
        while args.number_after_comma():  # optional texture indices after a face
            args.comma()
            args.float()
    args.comma()
    args.expect("}", f"'}}' to close face_indices ({n} entries)")
    return faces


def _parse_mesh2(args) -> dict:
    loc = args.loc
    verts = normals = faces = nidx = None
    while (kw := args.keyword(*_MESH2_SECTIONS)) is not None:
        if kw == "texture_list":
            args.warn("mesh2 texture_list", "mesh2 texture_list is not supported; ignored")
            args.skip_block()
        elif kw == "face_indices":
            faces = _face_list(args)
        elif kw in ("uv_vectors", "uv_indices"):
            _count_list(args, kw, None)
        elif kw == "vertex_vectors":
            verts = _count_list(args, kw, 3)
        elif kw == "normal_vectors":
            normals = _count_list(args, kw, 3)
        else:  # normal_indices
            nidx = [tuple(int(c) for c in v) for v in _count_list(args, kw, 3)]
    if verts is None or faces is None:
        raise args.error("expected vertex_vectors and face_indices in mesh2", loc)
    _check_indices(args, faces, len(verts), "face_indices", "vertex_vectors", loc)
    tris = [tuple(verts[i] for i in f) for f in faces]
    norms = None
    if normals is not None:
        idx = nidx if nidx is not None else faces
        _check_indices(args, idx, len(normals), "normal_indices" if nidx is not None else "face_indices",
                       "normal_vectors", loc)
        norms = [tuple(normals[i] for i in f) for f in idx]
    return _mesh_fields(args, tris, norms or [None] * len(tris), norms is not None)


def _check_indices(args, faces, n: int, what: str, into: str, loc) -> None:
    """Every index within ``into`` (a negative one would silently pick from the end)."""
    for face in faces:
        for i in face:
            if not 0 <= i < n:
                raise args.error(f"expected {what} from 0 to {n - 1} (the {into} entries), found {i}", loc)


# POV-Ray 3.7 (measured): a mesh face whose unit normals agree within this, component by
# component, is flat (7.2e-6 apart: flat; 1.07e-5: smooth)
_SAME_NORMAL = 1e-5


def _mesh_normals(args, nn) -> tuple | None:
    """A smooth face's normals as POV-Ray 3.7 keeps them in a mesh (semantics §4.1): a zero
    normal becomes <1,0,0> (its warning "Normal vector in mesh cannot be zero"); None when the
    three then agree (the face is flat)."""
    nn = [np.asarray(v, np.float64) for v in nn]
    zero = [not np.any(v) for v in nn]
    if any(zero):
        args.warn("mesh normal", "a zero normal in a mesh is changed to <1,0,0>, as POV-Ray does")
        nn = [np.array([1.0, 0.0, 0.0]) if z else v for v, z in zip(nn, zero, strict=True)]
    units = [v / np.linalg.norm(v) for v in nn]
    if all(np.all(np.abs(u - units[0]) <= _SAME_NORMAL) for u in units[1:]):
        return None
    return tuple(nn)


def _mesh_fields(args, tris, norms, smooth) -> dict:
    if not tris:
        args.leave_out("empty mesh; left out")
        return {}
    n = None
    if smooth:
        norms = [None if nn is None else _mesh_normals(args, nn) for nn in norms]
    if any(nn is not None for nn in norms):
        n = []
        for tri, nn in zip(tris, norms, strict=True):
            if nn is None:  # a flat face of a smooth mesh: its face normal at every vertex
                a, b, c = (np.asarray(v) for v in tri)
                fn = np.cross(b - a, c - a)
                nn = (fn, fn, fn)
            n.append(nn)
        n = np.asarray(n, dtype=np.float64)
    return {"triangles": np.asarray(tris, dtype=np.float64), "normals": n}
