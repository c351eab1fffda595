"""Derivatives against central differences, whole Jacobians at once, in float64.

``jax.test_util.check_grads`` checks random directions one eager call at a time and, for order 2,
builds a new program for every nesting of ``jvp``/``vjp``: a second-order check of one shape kernel
cost 20-50 s, almost all of it compiling. Here each check compiles three programs at most: the
forward and reverse Jacobians (or the Hessian) in one ``jit``, and the function (or its Jacobian)
``vmap``-ed over all ``2n`` shifted inputs in another. Every input direction is checked, not a
random one.

The Hessian is checked as ``jax.hessian`` computes it, forward over reverse: that differentiates
every custom derivative rule (the implicit-function-theorem hits) a second time. Reverse over
forward goes through the same rules in the other order and cost as much again to compile (a
lathe's: 23 s against 13 s), for a check of JAX's transposition rather than of our kernels.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree


def assert_derivatives_match_fd(f, args, *, order: int = 1, h: float = 1e-5, atol: float = 1e-5,
                                rtol: float = 1e-5) -> None:
    """``f(*args)`` → array: its forward- and reverse-mode Jacobians (``order=1``) or its Hessian
    (``order=2``, forward over reverse) equal central differences of ``f`` (of its Jacobian) with
    step ``h``. Needs ``jax.enable_x64``."""
    x, unravel = ravel_pytree(tuple(jnp.asarray(a, jnp.float64) for a in args))

    def flat(x_):
        return jnp.ravel(f(*unravel(x_)))

    if order == 1:
        derivatives = jax.jit(lambda x_: (jax.jacfwd(flat)(x_), jax.jacrev(flat)(x_)))(x)
        inner = flat
    elif order == 2:
        derivatives = (jax.jit(jax.jacfwd(jax.jacrev(flat)))(x),)
        inner = jax.jacfwd(flat)
    else:
        raise ValueError(order)
    steps = h * jnp.eye(x.size, dtype=x.dtype)
    values = jax.jit(jax.vmap(inner))(jnp.concatenate([x[None, :] + steps, x[None, :] - steps]))
    plus, minus = np.asarray(values[: x.size]), np.asarray(values[x.size:])
    central = np.moveaxis((plus - minus) / (2 * h), 0, -1)  # d/dx_i is the last axis, as jacfwd's
    for mode, derivative in zip(("forward", "reverse") if order == 1 else ("forward over reverse",),
                                derivatives, strict=True):
        np.testing.assert_allclose(np.asarray(derivative), central, atol=atol, rtol=rtol,
                                   err_msg=f"{mode}-mode derivative of order {order}")
