"""TraceRay: POV-Ray's recursive (Whitted) model, as the shading model of one hit driven by a scheduler.

The seed's recursion — shoot shadow rays to all lights, add the local lighting, shoot the reflected
and the refracted ray, combine — is two pieces joined at one function:

  * ``_model.shade_batch(ctx, rays)``: POV-Ray's shading model for a batch of rays (each one's hit,
    local lighting over the texture layers, shadows, and the children it spawns with their
    coefficients): ``shade(ctx, ray)`` vmapped, with adaptive area lights' shadows done per batch;
  * ``_scheduler.trace_tree(shade_rays, rays, …)``: the tree of rays, level by level (pools, chunk
    skipping, compaction; ``while_loop``s forward, a ``lax.scan`` where differentiated) and the
    reverse combine ``local + coef · child``.

Per-ray decisions are masks and weights: a child whose weight falls below ``adc_bailout`` (or that
does not exist) is a dead slot and contributes nothing. This module joins the two for the renderer.
"""

from __future__ import annotations

import jax

from .._plan import Effects
from ._model import TraceContext as TraceContext
from ._model import camera_rays, child_slots, shade_batch
from ._model import initial_media as initial_media
from ._model import make_context as make_context
from ._scheduler import slots_per_ray, trace_tree


def slots_per_camera_ray(effects: Effects, capacity: int | None = None) -> int:
    """Pool slots per camera ray: the widest level of the scene's ray tree, or ``capacity``."""
    return slots_per_ray(child_slots(effects), effects.depth, capacity)


def trace(ctx: TraceContext, o, d, chunk: int, capacity: int | None = None,
          media=None, grad_chunk: int | None = None, alive=None) -> tuple[jax.Array, jax.Array]:
    """Colours (N, 3) of N camera rays (origins and unit directions (N, 3)) that start inside the
    interiors ``media`` (``initial_media(ctx, eye)``; None: none), the dead ones of ``alive`` (N,)
    (None: none) padding that costs nothing where a whole chunk is dead, and the number of child rays
    dropped for lack of ``capacity`` (0 without one), shaded ``chunk`` rays at a time (derivatives:
    ``grad_chunk``): see ``_scheduler.trace_tree``."""
    eff = ctx.plan.effects

    # a function, not functools.partial(shade, ctx): JAX names traced functions after their source,
    # and for a partial it prints the arguments: the whole context (14 s for 1,000 spheres)
    def shade_rays(rays):
        return shade_batch(ctx, rays)

    return trace_tree(shade_rays, camera_rays(o, d, media, alive), depth=eff.depth,
                      branch=child_slots(eff), chunk=chunk, capacity=capacity, grad_chunk=grad_chunk)
