"""raytracer: a differentiable Whitted ray tracer in JAX that reads POV-Ray scenes.

Public API: the scene model (``Scene``, ``Camera``, ``Light``, ``Object``, shapes, textures; every
registered shape is in ``raytracer.shapes``, the classic ones also here),
``load_scene`` (POV-Ray SDL → ``Scene``), ``render`` (``Scene`` → linear image, jit-compiled and
differentiable), ``plan`` (what the compiled program simulates), and image I/O.
"""

from ._xla import tune_xla_flags as _tune_xla_flags

_tune_xla_flags()  # before anything starts a JAX backend (raytracer/_xla.py)

from . import params as params
from . import shapes as shapes
from .errors import InternalError as InternalError
from .errors import SceneError as SceneError
from .errors import SceneWarning as SceneWarning
from .errors import SourceLoc as SourceLoc
from .imageio import read_image as read_image
from .imageio import write_image as write_image
from .render import plan as plan
from .render import render as render
from .scene import CSG as CSG
from .scene import CSG_OPERATIONS as CSG_OPERATIONS
from .scene import PATTERNS as PATTERNS
from .scene import WAVES as WAVES
from .scene import AbstractObject as AbstractObject
from .scene import AbstractShape as AbstractShape
from .scene import AreaLight as AreaLight
from .scene import Box as Box
from .scene import Camera as Camera
from .scene import Cone as Cone
from .scene import Cylinder as Cylinder
from .scene import Disc as Disc
from .scene import Finish as Finish
from .scene import Fog as Fog
from .scene import ImageMap as ImageMap
from .scene import Interior as Interior
from .scene import Layer as Layer
from .scene import Light as Light
from .scene import Mesh as Mesh
from .scene import Normal as Normal
from .scene import Object as Object
from .scene import Pigment as Pigment
from .scene import Plane as Plane
from .scene import Polygon as Polygon
from .scene import Quadric as Quadric
from .scene import Reflection as Reflection
from .scene import Scene as Scene
from .scene import Settings as Settings
from .scene import SkySphere as SkySphere
from .scene import SmoothTriangle as SmoothTriangle
from .scene import Sphere as Sphere
from .scene import Spot as Spot
from .scene import Texture as Texture
from .scene import Torus as Torus
from .scene import Transform as Transform
from .scene import Triangle as Triangle
from .scene import axis_rotation_matrix as axis_rotation_matrix
from .scene import polygon_from_points as polygon_from_points
from .scene import pov_matrix as pov_matrix
from .scene import rotation_matrix as rotation_matrix
from .scene import scale_matrix as scale_matrix
from .scene import translation_matrix as translation_matrix
from .sdl import Animation as Animation
from .sdl import load_scene as load_scene
