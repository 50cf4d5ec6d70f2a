"""Plot of Fig. 2: the two sensors' renders side by side, their CoC maps, and the measured ratio."""

from __future__ import annotations

import numpy as np

from .style import COLORS, add_colorbar, new_figure, save_figure


def _log_distance_axis(ax):
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    ax.set_xscale("log")
    ax.set_xticks([0.1, 0.2, 0.5, 1.0, 2.0])
    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_formatter(NullFormatter())


def _display(rgb):
    from scenes.display import linear_to_srgb

    return linear_to_srgb(np.asarray(rgb, dtype=np.float64))


def plot(data, config, out_stem):
    """Draw Fig. 2 from its one case (:func:`experiments.fig2_sensor_size.compute`'s dict); returns the paths."""
    data = data.single()
    m = data["metrics"]
    fig, axes = new_figure(2, 3, width_in=10.0, height_in=5.6)
    (a_rl, a_rs, a_ratio), (a_cl, a_cs, a_fit) = axes
    fl, fs = m["focal_length_mm"]
    fov_l, fov_s = m["fov_x_deg"]
    labels = (f"{config.sensors[0]} (22.2 mm)\nf = {fl:.1f} mm, f/{config.f_number:g}, FOV {fov_l:.1f}°",
              f"{config.sensors[1]} (7.18 mm)\nf = {fs:.2f} mm, f/{config.f_number:g}, FOV {fov_s:.1f}°")
    vmax = float(np.nanmax(data["coc_px_large"]))
    for ax_img, ax_coc, key, label in ((a_rl, a_cl, "large", labels[0]), (a_rs, a_cs, "small", labels[1])):
        h, w = data[f"rgb_{key}"].shape[:2]
        ax_img.imshow(_display(data[f"rgb_{key}"]), extent=(0, w, h, 0))
        ax_img.set_title(label)
        ax_img.set_xlabel("x (px)")
        ax_img.set_ylabel("y (px)")
        ax_img.grid(False)
        im = ax_coc.imshow(data[f"coc_px_{key}"], cmap="magma", vmin=0, vmax=vmax, extent=(0, w, h, 0))
        ax_coc.set_title(f"ground-truth CoC (Eq. 5), max {np.nanmax(data[f'coc_px_{key}']):.2f} px")
        ax_coc.set_xlabel("x (px)")
        ax_coc.set_ylabel("y (px)")
        ax_coc.grid(False)
        add_colorbar(fig, ax_coc, im, "CoC diameter c (px)")
    s = data["edge_depth_m"]
    a_ratio.plot(s, data["edge_ratio_eq6"], "-", color=COLORS[0], label="Eq. (6)")
    a_ratio.plot(s, data["edge_ratio"], "o", mfc="none", color=COLORS[1], label="measured (step edge)")
    a_ratio.axhline(m["sensor_width_ratio"], color="0.5", ls="--", lw=0.8, label="sensor width ratio")
    _log_distance_axis(a_ratio)
    a_ratio.set_xlabel("object distance S (m)")
    a_ratio.set_ylabel("relative blur ratio c'_large / c'_small (–)")
    a_ratio.set_title(f"measured {m['measured_ratio_median']:.3f} vs Eq. (6) {m['eq6_ratio']:.3f}")
    a_ratio.legend()
    for k, key in enumerate(("large", "small")):
        curve = np.where(data[f"curve_eq5_px_{key}"] >= 1.0, data[f"curve_eq5_px_{key}"], np.nan)
        a_fit.plot(data["curve_s_m"], curve, "-", color=COLORS[k], label=f"Eq. (5), {key} sensor")
        a_fit.plot(s, data[f"edge_coc_px_{key}"], "o", mfc="none", color=COLORS[k], label=f"fit, {key}")
    a_fit.set_ylim(1.0, None)
    a_fit.axvline(m["focus_distance_m"], color="0.5", lw=0.8, ls="--")
    _log_distance_axis(a_fit)
    a_fit.set_yscale("log")
    a_fit.set_xlabel("object distance S (m)")
    a_fit.set_ylabel(f"c (px of a {config.edge_width_px}-px-wide image)")
    a_fit.set_title("step-edge calibration renders")
    a_fit.legend(loc="lower right")
    return save_figure(fig, out_stem)
