"""The render plan: what the scene's *structure* asks the tracer to simulate.

Everything here is decided from static structure (object kinds, which optional fields are
present, static flags), never from array values, so it can be computed at trace time from a
scene whose leaves are tracers. The tracer is traced from this plan: absent primitives, absent
effects and unreachable recursion levels do not exist in the compiled program.

Flattening turns the object tree into *leaves* (one per primitive, with its transform composed
from all ancestors, its resolved texture and interior, and its CSG visibility conditions) and
inside-test trees for the CSG conditions and ``clipped_by``.
"""

from __future__ import annotations

import dataclasses

from . import patterns
from ._gc import without_collections
from ._packing import bucket
from .errors import SceneError, SceneWarning
from .scene import (
    CSG,
    AbstractObject,
    Interior,
    Light,
    Object,
    Scene,
    Texture,
    Transform,
)
from .scene._lights import light_effects
from .scene._transform import compose
from .scene.environment import environment_of

# straight (ior 1) surfaces a ray path may cross beyond max_trace_level: as many as the scene's
# straight-transmitting primitives can put on one line, up to this bound (the plan warns beyond it)
STRAIGHT_PASSES = 256
EXACT_STRAIGHT_PASSES = 16  # more are rounded up to a ``_packing.bucket`` size
MEDIA_SLOTS = 16  # at most this many interiors in a ray's list (POV-Ray's list has no bound)

SUPPORTED_PATTERNS = patterns.RENDERED  # registered patterns the renderer evaluates
# patterns a ``normal {}`` perturbs with: the continuous ones (a discrete pattern's normal lists are
# not rendered)
NORMAL_PATTERNS = frozenset(n for n, r in patterns.REGISTRY.items()
                            if r.rendered and not (r.discrete or r.averaged or r.imaged)) - {"solid"}


# ---------------------------------------------------------------- inside-test trees (static)
@dataclasses.dataclass(frozen=True)
class InPrim:
    """Inside test of primitive ``prim`` (index into ``Plan.prims``), negated when ``inverse``."""

    prim: int
    inverse: bool


@dataclasses.dataclass(frozen=True)
class InAll:
    terms: tuple[InsideTree, ...]
    inverse: bool = False


@dataclasses.dataclass(frozen=True)
class InAny:
    terms: tuple[InsideTree, ...]
    inverse: bool = False


@dataclasses.dataclass(frozen=True)
class InDiff:
    """Inside the first term and outside all others (``difference``)."""

    terms: tuple[InsideTree, ...]
    inverse: bool = False


InsideTree = InPrim | InAll | InAny | InDiff


def _texture_pigments(texture):
    """Every pigment a texture evaluates: its layers' (pigment maps' too) and its patterns'."""
    for tex in texture.textures():
        if tex.patterned:
            yield tex.pattern
        else:
            for layer in tex.layers:
                yield from layer.pigment.pigments()


def has_box(tree: InsideTree, prims) -> bool:
    """Whether POV-Ray's box of the object ``tree`` (its primitives ``prims``) is finite
    (semantics §4.4; ``shading._geometry.unit_boxes`` computes it): a primitive's unless its shape
    is unbounded (a plane, a quadric, a polynomial), an intersection's as soon as one part that is
    not inverted has one (a clipped object is the intersection with its clipping objects), a
    union's or merge's when all parts' are, a difference's when its first part's is."""
    if isinstance(tree, InPrim):
        return type(prims[tree.prim].obj.shape).bounded
    if isinstance(tree, InAll):
        return any(has_box(t, prims) and not t.inverse for t in tree.terms)
    if isinstance(tree, InAny):
        return all(has_box(t, prims) for t in tree.terms)
    return has_box(tree.terms[0], prims) and not tree.terms[0].inverse


@dataclasses.dataclass(frozen=True)
class Condition:
    """A hit on a leaf counts only if the point is inside (``want=True``) or outside ``tree``."""

    tree: InsideTree
    want: bool


@dataclasses.dataclass(frozen=True)
class Prim:
    """One primitive instance after flattening.

    Attributes:
        obj:        the ``Object`` (its shape holds the parameters; its own transform is NOT the
                    full transform: use ``transforms``).
        transforms: the chain of transforms, innermost first (object's own, then ancestors').
        texture:    resolved texture (own, else the nearest ancestor's, else the default).
        interior:   resolved interior, or None.
        rendered:   whether its surface can be hit (False for ``clipped_by`` objects).
        inverse:    whether its normals are turned inwards: its own ``inverse``, CSG inverses,
                    and being subtracted in a ``difference`` (inside tests use the CSG trees).
        conditions: CSG / clipping conditions a hit must satisfy.
        flags:      frozenset of POV object flags ("no_shadow", "no_image", "no_reflection",
                    "double_illuminate").
        bounds:     per enclosing object without a box of its own that has ``bounded_by``, the
                    primitives of its bounding objects: a ray sees the primitive only if it
                    crosses one of each (POV-Ray's ``bounded_by``, semantics §4.4).
    """

    obj: Object
    transforms: tuple[Transform, ...]
    texture: Texture
    interior: Interior | None
    rendered: bool
    inverse: bool
    conditions: tuple[Condition, ...]
    flags: frozenset[str]
    bounds: tuple[tuple[int, ...], ...] = ()

    @property
    def kind(self) -> str:
        return self.obj.shape.kind

    @property
    def transparent(self) -> bool:
        """Every layer of its texture can let light through (filter or transmit): it transmits
        rays, and a shadow ray is filtered at its crossings instead of blocked. (Asked of every
        primitive by the plan and both packings: computed once; ``functools.cached_property``
        takes a lock per read in Python 3.11.)"""
        known = self.__dict__.get("_transparent")
        if known is None:
            # (a patterned texture: where one of its textures is)
            known = self.__dict__["_transparent"] = any(
                all(layer.pigment.transparent for layer in leaf.layers) for leaf in self.texture.leaves())
        return known

    @property
    def discrete(self) -> bool:
        """Some layer's pigment is a discrete pattern (checker, brick, hexagon …): a face at an
        exact coordinate decides its colour, so its hit points are computed at the surface
        (``shading._geometry.closest_hit``'s ``refine``)."""
        return any(patterns.REGISTRY[pg.pattern].discrete for pg in _texture_pigments(self.texture))

    @property
    def fades(self) -> bool:
        """Its interior attenuates light over distance (``fade_distance``; ``fade_power`` defaults to 0,
        which fades transmitted rays by half, semantics §2.7)."""
        it = self.interior
        return it is not None and it.fade_distance is not None

    def world_from_object(self) -> Transform | None:
        return compose(*self.transforms)


@dataclasses.dataclass(frozen=True)
class Effects:
    """What the compiled tracer simulates (derived from the scene structure only).

    Attributes:
        kinds:          primitive kinds present (rendered or used in inside tests).
        shadows:        some light casts shadows.
        filtered_shadows: some shadow-casting object can be transparent (shadow rays filter).
        reflection:     some finish has ``reflection``.
        transmission:   some pigment can carry filter/transmit (rays continue through surfaces).
        refraction:     some interior has an ``ior`` (transmitted rays bend).
        highlights:     some finish has phong or specular.
        metallic:       some finish has the highlight ``metallic``.
        reflection_metallic: some reflection has ``metallic`` (its tint by the pigment).
        fresnel:        some reflection uses ``fresnel``.
        fade:           some light fades with distance.
        spotlights:     some light is a spotlight.
        area_lights:    some light has area-sampled shadows.
        parallel_lights: some light is parallel.
        patterns:       pigment patterns present.
        csg:            some hit must pass CSG/clipping conditions.
        interior_fade:  some interior fades light travelling inside.
        straight_passes: extra levels for straight (ior 1) transmission, which POV-Ray does not
                        count against ``max_trace_level``.
        depth:          levels the tracer unrolls: 1 without secondary rays, else
                        ``max_trace_level + straight_passes``.
        media_slots:    the length of a ray's interior list: 0 without refraction, else as many
                        entries as the scene can put in it at once, at most ``MEDIA_SLOTS``.
        environment:    the environment effects the scene switches on (``scene.ENVIRONMENT``'s
                        names, in its order: ``sky_sphere``, rays that hit nothing see it, its
                        pigments' patterns in ``patterns`` too; ``fog``, rays outside objects go
                        through it, and with transmission keep their interior list to know).
        normals:        the patterns of the layers' ``normal {}`` perturbations (none: the shading
                        normal is the surface's).
        texture_depth:  through how many patterns a point's texture is chosen (``texture_map``,
                        ``checker texture {…} texture {…}`` …, nested): 0 without patterned
                        textures; a hit then shades width ** texture_depth textures and blends
                        them (width 2, or an ``average``'s entries).
    """

    kinds: tuple[str, ...]
    shadows: bool
    filtered_shadows: bool
    reflection: bool
    transmission: bool
    refraction: bool
    highlights: bool
    metallic: bool
    reflection_metallic: bool
    fresnel: bool
    fade: bool
    spotlights: bool
    area_lights: bool
    parallel_lights: bool
    patterns: tuple[str, ...]
    csg: bool
    interior_fade: bool
    straight_passes: int
    depth: int
    media_slots: int = 0
    environment: tuple[str, ...] = ()
    normals: tuple[str, ...] = ()
    texture_depth: int = 0

    @property
    def sky_sphere(self) -> bool:
        return "sky_sphere" in self.environment

    @property
    def fog(self) -> bool:
        return "fog" in self.environment

    @property
    def secondary_rays(self) -> bool:
        return self.depth > 1

    def describe(self) -> str:
        on = [name for name in ("shadows", "filtered_shadows", "reflection", "transmission",
                                "refraction", "highlights", "metallic", "reflection_metallic",
                                "fresnel", "fade", "spotlights", "area_lights", "parallel_lights",
                                "csg", "interior_fade") if getattr(self, name)] + list(self.environment)
        return (f"primitives: {', '.join(self.kinds) or 'none'}; effects: {', '.join(on) or 'none'}; "
                f"patterns: {', '.join(self.patterns) or 'none'}; "
                + (f"normals: {', '.join(self.normals)}; " if self.normals else "")
                + (f"patterned textures: {self.texture_depth} deep; " if self.texture_depth else "")
                + f"depth: {self.depth}"
                + (f" (incl. {self.straight_passes} straight passes)" if self.straight_passes else ""))


def _media_slots(prims, rendered) -> int:
    """How many interiors a ray's list can hold at once: those around the camera (at most one per
    primitive) and one per entry into a transparent primitive not yet left (a transmitted ray only
    enters a transparent surface; it cannot enter one twice without leaving it). Whitted-style
    scenes need a few slots instead of ``MEDIA_SLOTS``: each slot is carried, gathered and
    compacted with every ray of the tree."""
    return min(MEDIA_SLOTS, len(prims) + sum(1 for p in rendered if p.transparent))


@dataclasses.dataclass(frozen=True)
class Plan:
    """The flattened scene: primitives, lights, effects, warnings, the inside tree of each
    top-level object (``roots``, in ``scene.objects`` order; used by ``inside()`` queries), and
    the objects POV-Ray bounds separately (``units``, whose bounding boxes decide exact ties
    between coincident surfaces; semantics §4.4)."""

    prims: tuple[Prim, ...]
    lights: tuple[Light, ...]
    effects: Effects
    warnings: tuple[SceneWarning, ...]
    roots: tuple[InsideTree, ...] = ()
    units: tuple[InsideTree, ...] = ()  # bounding units (``bounding_units``), as inside trees
    prim_unit: tuple[int, ...] = ()  # the unit of every primitive


# ---------------------------------------------------------------- flattening
_FLAGS = ("no_shadow", "no_image", "no_reflection", "double_illuminate")


def _made(cls, **fields):
    """``cls(**fields)`` for a frozen dataclass without ``__post_init__``, made as ``pickle`` makes
    one (its ``__dict__`` filled): a frozen dataclass's ``__init__`` sets each field through
    ``object.__setattr__``, ~1 µs a field for the 10^5 primitives of a large scene."""
    self = object.__new__(cls)
    self.__dict__.update(fields)
    return self


class _Flattener:
    def __init__(self):
        self.prims: list[Prim] = []
        # the inside trees of the ``bounded_by`` objects of an object without a box of its own, by
        # the id of its inside tree: primitives that are not rendered and that no condition names,
        # only their box is used (``bounding_units``)
        self.bounds: dict[int, tuple[InsideTree, ...]] = {}

    def _with_bounds(self, tree: InsideTree, obj, chain, interior, start: int) -> InsideTree:
        """``tree``, its object's ``bounded_by`` objects kept where it has no box of its own: an
        object with a box keeps it (the hint is a hint: no primitives added for it). Without one,
        POV-Ray shows the object only to rays that cross its bound (measured: a ray that does
        sees all of it, also where it leaves the bound), so its primitives (``start`` on) name
        the bound's (``Prim.bounds``)."""
        if obj.bounded_by and not has_box(tree, self.prims):
            end = len(self.prims)
            self.bounds[id(tree)] = trees = self._clip_trees(obj.bounded_by, chain, interior)
            bound = tuple(sorted(set().union(*(leaf_prims(t) for t in trees))))
            for k in range(start, end):
                p = self.prims[k]
                self.prims[k] = dataclasses.replace(p, bounds=p.bounds + (bound,))
        return tree

    def flatten(self, obj: AbstractObject, *, transforms, texture, interior, rendered, inverse,
                conditions, flags) -> InsideTree:
        """Adds ``obj``'s primitives; returns the inside tree of ``obj`` (in its final placement)."""
        if obj.no_shadow or obj.no_image or obj.no_reflection or obj.double_illuminate:
            flags = flags | {f for f in _FLAGS if getattr(obj, f)}
        obj_inverse = inverse != obj.inverse
        if isinstance(obj, Object):
            chain = ((obj.transform,) if obj.transform is not None else ()) + transforms
            clip_trees = self._clip_trees(obj.clipped_by, chain, interior) if obj.clipped_by else ()
            clip_conds = tuple(Condition(t, True) for t in clip_trees)
            index = len(self.prims)
            self.prims.append(_made(
                Prim, obj=obj, transforms=chain,
                texture=obj.texture if obj.texture is not None else texture,
                interior=obj.interior if obj.interior is not None else interior,
                rendered=rendered, inverse=obj_inverse, conditions=conditions + clip_conds,
                flags=frozenset(flags)))
            return self._with_bounds(_clipped(_made(InPrim, prim=index, inverse=obj_inverse), clip_trees),
                                     obj, chain, interior, index)
        if isinstance(obj, CSG):
            chain = ((obj.transform,) if obj.transform is not None else ()) + transforms
            tex = obj.texture if obj.texture is not None else texture
            inter = obj.interior if obj.interior is not None else interior
            start = len(self.prims)
            clip_trees = self._clip_trees(obj.clipped_by, chain, inter)
            clip_conds = tuple(Condition(t, True) for t in clip_trees)
            # First pass: inside trees of every child (primitives are appended in order).
            trees = []
            spans = []
            for child in obj.children:
                s = len(self.prims)
                trees.append(self.flatten(child, transforms=chain, texture=tex, interior=inter,
                                          rendered=rendered, inverse=False, conditions=(),
                                          flags=flags))
                spans.append((s, len(self.prims)))
            # Second pass: each child's primitives get the visibility conditions of this node.
            for i, (s, e) in enumerate(spans):
                conds = self._csg_conditions(obj.operation, i, trees) + clip_conds + conditions
                # the node's inverse flips its primitives' normals (inside trees carry it on the
                # node itself); so does being subtracted: A - B is A ∩ inverse(B), and the
                # cavity B leaves has B's normals turned inwards — without that, a ray leaving
                # hollow glass through the cavity wall would be taken for one entering it
                flip = obj_inverse != (obj.operation == "difference" and i > 0)
                for k in range(s, e):
                    p = self.prims[k]
                    self.prims[k] = dataclasses.replace(
                        p, conditions=p.conditions + conds, inverse=p.inverse != flip)
            node = {"union": InAny, "merge": InAny, "intersection": InAll,
                    "difference": InDiff}[obj.operation]
            return self._with_bounds(_clipped(node(tuple(trees), inverse=obj_inverse), clip_trees),
                                     obj, chain, inter, start)
        raise SceneError(f"not a scene object: {type(obj).__name__}")

    @staticmethod
    def _csg_conditions(operation: str, i: int, trees: list[InsideTree]) -> tuple[Condition, ...]:
        if operation == "union":  # (before the list of the others: a union of n children made
            return ()             # n² of them, advanced/isocacti's 36,000: 3.5 s a plan)
        others = [t for j, t in enumerate(trees) if j != i]
        if operation == "merge":
            return tuple(Condition(t, False) for t in others)
        if operation == "intersection":
            return tuple(Condition(t, True) for t in others)
        # difference: the first child's surface outside all others; a cut surface inside the first
        if i == 0:
            return tuple(Condition(t, False) for t in others)
        return (Condition(trees[0], True),) + tuple(Condition(t, False) for j, t in enumerate(trees)
                                                    if j not in (0, i))

    def _clip_trees(self, clips, chain, interior) -> tuple[InsideTree, ...]:
        return tuple(self.flatten(clip, transforms=chain, texture=Texture(), interior=interior,
                                  rendered=False, inverse=False, conditions=(), flags=frozenset())
                     for clip in clips)


def leaf_prims(tree: InsideTree) -> set[int]:
    """The primitives an inside tree tests."""
    if isinstance(tree, InPrim):
        return {tree.prim}
    return set().union(*(leaf_prims(t) for t in tree.terms))


def _clipped(tree: InsideTree, clip_trees: tuple[InsideTree, ...]) -> InsideTree:
    """A clipped object is inside where its own solid (with its ``inverse``) and every clipping
    object are (POV-Ray's inside test checks the clipping objects first, uninverted)."""
    return InAll((tree, *clip_trees)) if clip_trees else tree


def bounding_units(objects, roots, n_prims: int,
                   bounds: dict | None = None) -> tuple[tuple[InsideTree, ...], tuple[int, ...]]:
    """The objects POV-Ray puts in its bounding hierarchy, each as its inside tree (from which
    its box follows: ``shading._geometry.unit_boxes``), and the unit of every primitive.

    A top-level object is one unit, except that a ``union`` without ``inverse``, ``clipped_by``
    or ``bounded_by`` is split into its children, recursively (POV-Ray's ``split_union``, on by
    default; measured with povray 3.7, semantics §4.4). ``merge``, ``intersection`` and
    ``difference`` are never split. Clipping objects belong to the unit they clip. A unit with
    ``bounded_by`` objects (``bounds``: their trees by the id of the unit's tree) is their overlap
    with its own tree, for its box only: its objects' conditions do not name them (the bounds of
    an object inside a unit only belong to it)."""
    units: list[InsideTree] = []
    bounds = bounds or {}

    def split(obj, tree):
        if (isinstance(obj, CSG) and obj.operation == "union" and not obj.inverse and not obj.clipped_by
                and not obj.bounded_by):
            for child, term in zip(obj.children, tree.terms, strict=True):
                split(child, term)
        elif id(tree) in bounds:
            units.append(InAll((tree, *bounds[id(tree)])))
        else:
            units.append(tree)

    for obj, tree in zip(objects, roots, strict=True):
        if type(tree) is InPrim and id(tree) not in bounds:  # a primitive on its own (most objects)
            units.append(tree)
        else:
            split(obj, tree)
    unit_of: dict[int, int] = {}

    def mark(tree, u):
        if isinstance(tree, InPrim):
            unit_of.setdefault(tree.prim, u)
        else:
            for term in tree.terms:
                mark(term, u)
        for bound in bounds.get(id(tree), ()):
            mark(bound, u)

    for u, tree in enumerate(units):
        if type(tree) is InPrim:
            unit_of.setdefault(tree.prim, u)
        else:
            mark(tree, u)
    return tuple(units), tuple(unit_of[i] for i in range(n_prims))


@without_collections  # 10^5 primitives make no cycles (raytracer/_gc.py)
def make_plan(scene: Scene) -> Plan:
    """Flattens ``scene`` and derives its :class:`Effects` (structure only; safe under jit)."""
    fl = _Flattener()
    default_texture = Texture()
    roots = tuple(fl.flatten(obj, transforms=(), texture=default_texture, interior=None, rendered=True,
                             inverse=False, conditions=(), flags=frozenset()) for obj in scene.objects)
    prims = tuple(fl.prims)
    warnings = list(scene.warnings)
    rendered = [p for p in prims if p.rendered]
    # each texture, pigment and finish once (by identity: a declared one is shared by many objects)
    textures = list({id(t): t for p in rendered for t in p.texture.textures()}.values())
    layers = [layer for tex in textures if not tex.patterned for layer in tex.layers]
    finishes = list({id(layer.finish): layer.finish for layer in layers}.values())
    # (a pigment map's pigments too: their patterns are evaluated as well)
    pigments = list({id(pg): pg for layer in layers for pg in layer.pigment.pigments()}.values())
    pigments += [tex.pattern for tex in textures if tex.patterned]  # the patterns that choose textures
    if any(len(tex.layers) > 1 and sum(layer.finish.reflection is not None for layer in tex.layers) > 1
           for tex in textures):
        warnings.append(SceneWarning("layered texture", "layered textures: lower layers' reflections "
                                     "are traced along the top layer's mirror ray with its exponent"))
    if any("double_illuminate" in p.flags for p in rendered):
        warnings.append(SceneWarning("double_illuminate", "double_illuminate is not rendered"))
    environment = environment_of(scene)
    sky = [pg for e, v in environment if e.pigments is not None
           for pig in e.pigments(v) for pg in pig.pigments()]
    for pig in [*pigments, *sky]:
        if pig.pattern not in SUPPORTED_PATTERNS:
            warnings.append(SceneWarning(pig.pattern, f"pattern {pig.pattern!r} is not rendered"))
    bumps = list({id(layer.normal): layer.normal for layer in layers if layer.normal is not None}.values())
    for bump in bumps:
        if bump.pattern.pattern not in NORMAL_PATTERNS:
            warnings.append(SceneWarning("normal", f"normal pattern {bump.pattern.pattern!r} is not "
                                         "rendered; the surface's normal is used"))
    lights = scene.lights
    shadow_lights = [lt for lt in lights if not lt.shadowless]
    reflection = any(f.reflection is not None for f in finishes)
    transmission = any(pig.transparent for pig in pigments)
    refraction = transmission and any(p.interior is not None and p.interior.ior is not None
                                      for p in rendered)
    # POV-Ray lets rays pass ior-1 surfaces without using a level: as many passes as the
    # straight-transmitting primitives can make along one line (levels with no live ray cost a
    # test, ``_scheduler._shade_pool``)
    straight_prims = [p for p in rendered if transmission and p.transparent
                      and (p.interior is None or p.interior.ior is None)]
    straight_passes = sum(p.obj.shape.line_crossings for p in straight_prims)
    if straight_passes > STRAIGHT_PASSES:
        warnings.append(SceneWarning("straight transmission", (
            f"rays can cross up to {straight_passes} ior-1 transparent surfaces; those past "
            f"{STRAIGHT_PASSES} beyond max_trace_level are not traced")))
        straight_passes = STRAIGHT_PASSES
    elif straight_passes > EXACT_STRAIGHT_PASSES:
        # a count in the bucket of the scene's count (levels with no live ray cost a test): scenes
        # that differ only in their number of transparent items share one program
        straight_passes = min(bucket(straight_passes), STRAIGHT_PASSES)
    depth = scene.settings.max_trace_level + straight_passes if (reflection or transmission) else 1
    casters = [p for p in prims if p.rendered and "no_shadow" not in p.flags]
    effects = Effects(
        kinds=tuple(sorted({p.kind for p in prims})),
        shadows=bool(shadow_lights) and bool(casters),
        filtered_shadows=any(layer.pigment.transparent for p in casters for leaf in p.texture.leaves()
                             for layer in leaf.layers),
        reflection=reflection,
        transmission=transmission,
        refraction=refraction,
        highlights=any(f.phong is not None or f.specular is not None for f in finishes),
        metallic=any(f.metallic is not None for f in finishes),
        reflection_metallic=any(f.reflection is not None and f.reflection.metallic is not None
                                for f in finishes),
        fresnel=any(f.reflection is not None and f.reflection.fresnel for f in finishes),
        **light_effects(lights),  # fade, spotlights, area_lights, parallel_lights: from LIGHT_TYPES
        patterns=tuple(sorted({pig.pattern for pig in [*pigments, *sky]})),
        csg=any(p.conditions for p in prims),
        interior_fade=transmission and any(p.fades for p in rendered),
        straight_passes=straight_passes,
        depth=depth,
        # a fog needs to know which rays are inside objects (those have none)
        media_slots=(_media_slots(prims, rendered)
                     if refraction or (transmission and any(e.needs_media for e, _ in environment)) else 0),
        environment=tuple(e.name for e, _ in environment),
        normals=tuple(sorted({b.pattern.pattern for b in bumps if b.pattern.pattern in NORMAL_PATTERNS})),
        texture_depth=max((tex.depth for tex in textures), default=0),
    )
    units, prim_unit = bounding_units(scene.objects, roots, len(prims), fl.bounds)
    return Plan(prims=prims, lights=lights, effects=effects, warnings=tuple(dict.fromkeys(warnings)),
                roots=roots, units=units, prim_unit=prim_unit)
