"""The isosurface: where a user function equals a threshold, inside a box or sphere container.

``isosurface { function { F } [contained_by { box { A, B } | sphere { C, R } }] [threshold T]
[accuracy a] [max_gradient G] [evaluate P0, P1, P2] [open] [max_trace N | all_intersections] }``

POV-Ray's semantics (manual §3.4.5.1.6, measured with ``povray``): the surface is ``F(p) = T``;
the solid is where ``F < T`` (a sphere's distance function minus a radius renders that sphere);
the container cuts the solid, and where it does its wall is seen (its own normal) unless ``open``;
nothing outside the container exists. The function is compiled once from the scene language
(``raytracer/sdl/_functions.py``) into an expression (``raytracer/patterns/_expression.py``) whose
constants are this shape's parameters, so every number in the function, the threshold and the
container are differentiable.

Crossings of a line: its span inside the container is marched with steps the function's gradient
bound allows, ``|F − T| / G`` (a step cannot pass a root when ``|∇F| ≤ G``; at least ``accuracy``,
and at most ``MAX_STEPS`` steps a line), as POV-Ray's ``max_gradient`` is meant; each sign change
is a bracket, bisected to a float's resolution, and the root carries the implicit function
theorem's derivatives (``differentiable_root``: ``dt/dθ = −(∂F/∂θ)/(∂F/∂t)``), not the march's.
The normal is ``∇F / |∇F|`` by automatic differentiation (POV-Ray's is a finite difference of
``F`` over ``accuracy``). The march starts at the line's origin or the container's entry,
whichever is later: a ray's crossings ahead of it are what the renderer asks for, and ``slots``
of them are kept (``max_trace``: 2 by default so that a secondary ray leaving the surface finds
the next crossing, up to ``MAX_SLOTS`` with ``all_intersections``).

What differs from POV-Ray: where ``G`` is smaller than the function's real gradient both miss
parts of the surface, not necessarily the same parts; ``evaluate`` (POV-Ray's adaptive gradient
estimate) is read as the bound ``P0 · P1``; POV-Ray warns of the largest gradient it met, this
does not.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, Float

from .._dtype import as_float
from ..kernels._numerics import _bisect, differentiable_root, safe_normalize
from ..patterns._expression import evaluate
from ._base import AbstractShape
from ._box import box_hits
from ._sphere import sphere_hits

MAX_STEPS = 4096  # march steps a line at most: a span of more than MAX_STEPS·accuracy steps coarser
MAX_SLOTS = 8  # crossings kept with all_intersections
CULL_TO = 8  # isosurfaces of a group a ray marches: those whose containers it enters first
BISECTIONS = 24  # halvings of a bracket: its width (a step, at most the span) to below float32 resolution


class Isosurface(AbstractShape):
    """``isosurface { function { F } [contained_by { box or sphere }] [threshold T] [accuracy a]
    [max_gradient G] [open] [max_trace N] }``: where F = T inside the container, the solid where
    F < T; the container's wall where it cuts the solid, unless ``open`` (see the module
    docstring).

    Attributes:
        constants:    (C,) the function's constants, in the order the expression numbers them.
        threshold:    () the level ``T``.
        container:    (2, 3) the box's corners, or the sphere's centre and (radius, 0, 0).
        expression:   static: the function (``raytracer.patterns._expression``).
        sphere:       static: the container is a sphere (else a box).
        max_gradient: static: the gradient bound ``G`` of the march.
        accuracy:     static: the shortest step, and the march's resolution.
        open:         static: the container's wall is not seen.
        slots:        static: crossings kept along a line (``max_trace``).
    """

    kind: ClassVar[str] = "isosurface"
    crossings: ClassVar[int] = 2
    sdl_keywords: ClassVar[tuple[str, ...]] = ("isosurface",)
    sdl_flags: ClassVar[tuple[str, ...]] = ("open",)
    costly_kernel: ClassVar[bool] = True

    constants: Float[Array, " C"] = eqx.field(converter=as_float)
    threshold: Float[Array, ""] = eqx.field(converter=as_float)
    container: Float[Array, "2 3"] = eqx.field(converter=as_float)
    expression: tuple = eqx.field(static=True)
    sphere: bool = eqx.field(static=True, default=False)
    max_gradient: float = eqx.field(static=True, default=1.1)
    accuracy: float = eqx.field(static=True, default=0.001)
    open: bool = eqx.field(static=True, default=False)
    slots: int = eqx.field(static=True, default=2)

    # a ray marches the 8 isosurfaces whose containers it enters first (``AbstractShape.cull_to``)
    cull_to: ClassVar[int | None] = CULL_TO

    def entry(self, o, d):
        _, _, crosses, start = self._span_ahead(o, d)
        return jnp.where(crosses, start, jnp.inf)

    def n_crossings(self) -> int:
        return self.slots

    @property
    def line_crossings(self) -> int:
        return self.slots

    def value(self, p: Float[Array, "3"]) -> Float[Array, ""]:
        """``F(p) − T``: negative inside."""
        return evaluate(self.expression, self.constants, (p[0], p[1], p[2])) - self.threshold

    def _span_ahead(self, o, d):
        """The container's crossings ``t`` (2,) and normals, whether the line's span in it reaches
        ahead of ``o``, and where that span starts (``o`` itself from inside)."""
        if self.sphere:
            t, n = sphere_hits(self.container[0], self.container[1, 0], o, d)
        else:
            t, n = box_hits(self.container[0], self.container[1], o, d)
        crosses = jnp.isfinite(t[0]) & jnp.isfinite(t[1]) & (t[1] > 0)
        return t, n, crosses, jnp.where(crosses, jnp.maximum(t[0], 0.0), 0.0)

    def hits(self, o, d):
        return isosurface_hits(self, o, d)

    def inside(self, p):
        return self._in_container(p) & (self.value(p) < 0)

    def _in_container(self, p):
        if self.sphere:
            return jnp.sum((p - self.container[0]) ** 2) < self.container[1, 0] ** 2
        lo = jnp.minimum(self.container[0], self.container[1])
        hi = jnp.maximum(self.container[0], self.container[1])
        return jnp.all((p > lo) & (p < hi))

    def bounds(self):
        from ._base import array_module

        xp = array_module(self.container)
        c = xp.asarray(self.container)
        if self.sphere:
            r = xp.abs(c[1, 0])
            return c[0] - r, c[0] + r
        return xp.minimum(c[0], c[1]), xp.maximum(c[0], c[1])

    @classmethod
    def parse_sdl(cls, keyword, args):
        compiled = args.function()  # first, as POV-Ray requires
        fields = {"compiled": compiled, "container": ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)),
                  "sphere": False, "threshold": 0.0, "accuracy": 0.001, "max_gradient": 1.1,
                  "slots": 2}
        while True:
            kw = args.keyword("contained_by", "threshold", "accuracy", "max_gradient", "evaluate",
                              "max_trace", "all_intersections", "open")
            if kw is None:
                return fields
            if kw == "contained_by":
                args.expect("{", "'{' after contained_by")
                inner = args.keyword("box", "sphere")
                if inner is None:
                    raise args.error("expected a box or a sphere in contained_by, found "
                                     f"{args.describe_next()}")
                args.expect("{", f"'{{' after {inner}")
                first = args.vector()
                args.comma()
                if inner == "box":
                    fields["container"], fields["sphere"] = (first, args.vector()), False
                else:
                    fields["container"], fields["sphere"] = (first, (args.float(), 0.0, 0.0)), True
                args.expect("}", f"'}}' to close the {inner}")
                args.expect("}", "'}' to close contained_by")
            elif kw == "evaluate":
                p0 = args.float()
                args.comma()
                p1 = args.float()
                args.comma()
                args.float()
                fields["max_gradient"] = max(p0 * p1, 1e-6)
            elif kw == "max_trace":
                fields["slots"] = int(min(max(args.float(), 2), MAX_SLOTS))
            elif kw == "all_intersections":
                fields["slots"] = MAX_SLOTS
            elif kw == "open":
                fields["open"] = True
            else:
                value = args.float()
                if kw in ("accuracy", "max_gradient") and not value > 0:
                    raise args.error(f"{kw} must be positive, found {value:g}")
                fields[kw] = value

    @classmethod
    def from_sdl(cls, fields):
        tree, constants = fields["compiled"]
        return Isosurface(constants=np.asarray(constants, np.float64).reshape(-1),
                          threshold=fields["threshold"],
                          container=np.asarray(fields["container"], np.float64), expression=tree,
                          sphere=fields["sphere"], max_gradient=float(fields["max_gradient"]),
                          accuracy=float(fields["accuracy"]), open=bool(fields.get("open", False)),
                          slots=int(fields["slots"]))


def isosurface_hits(shape: Isosurface, o, d):
    """The first ``shape.slots`` crossings of the line ahead of ``o`` (see the module docstring):
    ``t`` (K,) ascending, ``+inf`` in empty slots; unit outward normals (K, 3)."""
    k = shape.slots
    dtype = jnp.result_type(o, d, shape.constants, shape.container)
    o, d = jnp.asarray(o, dtype), jnp.asarray(d, dtype)
    t_box, n_box, crosses, start = shape._span_ahead(o, d)
    t_in, t_out = t_box[0], t_box[1]
    stop = jnp.where(crosses, t_out, 0.0)
    length = lax.stop_gradient(jnp.sqrt(jnp.sum(d * d)))  # the march chooses; it is not differentiated
    held = jax.lax.stop_gradient(shape)
    o_h, d_h = lax.stop_gradient(o), lax.stop_gradient(d)

    def g(t):
        return held.value(o_h + t * d_h)

    start_h, stop_h = lax.stop_gradient(start), lax.stop_gradient(stop)
    min_step = jnp.maximum(shape.accuracy / jnp.maximum(length, 1e-30), (stop_h - start_h) / MAX_STEPS)
    rate = shape.max_gradient * length

    def cond(state):
        i, t, _, count, _ = state
        return (i < MAX_STEPS) & (t < stop_h) & (count < k)

    def body(state):
        i, t, g_t, count, brackets = state
        step = jnp.maximum(jnp.abs(g_t) / rate, min_step)
        t_next = jnp.minimum(t + step, stop_h)
        g_next = g(t_next)
        crossed = (g_t < 0) != (g_next < 0)
        slot = jnp.where(crossed, count, k)  # k: out of range, dropped
        brackets = brackets.at[slot].set(jnp.stack([t, t_next]), mode="drop")
        return i + 1, t_next, g_next, count + crossed.astype(count.dtype), brackets

    init = (jnp.zeros((), jnp.int32), start_h, g(start_h), jnp.zeros((), jnp.int32),
            jnp.full((k, 2), jnp.inf, dtype))
    _, _, _, count, brackets = lax.while_loop(cond, body, init)
    found = (jnp.arange(k) < count) & crosses
    lo = jnp.where(found, brackets[:, 0], 0.0)
    hi = jnp.where(found, brackets[:, 1], 0.0)
    roots, _ = _bisect(jax.vmap(g), lo, hi, BISECTIONS)

    def crossing(t_star):
        t = differentiable_root(lambda t_: shape.value(o + t_ * d), t_star)
        p = o + t * d
        n = safe_normalize(jax.grad(shape.value)(p))  # (+z where ∇F vanishes: a ball's centre)
        return t, n

    t_in_root, n_in_root = jax.vmap(crossing)(jnp.where(found, roots, 0.0))
    t_root = jnp.where(found, t_in_root, jnp.inf)
    n_root = n_in_root  # unit in every slot, as every kernel's
    if shape.open:
        return t_root, n_root
    # the container's wall where it cuts the solid: entered (ahead of o) or left inside it
    inside_at = jax.vmap(lambda t: g(t) < 0)(jnp.where(crosses, t_box, 0.0))
    ahead = jnp.stack([t_in >= 0, jnp.asarray(True)])
    wall_t = jnp.where(crosses & inside_at & ahead, t_box, jnp.inf)
    t_all = jnp.concatenate([t_root, wall_t])
    n_all = jnp.concatenate([n_root, n_box])
    order = jnp.argsort(t_all)[:k]
    return t_all[order], n_all[order]
