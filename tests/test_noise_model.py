"""The signal-dependent noise model: variance a·x + b in linear light, carried through the tone curve,
estimated per intensity level, and read by Eq. (9)'s thresholds and the checked fit's residual test."""

from __future__ import annotations

import numpy as np
import pytest

from method import DefocusParams
from method.blur.model_fit_checked import noise_residual_share
from method.blur.noise_model import estimate_noise_levels, noise_variance, noise_variance_map
from method.edges.elder_zucker import detect_edges
from method.luma import decode_slope, light_of, to_light
from tests.tolerances import (DECODE_SLOPE_ATOL, NOISE_ESTIMATE_A_RTOL, NOISE_ESTIMATE_VARIANCE_RTOL,
                              NOISE_MODEL_VARIANCE_RTOL)

LEVELS = ("iso100", "iso800", "iso3200")


def _srgb_slope(y):
    """d decode / dy of IEC 61966-2-1, analytic."""
    y = np.asarray(y, dtype=np.float64)
    return np.where(y <= 0.04045, 1 / 12.92, 2.4 / 1.055 * ((y + 0.055) / 1.055) ** 1.4)


def test_decode_slope_is_the_curves_derivative():
    y = np.array([0.01, 0.1, 0.2, 0.5, 0.9, 0.99])
    np.testing.assert_allclose(decode_slope(y, "srgb"), _srgb_slope(y), atol=DECODE_SLOPE_ATOL)
    np.testing.assert_allclose(decode_slope(y, "linear"), 1.0, atol=DECODE_SLOPE_ATOL)
    assert decode_slope(0.2, "srgb") == pytest.approx(0.31, abs=0.01)
    assert decode_slope(0.9, "srgb") == pytest.approx(1.98, abs=0.01)
    with pytest.raises(ValueError, match="allowed: .*'linear', 'srgb'"):
        decode_slope(0.5, "bogus")


@pytest.mark.parametrize("encoding", ["srgb", "linear"])
@pytest.mark.parametrize("level", LEVELS)
def test_model_variance_matches_the_camera_pipeline(level, encoding):
    """a·x + b through the tone curve = the sample variance of flat patches of the camera pipeline."""
    from scenes.display import NOISE_LEVELS, camera_image, linear_to_srgb

    a, b = NOISE_LEVELS[level]
    for x in (0.15, 0.3, 0.6):
        patch = camera_image(np.full((200, 200), x), encoding=encoding, noise=level, rng=5)
        y = float(linear_to_srgb(x)) if encoding == "srgb" else x
        predicted = noise_variance(y, a, b, light=light_of(encoding), encoding=encoding)
        assert patch.var() == pytest.approx(float(predicted), rel=NOISE_MODEL_VARIANCE_RTOL), (level, encoding, x)


def test_model_variance_in_display_light_is_not_the_linear_one():
    """The tone curve matters: the same sensor's variance differs by decode′(y)² (0.31² at y 0.2, 1.98² at 0.9)."""
    a, b = 1.6e-3, 2.7e-6
    y = np.array([0.2, 0.9])
    x = to_light(y, "linear", encoding="srgb")
    display = noise_variance(y, a, b, light="display", encoding="srgb")
    linear = noise_variance(x, a, b, light="linear")
    np.testing.assert_allclose(display / linear, 1 / _srgb_slope(y) ** 2, rtol=1e-6)
    assert display[0] > 5 * linear[0] and display[1] < linear[1] / 3


@pytest.fixture(scope="module")
def mosaics():
    from scenes.analytic.lens import lens_mosaic

    return {(fam, level): lens_mosaic(family=fam, sigmas=(1.0, 2.0, 4.0, 8.0) * 2, tile=128, cols=4, supersample=2,
                                      noise=level, rng=1).image[..., 1]
            for fam in ("dead_leaves", "shading") for level in LEVELS}


@pytest.mark.parametrize("light", ["linear", "display"])
@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("family", ["dead_leaves", "shading"])
def test_estimator_recovers_the_pipeline_levels(mosaics, family, level, light):
    """One channel of a lens mosaic (sRGB, 8 bits): the fitted a·x + b is the pipeline's within tolerance."""
    from scenes.display import NOISE_LEVELS

    a, b = NOISE_LEVELS[level]
    seen = to_light(mosaics[family, level], light, encoding="srgb")
    est_a, est_b = estimate_noise_levels(seen, light=light, encoding="srgb")
    assert est_a == pytest.approx(a, rel=NOISE_ESTIMATE_A_RTOL)
    x = np.linspace(0.1, 0.9, 9)
    np.testing.assert_allclose(est_a * x + est_b, a * x + b, rtol=NOISE_ESTIMATE_VARIANCE_RTOL)


def test_estimator_tells_the_levels_apart(mosaics):
    """Each ISO level is estimated above the one below it (the estimate follows the noise, not the scene)."""
    a = [estimate_noise_levels(to_light(mosaics["dead_leaves", lv], "linear"), light="linear")[0] for lv in LEVELS]
    assert a[0] * 4 < a[1] < a[2] / 2


def test_estimator_of_a_flat_image_falls_back_to_one_variance():
    rng = np.random.default_rng(0)
    img = 0.5 + rng.normal(0, 0.01, (64, 64))
    a, b = estimate_noise_levels(img, light="linear")
    assert a == 0 and b == pytest.approx(1e-4, rel=0.2)


def test_variance_map_is_none_for_the_constant_model_and_follows_the_level():
    img = np.concatenate([np.full((32, 32), 0.05), np.full((32, 32), 0.8)], axis=1)
    assert noise_variance_map(img, DefocusParams()) is None
    p = DefocusParams(noise_model="signal_dependent", noise_a=1e-3, noise_b=1e-6, measure_light="linear")
    v = noise_variance_map(img, p)
    assert v[16, 4] == pytest.approx(1e-3 * 0.05 + 1e-6, rel=1e-6)
    assert v[16, 60] == pytest.approx(1e-3 * 0.8 + 1e-6, rel=1e-6)


def _halves(level, seed=2):
    """Dark (linear 0.03) | bright (linear 0.7) halves through the camera pipeline, measured in linear light."""
    from scenes.display import camera_image

    lin = np.concatenate([np.full((96, 64), 0.03), np.full((96, 64), 0.7)], axis=1)
    return to_light(camera_image(lin, encoding="srgb", noise=level, quantize_bits=8, rng=seed), "linear")


def test_thresholds_follow_the_signal_dependent_noise():
    """A constant s_n (paper's 2.5/255, read in linear light) calls the bright half's noise edges; the
    per-pixel variance keeps Eq. (9)'s false-positive rate there and still finds the step."""
    seen = _halves("iso800")
    far = np.zeros(seen.shape, dtype=bool)
    far[8:-8, 8:56] = far[8:-8, 72:120] = True  # flat, ≥ 8 px from the step and the border
    constant = detect_edges(seen)
    params = DefocusParams(noise_model="signal_dependent", measure_light="linear")
    varying = detect_edges(seen, noise_variance=noise_variance_map(seen, params))
    assert np.count_nonzero(constant.edges & far) > 50
    assert np.count_nonzero(varying.edges & far) == 0
    assert varying.edges[8:-8, 62:66].any(axis=1).mean() > 0.9  # the step, on (nearly) every row


def test_constant_variance_map_gives_the_constant_thresholds():
    seen = _halves("iso100")
    s_n = 2.5 / 255
    a = detect_edges(seen, noise_std=s_n)
    b = detect_edges(seen, noise_variance=np.full(seen.shape, s_n ** 2))
    np.testing.assert_array_equal(a.edges, b.edges)
    np.testing.assert_array_equal(a.sigma1, b.sigma1)
    assert a.noise_variance is None and b.noise_variance is not None


@pytest.mark.parametrize("bad", [np.zeros((4, 4)), -np.ones((96, 128)), np.full((96, 128), np.nan)])
def test_detect_edges_refuses_a_bad_variance_map(bad):
    with pytest.raises(ValueError, match="noise_variance"):
        detect_edges(_halves("iso100"), noise_variance=bad)
    with pytest.raises(ValueError, match="noise_variance"):  # also when it is computed lazily
        detect_edges(_halves("iso100"), noise_variance=lambda: bad)


def test_lazy_noise_estimates_give_the_same_edges():
    """Callables for the variance map and the spectrum (the pipeline's: run while the first gradients are
    transformed) give the bytes of the arrays themselves."""
    from method.blur.noise_spectrum import noise_spectrum_of

    seen = _halves("iso800")
    params = DefocusParams(noise_model="signal_dependent", measure_light="linear", noise_spectrum="estimated")
    var, spectrum = noise_variance_map(seen, params), noise_spectrum_of(seen, params)
    calls = []
    eager = detect_edges(seen, noise_variance=var, noise_spectrum=spectrum)
    lazy = detect_edges(seen, noise_variance=lambda: calls.append(1) or var,
                        noise_spectrum=lambda: calls.append(2) or spectrum)
    assert calls == [1, 2]
    for name in ("edges", "theta", "gradient_magnitude", "sigma1", "sigma2", "noise_variance"):
        assert getattr(lazy, name).tobytes() == getattr(eager, name).tobytes(), name
    assert lazy.noise_spectrum == spectrum
    assert detect_edges(seen, noise_variance=lambda: None).noise_variance is None


def test_residual_share_reads_the_per_pixel_variance():
    diag = {"window": np.full((2, 3), 9.0), "sigma2": np.array([[1.0, 2.0, np.nan], [1.0, 1.0, 1.0]]),
            "energy": np.full((2, 3), 0.5)}
    s_n = 0.01
    constant = noise_residual_share(diag, noise_std=s_n)
    same = noise_residual_share(diag, noise_std=123.0, noise_variance=np.full((2, 3), s_n ** 2))
    np.testing.assert_allclose(same, constant, rtol=1e-12)
    var = np.full((2, 3), s_n ** 2)
    var[1, 2] *= 4
    scaled = noise_residual_share(diag, noise_std=s_n, noise_variance=var)
    assert scaled[1, 2] == pytest.approx(4 * constant[1, 2]) and scaled[1, 1] == pytest.approx(constant[1, 1])
    assert scaled[0, 2] == 0  # not fitted


@pytest.mark.filterwarnings("ignore::method.pipeline.NoEdgesWarning")
def test_pipeline_runs_with_either_model_and_paper_is_constant():
    from method import estimate_defocus_map

    img = np.repeat(_halves("iso800")[..., None], 3, axis=2)
    assert DefocusParams().noise_model == DefocusParams.preset("paper").noise_model == "constant"
    base = DefocusParams.preset("robust")
    constant = estimate_defocus_map(img, base.replace(noise_model="constant"), encoding="linear")
    varying = estimate_defocus_map(img, base.replace(noise_model="signal_dependent"), encoding="linear")
    assert np.count_nonzero(constant.edges) > 2 * np.count_nonzero(varying.edges) > 0
    assert varying.edge_map.noise_variance is not None and constant.edge_map.noise_variance is None


@pytest.mark.parametrize("fields, needle", [
    ({"noise_model": "poisson"}, "noise_model='poisson' is invalid (unknown noise model); allowed: 'constant', "
                                 "'signal_dependent'"),
    ({"noise_a": -1e-3, "noise_b": 0.0}, "noise_a=-0.001 is invalid; allowed: None or finite and >= 0"),
    ({"noise_a": 1e-3, "noise_b": -1e-6}, "noise_b=-1e-06 is invalid; allowed: None or finite and >= 0"),
    ({"noise_a": float("inf"), "noise_b": 0.0}, "noise_a=inf is invalid"),
    ({"noise_a": 1e-3}, "noise_b=None is invalid; allowed: None together with noise_a"),
    ({"noise_a": 0.0, "noise_b": 0.0}, "noise_b=0.0 is invalid; allowed: noise_a + noise_b > 0"),
])
def test_bad_noise_fields(fields, needle):
    with pytest.raises(ValueError) as info:
        DefocusParams(**{"noise_model": "signal_dependent", **fields})
    assert needle in str(info.value)


def test_good_noise_fields():
    p = DefocusParams(noise_model="signal_dependent", noise_a=2e-4, noise_b=0)
    assert (p.noise_a, p.noise_b, p.edges.noise_model) == (2e-4, 0, "signal_dependent")
    with pytest.raises(ValueError, match="light=.*allowed"):
        noise_variance(0.5, 1e-3, 0.0, light="raw")


def test_second_differences_are_numpys_shifted_sum_byte_for_byte(rng):
    """The one-pass kernel of the noise estimate equals the nine shifted NumPy images summed left to right."""
    from method.blur.image_noise import _second_differences

    for shape in ((3, 3), (10, 17), (64, 41)):
        g = rng.random(shape) * rng.choice([1e-3, 1.0, 1e3], size=shape)
        want = (g[:-2, :-2] - 2 * g[:-2, 1:-1] + g[:-2, 2:] - 2 * g[1:-1, :-2] + 4 * g[1:-1, 1:-1]
                - 2 * g[1:-1, 2:] + g[2:, :-2] - 2 * g[2:, 1:-1] + g[2:, 2:])
        got = _second_differences(g)
        assert got.shape == want.shape and got.tobytes() == want.tobytes(), shape
    assert _second_differences(np.zeros((2, 5))).shape == (0, 3)
    ramp = np.add.outer(np.arange(6.0), 2 * np.arange(7.0))
    assert np.all(_second_differences(ramp) == 0)  # 0 on a linear ramp; not a copy of the input
