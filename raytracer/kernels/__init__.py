"""Ray-primitive intersection kernels: ONE ray against ONE primitive, in object space.

Each primitive kind ``<kind>`` has

* ``<kind>_hits(params..., o, d) -> (t, n)``: ``t`` (K,) holds every crossing of the line ``o + t d``
  with the surface, of any sign, ``+inf`` in unused slots; ``n`` (K, 3) the unit outward normal there.
  ``d`` need not be unit length, so ``t`` is the same ray parameter as in world space.
* ``<kind>_inside(params..., p) -> bool``: strictly inside the solid (POV-Ray semantics).
* ``<KIND>_K``: the number of slots K, a Python int.

Batch with ``jax.vmap``. Shared numerics (stable quadratic, quartic, safe functions) are re-exported too.
"""

from ._box import BOX_K as BOX_K
from ._box import box_hits as box_hits
from ._box import box_inside as box_inside
from ._cone import CONE_K as CONE_K
from ._cone import CYLINDER_K as CYLINDER_K
from ._cone import cone_hits as cone_hits
from ._cone import cone_inside as cone_inside
from ._cone import cylinder_hits as cylinder_hits
from ._cone import cylinder_inside as cylinder_inside
from ._disc import DISC_K as DISC_K
from ._disc import disc_hits as disc_hits
from ._disc import disc_inside as disc_inside
from ._numerics import differentiable_root as differentiable_root
from ._numerics import safe_arccos as safe_arccos
from ._numerics import safe_div as safe_div
from ._numerics import safe_mask as safe_mask
from ._numerics import safe_normalize as safe_normalize
from ._numerics import safe_pow as safe_pow
from ._numerics import safe_sqrt as safe_sqrt
from ._numerics import solve_linear as solve_linear
from ._numerics import solve_quadratic as solve_quadratic
from ._numerics import solve_quartic as solve_quartic
from ._plane import PLANE_K as PLANE_K
from ._plane import plane_hits as plane_hits
from ._plane import plane_inside as plane_inside
from ._polygon import POLYGON_K as POLYGON_K
from ._polygon import polygon_hits as polygon_hits
from ._polygon import polygon_inside as polygon_inside
from ._quadric import QUADRIC_K as QUADRIC_K
from ._quadric import quadric_hits as quadric_hits
from ._quadric import quadric_inside as quadric_inside
from ._quadric import quadric_value as quadric_value
from ._sphere import SPHERE_K as SPHERE_K
from ._sphere import sphere_hits as sphere_hits
from ._sphere import sphere_inside as sphere_inside
from ._torus import TORUS_K as TORUS_K
from ._torus import torus_hits as torus_hits
from ._torus import torus_inside as torus_inside
from ._torus import torus_value as torus_value
from ._triangle import SMOOTH_TRIANGLE_K as SMOOTH_TRIANGLE_K
from ._triangle import TRIANGLE_K as TRIANGLE_K
from ._triangle import smooth_triangle_hits as smooth_triangle_hits
from ._triangle import smooth_triangle_inside as smooth_triangle_inside
from ._triangle import triangle_hits as triangle_hits
from ._triangle import triangle_inside as triangle_inside
