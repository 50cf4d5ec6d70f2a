"""The model fit's fast paths against their slow, obviously-correct forms: the same bytes.

The Eq. (2c) template search computes each pass's dot products together
(:func:`method.blur.fit_templates._best_gaussian_template`); the oracle is the one-template-at-a-time
search :func:`method.blur.fit_templates._best_template` (which the disk model still uses).
:func:`method.blur.model_fit_checked.fit_measure_sd` evaluates only the fitted pixels; the oracle is
:func:`method.blur.measure_uncertainty.measure_sd` over every pixel of the image. The scale following
(:func:`method.blur.scale_follow.follow_scale_diagnostics`) and the checked fit's rules and confidences
(``method.blur.model_fit_checked._checked``) run on pixel lists; the oracles are their whole-image forms.
"""

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from method import DefocusParams
from method.blur.fit_templates import (COARSE_STRIDE, EMPTY_DISK_TABLE, _best_gaussian_template, _best_template,
                                       template_table)
from method.blur.measure_uncertainty import measure_sd, uncertainty_confidence, width_information
from method.blur.model_fit import apply_fit_rules, model_fit_diagnostics
from method.blur.model_fit_checked import (_checked, _noise_spectrum, _noise_variance, fit_measure_sd,
                                           noise_residual_share, steered_second_noise_variance)
from method.blur.noise_model import noise_variance_map
from method.blur.psf_selection import PSF_SELECT_SAMPLE, psf_selection_sample, select_psf_model
from method.blur.scale_follow import _nearest_scale, follow_scale_diagnostics, follow_window_max
from method.blur.step_plateau import gate_step_measures
from method.pipeline import edges_stage


def _responses(rng, K, n):
    """n sampled responses of length 2K+1: Eq. (2c)-like lobes of random width, shift and sign, plus noise."""
    k = np.arange(-K, K + 1, dtype=np.float64)
    for _ in range(n):
        s = rng.uniform(0.4, 0.6 * K)
        t0 = rng.uniform(-0.7, 0.7)
        amp = rng.choice([1.0, -1.0, 0.0])  # negative and zero: no positive-amplitude template
        r = -amp * (k - t0) / s ** 3 * np.exp(-0.5 * ((k - t0) / s) ** 2)
        yield r + rng.normal(0.0, rng.choice([0.0, 1e-3, 0.05]) / s ** 2, r.shape), t0


@pytest.mark.parametrize("half_window, s_max", [(35, 91.0), (12, 5.0)])
def test_gaussian_search_is_the_one_template_at_a_time_search(half_window, s_max):
    s_grid, t0_grid, table, cum, table_t, cum_t, table_c, cum_c = template_table(half_window, s_max)
    n_s = s_grid.size
    buf = np.empty(max(n_s, 2 * COARSE_STRIDE + 1, 9))
    rng = np.random.default_rng(38)
    K = half_window
    checked = found = 0
    for r, t0 in _responses(rng, K, 400):
        a = -int(rng.integers(1, K + 1))
        b = int(rng.integers(1, K + 1))
        k0 = float(np.clip(t0 + rng.normal(0.0, 0.3), -0.9, 0.9))  # also beyond the t0 grid (clamped)
        energy_r = float(np.sum(r[a + K:b + K + 1] ** 2))
        want = _best_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, COARSE_STRIDE, False, 0.0,
                              *EMPTY_DISK_TABLE, 0, n_s)
        got = _best_gaussian_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, table_t, cum_t, table_c, cum_c,
                                      COARSE_STRIDE, buf)
        np.testing.assert_array_equal(np.array(got), np.array(want))  # bit-identical, NaN where no fit
        checked += 1
        found += bool(np.isfinite(want[0]))
    assert checked == 400 and 100 < found < 400  # both sides: fitted and declined responses


def test_transposed_templates_are_the_templates():
    s_grid, t0_grid, table, cum, table_t, cum_t, table_c, cum_c = template_table(20, 30.0)
    for full, t, c in ((table, table_t, table_c), (cum, cum_t, cum_c)):
        np.testing.assert_array_equal(t, full.transpose(1, 2, 0))
        np.testing.assert_array_equal(c, full.transpose(1, 2, 0)[:, :, ::COARSE_STRIDE])
    for t in (table_t, cum_t, table_c, cum_c):
        assert t.flags.c_contiguous and not t.flags.writeable


def _textured(size=80, seed=5):
    """A small image with blurred and sharp edges of several widths and some noise (linear light)."""
    rng = np.random.default_rng(seed)
    img = ndimage.zoom(rng.uniform(0.1, 0.9, (10, 10)), size / 10, order=0)
    img = np.where(np.arange(size)[None, :] < size // 2, ndimage.gaussian_filter(img, 3.0), img)
    return np.clip(img + rng.normal(0.0, 0.01, img.shape), 0.0, 1.0)


@pytest.mark.parametrize("noise_model", ["constant", "signal_dependent"])
def test_fit_measure_sd_on_the_fitted_pixels_is_measure_sd_on_the_image(noise_model):
    params = DefocusParams.preset("robust").replace(noise_model=noise_model)
    gray = _textured()
    em = edges_stage(gray, params=params, encoding="linear")
    diag = follow_scale_diagnostics(gray, em, params=params)
    nv = None if noise_model == "constant" else noise_variance_map(gray, params)
    got = fit_measure_sd(diag, em, params=params, noise_variance=nv)
    v_pixel = float(params.noise_std) ** 2 if nv is None else nv
    with np.errstate(invalid="ignore"):
        v_sample = steered_second_noise_variance(diag["sigma2"], 1.0) * v_pixel
    theta = np.asarray(em.theta, dtype=np.float64)
    proj = np.maximum(np.abs(np.cos(theta)), np.abs(np.sin(theta)))
    want = measure_sd(diag, sample_noise_variance=v_sample, proj=proj)
    np.testing.assert_array_equal(got, want)
    assert np.isfinite(got).sum() >= 50 and np.isnan(got).sum() > 0


def _width_information_every_offset(s, n):
    """width_information's sums over every offset of the longest window for every measure (m = 0 outside)."""
    half = 0.5 * (n - 1.0)
    mm = md = dd = np.zeros(s.size)
    for o in np.arange(-np.ceil(half.max()), np.ceil(half.max()) + 1):
        k = o + (half - np.floor(half))
        u = k / s
        m = np.where(np.abs(k) <= half + 1e-9, k * np.exp(-0.5 * u * u), 0.0)
        d = m * (u * u - 3.0)
        mm, md, dd = mm + m * m, md + m * d, dd + d * d
    with np.errstate(invalid="ignore", divide="ignore"):
        g = (dd - md * md / mm) / mm
    return np.where(np.isfinite(g), np.where(g > 1e-9, g, 0.0), np.nan)


def test_width_information_sums_only_the_offsets_each_window_reaches():
    rng = np.random.default_rng(7)
    n = rng.integers(3, 72, 3000)
    n[:10] = 161  # a few long windows, as the re-fit's
    s = rng.uniform(0.3, 40.0, n.size)
    s[::97] = np.nan
    n[::89] = 2  # too short: NaN
    got = width_information(s, n)
    ok = np.isfinite(s) & (n >= 3)
    np.testing.assert_array_equal(got[ok], _width_information_every_offset(s[ok], n[ok].astype(np.float64)))
    assert np.isnan(got[~ok]).all() and (got[ok] > 0).mean() > 0.9


def test_psf_choice_on_the_fitted_pixels_is_the_choice_on_the_image():
    """model_fit_diagnostics decides fit_psf="auto" on the fitted pixels in raster order: same sample, same model."""
    rng = np.random.default_rng(11)
    shape = (150, 160)
    fitted = rng.random(shape) < 0.4  # > PSF_SELECT_SAMPLE candidates: the sample is thinned
    s2 = np.where(fitted, rng.choice([0.5, 1.0, 2.0], shape), np.nan)
    width = np.where(fitted, s2 * rng.uniform(0.5, 4.0, shape), np.nan)
    res = np.where(fitted, rng.uniform(0.0, 0.02, shape), np.nan)
    flat = np.flatnonzero(fitted)
    want = psf_selection_sample(width, s2)
    got = np.zeros(shape, dtype=bool)
    got.ravel()[flat] = psf_selection_sample(width.ravel()[flat], s2.ravel()[flat])
    np.testing.assert_array_equal(got, want)
    assert 1000 < want.sum() <= PSF_SELECT_SAMPLE < (fitted & (width > 1.5 * s2)).sum()
    for shift, model in ((-0.004, "disk"), (0.004, "gaussian")):  # both sides of the choice
        disk_res = np.clip(res + shift * rng.uniform(0.5, 1.5, shape), 0.0, None)
        diag = {"residual": res, "width": width, "sigma2": s2}
        fits = {k: v.ravel()[flat] for k, v in diag.items()}
        assert select_psf_model(diag, width, disk_res) == model
        assert select_psf_model(fits, width.ravel()[flat], disk_res.ravel()[flat]) == model


def _blurry_steps(size=96, seed=3):
    """Steps blurred by σ 1.5 and 7 px (the wide one is re-fitted at a coarser scale), texture, noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:size, :size]
    img = 0.25 + 0.5 * (xx > size // 3) + 0.15 * (yy > size // 2)
    img = np.where(xx < size // 2, ndimage.gaussian_filter(img, 7.0), ndimage.gaussian_filter(img, 1.5))
    img += 0.1 * ndimage.zoom(rng.uniform(-1, 1, (8, 8)), size / 8, order=0) * (xx > 3 * size // 4)
    return np.clip(img + rng.normal(0.0, 0.005, img.shape), 0.0, 1.0)


def _follow_on_the_image(gray, em, params):
    """follow_scale_diagnostics with whole-image masks: the coarse and re-fit see a σ2 map NaN off their pixels."""
    diag = model_fit_diagnostics(gray, em, params=params)
    ratio, rho_max = params.fit_follow_scale, params.fit_follow_max_residual
    s2_det, s2_fit = np.asarray(em.sigma2, dtype=np.float64), diag["sigma2"]
    with np.errstate(invalid="ignore"):
        coarse_mask = em.edges & np.isfinite(s2_det) & np.isfinite(s2_fit) & (s2_det > s2_fit)
    psf = "disk" if params.fit_psf == "auto" and diag["disk"].any() else params.fit_psf
    base = params.replace(fit_max_scale=None, fit_scale_ratio=1.0, fit_psf=psf)
    coarse = model_fit_diagnostics(gray, dataclasses.replace(em, sigma2=np.where(coarse_mask, s2_det, np.nan)),
                                   params=base.replace(fit_window_max=follow_window_max(
                                       np.max(s2_det[coarse_mask]), 1.0, params.fit_window_max)))
    with np.errstate(invalid="ignore"):
        target = _nearest_scale(np.minimum(s2_det, ratio * coarse["sigma_b"]), params.sigma2_scales)
        refit = coarse_mask & np.isfinite(target) & (target > s2_fit) & (coarse["residual"] <= rho_max)
    fine = model_fit_diagnostics(gray, dataclasses.replace(em, sigma2=np.where(refit, target, np.nan)),
                                 params=base.replace(fit_window_max=follow_window_max(
                                     np.max(target[refit]), ratio, params.fit_window_max)))
    with np.errstate(invalid="ignore"):
        keep = refit & (_nearest_scale(ratio * fine["sigma_b"], params.sigma2_scales) >= target)
        keep &= fine["residual"] <= rho_max
    for name, values in diag.items():
        values[keep] = fine[name][keep]
    return diag, int(keep.sum())


def test_scale_following_on_the_pixel_list_is_the_whole_image_form():
    params = DefocusParams.preset("robust")
    gray = _blurry_steps()
    em = edges_stage(gray, params=params, encoding="linear")
    want, refitted = _follow_on_the_image(gray, em, params)
    got = follow_scale_diagnostics(gray, em, params=params)
    assert refitted >= 10  # the re-fit replaced some of the first fit's measures
    assert got.keys() == want.keys()
    for name in want:
        assert got[name].dtype == want[name].dtype
        np.testing.assert_array_equal(got[name], want[name])


def _checked_on_the_image(diag, params, gray, em, nv):
    """The checked fit's rules, noise allowance, plateau gate and confidences on whole-image maps."""
    sigma_b = apply_fit_rules(diag, params=params)
    limit = params.fit_max_residual + params.fit_residual_noise * noise_residual_share(
        diag, noise_std=params.noise_std, noise_variance=nv, noise_spectrum=_noise_spectrum(gray, em, params))
    with np.errstate(invalid="ignore"):
        good, strict = diag["residual"] <= limit, diag["residual"] <= params.fit_max_residual
    sigma_b = gate_step_measures(gray, em, np.where(good, sigma_b, np.nan), params=params)
    if params.measure_weighting == "uncertainty":
        sd = fit_measure_sd(diag, em, params=params, noise_variance=nv)
        return sigma_b, uncertainty_confidence(sd, np.isfinite(sigma_b))
    return sigma_b, np.where(np.isfinite(sigma_b), np.where(strict, 1.0, params.relaxed_fit_weight), np.nan)


@pytest.mark.parametrize("weighting, noise_model, gate", [("uncertainty", "signal_dependent", "plateau"),
                                                          ("hand", "constant", "plateau_flat"),
                                                          ("hand", "signal_dependent", "none")])
def test_checked_fit_on_the_fitted_pixels_is_the_whole_image_form(weighting, noise_model, gate):
    params = DefocusParams.preset("robust").replace(measure_weighting=weighting, noise_model=noise_model,
                                                    fit_step_gate=gate, relaxed_fit_weight=0.3)
    gray = np.hstack([_blurry_steps(), _textured(96)])
    em = edges_stage(gray, params=params, encoding="linear")
    diag = follow_scale_diagnostics(gray, em, params=params)
    nv = _noise_variance(gray, em, params)
    want = _checked_on_the_image(diag, params, gray, em, nv)
    got = _checked(diag, params, gray, em, nv)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype == np.float64
        np.testing.assert_array_equal(g, w)
    fitted = np.isfinite(diag["sigma_b"])
    assert 50 <= np.isfinite(want[0]).sum() < fitted.sum()  # some measures kept, some removed by the rules
    assert len(np.unique(want[1][np.isfinite(want[1])])) >= 2  # confidences on both sides of 1
