"""Image-difference metrics for linear RGB images (numpy only).

All metrics take two (H, W, 3) linear images, ``ours`` and ``reference``, of the same shape.
PSNR uses a **peak of 1.0 in linear units** (the white of an unclipped POV-Ray image), so
``psnr = -20·log10(rmse)``; identical images have PSNR ``inf``. SSIM is the usual Wang et al. (2004)
index on Rec. 709 luminance with an 11×11 Gaussian window (σ = 1.5), K1 = 0.01, K2 = 0.03 and a
data range of 1.0, averaged over the window positions that lie fully inside the image.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["Metrics", "Thresholds", "compare", "fraction_within", "luminance", "max_abs", "percentile_abs",
           "psnr", "rmse", "ssim"]

PEAK = 1.0
LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 / sRGB primaries, linear light


def _pair(ours, reference):
    a = np.asarray(ours, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image shapes differ: {a.shape} vs {b.shape}")
    return a, b


def rmse(ours, reference) -> float:
    """Root-mean-square error over all pixels and channels (linear units)."""
    a, b = _pair(ours, reference)
    return float(np.sqrt(np.mean((a - b) ** 2)))


def psnr(ours, reference, peak: float = PEAK) -> float:
    """Peak signal-to-noise ratio in dB with ``peak`` (default 1.0 linear): ``20·log10(peak/rmse)``."""
    e = rmse(ours, reference)
    return math.inf if e == 0 else 20.0 * math.log10(peak / e)


def max_abs(ours, reference) -> float:
    """Largest absolute difference over all pixels and channels."""
    a, b = _pair(ours, reference)
    return float(np.max(np.abs(a - b)))


def percentile_abs(ours, reference, q: float = 99.0) -> float:
    """The ``q``-th percentile of the absolute difference over all pixels and channels."""
    a, b = _pair(ours, reference)
    return float(np.percentile(np.abs(a - b), q))


def fraction_within(ours, reference, tol: float) -> float:
    """Fraction of pixels whose largest channel difference is at most ``tol``."""
    a, b = _pair(ours, reference)
    per_pixel = np.max(np.abs(a - b), axis=-1) if a.ndim == 3 else np.abs(a - b)
    return float(np.mean(per_pixel <= tol))


def luminance(image) -> np.ndarray:
    """(H, W) Rec. 709 luminance of a linear (H, W, 3) image."""
    return np.asarray(image, dtype=np.float64) @ LUMA


def _gaussian_kernel(sigma: float, radius: int) -> np.ndarray:
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def _filter_valid(img: np.ndarray, k: np.ndarray) -> np.ndarray:
    # separable correlation, keeping only positions where the window lies inside the image
    n = len(k)
    rows = sum(k[i] * img[i:img.shape[0] - n + 1 + i, :] for i in range(n))
    return sum(k[i] * rows[:, i:rows.shape[1] - n + 1 + i] for i in range(n))


def ssim(ours, reference, *, sigma: float = 1.5, radius: int = 5, data_range: float = PEAK,
         k1: float = 0.01, k2: float = 0.03) -> float:
    """Mean structural similarity of the luminance of two images (1.0 when identical)."""
    a, b = _pair(ours, reference)
    x = luminance(a) if a.ndim == 3 else a
    y = luminance(b) if b.ndim == 3 else b
    if min(x.shape) < 2 * radius + 1:
        raise ValueError(f"image {x.shape} smaller than the {2 * radius + 1}-pixel SSIM window")
    k = _gaussian_kernel(sigma, radius)
    mx, my = _filter_valid(x, k), _filter_valid(y, k)
    vx = _filter_valid(x * x, k) - mx * mx
    vy = _filter_valid(y * y, k) - my * my
    cxy = _filter_valid(x * y, k) - mx * my
    c1, c2 = (k1 * data_range) ** 2, (k2 * data_range) ** 2
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return float(np.mean(s))


@dataclasses.dataclass(frozen=True)
class Metrics:
    """All metrics of one comparison (``tol`` is the tolerance used for ``frac_within``)."""

    rmse: float
    psnr: float
    max_abs: float
    p99_abs: float
    frac_within: float
    tol: float
    ssim: float

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def compare(ours, reference, tol: float = 0.01) -> Metrics:
    """Every metric of ``ours`` against ``reference``."""
    return Metrics(rmse=rmse(ours, reference), psnr=psnr(ours, reference), max_abs=max_abs(ours, reference),
                   p99_abs=percentile_abs(ours, reference, 99.0),
                   frac_within=fraction_within(ours, reference, tol), tol=tol, ssim=ssim(ours, reference))


@dataclasses.dataclass(frozen=True)
class Thresholds:
    """Pass criteria of one scene against one reference; None means "not checked".

    Attributes:
        min_psnr:        PSNR (dB, peak 1.0 linear) must be at least this.
        max_rmse:        RMSE (linear) must be at most this.
        tol:             per-pixel tolerance (largest channel difference) for ``min_frac_within``.
        min_frac_within: at least this fraction of pixels must lie within ``tol``.
        max_p99:         99th percentile of the absolute difference must be at most this.
        min_ssim:        luminance SSIM must be at least this.
    """

    min_psnr: float | None = None
    max_rmse: float | None = None
    tol: float = 0.01
    min_frac_within: float | None = None
    max_p99: float | None = None
    min_ssim: float | None = None

    def failures(self, m: Metrics) -> list[str]:
        """Human-readable list of the criteria ``m`` violates (empty when it passes)."""
        out = []
        if self.min_psnr is not None and not m.psnr >= self.min_psnr:
            out.append(f"PSNR {m.psnr:.2f} < {self.min_psnr:g} dB")
        if self.max_rmse is not None and not m.rmse <= self.max_rmse:
            out.append(f"RMSE {m.rmse:.3g} > {self.max_rmse:g}")
        if self.min_frac_within is not None and not m.frac_within >= self.min_frac_within:
            out.append(f"within {self.tol:g}: {m.frac_within:.4f} < {self.min_frac_within:g}")
        if self.max_p99 is not None and not m.p99_abs <= self.max_p99:
            out.append(f"p99 {m.p99_abs:.3g} > {self.max_p99:g}")
        if self.min_ssim is not None and not m.ssim >= self.min_ssim:
            out.append(f"SSIM {m.ssim:.4f} < {self.min_ssim:g}")
        return out
