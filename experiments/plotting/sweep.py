"""Plot of an experiment sweep: each cell's metric per method variant (``python -m repro.sweep``)."""

from __future__ import annotations

from pathlib import Path

from experiments.sweep_table import metric_unit, summary

__all__ = ["plot_metric"]


def plot_metric(rows: list[dict], metric: str, path: Path) -> Path:
    """Each cell's ``metric`` per method variant (dots coloured by scene, bar = mean); PNG, atomic."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from defocus_cache import atomic_write

    labels = list(dict.fromkeys(r["method_variant"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(labels) + 2.5), 4.2), constrained_layout=True)
    cmap = plt.get_cmap("tab10")
    for j, scene in enumerate(scenes):
        xs, ys = [], []
        for r in rows:
            v = r.get(metric)
            if r["scene"] == scene and v is not None and np.isfinite(v):
                i = labels.index(r["method_variant"])
                xs.append(i + (j - (len(scenes) - 1) / 2) * 0.08)
                ys.append(v)
        ax.scatter(xs, ys, s=22, color=cmap(j % 10), label=scene, zorder=3)
    for s in summary(rows, metric):
        if s["mean"] is not None:
            i = labels.index(s["method_variant"])
            ax.hlines(s["mean"], i - 0.35, i + 0.35, color="k", lw=2, zorder=4)
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=20, ha="right", fontsize=8)
    ax.set_xlabel("method variant (preset/estimator and swept parameters)")
    ax.set_ylabel(f"{metric} [{metric_unit(metric)}]")
    ax.set_title(f"Sweep: {metric} per cell (dots, by scene) and mean (bar); {len(rows)} cells")
    ax.grid(axis="y", alpha=0.3)
    if scenes:
        ax.legend(title="scene", fontsize=8)
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path
