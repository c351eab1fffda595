"""``paused()``: Python's cyclic garbage collector held off for the duration of a block.

Loading, planning and packing a large scene make millions of small objects that form no reference
cycles (tokens, records, primitives, lists of leaves). Each collection of the oldest generation
walks every tracked object alive, and the allocations set such collections off again and again: for
100,000 spheres they were ~40 % of lexing and ~30 % of packing. Reference counting still frees
everything as usual; a cycle made meanwhile is collected once the block ends. Tracing and compiling
a program make few cycles (a reverse-mode render of ``glass.pov`` left 139 objects to collect), so
a render is traced under it too: for 100,000 spheres, collections were ~2.5 s of a 1.5 s trace.
The collector is process-wide, so the block restores it as it found it (a caller that turned it
off keeps it off).
"""

from __future__ import annotations

import contextlib
import functools
import gc


@contextlib.contextmanager
def paused():
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


def without_collections(fn):
    """``fn`` run under :func:`paused`."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with paused():
            return fn(*args, **kwargs)

    return wrapper
