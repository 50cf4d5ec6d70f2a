"""Beyond-the-paper model-fit switches: the noise-aware residual test (``fit_residual_noise``;
in the robust preset with ``relaxed_fit_weight``, see tests/test_relaxed_fit_confidence.py) and the fit
scale tied to the detector's σ2 (``fit_scale_ratio``; off in every preset)."""

import dataclasses
import math

import numpy as np
import pytest

from method.blur.estimators import estimate_blur
from method.blur.model_fit import model_fit_diagnostics, fit_scales
from method.blur.model_fit_checked import noise_residual_share, steered_second_noise_variance
from method.edges.elder_zucker import detect_edges
from method.edges.gaussian_derivatives import GaussianDerivativeBank, steer_second
from method.params import DefocusParams
from scenes.analytic import step_edge

ROBUST = DefocusParams.preset("robust")


@pytest.mark.parametrize("sigma2", [0.5, 1.0, 2.0, 4.0])
def test_noise_variance_matches_filtered_white_noise(sigma2):
    """v_n(σ2) is the variance of the harness's own steered 2nd-derivative filter applied to white noise."""
    rng = np.random.default_rng(3)
    noise = rng.normal(0.0, 0.01, (384, 384))
    ixx, ixy, iyy = GaussianDerivativeBank(noise, 8.0).hessian(sigma2)
    inner = (slice(40, -40), slice(40, -40))
    thetas = np.linspace(0, np.pi, 12, endpoint=False)
    measured = np.mean([np.var(steer_second(ixx, ixy, iyy, t)[inner]) for t in thetas])
    want = float(steered_second_noise_variance(sigma2, 0.01))
    assert abs(measured / want - 1) < 0.05
    if sigma2 >= 1.0:  # the continuous formula 3 s_n² / (16 π σ2⁶)
        assert abs(want / (3 * 0.01 ** 2 / (16 * math.pi * sigma2 ** 6)) - 1) < 5e-3


def test_noise_variance_shapes_and_nan():
    s = np.array([[1.0, np.nan], [2.0, 0.0]])
    v = steered_second_noise_variance(s, 0.5)
    assert v.shape == s.shape and np.isnan(v[0, 1]) and np.isnan(v[1, 1])
    assert v[0, 0] / v[1, 0] == pytest.approx(2.0 ** 6, rel=0.01)  # ∝ σ2⁻⁶ for σ2 ≥ 1


@pytest.mark.parametrize("sigma", [2.0, 6.0])
def test_noise_share_predicts_the_residual_the_noise_adds(sigma):
    """ρ(noisy) − ρ(clean) at the same edge pixels is of the order of the predicted share N·v_n/‖r‖².

    The share is an upper estimate: the least-squares fit absorbs part of the (spatially correlated)
    noise, more so in short windows (measured median ratio 0.43 at σ 2, 0.73 at σ 6). A variance off by
    a factor of 3 either way, or taken at the detector's σ2 instead of the fitted one, fails the test.
    """
    noise = 2.5 / 255
    ratios = []
    for i, a in enumerate(math.radians(x) for x in (0, 33, 71)):
        clean = step_edge((96, 96), sigma=sigma, angle=a, offset=0.21)
        noisy = step_edge((96, 96), sigma=sigma, angle=a, offset=0.21, noise_std=noise, rng=40 + i)
        em = detect_edges(noisy.image)
        inner = np.zeros(em.edges.shape, bool)
        inner[16:-16, 16:-16] = True
        sel = em.edges & inner & (np.abs(noisy.edge_distance) < 1.0)
        p = ROBUST.replace(noise_std=noise)
        dn = model_fit_diagnostics(noisy.image, em, params=p)
        dc = model_fit_diagnostics(clean.image, em, params=p)
        share = noise_residual_share(dc, noise_std=noise)
        ok = sel & np.isfinite(dn["residual"]) & np.isfinite(dc["residual"]) & (share > 0)
        ratios.append((dn["residual"][ok] - dc["residual"][ok]) / share[ok])
    r = np.concatenate(ratios)
    assert r.size > 50
    med = float(np.median(r))
    print(f"\nσ {sigma}: median (ρ_noisy − ρ_clean) / share = {med:.2f} over {r.size} px")
    assert 0.3 < med < 1.2


def test_noise_share_is_zero_where_not_fitted():
    d = {"window": np.array([0, 9]), "sigma2": np.array([np.nan, 2.0]), "energy": np.array([np.nan, 1e-6])}
    s = noise_residual_share(d, noise_std=0.01)
    assert s[0] == 0.0 and s[1] == pytest.approx(9 * float(steered_second_noise_variance(2.0, 0.01)) / 1e-6)


def test_residual_noise_allowance_keeps_noisy_blurry_steps_at_their_sigma():
    """σ 6 steps with noise 2.5/255 + 8 bits: the allowance keeps more measures, still at σ (±5 %)."""
    kept = {0.0: [], 2.0: []}
    for i, a in enumerate(math.radians(x) for x in (0, 33, 71, 128)):
        sc = step_edge((96, 96), sigma=6.0, angle=a, offset=0.21, noise_std=2.5 / 255, quantize_bits=8, rng=7 + i)
        em = detect_edges(sc.image)
        inner = np.zeros(em.edges.shape, bool)
        inner[16:-16, 16:-16] = True
        sel = em.edges & inner & (np.abs(sc.edge_distance) < 1.5)
        for k in kept:
            kept[k].append(estimate_blur(sc.image, em, params=ROBUST.replace(fit_residual_noise=k))[sel])
    base, relaxed = (np.concatenate(kept[k]) for k in (0.0, 2.0))
    assert np.isfinite(relaxed).sum() >= np.isfinite(base).sum()
    # only ever adds measures: every measure of k = 0 is unchanged
    both = np.isfinite(base)
    np.testing.assert_array_equal(relaxed[both], base[both])
    assert abs(np.median(relaxed[np.isfinite(relaxed)]) - 6.0) <= 0.05 * 6.0


def test_residual_noise_off_is_the_fixed_limit():
    """k = 0: exactly the measures with ρ ≤ fit_max_residual (σ unchanged); k = 2 only adds measures."""
    sc = step_edge((64, 64), sigma=3.0, angle=0.4, noise_std=2 / 255, quantize_bits=8, rng=1)
    em = detect_edges(sc.image, keep_hessians=True)
    off = ROBUST.replace(fit_residual_noise=0.0)
    a = estimate_blur(sc.image, em, params=off)
    rho = model_fit_diagnostics(sc.image, em, params=off)["residual"]
    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal(np.isfinite(a), em.edges & (rho <= off.fit_max_residual) & np.isfinite(a))
    b = estimate_blur(sc.image, em, params=ROBUST)
    np.testing.assert_array_equal(b[np.isfinite(a)], a[np.isfinite(a)])
    assert np.isfinite(b).sum() >= np.isfinite(a).sum()


def test_fit_scales_mapping():
    sc = step_edge((64, 64), sigma=1.0, angle=0.3)
    em = detect_edges(sc.image)
    assert fit_scales(em, params=DefocusParams()) is em  # the paper: the detector's σ2
    s2 = np.array([[0.5, 1.0, 2.0, 4.0, 8.0, np.nan]])
    fake = dataclasses.replace(em, sigma2=s2)
    got = fit_scales(fake, params=DefocusParams(fit_scale_ratio=0.5)).sigma2
    np.testing.assert_array_equal(got[0, :5], [0.5, 0.5, 1.0, 2.0, 4.0])
    assert np.isnan(got[0, 5])
    got = fit_scales(fake, params=DefocusParams(fit_scale_ratio=0.5, fit_max_scale=2.0)).sigma2
    np.testing.assert_array_equal(got[0, :5], [0.5, 0.5, 1.0, 2.0, 2.0])
    got = fit_scales(fake, params=DefocusParams(fit_max_scale=2.0)).sigma2  # the robust rule alone
    np.testing.assert_array_equal(got[0, :5], [0.5, 1.0, 2.0, 2.0, 2.0])


@pytest.mark.parametrize("sigma", [1.0, 3.0])
def test_fit_scale_ratio_recovers_step_sigma(sigma):
    """With fit_scale_ratio 0.5 the fit samples a finer response and still recovers σ (±5 %)."""
    errs, used = [], []
    p = ROBUST.replace(fit_scale_ratio=0.5)
    for i, a in enumerate(math.radians(x) for x in (0, 33, 71, 128)):
        sc = step_edge((80, 80), sigma=sigma, angle=a, offset=0.21, noise_std=1 / 255, quantize_bits=8, rng=100 + i)
        em = detect_edges(sc.image)
        inner = np.zeros(em.edges.shape, bool)
        inner[12:-12, 12:-12] = True
        sel = em.edges & inner & (np.abs(sc.edge_distance) < 1.5)
        errs.append(estimate_blur(sc.image, em, params=p)[sel] - sigma)
        used.append(model_fit_diagnostics(sc.image, em, params=p)["sigma2"][sel] / em.sigma2[sel])
    e = np.concatenate(errs)
    assert np.mean(np.isfinite(e)) > 0.8
    assert np.median(np.abs(e[np.isfinite(e)])) <= 0.05 * sigma
    u = np.concatenate(used)
    assert np.all(u[np.isfinite(u)] <= 1.0) and np.any(u[np.isfinite(u)] < 1.0)  # a finer scale was used


@pytest.mark.parametrize("field, bad", [("fit_residual_noise", [-1.0, math.inf, math.nan]),
                                        ("fit_scale_ratio", [0.0, -0.5, 1.5, math.nan])])
def test_fields_validated(field, bad):
    for v in bad:
        with pytest.raises(ValueError, match=field):
            DefocusParams(**{field: v})


def test_fields_in_the_presets():
    for name in ("paper", "zhuo_sim"):
        p = DefocusParams.preset(name)
        assert p.fit_residual_noise == 0.0 and p.fit_scale_ratio == 1.0 and p.relaxed_fit_weight == 1.0
    r = DefocusParams.preset("robust")
    assert r.fit_residual_noise == 2.0 and r.fit_scale_ratio == 1.0
    assert r.measure_weighting == "uncertainty" and r.relaxed_fit_weight == 1.0  # the hand weight unused
