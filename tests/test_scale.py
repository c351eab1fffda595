"""The compiled program does not grow with the scene: the scene is packed before the jit
boundary, so 20 and 200 spheres give programs of the same operations and a handful of arguments,
not ~16 per object; and the ray tree is held in pools of a bounded width, forward and reverse."""

import math
import re
import sys
from collections import Counter

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raytracer as rt
from raytracer import load_scene
from raytracer._packed import pack
from raytracer._packing import skeleton
from raytracer._tiles import FORWARD_CAPACITY, _render_part
from raytracer.render import PROGRESS_PARTS, compile_render
from raytracer.shading import _accel

render_module = sys.modules["raytracer.render"]  # the package's `render` is the function
packing = sys.modules["raytracer._packed"]
tiles = sys.modules["raytracer._tiles"]


def _spheres(n: int) -> str:
    rows = [f"sphere {{ <{i % 20 - 10}, 0.5, {i // 20}>, 0.4 pigment {{ rgb <{i % 7 / 7}, 0.5, 0.5> }} }}"
            for i in range(n)]
    return ("camera { location <0, 5, -12> look_at <0, 0, 3> }\nlight_source { <-5, 9, -9> color rgb 1 }\n"
            "plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }\n" + "\n".join(rows))


@pytest.mark.parametrize("mode", ["native", "none"])
def test_program_has_the_same_operations_for_20_and_200_spheres(tmp_path, monkeypatch, mode):
    if mode == "native" and _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    monkeypatch.setenv("RAYTRACER_ACCEL", mode)
    programs = []
    for n in (20, 200):
        path = tmp_path / f"s{n}.pov"
        path.write_text(_spheres(n))
        scene = load_scene(path, width=16, height=12)
        text = _render_part.lower(pack(scene), 16, 12, 1, 1, jnp.asarray(0), 4).as_text()
        ops = Counter(re.findall(r"= (\"?[a-z_]+\.[a-z_]+)", text))
        ops.pop("stablehlo.constant", None)  # the per-primitive tables are constants
        main = text[text.index("func.func public @main"):]
        programs.append((ops, main[:main.index("{")].count("%arg")))
    (ops20, args20), (ops200, args200) = programs
    assert ops20 == ops200
    assert args20 == args200 < 100


def _varied(n: int, csg: bool = False) -> str:
    """A plane and ``n`` spheres of every kind of material row the program looks up at a traced
    primitive: solid and checker pigments, a wave, fresnel reflection with conserve_energy, an
    inverted sphere, two texture layers, transparent ones that filter shadows, glass (refraction:
    the camera's media are in the program)."""
    looks = ["pigment { rgb <0.8, 0.4, 0.2> }",
             "pigment { checker rgb 1 rgb 0 scale 0.1 sine_wave } inverse",
             "pigment { rgb 0.5 } finish { reflection { 0.1, 0.6 fresnel on } conserve_energy }",
             "texture { pigment { rgb 1 } } texture { pigment { checker rgbt 1 rgbt <0, 0, 0, 0.5> } }",
             "pigment { rgbf <0.9, 0.9, 0.2, 0.8> }",
             "pigment { rgbf <1, 1, 1, 0.9> } interior { ior 1.4 }"]
    if csg:  # no glass: the camera's media would test each CSG object through the inside circuit
        looks = looks[:-1]
    rows = [f"sphere {{ <{i % 20 - 10}, 0.5, {i // 20}>, 0.4 {looks[i % len(looks)]} }}" for i in range(n)]
    if csg:  # and every seventh a CSG object the hierarchy holds as one item
        rows[::7] = [f"intersection {{ sphere {{ <{i % 20 - 10}, 0.5, {i // 20}>, 0.45 }} box {{ <-0.35, "
                     f"0.1, -0.35>, <0.35, 0.8, 0.35> translate <{i % 20 - 10}, 0, {i // 20}> }} "
                     f"{looks[i % len(looks)]} }}" for i in range(0, n, 7)]
    return ("camera { location <0, 5, -12> look_at <0, 0, 3> }\nlight_source { <-5, 9, -9> color rgb 1 }\n"
            "plane { y, 0 pigment { checker rgb 1 rgb 0.3 } }\n" + "\n".join(rows))


def test_scenes_that_differ_only_in_their_number_of_items_lower_to_one_program(tmp_path, monkeypatch):
    """The per-primitive tables (materials, normal signs, media, bounding units) and the
    hierarchy's tables are arrays padded to ``_packing.bucket`` sizes, not constants of the
    program, and more than 16 straight passes are rounded up to a bucket: 105 and 110 spheres (one
    bucket of primitives, items and passes) lower to the same program text, so XLA's compile of the
    first serves the second through the persistent cache; 130 spheres (the next bucket) do not.
    Before, each count made its own program (per-primitive constant tables, the tree's depth)."""
    if _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    texts = {}
    for n in (105, 110, 130):
        path = tmp_path / f"v{n}.pov"
        path.write_text(_varied(n))
        scene = load_scene(path, width=16, height=12)
        packed = pack(scene)
        assert packed.geo.accel is not None and packed.geo.accel.n_items == n
        texts[n] = _render_part.lower(packed, 16, 12, 1, 1, jnp.asarray(0), 4).as_text()
    assert texts[105] == texts[110]
    assert texts[110] != texts[130]


@pytest.mark.slow  # two programs lowered
def test_program_does_not_grow_with_lights_of_one_kind(tmp_path):
    """Lights of one structure are one vmapped computation: five point lights make the program two
    do, give or take the stacking (before, each light added its shadow rays and terms: 2,067 → 2,520
    operations from two to five lights)."""
    sizes = []
    for n in (2, 5):
        lights = "".join(f"\nlight_source {{ <{i}, 9, -9> color rgb 0.3 }}" for i in range(n - 1))
        path = tmp_path / f"l{n}.pov"
        path.write_text(_spheres(20) + lights)
        scene = load_scene(path, width=16, height=12)
        text = _render_part.lower(pack(scene), 16, 12, 1, 1, jnp.asarray(0), 4).as_text()
        sizes.append(len(re.findall(r"= (\"?[a-z_]+\.[a-z_]+)", text)))
    assert sizes[1] <= sizes[0] + 20, sizes


def test_packing_a_traced_scene_is_the_same_operations_for_20_and_200_spheres(tmp_path):
    """Under ``jax.grad`` without ``jit`` (an optimisation loop's eager step) the packing is traced
    again on every call, and each of its primitives is linearised on its own: gathering one entry
    per object made that 8,500 primitives (6 s a gradient) for 200 spheres. The gathers are one
    jitted call each, so the traced packing does not grow with the number of objects."""
    counts = []
    for n in (20, 200):
        path = tmp_path / f"s{n}.pov"
        path.write_text(_spheres(n))
        scene = load_scene(path, width=16, height=12)
        p, rest = eqx.partition(scene, eqx.is_inexact_array)

        def packed(p, rest=rest):
            leaves = jax.tree_util.tree_leaves(pack(eqx.combine(p, rest)))
            return [x for x in leaves if isinstance(x, jax.Array)]

        jaxpr = jax.make_jaxpr(packed)(p)
        counts.append(len(jaxpr.eqns))
    assert counts[0] == counts[1] < 200, counts

# ---------------------------------------------------------------- memory of the ray tree (item 3)
_GLASS_BOX = """#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 20 }
camera { location <0, 1.5, -4> look_at <0, 0.5, 0> right x*4/3 angle 45 }
light_source { <-5, 10, -8> color rgb 1 }
plane { y, 0 pigment { checker rgb 0.9, rgb 0.1 } }
box { <-0.6, 0, -0.6>, <0.6, 1.2, 0.6> rotate <0, 45, 0>
  pigment { rgbf <1, 1, 1, 0.9> }
  finish { ambient 0 diffuse 0 reflection { 0, 1 fresnel on } conserve_energy } interior { ior 1.6 } }
"""


def _largest_array_bytes(jaxpr) -> int:
    """The largest array any equation of ``jaxpr`` (and of the programs nested in it) makes."""
    best = 0
    for eqn in jaxpr.eqns:
        for v in eqn.outvars:
            if hasattr(v.aval, "shape"):
                best = max(best, math.prod(v.aval.shape) * v.aval.dtype.itemsize)
        for param in eqn.params.values():
            for sub in param if isinstance(param, (list, tuple)) else (param,):
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    best = max(best, _largest_array_bytes(inner))
    return best


@pytest.mark.parametrize("capacity", ["auto", None])
def test_reverse_mode_program_of_a_depth_20_tree_holds_a_tile_not_the_full_tree(tmp_path, capacity):
    # the glass box at max_trace_level 20 (its full-width tree: "Out of memory allocating
    # 112457682608 bytes"): the exact full-width tree needs 2^19 slots per camera ray; the default
    # compacts each level's live rays into FORWARD_CAPACITY slots per camera ray, so the largest
    # array of jax.grad's program is bounded by pixels × capacity × depth × a few values per slot
    # (16: the widest residual is a slot's vmapped pigments, RGBFT for each transparent crossing of
    # a shadow ray; 10 here, 2.4 MB. The full tree's would be 2^19 / 4 / 20 ≈ 6,500 times larger
    # per value)
    path = tmp_path / "box.pov"
    path.write_text(_GLASS_BOX)
    scene = load_scene(path, width=32, height=24)
    params, rest = eqx.partition(scene, eqx.is_inexact_array)

    def loss(p):
        return jnp.mean(rt.render(eqx.combine(p, rest), width=32, height=24, capacity=capacity))

    largest = _largest_array_bytes(jax.make_jaxpr(jax.grad(loss))(params).jaxpr)
    itemsize = scene.camera.location.dtype.itemsize
    if capacity is None:
        assert largest >= 32 * 24 * 2 ** 19 * itemsize
    else:
        assert largest <= 32 * 24 * FORWARD_CAPACITY * 20 * 16 * itemsize


_FULL_GLASS = """#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 adc_bailout 0 }
camera { location <0, 0, -1.6> look_at 0 angle 40 }
light_source { <-5, 10, -8> color rgb 1 }
plane { y, -2 pigment { checker rgb 0.9, rgb 0.1 } }
sphere { 0, 1 pigment { rgbf <1, 1, 1, 0.9> } finish { reflection { 0, 1 fresnel on } conserve_energy }
  interior { ior 1.5 } }
"""


def test_a_tree_wider_than_the_compiled_room_warns_at_run_time_and_auto_finds_the_room(tmp_path):
    # every pixel sees the glass sphere, and with adc_bailout 0 each ray has two live children at
    # the second level: one slot per camera ray is too few. Under jit the values are unknown when
    # the program is made, so the loss is reported when it runs; outside jit "auto" grows the room
    path = tmp_path / "glass.pov"
    path.write_text(_FULL_GLASS)
    scene = load_scene(path, width=8, height=6)
    params, rest = eqx.partition(scene, eqx.is_inexact_array)
    with pytest.warns(RuntimeWarning, match="did not fit the compiled room of 1 slots"):
        jax.block_until_ready(jax.jit(lambda p: rt.render(eqx.combine(p, rest), width=8, height=6,
                                                          capacity=1))(params))
    exact = rt.render(scene, width=8, height=6, capacity=None)
    np.testing.assert_allclose(rt.render(scene, width=8, height=6), exact, rtol=1e-6, atol=1e-7)
    g_exact = jax.grad(lambda p: jnp.sum(rt.render(eqx.combine(p, rest), width=8, height=6,
                                                  capacity=None)))(params)
    g_auto = jax.grad(lambda p: jnp.sum(rt.render(eqx.combine(p, rest), width=8, height=6)))(params)
    for a, b in zip(jax.tree_util.tree_leaves(g_auto), jax.tree_util.tree_leaves(g_exact), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)


def test_auto_room_starts_small_grows_once_and_is_remembered(tmp_path, monkeypatch):
    # the glass sphere needs more than one slot per camera ray: the first eager render tries the
    # first room (FIRST_CAPACITY, here 1), drops rays and renders again with four times the room;
    # the next render of the scene starts there. Under jit nothing can grow: FORWARD_CAPACITY
    path = tmp_path / "glass.pov"
    path.write_text(_FULL_GLASS)
    scene = load_scene(path, width=8, height=6)
    params, rest = eqx.partition(scene, eqx.is_inexact_array)
    rooms = []
    real = render_module._render_packed
    monkeypatch.setattr(render_module, "_render_packed", lambda *a: (rooms.append(a[4]), real(*a))[1])
    monkeypatch.setattr(tiles, "_ROOM", {})
    monkeypatch.setattr(tiles, "FIRST_CAPACITY", 1)
    rt.render(scene, width=8, height=6)
    assert rooms == [1, 4]
    rt.render(scene, width=8, height=6)
    assert rooms[2:] == [4]
    jax.jit(lambda p: rt.render(eqx.combine(p, rest), width=8, height=6))(params)
    assert rooms[3:] == [FORWARD_CAPACITY]


def test_compiled_render_grows_the_room_for_the_part_that_overflowed(tmp_path):
    # compile_render (the CLI's path) with a progress bar renders in parts; a part that drops rays
    # is rendered again with four times the room, and the parts already done are kept: the image
    # is the exact full-width tree's, and progress counts every part once
    path = tmp_path / "glass.pov"
    path.write_text(_FULL_GLASS)
    scene = load_scene(path, width=16, height=12)
    seen = []
    run = compile_render(scene, width=16, height=12, capacity=1,
                         progress=lambda done, total: seen.append((done, total)))
    image = run(scene)
    exact = rt.render(scene, width=16, height=12, capacity=None)
    np.testing.assert_allclose(image, exact, rtol=1e-6, atol=1e-7)
    assert seen == [(i + 1, PROGRESS_PARTS) for i in range(PROGRESS_PARTS)]
    # without a progress bar: the image in one program, grown the same way
    whole = compile_render(scene, width=16, height=12, capacity=1)
    np.testing.assert_allclose(whole(scene), exact, rtol=1e-6, atol=1e-7)


def test_the_compiled_program_takes_the_plan_packing_made_and_only_for_the_same_scene(tmp_path, monkeypatch):
    """``compile_render`` makes the plan once: the program's trace takes it from the packing (for
    100,000 spheres a second plan and the skeleton's objects were 4 s of the compile). A scene
    whose objects match but whose lights differ gets a plan of its own, with its own lights."""
    calls = []
    made = render_module.make_plan
    for module in (render_module, packing):  # compile_render's plan, and the packing's
        monkeypatch.setattr(module, "make_plan", lambda s: calls.append(1) or made(s))
    scene = load_scene(_spheres(3))
    compile_render(scene, width=8, height=6)
    assert len(calls) == 1
    packed = pack(scene)
    two_lights = eqx.tree_at(lambda s: s.lights, packed.rest, packed.rest.lights * 2)
    other = packed._replace(rest=two_lights)
    calls.clear()
    plan = packing._plan_of(other)
    assert len(calls) == 1 and len(plan.lights) == 2 * len(packing._plan_of(packed).lights)


def test_the_skeleton_key_tells_structures_apart_and_builds_the_placeholder_tree():
    """The objects' skeleton (the compiled program's static key) is read from its leaves' shapes
    and dtypes in one pass: equal for scenes that differ only in values, different when one leaf's
    dtype or shape or a static field differs, and its tree is every array replaced by its
    ``Placeholder`` (independently: a ``tree_map``). A leaf that is not an array is kept as it is."""
    from raytracer._packing import Placeholder, skeleton

    def objects(radius=1.0, centre_dtype=np.float32, triangles=1, open_=False):
        tri = np.arange(9 * triangles, dtype=np.float32).reshape(triangles, 3, 3)
        sphere = eqx.tree_at(lambda s: s.center, rt.Sphere((0, 1, 2), radius),
                             np.array([0, 1, 2], centre_dtype))  # (the constructor casts)
        return (rt.Object(sphere),
                rt.Object(rt.Mesh(tri, None)),
                rt.Object(rt.Cylinder((0, 0, 0), (0, 1, 0), 0.5, open=open_)))

    base = skeleton(objects())
    expected = jax.tree_util.tree_map(lambda x: Placeholder(tuple(np.shape(x)), str(np.asarray(x).dtype)),
                                      objects())
    assert base.value == expected
    assert skeleton(objects(radius=2.0)) == base and hash(skeleton(objects(radius=2.0))) == hash(base)
    for other in (objects(centre_dtype=np.float64), objects(triangles=2), objects(open_=True)):
        assert skeleton(other) != base
    traced = []
    jax.jit(lambda o: traced.append(skeleton(o)) or 0)(objects(radius=3.0))
    assert traced[0] == base  # the same key under a trace: a grad after a render traces no new program
    mixed = (np.zeros(3), 1.5)  # a Python number among the leaves: kept in the tree and the key
    assert skeleton(mixed).value == (Placeholder((3,), "float64"), 1.5)
    assert skeleton(mixed) != skeleton((np.zeros(3), 2.5))


def test_shapes_group_and_stack_as_a_pytree_walk_groups_and_stacks_them():
    """``pack_geometry`` reads a shape's variant and stacks its group from its fields: the groups
    and stacked arrays are those of the pytree walk (treedef and leaf shapes; ``tree_map`` of a
    stack) for every registered shape's test case, static variants included."""
    from raytracer.shading._geometry import _stack, _variant
    from tests.shapes._cases import CASES

    shapes = [case.make(*case.params) for case in CASES for _ in range(2)]
    sphere = rt.Sphere((0.0, 0.0, 0.0), 1.0)
    shapes += [eqx.tree_at(lambda s: s.center, sphere, np.zeros(3, np.float64)),  # float64: one group
               eqx.tree_at(lambda s: s.radius, sphere, 0.5),  # a Python number, a numpy scalar
               eqx.tree_at(lambda s: s.radius, sphere, np.float32(0.5)),
               rt.Polygon(np.zeros((3, 3)), edges=[[0, 1], [1, 2], [2, 0]])]  # static lists
    by_walk, by_fields = {}, {}
    for i, s in enumerate(shapes):
        leaves, treedef = jax.tree_util.tree_flatten(s)
        by_walk.setdefault((treedef, tuple(np.shape(x) for x in leaves)), []).append(i)
        by_fields.setdefault(_variant(s), []).append(i)
    assert sorted(by_walk.values()) == sorted(by_fields.values())
    for key, ids in by_fields.items():
        members = [shapes[i] for i in ids]
        fast = _stack(members, plain=isinstance(key[0], type))
        walked = jax.tree_util.tree_map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *members)
        assert jax.tree_util.tree_structure(fast) == jax.tree_util.tree_structure(walked)
        for a, b in zip(jax.tree_util.tree_leaves(fast), jax.tree_util.tree_leaves(walked), strict=True):
            np.testing.assert_array_equal(a, b)
            assert a.dtype == b.dtype


def test_materials_pack_shared_finishes_and_colour_maps_of_every_length_row_by_row():
    """A finish shared by several objects is stacked once and gathered; colour maps of different
    lengths are padded by repeating their last entry. Each row holds its own object's values."""
    from raytracer._plan import make_plan
    from raytracer.shading._materials import pack_materials

    shared = rt.Finish(diffuse=0.5, ambient=0.1)
    maps = [np.array([0.0]), np.array([0.0, 1.0]), np.array([0.0, 0.5, 1.0])]
    colours = [np.tile(np.arange(5.0), (len(v), 1)) * (1 + np.arange(len(v)))[:, None] for v in maps]
    pigments = [rt.Pigment(pattern=p, values=v, colors=c, transparent=True)
                for p, v, c in zip(("solid", "checker", "gradient"), maps, colours, strict=True)]
    finishes = [shared, rt.Finish(diffuse=0.9, ambient=0.2), shared]
    objects = tuple(rt.Object(rt.Sphere((3.0 * i, 0, 0), 1.0),
                              texture=rt.Texture(layers=(rt.Layer(pigment=pg, finish=f),)))
                    for i, (pg, f) in enumerate(zip(pigments, finishes, strict=True)))
    mats = pack_materials(make_plan(rt.Scene(camera=rt.Camera(), objects=objects)), np.float64)
    # rows past the objects' (padding to ``bucket(3)`` = 8 primitives) repeat the last one
    np.testing.assert_array_equal(mats.finish.diffuse, np.float32([0.5, 0.9] + [0.5] * 6))
    np.testing.assert_array_equal(mats.finish.ambient[:3], np.float32([0.1, 0.2, 0.1]))
    for row, (v, c) in enumerate(zip(maps, colours, strict=True)):
        n = len(v)
        np.testing.assert_array_equal(mats.values[row], np.concatenate([v, np.repeat(v[-1], 3 - n)]))
        np.testing.assert_array_equal(mats.colors[row], np.concatenate([c, np.repeat(c[-1:], 3 - n, 0)]))


def test_collections_paused_for_a_block_come_back_as_they_were():
    import gc

    from raytracer._gc import paused

    assert gc.isenabled()
    with pytest.raises(RuntimeError):
        with paused():
            assert not gc.isenabled()
            raise RuntimeError
    assert gc.isenabled()
    gc.disable()
    try:
        with paused():
            pass
        assert not gc.isenabled()  # a caller that turned it off keeps it off
    finally:
        gc.enable()


def test_a_scene_file_larger_than_the_token_cache_is_not_kept(tmp_path, monkeypatch):
    from raytracer.sdl import _stream

    small, large = tmp_path / "small.pov", tmp_path / "large.pov"
    small.write_text("#declare A = 1;\n")
    large.write_text(_spheres(30))
    monkeypatch.setattr(_stream, "LEXED_CACHE_TOKENS", 200)
    _stream._lexed_file(str(small))
    toks = _stream._lexed_file(str(large))
    assert len(toks) > 200
    kept = {key[0] for key in _stream._LEXED}
    assert str(small) in kept and str(large) not in kept


@pytest.mark.parametrize("count", [10, 400])
def test_a_parse_leaves_no_reference_cycles_that_grow_with_its_work(count):
    """``load_scene`` runs with the cyclic collector paused, so a parse must not make garbage that
    only the collector frees: what is left after macros, loops and objects stays a few objects
    (the interpreter, a cycle, is released when the parse ends), whatever the loop count."""
    import gc

    text = ("#macro Ball(I) sphere { <I, 0, 0>, 0.4 pigment { rgb <I / 500, 0.5, 0.5> } } #end\n"
            "camera { location -5*z look_at 0 }\nlight_source { <1, 5, -5> color rgb 1 }\n"
            f"#declare I = 0; #while (I < {count}) union {{ Ball(I) Ball(I + 0.5) }}\n"
            "#declare I = I + 1; #end\n")
    gc.collect()
    gc.disable()
    try:
        scene = load_scene(text)
        left = gc.collect()
    finally:
        gc.enable()
    assert len(scene.objects) == count and left <= 20


@pytest.mark.parametrize("csg, counts", [(False, (105, 110)), (True, (100, 105))])  # (one bucket each)
def test_a_scene_with_another_number_of_items_runs_the_program_compiled_for_the_first(tmp_path, monkeypatch,
                                                                                       csg, counts):
    """``render._signature``: the program is keyed by what its trace reads of the objects, so a
    scene that differs only in its number of hierarchy items (one bucket; CSG objects among them
    or not) runs the program traced for another — no trace, no compile — and its image is
    bit-equal to the one its own program (keyed by its whole skeleton, as before) makes."""
    if _accel.unavailable_reason() is not None:
        pytest.skip(_accel.unavailable_reason())
    monkeypatch.setenv("RAYTRACER_ACCEL", "native")
    scenes = {}
    for n in counts:
        path = tmp_path / f"v{n}.pov"
        path.write_text(_varied(n, csg))
        scenes[n] = load_scene(path, width=16, height=12)
        assert any(g.csg_member for g in pack(scenes[n]).geo.groups) == csg
    traced = []
    make_context = tiles.make_context
    monkeypatch.setattr(tiles, "make_context", lambda *a: traced.append(1) or make_context(*a))
    rt.render(scenes[counts[0]], width=16, height=12)
    assert traced
    traced.clear()
    shared = rt.render(scenes[counts[1]], width=16, height=12)
    assert not traced  # the program of the first count ran
    monkeypatch.setattr(packing, "_signature", lambda *a: None)
    packing._PACKED.clear()
    own = rt.render(scenes[counts[1]], width=16, height=12)
    assert traced  # keyed by its skeleton: a program of its own
    np.testing.assert_array_equal(np.asarray(shared), np.asarray(own))
    assert np.asarray(own).std() > 0.05  # spheres, a checker floor, shadows: not a blank image
    monkeypatch.undo()
    packing._PACKED.clear()
    keyed = pack(scenes[counts[1]]).objects  # keyed by the signature; its skeleton made when asked for
    assert keyed != skeleton(scenes[counts[1]].objects)
    assert keyed.value == skeleton(scenes[counts[1]].objects).value
