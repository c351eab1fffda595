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
from ._triangle import _triangle_margin, smooth_triangle_hits, triangle_hits

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

    def item_margin(self, o, d, sub):
        # the triangle's own: a mesh's outline is where the line leaves the triangle it crosses
        # last before it, which is the triangle the boundary term's ray saw there
        tri = self.triangles[sub]
        return _triangle_margin(tri[0], tri[1], tri[2], o, d)

    def items_are_faces(self) -> bool:
        # flat: each triangle shades with its own normal; smooth: the normals interpolate across
        # the edges (a smooth mesh's outline over itself is not seen yet)
        return self.normals is None

    def one_face(self, sub_a, sub_b):
        # one plane, within roundings: the same normal direction (sine 1e-4), and b's corners on a's
        # plane (1e-4 of the triangles' size)
        a, b = self.triangles[sub_a], self.triangles[sub_b]
        n_a = jnp.cross(a[1] - a[0], a[2] - a[0])
        n_b = jnp.cross(b[1] - b[0], b[2] - b[0])
        len_a, len_b = jnp.linalg.norm(n_a), jnp.linalg.norm(n_b)
        size = jnp.max(jnp.abs(jnp.concatenate([a, b]) - a[0][None]))
        parallel = jnp.linalg.norm(jnp.cross(n_a, n_b)) <= 1e-4 * len_a * len_b
        on_plane = jnp.all(jnp.abs((b - a[0][None]) @ n_a) <= 1e-4 * len_a * size)
        return parallel & on_plane

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
            norms.append(_NO_NORMALS)
        while not args.accept("}"):
            if args.keyword("texture") is not None:
                args.texture()
            elif args.keyword("texture_list") is not None:  # a texture per vertex, interpolated
                args.expect("{", "'{' after texture_list")
                for _ in range(3):
                    args.texture(identifier="texture_list")
                args.expect("}", "'}' to close texture_list (three textures)")
            elif args.keyword("uv_vectors") is not None:
                for i in range(3):
                    if i:
                        args.comma()
                    args.expr()
            else:
                raise args.error(f"expected '}}' after the mesh triangle, found {args.describe_next()}")
    return _mesh_fields(args, np.asarray(tris, np.float64).reshape(-1, 3, 3),
                        np.asarray(norms, np.float64).reshape(-1, 3, 3), smooth)


_NO_NORMALS = ((np.nan,) * 3,) * 3


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
        faces.append(args.vector(3))
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
            nidx = _count_list(args, kw, 3)
    if verts is None or faces is None:
        raise args.error("expected vertex_vectors and face_indices in mesh2", loc)
    corners = _indices(args, faces, len(verts), "face_indices", "vertex_vectors", loc)
    norms = None
    if normals is not None:
        if nidx is not None:
            nidx = nidx[:len(faces)]  # POV-Ray 3.7 ignores extra entries, without a warning
        idx = (_indices(args, faces, len(normals), "face_indices", "normal_vectors", loc) if nidx is None
               else _indices(args, nidx, len(normals), "normal_indices", "normal_vectors", loc))
        norms = _vectors(normals)[idx]
        if len(norms) < len(faces):  # POV-Ray 3.7 (measured): the faces past the list are flat
            norms = np.concatenate([norms, np.full((len(faces) - len(norms), 3, 3), np.nan)])
    return _mesh_fields(args, _vectors(verts)[corners], norms, norms is not None)


def _vectors(items: list) -> np.ndarray:
    return np.asarray(items, np.float64).reshape(-1, 3)


def _indices(args, items: list, n: int, what: str, into: str, loc) -> np.ndarray:
    """Indices read as floats, truncated toward zero as POV-Ray's (int); every one within
    ``into`` (a negative one would silently pick from the end)."""
    idx = np.trunc(np.asarray(items, np.float64).reshape(-1, 3))
    bad = ~((idx >= 0) & (idx < n))
    if bad.any():
        raise args.error(f"expected {what} from 0 to {n - 1} (the {into} entries), found {int(idx[bad][0])}",
                         loc)
    return idx.astype(np.int64)


# POV-Ray 3.7 (measured): a mesh face whose unit normals agree within this, component by
# component, is flat (7.2e-6 apart: flat; 1.07e-5: smooth)
_SAME_NORMAL = 1e-5


def _mesh_fields(args, tris: np.ndarray, norms: np.ndarray | None, smooth: bool) -> dict:
    """The mesh's fields from its faces (F, 3, 3) and, for a smooth mesh, their vertex normals
    (F, 3, 3; NaN for a flat triangle of a ``mesh``). As POV-Ray 3.7 keeps them (semantics §4.1):
    a zero normal becomes <1,0,0> (its warning "Normal vector in mesh cannot be zero"), and a face
    whose three unit normals then agree is flat: its face normal at every vertex, which
    interpolates to the same flat normal. No normals at all when every face is flat."""
    if not len(tris):
        args.leave_out("empty mesh; left out")
        return {}
    if not smooth:
        return {"triangles": tris, "normals": None}
    given = ~np.isnan(norms).any(axis=(1, 2))
    zero = ~norms.any(axis=2) & given[:, None]
    if zero.any():
        args.warn("mesh normal", "a zero normal in a mesh is changed to <1,0,0>, as POV-Ray does")
        norms = np.where(zero[..., None], np.array([1.0, 0.0, 0.0]), norms)
    with np.errstate(invalid="ignore"):
        units = norms / np.linalg.norm(norms, axis=2, keepdims=True)
    curved = given & ~(np.abs(units[:, 1:] - units[:, :1]) <= _SAME_NORMAL).all(axis=(1, 2))
    if not curved.any():
        return {"triangles": tris, "normals": None}
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    face = np.repeat(np.cross(b - a, c - a)[:, None], 3, axis=1)
    return {"triangles": tris, "normals": np.where(curved[:, None, None], norms, face)}
