"""Parse every POV-Ray sample scene and record a digest of each scene model, to compare two
versions of the parser (by this check, the lexer and the vector fast path changed no scene).

    python scripts/compare_parses.py run OUT.jsonl          # one line per scene: time, digest,
                                                             # warnings (first 60), error
    python scripts/compare_parses.py diff OLD.jsonl NEW.jsonl

Run an old version from a worktree with ``PYTHONPATH=<worktree>``. The digest covers the scene's
tree structure and every leaf's dtype, shape and bytes. Scenes are parsed one after another in one
process (the standard include files are lexed once), so times are for comparison, not absolute.
"""

from __future__ import annotations

import hashlib
import json
import logging
import subprocess
import sys
import time


def run(out_path: str) -> None:
    import jax
    import numpy as np

    import raytracer
    from raytracer.errors import SceneError

    messages: list[str] = []

    class _Keep(logging.Handler):
        def emit(self, record):
            messages.append(record.getMessage())

    log = logging.getLogger("raytracer")
    log.addHandler(_Keep())
    log.propagate = False
    log.setLevel(logging.WARNING)
    listing = subprocess.run(["dpkg", "-L", "povray-examples"], capture_output=True, text=True).stdout
    files = sorted(f for f in listing.split() if f.endswith(".pov"))
    with open(out_path, "w") as out:
        for f in files:
            messages.clear()
            t = time.perf_counter()
            row = {"file": f}
            try:
                scene = raytracer.load_scene(f)
                row["t"] = time.perf_counter() - t
                leaves, treedef = jax.tree_util.tree_flatten(scene)
                h = hashlib.sha1(str(treedef).encode())
                for leaf in leaves:
                    a = np.asarray(leaf)
                    h.update(f"{a.dtype}{a.shape}".encode())
                    h.update(a.tobytes())
                row["digest"] = h.hexdigest()
            except SceneError as e:
                row["t"], row["error"] = time.perf_counter() - t, str(e)
            row["warn"] = messages[:60]
            out.write(json.dumps(row) + "\n")
            out.flush()


def diff(old_path: str, new_path: str) -> int:
    def load(path):
        return {r["file"]: r for r in map(json.loads, open(path))}

    old, new = load(old_path), load(new_path)
    changed = 0
    for f in sorted(old.keys() | new.keys()):
        a, b = old.get(f, {}), new.get(f, {})
        keys = ("digest", "error", "warn")
        if [a.get(k) for k in keys] != [b.get(k) for k in keys]:
            changed += 1
            print("differs:", f)
    print(f"{changed} of {len(old | new)} scenes differ; total parse time "
          f"{sum(r['t'] for r in old.values()):.1f} s -> {sum(r['t'] for r in new.values()):.1f} s")
    return 1 if changed else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["run"] and len(sys.argv) == 3:
        run(sys.argv[2])
    elif sys.argv[1:2] == ["diff"] and len(sys.argv) == 4:
        sys.exit(diff(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
