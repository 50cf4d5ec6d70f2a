"""Biased cross-bilateral refinement, Eq. (3): grid vs oracle, bias mechanism, invariants."""

import numpy as np
import pytest

from method.cross_bilateral import BILATERAL_METHODS, biased_cross_bilateral, sharpness_bias
from tests.tolerances import BILATERAL_CONSTANT_ATOL, BILATERAL_GRID_REL_TOL


def _case(rng, h, w, density=0.08, smooth=True):
    ref = rng.random((h, w, 3))
    if smooth:  # photo-like: smooth colour fields plus a sharp region boundary
        yy, xx = np.mgrid[0:h, 0:w]
        ref = 0.5 * ref * 0.2 + 0.4 * (xx > w // 2)[..., None] + 0.3 * np.sin(yy / 7.0)[..., None] ** 2
        ref = np.clip(ref, 0, 1)
    mask = rng.random((h, w)) < density
    mask[0, 0] = True
    bm = np.where(mask, rng.random((h, w)) * 6.0, np.nan)
    return bm, ref


def test_methods_registered():
    assert set(BILATERAL_METHODS) == {"grid", "brute_force"}


@pytest.mark.parametrize("shape", [(24, 31), (64, 64), (90, 120)])
@pytest.mark.parametrize("bias", [True, False])
@pytest.mark.parametrize("sigmas", [(0.10, 0.10), (0.05, 0.05), (0.3, 0.2)])
def test_grid_matches_brute_force(rng, shape, bias, sigmas):
    bm, ref = _case(rng, *shape, smooth=shape[0] != 64)
    kw = dict(sigma_spatial=sigmas[0], sigma_range=sigmas[1], sharpness_bias=bias)
    fast = biased_cross_bilateral(bm, ref, method="grid", **kw)
    slow = biased_cross_bilateral(bm, ref, method="brute_force", **kw)
    edge = np.isfinite(bm)
    assert np.array_equal(np.isfinite(fast), edge) and np.array_equal(np.isfinite(slow), edge)
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.max(np.abs(fast[edge] - slow[edge])) <= BILATERAL_GRID_REL_TOL * span


def test_grey_reference_matches_brute_force(rng):
    bm, ref = _case(rng, 40, 40)
    grey = ref.mean(axis=2)
    fast = biased_cross_bilateral(bm, grey)
    slow = biased_cross_bilateral(bm, grey, method="brute_force")
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.nanmax(np.abs(fast - slow)) <= BILATERAL_GRID_REL_TOL * span


@pytest.mark.parametrize("method", ["grid", "brute_force"])
def test_constant_blur_measure_unchanged(rng, method):
    bm, ref = _case(rng, 50, 40)
    bm = np.where(np.isfinite(bm), 3.25, np.nan)
    out = biased_cross_bilateral(bm, ref, method=method)
    np.testing.assert_allclose(out[np.isfinite(bm)], 3.25, rtol=0, atol=BILATERAL_CONSTANT_ATOL)
    assert np.all(np.isnan(out[~np.isfinite(bm)]))


@pytest.mark.parametrize("method", ["grid", "brute_force"])
def test_bias_pulls_blurry_outlier_down(method):
    """Fig. 5: a blurry outlier among sharp measures of the same colour is pulled towards sharp."""
    h = w = 60
    ref = np.full((h, w, 3), 0.5)
    bm = np.full((h, w), np.nan)
    bm[::4, ::4] = 1.0          # sharp edges
    bm[30, 30] = 8.0            # outlier (e.g. a soft shadow)
    plain = biased_cross_bilateral(bm, ref, sharpness_bias=False, method=method)
    biased = biased_cross_bilateral(bm, ref, sharpness_bias=True, method=method)
    assert biased[30, 30] < plain[30, 30] < 8.0
    assert biased[30, 30] < 1.05   # b(8)/b(1) = e^-3.5: the outlier barely counts
    # and the sharp neighbours are disturbed less with the bias than without
    assert abs(biased[28, 28] - 1.0) < abs(plain[28, 28] - 1.0)


def test_range_weight_respects_colour_edge():
    """Measures across a strong colour edge do not mix (σr = 10 % of range)."""
    h, w = 40, 40
    ref = np.zeros((h, w, 3))
    ref[:, w // 2:] = 1.0
    bm = np.full((h, w), np.nan)
    bm[::3, : w // 2: 3] = 1.0
    bm[::3, w // 2::3] = 5.0
    out = biased_cross_bilateral(bm, ref, sharpness_bias=False)
    np.testing.assert_allclose(out[:, : w // 2][np.isfinite(out[:, : w // 2])], 1.0, atol=1e-6)
    np.testing.assert_allclose(out[:, w // 2:][np.isfinite(out[:, w // 2:])], 5.0, atol=1e-6)


def test_sharpness_bias_values():
    np.testing.assert_allclose(sharpness_bias(np.array([0.0, 2.0, 4.0])), np.exp([0.0, -1.0, -2.0]))
    with pytest.raises(ValueError):
        sharpness_bias(1.0, scale=0)


def test_no_edges_gives_all_nan(rng):
    out = biased_cross_bilateral(np.full((10, 12), np.nan), rng.random((10, 12, 3)))
    assert out.shape == (10, 12) and np.all(np.isnan(out))


@pytest.mark.parametrize("bad", [
    dict(method="nope"), dict(sigma_spatial=0), dict(sigma_range=-1), dict(bias_scale=np.inf)])
def test_bad_options_raise(rng, bad):
    bm, ref = _case(rng, 20, 20)
    with pytest.raises(ValueError):
        biased_cross_bilateral(bm, ref, **bad)


def test_bad_inputs_raise(rng):
    bm, ref = _case(rng, 20, 20)
    with pytest.raises(ValueError, match="shape"):
        biased_cross_bilateral(bm[:10], ref)
    with pytest.raises(ValueError, match=">= 0"):
        biased_cross_bilateral(np.where(np.isfinite(bm), -1.0, np.nan), ref)
    with pytest.raises(ValueError, match="Inf"):
        biased_cross_bilateral(np.where(np.isfinite(bm), np.inf, np.nan), ref)
    bad_ref = ref.copy()
    bad_ref[0, 0, 0] = np.nan
    with pytest.raises(ValueError):
        biased_cross_bilateral(bm, bad_ref)
