"""POV-Ray scene description language → :class:`raytracer.scene.Scene`."""

from ..errors import InternalError as InternalError
from ..errors import SceneError as SceneError
from ._animation import Animation as Animation
from ._load import load_scene as load_scene
from ._stream import Limits as Limits

__all__ = ["Animation", "InternalError", "Limits", "SceneError", "load_scene"]
