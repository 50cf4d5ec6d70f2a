"""The checks of the claims: each a query on one cell's rows of the results table, then a rule.

Every function takes :class:`experiments.results_query.Results` — the rows of the claim's figure for one
(preset, scene set) cell, preset-independent rows included (:func:`experiments.claims.matrix.cell_rows`)
— and returns a :class:`~experiments.claims.core.Verdict`. Metric names are the figures' case metrics
(``/``-separated paths, docs/results-schema.md).
"""

from __future__ import annotations

import math

from .core import (ALPHA_VISIBLE_CHANGE_PX, BIAS_MIN_OUTLIERS_BEFORE, BIAS_MIN_RELATIVE_DROP, DENSE_MAX_ABS_BIAS_PX,
                   DENSE_MAX_MAE_PX, DOUBLING_MAX_MEDIAN_REL_DIFF, DOUBLING_MAX_MEDIAN_REL_ERR, EQ_MAX_REL_ERR,
                   FIT_CLEAN_MAX_MEDIAN_AE_PX, FIT_NOISY_MAX_MEDIAN_AE_PX, NEIGHBOUR_BOTH_FAIL_REL,
                   NEIGHBOUR_PARTLY_FRACTION, NEIGHBOUR_REPRODUCED_FRACTION, PSNR_MARGIN_DB, REFINE_MIN_RELATIVE_GAIN,
                   SHARP_MAX_DROP_DB, SHARP_MIN_PSNR_DB, SMALL_CHANGE_MAX_REL, MissingData, Verdict, closer, compare,
                   err_or_inf, fmt, image_verdict, num)

__all__ = ["alpha_balance", "bias_outliers", "dense_map", "doubled_map", "doubling_verdict", "eq5", "eq6", "fit_name",
           "magnified_close", "model_fit_analytic", "neighbouring_edges", "refinement_small_change", "refocus",
           "rendered_edges", "sharp_stays_sharp"]


def _scenes(r, what: str):
    """``{scene: rows}`` of the rows that name a scene; MissingData when none does."""
    by = {k: v for k, v in r.group("scene").items() if k is not None}
    if not by:
        raise MissingData(f"no scenes with {what}")
    return dict(sorted(by.items()))


# --- optics ---------------------------------------------------------------------------------------
def eq5(r):
    """Eq. (5): every measured CoC within :data:`EQ_MAX_REL_ERR` (all the cell's cameras)."""
    r.require("fig10 rows")
    errs = [num(r.where(evaluation_id=e, scene=s).value("max_rel_err"))
            for e, s in dict.fromkeys((x["evaluation_id"], x["scene"]) for x in r.where(metric="max_rel_err"))]
    if not errs:
        raise MissingData("fig10: no metric max_rel_err")
    err = max(errs)
    n = int(sum(num(x["value"]) for x in r.where(metric="n_points")))
    v = "reproduced" if err <= EQ_MAX_REL_ERR else "not reproduced"
    cams = f" with {len(errs)} cameras" if len(errs) > 1 else ""
    return Verdict(v, f"{n} rendered step edges{cams}: fitted CoC within {100 * err:.2f} % of Eq. (5) (max).",
                   {"max_rel_err": err, "n_points": n, "cameras": len(errs)})


def eq6(r):
    """Eq. (6): the measured large/small-sensor blur ratio within :data:`EQ_MAX_REL_ERR` of Eq. (6)."""
    meas, eq6_ratio = num(r.value("measured_ratio_median")), num(r.value("eq6_ratio"))
    width, err = num(r.value("sensor_width_ratio")), num(r.value("max_ratio_rel_err"))
    v = "reproduced" if err <= EQ_MAX_REL_ERR else "not reproduced"
    return Verdict(v, f"Blur ratio large/small sensor measured {meas:.3f} vs Eq. (6) {eq6_ratio:.3f} "
                      f"(sensor-width ratio {width:.3f}); worst point {100 * err:.2f} % off.",
                   {"measured_ratio": meas, "eq6_ratio": eq6_ratio, "sensor_width_ratio": width, "max_rel_err": err})


# --- Fig. 4 ---------------------------------------------------------------------------------------
def fit_name(r) -> str:
    """The preset's model fit among the cell's estimators (``model_fit``, the robust ``model_fit_checked``)."""
    fits = [e for e in r.distinct("estimator") if isinstance(e, str) and e.startswith("model_fit")]
    if len(fits) > 1:
        raise ValueError(f"several model fits {fits} in one preset's rows")
    return fits[0] if fits else "model_fit"


def model_fit_analytic(r):
    fit = fit_name(r)
    straight = r.where(variant="analytic:straight", estimator=fit).require("fig4 straight steps")
    curved = r.where(variant="analytic:curved", estimator=fit).require("fig4 curved steps")
    clean, noisy = num(straight.value("clean/median_ae")), num(straight.value("noisy/median_ae"))
    curved_clean = num(curved.value("clean/median_ae"))
    n = int(num(straight.value("clean/n")) + num(curved.value("clean/n")))
    ok_clean = clean <= FIT_CLEAN_MAX_MEDIAN_AE_PX and curved_clean <= FIT_CLEAN_MAX_MEDIAN_AE_PX
    ok_noisy = noisy <= FIT_NOISY_MAX_MEDIAN_AE_PX
    v = "reproduced" if ok_clean and ok_noisy else ("partly reproduced" if ok_clean else "not reproduced")
    return Verdict(v, f"Median |error| of model fit ({fit}) on analytic steps: straight {fmt(clean)} px, "
                      f"curved {fmt(curved_clean)} px (clean), straight with noise + 8-bit {fmt(noisy)} px "
                      f"({n} clean edge pixels scored).",
                   {"straight_clean_median_ae": clean, "curved_clean_median_ae": curved_clean,
                    "straight_noisy_median_ae": noisy})


def neighbouring_edges(r):
    fit = fit_name(r)
    rows = r.where(variant="analytic:neighbouring").require("fig4 neighbouring edges")
    mf = rows.where(estimator=fit).metrics()
    zc = rows.where(estimator="zero_crossing").metrics()
    cases = [k[: -len("/median_rel_error")] for k in mf if k.endswith("/median_rel_error")]
    if not cases:
        raise MissingData("fig4: no neighbouring-edge cases")
    errs = {}
    for k in cases:
        if f"{k}/median_rel_error" not in zc:
            raise MissingData(f"fig4 case {k}: no zero_crossing")
        errs[k.replace("/", ".")] = (err_or_inf(mf[f"{k}/median_rel_error"]), err_or_inf(zc[f"{k}/median_rel_error"]))
    no_fit = sorted(k for k, (m, _) in errs.items() if math.isinf(m))
    excluded = sorted(k for k, (m, z) in errs.items() if m > NEIGHBOUR_BOTH_FAIL_REL and z > NEIGHBOUR_BOTH_FAIL_REL)
    judged = {k: e for k, e in errs.items() if k not in excluded}
    if not judged:
        raise MissingData(f"fig4: all {len(errs)} nearby-edge cases have both estimators more than "
                          f"{100 * NEIGHBOUR_BOTH_FAIL_REL:.0f} % off")
    wins = sorted(k for k, (m, z) in judged.items() if m < z)
    n, k = len(judged), len(wins)
    frac = k / n
    v = ("reproduced" if frac >= NEIGHBOUR_REPRODUCED_FRACTION else
         "partly reproduced" if frac > NEIGHBOUR_PARTLY_FRACTION else "not reproduced")
    return Verdict(v, f"Model fit ({fit}) has the lower median relative error in {k} of {n} nearby-edge cases "
                      f"(bars and staircases, 2–6σ apart): {', '.join(wins) or 'none'}; {len(excluded)} of "
                      f"{len(errs)} cases excluded because both estimators are more than "
                      f"{100 * NEIGHBOUR_BOTH_FAIL_REL:.0f} % off"
                      + (f" ({', '.join(excluded)})." if excluded else ".")
                      + (f" The model fit gave no estimate in {len(no_fit)} cases ({', '.join(no_fit)}), counted as "
                         "a failure." if no_fit else ""),
                   {"cases": len(errs), "judged": n, "excluded": excluded, "model_fit_better": k, "fraction": frac,
                    "model_fit_no_estimate": no_fit})


def rendered_edges(r):
    fit = fit_name(r)
    pooled = r.where(variant="pooled", encoding="srgb").require("fig4 pooled rendered edges")
    mf = pooled.where(estimator=fit).nested("line_spread")
    zc = pooled.where(estimator="zero_crossing").nested("line_spread")
    if not mf or not zc:
        raise MissingData("fig4 pooled: no line_spread metrics of the model fit and the zero crossing")
    mae, med = (num(mf["mae"]), num(zc["mae"])), (num(mf["median_ae"]), num(zc["median_ae"]))
    better_mae, better_med = mae[0] < mae[1], med[0] < med[1]
    v = "reproduced" if better_mae and better_med else ("partly reproduced" if better_mae else "not reproduced")
    return Verdict(v, f"Rendered scenes (sRGB input, edge pixels off occlusion boundaries): model fit ({fit}) MAE "
                      f"{fmt(mae[0])} px / median {fmt(med[0])} px vs zero crossing "
                      f"{fmt(mae[1])} / {fmt(med[1])} px; outliers >1 px "
                      f"{fmt(mf.get('outlier_fraction'))} vs {fmt(zc.get('outlier_fraction'))}.",
                   {"model_fit": mf, "zero_crossing": zc})


# --- Fig. 5 ---------------------------------------------------------------------------------------
def _fig5_cases(r, *, outliers_only: bool) -> dict:
    out = {}
    for o in r.where(variant="stages").group("scene", "aperture").values():
        if outliers_only and not o.get("outlier_scene"):
            continue
        row = o.rows[0]
        out[f"{row['scene']}_f{row['aperture']:g}"] = o.metrics()
    return out


def bias_outliers(r):
    rows = _fig5_cases(r, outliers_only=True)
    if not rows:
        raise MissingData("fig5: no cases of the outlier scenes (outlier_scene = 1)")
    before = {k: num(_need(m, "before/in_focus_outliers/fraction", f"fig5 {k}")) for k, m in rows.items()}
    after = {k: num(_need(m, "after_bias/in_focus_outliers/fraction", f"fig5 {k}")) for k, m in rows.items()}
    nobias = {k: m.get("after_no_bias/in_focus_outliers/fraction") for k, m in rows.items()}
    judged = [k for k in sorted(rows) if before[k] >= BIAS_MIN_OUTLIERS_BEFORE]
    if not judged:
        raise MissingData(f"fig5: no outlier-scene case has ≥ {100 * BIAS_MIN_OUTLIERS_BEFORE:.0f} % in-focus "
                          "outliers before the filter (nothing to correct)")
    keep = 1.0 - BIAS_MIN_RELATIVE_DROP
    fell = [after[k] <= keep * before[k] for k in judged]
    mean_b = sum(before[k] for k in judged) / len(judged)
    mean_a = sum(after[k] for k in judged) / len(judged)
    v = ("reproduced" if all(fell) else "partly reproduced" if mean_a <= keep * mean_b else "not reproduced")
    parts = "; ".join(f"{k}: {100 * before[k]:.1f} % → {100 * after[k]:.1f} % (no bias: "
                      f"{'n/a' if nobias[k] is None else f'{100 * num(nobias[k]):.1f} %'})" for k in sorted(rows))
    return Verdict(v, f"In-focus edges estimated blurry (σ_gt ≤ 1 px, estimate > 2 px), before → after the "
                      f"biased filter: {parts}; mean over the {len(judged)} judged cases {100 * mean_b:.1f} % → "
                      f"{100 * mean_a:.1f} %.",
                   {"before": before, "after": after, "after_no_bias": nobias, "judged": judged})


def refinement_small_change(r):
    cases = _fig5_cases(r, outliers_only=False)
    if not cases:
        raise MissingData("fig5: no cases")
    changes = {k: (num(_need(m, "before/mae", f"fig5 {k}")), num(_need(m, "after_bias/mae", f"fig5 {k}")))
               for k, m in cases.items()}
    rel = {k: abs(a - b) / b for k, (b, a) in changes.items()}
    small = [x <= SMALL_CHANGE_MAX_REL for x in rel.values()]
    mean_b = sum(b for b, _ in changes.values()) / len(changes)
    mean_a = sum(a for _, a in changes.values()) / len(changes)
    refines = mean_a <= (1.0 - REFINE_MIN_RELATIVE_GAIN) * mean_b
    v = ("reproduced" if refines and all(small) else
         "partly reproduced" if refines and 2 * sum(small) >= len(small) else "not reproduced")
    parts = "; ".join(f"{k}: {b:.2f} → {a:.2f} px" for k, (b, a) in sorted(changes.items()))
    return Verdict(v, f"MAE at edge pixels before → after the biased filter: {parts}; mean {mean_b:.2f} → "
                      f"{mean_a:.2f} px ({sum(small)} of {len(small)} cases change by ≤ "
                      f"{100 * SMALL_CHANGE_MAX_REL:.0f} %).",
                   {"mae_before_after": changes, "relative_change": rel, "mean_before": mean_b, "mean_after": mean_a})


# --- Fig. 6 and Fig. 11 ---------------------------------------------------------------------------
def _alpha_key(k: str) -> float:
    return float(k.split("=", 1)[1])


def _monotone(xs, sign) -> bool:
    span = abs(xs[-1] - xs[0])
    return sign * (xs[-1] - xs[0]) > 0 and all(sign * (y - x) >= -0.01 * span for x, y in zip(xs, xs[1:]))


def alpha_balance(r):
    rows = {}
    for name, sc in _scenes(r.where(encoding="srgb"), "fig6 sRGB rows").items():
        m = sc.metrics()
        if m.get("alpha_applies", 1.0) == 0.0:
            raise MissingData("fig6: this preset's propagation has no α (not Eq. 4)")
        terms = sc.nested("energy_terms")
        alphas = sorted(terms, key=_alpha_key)
        if len(alphas) < 2:
            raise MissingData(f"fig6 {name}: fewer than two α")
        data = [num(_need(terms[a], "data_term", f"fig6 {name}")) for a in alphas]
        smooth = [num(_need(terms[a], "smoothness_term", f"fig6 {name}")) for a in alphas]
        change = num(sc.value("map_change_px/textured_mean"))
        change_all = num(sc.value("map_change_px/all_mean"))
        rows[name] = {"alphas": [_alpha_key(a) for a in alphas], "data_term": data, "smoothness_term": smooth,
                      "trade_off": _monotone(data, -1) and _monotone(smooth, +1),
                      "map_change_textured_px": change, "map_change_all_px": change_all,
                      "visible": change >= ALPHA_VISIBLE_CHANGE_PX}
    trade = [x["trade_off"] for x in rows.values()]
    visible = [x["visible"] for x in rows.values()]
    v = ("reproduced" if all(trade) and all(visible) else
         "partly reproduced" if all(trade) and any(visible) else "not reproduced")
    parts = "; ".join(
        f"{k}: mean |Δmap| α {x['alphas'][0]:g}→{x['alphas'][-1]:g} {x['map_change_textured_px']:.3g} px textured "
        f"({x['map_change_all_px']:.3g} px all pixels), data term {x['data_term'][0]:.3g} → {x['data_term'][-1]:.3g} "
        f"px², smoothness term {x['smoothness_term'][0]:.3g} → {x['smoothness_term'][-1]:.3g} px²"
        f"{'' if x['trade_off'] else ' (no trade-off)'}" for k, x in rows.items())
    return Verdict(v, f"sRGB input: {parts}.", rows)


def dense_map(r):
    rows = {}
    for name, sc in _scenes(r.where(variant=None), "fig11 rendered scenes").items():
        rows[name] = {k: num(sc.value(k)) for k in ("textured_bias", "textured_mae", "all_bias", "all_mae")}
    good = {k: abs(x["textured_bias"]) <= DENSE_MAX_ABS_BIAS_PX and x["textured_mae"] <= DENSE_MAX_MAE_PX
            for k, x in rows.items()}
    n_good = sum(good.values())
    v = ("reproduced" if n_good == len(good) else
         "partly reproduced" if 2 * n_good >= len(good) else "not reproduced")
    parts = "; ".join(f"{k}: textured MAE {x['textured_mae']:.2f}, bias {x['textured_bias']:+.2f} (all pixels "
                      f"{x['all_mae']:.2f}, {x['all_bias']:+.2f})" for k, x in rows.items())
    return Verdict(v, f"Dense map vs σ_gt over textured pixels off occlusion boundaries, px: {parts}; recovered "
                      f"on {n_good} of {len(good)} scenes.", {"scenes": rows, "recovered": good})


# --- Fig. 7 and Fig. 8 ----------------------------------------------------------------------------
def _fig7_scenes(r) -> dict:
    """``{scene: (stage rows' nested metrics, preset rows' nested metrics)}`` of Fig. 7."""
    out = {}
    for name, sc in _scenes(r, "fig7 rows").items():
        stage, preset = sc.where(variant="stage"), sc.where(preset=tuple(p for p in sc.distinct("preset") if p))
        if not preset:
            raise MissingData(f"fig7 {name}: no rows of the preset")
        out[name] = (stage.nested(), preset.nested())
    return out


def doubled_map(r):
    rows = {}
    for name, (_, p) in _fig7_scenes(r).items():
        w = f"fig7 {name}"
        d, g = _need(p, "k_x_map_small_vs_map_large", w), _need(p, "maps_vs_gt_large", w)
        kx, fl = _need(g, "k_x_map_small", w), _need(g, "map_large", w)
        rows[name] = {"doubled_f8_vs_map_f4_median_rel": num(_need(d, "median_rel_error", w)),
                      "doubled_f8_vs_map_f4_mae": num(_need(d, "mae", w)),
                      "doubled_f8_vs_gt_median_rel": num(_need(kx, "median_rel_error", w)),
                      "map_f4_vs_gt_median_rel": num(_need(fl, "median_rel_error", w)),
                      "doubled_f8_vs_gt_mae": num(_need(kx, "mae", w)), "map_f4_vs_gt_mae": num(_need(fl, "mae", w))}
    v, evidence = doubling_verdict(rows)
    return Verdict(v, evidence, rows)


def doubling_verdict(rows: dict) -> tuple[str, str]:
    """The doubling claim's rule on per-scene numbers: (verdict, evidence).

    ``rows``: ``{scene: {"doubled_f8_vs_map_f4_median_rel", "doubled_f8_vs_gt_median_rel",
    "map_f4_vs_gt_median_rel" (dimensionless), "doubled_f8_vs_map_f4_mae", "doubled_f8_vs_gt_mae",
    "map_f4_vs_gt_mae" (px)}}`` (:func:`doubled_map` reads them from Fig. 7's rows;
    :mod:`experiments.doubling_sizes` computes them at two render sizes).
    """
    similar = [x["doubled_f8_vs_map_f4_median_rel"] <= DOUBLING_MAX_MEDIAN_REL_DIFF for x in rows.values()]
    accurate = [max(x["doubled_f8_vs_gt_median_rel"], x["map_f4_vs_gt_median_rel"]) <= DOUBLING_MAX_MEDIAN_REL_ERR
                for x in rows.values()]
    v = ("reproduced" if all(similar) and all(accurate) else "partly reproduced" if all(similar) else "not reproduced")
    parts = "; ".join(
        f"{k}: 2×map(f/8) vs map(f/4) median {100 * x['doubled_f8_vs_map_f4_median_rel']:.0f} % apart (MAE "
        f"{x['doubled_f8_vs_map_f4_mae']:.2f} px); vs σ_gt(f/4) median error 2×map(f/8) "
        f"{100 * x['doubled_f8_vs_gt_median_rel']:.0f} % (MAE {x['doubled_f8_vs_gt_mae']:.2f} px), map(f/4) "
        f"{100 * x['map_f4_vs_gt_median_rel']:.0f} % (MAE {x['map_f4_vs_gt_mae']:.2f} px)" for k, x in rows.items())
    return v, f"{parts}."


def _need(node: dict, key: str, where: str):
    if key not in node:
        raise MissingData(f"{where}: no {key}")
    return node[key]


def magnified_close(r):
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    rows, pairs, others = {}, [], {}
    for name, (s, p) in _fig7_scenes(r).items():
        base = _need(s.get("image_vs_large", {}), "unchanged_small", f"fig7 {name}")
        q = p.get("image_vs_large", {})
        mag = _need(q, "magnified_estimated", f"fig7 {name}")
        pairs.append(closer(base, mag))
        rows[name] = {"ssim": (num(base["ssim"]), num(mag["ssim"])), "psnr": (num(base["psnr_db"]), num(mag["psnr_db"]))}
        sub = q.get("magnified_estimated_subtract")
        if sub is not None:  # the other reading of the Sec. 5 map floor (not part of the verdict)
            rows[name]["subtract"] = {"ssim": num(sub["ssim"]), "psnr": num(sub["psnr_db"]),
                                      "map_floor_px": num(p.get("map_floor_px"))}
        for rend in [x for x in list(MAGNIFICATION_RENDERERS)[1:] if f"magnified_estimated_{x}" in q]:
            row = q[f"magnified_estimated_{rend}"]  # the claim judged with another renderer (not the verdict)
            others.setdefault(rend, {"pairs": [], "scenes": {}})
            others[rend]["pairs"].append(closer(base, row))
            others[rend]["scenes"][name] = {"ssim": num(row["ssim"]), "psnr": num(row["psnr_db"])}
    v = image_verdict(pairs)
    parts = "; ".join(f"{k}: SSIM {x['ssim'][0]:.3f} → {x['ssim'][1]:.3f}, PSNR {x['psnr'][0]:.1f} → "
                      f"{x['psnr'][1]:.1f} dB" for k, x in rows.items())
    evidence = f"f/8 render unchanged → magnified ×2, compared with the real f/4 render: {parts}."
    sub_rows = {k: x["subtract"] for k, x in rows.items() if "subtract" in x}
    if sub_rows:
        evidence += (" With the map's lower-5 % value p_lo subtracted in quadrature instead of clamping at 0 "
                     "(the other reading of Sec. 5, not used for the verdict): " +
                     "; ".join(f"{k} (p_lo {x['map_floor_px']:.2f} px): SSIM {x['ssim']:.3f}, PSNR {x['psnr']:.1f} dB"
                               for k, x in sub_rows.items()) + ".")
    numbers = dict(rows)
    if others:
        numbers["renderers"] = {}
        for rend, o in others.items():
            o_verdict = image_verdict(o["pairs"])
            numbers["renderers"][rend] = {"verdict": o_verdict, "scenes": o["scenes"]}
            evidence += (f" Re-judged with the {rend} renderer (the verdict above is the paper's gather): {o_verdict}; "
                         + "; ".join(f"{k}: SSIM {x['ssim']:.3f}, PSNR {x['psnr']:.1f} dB"
                                     for k, x in o["scenes"].items()) + ".")
    return Verdict(v, evidence, numbers)


#: Fig. 7 rows shown beside the verdict's row of "sharp regions stay sharp": (key, label).
_SHARP_BESIDE = (("magnified_estimated", "gather, floor clamp"), ("magnified_estimated_scatter", "scatter, floor clamp"),
                 ("magnified_estimated_subtract", "gather, floor subtract"))


def _psnr_pair(base, row, where):
    return {key: (num(_need(base, f"psnr_{key}_db", where)), num(_need(row, f"psnr_{key}_db", where)))
            for key in ("in_focus", "defocused")}


def _default_magnification(p) -> str:
    """"<renderer>, floor <mode>" of a preset's default magnification (its flags in Fig. 7's metrics)."""
    flags = [k for k, v in (p.get("default_magnification") or {}).items() if num(v) == 1]
    name = {part: k.split("_", 1)[1] for k in flags for part in ("renderer", "floor") if k.startswith(part + "_")}
    return f"{name.get('renderer', '?')}, floor {name.get('floor', '?')}"


def sharp_stays_sharp(r):
    """Judged on the preset's own magnification (``magnified_estimated_default``: the paper preset's is the
    gather + clamp row, robust's its renderer and estimated floor), or the gather + clamp row when the
    table has no such row; the other magnifications are shown beside it."""
    rows = {}
    for name, (s, p) in _fig7_scenes(r).items():
        base = _need(s.get("image_vs_large", {}), "unchanged_small", f"fig7 {name}")
        q = p.get("image_vs_large", {})
        key = "magnified_estimated_default" if "magnified_estimated_default" in q else "magnified_estimated"
        x = _psnr_pair(base, _need(q, key, f"fig7 {name}"), f"fig7 {name}")
        x["sharp_kept"] = x["in_focus"][1] >= min(x["in_focus"][0] - SHARP_MAX_DROP_DB, SHARP_MIN_PSNR_DB)
        x["blur_gained"] = compare(x["defocused"][0], x["defocused"][1], PSNR_MARGIN_DB) == 1
        x["judged_on"] = _default_magnification(p) if key.endswith("default") else "gather, floor clamp"
        x["beside"] = {label: {"in_focus": num(q[k]["psnr_in_focus_db"]), "defocused": num(q[k]["psnr_defocused_db"])}
                       for k, label in _SHARP_BESIDE if k in q and label != x["judged_on"]}
        rows[name] = x
    kept = [x["sharp_kept"] for x in rows.values()]
    gained = [x["blur_gained"] for x in rows.values()]
    v = ("reproduced" if all(kept) and all(gained) else "partly reproduced" if all(gained) else "not reproduced")
    parts = "; ".join(f"{k} ({x['judged_on']}): in-focus PSNR {x['in_focus'][0]:.1f} → {x['in_focus'][1]:.1f} dB, "
                      f"defocused {x['defocused'][0]:.1f} → {x['defocused'][1]:.1f} dB" for k, x in rows.items())
    evidence = f"Against the real f/4 render, unchanged f/8 → magnified as the preset magnifies: {parts}."
    beside = "; ".join(f"{k} {label}: in-focus {y['in_focus']:.1f} dB, defocused {y['defocused']:.1f} dB"
                       for k, x in rows.items() for label, y in x["beside"].items())
    if beside:
        evidence += f" The other magnifications (not used for the verdict): {beside}."
    return Verdict(v, evidence, rows)


def refocus(r):
    q = r.nested("images_vs_d2")
    base = _need(q, "unchanged_d1", "fig8")
    est = _need(q, "refocused_estimated", "fig8")
    v = image_verdict([closer(base, est)])
    oracle = q.get("refocused_estimated_oracle_virtual")
    extra = (f" With the true σ of the D2 render as the virtual map: {num(oracle['psnr_db']):.1f} dB, "
             f"SSIM {num(oracle['ssim']):.3f}." if oracle else "")
    return Verdict(v, f"Against a real render focused at the new distance: D1 render unchanged "
                      f"{num(base['psnr_db']):.1f} dB / SSIM {num(base['ssim']):.3f}; refocused from the estimated "
                      f"map alone {num(est['psnr_db']):.1f} dB / SSIM {num(est['ssim']):.3f}.{extra}",
                   {"unchanged": base, "refocused_estimated": est, "refocused_oracle_virtual": oracle})
