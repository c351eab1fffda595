"""A linear function with a transpose of its own that also ``vmap``s.

``jax.custom_derivatives.linear_call(fun, fun_transpose, residuals, linear)`` calls ``fun`` and
tells reverse mode to transpose it by calling ``fun_transpose``: a linear map whose work is a loop
of a length known only when the program runs (``while_loop``, which JAX cannot transpose) can be
written as such a pair of loops. JAX gives the primitive no batching rule; the one here maps both
functions with ``jax.vmap``, every linear operand and output batched (so that the transpose's
outputs are batched as its linear inputs are).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.custom_derivatives import linear_call
from jax.extend.core import jaxpr_as_fun
from jax.interpreters import batching

__all__ = ["linear_call"]


def _batched(args, dims, *, callee, transpose_thunk, num_callee_consts: int, num_res: int):
    size = next(x.shape[d] for x, d in zip(args, dims, strict=True) if d is not None)
    fixed = num_callee_consts + num_res
    held, held_axes = list(args[:fixed]), list(dims[:fixed])
    linear = [jnp.broadcast_to(x, (size, *x.shape)) if d is None else jnp.moveaxis(x, d, 0)
              for x, d in zip(args[fixed:], dims[fixed:], strict=True)]
    fun = jaxpr_as_fun(callee)
    t_jaxpr, t_consts = transpose_thunk()
    fun_t = jaxpr_as_fun(t_jaxpr)

    def mapped(r, lin):
        return jax.vmap(lambda r_, l_: fun(*r_, *l_), in_axes=(held_axes, 0))(r, lin)

    def mapped_t(r, ct):
        res, res_axes = r[num_callee_consts:], held_axes[num_callee_consts:]
        return jax.vmap(lambda r_, c_: fun_t(*t_consts, *r_, *c_), in_axes=(res_axes, 0))(res, ct)

    out = linear_call(mapped, mapped_t, held, linear)
    return out, [0] * len(out)


def _register() -> None:
    try:  # the primitive is not exported; without it, vmap of a linear_call says it has no rule
        from jax._src.custom_derivatives import linear_call_p
    except ImportError:  # pragma: no cover
        return
    if linear_call_p not in batching.fancy_primitive_batchers:  # (unless JAX has come to give one)
        batching.primitive_batchers[linear_call_p] = _batched


_register()
