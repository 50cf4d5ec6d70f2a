"""Defocus magnification (Sec. 5): identities, measured σ growth, never sharpens, range."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import ndimage

from method.magnify.magnification import MAGNIFICATION_KERNELS, MAP_FLOOR_MODES, magnify_defocus, preprocess_defocus_map
from tests.tolerances import MAGNIFY_GRADIENT_ENERGY_RTOL, MAGNIFY_SIGMA_RTOL


def _edge_sigma(profile):
    """Std of the derivative of a monotone edge profile, px (second moment)."""
    d = np.diff(profile)
    x = np.arange(len(d)) + 0.5
    mu = np.sum(d * x) / np.sum(d)
    return float(np.sqrt(np.sum(d * (x - mu) ** 2) / np.sum(d)))


def _blurred_step(sigma, n=240):
    x = np.zeros((48, n))
    x[:, n // 2:] = 1.0
    return np.clip(ndimage.gaussian_filter1d(x, sigma, axis=1, mode="nearest"), 0.0, 1.0)  # round-off can exceed 1


def test_kernels_registered():
    assert set(MAGNIFICATION_KERNELS) == {"gaussian", "disk"}


@pytest.mark.parametrize("kernel", ["gaussian", "disk"])
def test_kernel_variances(kernel):
    for s in (0.5, 1.3, 4.0, 11.0):
        k, var = MAGNIFICATION_KERNELS[kernel](s)
        assert k.min() >= 0 and abs(k.sum() - 1) < 1e-12
        # sampled kernels match σ once they span a few pixels (disk R = 2σ has σ = R/2); below that the
        # measured variance (e.g. 0.215 px² for σ = 0.5) is what the variance interpolation uses.
        if (kernel == "gaussian" and s >= 1.3) or s >= 4:
            assert abs(np.sqrt(var) - s) / s < 0.02


def test_factor_one_and_zero_map_are_exact_identities(rng):
    img = rng.random((20, 30, 3))
    m = rng.random((20, 30)) * 4
    assert np.array_equal(magnify_defocus(img, m, factor=1.0), img)
    assert np.array_equal(magnify_defocus(img, np.zeros((20, 30)), factor=3.0), img)
    assert np.array_equal(magnify_defocus(img[..., 0], np.zeros((20, 30)), factor=2.0), img[..., 0])


def test_zero_region_kept_bit_exact(rng):
    img = rng.random((40, 40, 3))
    m = np.zeros((40, 40))
    m[:, 25:] = 3.0
    out = magnify_defocus(img, m, factor=2.0, preprocess=False)
    assert np.array_equal(out[:, :25], img[:, :25])
    assert not np.allclose(out[:, 30:], img[:, 30:])


@pytest.mark.parametrize("kernel", ["gaussian", "disk"])
@pytest.mark.parametrize("sigma, factor", [(1.0, 2.0), (2.0, 2.0), (1.5, 3.0), (3.0, 1.5)])
def test_blurred_step_total_sigma_scales_by_factor(kernel, sigma, factor):
    img = _blurred_step(sigma)
    s0 = _edge_sigma(img[24])
    out = magnify_defocus(img, np.full(img.shape, s0), factor=factor, kernel=kernel, preprocess=False)
    measured = _edge_sigma(out[24])
    assert abs(measured - factor * s0) <= MAGNIFY_SIGMA_RTOL * factor * s0


def test_preprocessed_constant_map_unchanged():
    np.testing.assert_allclose(preprocess_defocus_map(np.full((30, 40), 2.0)), 2.0)


def test_preprocess_clips_percentiles_and_clamps(rng):
    m = rng.normal(1.0, 2.0, size=(100, 100))
    out = preprocess_defocus_map(m, clip_percent=5.0, smoothing=0.0)
    lo, hi = np.percentile(m, [5, 95])
    assert out.min() >= max(lo, 0.0) - 1e-12 and out.max() <= hi + 1e-12
    assert out.min() >= 0.0
    smooth = preprocess_defocus_map(m, clip_percent=5.0, smoothing=0.02)
    assert smooth.std() < out.std()


def _gradient_energy(img):
    return float(np.sum(np.diff(img, axis=0) ** 2) + np.sum(np.diff(img, axis=1) ** 2))


@settings(max_examples=25, deadline=None)
@given(
    img=arrays(np.float64, st.tuples(st.integers(8, 24), st.integers(8, 24)), elements=st.floats(0, 1)),
    level=st.floats(0.0, 6.0),
    factor=st.floats(1.0, 4.0),
    kernel=st.sampled_from(["gaussian", "disk"]),
)
def test_constant_map_never_sharpens_and_stays_in_range(img, level, factor, kernel):
    out = magnify_defocus(img, np.full(img.shape, level), factor=factor, kernel=kernel)
    assert out.shape == img.shape and np.all(np.isfinite(out))
    assert out.min() >= 0.0 and out.max() <= 1.0
    assert _gradient_energy(out) <= _gradient_energy(img) * (1 + MAGNIFY_GRADIENT_ENERGY_RTOL) + 1e-12


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), factor=st.floats(1.0, 4.0), kernel=st.sampled_from(["gaussian", "disk"]))
def test_varying_map_reduces_local_contrast(seed, factor, kernel):
    """Spatially varying maps (after the paper's preprocessing): no NaN, in range, gradient energy
    does not increase, and local contrast (std in 5×5 windows) does not increase on average."""
    r = np.random.default_rng(seed)
    img = ndimage.gaussian_filter(r.random((32, 32, 3)), (1, 1, 0))
    m = ndimage.zoom(r.random((4, 4)) * 5, 8, order=1)
    out = magnify_defocus(img, m, factor=factor, kernel=kernel)
    assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1
    assert _gradient_energy(out) <= _gradient_energy(img) * (1 + MAGNIFY_GRADIENT_ENERGY_RTOL) + 1e-12

    def local_std(a):
        mu = ndimage.uniform_filter(a, (5, 5, 1))
        return np.sqrt(np.maximum(ndimage.uniform_filter(a * a, (5, 5, 1)) - mu * mu, 0))

    assert local_std(out).mean() <= local_std(img).mean() + 1e-12


@pytest.mark.parametrize("bad", [dict(factor=0.5), dict(factor=np.nan), dict(factor=np.inf), dict(kernel="box")])
def test_bad_options_raise(rng, bad):
    with pytest.raises(ValueError):
        magnify_defocus(rng.random((10, 10)), np.ones((10, 10)), **bad)


def test_bad_inputs_raise(rng):
    img = rng.random((10, 12, 3))
    with pytest.raises(ValueError, match="shape"):
        magnify_defocus(img, np.ones((12, 10)))
    with pytest.raises(ValueError, match="NaN"):
        magnify_defocus(img, np.full((10, 12), np.nan))
    with pytest.raises(ValueError, match=">= 0"):
        magnify_defocus(img, -np.ones((10, 12)), preprocess=False)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        magnify_defocus(img * 2, np.ones((10, 12)))


# --- map floor (Sec. 5 "clamp its minimum value to 0": literal clamp vs subtracting the floor) -----------
FLOOR = 0.5   # in-focus floor of the synthetic map, px
BLURRY = 2.0  # σ of the blurry region of the synthetic map, px


def _floor_map(h=48, w=240):
    """B = FLOOR px on the left half (sharp), BLURRY px on the right half."""
    m = np.full((h, w), FLOOR)
    m[:, w // 2:] = BLURRY
    return m


def test_floor_modes_registered():
    assert set(MAP_FLOOR_MODES) == {"clamp", "subtract", "shift", "auto"}


def test_floor_subtract_removes_the_floor_in_quadrature():
    m = _floor_map()
    clamp = preprocess_defocus_map(m, smoothing=0.0)
    sub = preprocess_defocus_map(m, smoothing=0.0, floor="subtract")
    shift = preprocess_defocus_map(m, smoothing=0.0, floor="shift")
    np.testing.assert_array_equal(clamp, m)  # the literal reading leaves a positive map alone
    assert np.all(sub[:, :120] == 0.0) and np.all(shift[:, :120] == 0.0)
    np.testing.assert_allclose(sub[:, 120:], np.sqrt(BLURRY**2 - FLOOR**2), rtol=1e-12)
    np.testing.assert_allclose(shift[:, 120:], BLURRY - FLOOR, rtol=1e-12)


@pytest.mark.parametrize("floor, expected_b", [("clamp", BLURRY), ("subtract", np.sqrt(BLURRY**2 - FLOOR**2))])
def test_floor_subtract_extra_blur_measured(rng, floor, expected_b):
    """Magnified with the Sec. 5 preprocessing (no smoothing): pixels at the floor are untouched by
    "subtract" (0 extra blur); a step in the blurry region gets total σ² = s0² + (k² − 1)·B'² with
    B' = √(B² − floor²) ("subtract") or B ("clamp")."""
    k = 2.0
    img = np.roll(_blurred_step(1.0), 60, axis=1)  # the step (σ 1 px) moved to column 180, in the blurry half
    img[:, :60] = 0.0  # (undo the wrap-around)
    img[:, :100] = rng.random((48, 100))  # sharp texture in the floor region
    s0 = _edge_sigma(img[24, 130:])
    out = magnify_defocus(img, _floor_map(), factor=k, smoothing=0.0, floor=floor)
    assert np.all(np.isfinite(out))
    if floor == "subtract":
        np.testing.assert_array_equal(out[:, :120], img[:, :120])
    else:
        assert not np.allclose(out[:, :100], img[:, :100])
    expected = np.sqrt(s0**2 + (k * k - 1) * expected_b**2)
    measured = _edge_sigma(out[24, 130:])
    assert abs(measured - expected) <= MAGNIFY_SIGMA_RTOL * expected, (measured, expected)


@pytest.mark.parametrize("floor", sorted(MAP_FLOOR_MODES))
def test_floor_modes_keep_identities(rng, floor):
    img = rng.random((20, 30, 3))
    m = rng.random((20, 30)) * 4
    assert np.array_equal(magnify_defocus(img, m, factor=1.0, floor=floor), img)
    assert np.array_equal(magnify_defocus(img, np.zeros((20, 30)), factor=3.0, floor=floor), img)
    assert np.array_equal(preprocess_defocus_map(np.zeros((20, 30)), floor=floor), np.zeros((20, 30)))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), floor=st.sampled_from(sorted(MAP_FLOOR_MODES)),
       clip=st.sampled_from([0.0, 5.0, 20.0]), smoothing=st.sampled_from([0.0, 0.005, 0.05]))
def test_floor_modes_finite_nonnegative_and_ordered(seed, floor, clip, smoothing):
    """Maps with negative overshoots and flat stretches: no NaN, ≥ 0, and subtract/shift never exceed clamp."""
    r = np.random.default_rng(seed)
    m = r.normal(0.6, 1.5, size=(24, 32))
    m[:8] = 0.4  # flat floor stretch
    out = preprocess_defocus_map(m, clip_percent=clip, smoothing=smoothing, floor=floor)
    assert np.all(np.isfinite(out)) and out.min() >= 0
    clamp = preprocess_defocus_map(m, clip_percent=clip, smoothing=smoothing)
    assert np.all(out <= clamp + 1e-12)
    img = r.random((24, 32))
    mag = magnify_defocus(img, m, factor=2.0, clip_percent=clip, smoothing=smoothing, floor=floor)
    assert np.all(np.isfinite(mag)) and mag.min() >= 0 and mag.max() <= 1


def test_floor_subtract_never_removes_more_than_shift():
    m = np.linspace(0.0, 5.0, 400).reshape(20, 20)
    sub = preprocess_defocus_map(m, smoothing=0.0, floor="subtract")
    shift = preprocess_defocus_map(m, smoothing=0.0, floor="shift")
    assert np.all(sub >= shift - 1e-12)


def test_floor_subtract_constant_map_is_identity(rng):
    """A constant map is all floor: "subtract" adds no blur at all (the literal "clamp" blurs everything)."""
    img = rng.random((16, 16, 3))
    assert np.array_equal(magnify_defocus(img, np.full((16, 16), 0.6), factor=2.0, floor="subtract"), img)
    assert not np.array_equal(magnify_defocus(img, np.full((16, 16), 0.6), factor=2.0), img)


@pytest.mark.parametrize("bad", ["zero", "", None, "Clamp"])
def test_bad_floor_raises_naming_allowed(rng, bad):
    for call in (lambda: preprocess_defocus_map(np.ones((10, 10)), floor=bad),
                 lambda: magnify_defocus(rng.random((10, 10)), np.ones((10, 10)), floor=bad),
                 lambda: magnify_defocus(rng.random((10, 10)), np.ones((10, 10)), floor=bad, preprocess=False)):
        with pytest.raises(ValueError, match="floor") as e:
            call()
        assert all(name in str(e.value) for name in MAP_FLOOR_MODES)


def test_params_map_floor_field():
    from method import DefocusParams

    assert DefocusParams().map_floor == "clamp"
    assert DefocusParams(map_floor="subtract").map_floor == "subtract"
    assert set(MAP_FLOOR_MODES) >= {"clamp", "subtract", "shift"}
    for mode in MAP_FLOOR_MODES:
        DefocusParams(map_floor=mode)
    with pytest.raises(ValueError, match="map_floor"):
        DefocusParams(map_floor="zero")
