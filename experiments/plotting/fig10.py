"""Plot of Fig. 10: c (cm) vs S (cm), Eq. (5) curves and measured points."""

from __future__ import annotations

import numpy as np

from .style import COLORS, new_figure, save_figure


def plot(data, config, out_stem):
    """Draw Fig. 10 from the figure's cases; returns the paths.

    Left: Eq. (5) curves and the points measured with the paper's camera; middle: their relative error;
    right (when computed): the relative error of the points measured with each held-out procedural scene's
    camera at its own depths, against the CoC on the film."""
    paper = data.one(variant="paper")
    procedural = [o for o in data.outputs.values() if o.case.scene_set is not None]
    data = {**paper.arrays(), "metrics": paper.info}
    fig, axes = new_figure(1, 3 if procedural else 2, width_in=11.0 if procedural else 8.0, height_in=3.4,
                           width_ratios=(2, 1, 1) if procedural else (2, 1))
    ax, ax_err = axes[0], axes[1]
    if procedural:
        _procedural_panel(axes[2], procedural)
    for k, n in enumerate(data["f_numbers"]):
        col = COLORS[k % len(COLORS)]
        ax.plot(data["curve_s_cm"], data["curve_c_cm"][k], color=col, lw=1.4, label=f"Eq. (5), N = {n:g}")
        ax.plot(data["points_s_cm"], data["points_c_cm"][k], "o", ms=4, mfc="none", color=col,
                label=f"Mitsuba, N = {n:g}")
        ax_err.plot(data["points_s_cm"], 100.0 * data["points_rel_err"][k], "o-", ms=3, color=col,
                    label=f"N = {n:g}")
    ax.axvline(config.focus_distance_cm, color="0.5", lw=0.8, ls="--")
    ax.set_xlabel("object distance S (cm)")
    ax.set_ylabel("circle of confusion c (cm, on the sensor)")
    ax.set_title(f"f = {config.focal_length_cm:g} cm, D = {config.focus_distance_cm:g} cm")
    ax.set_xlim(*config.curve_range_cm)
    ax.set_ylim(bottom=0)
    ax.legend(ncols=2)
    ax_err.axhline(0, color="0.5", lw=0.8)
    ax_err.set_xlabel("object distance S (cm)")
    ax_err.set_ylabel("measured / Eq. (5) − 1 (%)")
    m = data["metrics"]
    ax_err.set_title(f"max |error| {100 * m['max_rel_err']:.2f} % ({m['n_points']} renders)")
    lim = max(1.0, 1.2 * 100 * float(np.nanmax(np.abs(data["points_rel_err"]))))
    ax_err.set_ylim(-lim, lim)
    ax_err.legend()
    return save_figure(fig, out_stem)


def _procedural_panel(ax, outputs):
    """Relative error vs Eq. (5) of every procedural scene's points, against the CoC on the film (px)."""
    worst = 0.0
    for i, o in enumerate(outputs):
        a = o.arrays()
        ax.plot(a["coc_eq5_px"], 100.0 * a["rel_err"], "o", ms=4, color=COLORS[i % len(COLORS)], label=o.case.scene)
        worst = max(worst, float(np.nanmax(np.abs(a["rel_err"]))))
    ax.axhline(0, color="0.5", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("Eq. (5) CoC on the film (px)")
    ax.set_ylabel("measured / Eq. (5) − 1 (%)")
    ax.set_title(f"held-out scenes' cameras and depths\nmax |error| {100 * worst:.2f} %")
    lim = max(1.0, 1.2 * 100 * worst)
    ax.set_ylim(-lim, lim)
    ax.legend(fontsize=6)
