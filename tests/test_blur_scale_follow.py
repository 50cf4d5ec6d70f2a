"""The model fit's scale and window following a coarse estimate (``fit_follow_scale``): large blur measured."""

import numpy as np
import pytest

from method.blur.fit_templates import FIT_KAPPA
from method.blur.scale_follow import FOLLOW_WINDOW_SPAN, follow_window_max
from method.luma import measure_luminance
from method.params import DefocusParams
from method.pipeline import blur_stage, edges_stage
from scenes.analytic.lens import lens_step_edge
from tests import tolerances as tol

ROBUST = DefocusParams.preset("robust")
#: the robust preset's fit without the re-fit, and with it (the detector's σ2 reaching 16 px so that
#: steps of σ 12–16 px are detected at all)
WITHOUT = ROBUST.replace(fit_follow_scale=None)
FOLLOW = ROBUST.replace(sigma2_scales=(0.5, 1.0, 2.0, 4.0, 8.0, 16.0), fit_follow_scale=0.5,
                        fit_follow_max_residual=1.0)
#: the same with the residual guard: only coarse fits and re-fits with ρ ≤ 0.02 count
GUARDED = FOLLOW.replace(fit_follow_max_residual=0.02)


def _step_measures(sigma, params, *, seed=0, angle=0.4):
    """Sparse σ (px) at detected edge pixels within max(2, σ/2) px of an isolated disk step, in linear light."""
    n = 256 if sigma <= 8 else 320
    e = lens_step_edge((n, n), sigma=sigma, psf="disk", angle=angle, noise="iso100", quantize_bits=8, rng=seed)
    near = np.abs(e.edge_distance) < max(2.0, sigma / 2)
    near[:40], near[-40:], near[:, :40], near[:, -40:] = False, False, False, False
    gray = measure_luminance(e.image, params.measure_light)
    edges = edges_stage(gray, params=params)
    return blur_stage(gray, edges, params=params)[0][near & edges.edges]


@pytest.mark.parametrize("guard", [1.0, 0.02])
@pytest.mark.parametrize("sigma", [12.0, 16.0])
def test_follow_scale_recovers_large_disk_blur(sigma, guard):
    """With and without the residual guard: a blurred step's coarse fit and re-fit have ρ ≤ 0.005."""
    sparse = _step_measures(sigma, FOLLOW.replace(fit_follow_max_residual=guard))
    ok = np.isfinite(sparse)
    assert sparse.size > 100 and ok.mean() >= tol.LARGE_BLUR_MIN_COVERAGE, ok.mean()
    assert abs(np.median(sparse[ok]) - sigma) <= tol.LARGE_BLUR_MAX_REL_MEDIAN * sigma, np.median(sparse[ok])
    # without the re-fit the same edges are detected but measured at σ2 ≤ 2 px: mostly declined, and
    # what remains is far too small
    before = _step_measures(sigma, FOLLOW.replace(fit_follow_scale=None))
    good = np.isfinite(before)
    assert good.mean() < 0.5 or np.median(before[good]) < 0.5 * sigma


@pytest.mark.parametrize("guard", [1.0, 0.02])
def test_follow_scale_fixes_sigma_8_without_the_coarser_detector_scale(guard):
    """σ 8 is detected at σ2 ≤ 8 already: the re-fit alone lifts coverage and removes the bias."""
    sparse = _step_measures(8.0, WITHOUT.replace(fit_follow_scale=0.5, fit_follow_max_residual=guard))
    ok = np.isfinite(sparse)
    assert ok.mean() >= tol.LARGE_BLUR_MIN_COVERAGE and abs(np.median(sparse[ok]) - 8.0) <= 0.4
    before = _step_measures(8.0, WITHOUT)
    good = np.isfinite(before)
    assert good.mean() < 0.8 and np.median(before[good]) < 6.0  # measured 0.57, −4.7 px


@pytest.mark.parametrize("sigma", [1.0, 2.0, 4.0])
def test_small_blur_measures_unchanged(sigma):
    """Steps the first fit resolves keep their measure bit for bit (today's errors: |median| ≤ 0.03 px)."""
    for seed, angle in ((0, 0.4), (1, 1.1)):
        without = _step_measures(sigma, WITHOUT, seed=seed, angle=angle)
        for follow in (_step_measures(sigma, FOLLOW, seed=seed, angle=angle),
                       _step_measures(sigma, GUARDED, seed=seed, angle=angle)):
            assert np.array_equal(follow, without, equal_nan=True)
        ok = np.isfinite(follow)
        assert ok.mean() >= 0.95 and abs(np.median(follow[ok]) - sigma) <= 0.05


def test_guard_keeps_in_focus_texture_measures():
    """On in-focus texture (a σ ≤ 4 dead-leaves mosaic, display light) the coarse fit at σ2(p) = 4–8 px is
    widened by neighbouring edges (ρ 0.03–0.24): unguarded, the re-fit replaces some first-fit measures;
    guarded (ρ ≤ 0.02), the sparse map is the one without the re-fit, bit for bit."""
    from method import estimate_defocus_map
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(tile=48, sigmas=(0.5, 1.0, 2.0, 4.0), cols=4, noise_std=1.0 / 255, quantize_bits=8, rng=1)
    base = WITHOUT.replace(measure_light="display")
    sparse = {g: estimate_defocus_map(m.image, base.replace(fit_follow_scale=0.5, fit_follow_max_residual=g)).sparse_sigma
              for g in (1.0, 0.02)}
    off = estimate_defocus_map(m.image, base).sparse_sigma
    assert not np.array_equal(sparse[1.0], off, equal_nan=True)  # the unguarded re-fit acts here (seed 1)
    assert np.array_equal(sparse[0.02], off, equal_nan=True)


def test_follow_window_max():
    assert follow_window_max(8.0, 0.5, 71) == 2 * int(np.ceil(FIT_KAPPA * FOLLOW_WINDOW_SPAN * 16.0)) + 1
    assert follow_window_max(0.5, 1.0, 71) == 71  # never below the first fit's window
    assert follow_window_max(8.0, 0.5, 71) % 2 == 1


@pytest.mark.parametrize("bad", [0.0, -0.5, 1.5, float("nan")])
def test_fit_follow_scale_validated(bad):
    with pytest.raises(ValueError, match="fit_follow_scale"):
        DefocusParams(fit_follow_scale=bad)


@pytest.mark.parametrize("bad", [-0.01, 1.5, float("nan")])
def test_fit_follow_max_residual_validated(bad):
    with pytest.raises(ValueError, match="fit_follow_max_residual"):
        DefocusParams(fit_follow_max_residual=bad)
    assert DefocusParams(fit_follow_max_residual=0.0).fit_follow_max_residual == 0.0


def test_guard_of_zero_keeps_no_refit():
    """ρf = 0 admits no fit (every noisy fit has ρ > 0): the σ 8 step keeps the first fit's measures exactly."""
    zero = _step_measures(8.0, WITHOUT.replace(fit_follow_scale=0.5, fit_follow_max_residual=0.0))
    assert np.array_equal(zero, _step_measures(8.0, WITHOUT), equal_nan=True)


def test_paper_has_it_off():
    assert DefocusParams().fit_follow_scale is None
    assert DefocusParams().fit_follow_max_residual == 1.0


def test_large_lens_grid_and_its_flags():
    from experiments.bench import lens
    from tests.cli_run import run_in_process

    cfg = lens.lens_config(grid="large")
    assert cfg["sigmas"] == (8.0, 12.0, 16.0) and cfg["tile"] > lens.LENS_CONFIG["tile"] and not cfg["regions"]
    assert lens.lens_config(grid="large", psfs=["disk"])["psfs"] == ("disk",)
    assert lens.lens_config(grid="default") == lens.lens_config()
    with pytest.raises(ValueError, match="grid='huge' is invalid; allowed: default, full, tones, large"):
        lens.lens_config(grid="huge")
    for argv, text in ((["--accuracy", "--grid", "huge"], "allowed: default, full, tones, large"),
                       (["--grid", "large"], "--grid goes with --accuracy"),
                       (["--accuracy", "--full", "--grid", "large"], "exclude each other")):
        r = run_in_process("repro.bench", argv)
        assert r.returncode == 2 and text in r.stderr and r.stderr.count("\n") == 1, (argv, r.stderr)


def test_nearest_scale_matches_a_plain_broadcast_over_every_pixel():
    """The edge-pixel-only lookup equals the obvious whole-array nearest-in-log-scale oracle (NaN, 0, < 0, inf)
    and gives exactly the listed scales."""
    from method.blur.scale_follow import _nearest_scale

    def oracle(values, scales):
        grid = np.log(np.asarray(sorted(scales), dtype=np.float64))
        with np.errstate(invalid="ignore", divide="ignore"):
            logv = np.log(np.asarray(values, dtype=np.float64))
        ok = np.isfinite(logv)
        idx = np.argmin(np.abs(np.where(ok, logv, 0.0)[..., None] - grid), axis=-1)
        return np.where(ok, np.asarray(sorted(scales), dtype=np.float64)[idx], np.nan)

    rng = np.random.default_rng(0)
    v = rng.uniform(-1, 40, (60, 50))
    v[rng.random(v.shape) < 0.5] = np.nan
    v[0, :5] = [0.0, -2.0, np.inf, 1e-300, 3.0]
    for scales in ((0.5, 1.0, 2.0, 4.0, 8.0), (8.0, 0.5, 16.0)):
        got = _nearest_scale(v, scales)
        np.testing.assert_array_equal(got, oracle(v, scales))
        # the scales themselves (np.exp(np.log(8.0)) is not 8.0): the detector's responses at them serve the re-fit
        assert set(np.unique(got[np.isfinite(got)])) == set(scales)
