"""POV-Ray's animation settings: which frame a scene is loaded as, and the ``clock`` it sees.

POV-Ray renders frame ``f`` of ``Initial_Frame..Final_Frame`` with

    clock = Initial_Clock + (f - Initial_Frame) · (Final_Clock - Initial_Clock)
                                                  / (Final_Frame - Initial_Frame)

(the denominator is one larger with ``Cyclic_Animation``, so the last frame does not repeat the
first). Without animation a scene sees ``clock = 0``, ``frame_number = 0`` and ``clock_on = 0``.
POV-Ray's sample portfolio scenes are animations: their ``.ini`` files give the frame range, and
the scenes index arrays with ``frame_number``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path


@dataclasses.dataclass(frozen=True)
class Animation:
    """One frame of an animation (POV-Ray's INI options ``Initial_Frame`` … ``Cyclic_Animation``)."""

    frame: int = 1
    initial_frame: int = 1
    final_frame: int = 1
    initial_clock: float = 0.0
    final_clock: float = 1.0
    cyclic: bool = False

    @property
    def clock_delta(self) -> float:
        steps = self.final_frame - self.initial_frame + (1 if self.cyclic else 0)
        return 0.0 if steps <= 0 else (self.final_clock - self.initial_clock) / steps

    @property
    def clock(self) -> float:
        if self.final_frame == self.initial_frame and not self.cyclic:
            return self.initial_clock
        return self.initial_clock + (self.frame - self.initial_frame) * self.clock_delta

    def constants(self) -> dict[str, float]:
        """The SDL's animation identifiers for this frame."""
        return {"clock": self.clock, "clock_delta": self.clock_delta, "clock_on": 1.0,
                "frame_number": float(self.frame), "initial_frame": float(self.initial_frame),
                "final_frame": float(self.final_frame), "initial_clock": self.initial_clock,
                "final_clock": self.final_clock}

    @classmethod
    def from_ini(cls, path: str | Path, frame: int | None = None) -> Animation:
        """The animation an INI file describes (``Key=Value`` lines or ``+KFI``/``+KFF``/``+KI``/
        ``+KF``/``+KC`` switches, read by :func:`raytracer.sdl._options.read_ini`), at ``frame``
        (default: its first frame)."""
        from ._options import PovOptions, read_ini

        opts = PovOptions()
        read_ini(path, opts)
        return cls.from_options(opts, frame)

    @classmethod
    def from_options(cls, opts, frame: int | None = None) -> Animation:
        """The animation POV-Ray's options (:class:`raytracer.sdl._options.PovOptions`) describe, at
        ``frame`` (default: its first); a lone ``Clock`` is one frame at that clock."""
        values = {k: getattr(opts, k) for k in ("initial_frame", "final_frame", "initial_clock",
                                                 "final_clock", "cyclic") if getattr(opts, k) is not None}
        if opts.clock is not None and not values:
            values = {"initial_clock": opts.clock, "final_clock": opts.clock}
        anim = cls(**values)
        return dataclasses.replace(anim, frame=anim.initial_frame if frame is None else frame)
