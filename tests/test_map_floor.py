"""The estimated in-focus floor ("auto"), the focus point and the keep-sharp mask of the magnification."""

import numpy as np
import pytest
from scipy import ndimage

from method import DefocusParams
from method.magnify.magnification import magnify_defocus, preprocess_defocus_map
from method.magnify.map_floor import (FloorEstimate, estimate_floor, floor_at_point, keep_sharp_weight,
                                      soft_floor)


def _two_region_map(rng, h=60, w=120, floor=0.9, blurry=3.0, noise=0.05):
    """Left half: an in-focus floor read with some noise; right half: a blurry background."""
    m = np.full((h, w), blurry) + noise * rng.standard_normal((h, w))
    m[:, : w // 2] = floor + noise * rng.standard_normal((h, w // 2))
    return m


def test_soft_floor_is_zero_within_the_uncertainty():
    est = FloorEstimate(0.8, 0.2)
    m = np.linspace(0.0, 1.0, 201)  # up to t = f + u = 1.0 px
    assert np.all(soft_floor(m, est) == 0.0)
    assert np.all(soft_floor(np.array([1.0001, 1.1, 2.0]), est) > 0)


def test_soft_floor_has_no_seam_and_tends_to_quadrature():
    """σ' is continuous with a bounded derivative (no seam at the threshold), monotone, and far above
    it removes the floor in quadrature: σ'² = σ² − (t² + 2W/3)."""
    est = FloorEstimate(0.8, 0.2)
    m = np.linspace(0.0, 8.0, 80001)
    s = soft_floor(m, est)
    d = np.diff(s) / np.diff(m)
    t, u = est.threshold, est.uncertainty
    width = 2 * t * u + u * u
    bound = (t + u) * np.sqrt(3 / width)
    assert d.min() >= 0 and d.max() <= bound * (1 + 1e-6)
    assert np.max(np.abs(np.diff(d))) < 0.1  # derivative continuous: no kink at t or at t + u (a kink jumps by ~2)
    far = m > 3.0
    np.testing.assert_allclose(s[far] ** 2, m[far] ** 2 - (t * t + 2 * width / 3), rtol=1e-9)


def test_a_bad_soft_floor_would_fail_the_seam_check():
    """The quadrature subtraction of the threshold (the "subtract" reading) has an unbounded slope at t."""
    t = 1.0
    m = np.linspace(0.0, 3.0, 30001)
    s = np.sqrt(np.maximum(m * m - t * t, 0.0))
    assert (np.diff(s) / np.diff(m)).max() > 10


def test_estimate_floor_finds_the_sharp_mode(rng):
    m = _two_region_map(rng)
    est = estimate_floor(m)
    assert 0.8 < est.floor < 0.95
    assert est.threshold >= np.percentile(m[:, :60], 50)
    assert est.threshold < 2.0


def test_auto_floor_leaves_the_in_focus_half_untouched(rng):
    m = _two_region_map(rng)
    img = rng.random((60, 120, 3))
    out = magnify_defocus(img, m, factor=2.0, floor="auto", renderer="scatter")
    processed = preprocess_defocus_map(m, floor="auto")
    zero = processed == 0
    assert zero[:, :50].mean() > 0.95  # in-focus half: no blur added (away from the boundary)
    assert processed[:, 70:].min() > 2.0  # the background keeps most of its blur
    inner = ndimage.binary_erosion(zero, iterations=2, border_value=1)  # the scatter's one-pixel soft rim aside
    np.testing.assert_array_equal(out[inner], img[inner])
    clamp = magnify_defocus(img, m, factor=2.0, floor="clamp", renderer="scatter")
    assert not np.allclose(clamp[:, :50], img[:, :50])  # the literal reading blurs the subject


def test_focus_point_reads_the_floor_there(rng):
    """A subject at 1.5 px (e.g. a focus plane the map reads higher than the sharpest region) stays sharp
    when named; without the point only the sharpest region is kept."""
    m = _two_region_map(rng, floor=0.6)
    m[20:40, 80:100] = 1.5 + 0.03 * rng.standard_normal((20, 20))
    named = preprocess_defocus_map(m, floor="clamp", smoothing=0.0, focus_point=(90, 30))
    assert np.all(named[22:38, 82:98] == 0.0)
    auto = preprocess_defocus_map(m, floor="auto", smoothing=0.0)
    assert np.all(auto[22:38, 82:98] > 0.2)
    est = floor_at_point(m, (90, 30))
    assert abs(est.floor - 1.5) < 0.05


def test_keep_sharp_mask_is_untouched_and_feathered(rng):
    m = np.full((40, 80), 3.0)
    mask = np.zeros((40, 80), bool)
    mask[10:30, 10:30] = True
    img = rng.random((40, 80, 3))
    out = magnify_defocus(img, m, factor=2.0, keep_sharp=mask, renderer="gather")
    np.testing.assert_array_equal(out[mask], img[mask])
    w = keep_sharp_weight(mask, mask.shape, 6.0)
    assert np.all(w[mask] == 0) and np.all(w[:, 40:] == 1)
    assert np.all(np.abs(np.diff(w[20])) <= 0.26)  # a smoothstep over 6 px: at most 1.5/6 per px, no seam
    soft = keep_sharp_weight(np.full((40, 80), 0.25), (40, 80), 6.0)
    np.testing.assert_allclose(soft, 0.75)


@pytest.mark.parametrize("point", [(-1, 5), (80, 5), (5, 40), (np.nan, 3), "centre", (1, 2, 3)])
def test_focus_point_outside_the_image_is_refused(rng, point):
    with pytest.raises(ValueError, match="focus_point"):
        magnify_defocus(rng.random((40, 80)), np.ones((40, 80)), focus_point=point)


@pytest.mark.parametrize("mask", [np.zeros((40, 81), bool), np.zeros((80, 40), bool), np.full((40, 80), 1.5),
                                  np.full((40, 80), np.nan), np.zeros((40, 80, 3), bool)])
def test_bad_keep_sharp_is_refused(rng, mask):
    with pytest.raises(ValueError, match="keep_sharp"):
        magnify_defocus(rng.random((40, 80)), np.ones((40, 80)), keep_sharp=mask)


def test_given_map_without_preprocessing_takes_the_subject_too(rng):
    m = np.full((30, 30), 2.0)
    m[:, :15] = 0.7
    img = rng.random((30, 30))
    out = magnify_defocus(img, m, factor=2.0, preprocess=False, focus_point=(5, 5))
    np.testing.assert_array_equal(out[:, :12], img[:, :12])


def test_presets_floor():
    assert DefocusParams.preset("robust").map_floor == "auto"
    assert DefocusParams.preset("paper").map_floor == "clamp"


def test_preset_renderers_agree_with_the_command_line():
    """The renderer each preset names is the one repro.magnify uses without --renderer."""
    from repro import magnify

    assert DefocusParams.preset("robust").magnify_renderer == magnify.DEFAULT_RENDERER == "scatter"
    assert DefocusParams.preset("paper").magnify_renderer == magnify.PAPER_RENDERER == "gather"


def test_a_wide_sharp_half_beside_a_narrow_blurry_mode(rng):
    """The blurry background's mode is the highest of the density; the floor is still read in the sharper half."""
    m = np.full((60, 120), 2.4) + 0.05 * rng.standard_normal((60, 120))
    m[:, :60] = rng.uniform(0.3, 1.2, (60, 60))
    est = estimate_floor(m)
    assert est.threshold < 1.2
    assert np.all(soft_floor(m[:, 60:], est) > 1.5)
