"""Region (spectral) blur estimators: known σ in → σ out, no measure without texture, bad options."""

import numpy as np
import pytest

from method.params import DefocusParams
from method.region_estimators import REGION_ESTIMATORS, estimate_region_blur
from scenes.analytic import dead_leaves, degrade


def _leaves(sigma, *, noise=1.0 / 255, seed=0, size=192):
    img = dead_leaves((size, size), sigma=sigma, rng=seed)
    return degrade(img, noise_std=noise, quantize_bits=8, rng=seed + 1)


@pytest.mark.parametrize("sigma", [1.0, 3.0])
def test_local_spectrum_recovers_gaussian_sigma_on_dead_leaves(sigma):
    params = DefocusParams(region_estimator="local_spectrum")
    s, info = estimate_region_blur(_leaves(sigma), params=params)
    assert s.shape == (192, 192) and info.shape == (192, 192)
    assert abs(np.nanmedian(s) - sigma) < 0.3 + 0.1 * sigma
    assert np.all(info[np.isfinite(s)] > 0)


def test_flat_image_has_no_measure():
    params = DefocusParams(region_estimator="local_spectrum")
    s, info = estimate_region_blur(np.full((96, 96), 0.5), params=params)
    assert np.all(np.isnan(s)) and np.all(info == 0)


def test_bad_region_options_raise_naming_allowed_values():
    with pytest.raises(ValueError, match="local_spectrum"):
        DefocusParams(region_estimator="nope")
    with pytest.raises(ValueError, match="spectrum_or_white"):
        DefocusParams(region_noise_model="pink")
    with pytest.raises(ValueError, match="disk"):
        DefocusParams(region_psf="box")
    with pytest.raises(ValueError, match="local_spectrum"):
        estimate_region_blur(np.zeros((64, 64)), params=DefocusParams())
    assert set(REGION_ESTIMATORS) == {"local_spectrum", "gsm"}
