"""Plot of Fig. 6: dense maps for each α next to the ground truth, per method preset, and the errors vs α."""

from __future__ import annotations

import numpy as np

from .style import RC, COLORS, add_colorbar, plt, plot_scene_sets, save_figure, set_scenes


def plot(data, config, out_stem):
    """Draw the figure for the default scene set (``out_stem``) and each further set
    (``<out_stem>_<set>``), captioned with the set (:func:`.style.plot_scene_sets`)."""
    return plot_scene_sets(lambda fd, name, stem: plot_one_set(*_set_view(fd, name), stem), data, config, out_stem)


def _set_view(fd, set_name):
    """(arrays and metrics, config) of one scene set: the paper preset's first scene in the plotted
    encoding, every other preset's maps there, per-scene metrics and their means over the set's scenes."""
    import dataclasses
    import types

    from experiments.fig6_alpha_sweep import alpha_summary

    config = fd.config
    scenes = [s for s in set_scenes(config, set_name) if fd.find(scene_set=set_name, scene=s)]
    cfg = types.SimpleNamespace(**{f.name: getattr(config, f.name) for f in dataclasses.fields(config)},
                                scenes=tuple(scenes))
    enc, first = config.plot_encoding, scenes[0]
    per = {p: {s: {e: fd.one(scene_set=set_name, scene=s, preset=p, encoding=e).nested() for e in config.encodings}
               for s in scenes} for p in config.presets if fd.find(scene_set=set_name, preset=p)}
    shown = fd.one(scene_set=set_name, scene=first, preset="paper", encoding=enc).arrays()
    view = {"alphas": np.asarray(config.alphas, dtype=np.float64), "image": shown["image"],
            "sigma_gt": shown["sigma_gt"], "occlusion": shown["occlusion"], "edges": shown["edges"],
            "maps": shown["maps"]}
    metrics = {"scenes": per["paper"], "presets": {},
               "summary": alpha_summary(per["paper"], config.encodings, config.alphas,
                                        from_sparse=config.ablation_from_sparse)}
    for p in [p for p in per if p != "paper"]:
        a = fd.one(scene_set=set_name, scene=first, preset=p, encoding=enc).arrays()
        view[f"preset_{p}__maps"], view[f"preset_{p}__refined"] = a["maps"], a["refined"]
        metrics["presets"][p] = {"scenes": per[p], "alpha_applies": bool(per[p][first][enc]["alpha_applies"]),
                                 "summary": alpha_summary(per[p], config.encodings, config.alphas, from_sparse=False)}
    view["metrics"] = metrics
    return view, cfg


def plot_one_set(data, config, out_stem):
    """Draw Fig. 6 for one scene set from :func:`_set_view`'s dict and config; returns the paths.

    Top: one row per method preset of ``config.presets`` (first ``paper``, the reproduction):
    input and σ_gt (occlusion bands grey) in the paper's row, the preset's name and its Eq. (3)
    output BM at edge pixels in the others, then the map for every α (titles: MAE over all /
    textured pixels); one colour scale, colour bar "σ (px)". Bottom: the paper preset's MAE (all /
    textured pixels) vs α for each encoding, bias vs α and the RMS deviation from the data term's
    measures at edges vs α; then MAE and bias vs α of every preset (plotted encoding).
    """
    alphas = np.asarray(data["alphas"])
    maps, gt = data["maps"], data["sigma_gt"]
    others = [p for p in getattr(config, "presets", ("paper",))[1:] if f"preset_{p}__maps" in data]
    k = len(alphas)
    ncols = k + 2
    with plt.rc_context(RC):
        fig = plt.figure(figsize=(2.3 * ncols, 2.1 * (1 + len(others)) + 2.9), layout="constrained")
        top, bottom = fig.subfigures(2, 1, height_ratios=(2.1 * (1 + len(others)), 2.9))
        axes_top = np.atleast_2d(top.subplots(1 + len(others), ncols))
        ax_mae, ax_bias, ax_fid, ax_pmae, ax_pbias = bottom.subplots(1, 5)
        vmax = _vmax(data, gt, maps, others)
        im = _draw(data, config, alphas, maps, gt, ncols, top, axes_top[0], ax_mae, ax_bias, ax_fid, vmax=vmax)
        for row, pname in zip(axes_top[1:], others):
            _preset_row(data, config, alphas, pname, row, vmax)
        add_colorbar(top, list(axes_top.ravel()), im, "σ (px)")
        _preset_curves(data, config, alphas, others, ax_pmae, ax_pbias)
    return save_figure(fig, out_stem)


def _vmax(data, gt, maps, others):
    parts = [gt[np.isfinite(gt)].ravel(), maps.ravel(), *(data[f"preset_{p}__maps"].ravel() for p in others)]
    return float(np.nanpercentile(np.concatenate(parts), 99.5))


def _off(ax):
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)


def _preset_row(data, config, alphas, pname, row, vmax):
    """One preset's row: its name, its BM at edges (Eq. 3 output), its map for every α."""
    pm = data["metrics"]["presets"][pname]
    m = pm["scenes"][config.scenes[0]][config.plot_encoding]
    row[0].axis("off")
    note = "" if pm.get("alpha_applies", True) else "\n(its propagation has\nno α: one map)"
    row[0].text(0.5, 0.5, f"preset\n“{pname}”{note}", ha="center", va="center", fontsize=12,
                transform=row[0].transAxes)
    row[1].set_facecolor("0.6")
    row[1].imshow(np.ma.masked_invalid(data[f"preset_{pname}__refined"]), cmap="viridis", vmin=0, vmax=vmax,
                  interpolation="nearest")
    row[1].set_title(f"{pname}: Eq. 3 output BM\nat edges (grey: none)")
    _off(row[1])
    for i, a in enumerate(alphas):
        ax = row[i + 2]
        ax.imshow(data[f"preset_{pname}__maps"][i], cmap="viridis", vmin=0, vmax=vmax)
        r = m[f"alpha={a:g}"]
        ax.set_title(f"{pname}, α = {a:g}\nMAE {r['all_mae']:.2f} / {r['textured_mae']:.2f} px")
        _off(ax)


def _preset_curves(data, config, alphas, others, ax_mae, ax_bias):
    """MAE (all / textured) and bias vs α of every preset, plotted encoding, mean over scenes."""
    enc = config.plot_encoding
    metrics = data["metrics"]
    rows_by = {"paper": metrics["summary"][enc],
               **{p: metrics["presets"][p]["summary"][enc] for p in others}}
    for j, (pname, summary) in enumerate(rows_by.items()):
        col = COLORS[(j + 2) % len(COLORS)]
        rows = [summary[f"alpha={a:g}"] for a in alphas]
        ax_mae.plot(alphas, [r["all_mae"] for r in rows], "o-", color=col, label=f"{pname}: all")
        ax_mae.plot(alphas, [r["textured_mae"] for r in rows], "s--", color=col, label=f"{pname}: textured")
        ax_bias.plot(alphas, [r["all_bias"] for r in rows], "o-", color=col, label=f"{pname}: all")
        ax_bias.plot(alphas, [r["textured_bias"] for r in rows], "s--", color=col, label=f"{pname}: textured")
    for ax in (ax_mae, ax_bias):
        ax.set_xscale("log")
        ax.set_xticks(alphas, [f"{a:g}" for a in alphas])
        ax.set_xlabel("data weight α (Eq. 4)")
        ax.legend(fontsize=6)
    ax_mae.set_ylim(bottom=0)
    ax_mae.set_ylabel("MAE vs σ_gt (px)")
    ax_mae.set_title(f"presets: MAE ({enc} input)")
    ax_bias.set_ylabel("mean signed error (px)")
    ax_bias.axhline(0, color="0.5", lw=0.8)
    ax_bias.set_title(f"presets: bias ({enc} input)")


def _draw(data, config, alphas, maps, gt, ncols, top, axes_top, ax_mae, ax_bias, ax_fid, *, vmax=None):
    if vmax is None:
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
        ax.set_title(f"paper, α = {a:g}\nMAE {r['all_mae']:.2f} / {r['textured_mae']:.2f} px")
    for ax in axes_top:
        _off(ax)

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
    ax_mae.set_title(f"paper: MAE (mean of {n} scene(s);\nocclusion bands excluded)")
    ax_bias.set_ylabel("mean signed error (px)")
    ax_bias.axhline(0, color="0.5", lw=0.8)
    ax_bias.set_title("paper: bias (estimate − σ_gt)")
    ax_fid.set_ylabel("RMS |B − BM| at edges (px)")
    ax_fid.set_yscale("log")
    ax_fid.set_title("paper: fidelity to the\ndata term's measures")
    for ax in (ax_mae, ax_bias, ax_fid):
        ax.legend(fontsize=6)
    return im
