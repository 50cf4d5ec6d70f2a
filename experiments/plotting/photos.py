"""Plot of the photos figure: per photo, the photo with its hand-drawn regions, the map of each preset
(scored), the magnified result, and crops of a sharp subject's border, unchanged and per renderer."""

from __future__ import annotations

import numpy as np

from matplotlib.patches import Rectangle

from .style import RC, add_colorbar, plt, save_figure

#: Outline colours of the regions (in focus, defocused).
_REGION_COLORS = {"in_focus": "#00FF66", "defocused": "#FF33CC"}


def plot(data, config, out_stem):
    """Draw the figure from its cases (:func:`experiments.figS2_photos.photo_view`); returns the PNG + PDF paths.

    One row per photo. Columns: the photo with the outlines of its in-focus (green) and defocused
    (magenta) regions; the defocus map of each scored preset (σ in px, one colour scale per row with a
    colour bar, titled with its ranking AUC and the share of in-focus pixels above the defocused
    median); the photo with the defocus of the ``magnify_preset`` map magnified ×factor (first
    renderer); then the border crop (white square on the photo, :func:`experiments.figS2_photos.border_crop`)
    of the photo and of the magnified result of each renderer, with the crop's pixel coordinates.
    """
    from experiments.figS2_photos import photo_view

    data = photo_view(data)
    items = [str(s) for s in data["items"]]
    metrics = data["metrics"]
    presets = list(metrics["presets_scored"])
    ncols = 3 + len(presets) + len(metrics.get("renderers", ["gather"]))
    with plt.rc_context(RC):
        fig = plt.figure(figsize=(2.9 * ncols + 0.6, 2.5 * len(items) + 0.3), layout="constrained")
        subs = np.atleast_1d(fig.subfigures(len(items), 1))
        for sub, name in zip(subs, items):
            _row(sub, data, name, presets)
    return save_figure(fig, out_stem)


def _row(sub, data, name, presets):
    metrics = data["metrics"]
    scores = metrics["photos"][name]
    renderers = list(metrics.get("renderers", ["gather"]))
    axes = sub.subplots(1, 3 + len(presets) + len(renderers))
    img = np.clip(data[f"{name}__input"], 0, 1)
    h, w = img.shape[:2]
    axes[0].imshow(img)
    for label, colour in _REGION_COLORS.items():
        mask = data[f"{name}__{label}"].astype(float)
        axes[0].contour(mask, levels=[0.5], colors=[colour], linewidths=1.2)
    axes[0].set_title(f"{name} ({w}×{h}): regions\ngreen in focus, magenta defocused")
    maps = {p: data[f"{name}__{p}__map"] for p in presets}
    vmax = max(float(np.nanpercentile(np.concatenate([m.ravel() for m in maps.values()]), 99.5)), 1e-3)
    im = None
    for ax, p in zip(axes[1:], presets):
        s = scores[p]
        im = ax.imshow(maps[p], cmap="viridis", vmin=0, vmax=vmax)
        ok = "meets targets" if s["meets_targets"] else "misses targets"
        ax.set_title(f"{p} ({ok})\nAUC {s['auc']:.3f}, in focus > defoc. median "
                     f"{100 * s['in_focus_above_defocused_median']:.1f} %\n"
                     f"median σ: in focus {s['in_focus_median_px']:.2f}, defoc. {s['defocused_median_px']:.2f} px",
                     fontsize=7)
    add_colorbar(sub, list(axes[1:1 + len(presets)]), im, "σ (px)")
    k = 1 + len(presets)
    axes[k].imshow(np.clip(data[f"{name}__magnified"], 0, 1))
    axes[k].set_title(f"{metrics['magnify_preset']} map: defocus magnified ×{metrics['factor']:g}\n({renderers[0]})")
    y0, y1, x0, x1 = scores.get("border_crop", (0, h, 0, w))
    axes[0].add_patch(Rectangle((x0 - 0.5, y0 - 0.5), x1 - x0, y1 - y0, fill=False, edgecolor="white", linewidth=1.2))
    crops = [("unchanged", data[f"{name}__input"])]
    crops += [(r, data[f"{name}__magnified" + (f"_{r}" if i else "")]) for i, r in enumerate(renderers)]
    for ax, (label, img_r) in zip(axes[k + 1:], crops):
        ax.imshow(np.clip(img_r[y0:y1, x0:x1], 0, 1), extent=(x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5))
        ax.set_title(f"border crop: {label}" + ("" if label == "unchanged" else f" ×{metrics['factor']:g}"), fontsize=8)
        ax.set_xlabel("x (px)", fontsize=7)
        ax.set_ylabel("y (px)", fontsize=7)
        ax.tick_params(labelsize=6)
    for ax in axes[:k + 1]:
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
    for ax in axes[k + 1:]:
        ax.grid(False)
