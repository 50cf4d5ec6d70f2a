"""Figures 6 (α sweep), 7 (doubled defocus) and 11 (gallery): quick computes, paper claims, goldens, plots.

The quick configs use the small render preset (160×120 px); renders and figure results are cached
in ``$DEFOCUS_CACHE_DIR`` so a second run only re-checks them. Each figure runs the method presets
of its config: ``paper`` (the reproduction: the top-level metrics the claims and goldens read) and
``robust`` beside it (``metrics["presets"]["robust"]``).
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


def _quick(module):
    from experiments.registry import compute_cached

    fig = module.FIGURE
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return compute_cached(fig, fig.config("quick")).as_data()


@pytest.fixture(scope="module")
def fig6():
    from experiments import fig6_alpha_sweep

    return _quick(fig6_alpha_sweep)


@pytest.fixture(scope="module")
def fig7():
    from experiments import fig7_doubled_defocus

    return _quick(fig7_doubled_defocus)


@pytest.fixture(scope="module")
def fig11():
    from experiments import fig11_gallery

    return _quick(fig11_gallery)


# --- fig6 ---------------------------------------------------------------------------------------
def test_fig6_shape_and_regions(fig6):
    from experiments.fig6_alpha_sweep import QUICK

    k = len(QUICK.alphas)
    h, w = fig6["sigma_gt"].shape
    assert fig6["maps"].shape == (k, h, w) and np.all(np.isfinite(fig6["maps"])) and fig6["maps"].min() >= 0
    for scene in QUICK.scenes:
        for enc in QUICK.encodings:
            assert fig6[f"maps_{scene}_{enc}"].shape == (k, h, w)
    # occlusion bands are excluded from every region
    m = fig6["metrics"]["scenes"][QUICK.scenes[0]][QUICK.plot_encoding]
    expected_all = int(np.sum(np.isfinite(fig6["sigma_gt"]) & ~fig6["occlusion"]))
    assert m["regions"]["all"] == expected_all and m["occlusion_pixels_excluded"] > 0
    assert m["regions"]["textured"] <= m["regions"]["all"]


@pytest.mark.parametrize("preset", ["paper", "robust"])
def test_fig6_alpha_sweep_matches_the_pipeline(preset):
    """The shared-stage sweep gives estimate_defocus_map's map for the same α and preset (no re-implementation drift)."""
    from experiments.fig6_alpha_sweep import QUICK, sweep_alpha
    from method import DefocusParams, estimate_defocus_map
    from scenes import render_scene

    r = render_scene(QUICK.scenes[0], preset=QUICK.preset, f_number=QUICK.f_number, progress=False)
    img = r.image(encoding="srgb", quantize_bits=QUICK.quantize_bits)
    params = DefocusParams.preset(preset)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sweep = sweep_alpha(img, (0.2, 0.5), params if preset != "paper" else None)
        ref = estimate_defocus_map(img, params.replace(alpha=0.5))
    np.testing.assert_array_equal(sweep.edges, ref.edges)
    np.testing.assert_allclose(sweep.refined_sigma, ref.refined_sigma, rtol=0, atol=tol.FIG6_PIPELINE_MATCH_ATOL_PX)
    np.testing.assert_allclose(sweep.maps[1], ref.defocus_map, rtol=0, atol=tol.FIG6_PIPELINE_MATCH_ATOL_PX)


# --- method presets (paper = the reproduction, robust beside it) ---------------------------------
@pytest.mark.parametrize("module", FIGURE_MODULES)
def test_configs_run_paper_first_then_robust(module):
    import importlib

    mod = importlib.import_module(f"experiments.{module}")
    for mode in ("quick", "full"):
        assert mod.FIGURE.config(mode).presets == ("paper", "robust"), (module, mode)


def test_method_presets_validates_names():
    from experiments.fig6_alpha_sweep import method_presets
    from method import DefocusParams

    got = method_presets(("paper", "robust"))
    assert list(got) == ["paper", "robust"] and got["paper"] == DefocusParams()
    for bad in ((), ("robust",), ("robust", "paper"), ("paper", "paper"), ("paper", "nope")):
        with pytest.raises(ValueError, match="preset"):
            method_presets(bad)


def _finite(x):
    return x is not None and np.isfinite(float(x))


def test_fig6_robust_results(fig6):
    """Every scene, encoding and α has the robust preset's dense-map MAE / bias per region, and its maps."""
    from experiments.fig6_alpha_sweep import QUICK

    k = len(QUICK.alphas)
    h, w = fig6["sigma_gt"].shape
    rob = fig6["metrics"]["presets"]["robust"]
    assert set(fig6["metrics"]["presets"]) == {"robust"} and rob["alpha_applies"] is True
    for scene in QUICK.scenes:
        for enc in QUICK.encodings:
            paper, m = fig6["metrics"]["scenes"][scene][enc], rob["scenes"][scene][enc]
            maps = fig6[f"preset_robust__maps_{scene}_{enc}"]
            assert maps.shape == (k, h, w) and np.all(np.isfinite(maps)) and maps.min() >= 0
            for a in QUICK.alphas:
                row = m[f"alpha={a:g}"]
                assert set(row) == set(paper[f"alpha={a:g}"])  # the paper's metric names
                for region in ("all", "textured", "edges"):
                    assert _finite(row[f"{region}_mae"]) and row[f"{region}_mae"] > 0, (scene, enc, a, region)
                    assert _finite(row[f"{region}_bias"]), (scene, enc, a, region)
        assert "from_sparse" not in rob["summary"][QUICK.plot_encoding]
    assert fig6["preset_robust__maps"].shape == (k, h, w)
    assert fig6["preset_robust__refined"].shape == (h, w)


def test_fig7_robust_results(fig7):
    """Every scene has the robust preset's doubled-map-vs-f/4 comparisons and magnified-image metrics."""
    from experiments.fig7_doubled_defocus import QUICK

    rob = fig7["metrics"]["presets"]["robust"]["scenes"]
    assert set(rob) == set(QUICK.scenes)
    for scene, m in rob.items():
        paper = fig7["metrics"]["scenes"][scene]
        assert set(m["maps_vs_gt_large"]) == set(paper["maps_vs_gt_large"])
        assert set(m["image_vs_large"]) == set(paper["image_vs_large"])
        for key in ("map_small", "k_x_map_small", "map_large"):
            assert _finite(m["maps_vs_gt_large"][key]["mae"]) and _finite(m["maps_vs_gt_large"][key]["bias"])
        for key in ("magnified_estimated", "magnified_estimated_subtract"):
            assert _finite(m["image_vs_large"][key]["psnr_db"]) and 0 < m["image_vs_large"][key]["ssim"] <= 1
        # the preset-independent rows are the paper's
        for key in ("k_x_gt_small_naive", "gt_small_doubled_filter_aware"):
            assert m["maps_vs_gt_large"][key] == paper["maps_vs_gt_large"][key]
        for key in ("unchanged_small", "magnified_oracle_srgb", "magnified_oracle_linear"):
            assert m["image_vs_large"][key] == paper["image_vs_large"][key]
        shape = fig7[f"{scene}__image_small"].shape
        for key in ("map_small", "map_large", "map_small_subtract"):
            a = fig7[f"{scene}__robust__{key}"]
            assert a.shape == shape[:2] and np.all(np.isfinite(a)), key
        for key in ("magnified", "magnified_subtract"):
            assert fig7[f"{scene}__robust__{key}"].shape == shape


def test_fig7_rows_per_renderer_and_the_occlusion_band(fig7):
    """Every scene has the scatter's estimated and oracle rows beside the gather's, and every row its
    PSNR / SSIM in focus, defocused and in the f/4 render's occlusion band (the stored band's pixels)."""
    from experiments.fig7_doubled_defocus import QUICK

    assert fig7["metrics"]["renderers"] == list(QUICK.renderers) == ["gather", "scatter"]
    for scene in QUICK.scenes:
        m = fig7["metrics"]["scenes"][scene]
        q = m["image_vs_large"]
        assert m["occlusion_pixels"] == int(fig7[f"{scene}__occlusion"].sum()) > 0
        for row in ("magnified_estimated", "magnified_oracle_srgb", "magnified_oracle_linear"):
            for key in (row, f"{row}_scatter"):
                for metric in ("psnr_db", "psnr_occlusion_db", "psnr_in_focus_db", "psnr_defocused_db"):
                    assert _finite(q[key][metric]) or q[key][metric] == float("inf"), (scene, key, metric)
                for metric in ("ssim", "ssim_occlusion", "ssim_in_focus", "ssim_defocused"):
                    assert 0 < q[key][metric] <= 1, (scene, key, metric)
            assert fig7[f"{scene}__{row.replace('_estimated', '')}_scatter"].shape == fig7[f"{scene}__image_small"].shape
        rob = fig7["metrics"]["presets"]["robust"]["scenes"][scene]["image_vs_large"]
        assert rob["magnified_oracle_linear_scatter"] == q["magnified_oracle_linear_scatter"]
        assert fig7[f"{scene}__robust__magnified_scatter"].shape == fig7[f"{scene}__image_small"].shape


def test_fig7_scatter_closer_to_the_lens_with_the_oracle_map(fig7):
    """Measured finding: with the true map on the 8-bit sRGB f/8 input, the scatter renderer (linear light,
    disks, occlusion layers) is closer to the real f/4 render than the gather, overall and in the
    occlusion band, on every quick scene (e.g. heron_at_the_lake 36.5 → 39.2 dB, band 34.0 → 36.6 dB)."""
    sets = [fig7["metrics"], *fig7["metrics"].get("scene_sets", {}).values()]
    for metrics in sets:
        for scene, m in metrics["scenes"].items():
            g, s = m["image_vs_large"]["magnified_oracle_srgb"], m["image_vs_large"]["magnified_oracle_srgb_scatter"]
            assert s["psnr_db"] > g["psnr_db"] + 1.0, (scene, g["psnr_db"], s["psnr_db"])
            assert s["psnr_occlusion_db"] > g["psnr_occlusion_db"] + 1.0, (scene, g, s)


def test_fig11_robust_results(fig11):
    """Every rendered scene has the robust preset's dense-map MAE; every item its map and magnified result."""
    items = [str(s) for s in fig11["items"]]
    rob = fig11["metrics"]["presets"]["robust"]
    assert set(rob["items"]) == set(items) and set(rob["summary"]) == set(fig11["metrics"]["summary"])
    for item in items:
        m, paper = rob["items"][item], fig11["metrics"]["items"][item]
        assert set(m) == set(paper), item
        dmap = fig11[f"{item}__robust__map"]
        assert dmap.shape == fig11[f"{item}__map"].shape and np.all(np.isfinite(dmap)) and dmap.min() >= 0
        assert fig11[f"{item}__robust__magnified"].shape == fig11[f"{item}__input"].shape
        if item.startswith("scene:"):
            assert _finite(m["all_mae"]) and m["all_mae"] > 0 and _finite(m["all_bias"]), item
            assert _finite(m["textured_mae"]), item


def test_robust_dense_map_beats_the_paper(fig6, fig7, fig11):
    """Measured finding (beyond the paper): the robust preset's dense map is closer to σ_gt than the paper's.

    Quick figures (small renders), mean over scenes: fig6 sRGB α = 0.5 MAE, fig11 MAE, fig7's f/4 map
    MAE per scene. (fig11's mean signed error is not asserted: with the edge fit in linear light robust's
    is +0.12 px against the paper's +0.09 px on these small renders, measured 2026-12-04.)
    """
    p6, r6 = fig6["metrics"]["summary"]["srgb"], fig6["metrics"]["presets"]["robust"]["summary"]["srgb"]
    assert r6["alpha=0.5"]["all_mae"] < p6["alpha=0.5"]["all_mae"]
    p11, r11 = fig11["metrics"]["summary"], fig11["metrics"]["presets"]["robust"]["summary"]
    assert r11["scenes_mean_all_mae"] < p11["scenes_mean_all_mae"]
    for scene, m in fig7["metrics"]["presets"]["robust"]["scenes"].items():
        paper = fig7["metrics"]["scenes"][scene]["maps_vs_gt_large"]
        assert m["maps_vs_gt_large"]["map_large"]["mae"] < paper["map_large"]["mae"], scene


def test_fig6_larger_alpha_keeps_the_map_closer_to_the_measures(fig6):
    """Paper Sec. 4 / Fig. 6: the data term's fidelity at edge pixels grows monotonically with α."""
    from experiments.fig6_alpha_sweep import QUICK

    alphas = sorted(QUICK.alphas)
    for scene in QUICK.scenes:
        for enc in QUICK.encodings:
            m = fig6["metrics"]["scenes"][scene][enc]
            for source in ("refined", "from_sparse"):
                mm = m if source == "refined" else m["from_sparse"]
                rms = [mm[f"alpha={a:g}"]["edge_rms_to_bm"] for a in alphas]
                assert all(b <= a + tol.FIG6_FIDELITY_MONOTONE_ATOL_PX for a, b in zip(rms, rms[1:])), (scene, enc, source, rms)
                assert rms[-1] < rms[0], (scene, enc, source, rms)


def test_fig6_refinement_makes_alpha_nearly_irrelevant(fig6):
    """Measured finding: after Eq. (3) the maps for α = 0.1 … 1 differ little; without it they differ a lot."""
    from experiments.fig6_alpha_sweep import QUICK

    for scene in QUICK.scenes:
        for enc in QUICK.encodings:
            maps = fig6[f"maps_{scene}_{enc}"]
            raw = fig6[f"maps_from_sparse_{scene}_{enc}"]
            spread = float(np.abs(maps[0] - maps[-1]).max())
            assert spread < tol.FIG6_REFINED_ALPHA_SPREAD_MAX_PX, (scene, enc, spread)
            assert float(np.abs(raw[0] - raw[-1]).max()) > spread


def test_fig6_golden(fig6, goldens):
    """Every watched metric of the quick fig6 (all presets and scene sets) vs tests/golden/fig6_quick.json."""
    from tests.golden import golden_values

    goldens.check("fig6_quick", golden_values("fig6_quick", fig6["metrics"]))


# --- fig7 ---------------------------------------------------------------------------------------
def test_fig7_doubled_f8_map_is_closer_to_f4_truth(fig7):
    """Paper Fig. 7: 2 × (f/8 map) is closer to the f/4 ground truth than the f/8 map is."""
    for scene, m in fig7["metrics"]["scenes"].items():
        mm = m["maps_vs_gt_large"]
        assert mm["k_x_map_small"]["mae"] < mm["map_small"]["mae"], (scene, mm["k_x_map_small"], mm["map_small"])


def test_fig7_magnified_f8_is_closer_to_real_f4(fig7):
    """Paper Fig. 7: the f/8 render magnified ×2 is closer to the real f/4 render than the f/8 render is.

    Holds in SSIM and in the PSNR of the defocused regions on the tabletop stress scenes (quick); the
    whole-image PSNR does *not* improve (the estimated map's in-focus floor over-blurs sharp texture —
    reported in the metrics). Not asserted on paper_cameras: at the small preset (σ_gt ≤ 2 px at f/4)
    the magnified portrait_garden has the lower SSIM (0.899 vs 0.913 unchanged); the claims table
    reports that verdict.
    """
    for scene, m in fig7["metrics"]["scene_sets"]["tabletop_stress"]["scenes"].items():
        q = m["image_vs_large"]
        assert q["magnified_estimated"]["ssim"] > q["unchanged_small"]["ssim"], (scene, q)
        assert q["magnified_estimated"]["psnr_defocused_db"] > q["unchanged_small"]["psnr_defocused_db"], (scene, q)


def test_fig7_upper_bound_and_truth_consistency(fig7):
    """The oracle (σ_d = c/4) magnification bounds the estimated one; filter-aware doubling reproduces σ_gt(f/4)."""
    for scene, m in fig7["metrics"]["scenes"].items():
        q = m["image_vs_large"]
        for metric in ("psnr_db", "ssim"):
            assert q["magnified_oracle_srgb"][metric] > q["magnified_estimated"][metric], (scene, metric)
            assert q["magnified_oracle_srgb"][metric] > q["unchanged_small"][metric], (scene, metric)
        mm = m["maps_vs_gt_large"]
        assert mm["gt_small_doubled_filter_aware"]["mae"] < tol.FIG7_DOUBLED_TRUTH_ATOL_PX
        assert mm["k_x_gt_small_naive"]["bias"] > 0  # naive doubling also doubles the filter σ


def test_fig6_eq4_terms_trade_off_and_map_change_is_measured(fig6):
    """Eq. (4) minimised exactly: as α grows the data term cannot rise and the smoothness term cannot
    fall (slack: 1 % of the change, for the iterative solve and the [0, max_sigma] clip); the recorded
    map change is mean |map(α_max) − map(α_min)| over the textured pixels of the stored maps."""
    from experiments.fig6_alpha_sweep import QUICK

    for scene, per_enc in fig6["metrics"]["scenes"].items():
        for enc in QUICK.encodings:
            em = per_enc[enc]
            alphas = sorted(em["energy_terms"], key=lambda k: float(k.split("=")[1]))
            for term, sign in (("data_term", -1), ("smoothness_term", 1)):
                xs = [em["energy_terms"][a][term] for a in alphas]
                slack = 0.01 * abs(xs[-1] - xs[0])
                assert all(sign * (y - x) >= -slack for x, y in zip(xs, xs[1:])), (scene, enc, term, xs)
            ch = em["map_change_px"]
            assert ch["textured_mean"] >= 0 and ch["all_mean"] >= 0 and ch["alphas"] == [min(QUICK.alphas), max(QUICK.alphas)]
    maps = fig6["maps"]  # plotted scene and encoding, (k, H, W)
    m = fig6["metrics"]["scenes"][QUICK.scenes[0]][QUICK.plot_encoding]["map_change_px"]
    lo, hi = int(np.argmin(QUICK.alphas)), int(np.argmax(QUICK.alphas))
    assert m["all_mean"] == pytest.approx(float(np.mean(np.abs(maps[hi] - maps[lo])[
        np.isfinite(fig6["sigma_gt"]) & ~fig6["occlusion"]])), rel=1e-3, abs=1e-6)


def test_fig7_doubled_map_vs_f4_map_is_measured_on_the_maps(fig7):
    """k_x_map_small_vs_map_large is the MAE of k × map(f/8) against map(f/4) over the evaluated pixels."""
    k = fig7["metrics"]["factor"]
    for scene, m in fig7["metrics"]["scenes"].items():
        mask = fig7[f"{scene}__mask"].astype(bool)
        d = np.abs(k * fig7[f"{scene}__map_small"].astype(np.float64) - fig7[f"{scene}__map_large"])[mask]
        assert m["k_x_map_small_vs_map_large"]["mae"] == pytest.approx(float(d.mean()), rel=1e-4), scene


def test_fig7_golden(fig7, goldens):
    """Every watched metric of the quick fig7 (all presets and scene sets) vs tests/golden/fig7_quick.json."""
    from tests.golden import golden_values

    goldens.check("fig7_quick", golden_values("fig7_quick", fig7["metrics"]))


# --- fig11 --------------------------------------------------------------------------------------
def test_fig11_items_and_outputs(fig11):
    from experiments.fig11_gallery import QUICK

    items = [str(s) for s in fig11["items"]]
    assert items == [f"scene:{s}" for s in QUICK.scenes] + [f"photo:{p}" for p in QUICK.photos]
    assert len(QUICK.photos) >= 3
    for item in items:
        img, dmap, out = fig11[f"{item}__input"], fig11[f"{item}__map"], fig11[f"{item}__magnified"]
        assert img.shape[:2] == dmap.shape == out.shape[:2] and img.shape[2] == 3
        assert np.all(np.isfinite(dmap)) and dmap.min() >= 0 and 0 <= out.min() and out.max() <= 1
        m = fig11["metrics"]["items"][item]
        assert m["timings"]["estimate_wall_s"] > 0 and 0 < m["edge_fraction"] < 1
        if item.startswith("photo:"):
            assert max(img.shape[:2]) <= QUICK.photo_max_side
        else:
            assert np.isfinite(m["all_mae"]) and m["all_mae"] > 0


def test_fig11_load_photo_rejects_unknown():
    from experiments.fig11_gallery import load_photo

    with pytest.raises(ValueError, match="unknown"):
        load_photo("no_such_photo")
    with pytest.raises(ValueError, match="RGB"):
        load_photo("camera")  # greyscale
    img, s = load_photo("chelsea", 100)
    assert max(img.shape[:2]) == 100 and 0 < s < 1 and img.dtype == np.float64


def test_fig11_golden(fig11, goldens):
    """Every watched metric of the quick fig11 (all presets and scene sets) vs tests/golden/fig11_quick.json."""
    from tests.golden import golden_values

    goldens.check("fig11_quick", golden_values("fig11_quick", fig11["metrics"]))


# --- plots through the CLI ----------------------------------------------------------------------
def test_cli_plots_fig6_fig7_fig11(tmp_path, fig6, fig7, fig11):
    """``repro.figures fig6 fig7 fig11 --quick --preset robust`` writes PNG + PDF + metrics.

    ``--preset robust`` gives ("paper", "robust"), the quick configs' own presets, so the compute
    results are the fixtures' cached ones.
    """
    import json

    env = os.environ.copy()
    proc = subprocess.run([sys.executable, "-m", "repro.figures", "fig6", "fig7", "fig11", "--quick", "--preset",
                           "robust", "--out", str(tmp_path)], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    for name in ("fig6", "fig7", "fig11"):
        for ext in (".png", ".pdf", ".metrics.json"):
            path = tmp_path / f"{name}{ext}"
            assert path.is_file() and path.stat().st_size > 1000, path
        info = json.loads((tmp_path / f"{name}.metrics.json").read_text())
        assert info["config"]["presets"] == ["paper", "robust"] and info["cache"]["hit"] is True, name
        assert "robust" in info["metrics"]["presets"], name
    assert proc.stdout.count("cached") == 3



def test_compute_scene_sets_nests_the_other_sets_per_the_contract():
    """experiments.scene_sets: flat keys = the default set, ``scene_set`` names it, ``scene_sets.<name>``
    has the other set's metrics in the same shape (own ``presets``), arrays under ``<name>__``; each set's
    scenes must belong to that set."""
    import dataclasses

    from experiments.scene_sets import check_scene_sets, compute_scene_sets, set_arrays

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Cfg:
        scenes: tuple = ("portrait_garden",)
        scene_set: str = "paper_cameras"
        other_scene_sets: tuple = (("tabletop_stress", (("scenes", ("planes", "portrait")),)),)

    calls = []

    def one(cfg):
        calls.append(cfg)
        return {"maps": np.full(2, len(cfg.scenes)), "metrics": {"scenes": list(cfg.scenes),
                                                                 "presets": {"robust": {"n": len(cfg.scenes)}}}}

    data = compute_scene_sets(one, Cfg())
    m = data["metrics"]
    assert [c.scenes for c in calls] == [("portrait_garden",), ("planes", "portrait")]
    assert m["scene_set"] == "paper_cameras" and m["scenes"] == ["portrait_garden"]
    assert m["scene_sets"] == {"tabletop_stress": {"scenes": ["planes", "portrait"], "presets": {"robust": {"n": 2}},
                                                   "scene_set": "tabletop_stress"}}
    assert data["maps"].tolist() == [1, 1] and data["tabletop_stress__maps"].tolist() == [2, 2]
    stress = set_arrays(data, "tabletop_stress")
    assert stress["maps"].tolist() == [2, 2] and stress["metrics"]["scene_set"] == "tabletop_stress"
    assert "tabletop_stress__maps" not in set_arrays(data, None)
    with pytest.raises(ValueError, match="no scene set"):
        set_arrays(data, "nope")
    with pytest.raises(ValueError, match="not in scene set"):
        check_scene_sets(Cfg(scenes=("planes",)))
    with pytest.raises(ValueError, match="not in scene set 'tabletop_stress'"):
        check_scene_sets(Cfg(other_scene_sets=(("tabletop_stress", (("scenes", ("portrait_garden",)),)),)))
    with pytest.raises(ValueError, match="scene_set"):
        check_scene_sets(Cfg(scene_set="nope"))


@pytest.mark.parametrize("module", ["fig5_cross_bilateral", "fig6_alpha_sweep", "fig7_doubled_defocus", "fig11_gallery"])
def test_figures_default_to_paper_cameras_with_the_tabletop_stress_set(module):
    import importlib

    from experiments.scene_sets import check_scene_sets
    from scenes import SCENE_SETS

    mod = importlib.import_module(f"experiments.{module}")
    for cfg in (mod.FULL, mod.QUICK):
        check_scene_sets(cfg)
        assert cfg.scene_set == "paper_cameras" and set(cfg.scenes) <= set(SCENE_SETS["paper_cameras"])
        assert [name for name, _ in cfg.other_scene_sets] == ["tabletop_stress"]
