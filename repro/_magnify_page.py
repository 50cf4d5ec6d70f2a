"""The before/after page of ``repro.magnify --html``: one self-contained HTML file to judge a magnification by eye.

The page holds everything inline (images as base64 ``data:`` URIs, its CSS and a few lines of script;
nothing is fetched): the whole photo with a before/after slider, two zoomed crops (the subject, the
background) with their own sliders at whole-pixel magnification, and the defocus map as a colour overlay
that a checkbox shows or hides. It is built in memory (:func:`magnify_page`) and written atomically
(:func:`write_magnify_page`).
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np
from scipy import ndimage

__all__ = ["MAIN_MAX_SIDE", "MAIN_MIN_SIDE", "OVERLAY_ALPHA", "ZOOM_DISPLAY", "ZOOM_SIDE", "magnify_page",
           "write_magnify_page", "zoom_centres"]

#: Longer side of the whole-photo view, px (bigger photos are downscaled for the page; the crops are not).
MAIN_MAX_SIDE = 1600
#: Shortest displayed longer side of the whole-photo view, CSS px (a small photo is shown enlarged).
MAIN_MIN_SIDE = 800
#: Side of a zoomed crop, px of the photo (smaller photos: a third of their shorter side, at least 16).
ZOOM_SIDE = 160
#: Displayed side of a zoomed crop, about, CSS px (shown at a whole-pixel magnification).
ZOOM_DISPLAY = 400
#: Opacity of the map overlay.
OVERLAY_ALPHA = 0.6

_STYLE = """
body { font: 15px/1.4 system-ui, sans-serif; margin: 1.5em auto; max-width: 1700px; padding: 0 1em; color: #222; }
.compare { position: relative; display: inline-block; line-height: 0; user-select: none; }
.compare img { display: block; max-width: 100%; }
.compare img.after, .compare img.map { position: absolute; left: 0; top: 0; width: 100%; height: 100%; }
.compare img.after { clip-path: inset(0 0 0 50%); }
.compare img.map { opacity: OVERLAY; display: none; }
.compare.show-map img.map { display: block; }
.zoom img { image-rendering: pixelated; }
.compare input[type=range] { position: absolute; left: 0; bottom: 4px; width: 100%; margin: 0; }
.zooms { display: flex; gap: 2em; flex-wrap: wrap; }
figure { margin: 0; } figcaption { font-size: 13px; color: #555; margin-top: .3em; }
.legend { display: inline-block; width: 240px; height: 12px; vertical-align: middle; }
"""

_SCRIPT = """
document.querySelectorAll('.compare').forEach(function (box) {
  var after = box.querySelector('img.after'), range = box.querySelector('input[type=range]');
  function show() { after.style.clipPath = 'inset(0 0 0 ' + range.value + '%)'; }
  range.addEventListener('input', show); show();
});
document.getElementById('show-map').addEventListener('change', function (e) {
  document.querySelectorAll('.compare').forEach(function (box) { box.classList.toggle('show-map', e.target.checked); });
});
"""


def _data_uri(rgb8, fmt: str) -> str:
    """An 8-bit HxW(x3) array as a ``data:`` URI of a PNG or JPEG (quality 92, 4:4:4)."""
    from PIL import Image

    buf = io.BytesIO()
    im = Image.fromarray(rgb8)
    if fmt == "jpeg":
        im.save(buf, format="JPEG", quality=92, subsampling=0)
    else:
        im.save(buf, format="PNG", optimize=False)
    return f"data:image/{fmt};base64,{base64.b64encode(buf.getvalue()).decode('ascii')}"


def _to8(display) -> np.ndarray:
    return np.round(np.clip(display, 0.0, 1.0) * 255.0).astype(np.uint8)


def _colour_map(sigma, vmax) -> np.ndarray:
    """σ px → 8-bit RGBA of matplotlib's magma colour map over [0, vmax], opaque (the page sets the overlay's opacity)."""
    import matplotlib

    rgba = matplotlib.colormaps["magma"](np.clip(np.asarray(sigma) / vmax, 0.0, 1.0))
    rgba[..., 3] = 1.0
    return _to8(rgba)


def _shrink(a, side) -> np.ndarray:
    """8-bit image downscaled (Lanczos) so its longer side is at most ``side`` px."""
    from PIL import Image

    h, w = a.shape[:2]
    if max(h, w) <= side:
        return a
    s = side / max(h, w)
    return np.asarray(Image.fromarray(a).resize((max(1, round(w * s)), max(1, round(h * s))), Image.LANCZOS))


def zoom_centres(sigma, *, focus_point=None, keep_sharp=None, side=ZOOM_SIDE) -> tuple[tuple[int, int], ...]:
    """(row, column) centres of the subject's and the background's crops.

    Parameters
    ----------
    sigma : ndarray, HxW, float
        The defocus map, σ px.
    focus_point : (x, y), optional, keyword-only
        The subject, when the user named it.
    keep_sharp : ndarray, HxW, optional, keyword-only
        The subject's mask: its centroid, when no ``focus_point``.
    side : int, keyword-only
        Crop side, px.

    Returns
    -------
    ((row, col) of the subject, (row, col) of the background)
        The subject: ``focus_point``, else the mask's centroid, else where the map averaged over a crop is
        lowest; the background: where that average is highest.
    """
    mean = ndimage.uniform_filter(np.asarray(sigma, dtype=np.float64), size=side, mode="nearest")
    background = np.unravel_index(int(np.argmax(mean)), mean.shape)
    if focus_point is not None:
        subject = (int(focus_point[1]), int(focus_point[0]))
    elif keep_sharp is not None and np.any(keep_sharp > 0):
        rows, cols = np.nonzero(keep_sharp > 0.5) if np.any(keep_sharp > 0.5) else np.nonzero(keep_sharp > 0)
        subject = (int(np.mean(rows)), int(np.mean(cols)))
    else:
        subject = np.unravel_index(int(np.argmin(mean)), mean.shape)
    return tuple(int(v) for v in subject), tuple(int(v) for v in background)


def _crop(a, centre, side):
    h, w = a.shape[:2]
    y0 = min(max(0, centre[0] - side // 2), max(0, h - side))
    x0 = min(max(0, centre[1] - side // 2), max(0, w - side))
    return a[y0:y0 + side, x0:x0 + side], (x0, y0)


def _compare(before, after, overlay, *, fmt, alt, zoom=1.0, css="") -> str:
    h, w = before.shape[:2]
    size = f' width="{round(w * zoom)}" height="{round(h * zoom)}"'
    imgs = "".join(f'<img class="{cls}" alt="{html.escape(alt)}: {cls}" src="{_data_uri(a, f)}"{size}>'
                   for cls, a, f in (("before", before, fmt), ("after", after, fmt), ("map", overlay, "png")))
    return (f'<div class="compare {css}">{imgs}<input type="range" min="0" max="100" value="50" '
            f'aria-label="{html.escape(alt)}: before (left) / after (right)"></div>')


def magnify_page(before, after, sigma, *, title: str, summary: str, focus_point=None, keep_sharp=None) -> str:
    """The page as a string.

    Parameters
    ----------
    before, after : ndarray, HxW or HxWx3, float in [0, 1]
        The photo and the magnified result in display values (what a screen shows).
    sigma : ndarray, HxW, float
        The defocus map, σ px of the photo.
    title, summary : str, keyword-only
        Heading and the line under it (plain text, escaped).
    focus_point, keep_sharp : keyword-only
        The subject, when the user named it (:func:`zoom_centres`).

    Returns
    -------
    str
        A complete HTML document with no external reference.
    """
    b8, a8 = _to8(before), _to8(after)
    vmax = float(np.max(sigma, initial=0.0)) or 1.0
    overlay = _colour_map(sigma, vmax)
    H, W = b8.shape[:2]
    side = max(16, min(ZOOM_SIDE, min(H, W) // 3))
    zoom = max(1, ZOOM_DISPLAY // side)
    subject, background = zoom_centres(sigma, focus_point=focus_point, keep_sharp=keep_sharp, side=side)
    figures = []
    for name, centre in (("subject", subject), ("background", background)):
        (bc, (x0, y0)), (ac, _), (mc, _) = (_crop(a, centre, side) for a in (b8, a8, overlay))
        figures.append(f'<figure id="zoom-{name}">{_compare(bc, ac, mc, fmt="png", alt=name, zoom=zoom, css="zoom")}'
                       f'<figcaption>{name}: {bc.shape[1]}x{bc.shape[0]} px at ({x0}, {y0}), shown {zoom}x'
                       '</figcaption></figure>')
    legend = _data_uri(_colour_map(np.linspace(0.0, vmax, 256)[None, :].repeat(8, axis=0), vmax), "png")
    main = _compare(_shrink(b8, MAIN_MAX_SIDE), _shrink(a8, MAIN_MAX_SIDE), _shrink(overlay, MAIN_MAX_SIDE),
                    fmt="jpeg", alt="photo", zoom=max(1.0, MAIN_MIN_SIDE / max(H, W)))
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_STYLE.replace('OVERLAY', str(OVERLAY_ALPHA))}</style>"
            f"</head><body><h1>{html.escape(title)}</h1><p>{html.escape(summary)}</p>"
            "<p>Drag a slider: before on the left, after on the right. "
            "<label><input type=\"checkbox\" id=\"show-map\"> show the defocus map</label> "
            f"<img class=\"legend\" alt=\"colour scale\" src=\"{legend}\"> σ 0 – {vmax:.3g} px</p>"
            f"<figure id=\"whole\">{main}<figcaption>the whole photo ({W}x{H} px)</figcaption></figure>"
            f"<h2>Zoomed</h2><div class=\"zooms\">{''.join(figures)}</div>"
            f"<script>{_SCRIPT}</script></body></html>\n")


def write_magnify_page(path, page: str) -> Path:
    """Write :func:`magnify_page`'s string atomically (UTF-8)."""
    from defocus_cache import atomic_write

    path = Path(path)
    with atomic_write(path) as tmp:
        Path(tmp).write_text(page, encoding="utf-8")
    return path
