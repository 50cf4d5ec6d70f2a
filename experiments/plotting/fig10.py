"""Plot of Fig. 10: c (cm) vs S (cm), Eq. (5) curves and measured points."""

from __future__ import annotations

import numpy as np

from .style import COLORS, new_figure, save_figure


def plot(data, config, out_stem):
    """Draw Fig. 10 from :func:`experiments.fig10_coc_vs_distance.compute`'s dict; returns the paths."""
    fig, (ax, ax_err) = new_figure(1, 2, width_in=8.0, height_in=3.4, width_ratios=(2, 1))
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
