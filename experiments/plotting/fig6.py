"""Plot of Fig. 6: dense maps for each α next to the ground truth, and the errors vs α."""

from __future__ import annotations

import numpy as np

from .style import _RC, COLORS, add_colorbar, plt, save_figure


def plot(data, config, out_stem):
    """Draw Fig. 6 from :func:`experiments.fig6_alpha_sweep.compute`'s dict; returns the paths.

    Top row: input, σ_gt, and the map for every α (titles: MAE over all / textured pixels) (one colour scale, colour bar "σ (px)"; occlusion
    boundaries hatched grey on σ_gt). Bottom row: MAE (all / textured pixels) vs α for each
    encoding, bias vs α, and the RMS deviation from the data term's measures at edges vs α.
    """
    alphas = np.asarray(data["alphas"])
    maps, gt = data["maps"], data["sigma_gt"]
    k = len(alphas)
    ncols = k + 2
    with plt.rc_context(_RC):
        fig = plt.figure(figsize=(2.3 * ncols, 5.4), layout="constrained")
        top, bottom = fig.subfigures(2, 1, height_ratios=(1.0, 1.1))
        axes_top = top.subplots(1, ncols)
        ax_mae, ax_bias, ax_fid = bottom.subplots(1, 3)
        _draw(data, config, alphas, maps, gt, ncols, top, axes_top, ax_mae, ax_bias, ax_fid)
    return save_figure(fig, out_stem)


def _draw(data, config, alphas, maps, gt, ncols, top, axes_top, ax_mae, ax_bias, ax_fid):
    vmax = float(np.nanpercentile(np.concatenate([gt[np.isfinite(gt)].ravel(), maps.ravel()]), 99.5))
    scene = config.scenes[0]
    axes_top[0].imshow(np.clip(data["image"], 0, 1))
    axes_top[0].set_title(f"input: {scene}\n{config.plot_encoding}, f/{config.f_number:g}")
    gt_show = np.ma.masked_where(data["occlusion"], gt)
    im = axes_top[1].imshow(gt_show, cmap="viridis", vmin=0, vmax=vmax)
    axes_top[1].set_title("ground truth σ_gt\n(grey: occlusion, excluded)")
    axes_top[1].set_facecolor("0.6")
    m = data["metrics"]["scenes"][scene][config.plot_encoding]
    for i, a in enumerate(alphas):
        ax = axes_top[i + 2]
        im = ax.imshow(maps[i], cmap="viridis", vmin=0, vmax=vmax)
        r = m[f"alpha={a:g}"]
        ax.set_title(f"α = {a:g}\nMAE {r['all_mae']:.2f} / {r['textured_mae']:.2f} px")
    for ax in axes_top:
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
    add_colorbar(top, list(axes_top), im, "σ (px)")

    summary = data["metrics"]["summary"]
    for j, enc in enumerate(config.encodings):
        col = COLORS[j % len(COLORS)]
        rows = [summary[enc][f"alpha={a:g}"] for a in alphas]
        ax_mae.plot(alphas, [r["all_mae"] for r in rows], "o-", color=col, label=f"{enc}: all")
        ax_mae.plot(alphas, [r["textured_mae"] for r in rows], "s--", color=col, label=f"{enc}: textured")
        ax_bias.plot(alphas, [r["all_bias"] for r in rows], "o-", color=col, label=f"{enc}")
        ax_fid.plot(alphas, [r["edge_rms_to_bm"] for r in rows], "o-", color=col, label=f"{enc}: from Eq. 3 BM")
        if "from_sparse" in summary[enc]:
            rs = [summary[enc]["from_sparse"][f"alpha={a:g}"] for a in alphas]
            ax_mae.plot(alphas, [r["all_mae"] for r in rs], "^:", color=col, label=f"{enc}: all, no Eq. 3")
            ax_bias.plot(alphas, [r["all_bias"] for r in rs], "^:", color=col, label=f"{enc}, no Eq. 3")
            ax_fid.plot(alphas, [r["edge_rms_to_bm"] for r in rs], "^:", color=col, label=f"{enc}: raw sparse, no Eq. 3")
    n = len(config.scenes)
    for ax in (ax_mae, ax_bias, ax_fid):
        ax.set_xscale("log")
        ax.set_xticks(alphas, [f"{a:g}" for a in alphas])
        ax.set_xlabel("data weight α (Eq. 4)")
    ax_mae.set_ylabel("MAE vs σ_gt (px)")
    ax_mae.set_title(f"MAE (mean of {n} scene(s); occlusion bands excluded)")
    ax_bias.set_ylabel("mean signed error (px)")
    ax_bias.axhline(0, color="0.5", lw=0.8)
    ax_bias.set_title("bias (estimate − σ_gt)")
    ax_fid.set_ylabel("RMS |B − BM| at edges (px)")
    ax_fid.set_yscale("log")
    ax_fid.set_title("fidelity to the data term's measures")
    for ax in (ax_mae, ax_bias, ax_fid):
        ax.legend(fontsize=6)
