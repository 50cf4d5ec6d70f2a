"""Shared plotting style: Agg backend, figure sizes, colour bars, atomic PNG + PDF output."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless; must precede pyplot

import matplotlib.pyplot as plt  # noqa: E402

__all__ = ["COLORS", "DPI", "add_colorbar", "new_figure", "plt", "save_figure"]

#: PNG resolution, dots per inch.
DPI = 150
#: Line colours (colour-blind-safe Okabe–Ito subset), used in order.
COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9")

_RC = {
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
    with plt.rc_context(_RC):
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
    from scenes.storage import atomic_write

    out_stem = Path(out_stem)
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    with plt.rc_context(_RC):
        for ext in (".png", ".pdf"):
            path = out_stem.with_name(out_stem.name + ext)
            with atomic_write(path) as tmp:
                fig.savefig(tmp, dpi=DPI, format=ext[1:], metadata=_metadata(ext))
            paths.append(path)
    plt.close(fig)
    return paths


def _metadata(ext):
    # Fixed metadata keeps PDFs byte-stable across runs (no creation date).
    return {"CreationDate": None} if ext == ".pdf" else {"Software": "defocus-repro"}
