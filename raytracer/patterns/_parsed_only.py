"""POV-Ray patterns we parse but do not render: the parser skips their arguments, warns with the
location and substitutes a neutral colour. Rendering one = giving it an evaluator (and moving it to
the module of its family)."""

from __future__ import annotations

from ._record import parsed_only

PATTERNS = (
    *(parsed_only(name) for name in (
        "spiral1", "spiral2", "quilted", "mandel", "julia", "magnet", "facets",
        "tiling", "pavement", "slope", "aoi", "image_pattern", "object", "function",
        "pigment_pattern", "fractal", "cubic", "square", "triangular", "noise_pigment",
        "bump_map", "material_map")),
    parsed_only("density_file", argument="file"),
)
