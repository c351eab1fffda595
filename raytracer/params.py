"""Naming, reading and replacing a scene's differentiable parameters.

Every inexact array leaf of a :class:`~raytracer.Scene` is a parameter. Its name is its path in
the pytree, written as Python would: ``objects[1].texture.layers[0].finish.diffuse``,
``lights[0].color``, ``camera.location``. These helpers are thin wrappers over
``jax.tree_util`` paths and ``eqx.tree_at``, so they work on scenes under ``jit`` and ``grad``.

Which parameters move visibility edges (silhouettes, shadow boundaries, reflected/refracted
outlines) — there, AD gives the derivative of each pixel's colour with the pixel's *hit object
held fixed*, and finite differences see a jump where an edge crosses a pixel centre:

================================================  ============================================
moves edges                                       never moves edges
================================================  ============================================
shape parameters and object transforms            pigment colours (incl. filter/transmit), maps
camera location / look_at / angle / vectors       ambient, emission, diffuse, brilliance,
light position and point_at (shadow edges)        phong, phong_size, specular, roughness,
ior (outlines seen through refraction; and TIR)   metallic, reflection amounts, light colour,
pattern transforms (colour edges of checker…)     fade_distance/fade_power, ambient_light
================================================  ============================================
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp


def _name(path) -> str:
    out = ""
    for key in path:
        if isinstance(key, jax.tree_util.GetAttrKey):
            out += f".{key.name}"
        elif isinstance(key, jax.tree_util.SequenceKey):
            out += f"[{key.idx}]"
        elif isinstance(key, jax.tree_util.DictKey):
            out += f"[{key.key!r}]"
        else:
            out += str(key)
    return out.lstrip(".")


def _is_parameter(x) -> bool:
    return eqx.is_inexact_array(x)


def _named(tree) -> dict:
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {_name(path): leaf for path, leaf in leaves if _is_parameter(leaf)}


def placed(values):
    """``values`` (a pytree of arrays) placed as the render's programs take them: replicated over
    this process's devices where the API splits the CPU into several (``raytracer/_xla.py``);
    traced values, and values where the process has one device, as they are.

    For the values a fit starts from: its step (``jax.jit`` of a loss and its gradient) returns
    gradients placed so, since its render runs on every device, and the parameters it is called
    with next are then placed so too. A first call with values made on one device (a NumPy array,
    ``jnp.asarray``) is another input to ``jit``, which traces and compiles the step a second time
    at its second call (3.5 s for a sphere's fit without the boundary term, 9 s with it). Not for
    the scene's other values a loss closes over: those stay NumPy arrays (:func:`parameters`),
    which the packing reads for the scene's structure (a colour that filters)."""
    if jax.process_count() > 1 or any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(values)):
        return values
    devices = jax.local_devices()
    if len(devices) < 2:
        return values
    mesh = jax.make_mesh((len(devices),), ("tiles",), devices=devices,
                         axis_types=(jax.sharding.AxisType.Auto,))
    return jax.device_put(values, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec()))


def parameters(tree) -> dict[str, jax.Array]:
    """All differentiable parameters of ``tree`` (a scene or any sub-pytree), by name (start a fit
    from :func:`placed` values of them: its step then compiles once)."""
    return _named(tree)


def get(tree, name: str) -> jax.Array:
    """The parameter called ``name`` (see :func:`parameters` for the names)."""
    params = _named(tree)
    if name not in params:
        close = [n for n in params if name.split(".")[-1] in n][:5]
        hint = f"; did you mean one of {close}?" if close else ""
        raise KeyError(f"no parameter {name!r}{hint}")
    return params[name]


def replace(tree, values: dict[str, jax.Array]):
    """A copy of ``tree`` with the named parameters replaced (shapes must match)."""
    names = list(values)
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    by_name = {_name(path): i for i, (path, leaf) in enumerate(leaves) if _is_parameter(leaf)}
    for n in names:
        if n not in by_name:
            raise KeyError(f"no parameter {n!r}")
    flat, treedef = jax.tree_util.tree_flatten(tree)
    for n in names:
        old = flat[by_name[n]]
        new = jnp.asarray(values[n], dtype=old.dtype)
        if new.shape != old.shape:
            raise ValueError(f"parameter {n!r} has shape {old.shape}, got {new.shape}")
        flat[by_name[n]] = new
    return jax.tree_util.tree_unflatten(treedef, flat)


def split(tree, names: list[str]):
    """``(selected, rest)`` such that ``eqx.combine(selected, rest) == tree``; ``selected`` holds only
    the named parameters (others ``None``): the sub-pytree to hand to ``jax.grad`` or an optimiser."""
    wanted = set(names)
    missing = wanted - set(_named(tree))
    if missing:
        raise KeyError(f"no parameters {sorted(missing)}")
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    mask_flat = [(_name(path) in wanted) and _is_parameter(leaf) for path, leaf in leaves]
    treedef = jax.tree_util.tree_structure(tree)
    mask = jax.tree_util.tree_unflatten(treedef, mask_flat)
    return eqx.partition(tree, mask)


# Parameter names (as :func:`parameters` writes them) that can move a visibility edge: a silhouette,
# a shadow boundary, a reflected/refracted outline, a pattern's colour edge or a bailout threshold.
# Everything else (colours, finish coefficients, light colour and fading, ambient light, background)
# changes pixel colours smoothly with the hit objects fixed.
_EDGE_MOVING = (".shape.", ".transform.", "camera.", ".position", ".point_at", ".spot.", ".area.",
                ".ior", ".pigment.values", ".pigment.vector", ".pigment.frequency", ".pigment.phase",
                ".pigment.turbulence", ".pigment.omega", ".pigment.lambda_", "adc_bailout",
                ".clipped_by")


def moves_edges(name: str) -> bool:
    """Whether the parameter called ``name`` can move a visibility or pattern edge (see the table above).

    ``adc_bailout`` counts as one: it is a threshold, so its derivative is zero almost everywhere and
    a jump where a ray weight crosses it.
    """
    dotted = "." + name
    return any(key in dotted for key in _EDGE_MOVING)


def random_tangent(tree, key: jax.Array, names=None):
    """A tangent for ``jax.jvp`` with ``tree``'s structure: a standard-normal random direction in the
    named parameters (all parameters if ``names`` is None; ``names`` may also be a predicate on the
    name) and zeros elsewhere, so one JVP checks many parameters at once."""
    if names is None:
        chosen = lambda n: True  # noqa: E731
    elif callable(names):
        chosen = names
    else:
        wanted = set(names)
        missing = wanted - set(_named(tree))
        if missing:
            raise KeyError(f"no parameters {sorted(missing)}")
        chosen = wanted.__contains__
    leaves, treedef = jax.tree_util.tree_flatten_with_path(tree)
    keys = jax.random.split(key, max(len(leaves), 1))
    out = []
    for k, (path, leaf) in zip(keys, leaves, strict=False):
        if not _is_parameter(leaf):
            out.append(leaf)
        elif chosen(_name(path)):
            out.append(jax.random.normal(k, leaf.shape, leaf.dtype))
        else:
            out.append(jnp.zeros_like(leaf))
    return jax.tree_util.tree_unflatten(treedef, out)
