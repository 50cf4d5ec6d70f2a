"""Plot of Fig. 11: one row per rendered scene / photo — input, map, magnified result, truth or edges."""

from __future__ import annotations

import numpy as np

from .style import _RC, add_colorbar, plt, save_figure


def plot(data, config, out_stem):
    """Draw Fig. 11 from :func:`experiments.fig11_gallery.compute`'s dict; returns the paths.

    Columns: input; estimated defocus map (colour bar "σ (px)", shared with column 4 in the row);
    magnified ×k result; σ_gt (renders, occlusion bands grey) or the sparse blur measures at edge
    pixels (photos, which have no ground truth).
    """
    items = [str(s) for s in data["items"]]
    metrics = data["metrics"]["items"]
    k = data["metrics"]["factor"]
    with plt.rc_context(_RC):
        fig = plt.figure(figsize=(10.5, 2.2 * len(items)), layout="constrained")
        subs = np.atleast_1d(fig.subfigures(len(items), 1))
        for sub, item in zip(subs, items):
            _row(sub, data, item, metrics[item], k)
    return save_figure(fig, out_stem)


def _row(sub, data, item, m, k):
    kind, name = item.split(":", 1)
    axes = sub.subplots(1, 4)
    img = np.clip(data[f"{item}__input"], 0, 1)
    dmap = data[f"{item}__map"]
    t = m["timings"]["estimate_wall_s"]
    h, w = m["shape"]
    axes[0].imshow(img)
    axes[0].set_title(f"{name} ({'render' if kind == 'scene' else 'photo'}, {w}×{h})\nestimate {t:.1f} s")
    if kind == "scene":
        other = data[f"{item}__gt"]
        vmax = float(np.nanpercentile(np.concatenate([other.ravel(), dmap.ravel()]), 99.5))
        title4 = "ground truth σ_gt (grey: excluded)"
        other = np.ma.masked_where(data[f"{item}__occlusion"].astype(bool) | ~np.isfinite(other), other)
        title_map = f"defocus map\nMAE {m['all_mae']:.2f} px, bias {m['all_bias']:+.2f} px"
    else:
        other = data[f"{item}__sparse"]
        vmax = float(np.nanpercentile(dmap, 99.5))
        title4 = "sparse σ at edge pixels (grey: none)"
        other = np.ma.masked_invalid(other)
        title_map = f"defocus map\nmedian {m['map_median_px']:.2f}, p95 {m['map_p95_px']:.2f} px"
    vmax = max(vmax, 1e-3)
    im = axes[1].imshow(dmap, cmap="viridis", vmin=0, vmax=vmax)
    axes[1].set_title(title_map)
    axes[2].imshow(np.clip(data[f"{item}__magnified"], 0, 1))
    axes[2].set_title(f"defocus magnified ×{k:g}")
    axes[3].set_facecolor("0.6")
    axes[3].imshow(other, cmap="viridis", vmin=0, vmax=vmax, interpolation="nearest")
    axes[3].set_title(title4)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
    add_colorbar(sub, [axes[1], axes[3]], im, "σ (px)")
