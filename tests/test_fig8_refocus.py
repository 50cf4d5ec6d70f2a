"""Fig. 8 (refocusing): spatially varying deconvolution and re-blur, the quick experiment, golden, plot.

The method tests are analytic (no rendering); the experiment tests use the small render preset and
the figure cache in ``$DEFOCUS_CACHE_DIR``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from tests import tolerances as tol

ROOT = Path(__file__).resolve().parents[1]


def _psnr(a, b):
    return float(10.0 * np.log10(1.0 / np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2)))


@pytest.fixture(scope="module")
def ramp_case():
    """Periodic pattern blurred by a Gaussian whose σ ramps 0.5 → 3 px left to right, 8-bit."""
    h, w = 96, 128
    y, x = np.mgrid[0:h, 0:w]
    sharp = np.clip(0.5 + 0.25 * np.sign(np.sin(x / 5.0) * np.sin(y / 7.0)) + 0.1 * np.sin(0.9 * x + 0.4 * y), 0, 1)
    sigma = 0.5 + 2.5 * x / (w - 1.0)
    levels = np.linspace(0.5, 3.0, 51)
    stack = np.stack([ndimage.gaussian_filter(sharp, s, mode="reflect") for s in levels])
    idx = np.abs(sigma[None] - levels[:, None, None]).argmin(0)
    blurred = np.round(np.take_along_axis(stack, idx[None], 0)[0] * 255) / 255
    return sharp, blurred, sigma


# --- method ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["wiener", "cls"])
def test_deconvolution_with_true_map_improves_psnr(ramp_case, method):
    from method.magnify.refocusing import deconvolve_defocus

    sharp, blurred, sigma = ramp_case
    out = deconvolve_defocus(blurred, sigma, method=method)
    assert out.shape == blurred.shape and np.all(np.isfinite(out)) and 0 <= out.min() and out.max() <= 1
    gain = _psnr(out, sharp) - _psnr(blurred, sharp)
    assert gain > tol.FIG8_DECONV_MIN_GAIN_DB, gain


def test_zero_map_is_the_identity(ramp_case):
    from method.magnify.refocusing import deconvolve_defocus, refocus

    _, blurred, sigma = ramp_case
    rgb = np.stack([blurred, blurred ** 2, 1 - blurred], axis=-1)
    zero = np.zeros_like(sigma)
    for img in (blurred, rgb):
        np.testing.assert_array_equal(deconvolve_defocus(img, zero), img)
        np.testing.assert_array_equal(refocus(img, zero, zero), img)
    # σ = 0 pixels pass through bit for bit inside a map that is non-zero elsewhere
    part = np.where(np.arange(sigma.shape[1])[None, :] < 40, 0.0, sigma)
    out = deconvolve_defocus(rgb, part)
    np.testing.assert_array_equal(out[:, :40], rgb[:, :40])


def test_refocus_with_the_same_map_returns_the_input(ramp_case):
    from method.magnify.refocusing import refocus

    sharp, blurred, sigma = ramp_case
    assert _psnr(refocus(blurred, sigma, sigma), blurred) > tol.FIG8_SAME_MAP_MIN_PSNR_DB
    const = np.full_like(sigma, 1.7)
    bc = np.round(ndimage.gaussian_filter(sharp, 1.7, mode="reflect") * 255) / 255
    diff = np.abs(refocus(bc, const, const) - bc)[8:-8, 8:-8]
    assert diff.max() < tol.FIG8_CONSTANT_ROUNDTRIP_ATOL, diff.max()


def test_refocus_moves_the_focus(ramp_case):
    """Swap which side is sharp: the refocused image is closer to the truth blurred by the new map."""
    from method.magnify.refocusing import refocus

    sharp, blurred, sigma = ramp_case
    new = sigma[:, ::-1].copy()
    levels = np.linspace(0.5, 3.0, 51)
    stack = np.stack([ndimage.gaussian_filter(sharp, s, mode="reflect") for s in levels])
    target = np.take_along_axis(stack, np.abs(new[None] - levels[:, None, None]).argmin(0)[None], 0)[0]
    out = refocus(blurred, sigma, new)
    assert _psnr(out, target) > _psnr(blurred, target) + tol.FIG8_DECONV_MIN_GAIN_DB


def test_large_sigma_and_extreme_values_stay_finite():
    from method.magnify.refocusing import deconvolve_defocus, refocus

    rng = np.random.default_rng(3)
    img = (rng.random((40, 50, 3)) > 0.5).astype(np.float64)
    m = rng.uniform(0, 12, (40, 50))
    for out in (deconvolve_defocus(img, m, nsr=1e-8), deconvolve_defocus(img, m, clip=False),
                refocus(img, m, m[::-1].copy(), kernel="disk")):
        assert np.all(np.isfinite(out))


@pytest.mark.parametrize("kwargs, match", [
    ({"defocus_map": -np.ones((8, 9))}, ">= 0"),
    ({"defocus_map": np.full((8, 9), np.nan)}, "NaN"),
    ({"defocus_map": np.ones((8, 8))}, "shape"),
    ({"nsr": 0.0}, "nsr"),
    ({"nsr": float("inf")}, "nsr"),
    ({"nsr": "x"}, "nsr"),
    ({"method": "richardson"}, "unknown"),
    ({"image": np.full((8, 9), 1.5)}, r"\[0, 1\]"),
    ({"image": np.ones((8, 9, 4))}, "HxW"),
])
def test_deconvolve_rejects_bad_input(kwargs, match):
    from method.magnify.refocusing import deconvolve_defocus

    args = {"image": np.full((8, 9), 0.5), "defocus_map": np.ones((8, 9))}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        deconvolve_defocus(args.pop("image"), args.pop("defocus_map"), **args)


def test_refocus_rejects_bad_new_map_and_kernel():
    from method.magnify.refocusing import refocus

    img, m = np.full((8, 9), 0.5), np.ones((8, 9))
    with pytest.raises(ValueError, match="new_blur_map"):
        refocus(img, m, -m)
    with pytest.raises(ValueError, match="new_blur_map"):
        refocus(img, m, np.ones((9, 8)))
    with pytest.raises(ValueError, match="kernel"):
        refocus(img, m, m, kernel="box")


def test_exported_from_method():
    import method

    assert method.refocus is method.magnify.refocusing.refocus
    assert method.deconvolve_defocus is method.magnify.refocusing.deconvolve_defocus
    assert set(method.DECONVOLUTION_METHODS) == {"wiener", "cls"}


# --- experiment (renders) -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def fig8(quick_figure):
    return quick_figure("fig8")


def _view(fig8, set_name="tabletop_stress", preset="paper"):
    """The arrays and metrics of one scene set and preset: its stage, map and main-λ cases merged, the λ sweep."""
    from experiments.plotting.fig8 import _set_view

    return _set_view(fig8, set_name, preset)[0]


@pytest.mark.render
def test_fig8_quick_arrays_and_metrics(fig8):
    cfg = fig8.config
    v = _view(fig8)
    h, w = v["image_d1"].shape[:2]
    assert (w, h) == (160, 120)
    for key in ("image_d1", "image_d2", "image_pinhole", "deconvolved_estimated", "deconvolved_oracle",
                "refocused_estimated", "refocused_estimated_oracle_virtual", "refocused_oracle"):
        a = v[key]
        assert a.shape == (h, w, 3) and np.all(np.isfinite(a)) and a.min() >= 0 and a.max() <= 1, key
    for key in ("map_estimated", "virtual_map_estimated", "gt_d1", "gt_d2", "gt_pinhole"):
        assert v[key].shape == (h, w) and np.all(np.isfinite(v[key])) and v[key].min() >= 0, key
    m = v["metrics"]
    assert m["in_focus_d2_pixels"] == int(v["in_focus_d2"].sum()) > 0
    assert set(m["images_vs_d2"]) == {"unchanged_d1", "refocused_estimated", "refocused_estimated_oracle_virtual",
                                      "refocused_oracle"}
    assert len(m["nsr_sweep"]) == len(cfg.nsr_sweep)
    # one case per λ, each reading the stage and the preset's map
    lam = fig8.find(scene_set="tabletop_stress", preset="paper")
    assert [o.case.variant for o in lam] == ["map", *(f"nsr={x:g}" for x in cfg.nsr_sweep)]
    assert all(len(o.case.needs) == 2 for o in lam[1:])
    # the renders share one pixel grid (sensor scaled at D2): regions sharp in both agree closely
    both = v["mask"] & (v["gt_d2"] < 0.35) & (v["gt_pinhole"] < 0.35)
    assert both.sum() > 100 and _psnr(v["image_d2"][both], v["image_pinhole"][both]) > 40


@pytest.mark.render
def test_fig8_click_and_virtual_map(fig8):
    """The click lies on the D2 plane; inverting the map's ordering there brings that region toward σ ≈ floor."""
    m = _view(fig8)["metrics"]
    assert m["click_depth_m"] == pytest.approx(m["focus_distance_2_m"], rel=1e-3)
    vm = m["virtual_map_vs_gt_d2"]
    assert vm["estimated"]["in_focus_d2"]["mae"] < vm["d1_map_unchanged"]["in_focus_d2"]["mae"]


@pytest.mark.render
def test_fig8_oracle_virtual_map_refocus_beats_the_input(fig8):
    """With the true D2 blur as virtual map, the refocused D1 render is closer to the real D2 render."""
    q = _view(fig8)["metrics"]["images_vs_d2"]
    for metric in ("psnr_db", "ssim"):
        assert q["refocused_estimated_oracle_virtual"][metric] > q["unchanged_d1"][metric], metric
        assert q["refocused_estimated_oracle_virtual"][metric] > q["refocused_estimated"][metric], metric


@pytest.mark.render
def test_fig8_golden(fig8, goldens):
    from tests.golden import golden_values

    goldens.check("fig8_quick", golden_values("fig8_quick", fig8.rows()))


@pytest.mark.render
def test_fig8_plot_through_cli(tmp_path, fig8):
    from experiments.results_query import read_table

    env = os.environ.copy()
    proc = subprocess.run([sys.executable, "-m", "repro.figures", "fig8", "--quick", "--workers", "1", "--out",
                           str(tmp_path)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "fig8.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "fig8.pdf").stat().st_size > 0 and (tmp_path / "fig8_paper_cameras.png").is_file()
    info = json.loads((tmp_path / "fig8.metrics.json").read_text())
    assert info["cache"]["hit"] is True and len(info["cases"]) == len(fig8.outputs)
    assert read_table(tmp_path).where(figure="fig8", metric="images_vs_d2/unchanged_d1/psnr_db")


@pytest.mark.render
def test_fig8_every_preset_and_scene_set_is_its_own_evaluation(fig8):
    """Each preset refocuses with its own map; the paper_cameras set has its own scene, D2 and click."""
    sets = {s: (scene, d2) for s, scene, d2, _ in fig8.config.scene_sets}
    m, pc = _view(fig8)["metrics"], _view(fig8, "paper_cameras")["metrics"]
    # the click lands on the D2 plane of the other scene (portrait_garden: the house at 10 m)
    assert pc["click_depth_m"] == pytest.approx(pc["focus_distance_2_m"], rel=1e-3)
    assert pc["focus_distance_2_m"] == sets["paper_cameras"][1] != m["focus_distance_2_m"]
    a, b = (fig8.one(scene_set=s, variant="stage").arrays()["image_d1"] for s in ("tabletop_stress", "paper_cameras"))
    assert a.shape == b.shape and not np.array_equal(a, b)
    for s in ("tabletop_stress", "paper_cameras"):
        paper, robust = _view(fig8, s)["metrics"], _view(fig8, s, "robust")["metrics"]
        assert robust["images_vs_d2"]["unchanged_d1"] == paper["images_vs_d2"]["unchanged_d1"]  # the same stage case
        assert robust["map_floor_px"] != paper["map_floor_px"]  # its own map
        maps = [fig8.one(scene_set=s, preset=p, variant="map").arrays()["map_estimated"] for p in ("paper", "robust")]
        assert not np.array_equal(*maps)
        assert robust["images_vs_d2"]["refocused_estimated"] != paper["images_vs_d2"]["refocused_estimated"]
