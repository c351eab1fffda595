"""What lets the scene's arrays be packed *outside* the compiled program and passed in.

A scene of N objects has about 16 leaves per object. Packed inside the jit trace, each leaf was an
argument of the program and each stacking one operation per object: 1,000 spheres made a program
of 13,000 arguments and 20,000 operations that took 14 s to trace and 37 s to compile. Instead,
``render`` packs the scene into struct-of-arrays first (``pack_geometry``, ``pack_materials``: numpy
when the values are concrete, one ``jnp`` operation per field when they are traced, so gradients
still reach the user's objects) and the program receives a few dozen arrays plus the scene's
*skeleton*: its objects with every array replaced by a :class:`Placeholder` (shape and dtype), from
which the same static plan is made inside.

* :class:`Frozen`: the static half of a packed pytree, hashable by content (the jit cache key).
* :func:`register_packed`: registers a dataclass as a pytree of its array fields.
* :func:`stack`: numpy or jnp stacking, whichever the values allow.
* :func:`skeleton`: the structure of a pytree with placeholders for its arrays.
"""

from __future__ import annotations

import dataclasses
import pickle

import jax
import jax.numpy as jnp
import numpy as np


class Frozen:
    """A static value compared and hashed by content: its pickled bytes (numpy arrays included), or
    ``key`` when given. The hash is computed once, so a jit cache lookup does not walk the value."""

    __slots__ = ("value", "_key", "_hash")

    def __init__(self, value, key=None):
        self.value = value
        self._key = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL) if key is None else key
        self._hash = hash(self._key)

    @classmethod
    def tree(cls, tree) -> Frozen:
        """A pytree of hashable leaves (a :func:`skeleton`), keyed by its structure and leaves."""
        leaves, treedef = jax.tree_util.tree_flatten(tree)
        return cls(tree, (treedef, tuple(leaves)))

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        return isinstance(other, Frozen) and (self is other or self._key == other._key)


def register_packed(cls, arrays: tuple[str, ...]):
    """Registers dataclass ``cls`` as a pytree whose children are the fields ``arrays`` (arrays or
    pytrees of them); every other field is static (compared by content)."""
    names = [f.name for f in dataclasses.fields(cls)]
    static = tuple(n for n in names if n not in arrays)

    def flatten(x):
        return [getattr(x, n) for n in arrays], Frozen({n: getattr(x, n) for n in static})

    def unflatten(aux, children):
        return cls(**dict(zip(arrays, children, strict=True)), **aux.value)

    jax.tree_util.register_pytree_node(cls, flatten, unflatten)
    return cls


def is_traced(*xs) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(xs))


def stack(xs, dtype=None):
    """``jnp.stack(xs)`` (cast to ``dtype``); numpy's when every entry is a concrete value, so
    packing a large scene is not one JAX dispatch per object."""
    if not is_traced(xs):
        out = np.stack([np.asarray(x) for x in xs])
        return out if dtype is None else out.astype(dtype)
    out = jnp.stack([jnp.asarray(x) for x in xs])
    return out if dtype is None else out.astype(dtype)


@dataclasses.dataclass(frozen=True)
class Placeholder:
    """Where an array was: its shape and dtype (enough for everything the plan asks)."""

    shape: tuple[int, ...]
    dtype: str

    @property
    def ndim(self) -> int:
        return len(self.shape)


def skeleton(tree):
    """``tree`` with every array leaf (numpy, JAX, tracer) replaced by its :class:`Placeholder`."""
    def leaf(x):
        if isinstance(x, (np.ndarray, jax.Array, np.generic)):
            return Placeholder(tuple(np.shape(x)), str(x.dtype))
        return x

    return jax.tree_util.tree_map(leaf, tree)
