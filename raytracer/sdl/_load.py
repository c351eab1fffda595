"""``load_scene``: the parser's one entry point."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .._gc import without_collections
from ..errors import InternalError, SceneError
from ._animation import Animation
from ._interpreter import Interpreter
from ._lexer import tokenize
from ._lower import lower_scene
from ._stream import Limits


def _is_path(path_or_text) -> bool:
    if isinstance(path_or_text, os.PathLike):
        return True
    s = str(path_or_text)
    if "\n" in s or "{" in s or len(s) > 4096:
        return False
    # one word with no SDL in it (``"myscene"``, ``"scenes/a.pov"``) names a file: no scene text is a
    # single word, and a missing file then says so instead of "undeclared identifier"
    word = s.strip() != "" and not any(c.isspace() or c in "#;<>(){}=" for c in s.strip())
    return s.endswith((".pov", ".inc")) or os.path.isfile(s) or word


@without_collections  # a parse makes almost no cycles (POV-Ray's heaviest sample scenes: ≤ 66 objects)
def load_scene(path_or_text, *, include_paths=(), strict: bool = False, width: int | None = None,
               height: int | None = None, limits: Limits | None = None,
               animation: Animation | None = None, fit_zero_terms: bool = True,
               files: set[str] | None = None):
    """Parses a POV-Ray 3.7 scene (a file path or SDL text) into a :class:`raytracer.scene.Scene`.

    Args:
        path_or_text: a path (an existing file, or a name ending in .pov/.inc) or SDL text.
        include_paths: folders searched for ``#include`` after the including file's folder, before
            ``$RAYTRACER_INCLUDE_PATH`` and POV-Ray's standard include folder.
        strict: raise SceneError for unsupported features instead of warning.
        width, height: the ``image_width``/``image_height`` the scene sees (default 160×120).
        limits: loop/recursion/include bounds (:class:`Limits`).
        animation: the frame to load (``clock``, ``frame_number`` …; :class:`Animation`, e.g.
            ``Animation.from_ini("scene.ini", frame=3)``); None: no animation (``clock`` = 0).
        fit_zero_terms: a term written as 0 whose value adds nothing at 0 (a colour's filter or
            transmit: ``rgbf <r, g, b, 0>``, ``filter 0``; a finish's ``reflection 0``, ``phong 0``,
            ``specular 0``, ``metallic 0``) is part of the scene's structure and compiled, as any
            written term (semantics §2.2 and §2.6, "present in the structure"), so the value can be
            fitted from 0. False: such a zero is left out, as if not written: the same image from a
            smaller, faster program (POV-Ray's ``advanced/pawns.pov``, whose opaque wood is written
            ``filter 0.000``: every object filtered shadows and passed rays on; a ``reflection 0``
            makes a tree of ``max_trace_level`` levels of a scene with no other reflection), but
            such a zero's derivative is then 0. The command line renders with False.
        files: a set that receives the paths of the scene files read (the scene's own and every
            ``#include``d file), also when the scene fails to load: what a re-render on change
            (``raytracer render --watch``) watches.

    Raises:
        SceneError: for any scene that cannot be loaded, with ``file:line:col``.
        InternalError: when the parser itself fails (a bug), chained to the original exception,
            with the scene location the interpreter had reached.
    """
    p = Interpreter(include_paths=include_paths, strict=strict, limits=limits,
                    width=width or 160, height=height or 120, animation=animation)
    old_limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(old_limit, 20000))
    lowering = False
    try:
        if _is_path(path_or_text):
            path = str(path_or_text)
            if not os.path.isfile(path):
                raise SceneError(f'expected a scene file, found no file "{path}"')
            toks = p.file_tokens(path)
            p.input_file_name = Path(path).name
            p.push_main(toks, path)
        else:
            p.push_main(tokenize(str(path_or_text), "<string>"), None)
        p.run()
        _check_open_blocks(p)
        lowering = True
        return lower_scene(p, fit_zero_terms)
    except SceneError:
        raise
    except RecursionError:  # a scene nested deeper than Python's stack (((((…))))), not a bug
        raise p.error("the scene nests too deeply (recursion limit)") from None
    except Exception as e:
        # the one boundary between the parser and its callers: whatever is not a SceneError is
        # ours, and says so (the scene errors are raised where the input is read)
        where = "while building the scene" if lowering else "while reading the scene"
        loc, chain = (None, ()) if lowering else (p.here(), p.chain())
        raise InternalError(f"{type(e).__name__}: {e} ({where})", loc, chain) from e
    finally:
        sys.setrecursionlimit(old_limit)
        if files is not None:
            files.update(p.token_cache)
        p.release()


def _check_open_blocks(p) -> None:
    for f in p.frames:
        if f.conds:
            entry = f.conds[-1]
            raise p.error(f"expected '#end' to close #{entry[0]}, found end of file")
