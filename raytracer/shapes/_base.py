"""What every primitive shape is: one record holding all the rest of the system asks of it.

A shape is a frozen Equinox module (its array fields are the differentiable parameters, its static
fields the static variants) that also carries, as methods and class variables:

============================  ========================================================================
``kind``                      its name in plans, messages and the registry
``crossings``                 K, the crossings of a line it reports (slots of ``hits``)
``line_crossings``            surfaces a straight line can really cross (bounds straight passes)
``solid``                     whether it has an inside (usable in CSG; ``inside`` is meaningful)
``hits(o, d)``                every crossing of the line ``o + t d`` in object space: ``t`` (K,) of
                              any sign, ``+inf`` in empty slots, and unit outward normals (K, 3)
                              (an isosurface's: the first K ahead of ``o``, semantics §4.1)
``inside(p)``                 strictly inside the solid (POV-Ray semantics); False for non-solids
``bounds()``                  object-space ``(lo, hi)`` corners of a box holding the surface, or
                              None for unbounded shapes (planes, most quadrics); tight where
                              POV-Ray's is, since exact ties between coincident surfaces go to the
                              object whose box the ray enters first (semantics §4.4)
``pov_bounds_margin``         how much larger POV-Ray's box is (polygon, disc)
``sdl_keywords``              the SDL keywords that make it (``mesh``, ``mesh2``)
``sdl_arguments``             its comma-separated arguments, in order, as ``(field, "vector" | "float")``
``sdl_flags``                 bare object-modifier keywords that set a bool field (``open``)
``parse_sdl(keyword, args)``  reads its arguments after ``keyword {`` through :class:`ShapeArgs`
``from_sdl(fields)``          builds the shape from what ``parse_sdl`` returned
``to_mitsuba(m, camera)``     its exact Mitsuba 3 equivalent, or raises :class:`NoEquivalent`
``silhouette_margin(o, d)``   a smooth function of a line, positive where it crosses the shape
``item_margin(o, d, sub)``    the same for one native item (a mesh's triangle ``sub``)
``cull_to``, ``entry(o, d)``  a kernel too costly for every member of a group: the members a ray
                              crosses are the ``cull_to`` whose bounds it enters first (``entry``)
``faces``, ``face(p)``,       the smooth pieces of its surface and which one a point lies on; the
``face_distance(…)``          line's crossing with one piece's whole surface (creases, edges=True)
============================  ========================================================================

The renderer, the plan, the SDL interpreter and the Mitsuba converter ask these and the registry
(``raytracer.shapes.REGISTRY``); none of them names a shape. ``hits`` and ``inside`` handle ONE
ray and ONE shape; batch with ``jax.vmap`` over a stacked shape (``tree_map(jnp.stack, …)``).
"""

from __future__ import annotations

import abc
import re
from pathlib import Path
from typing import Any, ClassVar, NamedTuple, Protocol

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._build import Record, build


class NoEquivalent(Exception):
    """The shape (as placed) has no exact Mitsuba 3 equivalent.

    Attributes:
        feature: short name of what is missing (``"torus"``, ``"disc with a hole"``).
    """

    def __init__(self, feature: str, detail: str = ""):
        self.feature = feature
        self.detail = detail
        super().__init__(feature + (f" ({detail})" if detail else ""))


class MitsubaShape(NamedTuple):
    """A shape's Mitsuba equivalent in world space, as plain data (no Mitsuba import here).

    Attributes:
        entries: Mitsuba shape dictionaries; a ``"to_world"`` value is a (4, 4) numpy matrix (the
                 converter wraps it). Two entry types are not Mitsuba plugins but requests the
                 converter fulfils: ``"_mesh"`` (``vertices`` (F, 3, 3) world positions, ``normals``
                 (F, 3, 3) world vertex normals or None) and ``"_plane"`` (``point``, unit
                 ``normal``): an infinite plane, which Mitsuba lacks, stood in for by a large
                 rectangle under the camera.
        closed:  the entries enclose a volume (a dielectric interior is meaningful).
        planar:  flat surfaces (POV-Ray shades both sides).
    """

    entries: list[dict]
    closed: bool
    planar: bool


class ShapeArgs(Protocol):
    """What a shape's SDL parser may ask of the interpreter (``raytracer.sdl`` implements it).

    Values are evaluated expressions; every method raises the interpreter's ``SceneError`` with
    ``file:line:col`` on bad input.
    """

    @property
    def loc(self) -> Any:
        """Source location of the next token."""

    def float(self) -> float: ...

    def expr(self) -> Any:
        """Any expression's value (float, vector, colour, string)."""

    def describe_next(self) -> str:
        """The next token as an error message shows it (``'foo'``, ``end of file``)."""

    def vector(self, size: int = 3, *, allow_2d: bool = False) -> tuple[float, ...]:
        """A vector of ``size`` components; ``allow_2d`` also takes a 2-D vector (z = 0)."""

    def coefficients(self, count: int) -> tuple[float, ...]:
        """``<A1, …, A_count>``: exactly ``count`` numbers (more than a vector value holds)."""

    def count(self, what: str) -> int:
        """A non-negative whole number of ``what`` (bounded; an error names ``what``)."""

    def comma(self) -> None:
        """An optional comma."""

    def accept(self, op: str) -> bool:
        """Consumes the operator ``op`` if it is next."""

    def expect(self, op: str, what: str = "") -> None: ...

    def keyword(self, *names: str) -> str | None:
        """Consumes and returns the next identifier if it is one of ``names``."""

    def number_after_comma(self) -> bool:
        """Whether a comma follows and then a literal number (optional trailing indices)."""

    def texture(self, identifier: str | None = None) -> None:
        """Reads ``{…}`` of a ``texture`` (or a texture identifier) for the object being built;
        the first one given is used for the whole object (per-part textures are not rendered).
        With ``identifier`` (the list being read, ``texture_list``) only an identifier is accepted."""

    def skip_block(self) -> None:
        """Skips a ``{…}`` block."""

    def error(self, message: str, loc: Any = None) -> Exception:
        """The ``SceneError`` to raise (at ``loc``, default: the next token)."""

    def warn(self, feature: str, message: str, loc: Any = None) -> None: ...

    def find_file(self, name: str, what: str) -> str:
        """The path of the file ``name`` (a font), searched as an include file is; an error names
        ``what`` where it is not found."""

    def leave_out(self, message: str) -> None:
        """The object is dropped from the scene (with a warning naming it)."""

    def part(self, what: str) -> np.ndarray:
        """A part's modifiers up to and including its closing ``}`` (a blob component's): its
        transforms, returned as one (4, 4) matrix applied to the part's column points, and its
        ``texture``, ``pigment``, ``finish`` and ``normal``, which follow the rule of
        :meth:`texture` (the first part's texture for the whole object, warned)."""

    def function(self, n_args: int = 3) -> tuple[tuple, tuple[float, ...]]:
        """``function { … }`` compiled: ``(expression, constants)``
        (``raytracer.patterns._expression``), called with ``n_args`` arguments (x, y, z). A
        function using what is not compiled leaves the object out (warned)."""


SdlArguments = tuple[tuple[str, str], ...]  # (field, "vector" | "float"), in order


def array_module(*xs):
    """``jax.numpy`` if any input is a JAX array or tracer, else ``numpy`` (bounds stay cheap)."""
    return jnp if any(isinstance(x, jax.Array) for x in xs) else np


class AbstractShape(Record):
    """A primitive shape in its object space (see the module docstring for the interface)."""

    kind: ClassVar[str]
    crossings: ClassVar[int]
    solid: ClassVar[bool] = True
    bounded: ClassVar[bool] = True  # False: ``bounds`` is None (planes, quadrics, polynomials)

    @property
    def line_crossings(self) -> int:
        """Surfaces a straight line can cross (bounds the straight ior-1 passes of the plan)."""
        return type(self).crossings
    sdl_keywords: ClassVar[tuple[str, ...]] = ()
    sdl_arguments: ClassVar[SdlArguments] = ()  # (field, "vector" | "float") in order
    sdl_flags: ClassVar[tuple[str, ...]] = ()
    # POV-Ray's bounding box of the shape is this much larger on every side (world units; measured,
    # 8e-4 < m <= 1e-3 for polygon and disc). Only which of two coincident surfaces is seen
    # depends on it (semantics §4.4).
    pov_bounds_margin: ClassVar[float] = 0.0

    def n_crossings(self) -> int:
        """K for this instance (a mesh reports one crossing per triangle)."""
        return type(self).crossings

    @abc.abstractmethod
    def hits(self, o: Float[Array, "3"], d: Float[Array, "3"]) -> tuple[Float[Array, " K"], Float[Array, "K 3"]]:  # noqa: E501
        """Every crossing of the line ``o + t d`` (object space): ``t`` (K,), normals (K, 3)."""

    def inside(self, p: Float[Array, "3"]) -> Bool[Array, ""]:
        """False: a shape without an inside (triangles, polygons, meshes)."""
        return jnp.zeros((), bool)

    def bounds(self):
        """Object-space ``(lo (3,), hi (3,))``, or None when the shape is unbounded."""
        return None

    def silhouette_margin(self, o: Float[Array, "3"], d: Float[Array, "3"]) -> Float[Array, ""]:
        """A smooth function of the line ``o + t d`` (object space, ``d`` any length) that is positive
        where the line crosses the shape, negative where it misses it, and crosses zero with a
        nonzero slope where the two meet: the shape's outline as seen along ``d``. The boundary
        term of a pixel's derivative (``raytracer/_edges.py``) finds where it vanishes between two
        camera rays and, by its derivatives, how that place moves with the scene. Any positive
        multiple of one margin is as good (only its zero and the ratio of its derivatives count).
        A shape without one (the default) gets no boundary term at its outline (``has_margin``)."""
        raise NotImplementedError(f"{self.kind} has no silhouette margin")

    def item_margin(self, o: Float[Array, "3"], d: Float[Array, "3"], sub) -> Float[Array, ""]:
        """:meth:`silhouette_margin` of native item ``sub`` alone (a mesh's triangle: the boundary
        term knows which one a ray sees, ``Hit.sub``); by default the shape's own."""
        return self.silhouette_margin(o, d)

    def shows_inside(self) -> bool:
        """Whether a camera ray can see this surface from inside the solid and, across an edge of
        the surface itself, from outside (an open cylinder's rim: its outside on one side, the
        bore's wall on the other: one primitive on both sides); such a shape gives
        :meth:`rim_margin` (``edges=True``)."""
        return False

    def rim_margin(self, o: Float[Array, "3"], d: Float[Array, "3"]) -> Float[Array, ""]:
        """A smooth function of a line whose zero is where it passes through an edge of the surface
        (:meth:`shows_inside`), near the line: the boundary term's margin there."""
        raise NotImplementedError(f"{self.kind} shows no inside")

    def items_are_faces(self) -> bool:
        """Whether the shading may jump between neighbouring items (a flat mesh's triangles: the
        normal is each one's own), so that the boundary term sees a change of the item seen on the
        shape as an edge: a crease, or the shape's outline over itself (static; False: its items
        are pieces of one smooth surface, or the shape has one)."""
        return False

    def one_face(self, sub_a, sub_b) -> Bool[Array, ""]:
        """Whether items ``sub_a`` and ``sub_b`` (traced) lie in one face, across which the shading
        does not jump (a quad's two triangles); asked only where :meth:`items_are_faces`."""
        return jnp.ones((), bool)

    @classmethod
    def has_margin(cls) -> bool:
        """Whether the class gives :meth:`silhouette_margin` (or, per item, :meth:`item_margin`)."""
        return (cls.silhouette_margin is not AbstractShape.silhouette_margin
                or cls.item_margin is not AbstractShape.item_margin)

    # Creases: the smooth pieces of the surface between which its normal jumps (a box's six
    # faces; a closed cylinder's or cone's side and two discs). The boundary term sees a crease as
    # an edge where what is seen crosses from one face to another and their shading differs.
    faces: ClassVar[int] = 1

    def face(self, p: Float[Array, "3"]) -> Int[Array, ""]:
        """Which face the object-space surface point ``p`` lies on (0 …``faces`` − 1): any answer
        near a crease, a consistent one elsewhere. 0 for a shape of one face."""
        return jnp.zeros((), jnp.int32)

    def face_distance(self, o: Float[Array, "3"], d: Float[Array, "3"], face, t_ref) -> Float[Array, ""]:
        """The crossing of the line ``o + t d`` (object space) with face ``face``'s whole surface,
        extended past its edges (a box face's plane, a cylinder's unbounded side), nearest
        ``t_ref`` (held); ``+inf`` where it misses. A smooth function of the shape and the line:
        the difference of two faces' is zero where the line meets the crease between them, which
        is how the boundary term finds a crease and how it moves. Shapes with ``faces`` > 1
        define it."""
        raise NotImplementedError(f"{self.kind} has one face")

    # A group of more members than this computes the crossings of only the ``cull_to`` whose bounds
    # a ray enters first (``entry``), the others' slots empty (``shading/_geometry._culled``): for a
    # kernel so costly a ray cannot pay it for every member (an isosurface's march). None: all.
    cull_to: ClassVar[int | None] = None

    def entry(self, o: Float[Array, "3"], d: Float[Array, "3"]) -> Float[Array, ""]:
        """Where the line enters the shape's bounds ahead of ``o`` (0 from inside), +inf where it
        misses them: what ``cull_to`` orders a group's members by."""
        raise NotImplementedError(f"{self.kind} sets no cull_to: nothing orders its members")

    # The acceleration structure (``shading/_accel.py``) can choose among shapes that name one of
    # its native kernels. It only chooses: the hit is then computed again by ``sub_hits``.
    native_kernel: ClassVar[int | None] = None  # one of the NATIVE_* kernels below
    # its JAX kernel costs a ray far more than the hierarchy's query (a quartic's roots): one such
    # shape pays for the query alone, however few items the scene has (``_geometry.hierarchy_choice``)
    costly_kernel: ClassVar[bool] = False

    def native_items(self) -> tuple[Float[Array, "k 12"], Float[Array, "k V 3"]]:
        """The shape as ``k`` items of ``native_kernel`` (object space): their parameters (k, 12)
        (sphere: centre, radius; box: two corners; triangle: three vertices; frustum: base, base
        radius, cap, cap radius, open; disc: centre, normal, radius, hole radius; superellipsoid: e,
        n; zero padded) and
        points whose hull holds each item (k, V, 3) (its bounding box comes from them)."""
        raise NotImplementedError(f"{self.kind} has no native kernel")

    # rows of ITEM_PARAMS numbers one item takes (its map, then ``native_items``' parameters, 12 a
    # row after the first row's): a polynomial's 35 coefficients take 2
    native_rows: ClassVar[int] = 1

    def n_native_items(self) -> int:
        """k of ``native_items`` (static: from shapes alone)."""
        return 1

    def n_native_rows(self) -> int:
        """Rows an item of this shape (or of this stack of them) takes: ``native_rows`` unless its
        parameters' count depends on the shape (a prism's outline)."""
        return type(self).native_rows

    def kernel_form(self) -> tuple[object, object]:
        """``(kernel, arrays)``: shapes of several classes whose crossings one kernel
        ``kernel(arrays, o, d)`` computes from arrays of one structure name that kernel (a
        cylinder is a frustum with equal radii; ``open`` an array there, not a static field), so a
        query evaluates it once for groups of them all (``shading/_accel._alike``). Works on a
        shape or a stack of them. Default ``(None, self)``: the shape's own ``sub_hits``."""
        return None, self

    def near_hit(self, o: Float[Array, "3"], d: Float[Array, "3"], t0) -> tuple[Float[Array, " 1"], Float[Array, "1 3"]] | None:  # noqa: E501
        """The crossing at ``t0`` (finite: the native hierarchy's own solver found it, in double
        precision, without gradient), differentiable as ``hits`` is; or None (the default), when
        the hierarchy's choice is computed again by ``sub_hits``. For shapes whose every crossing
        costs a search (a superellipsoid's brackets: ~400 evaluations of its norm) and whose one
        crossing, given, costs two Newton steps."""
        return None

    def sub_hits(self, o: Float[Array, "3"], d: Float[Array, "3"], sub) -> tuple[Float[Array, " J"], Float[Array, "J 3"]]:  # noqa: E501
        """The crossings of native item ``sub`` (an index into ``native_items``): by default every
        crossing (the shape is one item); a mesh answers for the one triangle."""
        return self.hits(o, d)

    @classmethod
    def parse_sdl(cls, keyword: str, args: ShapeArgs) -> dict:
        """The fields read after ``keyword {`` (up to the object modifiers): by default the
        comma-separated ``sdl_arguments``; shapes with other syntax override this."""
        return read_arguments(cls, args)

    @classmethod
    def from_sdl(cls, fields: dict) -> AbstractShape:
        return build(cls, **fields)

    def to_mitsuba(self, world_from_object: np.ndarray, camera_origin: np.ndarray) -> MitsubaShape:
        raise NoEquivalent(self.kind, "no Mitsuba primitive; tessellation would be an approximation")

    def absorb_transform(self, world_from_object: np.ndarray) -> AbstractShape | None:
        """This shape with ``world_from_object`` (a concrete 4×4, at load time) folded into its own
        parameters, or None when it cannot be. A folded shape is intersected where it is, not
        through a ray moved into its object space: a float32 origin moved by a translation of
        1e6 keeps 1/16 of a unit. Textures are placed in world space, so only
        the geometry changes hands."""
        return None


def read_arguments(cls: type[AbstractShape], args: ShapeArgs) -> dict:
    """``cls.sdl_arguments``, comma-separated, as a dict of fields."""
    fields = {}
    for i, (name, kind) in enumerate(cls.sdl_arguments):
        if i:
            args.comma()
        fields[name] = args.vector() if kind == "vector" else args.float()
    return fields


# the kernels of raytracer/_native/bvh.cc
def native_kinds() -> dict[str, int]:
    """The native kernels' numbers, ``KIND_<NAME>`` → n, from ``raytracer/_native/kinds.h``: the one
    place both the C++ code and ours read them from."""
    text = (Path(__file__).resolve().parent.parent / "_native" / "kinds.h").read_text()
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"constexpr int KIND_(\w+) = (-?\d+);", text)}


_KINDS = native_kinds()
NATIVE_SPHERE, NATIVE_BOX, NATIVE_TRIANGLE = _KINDS["SPHERE"], _KINDS["BOX"], _KINDS["TRIANGLE"]
NATIVE_FRUSTUM, NATIVE_DISC, NATIVE_TORUS = _KINDS["FRUSTUM"], _KINDS["DISC"], _KINDS["TORUS"]
NATIVE_PLANE = _KINDS["PLANE"]  # unbounded: only a member of a CSG object the hierarchy holds (``_accel``)
NATIVE_SUPERELLIPSOID = _KINDS["SUPERELLIPSOID"]
NATIVE_QUADRIC = _KINDS["QUADRIC"]  # unbounded, as a plane: only a member of a CSG object the hierarchy holds
NATIVE_POLY = _KINDS["POLY"]  # unbounded, as a plane; two rows of parameters (``native_rows``)
NATIVE_PRISM = _KINDS["PRISM"]  # a swept outline over several rows (``n_native_rows``)
NATIVE_LATHE = _KINDS["LATHE"]  # a turned curve, laid out as a prism's item
NATIVE_BLOB = _KINDS["BLOB"]  # summed component fields over several rows (``n_native_rows``)
UNBOUNDED_KERNELS = frozenset({NATIVE_PLANE, NATIVE_QUADRIC, NATIVE_POLY})


def box_corners(lo, hi):
    """(8, 3): the corners of the box ``lo``–``hi``."""
    xp = array_module(lo, hi)
    return xp.stack([xp.stack([(lo, hi)[(i >> a) & 1][a] for a in range(3)]) for i in range(8)])


def native_params(*parts):
    """(1, 12): the parts (scalars and vectors) flattened and zero padded to 12 numbers (numpy when
    no part is a JAX array: ``_accel._items`` computes a small concrete group's items on the host)."""
    xp = array_module(*parts)
    flat = xp.concatenate([xp.reshape(xp.asarray(x), (-1,)) for x in parts])
    return xp.pad(flat, (0, 12 - flat.shape[0]))[None]


def disc_bounds(center, normal, radius):
    """The exact box of the disc of ``radius`` about ``center`` with normal ``normal`` (any
    nonzero length; a zero normal gives the cube of half-side ``|radius|``): its half-extent along
    axis k is ``|radius|·√(1 − n̂_k²)``."""
    xp = array_module(center, normal, radius)
    n2 = xp.asarray(normal) * xp.asarray(normal)
    s = n2.sum()
    frac = xp.where(s > 0, n2 / xp.where(s > 0, s, 1.0), 0.0)
    v = 1.0 - frac
    ok = v > 0
    half = xp.abs(radius) * xp.where(ok, xp.sqrt(xp.where(ok, v, 1.0)), 0.0)
    return center - half, center + half


def world_bounds(shape: AbstractShape, world_from_object=None):
    """World-space ``(lo, hi)`` of ``shape`` placed by ``world_from_object`` (4, 4), or None.

    The eight corners of the object-space box are transformed; the result holds the surface (it is
    exact for boxes under axis-aligned scales and translations, conservative otherwise).
    """
    b = shape.bounds()
    if b is None:
        return None
    lo, hi = b
    if world_from_object is None:
        return lo, hi
    xp = array_module(lo, hi, world_from_object)
    m = xp.asarray(world_from_object)
    corners = box_corners(lo, hi)
    pts = corners @ m[:3, :3].T + m[None, :3, 3]
    return pts.min(axis=0), pts.max(axis=0)


# ------------------------------------------------------------ plain-numpy helpers for to_mitsuba
def unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def frame(n) -> np.ndarray:
    """3×3 rotation whose third column is the unit vector ``n``."""
    n = unit(n)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = unit(np.cross(a, n))
    return np.stack([t, np.cross(n, t), n], axis=1)


def affine(linear, translation) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = linear
    m[:3, 3] = translation
    return m


def similarity_scale(m) -> float | None:
    """The uniform scale of a rotation·scale (+translation) matrix, or None if it is not one."""
    a = np.asarray(m, np.float64)[:3, :3]
    s2 = np.trace(a.T @ a) / 3.0
    if s2 <= 0 or not np.allclose(a.T @ a, s2 * np.eye(3), rtol=0.0, atol=1e-5 * s2):  # float32 input
        return None
    return float(np.sqrt(s2))


def apply_point(m, p) -> np.ndarray:
    return (np.asarray(m, np.float64) @ np.append(np.asarray(p, np.float64), 1.0))[:3]


def mesh_entry(triangles, normals, m) -> dict:
    """The ``"_mesh"`` request for (F, 3, 3) object-space triangles and optional vertex normals."""
    m = np.asarray(m, np.float64)
    tris = np.asarray(triangles, np.float64)
    world = tris @ m[:3, :3].T + m[:3, 3]
    nw = None
    if normals is not None:
        normals = np.asarray(normals, np.float64)
        if not np.allclose(np.linalg.norm(normals, axis=-1), 1.0, rtol=1e-5):
            raise NoEquivalent("smooth triangle normals that are not unit length",
                               "POV interpolates unnormalised normals, Mitsuba normalises")
        nw = normals @ np.linalg.inv(m[:3, :3])  # the inverse transpose, row vectors
        nw = nw / np.linalg.norm(nw, axis=-1, keepdims=True)
    return {"type": "_mesh", "vertices": world, "normals": nw}
