"""Property-based tests (hypothesis) of the photo-level pipeline, plus unit tests of
method/magnify/upsampling.py (working resolution, downscaling, guided upsampling, tiled magnification).

Properties, for random valid images and parameters:

* the defocus map is finite, ≥ 0 and has the photo's HxW (full resolution or working resolution);
* magnifying with factor 1 is the identity, bit for bit (also for a zero map);
* magnification never sharpens: each output pixel lies within the input's range over the blur
  kernel's window (a convex combination of input pixels), so local contrast cannot grow, and the
  gradient energy does not increase;
* tiled magnification equals the whole-image call;
* 8/16-bit PNG/TIFF files round-trip exactly.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import ndimage

from method.magnify.magnification import MAGNIFICATION_KERNELS, magnify_defocus, preprocess_defocus_map
from method.magnify.upsampling import (
    _halo,
    downscale_image,
    estimate_defocus_map_at_scale,
    guided_upsample,
    magnify_defocus_tiled,
    prefilter_sigma,
    working_shape,
    working_to_full_sigma,
)
from method.validation import MIN_IMAGE_SIDE
from tests.tolerances import (
    DOWNSCALE_REFERENCE_ATOL,
    GUIDED_EDGE_POSITION_PX,
    GUIDED_EDGE_SPILL,
    MAGNIFY_GRADIENT_ENERGY_RTOL,
    MAGNIFY_LOCAL_RANGE_ATOL,
    TILED_MAGNIFY_ATOL,
)

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def images(draw, *, min_side=MIN_IMAGE_SIDE, max_side=40):
    """Random valid photos: blocky texture (edges) + noise, optionally blurred, RGB or grey."""
    h = draw(st.integers(min_side, max_side))
    w = draw(st.integers(min_side, max_side))
    grey = draw(st.booleans())
    seed = draw(st.integers(0, 2**31 - 1))
    block = draw(st.integers(1, 8))
    noise = draw(st.sampled_from([0.0, 0.01, 0.1]))
    blur = draw(st.sampled_from([0.0, 0.7, 2.0]))
    rng = np.random.default_rng(seed)
    base = rng.random((h // block + 1, w // block + 1) + (() if grey else (3,)))
    img = np.repeat(np.repeat(base, block, axis=0), block, axis=1)[:h, :w]
    if blur:
        img = ndimage.gaussian_filter(img, (blur, blur) + (() if grey else (0,)))
    img = img + rng.normal(0.0, noise, img.shape)
    return np.clip(img, 0.0, 1.0)


@st.composite
def smooth_maps(draw, shape, *, max_sigma=6.0):
    """Non-negative smooth blur maps (σ px) of a given HxW."""
    seed = draw(st.integers(0, 2**31 - 1))
    top = draw(st.floats(0.0, max_sigma))
    rng = np.random.default_rng(seed)
    m = ndimage.gaussian_filter(rng.random(shape), 3.0)
    m = (m - m.min()) / (np.ptp(m) + 1e-12)
    return top * m


# ------------------------------------------------------------------------------------------------
# the estimated map
# ------------------------------------------------------------------------------------------------


@SETTINGS
@given(img=images(), alpha=st.floats(0.05, 2.0), estimator=st.sampled_from(["model_fit", "zero_crossing",
                                                                            "gradient_ratio"]),
       budget=st.sampled_from([None, 200, 500]))
def test_map_finite_nonnegative_full_shape(img, alpha, estimator, budget):
    from method.blur.estimators import BLUR_ESTIMATORS
    from method.params import DefocusParams

    if estimator not in BLUR_ESTIMATORS:
        pytest.skip(f"estimator {estimator} not registered")
    params = DefocusParams(alpha=alpha, estimator=estimator)
    h, w = img.shape[:2]
    max_px = h * w if budget is None else max(budget, MIN_IMAGE_SIDE**2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # NoEdgesWarning on flat draws
        res = estimate_defocus_map_at_scale(img, params, max_working_pixels=max_px)
    m = res.defocus_map
    assert m.shape == (h, w)
    assert np.all(np.isfinite(m)) and m.min() >= 0
    hw, ww = res.working_shape
    # within budget, unless a side was held at the method's minimum (very elongated photos)
    assert hw * ww <= max_px or min(hw, ww) == MIN_IMAGE_SIDE


# ------------------------------------------------------------------------------------------------
# magnification
# ------------------------------------------------------------------------------------------------


@SETTINGS
@given(data=st.data(), kernel=st.sampled_from(sorted(MAGNIFICATION_KERNELS)), preprocess=st.booleans())
def test_factor_one_is_identity(data, kernel, preprocess):
    img = data.draw(images())
    m = data.draw(smooth_maps(img.shape[:2]))
    for fn in (magnify_defocus, magnify_defocus_tiled):
        out = fn(img, m, factor=1.0, kernel=kernel, preprocess=preprocess)
        assert out.shape == img.shape
        np.testing.assert_array_equal(out, img)
    np.testing.assert_array_equal(magnify_defocus(img, np.zeros(img.shape[:2]), factor=3.0), img)


def _local_range(a, radius):
    size = (2 * radius + 1, 2 * radius + 1) + ((1,) if a.ndim == 3 else ())
    return (ndimage.minimum_filter(a, size=size, mode="reflect"),
            ndimage.maximum_filter(a, size=size, mode="reflect"))


@SETTINGS
@given(data=st.data(), factor=st.floats(1.0, 4.0), kernel=st.sampled_from(sorted(MAGNIFICATION_KERNELS)))
def test_magnification_never_sharpens(data, factor, kernel):
    img = data.draw(images(min_side=12))
    m = data.draw(smooth_maps(img.shape[:2]))
    out = magnify_defocus(img, m, factor=factor, kernel=kernel)
    assert out.shape == img.shape and np.all(np.isfinite(out))
    # each output pixel is a convex combination of input pixels within the largest kernel's reach
    pm = preprocess_defocus_map(m)
    radius = _halo(np.sqrt(factor**2 - 1) * float(pm.max()))
    lo, hi = _local_range(img, radius)
    assert np.all(out >= lo - MAGNIFY_LOCAL_RANGE_ATOL) and np.all(out <= hi + MAGNIFY_LOCAL_RANGE_ATOL)
    # local contrast (3×3 range) never exceeds the input's over the same reach
    lo3, hi3 = _local_range(out, 1)
    lo_in, hi_in = _local_range(img, radius + 1)
    assert np.all(hi3 - lo3 <= hi_in - lo_in + MAGNIFY_LOCAL_RANGE_ATOL)
    # and the image-wide gradient energy does not grow
    def energy(a):
        return float(np.sum(np.diff(a, axis=0) ** 2) + np.sum(np.diff(a, axis=1) ** 2))
    assert energy(out) <= energy(img) * (1 + MAGNIFY_GRADIENT_ENERGY_RTOL) + 1e-12


@settings(max_examples=5, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(h=st.integers(257, 330), w=st.integers(257, 330), seed=st.integers(0, 1000),
       factor=st.floats(1.2, 3.0), kernel=st.sampled_from(sorted(MAGNIFICATION_KERNELS)),
       grey=st.booleans())
def test_tiled_equals_whole(h, w, seed, factor, kernel, grey):
    rng = np.random.default_rng(seed)
    img = rng.random((h, w) if grey else (h, w, 3))
    m = ndimage.gaussian_filter(rng.random((h, w)), 4) * 6
    whole = magnify_defocus(img, m, factor=factor, kernel=kernel)
    calls = []
    tiled = magnify_defocus_tiled(img, m, factor=factor, kernel=kernel, tile_pixels=256 * 256,
                                  progress=calls.append)
    assert len(calls) > 1  # really tiled
    assert np.max(np.abs(whole - tiled)) <= TILED_MAGNIFY_ATOL


# ------------------------------------------------------------------------------------------------
# working resolution and upsampling
# ------------------------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None, derandomize=True)
@given(h=st.integers(8, 20000), w=st.integers(8, 20000), budget=st.integers(64, 5_000_000))
def test_working_shape_within_budget_and_aspect(h, w, budget):
    (hw, ww), s = working_shape((h, w), max_working_pixels=budget)
    assert 0 < s <= 1
    if h * w <= budget:
        assert (hw, ww) == (h, w) and s == 1.0
    else:
        assert hw * ww <= budget or min(hw, ww) == MIN_IMAGE_SIDE
        assert hw <= h and ww <= w
        assert abs(hw / ww - h / w) <= (h / w) * (1 / min(hw, ww)) + 1e-12 or min(hw, ww) == MIN_IMAGE_SIDE


def test_working_shape_rejects_bad_input():
    with pytest.raises(ValueError, match="smallest supported side"):
        working_shape((5, 100))
    with pytest.raises(ValueError, match="max_working_pixels"):
        working_shape((100, 100), max_working_pixels=10)


def test_downscale_matches_filter_then_resample(rng):
    from method.magnify.upsampling import _resize_axis

    img = rng.random((123, 171, 3))
    out = downscale_image(img, (40, 57))
    sy, sx = (123 / 40 - 1) / 2, (171 / 57 - 1) / 2
    ref = np.stack([_resize_axis(_resize_axis(ndimage.gaussian_filter(img[..., c], (sy, sx), mode="nearest",
                                                                      truncate=4.0), 40, 0), 57, 1)
                    for c in range(3)], axis=-1)
    assert out.shape == (40, 57, 3)
    assert np.max(np.abs(out - ref)) <= DOWNSCALE_REFERENCE_ATOL
    assert downscale_image(img[..., 0], (40, 57)).shape == (40, 57)
    np.testing.assert_array_equal(downscale_image(img, (123, 171)), img)


def test_sigma_conversion():
    s = np.array([0.0, 0.5, 2.0, 10.0])
    np.testing.assert_array_equal(working_to_full_sigma(s, 1.0), s)
    np.testing.assert_allclose(working_to_full_sigma(s, 0.25, remove_prefilter=False), s / 0.25)
    pre = prefilter_sigma(0.25)
    assert pre == pytest.approx(1.5)
    np.testing.assert_allclose(working_to_full_sigma(s, 0.25), np.sqrt(np.maximum((s / 0.25) ** 2 - pre**2, 0)))
    # a Gaussian edge of σ px blurred and downscaled reads σ·s + prefilter: the conversion inverts it
    assert working_to_full_sigma(np.sqrt((8.0 * 0.25) ** 2 + (pre * 0.25) ** 2), 0.25) == pytest.approx(8.0)


def test_guided_upsample_follows_full_resolution_edge():
    H, W, edge = 200, 300, 151
    img = np.zeros((H, W, 3))
    img[:, edge:] = 1.0
    (h, w), s = working_shape(img.shape, max_working_pixels=3750)
    small = downscale_image(img, (h, w))
    low = np.where(small[..., 0] > 0.5, 4.0, 1.0)
    up = guided_upsample(low, small, img)
    assert up.shape == (H, W)
    assert up.min() >= 1.0 and up.max() <= 4.0
    row = up[H // 2]
    jump = int(np.argmax(np.diff(row))) + 1
    assert abs(jump - edge) <= GUIDED_EDGE_POSITION_PX
    spill = GUIDED_EDGE_SPILL * 3.0  # step height 3
    assert row[: edge - 3].max() <= 1.0 + spill and row[edge + 3:].min() >= 4.0 - spill


@SETTINGS
@given(data=st.data())
def test_guided_upsample_range_and_constant(data):
    img = data.draw(images(min_side=24, max_side=60))
    h, w = max(8, img.shape[0] // 3), max(8, img.shape[1] // 3)
    small = downscale_image(img, (h, w))
    low = data.draw(smooth_maps((h, w)))
    up = guided_upsample(low, small, img)
    assert up.shape == img.shape[:2]
    assert np.all(np.isfinite(up)) and up.min() >= low.min() and up.max() <= low.max()
    const = guided_upsample(np.full((h, w), 2.5), small, img)
    np.testing.assert_array_equal(const, 2.5)


# ------------------------------------------------------------------------------------------------
# photo files
# ------------------------------------------------------------------------------------------------


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(h=st.integers(1, 30), w=st.integers(1, 30), bits=st.sampled_from([8, 16]),
       suffix=st.sampled_from([".png", ".tif"]), grey=st.booleans(), seed=st.integers(0, 1000))
def test_lossless_files_roundtrip(tmp_path, h, w, bits, suffix, grey, seed):
    from repro.photo_io import read_photo, write_photo

    levels = 2**bits - 1
    rng = np.random.default_rng(seed)
    img = rng.integers(0, levels + 1, (h, w) if grey else (h, w, 3)) / levels
    path = write_photo(tmp_path / f"r{h}x{w}{bits}{int(grey)}{suffix}", img, bit_depth=bits)
    photo = read_photo(path)
    assert photo.bit_depth == bits
    np.testing.assert_array_equal(photo.image, img)
