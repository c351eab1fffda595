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
* :func:`inverse_affines`, :func:`with_field`: packing steps that do not grow with the scene in
  JAX dispatches or tree walks.
* :func:`bucket`, :func:`pad_rows`: per-object arrays are padded to a few sizes, so that scenes
  that differ only in their number of objects the hierarchy holds lower to one program.
"""

from __future__ import annotations

import dataclasses
import functools
import operator
import pickle

import jax
import jax.numpy as jnp
import numpy as np


class Frozen:
    """A static value compared and hashed by content: its pickled bytes (numpy arrays included), or
    ``key`` when given. The hash is computed once, so a jit cache lookup does not walk the value.
    With ``make`` (and ``key``), the value is made on first use: a jit cache hit never needs it.
    ``memo``: what a user of this value derived from it, kept as long as it lives (not compared)."""

    __slots__ = ("_value", "_make", "_key", "_hash", "memo")

    def __init__(self, value=None, key=None, make=None):
        self._value, self._make, self.memo = value, make, None
        self._key = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL) if key is None else key
        self._hash = hash(self._key)

    @property
    def value(self):
        if self._make is not None:
            self._value, self._make = self._make(), None
        return self._value

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        # the hashes first: JAX compares static arguments of unequal hashes too (a tree of 100,000
        # objects' skeleton against another's took 0.18 s a comparison, 8 of them a trace)
        return isinstance(other, Frozen) and (self is other or (self._hash == other._hash
                                                                 and self._key == other._key))


def register_packed(cls, arrays: tuple[str, ...]):
    """Registers dataclass ``cls`` as a pytree whose children are the fields ``arrays`` (arrays or
    pytrees of them); every other field is static (compared by content, or by the key
    :func:`keyed` gave it)."""
    names = [f.name for f in dataclasses.fields(cls)]
    static = tuple(n for n in names if n not in arrays)
    cls._packed_static_names = static

    def flatten(x):
        # the static half is pickled once per instance (a jit call flattens its arguments)
        aux = x.__dict__.get("_packed_static")
        if aux is None:
            aux = Frozen({n: getattr(x, n) for n in static})
            object.__setattr__(x, "_packed_static", aux)
        return [getattr(x, n) for n in arrays], aux

    def unflatten(aux, children):
        x = cls(**dict(zip(arrays, children, strict=True)), **aux.value)
        object.__setattr__(x, "_packed_static", aux)
        return x

    jax.tree_util.register_pytree_node(cls, flatten, unflatten)
    return cls


def keyed(x, key) -> None:
    """Gives packed value ``x`` (of a :func:`register_packed` class) the static half compared by
    ``key`` instead of by its content: a program is then keyed by what its trace reads of ``x``
    (the caller's promise), not by every static table (``_packed._signature``)."""
    static = {n: getattr(x, n) for n in type(x)._packed_static_names}
    object.__setattr__(x, "_packed_static", Frozen(static, key=key))


def is_traced(*xs) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(xs))


def any_traced(xs) -> bool:
    """``is_traced`` for a flat list of arrays and numbers (no tree walk): their types, collected
    in one C loop (10^5 entries: 3 ms, against 35 ms for an ``isinstance`` per entry)."""
    return any(issubclass(t, jax.core.Tracer) for t in set(map(type, xs)))


def stack(xs, dtype=None):
    """``jnp.stack(xs)`` (cast to ``dtype``); numpy's when every entry is a concrete value, so
    packing a large scene is not one JAX dispatch per object. Traced entries are stacked by one
    jitted call (:func:`traced_op`)."""
    if not any_traced(xs):
        # one C loop over the entries (np.stack expands each one first: 4-10x slower for 10^5)
        out = np.array(xs)
        return out if dtype is None else out.astype(dtype, copy=False)
    return traced_op(_stack, as_dtype(xs, dtype), None if dtype is None else np.dtype(dtype).name)


def as_dtype(xs, dtype) -> tuple:
    """``xs`` with its NumPy float entries in ``dtype`` before they enter a jitted call: a float64
    constant (``EYE4``) passed next to float32 tracers was staged as float64 after a render under
    ``jax.enable_x64`` had traced the same call, and the program failed to lower."""
    if dtype is None:
        return tuple(xs)
    return tuple(x.astype(dtype) if isinstance(x, np.ndarray) and x.dtype.kind == "f" else x for x in xs)


def _stack(xs, dtype):
    out = jnp.stack([jnp.asarray(x) for x in xs])
    return out if dtype is None else out.astype(dtype)


@functools.partial(jax.jit, static_argnums=(0, 2))
def _traced_op(fn, xs, static):
    return fn(xs, static)


def traced_op(fn, xs, static=None):
    """``fn(xs, static)`` as one jitted call: packing a traced scene gathers one entry per object,
    and under an eager transformation (``jax.grad(loss)(scene)`` without ``jit``) each primitive
    of it is linearised on its own, every call (200 spheres: 8,500 primitives, 6 s a gradient).
    As one call, the transformation sees one primitive and caches its rule. ``fn`` a module-level
    function, ``static`` hashable."""
    return _traced_op(fn, xs, static)


def bucket(n: int) -> int:
    """The length a per-object array of ``n`` entries is padded to: 8, or the smallest m·2^e ≥ n
    with m in 5…8 (at most 25 % of padding past 8). Scenes whose counts fall in one bucket give
    arrays of one shape, hence one program (the persistent compilation cache then serves both)."""
    if n <= 8:
        return 8
    e = (n - 1).bit_length() - 3
    return -(-n // (1 << e)) * (1 << e)


def pad_rows(x, n: int, fill=None):
    """``x`` with ``n`` rows (axis 0): its own, then copies of its last row (``fill``: that value
    instead). Concrete arrays are padded with numpy (a jnp op per new shape would compile)."""
    m = x.shape[0]
    if m == n:
        return x
    if isinstance(x, jax.core.Tracer):
        tail = (jnp.repeat(x[-1:], n - m, 0) if fill is None
                else jnp.full((n - m, *x.shape[1:]), fill, x.dtype))
        return jnp.concatenate([x, tail])
    x = np.asarray(x)
    tail = np.repeat(x[-1:], n - m, 0) if fill is None else np.full((n - m, *x.shape[1:]), fill, x.dtype)
    return np.concatenate([x, tail])


EYE4 = np.eye(4)
EYE4.flags.writeable = False  # the identity where a transform is absent: one array, never written


def inverse_affines(m):
    """(n, 4, 4) inverses of affine matrices: numpy's batched inverse for concrete values (no
    compilation for each new n), ``jax.vmap(inverse_affine)`` (differentiable) for traced ones."""
    from .scene._transform import inverse_affine

    if is_traced(m):
        return jax.vmap(inverse_affine)(m)
    m = np.asarray(m)
    a_inv = np.linalg.inv(m[:, :3, :3])
    out = np.zeros_like(m)
    out[:, :3, :3] = a_inv
    out[:, :3, 3] = -np.einsum("nij,nj->ni", a_inv, m[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def with_field(module, name: str, value):
    """A copy of Equinox module ``module`` with field ``name`` set to ``value``, without walking the
    tree (``eqx.tree_at`` flattens the whole scene: 8 s for 10,000 objects) or running converters."""
    new = object.__new__(type(module))
    for f in dataclasses.fields(module):
        object.__setattr__(new, f.name, value if f.name == name else getattr(module, f.name))
    return new


@dataclasses.dataclass(frozen=True)
class Placeholder:
    """Where an array was: its shape and dtype (enough for everything the plan asks)."""

    shape: tuple[int, ...]
    dtype: str


_SHAPE_DTYPE = operator.attrgetter("shape", "dtype")
_BLOCK = 1 << 16


def array_types(types) -> bool:
    """Whether every type of ``types`` is an array's (numpy, numpy scalar, JAX, tracer: a tracer
    is an instance of ``jax.Array`` but its class is no subclass of it)."""
    return all(issubclass(t, (np.ndarray, np.generic, jax.Array, jax.core.Tracer)) for t in types)


def skeleton(tree, flat=None) -> Frozen:
    """``tree`` with every array leaf (numpy, JAX, tracer) replaced by its :class:`Placeholder`, as
    one :class:`Frozen` value keyed by its structure and its leaves' shapes and dtypes (one walk of
    the tree, or none when ``flat`` gives its ``(leaves, treedef)``); the tree of placeholders is
    built on first use (tracing), not for a render that finds its program compiled."""
    leaves, treedef = jax.tree_util.tree_flatten(tree) if flat is None else flat
    if array_types(set(map(type, leaves))):
        # every leaf an array: its (shape, dtype) read in one C loop (10^5 spheres: 1.6 M leaves,
        # 0.7 s against 1.3 s for a Python call per leaf). The key holds each distinct pair once
        # (in order of first appearance) and every leaf's pair as a number in one bytes object:
        # 1.6 M tuples kept for the life of the packed scene would be walked by every full
        # collection of Python's cyclic GC. The pairs are read in blocks (a list of 1.6 M of
        # them was ~190 MB).
        number: dict = {}
        blocks = []
        for start in range(0, len(leaves), _BLOCK):
            pairs = list(map(_SHAPE_DTYPE, leaves[start:start + _BLOCK]))
            for pair in dict.fromkeys(pairs):
                number.setdefault(pair, len(number))
            blocks.append(np.fromiter(map(number.__getitem__, pairs), np.int32, len(pairs)))
        distinct = tuple(number)
        codes = np.concatenate(blocks).tobytes() if blocks else b""
        del number, blocks

        def make():
            made = [Placeholder(tuple(shape), str(dtype)) for shape, dtype in distinct]
            return treedef.unflatten([made[k] for k in np.frombuffer(codes, np.int32).tolist()])

        return Frozen(key=(treedef, distinct, codes), make=make)
    made: dict = {}

    def leaf(x):
        if isinstance(x, (np.ndarray, jax.Array, np.generic)):
            key = (np.shape(x), x.dtype)
            if key not in made:
                made[key] = Placeholder(tuple(np.shape(x)), str(x.dtype))
            return made[key]
        return x

    placeholders = tuple(leaf(x) for x in leaves)
    return Frozen(key=(treedef, placeholders), make=lambda: treedef.unflatten(placeholders))
