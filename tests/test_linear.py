"""``_linear.linear_call``: a linear map written as a loop of a length the program computes, with
its transpose as another such loop, differentiated in both modes and batched (``vmap``), against
closed forms."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer._linear import linear_call


def _first_terms(a, n):
    """``(Σ_{i<n} sin(a i) x_i)``'s linear map in x (length 8) as a while loop of n steps, and its
    transpose as another, through a custom_jvp whose tangent is that map of a's tangent."""

    def fun(res, x):
        a, n = res
        return jax.lax.fori_loop(0, n, lambda i, acc: acc.at[i].set(jnp.cos(a * i) * i * x), jnp.zeros(8))

    def fun_t(res, ct):
        a, n = res
        return jax.lax.fori_loop(0, n, lambda i, acc: acc + jnp.cos(a * i) * i * ct[i], jnp.zeros(()))

    @jax.custom_jvp
    def f(a):
        return jnp.where(jnp.arange(8) < n, jnp.sin(a * jnp.arange(8)), 0.0)

    @f.defjvp
    def _(primals, tangents):
        (a,), (a_dot,) = primals, tangents
        return f(a), linear_call(fun, fun_t, (a, n), a_dot)

    return f(a)


@pytest.mark.parametrize("mode", ["jvp", "grad", "jit grad", "vmap grad", "grad of vmap"])
def test_a_loop_and_its_transpose_differentiate_and_batch_as_the_closed_form(mode):
    w = jnp.arange(1.0, 9.0)

    def loss(a, n):
        return jnp.sum(w * _first_terms(a, n))

    def exact(a, n):
        return sum(float(w[i]) * i * np.cos(a * i) for i in range(n))

    a, n = 0.3, jnp.int32(5)
    if mode == "jvp":
        got, want = jax.jvp(lambda a: loss(a, n), (a,), (1.0,))[1], exact(a, 5)
    elif mode == "grad":
        got, want = jax.grad(loss)(a, n), exact(a, 5)
    elif mode == "jit grad":
        got, want = jax.jit(jax.grad(loss))(a, n), exact(a, 5)
    elif mode == "vmap grad":
        got = jax.vmap(jax.grad(loss), in_axes=(0, None))(jnp.array([0.3, 0.7]), n)
        want = [exact(0.3, 5), exact(0.7, 5)]
    else:
        got = jax.grad(lambda a: jnp.sum(jax.vmap(lambda n: loss(a, n))(jnp.array([3, 5]))))(a)
        want = exact(a, 3) + exact(a, 5)
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-5)
