"""The scene model: frozen Equinox pytrees whose array leaves are the differentiable parameters.

Leaves given as numbers, lists or numpy arrays are stored as read-only numpy arrays of the default
float dtype (float32, or float64 under ``jax_enable_x64``); JAX arrays and tracers are kept as
they are. numpy leaves are ordinary JAX leaves — ``jit``, ``grad``, ``eqx.tree_at`` and
``raytracer.params`` take them as they take JAX arrays — and cost ~1 µs to make instead of
~30-60 µs, which is what lets a 10^5-primitive POV-Ray scene load in a second. For JAX-only
methods such as ``.at[]``, take ``jnp.asarray(leaf)`` first.
"""

from ..shapes import AbstractShape as AbstractShape
from ..shapes import Box as Box
from ..shapes import Cone as Cone
from ..shapes import Cylinder as Cylinder
from ..shapes import Disc as Disc
from ..shapes import Mesh as Mesh
from ..shapes import Plane as Plane
from ..shapes import Polygon as Polygon
from ..shapes import Quadric as Quadric
from ..shapes import SmoothTriangle as SmoothTriangle
from ..shapes import Sphere as Sphere
from ..shapes import Torus as Torus
from ..shapes import Triangle as Triangle
from ..shapes import polygon_from_points as polygon_from_points
from ._camera import PINHOLE as PINHOLE
from ._camera import SEES_EVERYWHERE as SEES_EVERYWHERE
from ._camera import Camera as Camera
from ._lights import AreaLight as AreaLight
from ._lights import Light as Light
from ._lights import Spot as Spot
from ._objects import CSG as CSG
from ._objects import CSG_OPERATIONS as CSG_OPERATIONS
from ._objects import AbstractObject as AbstractObject
from ._objects import Object as Object
from ._scene import Scene as Scene
from ._scene import Settings as Settings
from ._texture import PATTERNS as PATTERNS
from ._texture import WAVES as WAVES
from ._texture import Finish as Finish
from ._texture import ImageMap as ImageMap
from ._texture import Interior as Interior
from ._texture import Layer as Layer
from ._texture import Normal as Normal
from ._texture import Pigment as Pigment
from ._texture import Reflection as Reflection
from ._texture import Texture as Texture
from ._transform import Transform as Transform
from ._transform import axis_rotation_matrix as axis_rotation_matrix
from ._transform import pov_matrix as pov_matrix
from ._transform import rotation_matrix as rotation_matrix
from ._transform import scale_matrix as scale_matrix
from ._transform import translation_matrix as translation_matrix
from .environment import ENVIRONMENT as ENVIRONMENT
from .environment import EnvironmentArgs as EnvironmentArgs
from .environment import EnvironmentLowering as EnvironmentLowering
from .environment import EnvironmentType as EnvironmentType
from .environment import Fog as Fog
from .environment import SkySphere as SkySphere
from .environment import environment_of as environment_of
