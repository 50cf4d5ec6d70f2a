"""Shared plotting style: Agg backend, figure sizes, colour bars, atomic PNG + PDF output."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless; must precede pyplot

import matplotlib.pyplot as plt  # noqa: E402

__all__ = ["COLORS", "DPI", "SCENE_SET_CAPTIONS", "add_colorbar", "new_figure", "plot_scene_sets", "plt",
           "save_figure", "set_scenes"]

from ..scene_sets import SCENE_SET_CAPTIONS  # noqa: E402  (one line per set, written under its figures)

_caption: list[str] = []  # caption of the figure being drawn (set by plot_scene_sets)

#: PNG resolution, dots per inch.
DPI = 150
#: Line colours (colour-blind-safe Okabe–Ito subset), used in order.
COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9")

RC = {
    "font.size": 9,
    "axes.titlesize": 9,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "savefig.bbox": "tight",
    "pdf.fonttype": 42,  # embed TrueType (editable text in PDFs)
}


def new_figure(nrows=1, ncols=1, *, width_in=6.5, height_in=3.5, **kwargs):
    """A figure and axes with the project style (sizes in inches)."""
    with plt.rc_context(RC):
        fig, axes = plt.subplots(nrows, ncols, figsize=(width_in, height_in), **kwargs)
    fig.set_layout_engine("constrained")
    return fig, axes


def add_colorbar(fig, ax, mappable, label):
    """Colour bar beside ``ax`` with a label (include the unit in ``label``)."""
    cb = fig.colorbar(mappable, ax=ax, shrink=0.85)
    cb.set_label(label)
    return cb


def save_figure(fig, out_stem) -> list[Path]:
    """Write ``out_stem.png`` and ``out_stem.pdf`` atomically, close the figure, return the paths."""
    from defocus_cache import atomic_write

    out_stem = Path(out_stem)
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    if _caption:
        fig.text(0.5, 0.0, _caption[-1], ha="center", va="top", fontsize=8, style="italic")
    paths = []
    with plt.rc_context(RC):
        for ext in (".png", ".pdf"):
            path = out_stem.with_name(out_stem.name + ext)
            with atomic_write(path) as tmp:
                fig.savefig(tmp, dpi=DPI, format=ext[1:], metadata=_metadata(ext))
            paths.append(path)
            fig.set_layout_engine("none")  # the layout the first format computed serves the second
    plt.close(fig)
    return paths


def plot_scene_sets(plot_one, data, config, out_stem) -> list[Path]:
    """Draw a figure once per scene set: the default (first) set to ``out_stem``, each further one to
    ``<out_stem>_<set>`` (e.g. ``fig5_tabletop_stress.png``), each captioned with its set.

    Parameters
    ----------
    plot_one : callable
        ``plot_one(data, set_name, out_stem) -> list[Path]`` drawing one scene set from the figure's cases.
    data : experiments.figure_data.FigureData
        The figure's finished cases.
    config : frozen dataclass
        The figure's config (its ``scene_sets`` name the sets, in order).
    out_stem : Path
    """
    out_stem = Path(out_stem)
    have = set(data.values("scene_set"))
    names = [name for name, _ in config.scene_sets if name in have]
    paths = []
    for i, name in enumerate(names):
        stem = out_stem if i == 0 else out_stem.with_name(f"{out_stem.name}_{name}")
        _caption.append(SCENE_SET_CAPTIONS.get(name, f"scene set {name}"))
        try:
            paths += plot_one(data, name, stem)
        finally:
            _caption.pop()
    return paths


def set_scenes(config, set_name) -> tuple[str, ...]:
    """The scenes of ``set_name`` in a config's ``scene_sets``."""
    return dict(config.scene_sets)[set_name]


def _metadata(ext):
    # Fixed metadata keeps PDFs byte-stable across runs (no creation date).
    return {"CreationDate": None} if ext == ".pdf" else {"Software": "defocus-repro"}
