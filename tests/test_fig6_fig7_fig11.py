"""Figures 6 (α sweep), 7 (doubled defocus) and 11 (gallery): quick cases, paper claims, goldens, plots.

The quick configs use the small render preset (160×120 px); renders and case results are cached in
``$DEFOCUS_CACHE_DIR`` (the session's ``quick_figure`` reads them once). Each figure runs the method
presets of its config, ``paper`` (the reproduction) and ``robust`` beside it, each its own cases, on
every scene set of its config (the hand-built ones and the procedural test split).
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from tests import tolerances as tol

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.render
FIGURE_MODULES = ("fig6_alpha_sweep", "fig7_doubled_defocus", "fig11_gallery")


@pytest.fixture(scope="module")
def fig6(quick_figure):
    return quick_figure("fig6")


@pytest.fixture(scope="module")
def fig7(quick_figure):
    return quick_figure("fig7")


@pytest.fixture(scope="module")
def fig11(quick_figure):
    return quick_figure("fig11")


def _finite(x):
    return x is not None and np.isfinite(float(x))


# --- fig6 ---------------------------------------------------------------------------------------
def test_fig6_cases_shape_and_regions(fig6):
    cfg = fig6.config
    k = len(cfg.alphas)
    assert len(fig6.outputs) == sum(len(s) for _, s in cfg.scene_sets) * len(cfg.presets) * len(cfg.encodings)
    for o in fig6.outputs.values():
        a = o.arrays()
        h, w = a["sigma_gt"].shape
        assert a["maps"].shape == (k, h, w) and np.all(np.isfinite(a["maps"])) and a["maps"].min() >= 0
        assert ("maps_from_sparse" in a) == (o.case.preset == "paper"), o.case.label  # the ablation: paper only
        # occlusion bands are excluded from every region
        m = o.metrics
        assert m["regions/all"] == int(np.sum(np.isfinite(a["sigma_gt"]) & ~a["occlusion"]))
        assert m["regions/textured"] <= m["regions/all"] and m["occlusion_pixels_excluded"] >= 0
    first = fig6.one(scene_set="paper_cameras", preset="paper", encoding="srgb")
    assert first.metrics["occlusion_pixels_excluded"] > 0


@pytest.mark.parametrize("preset", ["paper", "robust"])
def test_fig6_alpha_sweep_matches_the_pipeline(preset):
    """The shared-stage sweep gives estimate_defocus_map's map for the same α and preset (no re-implementation drift)."""
    from experiments.fig6_alpha_sweep import QUICK, sweep_alpha
    from method import DefocusParams, estimate_defocus_map
    from scenes import render_scene

    r = render_scene(QUICK.scene_sets[0][1][0], preset=QUICK.preset, f_number=QUICK.f_number, progress=False)
    img = r.image(encoding="srgb", quantize_bits=QUICK.quantize_bits)
    params = DefocusParams.preset(preset)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sweep = sweep_alpha(img, (0.2, 0.5), params if preset != "paper" else None)
        ref = estimate_defocus_map(img, params.replace(alpha=0.5))
    np.testing.assert_array_equal(sweep.edges, ref.edges)
    np.testing.assert_allclose(sweep.refined_sigma, ref.refined_sigma, rtol=0, atol=tol.FIG6_PIPELINE_MATCH_ATOL_PX)
    np.testing.assert_allclose(sweep.maps[1], ref.defocus_map, rtol=0, atol=tol.FIG6_PIPELINE_MATCH_ATOL_PX)


# --- method presets and scene sets ---------------------------------------------------------------
@pytest.mark.parametrize("module", FIGURE_MODULES)
def test_configs_run_paper_and_robust_on_every_scene_set(module):
    import importlib

    from experiments.scene_sets import PROCEDURAL_TEST, check_scene_sets

    mod = importlib.import_module(f"experiments.{module}")
    for mode in ("quick", "full"):
        cfg = mod.FIGURE.config(mode)
        assert cfg.presets == ("paper", "robust"), (module, mode)
        sets = check_scene_sets(cfg.scene_sets)
        assert [s for s, _ in sets] == ["paper_cameras", "tabletop_stress", PROCEDURAL_TEST], (module, mode)
        assert all(c.preset in cfg.presets for c in mod.FIGURE.cases(cfg) if c.preset is not None)


def test_method_presets_validates_names():
    from experiments.cases import method_presets
    from method import DefocusParams

    got = method_presets(("paper", "robust"))
    assert list(got) == ["paper", "robust"] and got["paper"] == DefocusParams()
    assert list(method_presets(("robust",))) == ["robust"]
    for bad in ((), ("paper", "paper"), ("paper", "nope")):
        with pytest.raises(ValueError, match="preset"):
            method_presets(bad)


def test_scene_sets_are_checked():
    from experiments.scene_sets import check_scene_sets, procedural_test_scenes

    assert procedural_test_scenes(2) == ("procedural_100000", "procedural_100001")
    with pytest.raises(ValueError, match="invalid for scene set 'paper_cameras'"):
        check_scene_sets([("paper_cameras", ("planes",))])
    with pytest.raises(ValueError, match="invalid for scene set 'procedural_test'"):
        check_scene_sets([("procedural_test", ("procedural_5",))])  # a dev seed is not in the test split
    with pytest.raises(ValueError, match="scene_set='nope'"):
        check_scene_sets([("nope", ("planes",))])
    with pytest.raises(ValueError, match="appears twice"):
        check_scene_sets([("tabletop_stress", ("planes",)), ("tabletop_stress", ("portrait",))])


def test_fig6_robust_results(fig6):
    """Every scene, encoding and α has the robust preset's dense-map MAE / bias per region, as the paper's."""
    cfg = fig6.config
    for paper in fig6.find(preset="paper"):
        c = paper.case
        rob = fig6.one(scene_set=c.scene_set, scene=c.scene, preset="robust", encoding=c.encoding)
        assert rob.metrics["alpha_applies"] is True
        for a in cfg.alphas:
            row, prow = rob.nested()[f"alpha={a:g}"], paper.nested()[f"alpha={a:g}"]
            assert set(row) == set(prow)  # the paper's metric names
            for region in ("all", "textured", "edges"):
                assert _finite(row[f"{region}_mae"]) and row[f"{region}_mae"] > 0, (c.label, a, region)
                assert _finite(row[f"{region}_bias"]), (c.label, a, region)
        assert "from_sparse" not in rob.nested()


def _mean(fd, metric, **fields):
    vals = [o.metrics[metric] for o in fd.find(**fields)]
    return float(np.mean(vals))


def test_robust_dense_map_beats_the_paper(fig6, fig7, fig11):
    """Measured finding (beyond the paper): on the hand-built scenes the robust preset's dense map is closer to
    σ_gt than the paper's.

    Quick figures (small renders), paper_cameras: fig6 sRGB α = 0.5 MAE and fig11 MAE, means over the
    scenes; fig7's f/4 map MAE per scene. (fig11's mean signed error is not asserted: with the edge fit in
    linear light robust's is +0.12 px against the paper's +0.09 px on these small renders, measured
    2026-12-04.)
    """
    s = "paper_cameras"
    assert _mean(fig6, "alpha=0.5/all_mae", scene_set=s, encoding="srgb", preset="robust") < \
        _mean(fig6, "alpha=0.5/all_mae", scene_set=s, encoding="srgb", preset="paper")
    assert _mean(fig11, "all_mae", scene_set=s, preset="robust") < _mean(fig11, "all_mae", scene_set=s, preset="paper")
    for paper in fig7.find(scene_set=s, preset="paper"):
        rob = fig7.one(scene_set=s, scene=paper.case.scene, preset="robust")
        key = "maps_vs_gt_large/map_large/mae"
        assert rob.metrics[key] < paper.metrics[key], paper.case.scene


def test_fig6_larger_alpha_keeps_the_map_closer_to_the_measures(fig6):
    """Paper Sec. 4 / Fig. 6: the data term's fidelity at edge pixels grows monotonically with α."""
    alphas = sorted(fig6.config.alphas)
    for o in fig6.find(preset="paper"):
        m = o.nested()
        for source in ("refined", "from_sparse"):
            mm = m if source == "refined" else m["from_sparse"]
            rms = [mm[f"alpha={a:g}"]["edge_rms_to_bm"] for a in alphas]
            assert all(b <= a + tol.FIG6_FIDELITY_MONOTONE_ATOL_PX for a, b in zip(rms, rms[1:])), (o.case.label, source, rms)
            assert rms[-1] < rms[0], (o.case.label, source, rms)


def test_fig6_refinement_makes_alpha_nearly_irrelevant(fig6):
    """Measured finding: after Eq. (3) the maps for α = 0.1 … 1 differ little; without it they differ a lot."""
    for o in fig6.find(preset="paper"):
        a = o.arrays()
        spread = float(np.abs(a["maps"][0] - a["maps"][-1]).max())
        assert spread < tol.FIG6_REFINED_ALPHA_SPREAD_MAX_PX, (o.case.label, spread)
        assert float(np.abs(a["maps_from_sparse"][0] - a["maps_from_sparse"][-1]).max()) > spread


def test_fig6_eq4_terms_trade_off_and_map_change_is_measured(fig6):
    """Eq. (4) minimised exactly: as α grows the data term cannot rise and the smoothness term cannot
    fall (slack: 1 % of the change, for the iterative solve and the [0, max_sigma] clip); the recorded
    map change is mean |map(α_max) − map(α_min)| over the stored maps."""
    cfg = fig6.config
    for o in fig6.outputs.values():
        em = o.nested()
        alphas = sorted(em["energy_terms"], key=lambda k: float(k.split("=")[1]))
        for term, sign in (("data_term", -1), ("smoothness_term", 1)):
            xs = [em["energy_terms"][a][term] for a in alphas]
            slack = 0.01 * abs(xs[-1] - xs[0])
            assert all(sign * (y - x) >= -slack for x, y in zip(xs, xs[1:])), (o.case.label, term, xs)
        ch = em["map_change_px"]
        assert ch["textured_mean"] >= 0 and ch["all_mean"] >= 0
        assert [ch["alphas"]["0"], ch["alphas"]["1"]] == [min(cfg.alphas), max(cfg.alphas)]
    o = fig6.one(scene_set="paper_cameras", preset="paper", encoding=cfg.plot_encoding)
    a = o.arrays()
    lo, hi = int(np.argmin(cfg.alphas)), int(np.argmax(cfg.alphas))
    keep = np.isfinite(a["sigma_gt"]) & ~a["occlusion"]
    assert o.metrics["map_change_px/all_mean"] == pytest.approx(
        float(np.mean(np.abs(a["maps"][hi] - a["maps"][lo])[keep])), rel=1e-3, abs=1e-6)


def test_fig6_golden(fig6, goldens):
    """Every watched row of the quick fig6 (all presets and scene sets) vs tests/golden/fig6_quick.json."""
    from tests.golden import golden_values

    goldens.check("fig6_quick", golden_values("fig6_quick", fig6.rows()))


# --- fig7 ---------------------------------------------------------------------------------------
def test_fig7_cases_stage_then_presets(fig7):
    """Per scene one stage case (renders, the preset-independent rows) and one case per preset reading it."""
    cfg = fig7.config
    for set_name, scenes in cfg.scene_sets:
        for scene in scenes:
            stage = fig7.one(scene_set=set_name, scene=scene, variant="stage")
            assert stage.case.preset is None and set(stage.nested()["maps_vs_gt_large"]) == {
                "k_x_gt_small_naive", "gt_small_doubled_filter_aware"}
            for p in cfg.presets:
                o = fig7.one(scene_set=set_name, scene=scene, preset=p)
                assert o.case.needs == (stage.case,)
                m = o.nested()
                for key in ("map_small", "k_x_map_small", "map_large"):
                    assert _finite(m["maps_vs_gt_large"][key]["mae"]) and _finite(m["maps_vs_gt_large"][key]["bias"])
                for key in ("magnified_estimated", "magnified_estimated_subtract"):
                    assert _finite(m["image_vs_large"][key]["psnr_db"]) and 0 < m["image_vs_large"][key]["ssim"] <= 1
                # no copy of a preset-independent row in a preset's case: each measured value is one row
                assert "unchanged_small" not in m["image_vs_large"] and "k_x_gt_small_naive" not in m["maps_vs_gt_large"]
                shape = stage.arrays()["image_small"].shape
                a = o.arrays()
                for key in ("map_small", "map_large", "map_small_subtract"):
                    assert a[key].shape == shape[:2] and np.all(np.isfinite(a[key])), key
                for key in ("magnified", "magnified_subtract", "magnified_scatter"):
                    assert a[key].shape == shape


def test_fig7_rows_per_renderer_and_the_occlusion_band(fig7):
    """Every scene has the scatter's estimated and oracle rows beside the gather's, and every row its
    PSNR / SSIM in focus, defocused and in the f/4 render's occlusion band (the stored band's pixels)."""
    assert list(fig7.config.renderers) == ["gather", "scatter"]
    for stage in fig7.find(variant="stage"):
        s = stage.nested()
        assert s["occlusion_pixels"] == int(stage.arrays()["occlusion"].sum()) > 0
        for o in fig7.find(scene_set=stage.case.scene_set, scene=stage.case.scene, variant=None):
            q = {**s["image_vs_large"], **o.nested()["image_vs_large"]}
            for row in ("magnified_estimated", "magnified_oracle_srgb", "magnified_oracle_linear"):
                for key in (row, f"{row}_scatter"):
                    for metric in ("psnr_db", "psnr_occlusion_db", "psnr_in_focus_db", "psnr_defocused_db"):
                        assert _finite(q[key][metric]) or q[key][metric] == float("inf"), (o.case.label, key, metric)
                    for metric in ("ssim", "ssim_occlusion", "ssim_in_focus", "ssim_defocused"):
                        assert 0 < q[key][metric] <= 1, (o.case.label, key, metric)


def test_fig7_each_preset_scores_its_own_magnification(fig7):
    """The paper preset's default row is its gather + clamp row; robust's is its scatter with the estimated
    floor, which keeps the in-focus pixels closer to the f/4 render than the literal clamp on every scene."""
    for o in fig7.find(variant=None):
        m = o.nested()
        q, flags = m["image_vs_large"], {k for k, v in m["default_magnification"].items() if v}
        if o.case.preset == "paper":
            assert flags == {"renderer_gather", "floor_clamp"}
            assert q["magnified_estimated_default"] == q["magnified_estimated"]
        else:
            assert flags == {"renderer_scatter", "floor_auto"}
            assert q["magnified_estimated_default"]["psnr_in_focus_db"] > q["magnified_estimated"]["psnr_in_focus_db"], \
                o.case.label


def test_fig7_scatter_closer_to_the_lens_with_the_oracle_map(fig7):
    """Measured finding: with the true map on the 8-bit sRGB f/8 input, the scatter renderer (linear light,
    disks, occlusion layers) is closer to the real f/4 render than the gather, overall and in the
    occlusion band, on every quick hand-built scene (e.g. portrait_garden 40.2 → 44.0 dB, band 35.3 →
    39.7 dB)."""
    for stage in fig7.find(variant="stage", scene_set=("paper_cameras", "tabletop_stress")):
        q = stage.nested()["image_vs_large"]
        g, s = q["magnified_oracle_srgb"], q["magnified_oracle_srgb_scatter"]
        assert s["psnr_db"] > g["psnr_db"] + 1.0, (stage.case.scene, g["psnr_db"], s["psnr_db"])
        assert s["psnr_occlusion_db"] > g["psnr_occlusion_db"] + 1.0, (stage.case.scene, g, s)


def test_fig7_doubled_f8_map_is_closer_to_f4_truth(fig7):
    """Paper Fig. 7: 2 × (f/8 map) is closer to the f/4 ground truth than the f/8 map is (hand-built scenes)."""
    for o in fig7.find(preset="paper", scene_set=("paper_cameras", "tabletop_stress")):
        mm = o.nested()["maps_vs_gt_large"]
        assert mm["k_x_map_small"]["mae"] < mm["map_small"]["mae"], (o.case.scene, mm["k_x_map_small"], mm["map_small"])


def test_fig7_magnified_f8_is_closer_to_real_f4(fig7):
    """Paper Fig. 7: the f/8 render magnified ×2 is closer to the real f/4 render than the f/8 render is.

    Holds in SSIM and in the PSNR of the defocused regions on the tabletop stress scenes (quick); the
    whole-image PSNR does *not* improve (the estimated map's in-focus floor over-blurs sharp texture —
    reported in the rows). Not asserted on paper_cameras: at the small preset (σ_gt ≤ 2 px at f/4)
    the magnified portrait_garden has the lower SSIM (0.899 vs 0.913 unchanged); the claims table
    reports that verdict.
    """
    for o in fig7.find(scene_set="tabletop_stress", preset="paper"):
        stage = fig7.one(scene_set="tabletop_stress", scene=o.case.scene, variant="stage")
        base = stage.nested()["image_vs_large"]["unchanged_small"]
        mag = o.nested()["image_vs_large"]["magnified_estimated"]
        assert mag["ssim"] > base["ssim"], (o.case.scene, base, mag)
        assert mag["psnr_defocused_db"] > base["psnr_defocused_db"], (o.case.scene, base, mag)


def test_fig7_upper_bound_and_truth_consistency(fig7):
    """The oracle (σ_d = c/4) magnification bounds the estimated one; filter-aware doubling reproduces σ_gt(f/4)."""
    for o in fig7.find(preset="paper"):
        stage = fig7.one(scene_set=o.case.scene_set, scene=o.case.scene, variant="stage").nested()
        q = {**stage["image_vs_large"], **o.nested()["image_vs_large"]}
        for metric in ("psnr_db", "ssim"):
            assert q["magnified_oracle_srgb"][metric] > q["magnified_estimated"][metric], (o.case.label, metric)
            assert q["magnified_oracle_srgb"][metric] > q["unchanged_small"][metric], (o.case.label, metric)
        mm = stage["maps_vs_gt_large"]
        assert mm["gt_small_doubled_filter_aware"]["mae"] < tol.FIG7_DOUBLED_TRUTH_ATOL_PX
        assert mm["k_x_gt_small_naive"]["bias"] > 0  # naive doubling also doubles the filter σ


def test_fig7_doubled_map_vs_f4_map_is_measured_on_the_maps(fig7):
    """k_x_map_small_vs_map_large is the MAE of k × map(f/8) against map(f/4) over the evaluated pixels."""
    k = fig7.config.factor
    for o in fig7.find(preset="paper"):
        mask = fig7.one(scene_set=o.case.scene_set, scene=o.case.scene, variant="stage").arrays()["mask"].astype(bool)
        a = o.arrays()
        d = np.abs(k * a["map_small"].astype(np.float64) - a["map_large"])[mask]
        assert o.metrics["k_x_map_small_vs_map_large/mae"] == pytest.approx(float(d.mean()), rel=1e-4), o.case.label


def test_render_in_front_is_depth_before_the_focus_plane():
    """Render.in_front = depth < the camera's focus distance (from the sidecar), False where the ray missed;
    a procedural scene has pixels on both sides of the focus plane."""
    from scenes import render_scene

    r = render_scene("procedural_100000", preset="small", f_number=8.0, seed=0, progress=False)
    depth = np.asarray(r.depth, dtype=np.float64)
    focus = float(r.metadata["camera"]["focus_distance_m"])
    expected = np.isfinite(depth) & (depth < focus)
    np.testing.assert_array_equal(r.in_front, expected)
    assert r.in_front.dtype == bool and 0 < r.in_front.mean() < 1


def test_fig7_oracle_rows_are_told_what_is_in_front(monkeypatch):
    """The oracle magnifications of a renderer that models occlusion receive the pair's in_front mask (both
    the sRGB and the linear oracle); the gather, which has no occlusion, receives none."""
    from experiments import fig7_doubled_defocus as f7

    calls = []

    def spy(image, defocus_map, *, renderer, in_front=None, **kwargs):
        calls.append((renderer, in_front))
        return np.array(image, dtype=np.float64)

    monkeypatch.setattr("method.magnify_defocus", spy)
    shape = (12, 16)
    rng = np.random.default_rng(0)
    front = np.zeros(shape, bool)
    front[:4] = True
    gt = np.full(shape, 1.0)
    flags = np.ones(shape, bool)
    pair = f7._RenderedPair(image_small=rng.random((*shape, 3)), image_large=rng.random((*shape, 3)),
                            linear_small=rng.random((*shape, 3)), gt_small=gt, gt_large=2 * gt,
                            defocus_small=np.sqrt(gt**2 - 1 / 12), mask=flags, in_focus=~flags, defocused=flags,
                            occlusion=~flags, in_front=front)
    f7._preset_independent(pair, f7.QUICK)
    assert [r for r, _ in calls] == ["gather", "gather", "scatter", "scatter"]
    assert [f is None for _, f in calls[:2]] == [True, True]
    for _, f in calls[2:]:
        np.testing.assert_array_equal(f, front)


def test_fig7_oracle_scatter_with_in_front_is_no_worse(fig7):
    """On every quick scene the stored in_front mask is the f/8 render's depth < focus distance, and the
    scatter oracle told what is in front is at least as close to the f/4 render as the same oracle without
    it (measured on the quick scenes: +0.0 to +0.46 dB overall, up to +0.9 dB in the occlusion band; the
    procedural scenes, 20–24 % of their pixels in front, gain +0.16 / +0.46 dB)."""
    from experiments import fig7_doubled_defocus as f7
    from scenes import render_scene
    from scenes.render import FILTER_SIGMA_PX

    cfg = fig7.config
    for stage in fig7.find(variant="stage"):
        a = stage.arrays()
        r = render_scene(stage.case.scene, preset=cfg.preset, f_number=cfg.f_number_small_aperture,
                         seed=cfg.render_seed, progress=False)
        front = a["in_front"].astype(bool)
        np.testing.assert_array_equal(front, np.asarray(r.depth, np.float64) < r.camera.focus_distance_m)
        assert stage.nested()["in_front_pixels"] == int(front.sum())
        pair = f7._RenderedPair(linear_small=None, defocus_small=None, **{k: a[k] for k in f7._PAIR_FIELDS})
        gt = a["gt_small"].astype(np.float64)
        oracle = np.where(np.isfinite(gt), np.sqrt(np.maximum(gt**2 - FILTER_SIGMA_PX**2, 0.0)), 0.0)
        with_, without = (f7._score_image(f7._magnify(a["image_small"], oracle, cfg, "scatter", preprocess=False,
                                                      in_front=f), pair) for f in (front, None))
        assert with_["psnr_db"] >= without["psnr_db"] - 1e-6, (stage.case.label, with_["psnr_db"], without["psnr_db"])
        if stage.case.scene_set == "procedural_test":  # an object well in front of the focus in every layout
            assert with_["psnr_db"] > without["psnr_db"] + 0.1, (stage.case.label, with_, without)
        # the stored row is the one told what is in front
        stored = stage.nested()["image_vs_large"]["magnified_oracle_srgb_scatter"]["psnr_db"]
        assert stored == pytest.approx(with_["psnr_db"], abs=1e-3), stage.case.label


def test_fig7_golden(fig7, goldens):
    """Every watched row of the quick fig7 (all presets and scene sets) vs tests/golden/fig7_quick.json."""
    from tests.golden import golden_values

    goldens.check("fig7_quick", golden_values("fig7_quick", fig7.rows()))


# --- fig11 --------------------------------------------------------------------------------------
def test_fig11_items_and_outputs(fig11):
    cfg = fig11.config
    assert fig11.values("scene", variant="photo") == list(cfg.photos) and len(cfg.photos) >= 3
    assert fig11.values("scene", scene_set="paper_cameras") == list(dict(cfg.scene_sets)["paper_cameras"])
    for o in fig11.outputs.values():
        a, m = o.arrays(), o.metrics
        img, dmap, out = a["input"], a["map"], a["magnified"]
        assert img.shape[:2] == dmap.shape == out.shape[:2] and img.shape[2] == 3
        assert np.all(np.isfinite(dmap)) and dmap.min() >= 0 and 0 <= out.min() and out.max() <= 1
        assert o.info["timings"]["estimate_wall_s"] > 0 and 0 < m["edge_fraction"] < 1
        if o.case.variant == "photo":
            assert max(img.shape[:2]) <= cfg.photo_max_side and "all_mae" not in m
        else:
            assert np.isfinite(m["all_mae"]) and m["all_mae"] > 0 and _finite(m["textured_mae"])
            assert set(m) == set(fig11.one(scene_set=o.case.scene_set, scene=o.case.scene, preset="paper").metrics)


def test_fig11_load_photo_rejects_unknown():
    from experiments.fig11_gallery import load_photo

    with pytest.raises(ValueError, match="unknown"):
        load_photo("no_such_photo")
    with pytest.raises(ValueError, match="RGB"):
        load_photo("camera")  # greyscale
    img, s = load_photo("chelsea", 100)
    assert max(img.shape[:2]) == 100 and 0 < s < 1 and img.dtype == np.float64


def test_fig11_golden(fig11, goldens):
    """Every watched row of the quick fig11 (all presets and scene sets) vs tests/golden/fig11_quick.json."""
    from tests.golden import golden_values

    goldens.check("fig11_quick", golden_values("fig11_quick", fig11.rows()))


# --- plots through the CLI ----------------------------------------------------------------------
def test_cli_plots_fig11_from_the_cache(tmp_path, fig11):
    """``repro.figures fig11 --quick --preset robust`` writes PNG + PDF + metrics per scene set and the table.

    ``--preset robust`` gives ("paper", "robust"), the quick config's own presets, so every case comes from
    the cache (the fixture computed them). One figure: running several figures in one call is tested on
    fig2 + fig10 (tests/test_figures.py); fig6's and fig7's plots are drawn in process below.
    """
    import json

    from experiments.results_query import read_table

    env = os.environ.copy()
    proc = subprocess.run([sys.executable, "-m", "repro.figures", "fig11", "--quick", "--preset", "robust",
                           "--workers", "1", "--out", str(tmp_path)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    for stem in ("fig11", "fig11_tabletop_stress", "fig11_procedural_test"):
        for ext in (".png", ".pdf"):
            path = tmp_path / f"{stem}{ext}"
            assert path.is_file() and path.stat().st_size > 1000, path
    info = json.loads((tmp_path / "fig11.metrics.json").read_text())
    assert info["config"]["presets"] == ["paper", "robust"] and info["cache"]["hit"] is True
    assert info["cases"] == [c.label for c in fig11.outputs] and info["evaluation_id"] == fig11.evaluation_id
    assert len(read_table(tmp_path).where(figure="fig11")) == len(fig11.rows())
    assert proc.stdout.count(": cached") == 1


@pytest.mark.parametrize("name", ["fig6", "fig7"])
def test_plot_of_one_scene_set(tmp_path, quick_figure, name):
    """``repro.figures.write_figure`` draws fig6 / fig7 (PNG + PDF + metrics) from the quick cases of one scene
    set, the procedural test split, drawn as the default set (every set is drawn by the same
    ``plot_one_set``; :func:`experiments.plotting.style.plot_scene_sets`, which names the further sets' files,
    is exercised by the CLI test above)."""
    import json

    from experiments.figure_data import FigureData
    from repro.figures import write_figure

    fd = quick_figure(name)
    one = FigureData(fd.figure, fd.config, {c: o for c, o in fd.outputs.items() if c.scene_set == "procedural_test"},
                     fd.mode)
    assert 0 < len(one.outputs) < len(fd.outputs)
    got = write_figure(one, tmp_path)
    assert [Path(f).name for f in got["files"]] == [f"{name}.png", f"{name}.pdf", f"{name}.metrics.json"]
    assert (tmp_path / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / f"{name}.pdf").read_bytes()[:5] == b"%PDF-"
    assert all((tmp_path / f"{name}{ext}").stat().st_size > 10_000 for ext in (".png", ".pdf"))
    info = json.loads((tmp_path / f"{name}.metrics.json").read_text())
    assert info["cases"] == [c.label for c in one.outputs] and info["cache"]["cases"] == len(one.outputs)
