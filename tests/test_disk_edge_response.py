"""The disk-blurred step response (method.blur.disk_edge_response) and the model fit's PSF models (fit_psf).

Analytic truth: a step blurred by a uniform disk of diameter c (the thin lens's defocus, Eq. 5) has
per-axis std c/4; the disk model recovers it, the paper's Gaussian model (Eq. 2c) over-estimates it
or rejects the fit, and the per-image selection ("auto", the robust preset) picks the right model on
disk- and Gaussian-blurred images alike.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.ndimage import gaussian_filter
from scipy.signal import fftconvolve

from method import DefocusParams
from method.blur.estimators import estimate_blur_with_confidence
from method.blur.model_fit import (FIT_PSF_MODELS, PSF_SELECT_MIN_EDGES, model_fit_diagnostics, response_model,
                                   select_psf_model)
from method.blur.disk_edge_response import DISK_RHO_MAX, disk_line_spread, disk_step_response
from method.edges.elder_zucker import detect_edges

#: Table lookup vs direct integration, relative to the peak |r| (measured ≤ 1.4e-3).
RESPONSE_RTOL = 2.5e-3
#: Median σ of the disk fit on disk-blurred steps (8 bits + noise 1/255) vs c/4 (measured ≤ 2 %).
DISK_FIT_RTOL = 0.04


def _direct_response(t, radius, sigma2):
    """Slow oracle: ∫ L_R(x) g'_σ2(t − x) dx by adaptive quadrature."""
    def f(x):
        u = t - x
        return (disk_line_spread(x, radius=radius)
                * (-u / (math.sqrt(2 * math.pi) * sigma2 ** 3) * math.exp(-0.5 * (u / sigma2) ** 2)))
    return quad(f, -radius, radius, points=[max(-radius, min(radius, t))], limit=400, epsabs=1e-14)[0]


@pytest.mark.parametrize("radius, sigma2", [(0.2, 0.5), (1.0, 0.5), (3.0, 0.5), (6.0, 1.0), (12.0, 2.0),
                                            (40.0, 0.5), (2.0, 4.0)])
def test_response_matches_direct_integration(radius, sigma2):
    t = np.linspace(-radius - 5 * sigma2, radius + 5 * sigma2, 241)
    got = disk_step_response(t, radius=radius, sigma2=sigma2)
    want = np.array([_direct_response(x, radius, sigma2) for x in t])
    assert np.max(np.abs(got - want)) <= RESPONSE_RTOL * np.max(np.abs(want))


def test_response_is_the_gaussian_model_for_a_tiny_disk():
    sigma2 = 2.0
    radius = sigma2 / (1.01 * DISK_RHO_MAX)  # beyond the table: the Gaussian of the same second moment
    t = np.linspace(-10, 10, 101)
    s = math.sqrt(sigma2 ** 2 + radius ** 2 / 4)
    np.testing.assert_allclose(disk_step_response(t, radius=radius, sigma2=sigma2), response_model(t, s=s),
                               rtol=0, atol=1e-12)
    # just inside the table the two agree closely too (no jump at the switch)
    inside = sigma2 / (0.99 * DISK_RHO_MAX)
    a = disk_step_response(t, radius=inside, sigma2=sigma2)
    b = response_model(t, s=math.sqrt(sigma2 ** 2 + inside ** 2 / 4))
    assert np.max(np.abs(a - b)) <= 1e-3 * np.max(np.abs(b))


def test_line_spread_moments():
    x = np.linspace(-3, 3, 600001)
    dx = x[1] - x[0]
    lsf = disk_line_spread(x, radius=2.5)
    assert abs(np.sum(lsf) * dx - 1) < 1e-6
    assert abs(np.sum(x ** 2 * lsf) * dx - 2.5 ** 2 / 4) < 1e-5  # per-axis std R/2 = c/4


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_bad_radius_or_scale(bad):
    with pytest.raises(ValueError, match="radius"):
        disk_step_response([0.0], radius=bad, sigma2=1.0)
    with pytest.raises(ValueError, match="sigma2"):
        disk_step_response([0.0], radius=1.0, sigma2=bad)
    with pytest.raises(ValueError, match="radius"):
        disk_line_spread([0.0], radius=bad)


def _disk_kernel(radius, supersample=8):
    n = int(math.ceil(radius)) + 1
    y, x = (np.mgrid[-n * supersample:(n + 1) * supersample, -n * supersample:(n + 1) * supersample] + 0.5) \
        / supersample - 0.5
    inside = (x ** 2 + y ** 2 <= radius ** 2).astype(float)
    k = inside.reshape(2 * n + 1, supersample, 2 * n + 1, supersample).sum((1, 3))
    return k / k.sum()


def _blurred_step(sigma, psf, *, size=128, angle=0.3, seed=0):
    """A straight step (0.2 → 0.8) blurred by a disk of diameter 4σ or a Gaussian σ; 8 bits + noise 1/255."""
    yy, xx = np.mgrid[:size, :size]
    c = size / 2 * (math.cos(angle) + math.sin(angle))
    step = np.where(xx * math.cos(angle) + yy * math.sin(angle) > c, 0.8, 0.2)
    if psf == "disk":
        pad = 40
        img = fftconvolve(np.pad(step, pad, mode="edge"), _disk_kernel(2 * sigma), mode="same")[pad:-pad, pad:-pad]
    else:
        img = gaussian_filter(step, sigma, mode="nearest")
    img = img + np.random.default_rng(seed).normal(0, 1 / 255, img.shape)
    return np.round(np.clip(img, 0, 1) * 255) / 255


def _median_fit(img, params):
    em = detect_edges(img, noise_std=params.noise_std)
    inner = em.edges.copy()
    inner[:20] = inner[-20:] = False
    inner[:, :20] = inner[:, -20:] = False
    sigma, _ = estimate_blur_with_confidence(img, em, params=params)
    ok = inner & np.isfinite(sigma)
    return (float(np.median(sigma[ok])) if ok.any() else math.nan), ok.sum() / inner.sum()


@pytest.mark.parametrize("sigma", [1.0, 2.0, 3.0, 4.0, 6.0])
def test_disk_fit_recovers_disk_blur_and_the_gaussian_fit_does_not(sigma):
    img = _blurred_step(sigma, "disk")
    got, coverage = _median_fit(img, DefocusParams.preset("robust", fit_psf="disk"))
    assert coverage > 0.9
    assert abs(got - sigma) <= DISK_FIT_RTOL * sigma, got
    gauss, g_coverage = _median_fit(img, DefocusParams.preset("robust", fit_psf="gaussian"))
    # the paper's model: ≥ 10 % too wide, or its goodness-of-fit test rejects most of the edge
    assert g_coverage < 0.6 or gauss > 1.1 * sigma, (gauss, g_coverage)


@pytest.mark.parametrize("psf", ["disk", "gaussian"])
def test_auto_selects_the_blurring_model(psf):
    img = _blurred_step(3.0, psf)
    robust = DefocusParams.preset("robust")
    assert robust.fit_psf == "auto"
    em = detect_edges(img, noise_std=robust.noise_std)
    g = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="gaussian"))
    d = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="disk"))
    assert select_psf_model(g, d["width"], d["residual"]) == psf
    # and "auto" gives exactly that model's measures
    auto, _ = estimate_blur_with_confidence(img, em, params=robust)
    want, _ = estimate_blur_with_confidence(img, em, params=robust.replace(fit_psf=psf))
    np.testing.assert_array_equal(auto, want)


def test_auto_keeps_the_paper_model_without_evidence():
    """Fewer than PSF_SELECT_MIN_EDGES resolved, well-fitted edges: Eq. (2c)."""
    img = _blurred_step(3.0, "disk")
    robust = DefocusParams.preset("robust")
    em = detect_edges(img, noise_std=robust.noise_std)
    g = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="gaussian"))
    d = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="disk"))
    keep = np.flatnonzero(np.isfinite(d["residual"]).ravel())[:PSF_SELECT_MIN_EDGES - 1]
    few = np.full(d["residual"].size, np.nan)
    few[keep] = d["residual"].ravel()[keep]
    assert select_psf_model(g, d["width"], few.reshape(d["residual"].shape)) == "gaussian"


def test_best_takes_the_smaller_residual_per_edge():
    img = _blurred_step(2.0, "disk")
    robust = DefocusParams.preset("robust")
    em = detect_edges(img, noise_std=robust.noise_std)
    g = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="gaussian"))
    d = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="disk"))
    b = model_fit_diagnostics(img, em, params=robust.replace(fit_psf="best"))
    ok = np.isfinite(g["residual"]) & np.isfinite(d["residual"])
    np.testing.assert_array_equal(b["residual"][ok], np.minimum(g["residual"], d["residual"])[ok])
    assert b["disk"][ok].any()  # on a disk-blurred step the disk fits some edges better
    np.testing.assert_array_equal(b["width"][ok & b["disk"]], d["width"][ok & b["disk"]])


def test_gaussian_model_is_the_paper_fit_bit_for_bit():
    """fit_psf="gaussian" (the paper's default) leaves the Eq. (2c) fit exactly as it was."""
    img = _blurred_step(2.0, "gaussian")
    paper = DefocusParams()
    assert paper.fit_psf == "gaussian" and set(FIT_PSF_MODELS) == {"gaussian", "disk", "best", "auto"}
    em = detect_edges(img, noise_std=paper.noise_std)
    g = model_fit_diagnostics(img, em, params=paper)
    assert not g["disk"].any()
    d = model_fit_diagnostics(img, em, params=paper.replace(fit_psf="disk"))
    # the disk fit runs on the same windows (same samples and energy) and differs in width
    np.testing.assert_array_equal(g["window"], d["window"])
    np.testing.assert_array_equal(g["energy"], d["energy"])
    assert np.nanmax(np.abs(g["width"] - d["width"])) > 0.05


@pytest.mark.parametrize("s_prime, sig_p, t0", [(1.5, 1.0, 0.0), (4.0, 0.6, 0.3), (9.0, 2.0, -0.45), (2.05, 2.0, 0.1)])
def test_fit_kernel_disk_score_matches_the_public_response(s_prime, sig_p, t0):
    """The fit's fast template scoring (method.blur.fit_templates._score_disk) against templates from
    disk_step_response: (r·m)²/(m·m) over the window, m(k) = r_disk(k − t0; R', σ')."""
    from method.blur.fit_templates import _score_disk
    from method.blur.disk_edge_response import response_table

    K = 20
    rng = np.random.default_rng(3)
    r = rng.standard_normal(2 * K + 1)
    a, b = -12, 15
    radius = 2.0 * math.sqrt(s_prime ** 2 - sig_p ** 2)
    k = np.arange(a, b + 1, dtype=np.float64)
    m = disk_step_response(k - t0, radius=radius, sigma2=sig_p)
    dot = float(np.dot(r[k.astype(int) + K], m))
    want = dot * dot / float(np.dot(m, m)) if dot > 0 else 0.0
    got = _score_disk(r, a, b, K, s_prime, t0, sig_p, *response_table())
    assert got == pytest.approx(want, rel=1e-9, abs=1e-12)
    got_neg = _score_disk(-r, a, b, K, s_prime, t0, sig_p, *response_table())  # A > 0 constraint
    assert (got_neg == 0.0) == (dot > 0)


# --- which model measured the edges: estimate_blur_measures and DefocusResult.psf_model ------------

@pytest.mark.parametrize("fit_psf", sorted(FIT_PSF_MODELS))
def test_blur_measures_equal_the_plain_estimator_and_mark_the_disk(fit_psf):
    """σ and confidence of estimate_blur_measures are bit-identical to estimate_blur_with_confidence;
    psf_disk marks exactly the measures whose fit used the disk (the fit's own diagnostics)."""
    from method.blur.estimators import estimate_blur_measures

    img = _blurred_step(3.0, "disk")
    params = DefocusParams.preset("robust", fit_psf=fit_psf)
    em = detect_edges(img, noise_std=params.noise_std, keep_hessians=True)
    sigma, conf, disk = estimate_blur_measures(img, em, params=params)
    want_s, want_c = estimate_blur_with_confidence(img, em, params=params)
    np.testing.assert_array_equal(sigma, want_s)
    np.testing.assert_array_equal(conf, want_c)
    diag = model_fit_diagnostics(img, em, params=params)
    np.testing.assert_array_equal(disk, diag["disk"] & np.isfinite(sigma))
    assert disk.dtype == bool and not disk[~np.isfinite(sigma)].any()
    if fit_psf in ("disk", "auto"):  # "auto" chooses the disk on this disk-blurred step
        assert disk[np.isfinite(sigma)].all()
    if fit_psf == "gaussian":
        assert not disk.any()


@pytest.mark.parametrize("psf", ["disk", "gaussian"])
def test_result_says_which_model_the_robust_preset_chose(psf):
    from method.pipeline import estimate_defocus_map

    img = _blurred_step(3.0, psf)
    # these steps are blurred in display values: the fit is judged in the light the blur acted in
    res = estimate_defocus_map(img, DefocusParams.preset("robust", measure_light="display"))
    assert res.psf_model == psf
    assert res.psf_disk.shape == img.shape and res.psf_disk.sum() == (
        np.isfinite(res.sparse_sigma).sum() if psf == "disk" else 0)
    # the paper always fits Eq. (2c); an estimator that fits no PSF model says nothing
    assert estimate_defocus_map(img, DefocusParams()).psf_model == "gaussian"
    assert estimate_defocus_map(img, DefocusParams(estimator="gradient_ratio")).psf_model is None


def test_result_psf_model_mixed():
    """'best' picks per edge: a Gaussian-blurred step beside a disk-blurred one → 'mixed', the disk
    on the disk's side."""
    from method.pipeline import estimate_defocus_map

    img = np.concatenate([_blurred_step(3.0, "gaussian"), _blurred_step(3.0, "disk")], axis=1)
    res = estimate_defocus_map(img, DefocusParams.preset("robust", fit_psf="best", measure_light="display"))
    measured = np.isfinite(res.sparse_sigma)
    assert res.psf_model == "mixed"
    left, right = np.zeros_like(measured), np.zeros_like(measured)
    left[:, 20:108], right[:, 148:236] = True, True  # away from the seam and the borders
    assert res.psf_disk[measured & right].mean() > 0.9 and res.psf_disk[measured & left].mean() < 0.1
