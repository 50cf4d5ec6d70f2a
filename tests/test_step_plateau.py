"""The plateau gate of the checked fit (``fit_step_gate``): shading bands are no measure, blurred steps stay."""

import math
import types

import numpy as np
import pytest
from scipy.special import ndtr

from method.blur.estimators import estimate_blur
from method.blur.step_plateau import (GAUSSIAN_STEP_REACH, PLATEAU_FLATNESS, PLATEAU_MIN_SIGMA, STEP_GATES,
                                      gate_step_measures, plateau_profile)
from method.edges.elder_zucker import detect_edges
from method.params import DefocusParams
from scenes.analytic import step_edge
from scenes.analytic.lens import lens_step_edge

ROBUST = DefocusParams.preset("robust")
NO_GATE = ROBUST.replace(fit_step_gate="none")
NOISE = 2.5 / 255
ANGLE = 0.3
SHAPE = (128, 128)


def _distance(shape=SHAPE, angle=ANGLE):
    """Signed distance (px) from the line through the image centre with normal (cos a, sin a)."""
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    return (xx - (shape[1] - 1) / 2) * math.cos(angle) + (yy - (shape[0] - 1) / 2) * math.sin(angle)


def _gate_at_line(image, sigma_b, gate, *, angle=ANGLE, inner=40, reach=1.0):
    """Share of the pixels within 0.5 px of the centre line (away from the borders) the gate keeps,
    given the measure σb there and the line's normal as θ."""
    t = _distance(image.shape, angle)
    line = np.abs(t) < 0.5
    line[:inner], line[-inner:], line[:, :inner], line[:, -inner:] = False, False, False, False
    sb = np.where(line, float(sigma_b), np.nan)
    edge_map = types.SimpleNamespace(theta=np.full(image.shape, angle))
    out = gate_step_measures(image, edge_map, sb, params=ROBUST.replace(fit_step_gate=gate, fit_plateau_reach=reach))
    return np.isfinite(out[line]).mean()


def _noisy(image, seed):
    return np.clip(image + np.random.default_rng(seed).normal(0.0, NOISE, image.shape), 0.0, 1.0)


def _step(psf, sigma, seed):
    if psf == "gaussian":
        return step_edge(SHAPE, sigma=sigma, angle=ANGLE, low=0.1, high=0.5, noise_std=NOISE, rng=seed).image
    img = lens_step_edge(SHAPE, sigma=sigma, psf="disk", angle=ANGLE, low=0.35, high=0.7).image
    return _noisy(img, seed)


def _cosine(period, seed):
    return _noisy(0.3 + 0.15 * np.sin(2 * np.pi * _distance() / period), seed)


@pytest.mark.parametrize("gate", ["plateau", "plateau_flat"])
@pytest.mark.parametrize("psf", ["gaussian", "disk"])
@pytest.mark.parametrize("sigma", [1.0, 2.0, 4.0, 6.0, 8.0])
def test_the_gate_keeps_blurred_steps_at_their_true_sigma(gate, psf, sigma):
    """Every pixel on a Gaussian- or disk-blurred step's edge line, measured at its true σ, is kept (noise
    2.5/255). A reach limit above the Gaussian step's 1.40 or a flatness limit below the Gaussian's 0.19
    (plus the noise) fails here."""
    img = _step(psf, sigma, seed=int(sigma * 10))
    for reach in (ROBUST.fit_plateau_reach, 1.0):  # the preset's limit and the strictest measured
        assert _gate_at_line(img, sigma, gate, reach=reach) == 1.0


@pytest.mark.parametrize("gate", ["plateau", "plateau_flat"])
@pytest.mark.parametrize("period", [12.0, 16.0, 24.0, 32.0])
def test_the_gate_rejects_smooth_periodic_shading_read_as_blur(gate, period):
    """A cosine band read as a blurred step has its extrema at ±σ ≈ P/4 and turns back beyond them: no
    measure at the zero crossing for σb = P/4 (what the fit reads) nor for two thirds of it (below
    that, at P/8, the first plateau samples fall on the crest and a few are kept)."""
    img = _cosine(period, seed=int(period))
    assert _gate_at_line(img, period / 4, gate, reach=ROBUST.fit_plateau_reach) == 0.0
    assert _gate_at_line(img, period / 4, gate, reach=1.0) == 0.0
    assert _gate_at_line(img, period / 6, gate, reach=1.0) <= 0.05


def test_the_flatness_test_rejects_a_shading_ramp_that_keeps_rising_and_plateau_alone_keeps_it():
    """A soft terminator whose lit side is a shading gradient (no plateau: it keeps rising past the edge)
    is no measure for "plateau_flat"; "plateau" only asks that the level be reached, and keeps it."""
    t = _distance()
    img = _noisy(0.15 + 0.1 * ndtr(t / 2.0) + 0.02 * np.clip(t, 0, None), seed=3)
    assert _gate_at_line(img, 2.0, "plateau_flat") == 0.0
    assert _gate_at_line(img, 2.0, "plateau") == 1.0


def test_an_untextured_penumbra_between_two_levels_is_kept_a_blurred_step_is_what_it_is():
    """The limit of any profile test: a linear penumbra between two lit levels is a box-blurred step
    (σ = half-width/√3); both gates keep it."""
    half_width = 6.0
    t = _distance()
    img = _noisy(0.2 + 0.4 * np.clip(0.5 + t / (2 * half_width), 0, 1), seed=4)
    for gate in ("plateau", "plateau_flat"):
        assert _gate_at_line(img, half_width / math.sqrt(3), gate) == 1.0


def test_the_profile_measures_of_a_gaussian_step_and_of_a_cosine():
    """Reach and flatness of a noise-free Gaussian step (σ 4, after the 1-px pre-smoothing) against the
    closed forms of the module's constants; a cosine's reach is negative on both sides."""
    t = _distance()
    rows, cols = np.array([64]), np.array([64])
    x0 = t[64, 64]
    step = ndtr((t - x0) / 4.0)
    reach, flat, evident = plateau_profile(step, rows, cols, np.array([ANGLE]), np.array([4.0]), noise_std=0.0)
    assert evident.all()
    assert reach == pytest.approx(GAUSSIAN_STEP_REACH, abs=0.005) and flat == pytest.approx(0.192, abs=0.005)
    assert reach.min() > ROBUST.fit_plateau_reach and flat.max() < PLATEAU_FLATNESS
    wave = np.sin(2 * np.pi * (t - x0) / 24.0)
    reach, _, evident = plateau_profile(wave, rows, cols, np.array([ANGLE]), np.array([6.0]), noise_std=0.0)
    assert evident.all() and (reach < 0).all()


def test_the_reach_limit_decides_a_profile_that_turns_partly_back():
    """A step (σ 3) whose bright side falls back by half its contrast 2σ beyond the edge has a reach
    between 0.5 and 1: rejected at the default limit 1, kept at 0.5."""
    t = _distance()
    img = _noisy(0.2 + 0.3 * (ndtr(t / 3.0) - 0.5 * ndtr((t - 6.0) / 3.0)), seed=9)
    reach, _, _ = plateau_profile(img, np.array([64]), np.array([64]), np.array([ANGLE]), np.array([3.0]),
                                  noise_std=NOISE)
    assert 0.5 < reach.min() < 1.0
    assert _gate_at_line(img, 3.0, "plateau") == 0.0
    assert _gate_at_line(img, 3.0, "plateau", reach=0.5) == 1.0


def test_a_core_hidden_in_the_noise_is_never_rejected_and_small_measures_are_not_judged():
    """Noise alone (no evidence of a core) and measures below PLATEAU_MIN_SIGMA stay, whatever the profile."""
    flat_noise = _noisy(np.full(SHAPE, 0.3), seed=5)
    assert _gate_at_line(flat_noise, 4.0, "plateau") == 1.0
    img = _cosine(4.0 * 0.9, seed=6)  # a cosine read at σb just below the smallest judged σ
    assert _gate_at_line(img, 0.9 * PLATEAU_MIN_SIGMA, "plateau") == 1.0


def test_none_returns_the_fit_unchanged_and_is_the_paper_s():
    """"none" hands back the very array (so the paper preset is bit-identical to before); robust gates."""
    sb = np.full(SHAPE, 3.0)
    out = gate_step_measures(_cosine(24.0, 7), types.SimpleNamespace(theta=np.zeros(SHAPE)), sb,
                             params=NO_GATE)
    assert out is sb
    assert DefocusParams.preset("paper").fit_step_gate == "none"
    assert ROBUST.fit_step_gate == "plateau" and ROBUST.fit_plateau_reach == 0.5
    assert set(STEP_GATES) == {"none", "plateau", "plateau_flat"}


def test_an_unknown_gate_is_refused_naming_the_allowed_ones():
    with pytest.raises(ValueError, match=r"DefocusParams\.fit_step_gate='nope' is invalid \(unknown step gate\); allowed: 'none', 'plateau', 'plateau_flat'"):
        DefocusParams(fit_step_gate="nope")


@pytest.mark.parametrize("reach, kept_max", [(0.5, 0.03), (1.0, 0.01)])
@pytest.mark.parametrize("period", [24.0, 32.0])
def test_the_robust_fit_with_the_gate_gives_no_measure_on_shading_bands(period, reach, kept_max):
    """End to end (edges, the checked fit, the gate): the robust fit reads cosine bands of period 24 and
    32 px as σ ≈ 5–7 px at hundreds of pixels; with the preset's plateau gate (reach 0.5) at most 3 % of
    those stay (measured 1.9–2.3 %), with the strict reach 1 at most 1 %."""
    img = _cosine(period, seed=8)
    em = detect_edges(img, sigma1_scales=ROBUST.sigma1_scales, sigma2_scales=ROBUST.sigma2_scales,
                      noise_std=ROBUST.noise_std)
    before = estimate_blur(img, em, params=NO_GATE)
    after = estimate_blur(img, em, params=ROBUST.replace(fit_plateau_reach=reach))
    assert np.isfinite(before).sum() > 500 and np.nanmedian(before) > 4.0
    assert np.isfinite(after).sum() <= kept_max * np.isfinite(before).sum()


@pytest.mark.parametrize("sigma", [1.0, 2.0, 4.0, 8.0])
def test_the_robust_fit_with_the_gate_keeps_every_measure_of_a_blurred_step(sigma):
    """End to end on a noisy Gaussian step: the gate removes none of the checked fit's measures."""
    img = _step("gaussian", sigma, seed=11)
    em = detect_edges(img, sigma1_scales=ROBUST.sigma1_scales, sigma2_scales=ROBUST.sigma2_scales,
                      noise_std=ROBUST.noise_std)
    before = estimate_blur(img, em, params=NO_GATE)
    after = estimate_blur(img, em, params=ROBUST)
    assert np.isfinite(before).sum() > 20
    np.testing.assert_array_equal(after, before)
