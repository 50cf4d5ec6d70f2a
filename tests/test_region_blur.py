"""Region (spectral) blur estimators: known σ in → σ out, no measure without texture, bad options, oracles.

Tolerances (measured on 256² dead leaves, 8 bits + noise 1/255 and 2/255, seeds 0–1,
raw per-window estimates before any fusion, docs/region-blur.md): Gaussian median error +0.19 px at
σ 1 (the dead leaves' own ≈ 0.5 px roll-off in quadrature), +0.14 px at σ 2, ≤ 0.04 px at σ 3–4,
−0.20 px at σ 6, −0.57 px at σ 8; disk median error ≤ 0.07 px for σ 1–6. The tolerances below allow
about 1.5–3× that on the smaller test images.
"""

import numpy as np
import pytest
from scipy.ndimage import convolve

import method.blur.local_spectrum as bls
import method.blur.spectrum_model as bsm
from method import PRESETS, DefocusParams
from method.blur.region_estimators import REGION_ESTIMATORS, estimate_region_blur
from scenes.analytic import dead_leaves, degrade

#: |median σ̂ − σ| allowed on the Gaussian dead leaves, px: max(GAUSS_TOL_PX, GAUSS_TOL_REL · σ).
GAUSS_TOL_PX = 0.3
GAUSS_TOL_REL = 0.1
#: |median σ̂ − σ| allowed on the disk-blurred dead leaves with the disk model, px (measured ≤ 0.07 at σ 1–6).
DISK_TOL_PX = 0.25
#: Largest share of windows measured on a noise-only image (measured: 0).
NOISE_ONLY_MAX_MEASURED = 0.02


def _leaves(sigma, *, noise=1.0 / 255, seed=0, size=192):
    img = dead_leaves((size, size), sigma=sigma, rng=seed)
    return degrade(img, noise_std=noise, quantize_bits=8, rng=seed + 1)


def _disk_kernel(sigma):
    """Disk of radius R = 2·√(σ² − 1/12) integrated over each 1-px box (8× supersampled), normalised."""
    radius = 2.0 * np.sqrt(sigma ** 2 - 1.0 / 12.0)
    ss, half = 8, int(np.ceil(radius + 1))
    x = (np.arange(-half * ss, (half + 1) * ss) + 0.5) / ss - 0.5
    xx, yy = np.meshgrid(x, x)
    k = (xx ** 2 + yy ** 2 <= radius ** 2).astype(float)
    n = 2 * half + 1
    k = k[:n * ss, :n * ss].reshape(n, ss, n, ss).sum((1, 3))
    return k / k.sum()


@pytest.mark.parametrize("sigma,size", [(1.0, 192), (2.0, 192), (4.0, 192), (6.0, 256), (8.0, 256)])
def test_local_spectrum_recovers_gaussian_sigma_on_dead_leaves(sigma, size):
    params = DefocusParams(region_estimator="local_spectrum")
    s, info = estimate_region_blur(_leaves(sigma, size=size), params=params)
    assert s.shape == (size, size) and info.shape == (size, size)
    assert np.mean(np.isfinite(s)) > 0.9
    assert abs(np.nanmedian(s) - sigma) <= max(GAUSS_TOL_PX, GAUSS_TOL_REL * sigma)
    assert np.all(info[np.isfinite(s)] > 0) and np.all(info[np.isnan(s)] == 0)


def test_estimate_orders_blur_levels():
    params = DefocusParams(region_estimator="local_spectrum")
    med = [np.nanmedian(estimate_region_blur(_leaves(sg), params=params)[0]) for sg in (1.0, 2.0, 3.0)]
    assert med[0] < med[1] < med[2]


@pytest.mark.parametrize("sigma", [2.0, 4.0])
def test_disk_model_recovers_disk_blur_in_the_harness_convention(sigma):
    sharp = dead_leaves((192, 192), sigma=0.0, rng=3)
    img = degrade(convolve(sharp, _disk_kernel(sigma), mode="reflect"), noise_std=1.0 / 255, quantize_bits=8, rng=4)
    s, _ = estimate_region_blur(img, params=DefocusParams(region_estimator="local_spectrum", region_psf="disk"))
    assert abs(np.nanmedian(s) - sigma) <= DISK_TOL_PX


def test_disk_model_floor_is_the_pixel_box():
    grid = bls.sigma_grid(0.0, 12.0, "disk")
    assert grid[0] == pytest.approx(1.0 / np.sqrt(12.0))


def test_edges_psf_follows_the_edge_fit():
    img = _leaves(3.0, size=128)
    p = DefocusParams(region_estimator="local_spectrum", region_psf="edges")
    s_edges_disk, _ = estimate_region_blur(img, params=p, edge_psf="disk")
    s_disk, _ = estimate_region_blur(img, params=p.replace(region_psf="disk"))
    s_edges_none, _ = estimate_region_blur(img, params=p)
    s_gauss, _ = estimate_region_blur(img, params=p.replace(region_psf="gaussian"))
    np.testing.assert_array_equal(s_edges_disk, s_disk)
    np.testing.assert_array_equal(s_edges_none, s_gauss)
    assert not np.array_equal(s_disk, s_gauss, equal_nan=True)


@pytest.mark.parametrize("name", sorted(REGION_ESTIMATORS))
def test_flat_image_has_no_measure(name):
    s, info = estimate_region_blur(np.full((96, 96), 0.5), params=DefocusParams(region_estimator=name))
    assert np.all(np.isnan(s)) and np.all(info == 0)


@pytest.mark.parametrize("name", sorted(REGION_ESTIMATORS))
def test_noise_only_image_has_no_measure(name):
    rng = np.random.default_rng(5)
    img = np.clip(np.round((0.5 + rng.normal(0, 2.0 / 255, (128, 128))) * 255) / 255, 0, 1)
    s, info = estimate_region_blur(img, params=DefocusParams(region_estimator=name))
    assert np.mean(np.isfinite(s)) <= NOISE_ONLY_MAX_MEASURED
    # the same noise on texture is measured: the verdict has two sides
    s2, _ = estimate_region_blur(np.clip(img - 0.5 + _leaves(2.0, noise=0.0, size=128), 0, 1),
                                 params=DefocusParams(region_estimator=name))
    assert np.mean(np.isfinite(s2)) > 0.9


def test_information_falls_as_noise_rises():
    params = DefocusParams(region_estimator="local_spectrum")
    info = [np.median(estimate_region_blur(_leaves(2.0, noise=n / 255), params=params)[1]) for n in (0.5, 2.0, 6.0)]
    assert info[0] > info[1] > info[2] > 0


def test_gsm_variant_recovers_sigma():
    s, _ = estimate_region_blur(_leaves(3.0), params=DefocusParams(region_estimator="gsm"))
    assert abs(np.nanmedian(s) - 3.0) <= max(GAUSS_TOL_PX, GAUSS_TOL_REL * 3.0)


def test_spectrum_or_white_noise_model_recovers_sigma():
    params = DefocusParams(region_estimator="local_spectrum", region_noise_model="spectrum_or_white")
    s, _ = estimate_region_blur(_leaves(3.0), params=params)
    assert abs(np.nanmedian(s) - 3.0) <= max(GAUSS_TOL_PX, GAUSS_TOL_REL * 3.0)


def test_spectrum_noise_model_recovers_small_sigma():
    # measured: on dead leaves the image's own floor over-reads the noise at low frequencies when
    # the blur is large (σ 3 → 0.44 px median on 256², docs/region-blur.md); at σ 1 it is accurate
    params = DefocusParams(region_estimator="local_spectrum", region_noise_model="spectrum")
    s, _ = estimate_region_blur(_leaves(1.0), params=params)
    assert abs(np.nanmedian(s) - 1.0) <= GAUSS_TOL_PX


def test_noise_variance_estimate():
    rng = np.random.default_rng(0)
    for std in (1.0 / 255, 3.0 / 255):
        img = 0.5 + rng.normal(0, std, (256, 256))
        assert np.sqrt(bls.estimate_noise_variance(img, bits=None)) == pytest.approx(std, rel=0.1)
    # on blurred texture the quietest blocks still read the noise
    assert np.sqrt(bls.estimate_noise_variance(_leaves(2.0, noise=2.0 / 255, size=256))) == pytest.approx(2.0 / 255, rel=0.15)
    assert bls.estimate_noise_variance(np.full((64, 64), 0.5)) == pytest.approx(bls.LSB ** 2 / 12)


# --- oracles for the fast kernels -------------------------------------------------------------------

def test_ring_powers_match_a_per_window_loop():
    img = _leaves(2.0, size=96)
    z = bls._gradient_field(img)
    gx, gy = z.real.astype(np.float64), z.imag.astype(np.float64)
    n = 16
    ys, xs = np.array([0, 10, 79]), np.array([5, 40, 79])
    fast = bls._ring_powers(z, ys, xs, n)
    w = bsm.hann_window(n)
    k = np.fft.fftfreq(n) * n
    for i, (y, x) in enumerate(zip(ys, xs)):
        px = np.abs(np.fft.fft2(w * gx[y:y + n, x:x + n])) ** 2 + np.abs(np.fft.fft2(w * gy[y:y + n, x:x + n])) ** 2
        ring = np.zeros(fast.shape[1])
        for a in range(n):
            for b in range(n):
                r = int(round(np.hypot(k[a], k[b])))
                if r > 0:
                    ring[r - 1] += px[a, b]
        np.testing.assert_allclose(fast[i], ring, rtol=2e-4, atol=1e-9)


def test_windowed_expectation_matches_direct_double_sum():
    n, L = 6, 32
    wv = 2 * np.pi * np.fft.fftfreq(L)
    spec = np.exp(-(1.3 ** 2) * (wv[None] ** 2 + wv[:, None] ** 2)) + 0.1
    fast = bsm._windowed_expectation(spec, n)
    acf = np.real(np.fft.ifft2(spec))  # R at integer lags (mod L)
    w = bsm.hann_window(n)
    slow = np.zeros((n, n))
    pos = [(a, b) for a in range(n) for b in range(n)]
    for ka in range(n):
        for kb in range(n):
            tot = 0j
            for (a, b) in pos:
                for (c, d) in pos:
                    ph = np.exp(-2j * np.pi * (ka * (a - c) + kb * (b - d)) / n)
                    tot += w[a, b] * w[c, d] * acf[(a - c) % L, (b - d) % L] * ph
            slow[ka, kb] = tot.real
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-12)


def test_fit_matches_a_per_window_brute_force_likelihood():
    from scipy.optimize import minimize_scalar

    img = _leaves(2.5, size=96)
    z = bls._gradient_field(img)
    n = 24
    grid = tuple(float(x) for x in bls.sigma_grid(0.0, 12.0, "gaussian"))
    A, dA, Nu, kappa = bsm.model_tables(n, "gaussian", grid)
    ys = xs = np.array([0, 30, 60])
    P = bls._ring_powers(z, ys, xs, n).astype(np.float64)
    v = bls.estimate_noise_variance(img)
    N = np.broadcast_to(v * Nu, P.shape)
    j, s, *_ = bls._fit(P.astype(np.float32), A.astype(np.float32), N.astype(np.float32), kappa.astype(np.float32))
    for i in range(len(ys)):
        def nll_at(g):
            def f(logs):
                m = np.exp(logs) * A[g] + N[i]
                return np.sum(kappa * (P[i] / m + np.log(m)))
            return minimize_scalar(f, bounds=(-40, 10), method="bounded", options={"xatol": 1e-8}).fun
        slow = np.array([nll_at(g) for g in range(len(grid))])
        assert abs(int(np.argmin(slow)) - int(j[i])) <= 1
        assert slow[j[i]] - slow.min() < 0.05


# --- options ------------------------------------------------------------------------------------

def test_paper_preset_has_no_region_estimator():
    assert PRESETS["paper"].region_estimator is None and DefocusParams().region_estimator is None


@pytest.mark.parametrize("field,value,allowed", [
    ("region_estimator", "nope", "local_spectrum"),
    ("region_noise_model", "pink", "spectrum_or_white"),
    ("region_psf", "box", "edges"),
    ("region_window_min", 8, "16"),
    ("region_window_max", 16.5, "16"),
    ("region_window_scale", 0.0, "> 0"),
    ("region_sigma_max", -1.0, "region_sigma_min < region_sigma_max"),
    ("region_stride", 0, ">= 1"),
])
def test_bad_region_options_raise_naming_allowed_values(field, value, allowed):
    with pytest.raises(ValueError, match=f"{field}.*allowed.*{allowed}"):
        DefocusParams(**{field: value})


def test_bad_calls_raise():
    img = _leaves(2.0, size=64)
    with pytest.raises(ValueError, match="local_spectrum"):
        estimate_region_blur(img, params=DefocusParams())  # region_estimator None
    with pytest.raises(ValueError, match="edge_psf.*gaussian"):
        estimate_region_blur(img, params=DefocusParams(region_estimator="local_spectrum"), edge_psf="box")
    with pytest.raises(ValueError, match="HxW"):
        estimate_region_blur(np.zeros(64), params=DefocusParams(region_estimator="local_spectrum"))
    with pytest.raises(ValueError, match="17x17"):
        estimate_region_blur(np.zeros((8, 64)), params=DefocusParams(region_estimator="local_spectrum"))


def test_colour_input_uses_luminance():
    img = _leaves(2.0, size=96)
    p = DefocusParams(region_estimator="local_spectrum")
    s_grey, _ = estimate_region_blur(img, params=p)
    s_rgb, _ = estimate_region_blur(np.repeat(img[..., None], 3, axis=2), params=p)
    np.testing.assert_allclose(s_rgb, s_grey, rtol=1e-6, equal_nan=True)


def test_information_density_sums_to_one_window_per_block():
    img = _leaves(2.0, size=128)
    p = DefocusParams(region_estimator="local_spectrum", region_stride=16)
    grid = bls.local_spectrum_grid(img, stride=16, window_scale=p.region_window_scale)
    s, info = estimate_region_blur(img, params=p)
    cy, cx = grid["cy"], grid["cx"]
    # at a window centre the bilinear spread is that window's own value, divided by stride²
    np.testing.assert_allclose(s[np.ix_(cy, cx)], grid["sigma"], rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(info[np.ix_(cy, cx)] * 16 ** 2, grid["information"], rtol=1e-12)


# --- under lens blur: the disk model and the adequacy gate --------------------------------------
#: The gated disk model on lens mosaics (disk PSF in linear light, ISO 100, sRGB, 8 bits; one 3×2 mosaic
#: of 128-px tiles, σ 1–6): measured (benchmarks/region_gate.py, 2 seeds, 6 tiles) dead leaves 60 % of
#: windows kept at median +1 %, photos 34 % at +1 %, smooth shading 4 %.
GATED = dict(region_estimator="local_spectrum", region_psf="disk", region_gate="adequacy")
LENS_SIGMAS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
GATED_MAX_REL_MEDIAN = 0.05  # |median relative error| of the measured windows, dead leaves and photos
GATED_MIN_SHARE = 0.2
SHADING_MAX_SHARE = 0.1  # gated; ungated it measures everywhere, at +100 % and more


def _lens_case(family, seed=0):
    from scenes.analytic.lens import lens_mosaic

    m = lens_mosaic(family=family, psf="disk", sigmas=LENS_SIGMAS, tile=128, cols=3, noise="iso100", rng=seed)
    return m, ~m.boundary


def _region_rel(m, inner, **changes):
    s, _ = estimate_region_blur(m.image, params=DefocusParams.preset("robust", **changes))
    ok = inner & np.isfinite(s)
    return ok.sum() / inner.sum(), (s[ok] - m.sigma[ok]) / m.sigma[ok]


@pytest.mark.parametrize("family", ["dead_leaves", "photo"])
def test_gated_disk_model_reads_lens_blur_where_it_measures(family):
    m, inner = _lens_case(family)
    share, rel = _region_rel(m, inner, **GATED)
    assert share >= GATED_MIN_SHARE and abs(np.median(rel)) <= GATED_MAX_REL_MEDIAN, (share, np.median(rel))
    # the Gaussian model reads the same lens blur far too small (its transfer function has no sidelobes)
    _, rel_g = _region_rel(m, inner, region_estimator="local_spectrum", region_psf="gaussian")
    assert np.median(rel_g) < -0.2


def test_gate_says_no_measure_on_smooth_shading():
    m, inner = _lens_case("shading")
    share, _ = _region_rel(m, inner, **GATED)
    assert share <= SHADING_MAX_SHARE
    share_u, rel_u = _region_rel(m, inner, region_estimator="local_spectrum", region_psf="disk")
    assert share_u > 0.9 and np.median(rel_u) > 1.0  # without the gate: a confident wrong number


@pytest.mark.render
@pytest.mark.parametrize("scene,f_number", [("portrait", 8.0), ("street_figures", 4.0)])
def test_gated_disk_model_on_a_thin_lens_render(scene, f_number):
    """Small Mitsuba thin-lens renders (disk blur in linear light, sRGB, 8 bits): where the gated cue
    measures, its median relative error is within 10 % (measured +1.4 % / +2.7 %). It does not hold
    everywhere: docs/region-blur.md lists the renders where it misses."""
    from experiments.evaluation import ground_truth_sigma, input_image
    from scenes import render_scene

    r = render_scene(scene, preset="small", f_number=f_number, progress=False)
    gt = ground_truth_sigma(r)
    s, _ = estimate_region_blur(input_image(r), params=DefocusParams.preset("robust", **GATED))
    ok = np.isfinite(s) & np.isfinite(gt) & ~r.occlusion_boundary
    assert ok.mean() > 0.03
    assert abs(np.median((s[ok] - gt[ok]) / gt[ok])) <= 0.10
