"""Tone curves: one vocabulary in scenes and method, the per-image curve fit, the curve a result states."""

from __future__ import annotations

import numpy as np
import pytest

import scenes.display as display
from method import DefocusParams, estimate_defocus_map
from method.luma import ENCODINGS, decode, encode, to_light
from method.edges.tone_curve import INPUT_ENCODINGS, fit_encoding, resolve_encoding
from scenes.analytic.lens import lens_step_edge
from tests.cli_run import run_in_process


def test_scenes_and_method_curves_agree_and_invert():
    x = np.linspace(0.0, 1.0, 2001)
    assert tuple(ENCODINGS) == display.ENCODINGS
    for name in display.ENCODINGS:
        y = display.encode(x, name)
        np.testing.assert_allclose(encode(x, name), y, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(decode(y, name), x, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(display.decode(y, name), x, atol=1e-9, err_msg=name)
        assert y[0] == 0.0 and abs(y[-1] - 1.0) < 1e-12 and np.all(np.diff(y) > 0), name
    # the curves differ: a fit has something to choose between
    mid = {n: float(display.encode(np.array([0.18]), n)[0]) for n in display.ENCODINGS}
    assert mid["gamma1.8"] < mid["srgb"] - 0.05 and mid["filmic"] > mid["srgb"] + 0.1
    # the filmic curve is an S-curve in linear light: flatter at both ends than in the middle
    slope = np.gradient(display.srgb_to_linear(display.encode(x, "filmic")), x)
    assert slope[0] < 0.5 * slope[500] and slope[-1] < 0.5 * slope[500]
    # the camera pipeline applies it; the method reads a display image of that curve back to linear light
    img = display.camera_image(np.full((4, 4), 0.3), encoding="gamma2.2")
    np.testing.assert_allclose(to_light(img, "linear", encoding="gamma2.2"), 0.3, atol=1e-12)


def _step(encoding, sigma=2.0):
    return lens_step_edge((128, 128), sigma=sigma, angle=0.3, low=0.1, high=0.9, encoding=encoding,
                          noise="iso100", quantize_bits=8, rng=1).image


@pytest.mark.parametrize("encoding", ["srgb", "gamma1.8", "filmic"])
def test_fit_picks_the_curve_of_lens_blurred_steps(encoding):
    fit = fit_encoding(_step(encoding))
    assert fit.encoding == encoding and fit.n_edges >= 50
    twins = {"srgb", "gamma2.2"} if encoding in ("srgb", "gamma2.2") else {encoding}  # nearly the same curve
    assert all(fit.residuals[encoding] < r for n, r in fit.residuals.items() if n not in twins)


def test_fit_tells_gamma_22_from_the_others_and_keeps_srgb_when_they_tie():
    # gamma 2.2 and sRGB differ by < 0.03 in display values: between them the fit keeps sRGB, and
    # without sRGB among the candidates it picks gamma 2.2
    img = _step("gamma2.2")
    assert fit_encoding(img).encoding in ("srgb", "gamma2.2")
    assert fit_encoding(img, candidates=["gamma1.8", "gamma2.2", "filmic"]).encoding == "gamma2.2"
    assert fit_encoding(_step("srgb"), candidates=["gamma1.8", "filmic"]).encoding == "gamma1.8"


def test_no_edges_degrades_to_srgb():
    fit = fit_encoding(np.full((32, 32, 3), 0.5))
    assert fit.encoding == "srgb" and fit.n_edges == 0 and fit.residuals == {}


def test_result_states_the_curve_it_assumed():
    img = _step("filmic")
    params = DefocusParams.preset("robust")
    assert estimate_defocus_map(img, params, encoding="auto").encoding == "filmic"
    assert estimate_defocus_map(img, params, encoding="gamma2.2").encoding == "gamma2.2"
    assert estimate_defocus_map(img, params).encoding == "srgb"
    assert resolve_encoding(img, "linear") == "linear"


def test_bad_input():
    img = _step("srgb")
    with pytest.raises(ValueError, match=r"encoding='gamma3' is invalid.*'auto'.*'filmic'"):
        estimate_defocus_map(img, encoding="gamma3")
    with pytest.raises(ValueError, match="candidate encoding"):
        fit_encoding(img, candidates=["sRGB"])
    with pytest.raises(ValueError, match="max_edges=0 is invalid"):
        fit_encoding(img, max_edges=0)
    with pytest.raises(ValueError, match="encoding='gamma3' is invalid"):
        display.camera_image(np.zeros((4, 4)), encoding="gamma3")
    assert "auto" in INPUT_ENCODINGS and "auto" not in ENCODINGS


def test_cli_unknown_curve_is_one_line_exit_2(tmp_path):
    r = run_in_process("repro.estimate", [str(tmp_path / "x.png"), "--encoding", "gamma3"])
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "filmic" in r.stderr and "auto" in r.stderr


def test_cli_says_the_curve_it_assumed(tmp_path):
    import os

    from PIL import Image

    src = tmp_path / "step.png"
    Image.fromarray(np.round(_step("filmic") * 255).astype(np.uint8)).save(src)
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(tmp_path / "cache")}
    r = run_in_process("repro.estimate", [src, "--encoding", "auto", "-o", tmp_path / "m.npy"], env=env)
    assert r.returncode == 0 and "tone curve assumed: filmic (fitted to this photo's edges" in r.stderr
    r = run_in_process("repro.estimate", [src, "-o", tmp_path / "n.npy"], env=env)
    assert r.returncode == 0 and "tone curve assumed: srgb\n" in r.stderr


def test_magnifier_blends_a_tone_curve_image_in_its_own_linear_light():
    """A gamma 2.2 image magnified in linear light equals its linear radiance magnified and encoded back."""
    from method import magnify_defocus

    lin = np.random.default_rng(0).random((24, 24, 3)) * 0.8 + 0.1
    sigma = np.full((24, 24), 1.0)
    kw = dict(factor=2.0, preprocess=False, renderer="gather", light="linear")
    out = magnify_defocus(display.encode(lin, "gamma2.2"), sigma, encoding="gamma2.2", **kw)
    ref = magnify_defocus(lin, sigma, encoding="linear", **kw)
    np.testing.assert_allclose(out, display.encode(ref, "gamma2.2"), atol=1e-9)
