"""A POV-Ray user function (``function { … }``) as a JAX function of its arguments.

The scene language compiles a function's body once (``raytracer/sdl/_functions.py``) into an
**expression**: a tree of nested tuples, static and hashable, whose leaves are the function's
arguments and its numbered constants. The constants are an array beside the tree, so every number
written in a function (and every declared float it reads) is a differentiable parameter of the
shape or pattern that holds it, while the tree's structure is part of the compiled program.

Nodes (``op`` first):

==========================  =====================================================================
``("arg", k)``              the k-th argument (x, y, z of an isosurface's or a pattern's point)
``("const", i)``            ``constants[i]``
``("pow", a, n)``           ``a ** n`` for a whole number ``n`` written in the function (static:
                            ``x^2`` of a negative x is defined, as in POV-Ray)
``(op, a, b)``              ``+ - * / ^`` and the comparisons ``< <= = != >= >`` (1 or 0),
                            ``&`` and ``|`` (1 or 0, a value is true when it is not 0)
``("neg", a)``, ``("not", a)``
``("if", c, a, b)``         ``c ? a : b``
``("call", name, a, …)``    a built-in float function of POV-Ray's (``FUNCTIONS``)
``("internal", n, a, …)``   POV-Ray's internal function number n (``INTERNAL``)
==========================  =====================================================================

Where POV-Ray's arithmetic leaves the reals (a square root of a negative number, a logarithm of
zero, a division by zero) the value here stays finite (``safe_sqrt`` and its kin): a surface is not
defined there in either renderer, and a NaN must not reach an image or a gradient.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..kernels._numerics import safe_div, safe_mask, safe_sqrt
from ._noise import noise

Expression = tuple


def _log(x):
    return safe_mask(x > 0, jnp.log, x, placeholder=1.0, fallback=-1e30)


def _int(x):
    return jnp.trunc(x)


def _mod(a, b):  # POV-Ray's mod: a − int(a / b)·b, the sign of a
    return a - jnp.trunc(safe_div(a, b)) * b


def _select(a, b, c, d=None):
    if d is None:
        return jnp.where(a < 0, b, c)
    return jnp.where(a < 0, b, jnp.where(a == 0, c, d))


def _clipped(f, lo, hi):
    return lambda x: f(jnp.clip(x, lo, hi))


FUNCTIONS = {
    "abs": jnp.abs, "sin": jnp.sin, "cos": jnp.cos, "tan": jnp.tan,
    "asin": _clipped(jnp.arcsin, -1.0, 1.0), "acos": _clipped(jnp.arccos, -1.0, 1.0),
    "atan": jnp.arctan, "atan2": jnp.arctan2, "sinh": jnp.sinh, "cosh": jnp.cosh, "tanh": jnp.tanh,
    "asinh": jnp.arcsinh, "acosh": lambda x: jnp.arccosh(jnp.maximum(x, 1.0)),
    "atanh": _clipped(jnp.arctanh, -1.0 + 1e-7, 1.0 - 1e-7),
    "exp": jnp.exp, "ln": _log, "log": lambda x: _log(x) / jnp.log(10.0),
    "sqrt": safe_sqrt, "pow": lambda a, b: _power(a, b),
    "floor": jnp.floor, "ceil": jnp.ceil, "int": _int, "mod": _mod,
    "div": lambda a, b: jnp.trunc(safe_div(a, b)),
    "degrees": jnp.degrees, "radians": jnp.radians,
    "min": lambda *a: _fold(jnp.minimum, a), "max": lambda *a: _fold(jnp.maximum, a),
    "select": _select,
}
# the number of arguments each takes (min, max)
ARITY = {name: (1, 1) for name in FUNCTIONS}
ARITY.update({"atan2": (2, 2), "pow": (2, 2), "mod": (2, 2), "div": (2, 2), "min": (1, 64),
              "max": (1, 64), "select": (3, 4)})


def _fold(f, args):
    out = args[0]
    for a in args[1:]:
        out = f(out, a)
    return out


def _power(a, b):
    """``a ** b`` for a computed exponent: POV-Ray's ``pow`` of a positive base (a negative base's
    real powers exist only for whole exponents, which ``("pow", a, n)`` takes)."""
    whole = jnp.round(b)
    odd = jnp.abs(jnp.mod(whole, 2.0)) == 1.0
    magnitude = jnp.exp(b * _log(jnp.abs(a)))
    negative = (a < 0) & (b == whole)
    return jnp.where(a == 0, jnp.where(b == 0, 1.0, 0.0),
                     jnp.where(negative & odd, -magnitude, magnitude))


def _rounded_box(x, y, z, radius, sx, sy, sz):
    """Outside the box of half sizes ``s`` with edges rounded by ``radius``: the distance to it;
    inside its core (the box shrunk by ``radius``): −radius (measured against POV-Ray's values)."""
    q = [jnp.maximum(jnp.abs(c) - (s - radius), 0.0) for c, s in ((x, sx), (y, sy), (z, sz))]
    return safe_sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) - radius


def _noise3d(x, y, z):
    p = jnp.stack(jnp.broadcast_arrays(x, y, z), axis=-1)
    return jax.vmap(noise)(p.reshape(-1, 3)).reshape(p.shape[:-1])


def _length(*c):
    return safe_sqrt(sum(a * a for a in c))


# POV-Ray's internal functions that are compiled (functions.inc declares ``f_… = function {
# internal(n) }``): n → (name, argument count, function). Values measured with povray's parse-time
# evaluation (#debug) at four points: equal to 1e-6; f_noise3d is our noise (semantics §5.4: the
# same statistics, not POV-Ray's values).
INTERNAL = {
    57: ("f_r", 3, _length),
    61: ("f_sphere", 4, lambda x, y, z, r: _length(x, y, z) - r),
    70: ("f_torus", 5, lambda x, y, z, major, minor: _length(_length(x, z) - major, y) - minor),
    60: ("f_rounded_box", 7, _rounded_box),
    76: ("f_noise3d", 3, _noise3d),
}


def _truth(x):
    return x != 0


def evaluate(node: Expression, constants, args):
    """The expression's value at ``args`` (a tuple of arrays of one shape) with ``constants`` (an
    array); elementwise, so a batch of points is a batch of values."""
    op = node[0]
    if op == "arg":
        return args[node[1]]
    if op == "const":
        return jnp.broadcast_to(constants[node[1]], jnp.shape(args[0]))
    if op == "pow":
        base = evaluate(node[1], constants, args)
        n = node[2]
        out = jnp.ones_like(base)
        for _ in range(abs(n)):
            out = out * base
        return safe_div(1.0, out) if n < 0 else out
    if op == "call":
        return FUNCTIONS[node[1]](*(evaluate(a, constants, args) for a in node[2:]))
    if op == "internal":
        return INTERNAL[node[1]][2](*(evaluate(a, constants, args) for a in node[2:]))
    if op == "neg":
        return -evaluate(node[1], constants, args)
    if op == "not":
        return jnp.where(_truth(evaluate(node[1], constants, args)), 0.0, 1.0)
    if op == "if":
        c = evaluate(node[1], constants, args)
        return jnp.where(_truth(c), evaluate(node[2], constants, args), evaluate(node[3], constants, args))
    a, b = evaluate(node[1], constants, args), evaluate(node[2], constants, args)
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        return safe_div(a, b)
    if op == "^":
        return _power(a, b)
    one, zero = jnp.ones_like(a), jnp.zeros_like(a)
    if op == "&":
        return jnp.where(_truth(a) & _truth(b), one, zero)
    if op == "|":
        return jnp.where(_truth(a) | _truth(b), one, zero)
    test = {"<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b, "=": a == b, "!=": a != b}[op]
    return jnp.where(test, one, zero)
