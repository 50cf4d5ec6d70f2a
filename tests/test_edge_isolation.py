"""Isolation weights of edge measures (method.edges.isolation): a bar's two close edges weigh less
than an isolated step's, which weighs fully; the weight enters the pipeline's measure confidence."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from method import DefocusParams, estimate_defocus_map
from method.edges.isolation import EDGE_ISOLATION_METHODS, isolation_weights
from method.pipeline import edges_stage, luminance

SIGMA = 2.0  # px, blur of both test images


def _blurred(img):
    from scipy import ndimage

    rng = np.random.default_rng(0)
    out = ndimage.gaussian_filter(img, SIGMA) + rng.normal(0, 1 / 255, img.shape)
    return np.clip(np.round(out * 255) / 255, 0, 1)


def _step_and_bar():
    """96×192: an isolated vertical step (x < 48 dark) and, far from it, a 2-px bright bar (x 136–137)."""
    x = np.arange(192)[None, :] * np.ones((96, 1))
    img = np.where(x < 48, 0.2, 0.5) + 0.3 * ((x >= 136) & (x < 138))
    return _blurred(img)


@pytest.mark.parametrize("method", sorted(EDGE_ISOLATION_METHODS))
def test_bar_is_down_weighted_against_an_isolated_step(method):
    gray = _step_and_bar()
    params = DefocusParams()
    em = edges_stage(gray, params=params)
    sigma = np.where(em.edges, SIGMA, np.nan)  # the weight depends on σ̂ and the geometry only
    w = isolation_weights(gray, em.edges, em.theta, sigma, method=method, radius=3.0, floor=0.1)
    x = np.arange(192)[None, :] * np.ones((96, 1))
    inner = (np.arange(96)[:, None] > 12) & (np.arange(96)[:, None] < 84)  # away from the borders
    step = em.edges & inner & (np.abs(x - 47.5) < 3)
    bar = em.edges & inner & (x > 130) & (x < 146)
    assert step.sum() > 50 and bar.sum() > 50
    assert np.median(w[step]) == 1.0  # isolated: full weight
    assert np.median(w[bar]) < 0.8, np.median(w[bar])  # "normal": d = 5 of r = 6 px → 0.1 + 0.9·(5/6)² = 0.725  # its other side is ≈ 5 px = 2.5σ away (the blurred bar's edges sit apart by more than its width)
    assert np.all((w[em.edges] >= 0.1) & (w[em.edges] <= 1.0))
    assert np.all(np.isnan(w[~em.edges]))


def test_pipeline_multiplies_the_confidence_by_the_weight():
    gray = _step_and_bar()
    rgb = np.repeat(gray[..., None], 3, axis=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        off = estimate_defocus_map(rgb, DefocusParams())
        on = estimate_defocus_map(rgb, DefocusParams(edge_isolation="normal"))
    assert off.measure_confidence is None
    ok = np.isfinite(on.sparse_sigma)
    np.testing.assert_array_equal(on.sparse_sigma, off.sparse_sigma)
    c = on.measure_confidence[ok]
    assert np.all((c > 0) & (c <= 1)) and np.any(c < 0.5) and np.any(c == 1.0)


def test_bad_options_are_refused():
    g = np.zeros((8, 8))
    e = np.zeros((8, 8), dtype=bool)
    with pytest.raises(ValueError, match="allowed"):
        isolation_weights(g, e, g, g, method="nearest")
    with pytest.raises(ValueError, match="allowed"):
        isolation_weights(g, e, g, g, radius=0.0)
    with pytest.raises(ValueError, match="allowed"):
        DefocusParams(edge_isolation="nearest")
    with pytest.raises(ValueError, match="allowed"):
        DefocusParams(isolation_floor=0.0)
