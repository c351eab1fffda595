"""Metrics against closed forms."""

import math

import numpy as np
import pytest

from validation import metrics
from validation.metrics import Thresholds


@pytest.fixture
def image():
    rng = np.random.default_rng(0)
    return rng.uniform(0.0, 1.0, size=(40, 50, 3))


def test_identical_images_are_perfect(image):
    m = metrics.compare(image, image, tol=0.0)
    assert m.rmse == 0.0 and m.max_abs == 0.0 and m.p99_abs == 0.0
    assert math.isinf(m.psnr)
    assert m.frac_within == 1.0
    assert m.ssim == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("offset", [1e-3, 0.05, 0.5])
def test_constant_offset_has_rmse_max_and_p99_equal_to_the_offset(image, offset):
    shifted = image + offset
    assert metrics.rmse(shifted, image) == pytest.approx(offset, rel=1e-9)
    assert metrics.max_abs(shifted, image) == pytest.approx(offset, rel=1e-9)
    assert metrics.percentile_abs(shifted, image) == pytest.approx(offset, rel=1e-9)
    assert metrics.psnr(shifted, image) == pytest.approx(-20 * math.log10(offset), rel=1e-9)


def test_psnr_uses_a_linear_peak_of_one():
    a = np.zeros((4, 4, 3))
    assert metrics.psnr(a + 0.1, a) == pytest.approx(20.0)
    assert metrics.psnr(a + 0.1, a, peak=2.0) == pytest.approx(20.0 + 20 * math.log10(2.0))


def test_rmse_of_one_wrong_pixel_is_its_error_over_root_n():
    a = np.zeros((10, 10, 3))
    b = a.copy()
    b[3, 4] = (0.3, 0.0, 0.0)
    assert metrics.rmse(b, a) == pytest.approx(0.3 / math.sqrt(300))
    assert metrics.max_abs(b, a) == pytest.approx(0.3)


def test_fraction_within_counts_pixels_by_their_largest_channel_error():
    a = np.zeros((10, 10, 3))
    b = a.copy()
    b[0, :5, 2] = 0.02  # 5 pixels off by 0.02 in blue only
    b[1, :3, 0] = 0.005  # 3 pixels off by 0.005
    assert metrics.fraction_within(b, a, 0.01) == pytest.approx(95 / 100)
    assert metrics.fraction_within(b, a, 0.001) == pytest.approx(92 / 100)
    assert metrics.fraction_within(b, a, 0.02) == 1.0


def test_percentile_matches_numpy_definition():
    a = np.zeros((1, 100, 3))
    b = np.broadcast_to(np.arange(100, dtype=float)[None, :, None] / 100, a.shape)
    assert metrics.percentile_abs(b, a, 50) == pytest.approx(np.percentile(np.arange(100) / 100, 50))


def test_ssim_of_two_constant_images_is_the_luminance_term():
    # constant images have zero variance and covariance: SSIM = (2ab + C1) / (a² + b² + C1)
    a, b = 0.3, 0.5
    x = np.full((20, 20, 3), a)
    y = np.full((20, 20, 3), b)
    c1 = (0.01 * 1.0) ** 2
    assert metrics.ssim(x, y) == pytest.approx((2 * a * b + c1) / (a * a + b * b + c1), rel=1e-9)


def test_ssim_is_symmetric_and_drops_for_noise(image):
    rng = np.random.default_rng(1)
    noisy = image + rng.normal(0, 0.2, image.shape)
    s = metrics.ssim(noisy, image)
    assert s == pytest.approx(metrics.ssim(image, noisy), rel=1e-12)
    assert 0.0 < s < 0.9


def test_ssim_of_an_inverted_pattern_is_negative():
    x = np.zeros((32, 32, 3))
    x[:, ::2] = 1.0
    assert metrics.ssim(1.0 - x, x) < 0.0


def test_shape_mismatch_raises():
    with pytest.raises(ValueError, match="shapes differ"):
        metrics.rmse(np.zeros((2, 2, 3)), np.zeros((2, 3, 3)))


def test_thresholds_report_each_violated_criterion():
    m = metrics.Metrics(rmse=0.02, psnr=33.98, max_abs=0.5, p99_abs=0.1, frac_within=0.9, tol=0.01, ssim=0.95)
    assert Thresholds(min_psnr=30, min_frac_within=0.8).failures(m) == []
    failures = Thresholds(min_psnr=40, max_rmse=0.01, min_frac_within=0.99, max_p99=0.05,
                          min_ssim=0.99).failures(m)
    assert len(failures) == 5
    assert failures[0].startswith("PSNR 33.98 < 40")


def test_nan_metrics_fail_every_threshold():
    nan = float("nan")
    m = metrics.Metrics(rmse=nan, psnr=nan, max_abs=nan, p99_abs=nan, frac_within=nan, tol=0.01, ssim=nan)
    assert len(Thresholds(min_psnr=0, max_rmse=1, min_frac_within=0, max_p99=1, min_ssim=0).failures(m)) == 5
