"""Shared numerics of the intersection kernels (the kernels themselves live with their shapes in
``raytracer.shapes``): stable quadratic and quartic, safe sqrt/div/normalize/arccos/pow, and the
implicit-function-theorem root. Every function is finite, with finite gradients, for finite input."""

from ._common import matvec as matvec
from ._common import vecmat as vecmat
from ._numerics import differentiable_root as differentiable_root
from ._numerics import offset_sq_minus as offset_sq_minus
from ._numerics import safe_arccos as safe_arccos
from ._numerics import safe_div as safe_div
from ._numerics import safe_mask as safe_mask
from ._numerics import safe_normalize as safe_normalize
from ._numerics import safe_pow as safe_pow
from ._numerics import safe_sqrt as safe_sqrt
from ._numerics import solve_linear as solve_linear
from ._numerics import solve_quadratic as solve_quadratic
from ._numerics import solve_quartic as solve_quartic
from ._numerics import world_normal as world_normal
