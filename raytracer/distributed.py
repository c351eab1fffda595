"""One render, one gradient, or one animation across several processes or machines (``jax.distributed``).

JAX runs multi-controller: every process runs the same program. After
``jax.distributed.initialize(...)`` (``initialize`` below passes its arguments on; on a Slurm,
Open MPI or TPU cluster it finds them itself), each process calls the same function here with the
same scene:

* ``render(scene, width=…, height=…)``: process ``p`` of ``P`` traces part ``p`` of the image's
  tiles (tiles interleave pixels over the whole image, so the parts cost about the same), on its
  own devices (``jax.local_devices()``: one CPU, or every GPU of its machine); the parts are
  gathered (``multihost_utils.process_allgather``) and every process returns the whole image.
* ``value_and_grad(loss, scene, width=…, height=…)``: each process differentiates its part
  (``jax.vjp``), the image's cotangent comes from the gathered image, and the scene-shaped
  gradients of the parts are summed across processes. Every process returns the same
  ``(loss(image), d loss / d scene)``.
* ``frames(count)``: the animation frames a process renders (frame ``f`` goes to process
  ``f mod P``): the CLI's ``render --all-frames``.

On CPUs the cross-process collectives are gloo's (JAX's default), over TCP: processes on several
machines need only the coordinator's address. The same code runs on GPUs (``pip install
"jax[cuda12]"``): nothing here assumes a device kind. A single process (``P = 1``, no
``initialize``) gets exactly ``raytracer.render``'s image.

The ray-tree room (``capacity``) grows as in ``raytracer.render``: the dropped-ray counts are
summed across processes, so every process renders again together when any part overflowed.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import multihost_utils

from ._packed import pack
from ._plan import make_plan
from ._tiles import FIRST_CAPACITY, _assemble, _background_only, _render_part, _warn_dropped
from .render import _check, use_compilation_cache
from .scene import Scene


def initialize(coordinator_address: str | None = None, num_processes: int | None = None,
               process_id: int | None = None, **kwargs) -> None:
    """``jax.distributed.initialize`` (before any other JAX call): ``coordinator_address``
    ``"host:port"`` of process 0, the number of processes and this one's index; all optional on
    Slurm, Open MPI and TPU clusters."""
    jax.distributed.initialize(coordinator_address=coordinator_address, num_processes=num_processes,
                               process_id=process_id, **kwargs)


def frames(count: int, first: int = 0) -> list[int]:
    """The frames ``first … first + count - 1`` this process renders (every ``P``-th)."""
    return list(range(first + jax.process_index(), first + count, jax.process_count()))


def _gather(x) -> np.ndarray:
    """(P, …) this value of every process, in process order (a single process: x[None])."""
    if jax.process_count() == 1:
        return np.asarray(x)[None]
    return np.asarray(multihost_utils.process_allgather(np.asarray(x)))


def _part(scene: Scene, width: int, height: int, k: int, capacity):
    """This process's part: (colours (tiles, pixels per tile, 3), rays dropped)."""
    return _render_part(pack(scene), width, height, k, jax.process_count(),
                                jnp.asarray(jax.process_index()), capacity)


def _capacity(capacity):
    if capacity == "auto":
        return FIRST_CAPACITY, True
    if capacity is not None and (type(capacity) is not int or capacity < 1):
        raise ValueError(f"capacity must be a positive int, None or 'auto', got {capacity!r}")
    return capacity, False


def _whole(scene: Scene, parts, width: int, height: int, k: int):
    return _assemble(scene.settings, list(parts), width, height, k)


def render(scene: Scene, *, width: int, height: int, spp: int = 1, capacity: int | None | str = "auto"):
    """``raytracer.render`` with the tiles split across processes; every process gets the image."""
    k = _check(width, height, spp)
    use_compilation_cache()
    if not any(prim.rendered for prim in make_plan(scene).prims):
        return _background_only(scene, width, height, k)
    capacity, grow = _capacity(capacity)
    while True:
        colours, dropped = _part(scene, width, height, k, capacity)
        lost = int(_gather(dropped).sum())
        if capacity is None or lost == 0 or not grow:
            if capacity is not None:
                _warn_dropped(lost, capacity)
            return _whole(scene, _gather(colours), width, height, k)
        capacity *= 4  # every process sees the same total, so all render again together


def value_and_grad(loss, scene: Scene, *, width: int, height: int, spp: int = 1,
                   capacity: int | None | str = "auto"):
    """``(loss(image), jax.grad of it with respect to scene)`` with the render split across
    processes: the same values on every process. ``loss`` maps the (H, W, 3) image to a scalar."""
    k = _check(width, height, spp)
    use_compilation_cache()
    capacity, grow = _capacity(capacity)
    while True:
        colours, pullback, dropped = jax.vjp(
            lambda s, room=capacity: _part(s, width, height, k, room), scene, has_aux=True)
        lost = int(_gather(dropped).sum())
        if capacity is None or lost == 0 or not grow:
            break
        capacity *= 4
    if capacity is not None:
        _warn_dropped(lost, capacity)
    parts = jnp.asarray(_gather(colours))
    value, image_pullback = jax.vjp(lambda p: loss(_whole(scene, p, width, height, k)), parts)
    (d_parts,) = image_pullback(jnp.ones_like(value))
    (d_scene,) = pullback(d_parts[jax.process_index()])
    leaves, tree = jax.tree_util.tree_flatten(d_scene)
    summed = [x if x is None or x.dtype == jax.dtypes.float0 else jnp.asarray(_gather(x).sum(axis=0), x.dtype)
              for x in leaves]
    return value, jax.tree_util.tree_unflatten(tree, summed)
