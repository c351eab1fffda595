"""Per-primitive material arrays (texture layers, finish, interior), packed before the compiled
program runs (numpy for concrete values, jnp for traced ones, so gradients reach the user's objects:
see ``raytracer/_packing.py``), and pigment evaluation at a hit point (semantics §5.2)."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import patterns
from .._packing import (
    EYE4,
    any_traced,
    as_dtype,
    bucket,
    inverse_affines,
    is_traced,
    pad_rows,
    register_packed,
    stack,
    traced_op,
)
from .._plan import NORMAL_PATTERNS, Plan
from ..kernels import matvec, safe_sqrt
from ..scene import WAVES, Finish, Interior, Layer, Pigment, Reflection, Texture


@dataclasses.dataclass
class PackedMaterials:
    """Struct-of-arrays over texture layers and primitives.

    Pigment and finish arrays are indexed by *row* ``prim * n_layers + layer`` (layer 0 on top);
    rows of absent layers repeat the top layer and are masked by ``layer_present``. Interior
    arrays and ``transparent`` are indexed by primitive. Pigments of different patterns are
    evaluated pattern by pattern (only patterns present in the scene are traced) and selected by
    ``pattern_id``. Colour maps are padded to a common length by repeating their last entry, which
    leaves the lookup unchanged.

    The static per-row tables serve decisions made while tracing (which candidate rows are
    solid); the program's own lookups at a traced row read their copies in ``tables``, arrays
    padded like every other array here to ``bucket(N)`` primitives (rows of padding repeat the last
    one and are never read). So scenes that differ only in how many primitives the hierarchy
    holds (``_accel``) give one program, not one with each table as a constant.
    """

    n_layers: int  # static: the most layers any primitive's texture has
    layer_present: np.ndarray  # (N, n_layers) bool, static
    pattern_names: tuple[str, ...]
    pattern_id: np.ndarray  # (N,) int, static
    turbulent: tuple[bool, ...]  # per pattern name: any pigment of it has turbulence
    octaves: dict[str, int]  # per pattern name (static; the max over its pigments)
    waves: np.ndarray  # (N,) int index into scene.WAVES, static
    values: jax.Array  # (N, M)
    colors: jax.Array  # (N, M, 5)
    pattern_from_world: jax.Array  # (N, 4, 4)
    vector: jax.Array  # (N, 3)
    frequency: jax.Array  # (N,)
    phase: jax.Array  # (N,)
    turbulence: jax.Array  # (N, 3) (zeros where absent)
    omega: jax.Array
    lambda_: jax.Array
    finish: FinishArrays  # every row's finish
    fresnel: np.ndarray  # (N,) bool static
    conserve_energy: np.ndarray  # (N,) bool static
    ior: jax.Array  # (N,) (1 where absent)
    fade_distance: jax.Array  # (N,) (0 where absent: no fading)
    fade_power: jax.Array
    fade_color: jax.Array  # (N, 3)
    transparent: np.ndarray  # (N,) static: every layer's pigment can carry filter/transmit
    # (N,) bool: the row's pattern space keeps a point exact (``_exact_spaces``); moved to ``tables``
    # when padded (a value of the scene, not of the program's structure), then None
    exact_space: np.ndarray | None = None
    # the static tables above as arrays (a traced row's lookups): layer_present, pattern_id, waves,
    # fresnel, conserve_energy, transparent; and exact_space
    tables: dict[str, jax.Array] = dataclasses.field(default_factory=dict)
    # the layers' ``normal {}`` perturbations by row, None without any
    normals: PackedNormals | None = None
    # the pigments of the rows' pigment maps (``Pigment.entries``), row ``map_start[r] + i`` the
    # i-th of row r's (``tables["map_start"]``, ``tables["map_size"]``: 0 for a colour map); None
    # without any
    entries: PackedMaterials | None = None
    # the rows' image maps: every image padded to the largest (n, H, W, 5); row r's is
    # ``tables["image"][r]`` (-1: none), image i's size ``tables["image_size"][i]`` and its way of
    # wrapping ``image_modes[tables["image_mode"][i]]`` (the scene's distinct ones, static)
    images: jax.Array | None = None
    image_modes: tuple = ()
    # the scene's patterned textures (semantics §5.7), None without any; the rows above then hold
    # each primitive's first plain texture (what shadow rays and the boundary term see)
    textures: PackedTextures | None = None


class FinishArrays(NamedTuple):
    """The finishes of every material row, a field a stack: (N,) or (N, 3). What is absent in a
    finish is the value that adds nothing (0), or POV-Ray's default."""

    ambient: jax.Array
    emission: jax.Array
    diffuse: jax.Array
    brilliance: jax.Array
    phong: jax.Array
    phong_size: jax.Array
    specular: jax.Array
    roughness: jax.Array
    metallic: jax.Array
    refl_min: jax.Array
    refl_max: jax.Array
    refl_falloff: jax.Array
    refl_exponent: jax.Array
    refl_metallic: jax.Array


def _finish_arrays(f: Finish, no_reflection: Reflection) -> dict:
    r = f.reflection if f.reflection is not None else no_reflection
    return {
        "ambient": f.ambient, "emission": f.emission, "diffuse": f.diffuse,
        "brilliance": f.brilliance,
        "phong": f.phong if f.phong is not None else 0.0, "phong_size": f.phong_size,
        "specular": f.specular if f.specular is not None else 0.0,
        "roughness": f.roughness,
        "metallic": f.metallic if f.metallic is not None else 0.0,
        "refl_min": r.min, "refl_max": r.max, "refl_falloff": r.falloff,
        "refl_exponent": r.exponent, "refl_metallic": r.metallic if r.metallic is not None else 0.0,
    }


def _padded(xs, m: int, dtype):
    """(n, m, …): each array of ``xs`` (its own length along axis 0) padded to ``m`` entries by
    repeating its last entry (a colour-map lookup is unchanged by it)."""
    if not any_traced(xs):
        by_length: dict[int, list[int]] = {}
        for i, x in enumerate(xs):
            by_length.setdefault(x.shape[0], []).append(i)
        out = np.empty((len(xs), m) + np.shape(xs[0])[1:], dtype)
        for n, rows in by_length.items():  # one block per length, not one padding per entry
            block = np.array([xs[i] for i in rows])
            out[rows, :n] = block
            out[rows, n:] = block[:, n - 1:n]
        return out
    return traced_op(_padded_traced, as_dtype(xs, dtype), (m, np.dtype(dtype).name))


def _padded_traced(xs, static):
    m, dtype = static
    return jnp.stack([jnp.concatenate([x, jnp.repeat(x[-1:], m - x.shape[0], 0)]) if x.shape[0] < m
                      else jnp.asarray(x) for x in xs]).astype(dtype)


def pack_materials(plan: Plan, dtype) -> PackedMaterials:
    n_layers = max(len(p.texture.layers) for p in plan.prims)
    present = np.array([[k < len(p.texture.layers) for k in range(n_layers)] for p in plan.prims])
    layers = [p.texture.layers[k if k < len(p.texture.layers) else 0]
              for p in plan.prims for k in range(n_layers)]
    pigments: list[Pigment] = [layer.pigment for layer in layers]
    finishes: list[Finish] = [layer.finish for layer in layers]
    air = Interior()  # one default, not one module built per primitive
    interiors = [p.interior if p.interior is not None else air for p in plan.prims]
    # the fields through each module's __dict__: an attribute read on an Equinox module goes through
    # its Python-level __getattribute__ (~1 µs), and this reads ~30 per primitive
    pg_ = [vars(pg) for pg in pigments]
    names = tuple(sorted({pg["pattern"] for pg in pg_}))
    m = max(pg["values"].shape[0] for pg in pg_)
    world_from_pattern = stack([EYE4 if pg["transform"] is None else pg["transform"].matrix
                                for pg in pg_], dtype)
    zero3 = np.zeros(3)
    no_reflection = Reflection()
    # a finish shared by many primitives (a declared one) is read and stacked once, then gathered
    by_id: dict[int, int] = {}
    fin = []
    for f in finishes:
        if id(f) not in by_id:
            by_id[id(f)] = len(fin)
            fin.append(_finish_arrays(f, no_reflection))
    fin_row = np.fromiter((by_id[id(f)] for f in finishes), np.int64, len(finishes))
    mats = PackedMaterials(
        n_layers=n_layers,
        layer_present=present,
        pattern_names=names,
        pattern_id=np.array([names.index(pg["pattern"]) for pg in pg_], dtype=np.int32),
        turbulent=tuple(any(pg["turbulence"] is not None for pg in pg_ if pg["pattern"] == nm)
                        for nm in names),
        octaves={nm: max(pg["octaves"] for pg in pg_ if pg["pattern"] == nm) for nm in names},
        waves=np.array([pat_wave_index(pg) for pg in pigments], dtype=np.int32),
        values=_padded([pg["values"] for pg in pg_], m, dtype),
        colors=_padded([_structural_colors(pg) for pg in pg_], m, dtype),
        pattern_from_world=inverse_affines(world_from_pattern),
        vector=stack([pg["vector"] for pg in pg_], dtype),
        frequency=stack([_frequency(pg) for pg in pg_], dtype),
        phase=stack([pg["phase"] for pg in pg_], dtype),
        turbulence=stack([zero3 if pg["turbulence"] is None else pg["turbulence"] for pg in pg_], dtype),
        omega=stack([pg["omega"] for pg in pg_], dtype),
        lambda_=stack([pg["lambda_"] for pg in pg_], dtype),
        finish=FinishArrays(*(stack([fi[k] for fi in fin], dtype)[fin_row] for k in FinishArrays._fields)),
        fresnel=np.array([f.reflection is not None and f.reflection.fresnel for f in finishes]),
        conserve_energy=np.array([f.conserve_energy for f in finishes]),
        ior=stack([1.0 if it.ior is None else it.ior for it in interiors], dtype),
        # a fade_power not written is POV-Ray's default 0 (which fades transmitted rays, §2.7)
        fade_distance=stack([0.0 if it.fade_distance is None else it.fade_distance for it in interiors],
                            dtype),
        fade_power=stack([0.0 if it.fade_power is None else it.fade_power for it in interiors], dtype),
        fade_color=stack([it.fade_color for it in interiors], dtype),
        transparent=np.array([p.transparent for p in plan.prims]),
        exact_space=_exact_spaces(world_from_pattern),
    )
    mats = _padded_to_bucket(mats, len(plan.prims))
    if any(pg["entries"] is not None for pg in pg_):
        _pack_entries(mats, pg_, dtype)
    if any(pg["image"] is not None for pg in pg_):
        _pack_images(mats, pg_, dtype)
    if any(layer.normal is not None and layer.normal.pattern.pattern in NORMAL_PATTERNS for layer in layers):
        mats.normals = pack_normals(layers, bucket(len(plan.prims)) * n_layers, dtype)
    if any(p.texture.patterned for p in plan.prims):
        mats.textures = pack_textures(plan.prims, dtype)
    return mats


@dataclasses.dataclass
class PackedTextures:
    """Patterned textures as a tree (semantics §5.7): its nodes are the scene's distinct textures,
    a plain one a leaf, a patterned one an inner node whose children are its entries.

    ``leaves`` holds the plain textures as :func:`pack_materials` holds primitives (leaf i's layers
    at rows ``i · n_layers + k``); ``selectors`` the inner nodes' patterns, one pigment row each.
    ``tables``: ``prim_node`` (N,) each primitive's node; per node ``node_leaf`` (its leaf, -1 for
    an inner node), ``node_selector`` (its pattern's row, 0 for a leaf), ``node_start`` and
    ``node_size`` (its children in ``children``; a leaf is its own one child), and
    ``prim_patterned`` (N,), ``patterned``'s copy. ``depth``, static: the most patterns on a path
    from a primitive's node to a leaf; a point blends ``width ** depth`` leaves."""

    leaves: PackedMaterials
    selectors: PackedMaterials
    tables: dict
    depth: int
    width: int  # static: the most children a node blends at a point (2, or an average's entries)
    patterned: np.ndarray  # (N,) bool, static: the primitive's texture is patterned


register_packed(PackedTextures, ("leaves", "selectors", "tables"))


@dataclasses.dataclass
class _TextureRow:
    """A plain texture as :func:`pack_materials` reads a primitive (no interior)."""

    texture: Texture
    interior: None = None

    @property
    def transparent(self) -> bool:
        return all(layer.pigment.transparent for layer in self.texture.layers)


def pack_textures(prims, dtype) -> PackedTextures:
    """The patterned textures of primitives ``prims`` (each texture once, by identity)."""
    index: dict[int, int] = {}
    nodes: list[Texture] = []

    def visit(tex: Texture) -> int:
        if id(tex) not in index:
            index[id(tex)] = len(nodes)
            nodes.append(tex)
            for entry in tex.entries or ():
                visit(entry)
        return index[id(tex)]

    prim_node = np.array([visit(p.texture) for p in prims], np.int32)
    leaves = [t for t in nodes if not t.patterned]
    inner = [t for t in nodes if t.patterned]
    leaf_of = {id(t): i for i, t in enumerate(leaves)}
    selector_of = {id(t): i for i, t in enumerate(inner)}
    children: list[int] = []
    start = np.zeros(len(nodes), np.int32)
    size = np.ones(len(nodes), np.int32)
    for i, t in enumerate(nodes):
        start[i] = len(children)
        kids = [index[id(e)] for e in t.entries] if t.patterned else [i]
        size[i] = len(kids)
        children.extend(kids)
    n_nodes = bucket(len(nodes))
    patterned = np.array([p.texture.patterned for p in prims])
    tables = {
        "prim_patterned": pad_rows(patterned, bucket(len(prims)), False),
        "prim_node": pad_rows(prim_node, bucket(len(prims))),
        "node_leaf": pad_rows(np.array([leaf_of.get(id(t), -1) for t in nodes], np.int32), n_nodes),
        "node_selector": pad_rows(np.array([selector_of.get(id(t), 0) for t in nodes], np.int32), n_nodes),
        "node_start": pad_rows(start, n_nodes),
        "node_size": pad_rows(size, n_nodes),
        "children": pad_rows(np.array(children, np.int32), bucket(len(children))),
    }
    return PackedTextures(leaves=pack_materials(_PigmentRows([_TextureRow(t) for t in leaves]), dtype),
                          selectors=pack_pigments([t.pattern for t in inner], dtype), tables=tables,
                          depth=max(t.depth for t in inner), patterned=patterned,
                          width=max([2] + [len(t.entries) for t in inner
                                           if patterns.REGISTRY[t.pattern.pattern].averaged]))


def texture_pigments(textures: PackedTextures, leaf, p):
    """The pigments (layers, 5) of leaf ``leaf``'s layers at ``p`` and which layers it has."""
    leaves = textures.leaves
    rows = leaf * leaves.n_layers + jnp.arange(leaves.n_layers)
    return (jax.vmap(lambda r: pigment_at(leaves, r, p))(rows),
            jnp.asarray(leaves.tables["layer_present"])[leaf])


def texture_choice(textures: PackedTextures, prim, p):
    """The leaves (width ** depth,) a primitive's texture shows at world point ``p`` and their
    weights, which sum to 1: at each patterned node, its pattern's value there chooses the two
    entries around it and the fraction between them, as a pigment map chooses pigments (a block
    pattern: its entry by index); an ``average`` weighs every entry by its position. A plain
    texture: itself, with weight 1 (and 0 for the copies)."""
    tables = textures.tables
    nodes = jnp.asarray(tables["prim_node"])[prim][None]
    weights = jnp.ones((1,), p.dtype)
    for _ in range(textures.depth):
        kids, w = jax.vmap(lambda node: _node_choice(textures, node, p))(nodes)  # (n, width)
        nodes, weights = kids.reshape(-1), (weights[:, None] * w).reshape(-1)
    return jnp.asarray(tables["node_leaf"])[nodes], weights


def _node_choice(textures: PackedTextures, node, p):
    """The children (width,) of ``node`` its point ``p`` blends and their weights: the two around
    its pattern's value and the fraction between (the rest weigh 0), every child of an average,
    or the node itself for a leaf."""
    tables, sel, width = textures.tables, textures.selectors, textures.width
    row = jnp.asarray(tables["node_selector"])[node]
    size = jnp.asarray(tables["node_size"])[node]
    q = _pattern_point(sel, row, p)
    pid = jnp.asarray(sel.tables["pattern_id"])[row]
    v = jnp.zeros((), p.dtype)
    for k in _evaluated_patterns(sel):
        v = jnp.where(pid == k, _raw_value(sel, k, row, q), v)
    lo, hi, f = map_choice(sel, row, waved_value(sel, row, v), size)
    start = jnp.asarray(tables["node_start"])[node]
    children = jnp.asarray(tables["children"])
    f = f.astype(p.dtype)
    slots = jnp.arange(width)
    kids = children[start + jnp.where(slots == 1, hi, lo)]
    w = jnp.where(slots == 0, 1.0 - f, jnp.where(slots == 1, f, 0.0))
    averaged = [k for k, name in enumerate(sel.pattern_names) if patterns.REGISTRY[name].averaged]
    if averaged:  # every entry, weighed by its position
        m = sel.values.shape[-1]
        at = jnp.minimum(slots, size - 1)
        aw = jnp.where(slots < size, sel.values[row][jnp.minimum(slots, m - 1)], 0.0).astype(p.dtype)
        total = jnp.sum(aw)
        is_avg = jnp.isin(pid, jnp.asarray(averaged))
        kids = jnp.where(is_avg, children[start + at], kids)
        w = jnp.where(is_avg, aw / jnp.where(total != 0, total, 1.0), w)
    leaf = jnp.asarray(tables["node_leaf"])[node] >= 0
    return jnp.where(leaf, node, kids), jnp.where(leaf, (slots == 0).astype(p.dtype), w)


def _pack_entries(mats: PackedMaterials, pg_: list[dict], dtype) -> None:
    """``mats.entries``: every row's pigment-map pigments in one pack, and each row's first and
    count of them in ``mats.tables``."""
    flat: list[Pigment] = []
    start = np.zeros(len(pg_), np.int32)
    size = np.zeros(len(pg_), np.int32)
    for r, pg in enumerate(pg_):
        if pg["entries"] is not None:
            start[r], size[r] = len(flat), len(pg["entries"])
            flat.extend(pg["entries"])
    mats.entries = pack_pigments(flat, dtype)
    rows = mats.tables["pattern_id"].shape[0]
    mats.tables["map_start"] = pad_rows(start, rows)
    mats.tables["map_size"] = pad_rows(size, rows)


def _pack_images(mats: PackedMaterials, pg_: list[dict], dtype) -> None:
    """``mats.images``: the rows' images (each once), padded to the largest, and ``tables["image"]``."""
    by_id: dict[int, int] = {}
    images = []
    index = np.full(len(pg_), -1, np.int32)
    for r, pg in enumerate(pg_):
        im = pg["image"]
        if im is not None:
            if id(im) not in by_id:
                by_id[id(im)] = len(images)
                images.append(im)
            index[r] = by_id[id(im)]
    h = max(im.pixels.shape[0] for im in images)
    w = max(im.pixels.shape[1] for im in images)
    padded = [jnp.pad(im.pixels, ((0, h - im.pixels.shape[0]), (0, w - im.pixels.shape[1]), (0, 0)))
              if is_traced(im.pixels) else np.pad(np.asarray(im.pixels), ((0, h - im.pixels.shape[0]),
                                                                         (0, w - im.pixels.shape[1]), (0, 0)))
              for im in images]
    mats.images = stack(padded, dtype)
    modes = [(im.map_type, im.once, im.interpolate) for im in images]
    mats.image_modes = tuple(sorted(set(modes)))
    mats.tables["image"] = pad_rows(index, mats.tables["pattern_id"].shape[0])
    mats.tables["image_size"] = np.array([im.pixels.shape[:2] for im in images], np.int32)
    mats.tables["image_mode"] = np.array([mats.image_modes.index(m) for m in modes], np.int32)


def _image_at(mats: PackedMaterials, row, p):
    """RGBFT (5,) of row ``row``'s image map at world point ``p`` (semantics §5.6, measured with
    povray: u = frac(x), v = frac(y) planar; the nearest pixel ``floor(u W)``, ``floor((1 − v) H)``
    from the top; bilinear between pixel centres, wrapping). One lookup per way of wrapping the
    scene's images use, the image and its size read by index: the program does not grow with the
    number of images."""
    q = _pattern_point(mats, row, p)
    i = jnp.maximum(jnp.asarray(mats.tables["image"])[row], 0)
    h, w = jnp.asarray(mats.tables["image_size"])[i, 0], jnp.asarray(mats.tables["image_size"])[i, 1]
    mode = jnp.asarray(mats.tables["image_mode"])[i]
    out = jnp.zeros(5, p.dtype)
    for m, (map_type, once, interpolate) in enumerate(mats.image_modes):
        u, v, outside = _image_uv(q, map_type, once)
        if interpolate:
            x, y = u * w - 0.5, (1.0 - v) * h - 0.5
            x0, y0 = jnp.floor(x), jnp.floor(y)
            fx, fy = x - x0, y - y0
            c0, r0 = x0.astype(jnp.int32), y0.astype(jnp.int32)
            r1, c1 = (r0 + 1) % h, (c0 + 1) % w
            r0, c0 = r0 % h, c0 % w
            c = ((mats.images[i, r0, c0] * (1 - fx) + mats.images[i, r0, c1] * fx) * (1 - fy)
                 + (mats.images[i, r1, c0] * (1 - fx) + mats.images[i, r1, c1] * fx) * fy)
        else:
            col = jnp.clip(jnp.floor(u * w).astype(jnp.int32), 0, w - 1)
            r = jnp.clip(jnp.floor((1.0 - v) * h).astype(jnp.int32), 0, h - 1)
            c = mats.images[i, r, col]
        c = jnp.where(outside, jnp.asarray([0.0, 0.0, 0.0, 0.0, 1.0], p.dtype), c)
        out = jnp.where(mode == m, c, out)
    return out


def _image_uv(q, map_type: int, once: bool):
    """The image coordinates (u, v) in [0, 1) of pattern-space point ``q`` and whether it lies
    outside a ``once`` image."""
    if map_type == 0:
        u, v = q[0], q[1]
        outside = ((u < 0) | (u >= 1) | (v < 0) | (v >= 1)) if once else jnp.asarray(False)
        return u - jnp.floor(u), v - jnp.floor(v), outside
    # spherical, cylindrical: around y from +x
    ring = q[0] * q[0] + q[2] * q[2]
    ok = ring > 0
    u = jnp.where(ok, jnp.arctan2(jnp.where(ok, q[2], 0.0), jnp.where(ok, q[0], 1.0)), 0.0) / (2 * np.pi)
    if map_type == 1:  # the latitude, from the south pole
        s = safe_sqrt(ring)
        v = 0.5 + jnp.where(ok | (q[1] != 0), jnp.arctan2(q[1], jnp.where(ok, s, 1.0)), 0.0) / np.pi
        return u - jnp.floor(u), jnp.clip(v, 0.0, 1.0 - 1e-7), jnp.asarray(False)
    v = q[1]
    outside = ((v < 0) | (v >= 1)) if once else jnp.asarray(False)
    return u - jnp.floor(u), v - jnp.floor(v), outside


@dataclasses.dataclass
class PackedNormals:
    """The layers' ``normal {}`` by material row (``PackedMaterials``' rows; ``_normals.perturbed``
    reads them): their patterns as pigment rows (colours unused), amount (0 where a layer has
    none), accuracy, the linear part of world_from_pattern, and the gain of POV-Ray's own normal
    patterns (``Pattern.normal_gain``, ``normal_bias``; 0 for the others)."""

    patterns: PackedMaterials
    amount: jax.Array  # (R,)
    accuracy: jax.Array  # (R,)
    world_from_pattern: jax.Array  # (R, 3, 3)
    gain: jax.Array  # (R,)
    bias: jax.Array  # (R,) ``Pattern.normal_bias``
    # slope maps (``Normal.slope_map``) padded by their last entry to (R, K, 3), and their lengths
    # (R,) (0: none); None where no layer has one
    slope: jax.Array | None = None
    slope_size: jax.Array | None = None


register_packed(PackedNormals, ("patterns", "amount", "accuracy", "world_from_pattern", "gain", "bias",
                                "slope", "slope_size"))

_FLAT = Pigment.solid((0.0, 0.0, 0.0))


def pack_normals(layers: list[Layer], n_rows: int, dtype) -> PackedNormals:
    """``layers`` (one per material row) → their normals, padded to ``n_rows`` rows. A layer
    without a normal, or whose pattern does not perturb (``NORMAL_PATTERNS``), has amount 0."""
    bumps = [layer.normal if layer.normal is not None and layer.normal.pattern.pattern in NORMAL_PATTERNS
             else None for layer in layers]
    pigments = [_FLAT if b is None else b.pattern for b in bumps]
    eye = np.eye(3)
    return PackedNormals(
        patterns=pack_pigments(pigments, dtype),
        amount=pad_rows(stack([0.0 if b is None else b.amount for b in bumps], dtype), n_rows),
        accuracy=pad_rows(stack([0.02 if b is None else b.accuracy for b in bumps], dtype), n_rows),
        world_from_pattern=pad_rows(stack([eye if pg.transform is None else pg.transform.matrix[:3, :3]
                                           for pg in pigments], dtype), n_rows),
        gain=pad_rows(stack([patterns.REGISTRY[pg.pattern].normal_gain for pg in pigments], dtype), n_rows),
        bias=pad_rows(stack([patterns.REGISTRY[pg.pattern].normal_bias for pg in pigments], dtype), n_rows),
        **_slope_maps(bumps, n_rows, dtype),
    )


def _slope_maps(bumps, n_rows: int, dtype) -> dict:
    """``PackedNormals``' slope maps: each padded by its last entry (an identity map where none)."""
    maps = [None if b is None else b.slope_map for b in bumps]
    if all(m is None for m in maps):
        return {}
    identity = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    tables = [identity if m is None else m for m in maps]
    return {"slope": pad_rows(_padded(tables, max(t.shape[0] for t in tables), dtype), n_rows),
            "slope_size": pad_rows(np.array([0 if m is None else m.shape[0] for m in maps], np.int32),
                                   n_rows)}


def _structural_colors(pg: dict):
    """A pigment's colours as its structure renders them: an opaque pigment (``transparent`` False:
    no filter or transmit written) has filter and transmit 0 whatever its array holds, so the image
    does not depend on them and their gradient is zero (docs/gradients.md)."""
    c = pg["colors"]
    if pg["transparent"]:
        return c
    if is_traced(c):
        return jnp.concatenate([c[:, :3], jnp.zeros_like(c[:, 3:])], axis=1)
    if not np.any(c[:, 3:]):
        return c
    c = np.array(c)
    c[:, 3:] = 0
    return c


def _exact_spaces(world_from_pattern) -> np.ndarray:
    """(N,) bool: the row's pattern space is its world point times powers of two, plus an offset:
    a point exact in world is exact there too (no rotation, no other scale). Traced: all False."""
    if is_traced(world_from_pattern):
        return np.zeros(world_from_pattern.shape[0], bool)
    a = np.asarray(world_from_pattern)[:, :3, :3]
    diagonal = np.einsum("nii->ni", a)
    mantissa, _ = np.frexp(diagonal)
    off = a - np.einsum("ni,ij->nij", diagonal, np.eye(3))
    return np.all(off == 0, axis=(1, 2)) & np.all(np.abs(mantissa) == 0.5, axis=1)


@dataclasses.dataclass
class _PigmentRow:
    """A primitive as :func:`pack_materials` reads one: a texture of one layer, no interior."""

    texture: Texture
    interior: None = None
    transparent: bool = False


def pack_pigments(pigments, dtype) -> PackedMaterials:
    """Material rows 0 … n−1 holding ``pigments`` alone (one layer each, the default finish), for
    :func:`pigment_at` (a ``sky_sphere``'s pigments, evaluated at ray directions)."""
    rows = [_PigmentRow(Texture(layers=(Layer(pigment=pg),))) for pg in pigments]
    return pack_materials(_PigmentRows(rows), dtype)


@dataclasses.dataclass
class _PigmentRows:
    """What :func:`pack_materials` reads of a plan: its primitives."""

    prims: list


_ROW_ARRAYS = ("values", "colors", "pattern_from_world", "vector", "frequency", "phase", "turbulence",
               "omega", "lambda_")
_PRIM_ARRAYS = ("ior", "fade_distance", "fade_power", "fade_color")


def _padded_to_bucket(mats: PackedMaterials, n_prims: int) -> PackedMaterials:
    """``mats`` with its arrays padded to ``bucket(n_prims)`` primitives and its static tables'
    array copies (``PackedMaterials.tables``)."""
    n = bucket(n_prims)
    rows = n * mats.n_layers
    out = dataclasses.replace(
        mats,
        **{k: pad_rows(getattr(mats, k), rows) for k in _ROW_ARRAYS},
        **{k: pad_rows(getattr(mats, k), n) for k in _PRIM_ARRAYS},
        finish=FinishArrays(*(pad_rows(v, rows) for v in mats.finish)), exact_space=None)
    out.tables = {
        "layer_present": pad_rows(mats.layer_present, n, False),
        "pattern_id": pad_rows(mats.pattern_id, rows),
        "waves": pad_rows(mats.waves, rows),
        "fresnel": pad_rows(mats.fresnel, rows, False),
        "conserve_energy": pad_rows(mats.conserve_energy, rows, False),
        "transparent": pad_rows(mats.transparent, n, False),
        "exact_space": pad_rows(mats.exact_space, rows, False),
    }
    return out


register_packed(PackedMaterials, ("values", "colors", "pattern_from_world", "vector", "frequency", "phase",
                                  "turbulence", "omega", "lambda_", "finish", "ior", "fade_distance",
                                  "fade_power", "fade_color", "tables", "normals", "entries", "images",
                                  "textures"))


def _frequency(pg: dict):
    """A pigment's frequency (its fields), POV-Ray's default where it has none: 1, or 0 (none) for
    a discrete pattern."""
    if pg["frequency"] is not None:
        return pg["frequency"]
    return 0.0 if patterns.REGISTRY[pg["pattern"]].discrete else 1.0


def pat_wave_index(pg: Pigment) -> int:
    return WAVES.index(pg.wave)


def _color_map(v, values, colors):
    """Linear interpolation of all five channels; clamps outside the first/last entries (semantics §5.2)."""
    i = jnp.clip(jnp.searchsorted(values, v, side="right"), 1, values.shape[0] - 1)
    v0, v1 = values[i - 1], values[i]
    span = v1 - v0
    ok = span > 0
    s = jnp.where(ok, (v - v0) / jnp.where(ok, span, 1.0), 1.0)
    s = jnp.clip(s, 0.0, 1.0)
    c = colors[i - 1] * (1 - s) + colors[i] * s
    c = jnp.where(v <= values[0], colors[0], c)
    return jnp.where(v >= values[-1], colors[-1], c)


def pigment_at(mats: PackedMaterials, prim, p):
    """RGBFT (5,) pigment of material row ``prim`` (traced int; see ``PackedMaterials``) at world
    point ``p`` (3,). Every pattern of the scene is evaluated and the row's selected (one ray's
    code cannot branch under ``vmap``); :func:`pigments_at` evaluates only the row's pattern."""
    if _all_solid(mats):
        return mats.colors[prim, 0]
    q = _pattern_point(mats, prim, p)
    pid = jnp.asarray(mats.tables["pattern_id"])[prim]
    v = jnp.zeros((), p.dtype)
    for k in _evaluated_patterns(mats):
        v = jnp.where(pid == k, _raw_value(mats, k, prim, q), v)
    return _colour(mats, prim, p, v)


def _colour(mats: PackedMaterials, row, p, v):
    """RGBFT (5,) of row ``row`` at world point ``p`` whose pattern has raw value ``v``: its colour
    map's, or its pigment map's pigments at ``p`` blended."""
    c = _pigment_of_value(mats, row, v)
    if mats.images is not None:
        c = jnp.where(jnp.asarray(mats.tables["image"])[row] >= 0, _image_at(mats, row, p), c)
    if mats.entries is None:
        return c
    size = jnp.asarray(mats.tables["map_size"])[row]
    c = jnp.where(size > 0, _entries_at(mats, row, p, waved_value(mats, row, v), size), c)
    averaged = [k for k, name in enumerate(mats.pattern_names) if patterns.REGISTRY[name].averaged]
    if averaged:
        pid = jnp.asarray(mats.tables["pattern_id"])[row]
        c = jnp.where(jnp.isin(pid, jnp.asarray(averaged)) & (size > 0), _entries_mean(mats, row, p, size), c)
    return c


def _entries_mean(mats: PackedMaterials, row, p, size):
    """Row ``row``'s pigment map at ``p`` as ``average`` takes it: its pigments' mean weighted by
    their map positions (every pigment of the row in one vmapped evaluation)."""
    slots = jnp.arange(mats.values.shape[-1])
    weights = jnp.where(slots < size, mats.values[row], 0.0)
    rows = jnp.asarray(mats.tables["map_start"])[row] + jnp.minimum(slots, size - 1)
    c = jax.vmap(lambda r: pigment_at(mats.entries, r, p))(rows)
    total = jnp.sum(weights)
    return jnp.sum(weights[:, None] * c, axis=0) / jnp.where(total != 0, total, 1.0)


def map_bracket(values, w, size):
    """The two entries of a map around value ``w`` — ascending positions ``values``, of which the
    first ``size`` are the map's (the padding repeats the last) — and the fraction between them, as
    a colour map blends (semantics §5.2): ``(lo, hi, t)``, t 0 at or below the first position and
    1 at or above the last."""
    last = jnp.maximum(size - 1, 1)
    i = jnp.clip(jnp.searchsorted(values, w, side="right"), 1, last)
    lo, hi = jnp.minimum(i - 1, size - 1), jnp.minimum(i, size - 1)
    span = values[hi] - values[lo]
    ok = span > 0
    t = jnp.clip(jnp.where(ok, (w - values[lo]) / jnp.where(ok, span, 1.0), 1.0), 0.0, 1.0)
    below = w <= values[0]
    return jnp.where(below, 0, lo), jnp.where(below, jnp.minimum(1, size - 1), hi), jnp.where(
        below, 0.0, jnp.where(w >= values[size - 1], 1.0, t))


def _entries_at(mats: PackedMaterials, row, p, w, size):
    """Row ``row``'s pigment map at ``p`` for its waved value ``w``: the two pigments around ``w``
    blended as ``_color_map`` blends colours (a discrete pattern: its list entries by index, as
    ``_list_entry``)."""
    lo, hi, s = map_choice(mats, row, w, size)
    start = jnp.asarray(mats.tables["map_start"])[row]
    # the two pigments in one vmapped evaluation: the program holds the entries' patterns once
    c = jax.vmap(lambda r: pigment_at(mats.entries, r, p))(start + jnp.stack([lo, hi]))
    return c[0] * (1 - s) + c[1] * s


def map_choice(mats: PackedMaterials, row, w, size):
    """The two entries of row ``row``'s map (its first ``size``) around its waved value ``w`` and
    the fraction between them: ``map_bracket`` of the map's positions, or for a discrete pattern
    entry ``floor(w)`` and the next, by the fraction (``_list_entry``)."""
    pid = jnp.asarray(mats.tables["pattern_id"])[row]
    discrete = jnp.asarray([patterns.REGISTRY[name].discrete for name in mats.pattern_names])[pid]
    lo, hi, s = map_bracket(mats.values[row], w, size)
    # a list: entry floor(w) and the next, by the fraction
    x = jnp.clip(w, 0, size - 1)
    j = jnp.minimum(jnp.floor(x).astype(jnp.int32), size - 1)
    lo = jnp.where(discrete, j, lo)
    hi = jnp.where(discrete, jnp.minimum(j + 1, size - 1), hi)
    return lo, hi, jnp.where(discrete, x - j, s)


def _all_solid(mats: PackedMaterials) -> bool:
    return len(mats.pattern_names) == 1 and mats.pattern_names[0] == "solid"


def _evaluated_patterns(mats: PackedMaterials) -> list[int]:
    """Indices of the scene's patterns that have a value to compute: a solid colour is its map's
    only entry, and a pattern we do not render (the plan warned) shows its first colour."""
    return [k for k, name in enumerate(mats.pattern_names)
            if name != "solid" and patterns.REGISTRY[name].rendered]


def _pattern_point(mats: PackedMaterials, row, p):
    m = mats.pattern_from_world[row]
    return matvec(m[:3, :3], p) + m[:3, 3]


# float32 pattern-space points of a rotated or scaled space are exact to a few ulps of their size:
# a face the surface lies on (a rotated box's own faces) must not flicker between two cells
_FACE_ULPS = 4


def _raw_value(mats: PackedMaterials, k: int, row, q, warp: bool = True):
    """The raw value of the scene's pattern ``k`` (static) with row ``row``'s parameters at
    pattern-space point ``q``; ``warp`` False: ``q`` is already displaced by the row's turbulence
    (a pattern that uses its turbulence itself, as marble, still does)."""
    name = mats.pattern_names[k]
    turb = mats.turbulence[row] if mats.turbulent[k] else None
    if not warp and patterns.REGISTRY[name].turbulence == "warp":
        turb = None
    face_nudge = discrete_face_nudge(mats, row, q) if patterns.REGISTRY[name].discrete else None
    return patterns.pattern_value(name, q, mats.vector[row], turb, mats.octaves[name], mats.omega[row],
                                  mats.lambda_[row], face_nudge=face_nudge)


def discrete_face_nudge(mats: PackedMaterials, row, q):
    """What a discrete pattern of row ``row`` adds to pattern-space point ``q`` so that a face
    belongs to the cell above it: None (POV-Ray's 1e-10) in float64; in float32, 1e-10 where the
    row's space keeps exact points exact (its hit points are computed at the surface:
    ``_geometry.closest_hit``'s refine), else a few ulps of the point."""
    if q.dtype != jnp.float32:
        return None
    loose = _FACE_ULPS * jnp.finfo(q.dtype).eps * jnp.maximum(jnp.max(jnp.abs(q)), 1.0)
    return jnp.where(jnp.asarray(mats.tables["exact_space"])[row], patterns.FACE_NUDGE, loose)


def waved_value(mats: PackedMaterials, prim, v):
    """The value row ``prim``'s colour map looks up, of raw value ``v``: frequency and phase, then
    the row's wave."""
    # frequency / phase with POV's 1.00001 wrap (semantics §5.2 step 4), unless the frequency is 0:
    # a discrete pattern's (the index of its colour) unless the scene wrote one
    freq, phase = mats.frequency[prim], mats.phase[prim]
    w = jnp.fmod(v * freq + phase, 1.00001)
    w = jnp.where(w < 0, w - jnp.floor(w), w)
    v = jnp.where(freq != 0, w, v)
    wave = jnp.asarray(mats.tables["waves"])[prim]
    if np.any(mats.waves != 0):
        waved = jnp.stack([patterns.apply_wave(v, name) for name in WAVES])
        v = waved[wave]
    return v


def _pigment_of_value(mats: PackedMaterials, prim, v):
    """RGBFT (5,) of row ``prim`` whose pattern has raw value ``v``: frequency, phase, wave and
    colour map (or list entry); a solid row's colour whatever ``v``."""
    pid = jnp.asarray(mats.tables["pattern_id"])[prim]
    discrete = jnp.asarray([patterns.REGISTRY[name].discrete for name in mats.pattern_names])[pid]
    v = waved_value(mats, prim, v)
    kinds = [patterns.REGISTRY[name].discrete for name in mats.pattern_names if name != "solid"]
    if kinds and all(kinds):  # every pattern lists its colours (checker floors): no colour map
        c = _list_entry(v, mats.colors[prim])
    else:
        c = _color_map(v, mats.values[prim], mats.colors[prim])
        if any(kinds):
            c = jnp.where(discrete, _list_entry(v, mats.colors[prim]), c)
    return jnp.where(pid == _solid_index(mats), mats.colors[prim, 0], c)


PIGMENT_BLOCK = 512  # pigments_at: entries computed together (16,384 entries of two noise
#                      patterns, 69 % needed: 9.5 ms for every pattern everywhere, 5.8 ms in blocks
#                      of 512; blocks of 128 lost to their per-block cost)


def costly_patterns(mats: PackedMaterials) -> bool:
    """Whether the scene's pigments are worth computing by pattern (:func:`pigments_at`): it has
    turbulence or a noise pattern, whose values dominate a render where they filter shadows
    (``advanced/pawns``, ``incdemo/stones/stones1``: 65–70 % of the render's time)."""
    return any(mats.turbulent[k] or patterns.REGISTRY[mats.pattern_names[k]].noise
               for k in _evaluated_patterns(mats))


def pigments_at(mats: PackedMaterials, rows, points, needed):
    """RGBFT (M, 5) pigments of material rows ``rows`` (M,) at world points ``points`` (M, 3), each
    entry computing only its own row's pattern, and nothing where not ``needed`` (M,) bool (any
    value there). ``pigment_at`` computes every pattern of the scene for
    every entry; here the needed entries are grouped by pattern (a stable partition: counts, then
    each entry's rank in its group) and taken in blocks of ``PIGMENT_BLOCK``. A block computes the
    patterns it holds (``lax.cond``: one, except where two patterns' groups meet) and a block of
    entries not needed computes nothing. Values and derivatives are ``pigment_at``'s."""
    m = rows.shape[0]
    if _all_solid(mats):
        return mats.colors[rows, 0]
    pid = jnp.asarray(mats.tables["pattern_id"])[rows]
    kinds = _evaluated_patterns(mats)
    # groups: the patterns computed, then patterns we do not render (value 0, then the row's
    # frequency, phase, wave and map, as ``pigment_at``), then entries not needed and solid rows
    unrendered, nothing = len(kinds), len(kinds) + 1
    solid = pid == _solid_index(mats)
    key = jnp.where(needed & ~solid, unrendered, nothing).astype(jnp.int32)
    for j, k in enumerate(kinds):
        key = jnp.where(needed & (pid == k), j, key)
    member = key[:, None] == jnp.arange(nothing + 1)[None, :]  # (M, groups)
    counts = jnp.sum(member, axis=0, dtype=jnp.int32)
    rank = jnp.cumsum(member, axis=0, dtype=jnp.int32) - 1
    pos = (jnp.cumsum(counts) - counts)[key] + jnp.take_along_axis(rank, key[:, None], axis=1)[:, 0]
    n_blocks = -(-m // PIGMENT_BLOCK)
    size = n_blocks * PIGMENT_BLOCK  # positions past M: entry 0, in the group of nothing
    order = jnp.zeros((size,), jnp.int32).at[pos].set(jnp.arange(m, dtype=jnp.int32), unique_indices=True)
    keys = jnp.full((size,), nothing, jnp.int32).at[pos].set(key, unique_indices=True)
    order, keys = order.reshape(n_blocks, PIGMENT_BLOCK), keys.reshape(n_blocks, PIGMENT_BLOCK)

    def block(args):
        idx, key_b = args
        r, p = rows[idx], points[idx]
        q = jax.vmap(lambda r_, p_: _pattern_point(mats, r_, p_))(r, p)
        v = jnp.zeros(idx.shape, points.dtype)
        for j, k in enumerate(kinds):
            v = jax.lax.cond(jnp.any(key_b == j),
                             lambda v, j=j, k=k: jnp.where(key_b == j, jax.vmap(
                                 lambda r_, q_: _raw_value(mats, k, r_, q_))(r, q), v),
                             lambda v: v, v)
        return jax.vmap(lambda r_, p_, v_: _colour(mats, r_, p_, v_))(r, p, v)

    def block_or_first_colours(args):
        idx, key_b = args
        return jax.lax.cond(jnp.any(key_b < nothing), block, lambda a: mats.colors[rows[a[0]], 0], args)

    grouped = jax.lax.map(block_or_first_colours, (order, keys)).reshape(size, 5)
    return grouped[pos]  # entry e's pigment is at its position


def _list_entry(v, colors):
    """The colour a discrete pattern chooses (semantics §5.2): its value is the index of a list
    entry, taken by integer index — the entries sit at the fixed positions 0, 1, …, so the map's
    ``values`` play no part and a choice has no derivative with respect to them. A wave can map the
    index between two entries (``sine_wave`` takes a checker's 0 and 1 to 0.5: POV-Ray shows the
    mean of its two colours); the fraction then blends the two."""
    last = colors.shape[0] - 1
    x = jnp.clip(v, 0, last)
    i = jnp.floor(x).astype(jnp.int32)
    f = x - i
    return colors[i] * (1 - f) + colors[jnp.minimum(i + 1, last)] * f


def solid_rows(mats: PackedMaterials, rows: np.ndarray) -> np.ndarray:
    """Which of the material rows ``rows`` (static ints) are solid colours (static bools): their
    pigment is ``colors[row, 0]`` at every point (not a patterned texture's rows)."""
    solid = np.asarray(mats.pattern_id)[rows] == _solid_index(mats)
    if mats.textures is not None:
        solid &= ~mats.textures.patterned[np.asarray(rows) // mats.n_layers]
    return solid


def _solid_index(mats: PackedMaterials) -> int:
    return mats.pattern_names.index("solid") if "solid" in mats.pattern_names else -1
