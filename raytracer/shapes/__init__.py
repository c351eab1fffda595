"""Primitive shapes: one module per shape, one registry from which every table is derived.

Each shape class (an :class:`AbstractShape`) is its own record: scene parameters, crossings of a
line, inside test, bounds, static variants (static fields), SDL syntax and Mitsuba equivalent; see
``_base.py``. ``REGISTRY`` maps ``kind`` to the class and ``SDL_KEYWORDS`` maps each SDL keyword to
it. The renderer, the plan, the SDL interpreter and the Mitsuba converter use only these.

Adding a shape: a module here defining the class, one line in ``_SHAPES`` below, its test module
(``tests/shapes/``) and an example scene.
"""

from ._base import AbstractShape as AbstractShape
from ._base import MitsubaShape as MitsubaShape
from ._base import NoEquivalent as NoEquivalent
from ._base import ShapeArgs as ShapeArgs
from ._base import world_bounds as world_bounds
from ._blob import Blob as Blob
from ._box import Box as Box
from ._box import box_hits as box_hits
from ._box import box_inside as box_inside
from ._cone import Cone as Cone
from ._cone import Cylinder as Cylinder
from ._cone import cone_hits as cone_hits
from ._cone import cone_inside as cone_inside
from ._cone import cylinder_hits as cylinder_hits
from ._cone import cylinder_inside as cylinder_inside
from ._disc import Disc as Disc
from ._disc import disc_hits as disc_hits
from ._disc import disc_inside as disc_inside
from ._isosurface import Isosurface as Isosurface
from ._lathe import Lathe as Lathe
from ._mesh import Mesh as Mesh
from ._plane import Plane as Plane
from ._plane import plane_hits as plane_hits
from ._plane import plane_inside as plane_inside
from ._poly import Poly as Poly
from ._poly import poly_hits as poly_hits
from ._poly import poly_inside as poly_inside
from ._poly import poly_value as poly_value
from ._polygon import Polygon as Polygon
from ._polygon import polygon_from_points as polygon_from_points
from ._polygon import polygon_hits as polygon_hits
from ._prism import Prism as Prism
from ._quadric import Quadric as Quadric
from ._quadric import quadric_hits as quadric_hits
from ._quadric import quadric_inside as quadric_inside
from ._quadric import quadric_value as quadric_value
from ._sphere import Sphere as Sphere
from ._sphere import sphere_hits as sphere_hits
from ._sphere import sphere_inside as sphere_inside
from ._superellipsoid import Superellipsoid as Superellipsoid
from ._text import Text as Text
from ._torus import Torus as Torus
from ._torus import torus_hits as torus_hits
from ._torus import torus_inside as torus_inside
from ._torus import torus_value as torus_value
from ._triangle import SmoothTriangle as SmoothTriangle
from ._triangle import Triangle as Triangle
from ._triangle import smooth_triangle_hits as smooth_triangle_hits
from ._triangle import triangle_hits as triangle_hits

_SHAPES: tuple[type[AbstractShape], ...] = (
    Sphere, Plane, Box, Cylinder, Cone, Quadric, Torus, Disc, Triangle, SmoothTriangle, Polygon, Mesh,
    Superellipsoid, Poly, Prism, Text, Lathe, Isosurface, Blob,
)

REGISTRY: dict[str, type[AbstractShape]] = {cls.kind: cls for cls in _SHAPES}
SDL_KEYWORDS: dict[str, type[AbstractShape]] = {kw: cls for cls in _SHAPES for kw in cls.sdl_keywords}
