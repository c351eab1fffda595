"""The scene model's construction paths: ``build`` equals calling the class; numpy leaves behave
as JAX arrays do under jit and grad, and cannot be mutated."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raytracer import scene as S
from raytracer._build import build
from raytracer._dtype import as_float, default_float

CASES = [
    (S.Sphere, dict(center=(1.0, 2.0, 3.0), radius=0.5)),
    (S.Box, dict(corner1=(-1, -1, -1), corner2=[1, 1, 1])),
    (S.Cylinder, dict(base=(0, 0, 0), cap=(0, 1, 0), radius=0.25, open=True)),
    (S.Cone, dict(base=(0, 0, 0), base_radius=1.0, cap=(0, 2, 0), cap_radius=0.0)),
    (S.Disc, dict(center=(0, 0, 0), normal=(0, 1, 0), radius=2.0)),  # hole_radius defaulted
    (S.Transform, dict(matrix=np.eye(4))),
    (S.Finish, dict(ambient=(0.2, 0.2, 0.2), phong=1.0)),
    (S.Pigment, dict(pattern="checker", values=(0.0, 1.0), colors=np.eye(2, 5))),
]


@pytest.mark.parametrize(("cls", "kwargs"), CASES, ids=[c.__name__ for c, _ in CASES])
def test_build_equals_calling_the_class(cls, kwargs):
    a, b = cls(**kwargs), build(cls, **kwargs)
    assert type(a) is type(b)
    la, ta = jax.tree_util.tree_flatten(a)
    lb, tb = jax.tree_util.tree_flatten(b)
    assert ta == tb  # same static fields and structure
    for x, y in zip(la, lb, strict=True):
        assert x.dtype == y.dtype == default_float()
        np.testing.assert_array_equal(x, y)
    assert eqx.tree_equal(a, b)


def test_build_object_with_shared_texture():
    tex = S.Texture.of(S.Pigment.solid((1.0, 0.0, 0.0)))
    objs = [build(S.Object, shape=build(S.Sphere, center=(i, 0, 0), radius=1.0), texture=tex)
            for i in range(3)]
    assert all(o.texture is tex for o in objs)
    assert eqx.tree_equal(objs[0], S.Object(S.Sphere((0, 0, 0), 1.0), texture=tex))


def test_build_runs_check_init_and_rejects_bad_fields():
    with pytest.raises(ValueError, match="at least one child"):
        build(S.CSG, operation="union", children=())
    with pytest.raises(ValueError, match="unknown CSG operation"):
        build(S.CSG, operation="xor", children=(S.Object(S.Sphere((0, 0, 0), 1.0)),))
    with pytest.raises(TypeError, match="missing field 'radius'"):
        build(S.Sphere, center=(0, 0, 0))
    with pytest.raises(TypeError, match="unknown fields"):
        build(S.Sphere, center=(0, 0, 0), radius=1.0, colour=3)


def test_build_refuses_a_custom_init():
    class Custom(eqx.Module):
        a: float

        def __init__(self, a):
            self.a = 2 * a

    with pytest.raises(TypeError, match="custom __init__"):
        build(Custom, a=1.0)


def test_concrete_leaves_are_read_only_numpy():
    s = S.Sphere((0.0, 0.0, 0.0), 1.0)
    assert isinstance(s.center, np.ndarray)
    with pytest.raises(ValueError, match="read-only"):
        s.center[0] = 5.0
    src = np.zeros(3)
    as_float(src)
    assert src.flags.writeable  # the caller's array is copied, never frozen


def test_jax_arrays_and_tracers_pass_through():
    x = jnp.ones(3, dtype=default_float())
    assert as_float(x) is x

    def f(r):
        return S.Sphere((0.0, 0.0, 0.0), r).radius * 3.0

    assert float(jax.grad(f)(2.0)) == 3.0  # a tracer went through the converter uncast


def test_numpy_leaves_under_jit_and_grad():
    sphere = S.Sphere((1.0, 2.0, 3.0), 2.0)

    @eqx.filter_jit
    def volume_and_offset(s):
        return 4.0 / 3.0 * jnp.pi * s.radius**3 + jnp.sum(s.center)

    assert np.isclose(float(volume_and_offset(sphere)), 4.0 / 3.0 * np.pi * 8.0 + 6.0, rtol=1e-6)
    g = eqx.filter_grad(volume_and_offset)(sphere)
    assert np.isclose(float(g.radius), 4.0 * np.pi * 4.0, rtol=1e-6)  # d/dr (4/3 π r³) = 4π r²
    np.testing.assert_allclose(np.asarray(g.center), np.ones(3))


def test_python_numbers_become_the_arrays_numpy_makes_of_them():
    """``as_float`` reads Python numbers, tuples of them and tuples of such rows (a colour map)
    without numpy's checks: bit for bit the
    array numpy makes (through float64), signed zeros, NaN and infinities included, and a finite
    value past float32's range is refused as before."""
    from raytracer._dtype import OutOfPrecision, _as_float

    rng = np.random.default_rng(0)
    random = (rng.normal(size=40) * 10.0 ** rng.integers(-30, 30, 40)).tolist()
    values = [0.0, -0.0, 1, -7, 2**53 - 1, -(2**53) + 1, 3.4e38, -3.4e38, float("inf"), -float("inf"),
              float("nan"), 1e-45, -1e-40, *random]
    rows = [tuple(tuple(values[i + 5 * r:i + 5 * r + 5]) for r in range(k))
            for k in (1, 2) for i in range(0, 30, 6)]
    for x in values + [tuple(values[i:i + k]) for k in (2, 3, 5) for i in range(0, 40, 7)] + rows + [()]:
        want = np.asarray(x, np.float64).astype(default_float())
        got = _as_float(x)
        assert got.dtype == want.dtype and got.shape == want.shape and not got.flags.writeable
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want))
    if not jax.config.jax_enable_x64:
        for x in (1e39, -1e39, (0.0, 1e39), ((0.0, 1.0), (1e39, 0.0))):
            with pytest.raises(OutOfPrecision, match="float32's range"):
                _as_float(x)


def test_objects_share_a_finish_only_when_its_values_are_equal_bit_for_bit():
    from raytracer import load_scene

    finishes = ["ambient 0.1 diffuse 0.6", "diffuse 0.6 ambient 0.1", "ambient 0.1 diffuse 0.6",
                "ambient -0.0", "ambient 0.0", "ambient 0.1 diffuse 0.6 reflection 0.2"]
    text = "camera { location -5*z look_at 0 }\n" + "\n".join(
        f"sphere {{ <{i}, 0, 0>, 0.4 finish {{ {f} }} }}" for i, f in enumerate(finishes))
    got = [o.texture.layers[0].finish for o in load_scene(text).objects]
    assert got[0] is got[2]  # equal values: one module
    assert got[3] is not got[4] and np.signbit(got[3].ambient).all()
    assert got[5] is not got[0] and got[5].reflection is not None
    assert got[1] == got[0]  # (written in another order: equal, shared or not)
