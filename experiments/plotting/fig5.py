"""Plot of Fig. 5: sparse blur measure before / after the biased cross-bilateral filter (and no-bias),
plus the bias-scale sweep (dense-map MAE, in-focus outliers, blurry-edge bias vs s)."""

from __future__ import annotations

import math

import numpy as np

from .fig4 import dots
from .style import COLORS, add_colorbar, new_figure, plt, plot_scene_sets, save_figure

_TITLES = {"before": "before (BM)", "after_bias": "after bCBF (bias)", "after_no_bias": "after CBF (no bias)"}
#: Where s = inf is drawn on the log axis, as a multiple of the largest finite s.
_INF_FACTOR = 4.0


def _scale_positions(scales):
    """x positions (log axis) and tick labels of the bias scales s (px); inf drawn past the largest."""
    finite = [s for s in scales if math.isfinite(s)]
    top = max(finite) if finite else 1.0
    pos = np.array([s if math.isfinite(s) else top * _INF_FACTOR for s in scales], dtype=np.float64)
    labels = [f"{s:g}" + (" (paper)" if s == 2.0 else "") if math.isfinite(s) else "∞\n(no bias)"
              for s in scales]
    return pos, labels


def _sweep_panels(fig, axes_row, data, cases, config):
    """Replace one row of axes by three line plots of the bias-scale sweep."""
    gs = axes_row[0].get_gridspec()
    row = axes_row[0].get_subplotspec().rowspan.start
    for ax in axes_row:
        ax.remove()
    sub = gs[row, :].subgridspec(1, 3)
    panels = [fig.add_subplot(sub[0, i]) for i in range(3)]
    scales = [float(s) for s in np.asarray(data["bias_scales"], dtype=np.float64)]
    x, labels = _scale_positions(scales)
    for i, case in enumerate(cases):
        c = COLORS[i % len(COLORS)]
        panels[0].plot(x, data["sweep_dense_mae_all"][i], "o-", color=c, label=case)
        panels[0].plot(x, data["sweep_dense_mae_textured"][i], "s--", color=c, ms=3, alpha=0.7)
        panels[1].plot(x, 100 * data["sweep_in_focus_outliers"][i], "o-", color=c, label=case)
        panels[2].plot(x, data["sweep_refined_bias_blurry"][i], "o-", color=c, label=case)
        panels[2].plot(x, data["sweep_dense_bias_all"][i], "s--", color=c, ms=3, alpha=0.7)
    titles = ("dense map (Eq. 4) MAE vs σ_gt\nsolid: all pixels, dashed: textured",
              f"in-focus outliers of the refined measure\n(σ_gt ≤ {config.in_focus_px:g} px estimated "
              f"> {config.blurry_px:g} px)",
              f"bias (est − gt); solid: refined, blurry edges\n(σ_gt ≥ {config.blurry_edge_px:g} px); "
              f"dashed: dense, all pixels")
    ylabels = ("MAE (px)", "in-focus outliers (%)", "mean signed error (px)")
    for ax, t, yl in zip(panels, titles, ylabels):
        ax.set_xscale("log")
        ax.set_xticks(x)
        ax.set_xticklabels(labels)
        ax.minorticks_off()
        ax.axvline(2.0, color="0.5", lw=0.8, ls=":")
        ax.set_xlabel("bias scale s in b(BM) = exp(−BM/s) (px)")
        ax.set_ylabel(yl)
        ax.set_title(t, fontsize=8)
    panels[2].axhline(0.0, color="k", lw=0.6)
    panels[0].legend(fontsize=6)
    return panels


def plot(data, config, out_stem):
    """Draw the figure for the default scene set (``out_stem``) and each further set
    (``<out_stem>_<set>``), captioned with the set (:func:`.style.plot_scene_sets`)."""
    return plot_scene_sets(lambda fd, name, stem: plot_one_set(_set_view(fd, name), config, stem), data, config,
                           out_stem)


def _set_view(fd, set_name) -> dict:
    """The arrays and metrics of one scene set's cases: per case ``<scene>_f<N>`` its stage arrays and
    metrics; the sweep curves ``sweep_<name>`` (cases × scales) and ``bias_scales``."""
    from experiments.fig5_cross_bilateral import SWEEP_CURVES, scale_label

    view, metrics, cases = {}, {}, []
    scales = [float(s) for s in fd.config.bias_scales]
    curves = {name: [] for name in SWEEP_CURVES}
    for out in fd.find(scene_set=set_name, variant="stages"):
        c = out.case
        label = f"{c.scene}_f{c.aperture:g}"
        cases.append(label)
        a = out.arrays()
        for k in ("image", "sigma_gt", "occlusion", "before", "after_bias", "after_no_bias"):
            view[f"{label}_{k}"] = a[k]
        metrics[label] = out.nested()
        per_scale = {o.case.variant: o.nested() for o in fd.find(scene_set=set_name, scene=c.scene,
                                                                aperture=c.aperture) if o.case.variant != "stages"}
        for name, path in SWEEP_CURVES.items():
            row = []
            for sc in scales:
                v = per_scale[scale_label(sc)]
                for k in path:
                    v = v[k]
                row.append(np.nan if v is None else v)
            curves[name].append(row)
    view.update({f"sweep_{k}": np.asarray(v, dtype=np.float64) for k, v in curves.items()})
    view.update(cases=np.asarray(cases), bias_scales=np.asarray(scales, dtype=np.float64), metrics=metrics)
    return view


def plot_one_set(data, config, out_stem):
    """Draw Fig. 5 for one scene set from :func:`_set_view`'s dict; returns the paths."""
    cases = [str(c) for c in data["cases"]]
    m = data["metrics"]
    stages = list(_TITLES)
    sweep = "bias_scales" in data
    nrows = len(cases) + (1 if sweep else 0)
    fig, axes = new_figure(nrows, 2 + len(stages), width_in=12.0,
                           height_in=2.4 * len(cases) + 0.4 + (3.0 if sweep else 0.0), squeeze=False,
                           height_ratios=[1.0] * len(cases) + ([1.25] if sweep else []))
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
    for r, case in enumerate(cases):
        gt = data[f"{case}_sigma_gt"].astype(np.float64)
        vmax = max(2.5, float(np.nanpercentile(gt, 99.5)))
        row = axes[r]
        row[0].imshow(np.clip(data[f"{case}_image"], 0, 1))
        row[0].set_title(f"{case}\ninput (sRGB)", fontsize=7)
        im = row[1].imshow(np.where(data[f"{case}_occlusion"], np.nan, gt), cmap=cmap, vmin=0, vmax=vmax)
        row[1].set_title("ground truth σ\n(occlusion grey)", fontsize=7)
        for j, stage in enumerate(stages):
            row[2 + j].imshow(dots(data[f"{case}_{stage}"].astype(np.float64), radius=max(1, gt.shape[1] // 200)), cmap=cmap, vmin=0, vmax=vmax)
            s = m[case][stage]
            frac = s["in_focus_outliers"]["fraction"]
            frac_txt = "n/a" if frac is None else f"{100 * frac:.1f} %"
            mae = s["mae"]
            row[2 + j].set_title(f"{_TITLES[stage]}\nMAE {mae:.2f} px\nin-focus outliers {frac_txt}", fontsize=7)
        for ax in row:
            ax.set_xticks([])
            ax.set_yticks([])
        add_colorbar(fig, row[-1], im, "σ (px)")
    if sweep:
        _sweep_panels(fig, axes[-1], data, cases, config)
    return save_figure(fig, out_stem)
