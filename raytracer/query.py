"""Ray queries against one scene object, answered by the renderer's own geometry.

``trace`` shoots a ray and returns the nearest hit with its normal; ``inside`` tests a point. Both
use exactly what the renderer uses — the shape kernels, composed transforms, the CSG inside circuit
and ``clipped_by`` — so an answer is what a render would hit. Each is one jit-compiled function per
object (the geometry is packed once, outside the compiled program), for the SDL's ``trace()`` and
``inside()`` and for users placing things on surfaces.

POV-Ray's definitions (manual, "Functions"): ``trace(OBJECT, A, B [, N])`` returns the nearest
intersection of the ray from ``A`` along ``B`` with OBJECT, or <0,0,0> when there is none; ``N``
receives the normal (<0,0,0> when nothing was hit). ``inside(OBJECT, P)`` is 1 inside the object's
solid, else 0; a clipped object is inside where its solid and every clipping object are.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from ._dtype import default_float
from ._plan import make_plan
from .scene import AbstractObject, Camera, Scene
from .shading._geometry import (
    build_inside_circuit,
    closest_hit,
    evaluate_inside,
    pack_geometry,
    static_prim_mask,
)

# crossings closer to the ray's start than this (in units of the normalised direction) are
# ignored, as POV-Ray ignores depths below its own small tolerance
T_MIN = 1e-6


def _packed(obj: AbstractObject):
    plan = make_plan(Scene(camera=Camera(), objects=(obj,)))
    if not plan.prims:
        return None, None
    # packed once, outside the program: the inverse transforms (LAPACK calls) and stacking are
    # then constants, and each call runs only the intersection (~80 -> ~15 µs per call)
    return plan, pack_geometry(plan, default_float(), accelerate=False)


def compile_trace(obj: AbstractObject) -> Callable[[jax.Array], jax.Array] | None:
    """The nearest hit of a ray with ``obj``, or None when nothing of ``obj`` can be hit.

    Returns:
        ``f(ray)``: ``ray`` (6,) = origin and UNIT direction; the result (7,) is
        ``[found (1 or 0), point (3,), unit normal (3,)]``, the normal facing out of the solid.
    """
    plan, geo = _packed(obj)
    if plan is None:
        return None
    dtype = default_float()
    visible = jnp.asarray(static_prim_mask(geo, lambda i: plan.prims[i].rendered))

    @jax.jit
    def trace(ray):  # one (6,) argument, one (7,) result: one dispatch and one copy per call
        o, d = ray[:3].astype(dtype), ray[3:].astype(dtype)
        hit = closest_hit(geo, plan, o, d, T_MIN, visible)
        return jnp.concatenate([hit.found.astype(dtype)[None], o + hit.t * d, hit.normal])

    return trace


def compile_inside(obj: AbstractObject) -> Callable[[jax.Array], jax.Array] | None:
    """``f(p)``: whether the world point ``p`` (3,) is inside ``obj`` (None: nothing of ``obj``
    is left to test, so nothing is inside)."""
    plan, geo = _packed(obj)
    if plan is None:
        return None
    circuit = build_inside_circuit([(plan.roots[0], 0)])
    dtype = default_float()
    return jax.jit(lambda p: evaluate_inside(geo, circuit, jnp.asarray(p, dtype)[None])[0])
