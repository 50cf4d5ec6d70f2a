"""Fig. 4 (estimators at edges) and Fig. 5 (biased cross-bilateral) in quick mode: structure, plots,
golden metrics and the paper's qualitative claims (asserted only where they were measured to hold).
"""

import math

import numpy as np
import pytest

from tests import tolerances as tol

pytestmark = [pytest.mark.render]

ESTIMATORS = ("model_fit", "zero_crossing", "gradient_ratio")


@pytest.fixture(scope="module")
def fig4():
    from experiments.registry import FIGURES, compute_cached

    fig = FIGURES["fig4"]
    return fig, compute_cached(fig, fig.config("quick"))


@pytest.fixture(scope="module")
def fig5():
    from experiments.registry import FIGURES, compute_cached

    fig = FIGURES["fig5"]
    return fig, compute_cached(fig, fig.config("quick"))


def test_fig4_quick_structure(fig4):
    fig, res = fig4
    cfg = fig.config("quick")
    m = res.metrics
    pooled = m["rendered"]["pooled"]
    for enc in ("srgb", "linear"):
        for conv in ("line_spread", "erf_fit"):
            for e in ESTIMATORS:
                row = pooled[enc][conv][e]
                assert row["n"] > 500
                for k in ("mae", "median_ae", "median_rel_error", "outlier_fraction", "bias"):
                    assert math.isfinite(row[k]), (enc, conv, e, k)
    for fam in ("straight", "curved"):
        for cond in ("clean", "noisy"):
            assert set(m["analytic"][fam][cond]) == set(ESTIMATORS)
    a = res.arrays
    n_e, n_s = len(ESTIMATORS), len(cfg.analytic_sigmas)
    assert a["analytic_straight_median_ae"].shape == (2, n_e, n_s)
    assert a["curve_rendered_median_ae"].shape == (2, 2, n_e, len(cfg.error_bins_px) - 1)
    h, w = a["showcase_sigma_gt"].shape
    assert a["showcase_estimates"].shape == (n_e, h, w) and a["showcase_image"].shape == (h, w, 3)
    # estimates only at edge pixels: most of the map is NaN
    assert np.isnan(a["showcase_estimates"]).mean() > 0.5


def test_fig4_plot(fig4, tmp_path):
    fig, res = fig4
    paths = fig.plot_function()(res.as_data(), fig.config("quick"), tmp_path / "fig4")
    # the default scene set (tabletop_stress, flat keys) and the paper_cameras set (own file)
    assert [p.name for p in paths] == ["fig4.png", "fig4.pdf", "fig4_paper_cameras.png", "fig4_paper_cameras.pdf"]
    assert all(p.stat().st_size > 10_000 for p in paths)


def test_fig4_every_preset_and_scene_set_is_its_own_evaluation(fig4):
    """Each preset runs with its own parameters and fit; the rendered comparison runs on both scene sets;
    the analytic images (no scene set) once per preset."""
    fig, res = fig4
    cfg = fig.config("quick")
    m = res.metrics
    assert m["scene_set"] == cfg.scene_set == "tabletop_stress" and set(m["scene_sets"]) == {"paper_cameras"}
    assert set(m["presets"]) == {"robust"} and m["fit_estimator"] == "model_fit"
    robust = m["presets"]["robust"]
    assert robust["fit_estimator"] == "model_fit_checked" and robust["estimators"][0] == "model_fit_checked"
    # the robust fit rejects poor fits (NaN), the paper's never does: different numbers on the same images
    fail = {p: node["rendered"]["pooled"]["srgb"]["line_spread"][node["fit_estimator"]]["failure_rate"]
            for p, node in (("paper", m), ("robust", robust))}
    assert fail["robust"] > fail["paper"], fail
    zc = [node["analytic"]["straight"]["clean"]["zero_crossing"]["median_ae"] for node in (m, robust)]
    assert zc[0] != zc[1]  # the robust preset's own edge detector scales
    pc = m["scene_sets"]["paper_cameras"]
    stress_scenes = set(m["rendered"]["by_scene"])
    for node in (pc, pc["presets"]["robust"]):
        assert "analytic" not in node  # no scene set in analytic images: not repeated here
        assert set(node["rendered"]["by_scene"]) == set(dict(dict(cfg.other_scene_sets)["paper_cameras"])["scenes"])
        assert not stress_scenes & set(node["rendered"]["by_scene"])
        assert node["rendered"]["pooled"]["srgb"]["line_spread"]["zero_crossing"]["n"] > 200
    assert pc["presets"]["robust"]["fit_estimator"] == "model_fit_checked"


def test_fig4_goldens(fig4, goldens):
    from tests.golden import golden_values

    goldens.check("fig4_quick", golden_values("fig4_quick", fig4[1].metrics))


def test_model_fit_beats_zero_crossing_near_neighbouring_edges(fig4):
    """Paper (Sec. 3.2, Fig. 4): the model fit is more accurate than the zero crossings where two
    edges are close.

    Measured in quick mode (median relative error, σ ∈ {1, 2}, two orientations): it holds for
    opposite-polarity bars at D = 3σ and 4σ, clean and noisy (model fit 0.01–0.28, zero crossing
    0.15–0.41) — asserted here. It does NOT hold for bars at D = 2σ (0.18–0.20 vs 0.05–0.07) and
    D = 6σ (0.14 vs 0.09–0.11), nor for staircases at D ≥ 4σ; for staircases at D = 2σ–3σ the
    fit is "better" but both are off by 60–135 % (the two steps read as one wide edge), so that is
    not evidence for the claim and is not asserted.
    """
    cases = fig4[1].metrics["analytic"]["neighbouring"]["bar"]
    checked = 0
    for cond in ("clean", "noisy"):
        for k in tol.FIG4_BAR_CLAIM_SPACINGS:
            m = cases[cond][f"D={k:g}sigma"]
            mf, zc = m["model_fit"]["median_rel_error"], m["zero_crossing"]["median_rel_error"]
            assert mf < zc, (cond, k, mf, zc)
            assert zc >= tol.FIG4_BAR_ZC_MIN_REL_ERROR, (cond, k, zc)
            checked += 1
    assert checked == 2 * len(tol.FIG4_BAR_CLAIM_SPACINGS)


def test_fig4_convention_effect_is_the_sigma_gt_difference(fig4):
    # Same edge pixels under both conventions; erf_fit σ_gt ≥ line_spread σ_gt everywhere, so the
    # line_spread bias exceeds the erf_fit bias for every estimator and encoding.
    eff = fig4[1].metrics["bias_effects"]["convention_effect"]
    for e in ESTIMATORS:
        for subset in ("all", "blurred"):
            for enc, v in eff[e][subset].items():
                assert v >= -tol.FIG4_CONVENTION_EFFECT_ATOL, (e, subset, enc, v)


def test_fig5_quick_structure_and_plot(fig5, tmp_path):
    fig, res = fig5
    cfg = fig.config("quick")
    cases = [str(c) for c in res.arrays["cases"]]
    assert cases == [f"{s}_f{n:g}" for s in cfg.scenes for n in cfg.f_numbers]
    for case in cases:
        before = res.arrays[f"{case}_before"]
        after = res.arrays[f"{case}_after_bias"]
        # the filter keeps the support of the sparse map (values only at edge pixels)
        np.testing.assert_array_equal(np.isfinite(before), np.isfinite(after))
    paths = fig.plot_function()(res.as_data(), cfg, tmp_path / "fig5")
    assert all(p.stat().st_size > 10_000 for p in paths)
    # both scene sets: the default (paper_cameras, flat keys) and the stress set (nested, own file)
    m = res.metrics
    assert m["scene_set"] == cfg.scene_set == "paper_cameras" and set(m["scene_sets"]) == {"tabletop_stress"}
    stress_cfg = dict(dict(cfg.other_scene_sets)["tabletop_stress"])
    stress_cases = [str(c) for c in res.arrays["tabletop_stress__cases"]]
    assert stress_cases == [f"{s}_f{n:g}" for s in stress_cfg["scenes"] for n in cfg.f_numbers]
    assert set(stress_cases) <= set(m["scene_sets"]["tabletop_stress"]["summary"])
    assert m["outlier_scenes"] == ["patio_table"] and m["scene_sets"]["tabletop_stress"]["outlier_scenes"] == ["shadow_gloss"]
    assert sorted(p.name for p in paths) == ["fig5.pdf", "fig5.png", "fig5_tabletop_stress.pdf",
                                             "fig5_tabletop_stress.png"]


def test_fig5_goldens(fig5, goldens):
    from tests.golden import golden_values

    goldens.check("fig5_quick", golden_values("fig5_quick", fig5[1].metrics))


def test_bias_filter_lowers_in_focus_outliers(fig5):
    """Paper (Sec. 3.3, Fig. 5): the biased cross-bilateral filter removes the blur outliers of soft
    shadows and glossy highlights. On ``shadow_gloss`` (both apertures, small preset) the sparse
    measure has in-focus outliers (measured 18 % at f/8, 10 % at f/4); after the biased filter the
    fraction must drop, and must be lower than with the plain (no-bias) cross-bilateral filter,
    which measured *more* outliers than before filtering (the unbiased average pulls in-focus edges
    towards blurry neighbours).
    """
    m = fig5[1].metrics["scene_sets"]["tabletop_stress"]
    cases = [c for c in m if c.startswith("shadow_gloss_")]
    assert cases
    for case in cases:
        frac = {s: m[case][s]["in_focus_outliers"]["fraction"] for s in ("before", "after_bias", "after_no_bias")}
        assert frac["before"] >= tol.FIG5_MIN_OUTLIERS_BEFORE, (case, frac)
        assert frac["after_bias"] < frac["before"], (case, frac)
        assert frac["after_bias"] < frac["after_no_bias"], (case, frac)


def test_bias_filter_removes_the_outliers_of_the_paper_regime_scene(fig5):
    """The same on ``patio_table`` (paper_cameras: glossy globe and soft shadow at 2 m, 85 mm): the sparse
    measure has in-focus outliers at both apertures (quick: 2.5 % at f/8, 4.3 % at f/4) and the biased
    filter removes them. Unlike the tabletop scene, the plain filter here does not add outliers (both
    0 % after filtering at the small preset), so only "no more than without the bias" is asserted."""
    m = fig5[1].metrics
    cases = [c for c in m if any(c.startswith(f"{s}_") for s in m["outlier_scenes"])]
    assert cases
    for case in cases:
        frac = {s: m[case][s]["in_focus_outliers"]["fraction"] for s in ("before", "after_bias", "after_no_bias")}
        assert frac["before"] > 0.0, (case, frac)
        assert frac["after_bias"] < frac["before"], (case, frac)
        assert frac["after_bias"] <= frac["after_no_bias"], (case, frac)


def _sweep_index(res, scale):
    scales = [float(s) for s in res.arrays["bias_scales"]]
    return scales.index(scale)


def test_fig5_bias_sweep_structure_and_endpoints(fig5):
    """The sweep's arrays have the documented shapes; s = 2 repeats the paper's filter (``after_bias``)
    and s = inf the no-bias ablation (``after_no_bias``) exactly — same calls, same numbers."""
    fig, res = fig5
    cfg = fig.config("quick")
    a, m = res.arrays, res.metrics
    cases = [str(c) for c in a["cases"]]
    scales = [float(s) for s in a["bias_scales"]]
    assert scales == [float(s) for s in cfg.bias_scales] and math.isinf(scales[-1]) and 2.0 in scales
    i2, iinf = _sweep_index(res, 2.0), _sweep_index(res, math.inf)
    from experiments.fig5_cross_bilateral import SWEEP_CURVES, scale_label

    for name in SWEEP_CURVES:
        assert a[f"sweep_{name}"].shape == (len(cases), len(scales)), name
    for case in cases:
        h, w = a[f"{case}_sigma_gt"].shape
        refined, dense = a[f"{case}_sweep_refined"], a[f"{case}_sweep_dense"]
        assert refined.shape == dense.shape == (len(scales), h, w)
        assert np.all(np.isfinite(dense))
        for i in range(len(scales)):
            np.testing.assert_array_equal(np.isfinite(refined[i]), np.isfinite(a[f"{case}_before"]))
        np.testing.assert_array_equal(refined[i2], a[f"{case}_after_bias"])
        np.testing.assert_array_equal(refined[iinf], a[f"{case}_after_no_bias"])
        for idx, stage in ((i2, "after_bias"), (iinf, "after_no_bias")):
            sw = m["bias_sweep"][case][scale_label(scales[idx])]
            assert sw["refined"]["all_edges"]["mae"] == m[case][stage]["mae"], (case, stage)
            assert sw["refined"]["all_edges"]["bias"] == m[case][stage]["bias"], (case, stage)
            assert sw["in_focus_outliers"] == m[case][stage]["in_focus_outliers"], (case, stage)
            assert a["sweep_in_focus_outliers"][cases.index(case), idx] == \
                m[case][stage]["in_focus_outliers"]["fraction"]
        for sc in scales:
            d = m["bias_sweep"][case][scale_label(sc)]["dense"]
            assert d["all"]["n"] >= d["textured"]["n"] > 0 and d["edges"]["n"] > 0, (case, sc)


def test_fig5_bias_sweep_monotone_in_scale(fig5):
    """A weaker bias (larger s) keeps more blur: each refined edge value is an exponentially tilted
    weighted mean of BM, hence non-decreasing in s — per pixel; so the mean (and bias) at blurry edges
    (σ_gt ≥ 3 px) strictly increasing wherever there are any, and the in-focus outlier fraction
    non-decreasing. A scale not passed through to the filter (checked: every finite s filtered with
    s = 2 fails here) or maps stored under the wrong scale break this. Both scene sets; the blurry edges
    (σ_gt ≥ 3 px) are the tabletop stress scenes' at the small preset (the paper_cameras scenes reach
    σ_gt ≈ 2 px there)."""
    from experiments.fig5_cross_bilateral import scale_label
    from experiments.scene_sets import set_arrays

    _, res = fig5
    n_blurry = 0
    for set_name in (None, "tabletop_stress"):
        n_blurry += _check_sweep_monotone(set_arrays(res.as_data(), set_name), scale_label)
    assert n_blurry >= tol.FIG5_SWEEP_MIN_BLURRY_EDGES, n_blurry


def _check_sweep_monotone(a, scale_label) -> int:
    m = a["metrics"]
    cases = [str(c) for c in a["cases"]]
    scales = [float(s) for s in a["bias_scales"]]
    n_blurry = 0
    for ci, case in enumerate(cases):
        refined = a[f"{case}_sweep_refined"].astype(np.float64)
        step = np.diff(refined, axis=0)
        ok = np.isfinite(step)
        assert np.all(step[ok] >= -tol.FIG5_SWEEP_MONOTONE_ATOL_PX), (case, float(step[ok].min()))
        # strictly larger somewhere between every pair of consecutive scales
        assert all(np.nanmax(step[k]) > tol.FIG5_SWEEP_MONOTONE_ATOL_PX for k in range(len(step))), case
        frac = a["sweep_in_focus_outliers"][ci]
        assert np.all(np.diff(frac) >= 0), (case, frac)
        rows = [m["bias_sweep"][case][scale_label(s)]["refined"]["blurry_edges"] for s in scales]
        n = rows[0]["n"]
        assert all(r["n"] == n for r in rows), case
        if n:
            bias = np.array([r["bias"] for r in rows])
            np.testing.assert_array_equal(bias, a["sweep_refined_bias_blurry"][ci])
            assert np.all(np.diff(bias) > 0), (case, bias)
        n_blurry += n
    return n_blurry


def test_fig5_bias_sweep_dense_matches_pipeline(fig5):
    """The sweep's dense maps at s = 2 and s = inf are what :func:`method.estimate_defocus_map` gives
    with ``bias_scale=2`` / ``sharpness_bias=False`` (one quick case, re-rendered from the cache)."""
    from experiments.evaluation import input_image
    from method import DefocusParams, estimate_defocus_map
    from scenes import render_scene

    fig, res = fig5
    cfg = fig.config("quick")
    scene, n = cfg.scenes[-1], cfg.f_numbers[-1]
    case = f"{scene}_f{n:g}"
    render = render_scene(scene, preset=cfg.preset, f_number=n, progress=False)
    image = input_image(render, encoding=cfg.encoding, quantize_bits=cfg.quantize_bits)
    dense = res.arrays[f"{case}_sweep_dense"].astype(np.float64)
    for scale, params in ((2.0, DefocusParams(estimator=cfg.estimator, bias_scale=2.0)),
                          (math.inf, DefocusParams(estimator=cfg.estimator, sharpness_bias=False))):
        ref = estimate_defocus_map(image, params).defocus_map
        diff = np.abs(ref - dense[_sweep_index(res, scale)])
        assert diff.max() <= tol.FIG5_SWEEP_PIPELINE_ATOL_PX, (case, scale, float(diff.max()))
