"""Plot of Fig. 7: f/8 input, f/4 reference, magnified results (per renderer); maps (per method preset); bars."""

from __future__ import annotations

import numpy as np

from .style import RC, COLORS, add_colorbar, plt, plot_scene_sets, save_figure, set_scenes

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
    "magnified_estimated_scatter": "×2, estimated map, scatter",
    "magnified_oracle_srgb": "×2, oracle σ_d (sRGB)",
    "magnified_oracle_linear": "×2, oracle σ_d (linear)",
    "magnified_oracle_srgb_scatter": "×2, oracle σ_d (sRGB), scatter",
    "magnified_oracle_linear_scatter": "×2, oracle σ_d (linear), scatter",
}
#: Rows that depend on the method preset (one bar per preset); the others are the same for all.
_PRESET_MAPS = ("map_small", "k_x_map_small", "map_large")
_PRESET_IMAGES = ("magnified_estimated", "magnified_estimated_subtract", "magnified_estimated_scatter")


def _others(data, config):
    """The non-paper presets of ``config`` that the data has results for."""
    return [p for p in getattr(config, "presets", ("paper",))[1:] if p in data["metrics"].get("presets", {})]


def _scene_metrics(data, scene, pname):
    if pname == "paper":
        return data["metrics"]["scenes"][scene]
    return data["metrics"]["presets"][pname]["scenes"][scene]


def _renderers(data, config):
    """The further renderers (beyond the paper's first) the data has rows for."""
    names = data["metrics"].get("renderers", list(getattr(config, "renderers", ("gather",))))
    return [r for r in names[1:]]


def _categories(labels, preset_keys, presets, present=None):
    """Bar categories [(preset, key, label)]: the rows before the first preset-dependent one, every
    preset's copies of ``preset_keys`` (labelled with the preset's name), then the remaining rows;
    only the keys in ``present`` when given."""
    keys = [k for k in labels if present is None or k in present]
    preset_keys = [k for k in preset_keys if k in keys]
    first = min(keys.index(k) for k in preset_keys)
    lead = [k for k in keys[:first] if k not in preset_keys]
    tail = [k for k in keys[first:] if k not in preset_keys]
    out = [("paper", k, labels[k]) for k in lead]
    for p in presets:
        out += [(p, k, labels[k] + (f" ({p})" if len(presets) > 1 else "")) for k in keys if k in preset_keys]
    return out + [("paper", k, labels[k]) for k in tail]


def plot(data, config, out_stem):
    """Draw the figure for the default scene set (``out_stem``) and each further set
    (``<out_stem>_<set>``), captioned with the set (:func:`.style.plot_scene_sets`)."""
    return plot_scene_sets(lambda fd, name, stem: plot_one_set(*_set_view(fd, name), stem), data, config, out_stem)


def merge_nested(a: dict, b: dict) -> dict:
    """Nested dicts merged (``b`` adds to and overrides ``a``)."""
    out = dict(a)
    for k, v in b.items():
        out[k] = merge_nested(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _set_view(fd, set_name):
    """(arrays and metrics, config) of one scene set: per scene its stage case (renders, oracle rows)
    merged with each preset's case (``<scene>__<key>`` for the paper, ``<scene>__<P>__<key>`` else)."""
    import dataclasses
    import types

    config = fd.config
    scenes = [s for s in set_scenes(config, set_name) if fd.find(scene_set=set_name, scene=s)]
    cfg = types.SimpleNamespace(**{f.name: getattr(config, f.name) for f in dataclasses.fields(config)},
                                scenes=tuple(scenes), factor=config.factor)
    view, metrics = {}, {"scenes": {}, "presets": {}, "renderers": list(config.renderers)}
    for scene in scenes:
        stage = fd.one(scene_set=set_name, scene=scene, variant="stage")
        view.update({f"{scene}__{k}": v for k, v in stage.arrays().items()})
        for p in config.presets:
            out = fd.one(scene_set=set_name, scene=scene, preset=p)
            tag = "" if p == "paper" else f"{p}__"
            view.update({f"{scene}__{tag}{k}": v for k, v in out.arrays().items()})
            merged = merge_nested(stage.nested(), out.nested())
            if p == "paper":
                metrics["scenes"][scene] = merged
            else:
                metrics["presets"].setdefault(p, {"scenes": {}})["scenes"][scene] = merged
    view["metrics"] = metrics
    return view, cfg


def plot_one_set(data, config, out_stem):
    """Draw Fig. 7 for one scene set from :func:`_set_view`'s dict and config; returns the paths.

    Per scene: an image row and a map row of the ``paper`` preset (the reproduction; maps on one
    colour scale, "σ (px)"), one row per further preset of ``config.presets`` (e.g. ``robust``):
    its two magnified results and its f/8, 2 × f/8 and f/4 maps, and one row per further renderer
    (e.g. ``scatter``): its estimated-map and oracle results, and the |error| against the f/4 render
    of the gather's and its linear oracle result (colour bar "|error| (sRGB)") beside the f/4
    render's occlusion band. Then bar charts of the map MAE against σ_gt(f/4) and of the PSNR /
    SSIM against the real f/4 render, overall and in the occlusion band, every preset's bars
    labelled with its name. The image rows show both readings of Sec. 5's map floor
    (``floor="clamp"``, the default, and ``floor="subtract"``); the paper's map row the f/8 map after
    the ``"subtract"`` preprocessing.
    """
    scenes = config.scenes
    k = config.factor
    nl, ns = config.f_number_large_aperture, config.f_number_small_aperture
    others = _others(data, config)
    rows = 2 + len(others) + len(_renderers(data, config))
    with plt.rc_context(RC):
        fig = plt.figure(figsize=(13.5, 2.3 * rows * len(scenes) + 6.0 + 0.6 * len(others)), layout="constrained")
        subs = fig.subfigures(len(scenes) + 1, 1,
                              height_ratios=[float(rows)] * len(scenes) + [2.6 + 0.3 * len(others)])
        for sub, scene in zip(subs, scenes):
            _scene_rows(sub, data, scene, config, k, ns, nl, others)
        _bars(subs[-1], data, config, others)
    return save_figure(fig, out_stem)


def _off(ax):
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)


def _scene_rows(sub, data, scene, config, k, ns, nl, others=()):
    m = data["metrics"]["scenes"][scene]
    axes = sub.subplots(2 + len(others) + len(_renderers(data, config)), 5)
    q = m["image_vs_large"]
    pp = "paper: " if others else ""
    imgs = [("image_small", f"{scene}: f/{ns:g} input", q["unchanged_small"]),
            ("magnified", f"{pp}f/{ns:g} ×{k:g}, estimated map\n(Sec. 5 floor: clamp at 0)", q["magnified_estimated"]),
            ("magnified_subtract", f"{pp}f/{ns:g} ×{k:g}, estimated map\n(floor {m['map_floor_px']:.2f} px subtracted)",
             q["magnified_estimated_subtract"]),
            ("magnified_oracle_linear", f"×{k:g} with oracle σ_d (linear blur)", q["magnified_oracle_linear"]),
            ("image_large", f"real f/{nl:g} render (reference)", None)]
    for ax, (key, title, qq) in zip(axes[0], imgs):
        _image_panel(ax, data[f"{scene}__{key}"], title, qq)
    mm = m["maps_vs_gt_large"]
    maps = [("map_small", f"{pp}f/{ns:g} map", mm["map_small"]),
            ("map_small", f"{pp}{k:g} × f/{ns:g} map", mm["k_x_map_small"]),
            ("map_large", f"{pp}f/{nl:g} map", mm["map_large"]),
            ("map_small_subtract", f"f/{ns:g} map, Sec. 5 preprocessed\n(floor subtracted in quadrature)", None),
            ("gt_large", f"σ_gt(f/{nl:g}) (grey: excluded)", None)]
    vmax = float(np.nanpercentile(data[f"{scene}__gt_large"], 99.5))
    mask = data[f"{scene}__mask"].astype(bool)
    for i, (ax, (key, title, mt)) in enumerate(zip(axes[1], maps)):
        arr = data[f"{scene}__{key}"] * (k if i == 1 else 1.0)
        if key == "gt_large":
            arr = np.ma.masked_where(~mask, arr)
            ax.set_facecolor("0.6")
        im = _map_panel(ax, arr, title, mt, vmax, nl)
    map_axes = list(axes[1])
    for row, pname in zip(axes[2:], others):
        pm = _scene_metrics(data, scene, pname)
        pq, pmm = pm["image_vs_large"], pm["maps_vs_gt_large"]
        _image_panel(row[0], data[f"{scene}__{pname}__magnified"],
                     f"{pname}: f/{ns:g} ×{k:g}, its map\n(Sec. 5 floor: clamp at 0)", pq["magnified_estimated"])
        if "magnified_estimated_default" in pq and f"{scene}__{pname}__magnified_default" in data:
            # what a user of the preset gets: its own renderer and map floor
            used = sorted(f.split("_", 1)[1] for f, v in pm.get("default_magnification", {}).items() if v)
            _image_panel(row[1], data[f"{scene}__{pname}__magnified_default"],
                         f"{pname}: f/{ns:g} ×{k:g}, its default\n({', '.join(used)})", pq["magnified_estimated_default"])
        else:
            _image_panel(row[1], data[f"{scene}__{pname}__magnified_subtract"],
                         f"{pname}: f/{ns:g} ×{k:g}, its map\n(floor {pm['map_floor_px']:.2f} px subtracted)",
                         pq["magnified_estimated_subtract"])
        _map_panel(row[2], data[f"{scene}__{pname}__map_small"], f"{pname}: f/{ns:g} map", pmm["map_small"], vmax, nl)
        _map_panel(row[3], k * data[f"{scene}__{pname}__map_small"], f"{pname}: {k:g} × f/{ns:g} map",
                   pmm["k_x_map_small"], vmax, nl)
        _map_panel(row[4], data[f"{scene}__{pname}__map_large"], f"{pname}: f/{nl:g} map", pmm["map_large"], vmax, nl)
        map_axes += list(row[2:])
    add_colorbar(sub, map_axes, im, "σ (px)")
    for row, renderer in zip(axes[2 + len(others):], _renderers(data, config)):
        _renderer_row(sub, row, data, scene, renderer, q, k, ns)


def _renderer_row(sub, row, data, scene, renderer, q, k, ns):
    """Estimated and oracle results of ``renderer``; |error| of the gather's and its oracle (linear) result."""
    _image_panel(row[0], data[f"{scene}__magnified_{renderer}"], f"{renderer}: f/{ns:g} ×{k:g}, estimated map",
                 q[f"magnified_estimated_{renderer}"])
    _image_panel(row[1], data[f"{scene}__magnified_oracle_linear_{renderer}"],
                 f"{renderer}: ×{k:g} with oracle σ_d (linear)", q[f"magnified_oracle_linear_{renderer}"])
    ref = data[f"{scene}__image_large"].astype(np.float64)
    err = {name: np.abs(data[f"{scene}__magnified_oracle_linear{sx}"] - ref).mean(axis=-1)
           for name, sx in (("gather", ""), (renderer, f"_{renderer}"))}
    vmax = max(float(np.percentile(np.concatenate([e.ravel() for e in err.values()]), 99.5)), 1e-3)
    im = None
    for ax, (name, e) in zip(row[2:4], err.items()):
        key = "magnified_oracle_linear" + ("" if name == "gather" else f"_{renderer}")
        im = ax.imshow(e, cmap="magma", vmin=0, vmax=vmax)
        ax.set_title(f"|{name} oracle (linear) − f/4|\nocclusion band PSNR {float(q[key]['psnr_occlusion_db']):.1f} dB")
        _off(ax)
    add_colorbar(sub, list(row[2:4]), im, "|error| (sRGB)")
    row[4].imshow(data[f"{scene}__occlusion"].astype(float), cmap="gray", vmin=0, vmax=1)
    row[4].set_title("occlusion band of the f/4 render\n(white: within a CoC radius + 1 px\nof a depth jump)")
    _off(row[4])


def _image_panel(ax, img, title, qq):
    ax.imshow(np.clip(img, 0, 1))
    if qq is not None:
        title += f"\nPSNR {qq['psnr_db']:.1f} dB, SSIM {qq['ssim']:.3f}"
        if np.isfinite(float(qq.get("psnr_in_focus_db", float("nan")))):
            title += f"\nin focus {float(qq['psnr_in_focus_db']):.1f} dB"
    ax.set_title(title)
    _off(ax)


def _map_panel(ax, arr, title, mt, vmax, nl):
    im = ax.imshow(arr, cmap="viridis", vmin=0, vmax=vmax)
    if mt is not None:
        title += f"\nMAE vs σ_gt(f/{nl:g}) {mt['mae']:.2f} px, bias {mt['bias']:+.2f}"
    ax.set_title(title)
    _off(ax)
    return im


def _bars(sub, data, config, others=()):
    ax_map, ax_psnr, ax_ssim, ax_occ = sub.subplots(1, 4)
    scenes = config.scenes
    presets = ["paper", *others]
    present = set(data["metrics"]["scenes"][scenes[0]]["image_vs_large"])
    map_cats = _categories(_MAP_LABELS, _PRESET_MAPS, presets)
    img_cats = _categories(_IMAGE_LABELS, _PRESET_IMAGES, presets, present)
    width = 0.8 / len(scenes)
    for j, scene in enumerate(scenes):
        col = COLORS[j % len(COLORS)]
        x = np.arange(len(map_cats)) + j * width
        ax_map.bar(x, [_scene_metrics(data, scene, p)["maps_vs_gt_large"][key]["mae"] for p, key, _ in map_cats],
                   width, color=col, label=scene)
        x = np.arange(len(img_cats)) + j * width
        q = [_scene_metrics(data, scene, p)["image_vs_large"][key] for p, key, _ in img_cats]
        ax_psnr.bar(x, [float(v["psnr_db"]) for v in q], width, color=col, label=scene)
        ax_ssim.bar(x, [v["ssim"] for v in q], width, color=col, label=scene)
        ax_occ.bar(x, [float(v.get("psnr_occlusion_db", float("nan"))) for v in q], width, color=col, label=scene)
    off = 0.4 - width / 2
    ax_map.set_xticks(np.arange(len(map_cats)) + off, [c[2] for c in map_cats], rotation=25, ha="right")
    ax_map.set_ylabel(f"MAE vs σ_gt(f/{config.f_number_large_aperture:g}) (px)")
    ax_map.set_title("maps (occlusion bands excluded)")
    for ax, lab in ((ax_psnr, "PSNR vs real f/4 (dB)"), (ax_ssim, "SSIM vs real f/4"),
                    (ax_occ, "PSNR in the occlusion band (dB)")):
        ax.set_xticks(np.arange(len(img_cats)) + off, [c[2] for c in img_cats], rotation=35, ha="right",
                      fontsize=6)
        ax.set_ylabel(lab)
    qs = [_scene_metrics(data, s, p)["image_vs_large"][key] for s in scenes for p, key, _ in img_cats]
    ax_psnr.set_ylim(bottom=max(0.0, min(float(v["psnr_db"]) for v in qs) - 3.0))
    ax_ssim.set_ylim(bottom=max(0.0, min(v["ssim"] for v in qs) - 0.05), top=1.0)
    occ = [float(v["psnr_occlusion_db"]) for v in qs if np.isfinite(float(v.get("psnr_occlusion_db", np.nan)))]
    if occ:
        ax_occ.set_ylim(bottom=max(0.0, min(occ) - 3.0))
    ax_psnr.set_title("images vs the real f/4 render")
    ax_ssim.set_title("images vs the real f/4 render")
    ax_occ.set_title("occlusion band (f/4 render)")
    ax_map.legend()
