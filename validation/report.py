"""HTML report: per scene and reference, our image, the reference and a diff heat map, side by side."""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np

__all__ = ["diff_heatmap", "to_srgb8", "write_report"]

DIFF_RANGE = 0.1  # heat-map scale: black = 0, brightest = ≥ 0.1 linear (largest channel error)


def to_srgb8(image) -> np.ndarray:
    """(H, W, 3) linear → 8-bit sRGB (clipped to [0, 1]) for display."""
    x = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64)), 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(s * 255).astype(np.uint8)


def diff_heatmap(ours, reference, scale: float = DIFF_RANGE) -> np.ndarray:
    """8-bit RGB heat map (matplotlib 'inferno') of the per-pixel largest channel error / ``scale``."""
    d = np.max(np.abs(np.asarray(ours, np.float64) - np.asarray(reference, np.float64)), axis=-1)
    t = np.clip(np.nan_to_num(d, nan=scale) / scale, 0.0, 1.0)
    try:
        from matplotlib import colormaps

        rgb = colormaps["inferno"](t)[..., :3]
    except ImportError:  # plain black → red → yellow → white ramp
        rgb = np.stack([np.clip(3 * t, 0, 1), np.clip(3 * t - 1, 0, 1), np.clip(3 * t - 2, 0, 1)], -1)
    return np.round(rgb * 255).astype(np.uint8)


def _save_png(path: Path, rgb8: np.ndarray, zoom: int = 2) -> None:
    from PIL import Image

    img = Image.fromarray(rgb8)
    if zoom > 1:
        img = img.resize((img.width * zoom, img.height * zoom), Image.NEAREST)
    img.save(path)


def _fmt(x: float, spec: str) -> str:
    return "inf" if math.isinf(x) else format(x, spec)


def write_report(results, directory) -> Path:
    """Writes ``index.html`` and its PNGs into ``directory``; returns the page's path."""
    out = Path(directory)
    (out / "images").mkdir(parents=True, exist_ok=True)
    rows = []
    for r in results:
        stem = f"{r.scene.name.replace('/', '_')}_{r.reference}"
        cells = []
        for label, img in (("ours", r.ours), (r.reference, r.ref)):
            if img is not None:
                _save_png(out / "images" / f"{stem}_{label}.png", to_srgb8(img))
                body = f'<img src="images/{stem}_{label}.png">'
            else:
                body = "<div class=missing>no image</div>"
            cells.append(f"<figure>{body}<figcaption>{label}</figcaption></figure>")
        if r.ours is not None and r.ref is not None:
            _save_png(out / "images" / f"{stem}_diff.png", diff_heatmap(r.ours, r.ref))
            cells.append(f'<figure><img src="images/{stem}_diff.png"><figcaption>|diff|, '
                         f"black 0 → white ≥ {DIFF_RANGE:g}</figcaption></figure>")
        if r.metrics is not None:
            m = r.metrics
            numbers = (f"PSNR {_fmt(m.psnr, '.2f')} dB · RMSE {m.rmse:.2e} · max {m.max_abs:.3f} · "
                       f"p99 {m.p99_abs:.2e} · within {m.tol:g}: {m.frac_within:.4f} · SSIM {m.ssim:.4f}")
        else:
            numbers = ""
        notes = "; ".join(r.failures) if r.failures else (r.error or "")
        rows.append(f"""<section class="{r.status.lower()}">
<h2>{html.escape(r.scene.name)} vs {r.reference} — {r.status}</h2>
<p class=checks>checks: {html.escape(r.scene.checks)}</p>
<p>{numbers}</p>{f'<p class=notes>{html.escape(notes)}</p>' if notes else ''}
<div class=row>{''.join(cells)}</div></section>""")
    n_pass = sum(r.passed for r in results)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>raytracer validation</title>
<style>body{{font-family:sans-serif;margin:1em 2em}} .row{{display:flex;gap:8px}} figure{{margin:0}}
figcaption{{font-size:80%;text-align:center}}
section{{border-left:6px solid #999;padding-left:1em;margin:1.5em 0}}
section.pass{{border-color:#3a3}} section.fail,section.error{{border-color:#c33}}
.notes{{color:#a00}} .checks{{color:#555}} .missing{{width:320px;height:240px;background:#eee}}
</style></head><body>
<h1>raytracer validation</h1><p>{n_pass} of {len(results)} comparisons pass. Images are linear renders shown
as sRGB; the heat map is the largest channel error per pixel. PSNR uses peak 1.0 (linear).</p>
{''.join(rows)}</body></html>"""
    path = out / "index.html"
    path.write_text(page)
    return path
