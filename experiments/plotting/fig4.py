"""Plot of Fig. 4: input, σ_gt, estimates at edges (one colour scale), error-vs-σ curves."""

from __future__ import annotations

import numpy as np

from .style import COLORS, add_colorbar, new_figure, plot_scene_sets, plt, save_figure


def dots(sigma, radius=1):
    """Sparse σ map (NaN off edges) with each estimate spread to its (2r+1)² neighbours (nearest)."""
    from scipy.ndimage import distance_transform_edt

    ok = np.isfinite(sigma)
    if not ok.any():
        return sigma
    dist, (iy, ix) = distance_transform_edt(~ok, return_indices=True)
    out = sigma[iy, ix]
    out[dist > radius] = np.nan
    return out


def _log_ticks(ax, values):
    from matplotlib.ticker import FixedLocator, NullLocator

    ax.set_xscale("log")
    ticks = [float(v) for v in values]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xticklabels([f"{t:g}" for t in ticks], fontsize=6)


def plot(data, config, out_stem):
    """Draw the figure for the default scene set (``out_stem``) and each further set with rendered scenes
    (``<out_stem>_<set>``), captioned with the set (:func:`.style.plot_scene_sets`); the paper preset."""
    rendered = set(data.values("scene_set", variant="pooled"))
    sets = type("Sets", (), {"scene_sets": [(s, n) for s, n in config.scene_sets if s in rendered]})
    return plot_scene_sets(lambda fd, name, stem: plot_one_set(*_set_view(fd, name), stem), data, sets, out_stem)


def _set_view(fd, set_name, preset="paper"):
    """(arrays, config) of one scene set: the showcase render's maps, the pooled curves, the analytic arrays."""
    import dataclasses
    import types

    config = fd.config
    showcase = dict(config.showcase).get(set_name)
    view = dict(fd.one(scene_set=set_name, preset=preset, variant="pooled").arrays())
    shown = fd.one(scene_set=set_name, scene=showcase, preset=preset, aperture=float(config.showcase_f_number),
                   variant="rendered").arrays()
    view.update({k: v for k, v in shown.items() if k.startswith("showcase_")})
    for fam in ("straight", "curved"):
        a = fd.one(scene_set=None, preset=preset, variant=f"analytic:{fam}").arrays()
        view["analytic_sigmas"] = a["sigmas"]
        view[f"analytic_{fam}_median_ae"] = a["median_ae"]
        view[f"analytic_{fam}_failure_rate"] = a["failure_rate"]
    view.update({k: v for k, v in fd.one(scene_set=None, preset=preset, variant="analytic:neighbouring").arrays().items()
                 if k != "estimators"})
    cfg = types.SimpleNamespace(**{f.name: getattr(config, f.name) for f in dataclasses.fields(config)},
                                showcase_scene=showcase)
    return view, cfg


def plot_one_set(data, config, out_stem):
    """Draw Fig. 4 for one scene set from :func:`_set_view`'s arrays and config; returns the paths."""
    ests = [str(e) for e in data["estimators"]]
    encs = [str(e) for e in data["encodings"]]
    convs = [str(c) for c in data["conventions"]]
    n_maps = 2 + len(ests)
    fig, axes = new_figure(2, max(n_maps, 4), width_in=2.3 * max(n_maps, 4), height_in=5.6)
    top, bottom = axes[0], axes[1]
    img = data["showcase_image"]
    gt = data["showcase_sigma_gt"].astype(np.float64)
    vmax = float(np.nanpercentile(gt, 99.5))
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
    top[0].imshow(np.clip(img, 0, 1))
    top[0].set_title(f"{config.showcase_scene} f/{config.showcase_f_number:g} ({encs[0]})")
    im = top[1].imshow(np.where(data["showcase_occlusion"], np.nan, gt), cmap=cmap, vmin=0, vmax=vmax)
    top[1].set_title("ground truth σ")
    for i, e in enumerate(ests):
        top[2 + i].imshow(dots(data["showcase_estimates"][i].astype(np.float64), radius=max(1, gt.shape[1] // 200)), cmap=cmap, vmin=0, vmax=vmax)
        top[2 + i].set_title(e)
    for ax in top[:n_maps]:
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in top[n_maps:]:
        ax.axis("off")
    add_colorbar(fig, top[n_maps - 1], im, "σ (px)")

    # error vs σ_gt, rendered (first convention), per encoding
    edges = data["curve_bin_edges"]
    centers = np.sqrt(edges[:-1] * edges[1:])
    ax = bottom[0]
    for ei, e in enumerate(ests):
        for ai, enc in enumerate(encs):
            y = data["curve_rendered_median_ae"][ai, 0, ei]
            ok = data["curve_rendered_count"][ai, 0, ei] >= 10
            ax.plot(centers[ok], y[ok], "o-" if ai == 0 else "s--", ms=3, color=COLORS[ei % len(COLORS)],
                    label=f"{e} ({enc})")
    _log_ticks(ax, edges)
    ax.set_xlabel(f"ground-truth σ (px, {convs[0]})")
    ax.set_ylabel("median |σ_est − σ_gt| (px)")
    ax.set_title("rendered, edges (bins ≥ 10 px)")
    ax.legend(fontsize=6)

    sig = data["analytic_sigmas"]
    for col, fam in ((1, "straight"), (2, "curved")):
        ax = bottom[col]
        for ei, e in enumerate(ests):
            for ci, cond in enumerate(("clean", "noisy")):
                ax.plot(sig, np.maximum(data[f"analytic_{fam}_median_ae"][ci, ei], 1e-3), "o-" if ci == 0 else "s--", ms=3,
                        color=COLORS[ei % len(COLORS)], label=f"{e} ({cond})")
        _log_ticks(ax, sig)
        ax.set_yscale("log")
        ax.set_xlabel("σ (px)")
        ax.set_ylabel("median |σ_est − σ| (px, floor 0.001)")
        ax.set_title(f"analytic {fam}")
        ax.legend(fontsize=6)

    ax = bottom[3]
    ks = data["bar_spacings"]
    kinds = [str(k) for k in data["bar_kinds"]]
    for ei, e in enumerate(ests):
        for gi, kind in enumerate(kinds):
            ax.plot(ks, 100 * data["bar_median_rel_error"][gi, 1, ei], "o-" if gi == 0 else "s--", ms=3,
                    color=COLORS[ei % len(COLORS)], label=f"{e} ({kind})")
    ax.set_xlabel("edge spacing D / σ")
    ax.set_ylabel("median |σ_est − σ| / σ (%)")
    ax.set_title("neighbouring edges (noisy)")
    ax.set_yscale("log")
    ax.legend(fontsize=6)
    for ax in bottom[4:]:
        ax.axis("off")
    return save_figure(fig, out_stem)
