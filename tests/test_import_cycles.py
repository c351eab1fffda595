"""The package's modules import each other without a cycle (read from the source, nothing imported)."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "raytracer"


def _module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, name: str, modules: set[str], top_level_only: bool) -> set[str]:
    """The package modules ``path`` imports (``from . import x`` names x when x is a module).

    A module's own ancestor packages are left out: Python initialises them before the module, so
    ``from .. import scene`` in ``raytracer.sdl._lower`` depends on ``raytracer.scene`` only.
    """
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    nodes = tree.body if top_level_only else ast.walk(tree)
    found = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names)
    ancestors = {name.rsplit(".", k)[0] for k in range(1, name.count(".") + 1)}
    return {m for m in found if m in modules and m != name and m not in ancestors}


def import_cycles(package: Path = PACKAGE, top_level_only: bool = True) -> list[list[str]]:
    """Every cycle of the import graph, as its strongly connected components (Tarjan).

    ``top_level_only``: only imports run when the module is imported (not those inside functions).
    """
    paths = {_module_name(p, package.parent): p for p in package.rglob("*.py")}
    graph = {m: sorted(_imports(p, m, set(paths), top_level_only)) for m, p in paths.items()}
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_the_checker_finds_a_cycle_and_ignores_parent_packages(tmp_path):
    pkg = tmp_path / "raytracer"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from . import c\n")
    (pkg / "sub" / "__init__.py").write_text("from .a import f\n")
    (pkg / "sub" / "a.py").write_text("from .b import f\nfrom .. import c\n")
    (pkg / "sub" / "b.py").write_text("def f():\n    from . import a\n")
    (pkg / "c.py").write_text("import math\n")
    assert import_cycles(pkg, top_level_only=True) == []
    assert import_cycles(pkg, top_level_only=False) == [["raytracer.sub.a", "raytracer.sub.b"]]
    (pkg / "c.py").write_text("from .sub.b import f\n")
    (pkg / "sub" / "b.py").write_text("from .. import c\n")
    assert import_cycles(pkg) == [["raytracer.c", "raytracer.sub.b"]]


def test_no_import_cycle_in_the_package():
    assert import_cycles(top_level_only=False) == []  # deferred imports inside functions too


# The package's layers, lowest first (docs/architecture.md's table): a module imports its own layer
# and those below it, never one above.
LAYERS = (
    ("raytracer._dtype", "raytracer._build", "raytracer._gc", "raytracer.errors", "raytracer._xla",
     "raytracer._limits", "raytracer._linear", "raytracer._native", "raytracer._notice", "raytracer.imageio"),
    ("raytracer.kernels",),
    ("raytracer.shapes", "raytracer.patterns"),
    ("raytracer.scene",),
    ("raytracer._packing", "raytracer._plan", "raytracer._programs"),
    ("raytracer.shading",),
    ("raytracer._packed", "raytracer._tiles", "raytracer._adaptive", "raytracer._edges", "raytracer.render",
     "raytracer.query", "raytracer.distributed"),
    ("raytracer.sdl",),
    ("raytracer.params", "raytracer.cli", "raytracer"),
)
OUTSIDE = ("validation", "benchmarks", "mitsuba", "drjit", "optimistix")


def layer_of(module: str) -> int | None:
    """The layer of ``module``: that of the longest prefix in ``LAYERS`` naming it or its package."""
    best = None
    for i, group in enumerate(LAYERS):
        for prefix in group:
            names_it = module == prefix or module.startswith(prefix + ".")
            if names_it and (best is None or len(prefix) > best[1]):
                best = (i, len(prefix))
    return None if best is None else best[0]


def test_no_import_runs_up_the_layers_or_out_of_the_package():
    """Deferred imports inside functions count too; ``raytracer`` reaches ``validation`` only through
    its ``raytracer.commands`` entry point."""
    paths = {_module_name(p, PACKAGE.parent): p for p in PACKAGE.rglob("*.py")}
    up, unplaced, outside = [], [], []
    for name, path in sorted(paths.items()):
        mine = layer_of(name)
        if mine is None:
            unplaced.append(name)
            continue
        imported = sorted(_imports(path, name, set(paths), False))
        up += [f"{name} -> {m}" for m in imported if layer_of(m) > mine]
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            outside += [f"{name} imports {n}" for n in names if n.split(".")[0] in OUTSIDE]
    assert not unplaced, f"modules in no layer (add them to LAYERS): {unplaced}"
    assert not up, up
    assert not outside, outside
