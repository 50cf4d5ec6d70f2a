"""The model fit's fast paths against their slow, obviously-correct forms: the same bytes.

The Eq. (2c) template search computes each pass's dot products together
(:func:`method.blur.fit_templates._best_gaussian_template`); the oracle is the one-template-at-a-time
search :func:`method.blur.fit_templates._best_template` (which the disk model still uses).
:func:`method.blur.model_fit_checked.fit_measure_sd` evaluates only the fitted pixels; the oracle is
:func:`method.blur.measure_uncertainty.measure_sd` over every pixel of the image.
"""

import numpy as np
import pytest
from scipy import ndimage

from method import DefocusParams
from method.blur.fit_templates import (COARSE_STRIDE, EMPTY_DISK_TABLE, _best_gaussian_template, _best_template,
                                       template_table)
from method.blur.measure_uncertainty import measure_sd, width_information
from method.blur.model_fit_checked import fit_measure_sd, steered_second_noise_variance
from method.blur.noise_model import noise_variance_map
from method.blur.psf_selection import PSF_SELECT_SAMPLE, psf_selection_sample, select_psf_model
from method.blur.scale_follow import follow_scale_diagnostics
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
