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
import math
import re
from pathlib import Path

from ..errors import SceneError, SourceLoc


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
        ``+KF``/``+KC`` switches), at ``frame`` (default: its first frame)."""
        path = Path(path)
        try:
            lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
        except OSError as e:
            raise SceneError(f"cannot read {path}: {e.strerror}") from None
        keys = {"initial_frame": "initial_frame", "final_frame": "final_frame",
                "initial_clock": "initial_clock", "final_clock": "final_clock",
                "cyclic_animation": "cyclic", "+kfi": "initial_frame", "+kff": "final_frame",
                "+ki": "initial_clock", "+kf": "final_clock"}
        values: dict[str, object] = {}
        for n, raw in enumerate(lines, 1):
            line = raw.split(";", 1)[0].strip()
            if not line:
                continue
            for word in line.split() if line.startswith(("+", "-")) else [line]:
                m = re.fullmatch(r"([A-Za-z_]+)\s*=\s*(\S+)", word) or re.fullmatch(
                    r"(\+KFI|\+KFF|\+KI|\+KF)(-?[0-9.eE+-]+)", word, re.IGNORECASE)
                if word.lower() in ("+kc", "-kc"):
                    values["cyclic"] = word[0] == "+"
                    continue
                if m is None or m.group(1).lower() not in keys:
                    continue  # options that are not about animation
                field, text = keys[m.group(1).lower()], m.group(2)
                try:
                    if field == "cyclic":
                        values[field] = text.lower() in ("on", "true", "yes", "1")
                    elif not math.isfinite(float(text)):
                        raise ValueError(text)
                    elif field.endswith("frame"):
                        values[field] = int(float(text))
                    else:
                        values[field] = float(text)
                except ValueError:
                    raise SceneError(f"expected a number for {m.group(1)}, found '{text}'",
                                     SourceLoc(str(path), n, raw.find(text) + 1)) from None
        anim = cls(**values)
        return dataclasses.replace(anim, frame=anim.initial_frame if frame is None else frame)
