"""Plot of Fig. 11: one row per rendered scene / photo — input, map and magnified result per method
preset, truth or edges."""

from __future__ import annotations

import numpy as np

from .style import RC, add_colorbar, plt, plot_scene_sets, save_figure


def plot(data, config, out_stem):
    """Draw the figure for the default scene set (``out_stem``, with the photos) and each further set
    (``<out_stem>_<set>``), captioned with the set (:func:`.style.plot_scene_sets`)."""
    first = config.scene_sets[0][0]
    return plot_scene_sets(lambda fd, name, stem: plot_one_set(_set_view(fd, name, photos=name == first), config,
                                                               stem), data, config, out_stem)


def _set_view(fd, set_name, *, photos: bool) -> dict:
    """Arrays ``<item>[__<P>]__<key>`` and metrics ``items`` / ``presets.<P>.items`` of one scene set's
    renders (and of the photos), ``item`` = ``scene:<name>`` / ``photo:<name>``."""
    outs = [("scene", o) for o in fd.find(scene_set=set_name)]
    if photos:
        outs += [("photo", o) for o in fd.find(variant="photo")]
    view, items = {}, []
    metrics = {"items": {}, "presets": {}, "factor": fd.config.factor}
    for kind, o in outs:
        item, p = f"{kind}:{o.case.scene}", o.case.preset
        if item not in items:
            items.append(item)
        tag = "" if p == "paper" else f"__{p}"
        for k, v in o.arrays().items():
            view[f"{item}{tag if k in ('map', 'magnified', 'sparse') else ''}__{k}"] = v
        m = {**o.nested(), **o.info}
        if p == "paper":
            metrics["items"][item] = m
        else:
            metrics["presets"].setdefault(p, {"items": {}})["items"][item] = m
    view.update(items=np.asarray(items), metrics=metrics)
    return view


def plot_one_set(data, config, out_stem):
    """Draw Fig. 11 for one scene set from :func:`_set_view`'s dict; returns the paths.

    Columns: input; then for every method preset of ``config.presets`` (first ``paper``, the
    reproduction; e.g. ``robust`` beside it) its estimated defocus map (colour bar "σ (px)", one
    scale per row shared by every map of the row) and its magnified ×k result; last σ_gt (renders,
    occlusion bands grey) or the paper preset's sparse blur measures at edge pixels (photos, which
    have no ground truth).
    """
    items = [str(s) for s in data["items"]]
    metrics = data["metrics"]
    k = metrics["factor"]
    presets = ["paper", *[p for p in getattr(config, "presets", ("paper",))[1:] if p in metrics.get("presets", {})]]
    ncols = 2 + 2 * len(presets)
    with plt.rc_context(RC):
        fig = plt.figure(figsize=(2.6 * ncols + 0.6, 2.2 * len(items)), layout="constrained")
        subs = np.atleast_1d(fig.subfigures(len(items), 1))
        for sub, item in zip(subs, items):
            _row(sub, data, item, presets, k)
    return save_figure(fig, out_stem)


def _item_metrics(data, item, pname):
    if pname == "paper":
        return data["metrics"]["items"][item]
    return data["metrics"]["presets"][pname]["items"][item]


def _row(sub, data, item, presets, k):
    kind, name = item.split(":", 1)
    axes = sub.subplots(1, 2 + 2 * len(presets))
    img = np.clip(data[f"{item}__input"], 0, 1)
    tags = {p: "" if p == "paper" else f"__{p}" for p in presets}
    dmaps = {p: data[f"{item}{tags[p]}__map"] for p in presets}
    m = _item_metrics(data, item, "paper")
    h, w = m["shape"]
    times = ", ".join(f"{p} {_item_metrics(data, item, p)['timings']['estimate_wall_s']:.1f} s" for p in presets)
    axes[0].imshow(img)
    axes[0].set_title(f"{name} ({'render' if kind == 'scene' else 'photo'}, {w}×{h})\nestimate: {times}")
    if kind == "scene":
        other = data[f"{item}__gt"]
        vmax = float(np.nanpercentile(np.concatenate([other.ravel(), *(d.ravel() for d in dmaps.values())]), 99.5))
        title_last = "ground truth σ_gt (grey: excluded)"
        other = np.ma.masked_where(data[f"{item}__occlusion"].astype(bool) | ~np.isfinite(other), other)
    else:
        other = data[f"{item}__sparse"]
        vmax = float(np.nanpercentile(np.concatenate([d.ravel() for d in dmaps.values()]), 99.5))
        title_last = "paper: sparse σ at edge pixels\n(grey: none)"
        other = np.ma.masked_invalid(other)
    vmax = max(vmax, 1e-3)
    map_axes = []
    for j, pname in enumerate(presets):
        pm = _item_metrics(data, item, pname)
        ax_map, ax_mag = axes[1 + 2 * j], axes[2 + 2 * j]
        im = ax_map.imshow(dmaps[pname], cmap="viridis", vmin=0, vmax=vmax)
        if kind == "scene":
            ax_map.set_title(f"{pname}: defocus map\nMAE {pm['all_mae']:.2f} px, bias {pm['all_bias']:+.2f} px")
        else:
            ax_map.set_title(f"{pname}: defocus map\nmedian {pm['map_median_px']:.2f}, p95 {pm['map_p95_px']:.2f} px")
        ax_mag.imshow(np.clip(data[f"{item}{tags[pname]}__magnified"], 0, 1))
        ax_mag.set_title(f"{pname}: defocus magnified ×{k:g}")
        map_axes.append(ax_map)
    axes[-1].set_facecolor("0.6")
    axes[-1].imshow(other, cmap="viridis", vmin=0, vmax=vmax, interpolation="nearest")
    axes[-1].set_title(title_last)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
    add_colorbar(sub, [*map_axes, axes[-1]], im, "σ (px)")
