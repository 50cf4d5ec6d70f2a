"""The whole pipeline (method.estimate_defocus_map): contract, bad input, no edges, known blur."""

import warnings

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from method import DefocusParams, NoEdgesWarning, estimate_defocus_map
from method.pipeline import STAGES
from tests.tolerances import PIPELINE_TWO_REGION_SIGMA_RTOL


def _texture(rng, shape=(96, 128)):
    """Piecewise-constant random blocks (sharp step edges everywhere), grey in [0.2, 0.8]."""
    blocks = rng.uniform(0.2, 0.8, (shape[0] // 8, shape[1] // 8))
    return np.kron(blocks, np.ones((8, 8)))


def test_result_contract(rng):
    img = np.stack([_texture(rng)] * 3, axis=2)
    res = estimate_defocus_map(img)
    h, w = img.shape[:2]
    assert res.edges.shape == (h, w) and res.edges.dtype == bool and res.edges.any()
    for name in ("sparse_sigma", "refined_sigma", "defocus_map"):
        assert getattr(res, name).shape == (h, w)
    assert np.all(np.isnan(res.sparse_sigma[~res.edges]))
    assert np.all(np.isfinite(res.defocus_map)) and res.defocus_map.min() >= 0
    assert set(STAGES) <= set(res.timings) and res.timings["total"] > 0
    assert res.params == DefocusParams()


def test_grey_and_rgb_inputs_agree(rng):
    g = _texture(rng)
    a = estimate_defocus_map(g).defocus_map
    b = estimate_defocus_map(np.stack([g] * 3, axis=2)).defocus_map
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_two_regions_of_known_blur(rng):
    """Left half sharp, right half blurred by σ = 3 px: the map separates them and finds ≈ 3 px."""
    sigma = 3.0
    tex = _texture(rng, (128, 192))
    img = tex.copy()
    img[:, 96:] = gaussian_filter(tex, sigma, mode="reflect")[:, 96:]
    res = estimate_defocus_map(img)
    left = np.median(res.defocus_map[16:-16, 16:80])
    right = np.median(res.defocus_map[16:-16, 112:-16])
    sparse_right = np.nanmedian(res.sparse_sigma[16:-16, 112:-16])
    assert left < 1.0 < right
    assert sparse_right == pytest.approx(sigma, rel=PIPELINE_TWO_REGION_SIGMA_RTOL)


def test_constant_image_warns_and_returns_zero_map():
    with pytest.warns(NoEdgesWarning):
        res = estimate_defocus_map(np.full((32, 40, 3), 0.5))
    assert not res.edges.any()
    assert np.array_equal(res.defocus_map, np.zeros((32, 40)))


@pytest.mark.parametrize("image, message", [
    (np.zeros((16, 16, 4)), "HxW or HxWx3"),
    (np.zeros((16,)), "HxW or HxWx3"),
    (np.zeros((16, 16), dtype=np.uint8), "float"),
    (np.full((16, 16), 1.5), r"\[0, 1\]"),
    (np.full((16, 16), -0.1), r"\[0, 1\]"),
    (np.where(np.eye(16) > 0, np.nan, 0.5), "NaN or Inf"),
    (np.full((5, 5), 0.5), "smallest supported side"),
    ([[0.5] * 16] * 16, "numpy array"),
])
def test_bad_images_raise_value_error(image, message):
    with pytest.raises(ValueError, match=message):
        estimate_defocus_map(image)


@pytest.mark.parametrize("field, value", [
    ("alpha", 0.0), ("noise_std", -1.0), ("propagation_window", 4), ("bilateral_method", "fast"),
    ("false_positive_rate", 1.5), ("sigma1_scales", ()), ("propagation_downsample", 3),
])
def test_bad_params_raise_value_error(field, value):
    with pytest.raises(ValueError, match=field):
        DefocusParams(**{field: value})


def test_unknown_estimator_is_a_clear_error(rng):
    with pytest.raises(ValueError, match="no_such_estimator"):
        estimate_defocus_map(_texture(rng), DefocusParams(estimator="no_such_estimator"))


def test_no_nan_for_noise_only_image(rng):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoEdgesWarning)
        res = estimate_defocus_map(np.clip(0.5 + rng.normal(0, 0.002, (40, 40)), 0, 1))
    assert np.all(np.isfinite(res.defocus_map))
