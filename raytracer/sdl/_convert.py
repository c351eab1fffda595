"""Value conversions of the SDL: a value read where a float, vector, colour or count is expected.

No grammar here: the expression parser (``_expr``) and the built-in functions (``_builtins``) both
use these, and neither imports the other's grammar through this module.

Every float the interpreter makes is finite: the lexer refuses a literal beyond the double range,
and arithmetic and the built-in functions refuse a result beyond it (``finite``), so a count read
with ``as_int`` never meets an infinity or a NaN.
"""

from __future__ import annotations

from ..errors import fmt_number as fmt_number
from ._values import Vec

EPSILON = 1e-10
INT_MIN, INT_MAX = -(2**31), 2**31 - 1  # POV-Ray reads counts and integer arguments as C ints


def type_name(v) -> str:
    if isinstance(v, float):
        return "float"
    if isinstance(v, Vec):
        return "vector"
    if isinstance(v, str):
        return "string"
    own = getattr(v, "sdl_type_name", None)  # a value that names itself (an environment statement)
    if own is not None:
        return own
    return _TYPE_NAMES.get(type(v).__name__) or type(v).__name__.replace("Value", "").lower()


_TYPE_NAMES = {"PigRec": "pigment", "NormRec": "normal", "PigmentMapRec": "pigment_map",
               "SlopeMapRec": "slope_map", "TextureMapRec": "texture_map",
               "LayerRec": "texture layer", "TextureRec": "texture",
               "InteriorRec": "interior", "MaterialRec": "material", "LightRec": "light_source",
               "ObjRec": "object", "CameraRec": "camera", "TransformRec": "transform",
               "ArrayValue": "array", "MacroDef": "macro",
               "RandStream": "seed() stream"}


def as_float(p, v, loc=None) -> float:
    if isinstance(v, float):
        return v
    if isinstance(v, bool | int):
        return float(v)
    if isinstance(v, Vec):
        return v.c[0]
    raise p.error(f"expected a float, found {type_name(v)}", loc)


def as_int(p, v, loc, what: str, lo: int = INT_MIN, hi: int = INT_MAX) -> int:
    """A value read where an integer is expected, truncated toward zero as POV-Ray's (int) cast.

    Raises:
        SceneError: ``expected <what> from lo to hi, found …`` when the truncated value lies
            outside ``lo..hi`` (every count and index is read through here).
    """
    x = as_float(p, v, loc)
    if lo - 1 < x < hi + 1:  # int(x) is safe (NaN fails both comparisons) and near lo..hi
        n = int(x)
        if lo <= n <= hi:
            return n
    raise p.error(f"expected {what} from {lo} to {hi}, found {fmt_number(x)}", loc)


def finite(p, x: float, loc, what: str) -> float:
    """``x`` when it is finite; else a SceneError saying that ``what`` leaves the float range."""
    if x - x == 0.0:  # inf - inf and NaN - NaN are NaN
        return x
    raise p.error(f"{what} is outside the float range (±1.8e308)", loc)


def as_vector(p, v, n: int = 3, loc=None) -> tuple:
    if isinstance(v, float):
        return (v,) * n
    if isinstance(v, Vec):
        return v.padded(n)
    raise p.error(f"expected a vector, found {type_name(v)}", loc)


def as_color(p, v, loc=None) -> Vec:
    """A value used as a colour: a float fills all five channels (semantics §2.2)."""
    if isinstance(v, float):
        return Vec((v,) * 5, True)
    if isinstance(v, Vec):
        c = v.as_color()
        c.ft = v.ft or c.c[3] != 0.0 or c.c[4] != 0.0
        return c
    raise p.error(f"expected a colour, found {type_name(v)}", loc)


def truthy(p, v, loc=None) -> bool:
    return abs(as_float(p, v, loc)) > EPSILON


def check_string_length(p, length: int, loc, what: str, limit_name: str = "max_string_length") -> None:
    """A SceneError when ``length`` characters would exceed ``Limits.<limit_name>``."""
    limit = getattr(p.limits, limit_name)
    if length > limit:
        raise p.error(f"expected at most {limit} characters (Limits.{limit_name}), "
                      f"{what} would make {length}", loc)
