"""Plot of Fig. 7: f/8 input, f/4 reference, magnified results; maps; error bars."""

from __future__ import annotations

import numpy as np

from .style import _RC, COLORS, add_colorbar, plt, save_figure

_MAP_LABELS = {
    "map_small": "f/8 map",
    "k_x_map_small": "2 × f/8 map",
    "map_large": "f/4 map",
    "k_x_gt_small_naive": "2 × σ_gt(f/8)",
}
_IMAGE_LABELS = {
    "unchanged_small": "f/8 unchanged",
    "magnified_estimated": "×2, estimated map",
    "magnified_estimated_subtract": "×2, estimated map, floor subtracted",
    "magnified_oracle_srgb": "×2, oracle σ_d (sRGB)",
    "magnified_oracle_linear": "×2, oracle σ_d (linear)",
}


def plot(data, config, out_stem):
    """Draw Fig. 7 from :func:`experiments.fig7_doubled_defocus.compute`'s dict; returns the paths.

    One image row and one map row per scene (maps on one colour scale, "σ (px)"), then bar charts of
    the map MAE against σ_gt(f/4) and of the PSNR / SSIM against the real f/4 render. The image row
    shows both readings of Sec. 5's map floor (``floor="clamp"``, the default, and
    ``floor="subtract"``); the map row the f/8 map after the ``"subtract"`` preprocessing.
    """
    scenes = config.scenes
    k = config.factor
    nl, ns = config.f_number_large_aperture, config.f_number_small_aperture
    with plt.rc_context(_RC):
        fig = plt.figure(figsize=(13.5, 2.3 * 2 * len(scenes) + 2.8), layout="constrained")
        subs = fig.subfigures(len(scenes) + 1, 1, height_ratios=[2.0] * len(scenes) + [1.2])
        for sub, scene in zip(subs, scenes):
            _scene_rows(sub, data, scene, config, k, ns, nl)
        _bars(subs[-1], data, config)
    return save_figure(fig, out_stem)


def _off(ax):
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)


def _scene_rows(sub, data, scene, config, k, ns, nl):
    m = data["metrics"]["scenes"][scene]
    axes = sub.subplots(2, 5)
    q = m["image_vs_large"]
    imgs = [("image_small", f"{scene}: f/{ns:g} input", q["unchanged_small"]),
            ("magnified", f"f/{ns:g} ×{k:g}, estimated map\n(Sec. 5 floor: clamp at 0)", q["magnified_estimated"]),
            ("magnified_subtract", f"f/{ns:g} ×{k:g}, estimated map\n(floor {m['map_floor_px']:.2f} px subtracted)",
             q["magnified_estimated_subtract"]),
            ("magnified_oracle_linear", f"×{k:g} with oracle σ_d (linear blur)", q["magnified_oracle_linear"]),
            ("image_large", f"real f/{nl:g} render (reference)", None)]
    for ax, (key, title, qq) in zip(axes[0], imgs):
        ax.imshow(np.clip(data[f"{scene}__{key}"], 0, 1))
        if qq is not None:
            title += f"\nPSNR {qq['psnr_db']:.1f} dB, SSIM {qq['ssim']:.3f}"
            if np.isfinite(float(qq.get("psnr_in_focus_db", float("nan")))):
                title += f"\nin focus {float(qq['psnr_in_focus_db']):.1f} dB"
        ax.set_title(title)
        _off(ax)
    mm = m["maps_vs_gt_large"]
    maps = [("map_small", f"f/{ns:g} map", mm["map_small"]),
            ("map_small", f"{k:g} × f/{ns:g} map", mm["k_x_map_small"]),
            ("map_large", f"f/{nl:g} map", mm["map_large"]),
            ("map_small_subtract", f"f/{ns:g} map, Sec. 5 preprocessed\n(floor subtracted in quadrature)", None),
            ("gt_large", f"σ_gt(f/{nl:g}) (grey: excluded)", None)]
    vmax = float(np.nanpercentile(data[f"{scene}__gt_large"], 99.5))
    mask = data[f"{scene}__mask"].astype(bool)
    for i, (ax, (key, title, mt)) in enumerate(zip(axes[1], maps)):
        arr = data[f"{scene}__{key}"] * (k if i == 1 else 1.0)
        if key == "gt_large":
            arr = np.ma.masked_where(~mask, arr)
            ax.set_facecolor("0.6")
        im = ax.imshow(arr, cmap="viridis", vmin=0, vmax=vmax)
        if mt is not None:
            title += f"\nMAE vs σ_gt(f/{nl:g}) {mt['mae']:.2f} px, bias {mt['bias']:+.2f}"
        ax.set_title(title)
        _off(ax)
    add_colorbar(sub, list(axes[1]), im, "σ (px)")


def _bars(sub, data, config):
    ax_map, ax_psnr, ax_ssim = sub.subplots(1, 3)
    scenes = config.scenes
    width = 0.8 / len(scenes)
    for j, scene in enumerate(scenes):
        m = data["metrics"]["scenes"][scene]
        col = COLORS[j % len(COLORS)]
        x = np.arange(len(_MAP_LABELS)) + j * width
        ax_map.bar(x, [m["maps_vs_gt_large"][key]["mae"] for key in _MAP_LABELS], width, color=col, label=scene)
        x = np.arange(len(_IMAGE_LABELS)) + j * width
        ax_psnr.bar(x, [m["image_vs_large"][key]["psnr_db"] for key in _IMAGE_LABELS], width, color=col, label=scene)
        ax_ssim.bar(x, [m["image_vs_large"][key]["ssim"] for key in _IMAGE_LABELS], width, color=col, label=scene)
    off = 0.4 - width / 2
    ax_map.set_xticks(np.arange(len(_MAP_LABELS)) + off, list(_MAP_LABELS.values()), rotation=20, ha="right")
    ax_map.set_ylabel(f"MAE vs σ_gt(f/{config.f_number_large_aperture:g}) (px)")
    ax_map.set_title("maps (occlusion bands excluded)")
    for ax, lab in ((ax_psnr, "PSNR vs real f/4 (dB)"), (ax_ssim, "SSIM vs real f/4")):
        ax.set_xticks(np.arange(len(_IMAGE_LABELS)) + off, list(_IMAGE_LABELS.values()), rotation=20, ha="right")
        ax.set_ylabel(lab)
    lo = min(data["metrics"]["scenes"][s]["image_vs_large"][k]["psnr_db"] for s in scenes for k in _IMAGE_LABELS)
    ax_psnr.set_ylim(bottom=max(0.0, lo - 3.0))
    lo = min(data["metrics"]["scenes"][s]["image_vs_large"][k]["ssim"] for s in scenes for k in _IMAGE_LABELS)
    ax_ssim.set_ylim(bottom=max(0.0, lo - 0.05), top=1.0)
    ax_psnr.set_title("images vs the real f/4 render")
    ax_ssim.set_title("images vs the real f/4 render")
    ax_map.legend()
