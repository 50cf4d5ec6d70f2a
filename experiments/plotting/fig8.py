"""Plot of Fig. 8: refocusing results next to the real render focused at D2; maps; λ sweep."""

from __future__ import annotations

import numpy as np

from .style import RC, COLORS, add_colorbar, plot_scene_sets, plt, save_figure

_SWEEP_LABELS = {
    "refocused_estimated_psnr_db": "refocused, estimated maps (vs D2)",
    "refocused_oracle_psnr_db": "refocused, oracle maps (vs D2)",
    "deconvolved_estimated_psnr_db": "deconvolved, estimated map (vs pinhole)",
    "deconvolved_oracle_psnr_db": "deconvolved, oracle σ (vs pinhole)",
}


def _off(ax):
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)


def _q(title, q):
    title += f"\nPSNR {q['psnr_db']:.1f} dB, SSIM {q['ssim']:.3f}"
    if "psnr_in_focus_db" in q and np.isfinite(float(q["psnr_in_focus_db"])):
        title += f"\nin focus at D2: {float(q['psnr_in_focus_db']):.1f} dB"
    return title


def plot(data, config, out_stem):
    """Draw the figure for the default scene set (``out_stem``) and each further set
    (``<out_stem>_<set>``), captioned with the set (:func:`.style.plot_scene_sets`); the paper preset."""
    sets = type("Sets", (), {"scene_sets": [(s, (scene,)) for s, scene, _, _ in config.scene_sets]})
    return plot_scene_sets(lambda fd, name, stem: plot_one_set(*_set_view(fd, name), stem), data, sets, out_stem)


def _set_view(fd, set_name, preset="paper"):
    """(arrays and metrics, config) of one scene set and preset: its stage, map and λ cases merged; the
    λ sweep from every λ case."""
    import dataclasses
    import types

    from .fig7 import merge_nested

    config = fd.config
    stage = fd.one(scene_set=set_name, variant="stage")
    mcase = fd.one(scene_set=set_name, preset=preset, variant="map")
    main = fd.one(scene_set=set_name, preset=preset, variant=f"nsr={config.nsr:g}")
    view = {**stage.arrays(), **mcase.arrays(), **main.arrays()}
    metrics = merge_nested(merge_nested(stage.nested(), mcase.nested()), main.nested())
    sweep = sorted((o.nested() for o in fd.find(scene_set=set_name, preset=preset)
                    if o.case.variant.startswith("nsr=") and float(o.case.variant[4:]) in config.nsr_sweep),
                   key=lambda m: m["nsr"])
    metrics["nsr_sweep"] = {f"nsr={m['nsr']:g}": m for m in sweep}
    view["metrics"] = metrics
    cfg = types.SimpleNamespace(**{f.name: getattr(config, f.name) for f in dataclasses.fields(config)},
                                scene=stage.case.scene)
    return view, cfg


def plot_one_set(data, config, out_stem):
    """Draw Fig. 8 for one scene set from :func:`_set_view`'s dict and config; returns the paths.

    Row 1: the D1 input, the deconvolved input, the three refocused results and the real D2 render
    (PSNR/SSIM against it in the titles). Row 2: the estimated map, the estimated virtual-focus map
    (with the click), σ_gt at D2 and D1 on one colour scale, the deconvolution against the
    near-pinhole render. Row 3: PSNR bars against the D2 render and the λ sweep.
    """
    m = data["metrics"]
    q = m["images_vs_d2"]
    dq = m["deconvolution_vs_pinhole"]
    d1, d2 = m["focus_distance_1_m"], m["focus_distance_2_m"]
    n = config.f_number
    with plt.rc_context(RC):
        fig = plt.figure(figsize=(15.5, 8.8), layout="constrained")
        top, mid, bottom = fig.subfigures(3, 1, height_ratios=[1.1, 0.95, 1.0])
        axes = top.subplots(1, 6)
        imgs = [("image_d1", _q(f"{config.scene}: input, f/{n:g} focused at D1 = {d1:g} m", q["unchanged_d1"])),
                ("deconvolved_estimated", _q(f"deconvolved with the estimated map\n(λ = {config.nsr:g}; vs pinhole f/"
                                             f"{config.all_in_focus_f_number:g})", dq["deconvolved_estimated"])),
                ("refocused_estimated", _q("refocused: estimated map +\nvirtual map from the map alone",
                                           q["refocused_estimated"])),
                ("refocused_estimated_oracle_virtual", _q("refocused: estimated map +\noracle virtual map σ_gt(D2)",
                                                          q["refocused_estimated_oracle_virtual"])),
                ("refocused_oracle", _q("refocused: oracle σ_gt(D1) →\nσ_gt(D2)", q["refocused_oracle"])),
                ("image_d2", f"real render focused at D2 = {d2:g} m\n(reference)")]
        for ax, (key, title) in zip(axes, imgs):
            ax.imshow(np.clip(data[key], 0, 1))
            ax.set_title(title)
            _off(ax)
        x, y = (int(v) for v in data["focus_point_px"])
        axes[0].plot([x], [y], marker="+", color="yellow", markersize=12, mew=2)

        axes = mid.subplots(1, 6)
        vmax = float(np.nanpercentile(np.concatenate([data["gt_d1"].ravel(), data["gt_d2"].ravel()]), 99.5))
        vm = m["virtual_map_vs_gt_d2"]
        maps = [("map_estimated", "estimated map B at D1\n(Sec. 5 preprocessed)"),
                ("virtual_map_estimated", (f"virtual map √((σ_d − σ_t)² + p_lo²)\nσ_t = {m['sigma_t_px']:.2f} px "
                                           f"at +, MAE vs σ_gt(D2) {vm['estimated']['all']['mae']:.2f} px")),
                ("gt_d2", "σ_gt(D2) (oracle virtual map)"),
                ("gt_d1", "σ_gt(D1) (oracle map)")]
        for ax, (key, title) in zip(axes[:4], maps):
            im = ax.imshow(data[key], cmap="viridis", vmin=0, vmax=vmax)
            ax.set_title(title)
            _off(ax)
        axes[1].plot([x], [y], marker="+", color="red", markersize=12, mew=2)
        add_colorbar(mid, list(axes[:4]), im, "σ (px)")
        axes[4].imshow(data["in_focus_d2"], cmap="gray")
        axes[4].set_title(f"in focus at D2 (σ_d ≤ {config.in_focus_sigma_px:g} px),\noutside occlusion bands")
        _off(axes[4])
        axes[5].imshow(np.clip(data["image_pinhole"], 0, 1))
        axes[5].set_title(_q(f"near-pinhole f/{config.all_in_focus_f_number:g} render\n(D1 input vs it:)",
                             dq["unchanged_d1"]))
        _off(axes[5])

        ax_bar, ax_sweep = bottom.subplots(1, 2, width_ratios=[1.2, 1.0])
        names = ["unchanged_d1", "refocused_estimated", "refocused_estimated_oracle_virtual", "refocused_oracle"]
        labels = ["D1 unchanged", "estimated maps", "est. map +\noracle virtual", "oracle maps"]
        xs = np.arange(len(names))
        ax_bar.bar(xs - 0.2, [q[k]["psnr_db"] for k in names], 0.4, color=COLORS[0], label="all pixels")
        ax_bar.bar(xs + 0.2, [q[k]["psnr_in_focus_db"] for k in names], 0.4, color=COLORS[1],
                   label="in focus at D2")
        ax_bar.set_xticks(xs, labels)
        ax_bar.set_ylabel("PSNR vs real D2 render (dB)")
        lo = min(min(q[k]["psnr_db"], q[k]["psnr_in_focus_db"]) for k in names)
        ax_bar.set_ylim(bottom=max(0.0, lo - 3.0))
        ax_bar.set_title("refocusing D1 → D2")
        ax_bar.legend()
        sweep = list(m["nsr_sweep"].values())
        lam = [row["nsr"] for row in sweep]
        for i, (key, label) in enumerate(_SWEEP_LABELS.items()):
            ax_sweep.plot(lam, [row[key] for row in sweep], marker="o", color=COLORS[i % len(COLORS)], label=label)
        ax_sweep.axhline(q["unchanged_d1"]["psnr_db"], color=COLORS[0], ls="--", lw=1, label="D1 unchanged vs D2")
        ax_sweep.axhline(dq["unchanged_d1"]["psnr_db"], color=COLORS[2], ls=":", lw=1, label="D1 unchanged vs pinhole")
        ax_sweep.axvline(config.nsr, color="0.5", lw=1)
        ax_sweep.set_ylim(top=max(ax_sweep.get_ylim()[1], dq["unchanged_d1"]["psnr_db"], q["unchanged_d1"]["psnr_db"]) + 0.5)
        ax_sweep.set_xscale("log")
        ax_sweep.set_xlabel("deconvolution λ (noise-to-signal ratio)")
        ax_sweep.set_ylabel("PSNR (dB)")
        ax_sweep.set_title("sensitivity to λ (grey: λ used above)")
        ax_sweep.legend(fontsize="small")
    return save_figure(fig, out_stem)
