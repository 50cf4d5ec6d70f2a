"""Plot of Fig. 5: sparse blur measure before / after the biased cross-bilateral filter (and no-bias)."""

from __future__ import annotations

import numpy as np

from .fig4 import _dots
from .style import add_colorbar, new_figure, plt, save_figure

_TITLES = {"before": "before (BM)", "after_bias": "after bCBF (bias)", "after_no_bias": "after CBF (no bias)"}


def plot(data, config, out_stem):
    """Draw Fig. 5 from :func:`experiments.fig5_cross_bilateral.compute`'s dict; returns the paths."""
    cases = [str(c) for c in data["cases"]]
    m = data["metrics"]
    stages = list(_TITLES)
    fig, axes = new_figure(len(cases), 2 + len(stages), width_in=12.0, height_in=2.4 * len(cases) + 0.4,
                           squeeze=False)
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
            row[2 + j].imshow(_dots(data[f"{case}_{stage}"].astype(np.float64), radius=max(1, gt.shape[1] // 200)), cmap=cmap, vmin=0, vmax=vmax)
            s = m[case][stage]
            frac = s["in_focus_outliers"]["fraction"]
            frac_txt = "n/a" if frac is None else f"{100 * frac:.1f} %"
            mae = s["mae"]
            row[2 + j].set_title(f"{_TITLES[stage]}\nMAE {mae:.2f} px\nin-focus outliers {frac_txt}", fontsize=7)
        for ax in row:
            ax.set_xticks([])
            ax.set_yticks([])
        add_colorbar(fig, row[-1], im, "σ (px)")
    return save_figure(fig, out_stem)
