"""Metrics on hand-checkable inputs."""

import numpy as np
import pytest

from experiments.metrics import (
    dense_metrics,
    image_quality,
    in_focus_outlier_fraction,
    region_masks,
    rtf_normalized_errors,
    sparse_metrics,
    textured_mask,
)


def test_sparse_metrics_by_hand():
    gt = np.array([[1.0, 2.0], [3.0, np.nan]])
    est = np.array([[1.5, np.nan], [1.0, 4.0]])   # errors +0.5, (skip), -2.0, (skip)
    m = sparse_metrics(est, gt)
    assert m["n"] == 2
    assert m["mae"] == pytest.approx(1.25)
    assert m["bias"] == pytest.approx(-0.75)
    assert m["rmse"] == pytest.approx(np.sqrt((0.25 + 4.0) / 2))
    assert m["outlier_fraction"] == pytest.approx(0.5)
    assert m["median_rel_error"] == pytest.approx(np.median([0.5, 2.0 / 3.0]))


def test_sparse_metrics_empty_is_nan():
    m = sparse_metrics(np.full((2, 2), np.nan), np.ones((2, 2)))
    assert m["n"] == 0 and np.isnan(m["mae"])


def test_shape_mismatch_is_an_error():
    with pytest.raises(ValueError, match="shape"):
        sparse_metrics(np.zeros((2, 2)), np.zeros((3, 2)))


def test_rtf_normalisation_clips_at_3_275():
    gt = np.array([0.0, 10.0])
    est = np.array([3.275, 3.275])  # first: error 1 after normalisation; second: 0 (both clipped)
    r = rtf_normalized_errors(est, gt)
    assert r["nmae"] == pytest.approx(0.5)
    assert r["nmse"] == pytest.approx(0.5)


def test_in_focus_outliers():
    gt = np.array([0.5, 0.6, 0.7, 3.0])
    est = np.array([0.4, 2.5, 0.9, 0.1])
    r = in_focus_outlier_fraction(est, gt, in_focus_px=1.0, blurry_px=2.0)
    assert (r["n_in_focus"], r["n_blurry_estimates"]) == (3, 1)
    assert r["fraction"] == pytest.approx(1 / 3)


def test_texture_mask_and_regions(rng):
    img = np.zeros((32, 32))
    img[:, 16:] = rng.uniform(0, 1, (32, 16))
    t = textured_mask(img)
    assert t[:, 24:].all() and not t[:, :8].any()
    gt = np.ones((32, 32))
    gt[0, 0] = np.inf
    regions = region_masks(img, gt, edges=np.eye(32, dtype=bool))
    assert not regions["all"][0, 0] and regions["all"].sum() == 32 * 32 - 1
    assert regions["edges"].sum() == 31
    d = dense_metrics(gt, gt, regions=regions)
    assert d["textured"]["mae"] == 0.0


def test_image_quality_identity_and_noise(rng):
    a = rng.uniform(0, 1, (32, 32, 3))
    q = image_quality(a, a)
    assert q["ssim"] == pytest.approx(1.0) and np.isinf(q["psnr_db"])
    b = np.clip(a + rng.normal(0, 0.01, a.shape), 0, 1)
    q = image_quality(b, a)
    assert 38 < q["psnr_db"] < 42  # σ = 0.01 noise → PSNR ≈ 40 dB
