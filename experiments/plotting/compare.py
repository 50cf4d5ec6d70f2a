"""Per-scene scatter of two variants (``repro.compare``): A's value on x, B's on y, one panel per aperture."""

from __future__ import annotations

from .style import COLORS, new_figure, save_figure

__all__ = ["plot_scatter"]


def plot_scatter(panels, out_stem, *, a: str, b: str, metric: str, unit: str):
    """One panel per aperture: a point per scene at (A's value, B's value), the line y = x.

    Parameters
    ----------
    panels : list of (str, sequence of float, sequence of float)
        Per panel: its title (e.g. ``"f/8: B − A = -0.05\n95 % [-0.09, -0.01]"``), A's and B's values per
        scene (the same scenes, in the same order), in ``unit``.
    out_stem : path
        Output stem (``.png`` and ``.pdf`` are written).
    a, b : str, keyword-only
        The variants' names (axis labels).
    metric, unit : str, keyword-only
        What is plotted and its unit (axis labels).

    Returns
    -------
    list of Path
    """
    import numpy as np

    n = max(1, len(panels))
    fig, axes = new_figure(1, n, width_in=3.0 * n + 0.4, height_in=2.9, squeeze=False)
    for ax, (title, va, vb) in zip(axes[0], panels):
        va, vb = np.asarray(va, dtype=float), np.asarray(vb, dtype=float)
        hi = float(np.nanmax(np.concatenate([va, vb, [0.0]]))) * 1.05 or 1.0
        ax.plot([0.0, hi], [0.0, hi], color="0.5", lw=0.8, ls="--", label="y = x (no difference)")
        ax.scatter(va, vb, s=14, color=COLORS[0], alpha=0.8, label=f"one scene (n = {va.size})")
        ax.set_xlim(0.0, hi)
        ax.set_ylim(0.0, hi)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=8)
        ax.set_xlabel(f"{a}: {metric} ({unit})", fontsize=8)
        ax.set_ylabel(f"{b}: {metric} ({unit})", fontsize=8)
        ax.legend(loc="lower right", frameon=False, fontsize=7)
        ax.tick_params(labelsize=7)
    fig.suptitle(f"{b} against {a} per scene: below the line, {b} has the lower {metric}", fontsize=9)
    return save_figure(fig, out_stem)
