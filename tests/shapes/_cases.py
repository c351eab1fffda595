"""Every shape's test case: the ``CASES`` of ``test_<name>.py`` for each shape module
``raytracer/shapes/_<name>.py`` (the convention: a shape module and its test module)."""

import importlib
import pkgutil

import raytracer.shapes

from ._case import Case, random_rays  # noqa: F401  (re-exported for the generic tests)


def _collect() -> list:
    cases = []
    for info in sorted(pkgutil.iter_modules(raytracer.shapes.__path__), key=lambda m: m.name):
        if info.name.startswith("_") and info.name != "_base":
            module = importlib.import_module(f"{__package__}.test{info.name}")
            cases.extend(module.CASES)
    return cases


CASES = _collect()
CASE_IDS = [c.name for c in CASES]
