"""Plot of supplementary figure S1: MAE after each stage per preset, mosaic bias per σ bin, ablation."""

from __future__ import annotations

import numpy as np

from .style import COLORS, new_figure, save_figure

_LABELS = {"estimated:sparse": "sparse (edges)", "estimated:refined": "refined (edges)",
           "estimated:dense_textured": "dense (textured)",
           "oracle_refine:dense_textured": "dense, oracle → Eq. 3",
           "oracle_propagate:dense_textured": "dense, oracle → Eq. 4"}


def stage_view(fd) -> dict:
    """The cases of figure S1 as ``case_labels``, ``mae`` (images × presets × stages, px) and ``metrics``
    (``cases.<label>.<preset>`` = its stage errors, ``kind``; ``ablation.<row>.<label>``; ``presets``; ``stages``)."""
    from experiments.figS1_stages import STAGES, case_label

    config = fd.config
    presets = [p for p in config.presets if fd.find(preset=p)]
    images = [o.case for o in fd.outputs.values() if o.case.variant in ("mosaic", "render")
              and o.case.preset == presets[0]]
    labels = [case_label(c) for c in images]
    mae = np.full((len(images), len(presets), len(STAGES)), np.nan)
    cases, ablation = {}, {}
    for i, (c, label) in enumerate(zip(images, labels)):
        cases[label] = {"kind": c.variant}
        for j, p in enumerate(presets):
            m = fd.one(scene=c.scene, aperture=c.aperture, variant=c.variant, preset=p).nested()
            cases[label][p] = m
            for k, (inp, st) in enumerate(STAGES):
                v = m.get(inp, {}).get(st, {}).get("mae")
                mae[i, j, k] = np.nan if v is None else v
    for o in fd.outputs.values():
        if o.case.variant.startswith("ablation:"):
            ablation.setdefault(o.case.variant.split(":", 1)[1], {})[f"mosaic:{o.case.scene}"] = o.metrics
    return {"case_labels": np.asarray(labels), "mae": mae,
            "metrics": {"cases": cases, "ablation": ablation, "presets": presets,
                        "stages": [f"{a}:{b}" for a, b in STAGES]}}


def _bins(bins) -> list:
    """A stage's per-bin errors (a list, or the dict of a flattened list) as a list in bin order."""
    return [bins[k] for k in sorted(bins, key=int)] if isinstance(bins, dict) else list(bins)


def plot(data, config, out_stem):
    """Draw figure S1 from its cases (:func:`stage_view`); returns the paths."""
    data = stage_view(data)
    m = data["metrics"]
    presets = m["presets"]
    labels = [str(c) for c in data["case_labels"]]
    mae = np.asarray(data["mae"], dtype=float)
    n_p = len(presets)
    fig, axes = new_figure(2, max(n_p, 2), width_in=4.2 * max(n_p, 2), height_in=7.4, squeeze=False)
    x = np.arange(len(labels))
    width = 0.8 / mae.shape[2]
    for j, pname in enumerate(presets):
        ax = axes[0, j]
        for k, st in enumerate(m["stages"]):
            ax.bar(x + (k - (mae.shape[2] - 1) / 2) * width, mae[:, j, k], width, color=COLORS[k % len(COLORS)],
                   label=_LABELS.get(st, st))
        ax.set_xticks(x, labels, rotation=35, ha="right", fontsize=7)
        ax.set_ylabel("MAE vs σ_gt (px)")
        ax.set_title(f"preset {pname}")
        top = np.nanmax(mae) if np.isfinite(mae).any() else 1.0
        ax.set_ylim(0, 1.05 * top)
        if j == 0:
            ax.legend(fontsize=7)
    # bias per σ bin of the first mosaic's dense textured map, per preset
    ax = axes[1, 0]
    first = next((lab for lab in labels if lab.startswith("mosaic")), None)
    if first is not None:
        for j, pname in enumerate(presets):
            bins = _bins(m["cases"][first][pname]["estimated"]["dense_textured"]["bins"])
            xs = [0.5 * (float(b["lo"]) + (float(b["hi"]) if np.isfinite(float(b["hi"])) else float(b["lo"]) + 2))
                  for b in bins if b["n"]]
            ys = [b["bias"] for b in bins if b["n"]]
            ax.plot(xs, ys, "o-", color=COLORS[j % len(COLORS)], label=pname)
            ob = m["cases"][first][pname].get("oracle_refine", {}).get("dense_textured")
            if ob:
                ax.plot(xs, [b["bias"] for b in _bins(ob["bins"]) if b["n"]], "x--", color=COLORS[j % len(COLORS)],
                        lw=0.8, label=f"{pname}, oracle → Eq. 3")
        ax.axhline(0, color="0.5", lw=0.8)
        ax.axhspan(-0.3, 0.3, color="0.9", zorder=0, label="target ±0.3 px")
        ax.set_xlabel("σ_gt bin centre (px)")
        ax.set_ylabel("mean signed error of the dense map (px)")
        ax.set_title(f"{first}: bias per σ bin (textured pixels)")
        ax.legend(fontsize=7)
    ax = axes[1, 1]
    abl = m.get("ablation") or {}
    if abl and first is not None:
        rows = list(abl)
        vals = [abl[r][first]["dense_textured_mae"] for r in rows]
        sp = [abl[r][first]["sparse_mae"] for r in rows]
        y = np.arange(len(rows))
        ax.barh(y - 0.2, vals, 0.4, color=COLORS[0], label="dense (textured)")
        ax.barh(y + 0.2, sp, 0.4, color=COLORS[1], label="sparse (edges)")
        ax.set_yticks(y, [f"robust, {r}" if r != "all" else "robust (all switches)" for r in rows], fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("MAE vs σ_gt (px)")
        ax.set_title(f"ablation on {first}")
        ax.legend(fontsize=7)
    else:
        ax.axis("off")
    for j in range(2, axes.shape[1]):
        axes[1, j].axis("off")
    return save_figure(fig, out_stem)
