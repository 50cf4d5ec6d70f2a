"""Each edge measure's own uncertainty (method.blur.measure_uncertainty) and the weighting it drives.

``measure_weighting="uncertainty"`` gives each measure of the checked fit a confidence ∝ 1/Var(σb) in
Eq. (3) and Eq. (4), Var(σb) the Cramér–Rao variance of the fit's width under the pixel's noise;
``bias_weighting="uncertainty"`` applies Eq. (3)'s sharpness bias only as far as a measure is uncertain.
"""

import math

import numpy as np
import pytest
from scipy import ndimage

from method import DefocusParams, estimate_defocus_map
from method.blur.measure_uncertainty import (MEASURE_WEIGHTINGS, UNCERTAINTY_MIN_CONFIDENCE, uncertainty_confidence,
                                             width_information)
from method.blur.model_fit_checked import estimate_blur_model_fit_checked, estimate_blur_model_fit_checked_sd
from method.pipeline import edges_stage, refine_stage
from method.refine.cross_bilateral import biased_cross_bilateral

#: robust with the hand-set confidence (relaxed_fit_weight) it had before weighing by uncertainty
ROBUST = DefocusParams.preset("robust").replace(measure_weighting="hand", relaxed_fit_weight=0.1)
UNC = ROBUST.replace(measure_weighting="uncertainty")

#: Measured on straight Gaussian-blurred steps, σb 1–4 px, contrast 0.2–0.5, noise 0.005–0.02 (noise-free
#: image, the noise given to the model): the per-measure sd over the unbounded-window analytic bound
#: was 0.97–1.13 (the fit's window, ±2× the response's extremum, holds less information than an unbounded one).
ANALYTIC_RATIO = (0.9, 1.2)
#: Measured: the spread of σb over six noisy realisations was 1.1–2.2× the predicted sd (the samples of a
#: filtered response are correlated over ≈ σ2, so the white-sample bound is a lower bound).
MONTE_CARLO_RATIO = (1.0, 3.0)


def _step(contrast, sigma_b, *, noise=0.0, seed=0, size=96, base=0.25):
    """A vertical step in linear light, blurred by a Gaussian of σb px, optionally with white noise."""
    x = np.arange(size) - size / 2 + 0.5
    img = np.where(x[None, :] > 0, base + contrast, base) * np.ones((size, 1))
    img = ndimage.gaussian_filter(img, sigma_b, mode="nearest")
    if noise:
        img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(img, 0.0, 1.0)


def _params(noise):
    """Robust with the pixel noise given (variance noise², no shot noise) and the Gaussian model of Eq. (2c)."""
    return ROBUST.replace(noise_model="signal_dependent", noise_a=0.0, noise_b=noise ** 2, fit_psf="gaussian")


def _measures(contrast, sigma_b, model_noise, *, noise=0.0, seed=0):
    """(σb, sd, σ2) of the measures away from the image border."""
    p = _params(model_noise)
    g = _step(contrast, sigma_b, noise=noise, seed=seed)
    em = edges_stage(g, params=p, encoding="linear")
    s, sd = estimate_blur_model_fit_checked_sd(g, em, params=p)
    core = np.zeros(s.shape, dtype=bool)
    core[16:-16, 16:-16] = True
    keep = np.isfinite(s) & core
    assert keep.sum() >= 40
    return s[keep], sd[keep], np.minimum(np.asarray(em.sigma2)[keep], ROBUST.fit_max_scale)


def _analytic_sd(contrast, sigma_b, noise, sigma2):
    """The Cramér–Rao sd of σb for a continuous step and an unbounded window, white samples.

    The response's energy is A²/(4√π s³) per px, the noise's v = 3 noise²/(16π σ2⁶), and the width's
    relative information per unit energy 3/2, so sd(s)/s = (noise/A)·√(s³ / (2√π σ2⁶)); then Eq. (2d).
    """
    s = math.hypot(sigma_b, sigma2)
    sd_s = s * (noise / contrast) * math.sqrt(s ** 3 / (2.0 * math.sqrt(math.pi) * sigma2 ** 6))
    return math.sqrt((s + sd_s) ** 2 - sigma2 ** 2) - sigma_b


def test_width_information_is_three_halves_on_a_long_window_and_zero_on_three_samples():
    g = width_information(np.array([3.0, 6.0, 1.0, 1.0]), np.array([201, 401, 3, 9]))
    np.testing.assert_allclose(g[:2], 1.5, rtol=1e-3)
    assert g[2] == 0.0  # three centred samples cannot tell the width from the amplitude
    assert 0 < g[3] < 1.5  # a truncated window holds less information than an unbounded one
    assert np.isnan(width_information(np.array([np.nan, 2.0]), np.array([9, 2]))).all()


@pytest.mark.parametrize("contrast, noise", [(0.4, 0.005), (0.2, 0.01), (0.5, 0.02)])
@pytest.mark.parametrize("sigma_b", [1.0, 2.0, 3.0])
def test_sd_follows_the_analytic_cramer_rao_bound(contrast, noise, sigma_b):
    s, sd, sigma2 = _measures(contrast, sigma_b, noise)
    assert abs(np.median(s) - sigma_b) < 0.1
    expected = np.array([_analytic_sd(contrast, sigma_b, noise, q) for q in sigma2])
    ratio = float(np.median(sd / expected))
    assert ANALYTIC_RATIO[0] <= ratio <= ANALYTIC_RATIO[1], ratio


def test_sd_shrinks_with_contrast_and_grows_with_noise_in_proportion():
    # same σ2 for all three (σb 2 px: every edge fitted at the 2-px cap), so the bound is ∝ noise / contrast
    _, base, s2a = _measures(0.4, 2.0, 0.005)
    _, low_contrast, s2b = _measures(0.2, 2.0, 0.005)
    _, noisy, s2c = _measures(0.4, 2.0, 0.01)
    assert np.all(s2a == 2.0) and np.all(s2b == 2.0) and np.all(s2c == 2.0)
    # δσb is not linear in δs (Eq. 2d), so doubling sd(s) gives 2× sd(σb) to within 3 % at these sizes
    for other in (low_contrast, noisy):
        ratio = np.median(other) / np.median(base)
        assert 1.94 <= ratio <= 2.06, ratio
    _, noisier, s2d = _measures(0.4, 2.0, 0.02)
    assert np.all(s2d == 2.0)
    assert 1.94 <= np.median(noisier) / np.median(noisy) <= 2.06


def test_sd_bounds_the_spread_over_noisy_realisations():
    def spread(contrast, noise):
        s, sd = zip(*[_measures(contrast, 2.0, noise, noise=noise, seed=seed)[:2] for seed in range(4)])
        s, sd = np.concatenate(s), np.concatenate(sd)
        return float(np.std(s)), float(np.median(sd[np.isfinite(sd)]))

    emp_a, pred_a = spread(0.4, 0.01)
    emp_b, pred_b = spread(0.2, 0.01)
    for emp, pred in ((emp_a, pred_a), (emp_b, pred_b)):
        assert MONTE_CARLO_RATIO[0] <= emp / pred <= MONTE_CARLO_RATIO[1], (emp, pred)
    # halving the contrast: the realised spread and the predicted sd grow alike (within 20 %)
    assert abs((emp_b / emp_a) / (pred_b / pred_a) - 1.0) < 0.2


def test_the_residual_raises_the_sd_where_the_model_does_not_explain_the_response():
    # the same step with a cosine ripple beside it: the fit's residual per degree of freedom exceeds the noise
    p = _params(0.002)
    g = _step(0.4, 2.0)
    ripple = g + 0.03 * np.cos(np.arange(g.shape[1]) * 2 * np.pi / 7.0)[None, :]
    sds = []
    for img in (g, np.clip(ripple, 0, 1)):
        em = edges_stage(img, params=p, encoding="linear")
        s, sd = estimate_blur_model_fit_checked_sd(img, em, params=p)
        col = img.shape[1] // 2
        near = np.isfinite(s[:, col - 1:col + 1])
        sds.append(np.median(sd[:, col - 1:col + 1][near]))
    assert sds[1] > 1.5 * sds[0], sds


def test_sigma_of_the_sd_function_equals_the_checked_fit():
    p = _params(0.01)
    g = _step(0.3, 2.0, noise=0.01)
    em = edges_stage(g, params=p, encoding="linear")
    s, sd = estimate_blur_model_fit_checked_sd(g, em, params=p)
    np.testing.assert_array_equal(s, estimate_blur_model_fit_checked(g, em, params=p))
    assert np.array_equal(np.isfinite(s), np.isfinite(sd) | np.isinf(sd))


def test_confidence_is_inverse_variance_normalised_to_the_median():
    sd = np.array([[0.1, 0.1, 0.2, np.inf, np.nan, 0.05]])
    measures = np.array([[True, True, True, True, False, True]])
    c = uncertainty_confidence(sd, measures)
    np.testing.assert_allclose(c[0, [0, 1, 5]], 1.0)  # median sd 0.1: at least as precise weighs 1
    np.testing.assert_allclose(c[0, 2], 0.25)  # twice the sd: a quarter of the weight
    assert c[0, 3] == UNCERTAINTY_MIN_CONFIDENCE
    assert np.isnan(c[0, 4])


def _two_steps(noise=0.004, seed=1):
    """Two vertical steps σb 2 px in one sRGB image: the left of contrast 0.5, the right of 0.08."""
    w = 128
    x = np.arange(w)
    lin = 0.2 + 0.5 * (x >= 32) - 0.5 * (x >= 64) + 0.08 * (x >= 96)
    img = ndimage.gaussian_filter1d(np.tile(lin, (64, 1)), 2.0, axis=1, mode="nearest")
    img = img + np.random.default_rng(seed).normal(0, noise, img.shape)
    return np.clip(img, 0, 1)


def test_a_measure_the_noise_cannot_pin_down_weighs_less():
    img = _two_steps()
    r = estimate_defocus_map(img, UNC, encoding="linear")
    c = r.measure_confidence
    assert c is not None
    strong = np.isfinite(c[:, 28:36])
    weak = np.isfinite(c[:, 92:100])
    assert strong.sum() > 20 and weak.sum() > 20
    assert np.median(c[:, 28:36][strong]) > 2 * np.median(c[:, 92:100][weak])
    # with the hand-set weights the two edges weigh alike (both strict fits)
    hand = estimate_defocus_map(img, ROBUST, encoding="linear").measure_confidence
    assert hand is None or np.nanmedian(hand[:, 28:36]) == np.nanmedian(hand[:, 92:100])


def test_eq3_follows_the_certain_measure():
    # two measures side by side in one colour: a precise one at 1 px and an uncertain one at 3 px
    sparse = np.full((16, 16), np.nan)
    sparse[8, 4], sparse[8, 11] = 1.0, 3.0
    rgb = np.full((16, 16, 3), 0.5)
    conf = np.where(np.isfinite(sparse), 1.0, np.nan)
    conf[8, 11] = 0.01
    p = UNC.replace(bilateral_method="brute_force", bilateral_sigma_spatial=1.0)  # σs 16 px
    w = math.exp(-49.0 / (2 * 16.0 ** 2))  # the spatial weight between them, 7 px apart
    out = refine_stage(sparse, rgb, params=p, confidence=conf)
    np.testing.assert_allclose(out[8, 4], (1.0 + 0.01 * w * 3.0) / (1.0 + 0.01 * w))
    even = refine_stage(sparse, rgb, params=p, confidence=None)
    np.testing.assert_allclose(even[8, 4], (1.0 + w * 3.0) / (1.0 + w))
    assert abs(out[8, 4] - 1.0) < 0.03 < abs(even[8, 4] - 1.0)


def test_the_bias_acts_only_as_far_as_the_measure_is_uncertain():
    rng = np.random.default_rng(0)
    sparse = np.where(rng.random((24, 24)) < 0.3, rng.uniform(0, 4, (24, 24)), np.nan)
    ref = rng.random((24, 24, 3))
    kw = dict(method="brute_force", sigma_spatial=0.3, sigma_range=0.5)
    plain = biased_cross_bilateral(sparse, ref, sharpness_bias=False, **kw)
    paper = biased_cross_bilateral(sparse, ref, sharpness_bias=True, **kw)
    none = biased_cross_bilateral(sparse, ref, sharpness_bias=True, bias_strength=np.zeros((24, 24)), **kw)
    full = biased_cross_bilateral(sparse, ref, sharpness_bias=True, bias_strength=np.ones((24, 24)), **kw)
    np.testing.assert_allclose(none, plain, rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(full, paper, rtol=1e-12, equal_nan=True)
    half = biased_cross_bilateral(sparse, ref, sharpness_bias=True, bias_strength=np.full((24, 24), 0.5), **kw)
    e = np.isfinite(sparse)
    assert np.all(half[e] <= plain[e] + 1e-12) and np.all(half[e] >= paper[e] - 1e-12)
    assert np.mean(paper[e]) < np.mean(half[e]) < np.mean(plain[e])
    # through the pipeline: a certain measure (c = 1) is not biased, an uncertain one (c → 0) fully
    p = UNC.replace(sharpness_bias=True, bias_weighting="uncertainty", bilateral_method="brute_force")
    conf = np.where(e, 1.0, np.nan)
    np.testing.assert_allclose(refine_stage(sparse, ref, params=p, confidence=conf),
                               refine_stage(sparse, ref, params=p.replace(bias_weighting="uniform",
                                                                          sharpness_bias=False), confidence=conf),
                               rtol=1e-12, equal_nan=True)


def test_paper_weighs_every_measure_alike_and_robust_by_uncertainty():
    assert DefocusParams().measure_weighting == "hand" and DefocusParams().bias_weighting == "uniform"
    assert DefocusParams.preset("robust").measure_weighting == "uncertainty"
    assert ROBUST.measure_weighting in MEASURE_WEIGHTINGS


def test_uncertainty_weighting_needs_the_checked_fit():
    """With an estimator that reports no fit (the paper's model fit) the field has nothing to weigh."""
    img = _two_steps()
    p = DefocusParams(measure_weighting="uncertainty")
    assert estimate_defocus_map(img, p, encoding="linear").measure_confidence is None


@pytest.mark.parametrize("changes, field", [
    ({"measure_weighting": "inverse_variance"}, "measure_weighting"),
    ({"measure_weighting": 1}, "measure_weighting"),
    ({"bias_weighting": "sometimes"}, "bias_weighting"),
    ({"bias_weighting": "uncertainty", "sharpness_bias": False}, "bias_weighting"),
    ({"bias_weighting": "uncertainty", "sharpness_bias": True, "measure_weighting": "hand"}, "bias_weighting"),
])
def test_bad_values_raise(changes, field):
    with pytest.raises(ValueError, match=rf"DefocusParams\.{field}=.* is invalid.*; allowed: "):
        ROBUST.replace(**changes)


def test_bad_bias_strength_raises():
    sparse = np.full((8, 8), np.nan)
    sparse[4, 4] = 1.0
    ref = np.full((8, 8), 0.5)
    for bad in (np.full((8, 8), 1.5), np.full((8, 8), -0.1), np.full((8, 8), np.nan), np.zeros((4, 4))):
        with pytest.raises(ValueError, match="bias_strength"):
            biased_cross_bilateral(sparse, ref, bias_strength=bad)
