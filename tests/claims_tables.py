"""Made-up rows of the long results table for the claims' tests: each figure's cases as its compute would
give them (the metric paths of docs/results-schema.md), with the numbers a test chooses."""

from __future__ import annotations

SET = "paper_cameras"


def rows(figure: str, cases, *, mode: str = "quick") -> list[dict]:
    """Rows of ``figure``: ``cases`` = ``[(case ids, nested metrics)]``."""
    from experiments.metric_paths import flatten
    from experiments.results_table import metric_rows

    out = []
    for ids, metrics in cases:
        out += metric_rows({"evaluation_id": f"{figure}-{mode}-0000abcd", "source": "figures", "figure": figure, **ids},
                           flatten(metrics))
    return out


def fig10(err=0.01):
    return rows("fig10", [({"variant": "paper"}, {"max_rel_err": err, "n_points": 12})])


def fig10_procedural(*errs, scene_set="procedural_test"):
    return rows("fig10", [({"scene_set": scene_set, "scene": f"procedural_{100000 + i}", "aperture": 4.0},
                           {"max_rel_err": e, "n_points": 3}) for i, e in enumerate(errs)])


def fig2(err=0.01):
    return rows("fig2", [({}, {"measured_ratio_median": 3.0, "eq6_ratio": 3.0, "sensor_width_ratio": 3.1,
                               "max_ratio_rel_err": err})])


def fig4(clean=0.05, curved=0.05, noisy=0.1, cases=None, mf_mae=1.0, zc_mae=2.0, mf_med=0.5, zc_med=0.8, *,
         preset="paper", fit="model_fit", scene_set=SET):
    """Analytic steps (no scene set), neighbouring edges (``cases``: name → (fit, zero crossing) median
    relative errors) and the pooled rendered comparison of ``scene_set``."""
    if cases is None:
        cases = {f"D={i}sigma": (0.1, 0.3) for i in range(5)}
    base = {"preset": preset}
    out = []
    for fam, m in (("straight", {"clean": {"median_ae": clean, "n": 50}, "noisy": {"median_ae": noisy}}),
                   ("curved", {"clean": {"median_ae": curved, "n": 50}})):
        out += rows("fig4", [({**base, "variant": f"analytic:{fam}", "estimator": fit}, m)])
    for est, i in ((fit, 0), ("zero_crossing", 1)):
        out += rows("fig4", [({**base, "variant": "analytic:neighbouring", "estimator": est},
                              {"bar": {"noisy": {k: {"median_rel_error": v[i]} for k, v in cases.items()}}})])
    for est, mae, med in ((fit, mf_mae, mf_med), ("zero_crossing", zc_mae, zc_med)):
        out += rows("fig4", [({**base, "scene_set": scene_set, "variant": "pooled", "encoding": "srgb", "estimator": est},
                              {"line_spread": {"mae": mae, "median_ae": med, "outlier_fraction": 0.1}})])
    return out


def fig5(outliers=((0.2, 0.05), (0.1, 0.02)), maes=((1.0, 0.9), (1.0, 0.95)), *, scene_set=SET,
         outlier_scene=True):
    """Stage cases ``shadow_gloss`` at f/8, f/4, …: (before, after) in-focus outlier fractions and MAEs."""
    cases = {}
    for i, (b, a) in enumerate(outliers):
        cases.setdefault(i, {})["before"] = {"in_focus_outliers": {"fraction": b}}
        cases[i]["after_bias"] = {"in_focus_outliers": {"fraction": a}}
    for i, (b, a) in enumerate(maes):
        cases.setdefault(i, {}).setdefault("before", {})["mae"] = b
        cases[i].setdefault("after_bias", {})["mae"] = a
    return rows("fig5", [({"scene_set": scene_set, "scene": "shadow_gloss", "aperture": float(2 ** (i + 1)),
                           "variant": "stages"}, {**m, "outlier_scene": outlier_scene}) for i, m in cases.items()])


def fig6_scene(change=0.5, data=(1.0, 0.6, 0.3, 0.1), smooth=(0.01, 0.02, 0.04, 0.08), alpha_applies=True):
    terms = {f"alpha={a:g}": {"data_term": d, "smoothness_term": s}
             for a, d, s in zip((0.1, 0.2, 0.5, 1.0), data, smooth)}
    return {"energy_terms": terms, "map_change_px": {"textured_mean": change, "all_mean": change / 2},
            "alpha_applies": alpha_applies}


def fig6(*scenes, preset="paper", scene_set=SET):
    scenes = scenes or (fig6_scene(),)
    return rows("fig6", [({"scene_set": scene_set, "scene": f"s{i}", "preset": preset, "aperture": 4.0,
                           "encoding": "srgb"}, m) for i, m in enumerate(scenes)])


def fig11(*scenes, preset="paper", scene_set=SET):
    scenes = scenes or ((0.1, 0.5),)
    out = rows("fig11", [({"scene_set": scene_set, "scene": f"s{i}", "preset": preset, "aperture": 8.0},
                          {"textured_bias": b, "textured_mae": m, "all_bias": b - 2, "all_mae": m + 2})
                         for i, (b, m) in enumerate(scenes)])
    return out + rows("fig11", [({"scene": "x", "preset": preset, "variant": "photo"}, {"map_mean_px": 1.0})])


def fig7_scene(agree=0.1, err_doubled=0.1, err_f4=0.1, base=(30.0, 0.80), mag=(31.0, 0.85),
               in_focus=(99.0, 40.0), defocused=(28.0, 29.0)):
    """(stage metrics, preset metrics) of one Fig. 7 scene."""
    stage = {"image_vs_large": {"unchanged_small": {"psnr_db": base[0], "ssim": base[1], "psnr_in_focus_db": in_focus[0],
                                                    "psnr_defocused_db": defocused[0]}}}
    preset = {"k_x_map_small_vs_map_large": {"median_rel_error": agree, "mae": 0.3},
              "maps_vs_gt_large": {"k_x_map_small": {"median_rel_error": err_doubled, "mae": 0.4},
                                   "map_large": {"median_rel_error": err_f4, "mae": 0.4}},
              "image_vs_large": {"magnified_estimated": {"psnr_db": mag[0], "ssim": mag[1],
                                                         "psnr_in_focus_db": in_focus[1],
                                                         "psnr_defocused_db": defocused[1]}},
              "map_floor_px": 0.4}
    return stage, preset


def fig7(*scenes, preset="paper", scene_set=SET, with_stage=True):
    scenes = scenes or (fig7_scene(),)
    out = []
    for i, (stage, m) in enumerate(scenes):
        ids = {"scene_set": scene_set, "scene": f"s{i}", "aperture": 8.0, "encoding": "srgb"}
        if with_stage:
            out += rows("fig7", [({**ids, "variant": "stage"}, stage)])
        out += rows("fig7", [({**ids, "preset": preset}, m)])
    return out


def fig8(base=(23.0, 0.66), est=(24.0, 0.70), *, preset="paper", scene_set=SET):
    ids = {"scene_set": scene_set, "scene": "portrait", "aperture": 4.0, "encoding": "srgb"}
    return (rows("fig8", [({**ids, "variant": "stage"},
                           {"images_vs_d2": {"unchanged_d1": {"psnr_db": base[0], "ssim": base[1]}}})])
            + rows("fig8", [({**ids, "preset": preset, "variant": "nsr=0.01"},
                             {"images_vs_d2": {"refocused_estimated": {"psnr_db": est[0], "ssim": est[1]}}})]))


def drop(table: list[dict], metric_prefix: str) -> list[dict]:
    """``table`` without the rows whose metric starts with ``metric_prefix``."""
    return [r for r in table if not r["metric"].startswith(metric_prefix)]
