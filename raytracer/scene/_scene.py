"""The whole scene: camera, lights, objects and global settings."""

from __future__ import annotations

import equinox as eqx
from jaxtyping import Array, Float

from .._build import Record
from .._dtype import as_float
from ..errors import SceneWarning
from ._camera import Camera
from ._lights import Light
from ._objects import AbstractObject
from .environment import ENVIRONMENT

OUTPUT_TRANSFERS = ("linear", "gamma", "srgb_decode")


class Settings(Record):
    """``global_settings`` and the output transfer implied by ``#version``/``assumed_gamma`` (semantics §3.1).

    Attributes:
        ambient_light:   (3,) multiplies every finish's ambient, default white.
        adc_bailout:     rays whose weight falls below this are not traced (default 1/255).
        max_trace_level: static: primary ray + up to ``max_trace_level - 1`` bounces (default 5).
        output_transfer: static: how working values become linear output:
                         "linear" (3.7 + assumed_gamma 1), "gamma" (``value ** assumed_gamma``), or
                         "srgb_decode" (pre-3.7 scenes without assumed_gamma).
        assumed_gamma:   static float used by "gamma".
    """

    ambient_light: Float[Array, "3"] = eqx.field(converter=as_float, default=(1.0, 1.0, 1.0))
    adc_bailout: Float[Array, ""] = eqx.field(converter=as_float, default=1.0 / 255.0)
    max_trace_level: int = eqx.field(static=True, default=5)
    output_transfer: str = eqx.field(static=True, default="linear")
    assumed_gamma: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        if self.output_transfer not in OUTPUT_TRANSFERS:
            raise ValueError(f"unknown output transfer {self.output_transfer!r}")
        if not 1 <= self.max_trace_level <= 256:
            raise ValueError("max_trace_level must be in 1…256")


class Scene(Record):
    """A renderable scene. Every inexact array leaf is a differentiable parameter.

    Attributes:
        camera:     the camera.
        objects:    top-level objects (primitives or CSG trees).
        lights:     light sources.
        background: (3,) colour of rays that hit nothing (default black).
        environment: the environment effects' values (``scene.ENVIRONMENT``): a ``SkySphere``
                    (what rays that hit nothing see instead of the background, by direction), the
                    ``Fog``s (constant or ground) every ray goes through outside objects …; at
                    most one of an effect whose values do not add up.
        settings:   global settings.
        warnings:   static: features parsed but not rendered, with locations.
    """

    camera: Camera = eqx.field(default_factory=Camera)
    objects: tuple[AbstractObject, ...] = ()
    lights: tuple[Light, ...] = ()
    background: Float[Array, "3"] = eqx.field(converter=as_float, default=(0.0, 0.0, 0.0))
    environment: tuple[Record, ...] = ()
    settings: Settings = eqx.field(default_factory=Settings)
    warnings: tuple[SceneWarning, ...] = eqx.field(static=True, default=())

    def __check_init__(self):
        for value in self.environment:
            entry = next((e for e in ENVIRONMENT if isinstance(value, e.record)), None)
            if entry is None:
                raise TypeError(f"Scene.environment holds a {type(value).__name__}, not an environment "
                                f"effect ({', '.join(e.record.__name__ for e in ENVIRONMENT)})")
            if not entry.many and sum(isinstance(v, entry.record) for v in self.environment) > 1:
                raise ValueError(f"Scene.environment holds more than one {type(value).__name__}")
