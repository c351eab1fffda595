"""Docs that cannot drift: the generated part of docs/features.md is what the registries say."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _script():
    spec = importlib.util.spec_from_file_location("features_doc", ROOT / "scripts" / "features_doc.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_features_doc_lists_what_the_registries_hold():
    """``python scripts/features_doc.py`` rewrites it; a shape, pattern, light type, effect or warning
    added without doing so fails here."""
    script = _script()
    block = script.current_block(script.DOC.read_text())
    assert block is not None, "docs/features.md lost its generated part's markers"
    assert block == script.generated(), "docs/features.md is stale: run python scripts/features_doc.py"
    assert "`ovus`" in block and "| isosurface |" in block  # warned and rendered, from the registries
