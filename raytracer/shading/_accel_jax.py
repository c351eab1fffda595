"""The acceleration structure in pure JAX: the portable twin of the native hierarchy (``bvh.cc``).

It builds and queries the same tables as ``_accel._build`` / ``_accel._closest_query`` /
``_accel._any_query`` — ``node_box`` (2n-1, 6), ``node_info`` (2n-1, 4) int32 (a leaf is
``[first, count, 0, 0]`` over ``order[first:first + count]``, an inner node ``[left, 0, right,
axis]``, root 0), ``order`` (n,), ``kind``, ``mask``, ``params`` (n, 24) — so either half can be
swapped for the native one (the native traversal runs on a tree built here and the other way
round, which the tests do). It runs on any device, under ``jit``, ``vmap`` and ``grad`` (every
input is ``stop_gradient``: the hierarchy only chooses, as the native one).

Build: a linear BVH (Karras 2012, "Maximizing parallelism in the construction of BVHs, octrees,
and k-d trees"). Item boxes are padded as ``bvh.cc`` pads them; their centroids get 30-bit Morton
codes in the centroids' box; ``argsort`` sorts them (ties by index); every inner node of the binary
radix tree over the sorted keys (a code, then its index for equal codes) is found independently:
its direction, the other end of its range by an exponential then a binary search, its split by a
binary search on the common prefix. Inner node ``i`` is node ``i`` (so the root is 0), leaf ``p``
(the item ``order[p]``) is node ``n - 1 + p``, one item per leaf. An inner node's box is the union of
the boxes of the contiguous range of sorted leaves below it, read from a sparse table of
power-of-two range unions built one level per step (``ceil(log2 n)`` steps of ``O(n)`` work, exact:
min and max do not round), so no pass depends on the tree's depth. The split axis (for the native
traversal's near-child order) is the axis of the highest differing Morton bit.

Traversal: per ray a stack loop (``STACK`` entries of node and entry distance; the Karras tree's
depth is at most 30 + log2 n). A popped node whose entry lies beyond the best hit so far is dropped;
an inner node tests both children's boxes and pushes those hit, the nearer on top; a leaf's items
are tested one per step (a native leaf holds up to 4) with the kernels of ``bvh.cc`` (sphere, box,
triangle, frustum, disc; params: object_from_world 3x4 row-major, then the shape's 12 numbers), in
the input's precision (the native code works in float64). Closest hit keeps the nearest crossing
in (tmin, tmax) of the items whose ``mask & want`` is non-zero, any hit stops at the first.

The per-ray step is vmapped over ``LANES`` rays (structure of arrays: every ray quantity is a
scalar under ``vmap``, every table a column: a gathered row costs several column gathers on the
CPU) inside one ``lax.while_loop`` over the batch, a step being a no-op for a finished ray (so
``vmap`` adds no select over the stacks). When ``REFILL`` of the lanes have finished, their results
are scattered out and they take the next rays: a plain vmapped loop waits for its slowest ray with
most lanes idle (42 % of lane steps busy on camera rays, 90 % with refills; 1.5x faster there, 3x on
rays crossing a dense field). Under ``vmap`` every item kernel is computed at every step and one kept, so each
kind's kernel sits in a ``lax.cond`` on whether any item has that kind (a scene of spheres pays for
spheres only: 1.4x). ``closest_query`` and ``any_query`` have the native query's ``custom_vmap``
rule (every vmapped ray of a pool joins one query) and, unlike it, also batch over scenes (plain
``vmap`` then). Tried and dropped (no faster): keeping the nearer child out of the stack (half the
stack writes), testing a leaf child's item in its parent's step (only 9 % fewer steps on camera
rays, and the gathers then wait on the slab tests, which XLA's CPU fusion recomputes in every
consumer), larger or smaller ``LANES`` and ``REFILL``.

Measured on the 2-core CPU this was written on (shared, loaded: ``wall`` is the best of 5, float32,
jit, warm; the native code uses XLA's thread pool):

* closest hit, 307,200 camera rays (640x480) of ``sph1000.pov`` / ``sph10k.pov``:

  ==========================  ===============  ===============
  query on tree               1,000 spheres    10,000 spheres
  ==========================  ===============  ===============
  native on native (SAH)      72 ms            138 ms
  native on JAX (Karras)      88 ms            140 ms
  JAX on native               231 ms           363 ms
  JAX on JAX                  214 ms           387 ms
  ==========================  ===============  ===============

  (every pairing chooses the same item for every ray). The JAX query compiles in 4-8 s per call
  site (XLA CPU; the native call ~0.2 s): a 320x240 render of ``sph1000.pov`` (camera, reflection
  and shadow queries) takes 29 s on its first call instead of 8 s, then 0.52 s instead of 0.20 s,
  with the same image.
* build, n random boxes (JAX first call: 1.2-1.3 s of compile, 3.3 s at 1M):

  ==========  ===========  ===========
  n           native SAH   JAX Karras
  ==========  ===========  ===========
  1,000       1.0 ms       0.8 ms
  10,000      11 ms        7.9 ms
  100,000     132 ms       114 ms
  1,000,000   2.4 s        1.7 s
  ==========  ===========  ===========

  Of the JAX build at 1M, about 0.5 s is the stable ``argsort`` and 0.5 s the sparse table.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax
from jax.custom_batching import custom_vmap

ITEM_PARAMS = 24
KIND_SPHERE, KIND_BOX, KIND_TRIANGLE, KIND_FRUSTUM, KIND_DISC = 0, 1, 2, 3, 4
STACK = 64  # entries per ray: at most the tree's depth (Karras: <= 30 + log2 n; native: <= 64 + log2 n)
LANES = 8192  # rays traced at once
REFILL = 0.25  # the fraction of finished lanes that get new rays
PER_KIND = True  # skip the kernels of kinds no item has (lax.cond)
MORTON_BITS = 10  # per axis


# ================================================================ build
def _spread_bits(q):
    """The 10 low bits of ``q`` (uint32) moved to every third bit (bit b to bit 3b)."""
    out = jnp.zeros_like(q)
    for b in range(MORTON_BITS):
        out = out | (((q >> b) & 1) << (3 * b))
    return out


def _clz(x):
    return lax.clz(x).astype(jnp.int32)


def build(boxes):
    """The hierarchy of ``boxes`` (n, 6: lo xyz, hi xyz): ``(node_box (2n-1, 6), node_info (2n-1, 4)
    int32, order (n,) int32)`` in ``bvh.cc``'s layout. Static shapes, no host code."""
    boxes = lax.stop_gradient(jnp.asarray(boxes))
    n = boxes.shape[0]
    if n < 1:
        raise ValueError("build: no items")
    dtype = boxes.dtype
    lo, hi = boxes[:, :3], boxes[:, 3:]
    # as bvh.cc: an empty or NaN box is a point at 0 (its item is never hit anyway), every box is
    # padded by 1e-6 of its largest finite coordinate so that rounding never loses a hit
    scale = jnp.max(jnp.where(jnp.isfinite(boxes), jnp.abs(boxes), 0), axis=1, keepdims=True)
    pad = scale * 1e-6 + jnp.asarray(1e-30, dtype)
    ok = lo <= hi
    lo, hi = jnp.where(ok, lo, 0), jnp.where(ok, hi, 0)
    item_box = jnp.concatenate([lo - pad, hi + pad], axis=1)
    if n == 1:
        return item_box, jnp.array([[0, 1, 0, 0]], jnp.int32), jnp.zeros(1, jnp.int32)

    # ---- Morton codes of the centroids in the centroids' box, sorted (ties keep index order)
    cen = 0.5 * (lo + hi)
    cen = jnp.where(jnp.isfinite(cen), cen, 0)
    cmin, cmax = cen.min(axis=0, keepdims=True), cen.max(axis=0, keepdims=True)
    extent = cmax - cmin
    unit = jnp.where(extent > 0, (cen - cmin) / jnp.where(extent > 0, extent, 1), 0)
    cells = 1 << MORTON_BITS
    q = jnp.clip(jnp.floor(unit * cells), 0, cells - 1).astype(jnp.uint32)
    code = (_spread_bits(q[:, 0]) << 2) | (_spread_bits(q[:, 1]) << 1) | _spread_bits(q[:, 2])
    order = jnp.argsort(code, stable=True).astype(jnp.int32)
    key = code[order]

    def prefix(i, j):
        """Length of the common prefix of sorted keys i and j (a code, then its index: 64 bits),
        -1 when j is outside [0, n)."""
        inside = (j >= 0) & (j < n)
        jc = jnp.clip(j, 0, n - 1)
        x = key[i] ^ key[jc]
        same = _clz(i ^ jc) + 32
        return jnp.where(inside, jnp.where(x == 0, same, _clz(x)), -1)

    # ---- the n - 1 inner nodes, each on its own (Karras 2012, section 4)
    steps = n.bit_length() + 1  # enough for any range length <= n
    i = jnp.arange(n - 1, dtype=jnp.int32)
    # the direction of i's range: towards the neighbour sharing the longer prefix
    direction = jnp.where(prefix(i, i + 1) > prefix(i, i - 1), 1, -1).astype(jnp.int32)
    floor_prefix = prefix(i, i - direction)  # every key of the range shares more than this with i
    # an upper bound of the range's length (a power of two), then its exact other end (the loops
    # are fori_loops: unrolled, XLA's CPU compiler takes seconds over the fused searches)
    def grow(_, reach):
        return jnp.where(prefix(i, i + reach * direction) > floor_prefix, reach * 2, reach)

    reach = lax.fori_loop(0, steps, grow, jnp.full(n - 1, 2, jnp.int32))

    def extend(b, length):
        t = jnp.left_shift(jnp.int32(1), steps - b)  # 2^steps, ..., 2, 1
        longer = (t < reach) & (prefix(i, i + (length + t) * direction) > floor_prefix)
        return jnp.where(longer, length + t, length)

    length = lax.fori_loop(0, steps + 1, extend, jnp.zeros(n - 1, jnp.int32))
    j = i + length * direction
    node_prefix = prefix(i, j)

    # the split: the last key (from i's side) that shares more than node_prefix with i, by
    # steps of ceil(length / 2), ceil(length / 4), ... down to 1 (taken once)
    def advance(s, split):
        t = (length + jnp.left_shift(jnp.int32(1), s + 1) - 1) >> (s + 1)
        previous = (length + jnp.left_shift(jnp.int32(1), s) - 1) >> s
        live = (s == 0) | (previous > 1)
        further = live & (prefix(i, i + (split + t) * direction) > node_prefix)
        return jnp.where(further, split + t, split)

    split = lax.fori_loop(0, steps + 1, advance, jnp.zeros(n - 1, jnp.int32))
    gamma = i + split * direction + jnp.minimum(direction, 0)
    first, last = jnp.minimum(i, j), jnp.maximum(i, j)
    left = jnp.where(first == gamma, n - 1 + gamma, gamma)
    right = jnp.where(last == gamma + 1, n + gamma, gamma + 1)
    # split axis: the highest differing Morton bit (x at bits 3b+2, y 3b+1, z 3b); 0 if codes tie
    differ = key[gamma] ^ key[gamma + 1]
    axis = jnp.where(differ != 0, 2 - (31 - _clz(differ)) % 3, 0).astype(jnp.int32)
    zeros = jnp.zeros(n - 1, jnp.int32)
    inner_info = jnp.stack([left, zeros, right, axis], axis=1)
    p = jnp.arange(n, dtype=jnp.int32)
    leaf_info = jnp.stack([p, jnp.ones(n, jnp.int32), jnp.zeros(n, jnp.int32), jnp.zeros(n, jnp.int32)],
                          axis=1)
    node_info = jnp.concatenate([inner_info, leaf_info])

    # ---- boxes: inner node i holds the sorted leaves first..last; a sparse table of the unions of
    # 2^k consecutive leaves answers each range with two (overlapping) entries of level floor(log2)
    leaf_box = item_box[order]

    def union(a, b):
        return jnp.concatenate([jnp.minimum(a[:, :3], b[:, :3]), jnp.maximum(a[:, 3:], b[:, 3:])], axis=1)

    span = last - first + 1
    level = 31 - _clz(span)  # >= 1
    levels = n.bit_length() - 1  # floor(log2 n)

    def one_level(k, carry):
        table, inner_box = carry
        half = jnp.left_shift(jnp.int32(1), k - 1)
        table = union(table, table[jnp.minimum(p + half, n - 1)])
        other = jnp.maximum(last - jnp.left_shift(jnp.int32(1), k) + 1, 0)
        here = union(table[first], table[other])
        return table, jnp.where((level == k)[:, None], here, inner_box)

    _, inner_box = lax.fori_loop(1, levels + 1, one_level,
                                 (leaf_box, jnp.zeros((n - 1, 6), dtype)))
    node_box = jnp.concatenate([inner_box, leaf_box])
    return node_box, node_info, order


# ================================================================ items (bvh.cc's item_hit)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b, strict=True))


def _axpy(t, a, b):
    """b + t a"""
    return tuple(y + t * x for x, y in zip(a, b, strict=True))


def _sphere(q, ro, rd, tmin, tmax):
    """Centre q0..2, radius q3: the line's distance from the centre via the foot of the
    perpendicular (stable); both crossings."""
    inf = jnp.asarray(jnp.inf, q[0].dtype)
    oc = _sub(ro, q[0:3])
    a = _dot(rd, rd)
    a_safe = jnp.where(a > 0, a, 1)
    tc = -_dot(oc, rd) / a_safe
    foot = _axpy(tc, rd, oc)
    h2 = q[3] * q[3] - _dot(foot, foot)
    h = jnp.sqrt(jnp.maximum(h2, 0) / a_safe)
    ok = (a > 0) & (h2 >= 0) & (q[3] > 0)  # a radius <= 0 has no surface (as POV-Ray)
    return jnp.where(ok, tc - h, inf), jnp.where(ok, tc + h, inf)


def _box(q, ro, rd, tmin, tmax):
    """Corners q0..2, q3..5 (either order): slabs; an axis the ray runs along is in or out."""
    inf = jnp.asarray(jnp.inf, q[0].dtype)
    near, far, out = -inf, inf, jnp.zeros((), bool)
    for k in range(3):
        lo, hi = jnp.minimum(q[k], q[3 + k]), jnp.maximum(q[k], q[3 + k])
        flat = rd[k] == 0
        inv = 1 / jnp.where(flat, 1, rd[k])
        ta, tb = (lo - ro[k]) * inv, (hi - ro[k]) * inv
        near = jnp.maximum(near, jnp.where(flat, -inf, jnp.minimum(ta, tb)))
        far = jnp.minimum(far, jnp.where(flat, inf, jnp.maximum(ta, tb)))
        out = out | (flat & ((ro[k] < lo) | (ro[k] > hi)))
    ok = ~out & (near <= far)
    return jnp.where(ok, near, inf), jnp.where(ok, far, inf)


def _triangle(q, ro, rd, tmin, tmax):
    """Vertices q0..2, q3..5, q6..8 (Moller-Trumbore) with a hair of tolerance on the edges: the
    JAX kernel decides the exact hit of the chosen item."""
    dtype = q[0].dtype
    inf = jnp.asarray(jnp.inf, dtype)
    tol = 1e-9 if dtype == jnp.float64 else 8 * float(jnp.finfo(dtype).eps)
    p1, p2, p3 = q[0:3], q[3:6], q[6:9]
    e1, e2 = _sub(p2, p1), _sub(p3, p1)
    pv = (rd[1] * e2[2] - rd[2] * e2[1], rd[2] * e2[0] - rd[0] * e2[2], rd[0] * e2[1] - rd[1] * e2[0])
    det = _dot(e1, pv)
    det_ok = (det != 0) & jnp.isfinite(det)
    inv_det = 1 / jnp.where(det_ok, det, 1)
    s = _sub(ro, p1)
    u = _dot(s, pv) * inv_det
    qv = (s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0])
    v = _dot(rd, qv) * inv_det
    ok = det_ok & (u >= -tol) & (u <= 1 + tol) & (v >= -tol) & (u + v <= 1 + tol)
    return jnp.where(ok, _dot(e2, qv) * inv_det, inf), inf


def _disc(q, ro, rd, tmin, tmax):
    """Centre q0..2, normal q3..5, radius q6, hole radius q7."""
    inf = jnp.asarray(jnp.inf, q[0].dtype)
    nrm = q[3:6]
    nn = jnp.sqrt(_dot(nrm, nrm))
    nn_safe = jnp.where(nn > 0, nn, 1)
    ld = _sub(ro, q[0:3])
    dn, ln = _dot(nrm, rd) / nn_safe, _dot(nrm, ld) / nn_safe
    t = -ln / jnp.where(dn != 0, dn, 1)
    pd = _axpy(t, rd, ld)
    rho2 = _dot(pd, pd)
    ok = (nn > 0) & (dn != 0) & (rho2 <= q[6] * q[6]) & (rho2 >= q[7] * q[7])
    return jnp.where(ok, t, inf), inf


def _frustum(q, ro, rd, tmin, tmax):
    """Cylinder or cone (bvh.cc's ``frustum_hit``): base q0..2, base radius q3, cap q4..6, cap
    radius q7, open q8 != 0; the side |p_perp| = r(h), 0 <= h <= L, and unless open the end caps.
    The first crossing in (tmin, tmax)."""
    inf = jnp.asarray(jnp.inf, q[0].dtype)
    base, cap, rb, rc = q[0:3], q[4:7], q[3], q[7]
    closed = q[8] == 0
    axis = _sub(cap, base)
    length = jnp.sqrt(_dot(axis, axis))
    ok = length > 0
    length_safe = jnp.where(ok, length, 1)
    axis = tuple(x / length_safe for x in axis)
    slope = (rc - rb) / length_safe
    l = _sub(ro, base)
    h0, hd = _dot(l, axis), _dot(rd, axis)
    lp = _axpy(-h0, axis, l)
    dp = _axpy(-hd, axis, rd)
    r0 = rb + slope * h0
    qa = _dot(dp, dp) - (slope * hd) * (slope * hd)
    qb = 2 * (_dot(lp, dp) - slope * hd * r0)
    qc = _dot(lp, lp) - r0 * r0
    best = inf

    def keep(best, t, valid):
        return jnp.where(valid & (t > tmin) & (t < tmax) & (t < best), t, best)

    def side(best, t, valid):
        h = h0 + t * hd
        return keep(best, t, valid & (h >= 0) & (h <= length))

    quadratic = qa != 0
    disc = qb * qb - 4 * qa * qc
    root = jnp.sqrt(jnp.maximum(disc, 0))
    qq = -0.5 * (qb + jnp.where(qb < 0, -root, root))  # copysign(root, qb)
    real = quadratic & (disc >= 0)
    best = side(best, qq / jnp.where(quadratic, qa, 1), real)
    best = side(best, qc / jnp.where(qq != 0, qq, 1), real & (qq != 0))
    linear = ~quadratic & (qb != 0)
    best = side(best, -qc / jnp.where(linear, qb, 1), linear)
    caps = closed & (hd != 0)
    hd_safe = jnp.where(hd != 0, hd, 1)
    for h_end, radius in ((0.0, rb), (length, rc)):
        t = (h_end - h0) / hd_safe
        pc = _axpy(t, dp, lp)
        best = keep(best, t, caps & (_dot(pc, pc) <= radius * radius))
    return jnp.where(ok & (best < tmax), best, inf), inf


_KERNELS = {KIND_SPHERE: _sphere, KIND_BOX: _box, KIND_TRIANGLE: _triangle, KIND_FRUSTUM: _frustum,
            KIND_DISC: _disc}


def _first_crossing(kernel, p, o, d, tmin, tmax):
    """The first crossing in (tmin, tmax) of an item of ``kernel``'s kind (``p``: its 24 numbers)."""
    inf = jnp.asarray(jnp.inf, p.dtype)
    m = [p[k] for k in range(12)]
    ro = tuple(m[4 * r] * o[0] + m[4 * r + 1] * o[1] + m[4 * r + 2] * o[2] + m[4 * r + 3] for r in range(3))
    rd = tuple(m[4 * r] * d[0] + m[4 * r + 1] * d[1] + m[4 * r + 2] * d[2] for r in range(3))
    t0, t1 = kernel(tuple(p[12 + k] for k in range(12)), ro, rd, tmin, tmax)
    return jnp.where((t0 > tmin) & (t0 < tmax), t0, jnp.where((t1 > tmin) & (t1 < tmax), t1, inf))


def _item_hit(kind, p, o, d, tmin, tmax, present=None):
    """The first crossing of one item (``kind``, ``p`` its 24 parameters) by the ray with t in
    (tmin, tmax), or +inf: the kernels of ``bvh.cc``. Under ``vmap`` every kernel is computed and
    one kept; ``present`` (one unbatched bool per kind, or None) skips, through ``lax.cond``, the
    kinds that no item has (a scene of spheres pays for spheres only)."""
    inf = jnp.asarray(jnp.inf, p.dtype)
    t = inf
    for k, kernel in _KERNELS.items():
        crossing = functools.partial(_first_crossing, kernel)
        if present is None:
            here = crossing(p, o, d, tmin, tmax)
        else:  # the cond's operands are the gathered rows: slicing them fuses into the kernel
            here = lax.cond(present[k], crossing, lambda *_: inf, p, o, d, tmin, tmax)
        t = jnp.where(kind == k, here, t)
    return t


# ================================================================ traversal
def _slab(box, o, inv, tmin, tmax):
    """(hit, entry) of the ray's interval [tmin, tmax] with ``box`` (6,)."""
    near, far = tmin, tmax
    for k in range(3):
        a, b = (box[k] - o[k]) * inv[k], (box[3 + k] - o[k]) * inv[k]
        near = jnp.maximum(near, jnp.minimum(a, b))
        far = jnp.minimum(far, jnp.maximum(a, b))
    return near <= far, near


class _Tables(NamedTuple):
    """The query's tables as columns (``_prepare``)."""

    box: tuple  # six (nodes,) columns: lo x, y, z, hi x, y, z
    first: jax.Array  # (nodes,) a leaf's first item slot, an inner node's left child
    count: jax.Array  # (nodes,) a leaf's items (0: an inner node)
    right: jax.Array  # (nodes,) an inner node's right child
    item: jax.Array  # (slots,) the item of each leaf slot
    kind: jax.Array  # (slots,) its kernel
    mask: jax.Array  # (slots,) its visibility bits
    params: jax.Array  # (slots, 12) its kernel's numbers
    present: tuple | None  # per kernel, whether some item has it (``PER_KIND``)


class _Traversal(NamedTuple):
    """One ray's traversal (``_ray_loop``): its stack of nodes and entry distances, its nearest hit
    so far and its cursor in the leaf being read."""

    sp: jax.Array  # () the stack's height
    node: jax.Array  # (STACK + 2,) nodes
    near: jax.Array  # (STACK + 2,) their entry distances
    best_t: jax.Array  # () the nearest hit so far (tmax: none)
    best: jax.Array  # () its slot (-1: none)
    j: jax.Array  # () the next slot of the open leaf
    end: jax.Array  # () past its last slot


class _Lane(NamedTuple):
    """One lane's ray (``_trace_lanes``)."""

    o: tuple
    d: tuple
    inv: tuple
    tmin: jax.Array
    tmax: jax.Array
    want: jax.Array


def _prepare(tables):
    """The query's tables as columns (gathering one value of a column per ray is several times
    faster on the CPU than gathering rows), the items in leaf order (a leaf slot indexes them)."""
    node_box, node_info, order, kind, mask, params = tables[:6]  # (no tie rule: the unit tables)
    return _Tables(box=tuple(node_box[:, k] for k in range(6)), first=node_info[:, 0],
                   count=node_info[:, 1], right=node_info[:, 2], item=order, kind=kind[order],
                   mask=mask[order], params=params[order],
                   present=tuple(jnp.any(kind == k) for k in _KERNELS) if PER_KIND else None)


def _ray_loop(t, any_hit: bool):
    """(init, active, step, result) of one ray's traversal over the prepared tables ``t`` (vmapped
    by the caller). The stack holds nodes and their entry distances."""
    n_nodes, n_items = t.first.shape[0], t.item.shape[0]
    dtype = t.params.dtype

    def init(o, d, tmin, tmax):
        valid = jnp.isfinite(o[0] + o[1] + o[2] + d[0] + d[1] + d[2]) & (tmin < tmax)
        # two spare slots: pushes write past the top; the root is entered at tmin
        return _Traversal(sp=valid.astype(jnp.int32), node=jnp.zeros(STACK + 2, jnp.int32),
                          near=jnp.full(STACK + 2, tmin), best_t=tmax, best=jnp.int32(-1), j=jnp.int32(0),
                          end=jnp.int32(0))

    def active(s):
        live = (s.sp > 0) | (s.j < s.end)
        return (live & (s.best < 0)) if any_hit else live

    def step(s, o, d, inv, tmin, want):
        live = active(s)
        cursor = s.j < s.end  # inside a leaf of several items (the native tree's)
        pop = live & ~cursor
        top = jnp.maximum(s.sp - 1, 0)
        node, near = jnp.clip(s.node[top], 0, n_nodes - 1), s.near[top]
        sp = jnp.where(pop, s.sp - 1, s.sp)
        best_t, best = s.best_t, s.best
        visit = pop & (near <= best_t)
        first, count = t.first[node], t.count[node]
        leaf = count > 0
        # one item: the next of the current leaf, or the first of the leaf just popped
        slot = jnp.clip(jnp.where(cursor, s.j, first), 0, n_items - 1)
        test = live & (cursor | (visit & leaf)) & ((t.mask[slot] & want) != 0)
        hit_t = _item_hit(t.kind[slot], t.params[slot], o, d, tmin, best_t, t.present)
        closer = test & (hit_t < best_t)
        best_t, best = jnp.where(closer, hit_t, best_t), jnp.where(closer, slot, best)
        opened = visit & leaf
        j = jnp.where(cursor, s.j + 1, jnp.where(opened, first + 1, s.j))
        end = jnp.where(opened, first + count, s.end)
        # an inner node: its children's boxes, those hit pushed with the nearer on top
        inner = visit & ~leaf
        kid_l, kid_r = jnp.clip(first, 0, n_nodes - 1), jnp.clip(t.right[node], 0, n_nodes - 1)
        hit_l, near_l = _slab([c[kid_l] for c in t.box], o, inv, tmin, best_t)
        hit_r, near_r = _slab([c[kid_r] for c in t.box], o, inv, tmin, best_t)
        hit_l, hit_r = inner & hit_l, inner & hit_r
        both = hit_l & hit_r
        left_first = near_l <= near_r
        lower = jnp.where(both, jnp.where(left_first, kid_r, kid_l), jnp.where(hit_l, kid_l, kid_r))
        lower_t = jnp.where(both, jnp.where(left_first, near_r, near_l), jnp.where(hit_l, near_l, near_r))
        upper = jnp.where(left_first, kid_l, kid_r)
        upper_t = jnp.where(left_first, near_l, near_r)
        pushed = hit_l.astype(jnp.int32) + hit_r.astype(jnp.int32)
        # slots sp and sp + 1 are above the top: writing them is harmless when nothing is pushed
        nodes = s.node.at[sp].set(lower).at[sp + 1].set(upper)
        nears = s.near.at[sp].set(lower_t).at[sp + 1].set(upper_t)
        # a full stack drops the children (as bvh.cc; unreachable for the depths either build makes)
        sp = jnp.where(sp + pushed <= STACK, sp + pushed, sp)
        return _Traversal(sp=sp, node=nodes, near=nears, best_t=best_t, best=best, j=j, end=end)

    def result(s):
        found = s.best >= 0
        item = jnp.where(found, t.item[jnp.maximum(s.best, 0)], -1)
        return item, jnp.where(found, s.best_t, jnp.inf).astype(dtype)

    return init, active, step, result


def _trace_lanes(t, o, d, tmin, tmax, want, any_hit: bool):
    """Rays (3, R) o, d; (R,) tmin, tmax, want over the prepared tables: (item (R,), t (R,)).

    ``LANES`` rays are traced at once, one per lane; whenever ``REFILL`` of the lanes have finished
    (or all have), their results are written out and they take the next rays. A batch thus never
    waits for its slowest ray with most lanes idle (a plain vmapped loop over camera rays keeps
    fewer than half its lanes busy)."""
    init, active, step, result = _ray_loop(t, any_hit)
    rays = tmin.shape[0]
    lanes = min(LANES, rays)
    inv = 1 / d
    columns = (*o, *d, *inv, tmin, tmax, want)  # 12 per-ray columns

    def fetch(ray):
        c = [x[jnp.minimum(ray, rays - 1)] for x in columns]
        return _Lane(o=tuple(c[0:3]), d=tuple(c[3:6]), inv=tuple(c[6:9]), tmin=c[9], tmax=c[10], want=c[11])

    ray = jnp.arange(lanes, dtype=jnp.int32)
    lane = fetch(ray)
    state = jax.vmap(init)(lane.o, lane.d, lane.tmin, lane.tmax)
    out_item, out_t = jnp.full(rays, -1, jnp.int32), jnp.full(rays, jnp.inf, tmin.dtype)
    batched_step, batched_active = jax.vmap(step), jax.vmap(active)

    def refill(carry):
        state, lane, ray, next_ray, out_item, out_t = carry
        done = ~batched_active(state) & (ray < rays)
        item, hit_t = jax.vmap(result)(state)
        where = jnp.where(done, ray, rays)  # rays: out of bounds, dropped
        out_item = out_item.at[where].set(item, mode="drop")
        out_t = out_t.at[where].set(hit_t, mode="drop")
        new = next_ray + jnp.cumsum(done.astype(jnp.int32)) - 1
        take = done & (new < rays)
        fresh = fetch(new)
        lane = jax.tree_util.tree_map(lambda a, b: jnp.where(take, a, b), fresh, lane)
        start = jax.vmap(init)(fresh.o, fresh.d, fresh.tmin, fresh.tmax)
        # a new ray needs its own scalars and the first stack entry (the rest is above the top)
        state = _Traversal(*(v.at[:, 0].set(jnp.where(take, new_v[:, 0], v[:, 0])) if v.ndim == 2
                             else jnp.where(take, new_v, v) for v, new_v in zip(state, start, strict=True)))
        ray = jnp.where(take, new, jnp.where(done, rays, ray))
        next_ray = jnp.minimum(next_ray + jnp.sum(done, dtype=jnp.int32), rays)
        return state, lane, ray, next_ray, out_item, out_t

    def body(carry):
        state, lane, ray, next_ray, out_item, out_t = carry
        state = batched_step(state, lane.o, lane.d, lane.inv, lane.tmin, lane.want)
        carry = (state, lane, ray, next_ray, out_item, out_t)
        idle = jnp.sum(~batched_active(state) & (ray < rays))
        busy = jnp.sum(ray < rays)
        return lax.cond((idle >= max(1, int(REFILL * lanes))) | (idle == busy), refill, lambda c: c, carry)

    carry = (state, lane, ray, jnp.int32(lanes), out_item, out_t)
    carry = lax.while_loop(lambda c: jnp.any(c[2] < rays), body, refill(carry))
    return carry[4], carry[5]


def _trace(tables, o, d, tmin, tmax, want, any_hit: bool):
    """Rays of any leading shape S (o, d: S + (3,); tmin, tmax, want broadcast to S)."""
    sg = lax.stop_gradient
    tables = _prepare(tuple(sg(x) for x in tables))
    dtype = tables.params.dtype
    o, d = sg(jnp.asarray(o, dtype)), sg(jnp.asarray(d, dtype))
    shape = o.shape[:-1]
    tmin = jnp.broadcast_to(sg(jnp.asarray(tmin, dtype)), shape).reshape(-1)
    tmax = jnp.broadcast_to(sg(jnp.asarray(tmax, dtype)), shape).reshape(-1)
    want = jnp.broadcast_to(jnp.asarray(want, jnp.int32), shape).reshape(-1)
    o, d = o.reshape(-1, 3).T, d.reshape(-1, 3).T  # (3, R): structure of arrays
    if tmin.shape[0] == 0:
        return jnp.zeros(shape, jnp.int32), jnp.zeros(shape, dtype)
    item, t = _trace_lanes(tables, o, d, tmin, tmax, want, any_hit)
    return item.reshape(shape), t.reshape(shape)


def _query_fn(any_hit: bool):
    @custom_vmap
    def query(tables, o, d, tmin, tmax, want):
        """Rays of any leading shape ``S`` (``o``, ``d``: S + (3,)): (item S int32, -1 for none; t S,
        +inf for none). ``tables``: node_box, node_info, order, kind, mask, params."""
        return _trace(tables, o, d, tmin, tmax, want, any_hit)

    @query.def_vmap
    def _batched(axis_size, in_batched, tables, o, d, tmin, tmax, want):
        if any(jax.tree_util.tree_leaves(in_batched[0])):
            # a batch of scenes: the plain vmap of the whole traversal
            axes = (jax.tree_util.tree_map(lambda b: 0 if b else None, in_batched[0]),
                    *(0 if b else None for b in in_batched[1:]))
            out = jax.vmap(functools.partial(_trace, any_hit=any_hit), in_axes=axes)(tables, o, d, tmin, tmax,
                                                                                   want)
            return out, (True, True)
        # every vmapped ray becomes one query (the rays' leading axes are flattened by _trace)
        o_b, d_b = in_batched[1], in_batched[2]
        core = o.shape[1:-1] if o_b else o.shape[:-1]
        full = (axis_size, *core)

        def lift(x, batched, tail=()):
            x = jnp.asarray(x)
            if batched:  # align the ray dims to the right, as broadcasting does
                x = x.reshape((axis_size,) + (1,) * (len(full) + len(tail) - x.ndim) + x.shape[1:])
            return jnp.broadcast_to(x, full + tail)

        o, d = lift(o, o_b, (3,)), lift(d, d_b, (3,))
        tmin, tmax, want = (lift(x, b) for x, b in zip((tmin, tmax, want), in_batched[3:], strict=True))
        return query(tables, o, d, tmin, tmax, want), (True, True)

    return query


_closest = _query_fn(any_hit=False)
_any = _query_fn(any_hit=True)


def _without_gradient(query):
    def call(tables, o, d, tmin, tmax, want):
        # the custom_vmap primitive has no derivative rule: it must see no tangents at all
        sg = lax.stop_gradient
        return query(jax.tree_util.tree_map(sg, tables), sg(o), sg(d), sg(tmin), sg(tmax), want)

    call.__doc__ = query.__doc__
    return call


closest_query = _without_gradient(_closest)
any_query = _without_gradient(_any)
