"""Affine transforms as 4×4 matrices (column vectors, ``p_world = M @ p_object``).

POV-Ray writes transforms with row vectors and composes them in the order written; here the
matrix is ``world_from_object`` and ``a.then(b)`` means "apply a, then b" (``M = B @ A``).
The parser composes numpy matrices and hands over the product; the matrix is the
differentiable parameter.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._build import Record
from .._dtype import as_float


def translation_matrix(v) -> np.ndarray:
    """4×4 numpy matrix translating by ``v`` (3,)."""
    m = np.eye(4)
    m[:3, 3] = np.asarray(v, dtype=np.float64)
    return m


def scale_matrix(v) -> np.ndarray:
    """4×4 numpy matrix scaling by ``v`` (3,) (POV replaces a 0 component by 1; the parser does that)."""
    return np.diag([*np.asarray(v, dtype=np.float64), 1.0])


def rotation_matrix(angles_degrees) -> np.ndarray:
    """POV-Ray ``rotate <a, b, c>``: about x by a, then y by b, then z by c (semantics §4.3).

    Column-vector form ``Rz(c) @ Ry(b) @ Rx(a)`` with the standard right-handed matrices; in POV's
    left-handed frame this is the "left-hand rule" rotation.
    """
    a, b, c = np.radians(np.asarray(angles_degrees, dtype=np.float64))
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    return m


def axis_rotation_matrix(axis, angle_degrees) -> np.ndarray:
    """Rotation by ``angle_degrees`` about ``axis`` in POV's sense (as ``vaxis_rotate``)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    t = np.radians(angle_degrees)
    c, s = np.cos(t), np.sin(t)
    x, y, z = axis
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    m = np.eye(4)
    m[:3, :3] = c * np.eye(3) + s * k + (1 - c) * np.outer(axis, axis)
    return m


def pov_matrix(values) -> np.ndarray:
    """POV-Ray ``matrix <v00..v32>`` (12 numbers, row-vector convention) as a column-vector 4×4 matrix."""
    v = np.asarray(values, dtype=np.float64).reshape(4, 3)
    m = np.eye(4)
    m[:3, :3] = v[:3, :].T
    m[:3, 3] = v[3, :]
    return m


class Transform(Record):
    """An affine ``world_from_object`` transform.

    Attributes:
        matrix: (4, 4) column-vector matrix; the last row is ``[0, 0, 0, 1]``.
    """

    matrix: Float[Array, "4 4"] = eqx.field(converter=as_float)

    @classmethod
    def identity(cls) -> Transform:
        return cls(np.eye(4))

    @classmethod
    def translate(cls, v) -> Transform:
        return cls(translation_matrix(v))

    @classmethod
    def scale(cls, v) -> Transform:
        v = np.broadcast_to(np.asarray(v, dtype=np.float64), (3,))
        return cls(scale_matrix(v))

    @classmethod
    def rotate(cls, angles_degrees) -> Transform:
        return cls(rotation_matrix(angles_degrees))

    def then(self, other: Transform) -> Transform:
        """The transform that applies ``self`` first, then ``other``."""
        return Transform(other.matrix @ self.matrix)

    def apply_point(self, p):
        return self.matrix[:3, :3] @ p + self.matrix[:3, 3]

    def apply_vector(self, v):
        return self.matrix[:3, :3] @ v


def compose(*transforms: Transform | None) -> Transform | None:
    """Applies the given transforms in order (``None`` entries are skipped); ``None`` if all are."""
    out = None
    for t in transforms:
        if t is None:
            continue
        out = t if out is None else out.then(t)
    return out


def inverse_affine(m):
    """Inverse of a (4, 4) affine matrix, differentiable (3×3 inverse + translation)."""
    a = m[:3, :3]
    a_inv = jnp.linalg.inv(a)
    t = -a_inv @ m[:3, 3]
    top = jnp.concatenate([a_inv, t[:, None]], axis=1)
    bottom = jnp.zeros((1, 4), m.dtype).at[0, 3].set(1.0)
    return jnp.concatenate([top, bottom], axis=0)
