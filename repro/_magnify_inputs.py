"""What ``repro.magnify`` reads besides the photo: the subject (``--focus-point``, ``--keep-sharp``), front
and back (``--depth``), and the rule that fits a per-pixel file (map, mask, depth) to the photo's size.

Every reader checks the user's file before any output is written and raises
:class:`repro._cli.CLIError` (one line naming the flag, the file and what is allowed).
"""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import numpy as np

from repro._cli import CLIError

__all__ = ["DEPTH_SUFFIXES", "FOCUS_WINDOW_FRACTION", "SHARPEST_PERCENT", "FrontBack", "fit_to_photo", "front_back",
           "parse_focus_point", "read_depth", "read_keep_sharp"]

#: Files ``--depth`` reads (:func:`experiments.external_maps.read_map`: first array / first channel).
DEPTH_SUFFIXES = (".npy", ".npz", ".exr")
#: Half-width of the window read around ``--focus-point``, as a fraction of the photo's longer side (≥ 2 px).
FOCUS_WINDOW_FRACTION = 0.005
#: Without ``--focus-point`` the focus depth is read where the defocus map is lowest: its lowest this many %.
SHARPEST_PERCENT = 5.0


def fit_to_photo(values, shape, *, what: str, anti_alias: bool = True) -> tuple[np.ndarray, str | None, float]:
    """A per-pixel array fitted to the upright photo's size: as is, or resized when it has the photo's aspect ratio.

    Parameters
    ----------
    values : ndarray, h x w, float
        The file's values.
    shape : tuple
        The upright photo's shape (H, W, ...).
    what : str
        The flag and file, to name them in messages (e.g. ``"--depth d.npy"``).
    anti_alias : bool, keyword-only
        Low-pass before shrinking (off for values that must not be mixed across a boundary).

    Returns
    -------
    (ndarray H x W float64, note or None, s = W / w)

    Raises
    ------
    CLIError
        A size that is neither the photo's nor its aspect ratio.

    Notes
    -----
    An h×w array fits an H×W photo when h = round(w·H/W) or w = round(h·W/H) (the photo scaled by one
    factor, each side rounded to whole pixels). It is resized to H×W by bilinear interpolation of pixel
    centres (``skimage.transform.resize``, order 1, edge mode, anti-aliased when shrinking).
    """
    (H, W), (h, w) = shape[:2], values.shape
    if (h, w) == (H, W):
        return np.asarray(values, dtype=np.float64), None, 1.0
    if h < 1 or w < 1 or not (h == round(w * H / W) or w == round(h * W / H)):
        hint = (" (the photo is read upright, EXIF orientation applied: transpose it?)" if (h, w) == (W, H) else "")
        raise CLIError(f"{what}: {w}x{h} px does not fit the photo's {W}x{H} px{hint}; allowed: the photo's size "
                       "or its aspect ratio (resized)")
    from skimage.transform import resize

    s = W / w
    resized = resize(values.astype(np.float64), (H, W), order=1, mode="edge", anti_aliasing=anti_alias and s < 1,
                     preserve_range=True)
    return resized, f"{what} {w}x{h} px resized to the photo's {W}x{H} px", s


def parse_focus_point(text, shape) -> tuple[int, int]:
    """``--focus-point X,Y`` as integer pixel (column x, row y) of the upright photo, origin top left.

    Raises
    ------
    CLIError
        Not two numbers, or a point outside the photo (the message gives the allowed ranges).
    """
    H, W = shape[:2]
    allowed = f"allowed: X,Y with 0 <= X <= {W - 1} and 0 <= Y <= {H - 1} (px of the upright photo, origin top left)"
    parts = str(text).replace(" ", "").split(",")
    try:
        x, y = (float(p) for p in parts)
    except ValueError:
        raise CLIError(f"--focus-point {text!r} is not two numbers X,Y; {allowed}") from None
    if not (np.isfinite(x) and np.isfinite(y)):
        raise CLIError(f"--focus-point {text} is not finite; {allowed}")
    xi, yi = int(round(x)), int(round(y))
    if not (0 <= xi < W and 0 <= yi < H):
        raise CLIError(f"--focus-point {text} is outside the {W}x{H} px photo; {allowed}")
    return xi, yi


def read_keep_sharp(path, shape, *, max_pixels=None) -> np.ndarray:
    """``--keep-sharp MASK``: HxW float64 in [0, 1], 1 where the subject must stay sharp.

    Parameters
    ----------
    path : str or Path
        An image file :func:`repro.photo_io.read_photo` reads (PNG, JPEG, TIFF: white = keep sharp; an RGB mask
        is read by its brightest channel); the photo's size, or its aspect ratio (resized bilinearly).
    shape : tuple
        The upright photo's shape (H, W, ...).
    max_pixels : int or None, keyword-only
        Pixel budget of the mask file (as the photo's).

    Raises
    ------
    CLIError
        Missing or unreadable file, an EXR, another size, a mask with no pixel set.
    """
    from repro.photo_io import PhotoError, read_photo

    path = Path(path)
    what = f"--keep-sharp {path}"
    try:
        mask = read_photo(path, max_pixels=max_pixels)
    except PhotoError as exc:
        raise CLIError(f"--keep-sharp {exc}; allowed: a PNG, JPEG or TIFF mask, white where the subject is") from None
    if mask.encoding != "srgb":
        raise CLIError(f"{what}: a {mask.format} file holds light, not a mask; allowed: a PNG, JPEG or TIFF mask, "
                       "white where the subject is")
    values = mask.image if mask.image.ndim == 2 else mask.image.max(axis=2)
    values, _, _ = fit_to_photo(values, shape, what=what)
    if not np.any(values > 0):
        raise CLIError(f"{what}: no pixel is set (the mask is black); allowed: a mask that is white (or grey, "
                       "partly) where the subject is")
    return np.clip(values, 0.0, 1.0)


def read_depth(path, shape) -> tuple[np.ndarray, str | None]:
    """``--depth DEPTH``: HxW float64 values that grow with the distance from the camera, and a resize note.

    Parameters
    ----------
    path : str or Path
        ``.npy``, ``.npz`` (first array) or float ``.exr`` (first channel): a depth map (any unit) or a signed
        defocus map (negative in front of the focus plane, positive behind), the photo's size or its aspect
        ratio (resized bilinearly; the values are not scaled).
    shape : tuple
        The upright photo's shape (H, W, ...).

    Raises
    ------
    CLIError
        Missing, unreadable or not HxW; another suffix; NaN or Inf values; another size.
    """
    from experiments.external_maps import read_map

    path = Path(path)
    what = f"--depth {path}"
    if path.suffix.lower() not in DEPTH_SUFFIXES:
        raise CLIError(f"{what}: suffix {path.suffix or '(none)'!r}; allowed: {', '.join(DEPTH_SUFFIXES)}")
    if not path.is_file():
        raise CLIError(f"{what}: no such file")
    try:
        depth = read_map(path)
    except ValueError as exc:
        raise CLIError(f"--depth {exc}") from None
    bad = ~np.isfinite(depth)
    if bad.any():
        kind = "NaN" if np.isnan(depth).any() else "Inf"
        raise CLIError(f"{what}: {int(bad.sum())} non-finite values ({kind}); allowed: a finite depth (or signed "
                       "defocus) at every pixel")
    depth, note, _ = fit_to_photo(depth, shape, what=what, anti_alias=False)
    return depth, note


@dataclasses.dataclass(frozen=True)
class FrontBack:
    """Front and back of the focus plane read from ``--depth``.

    Attributes
    ----------
    in_front : ndarray, HxW, bool
        Pixels nearer than the focus depth by more than ``tolerance``.
    focus_depth : float
        The map's value at the subject (its unit).
    tolerance : float
        Margin below ``focus_depth`` still counted as the focus plane (the map's unit).
    where : str
        Where the focus depth was read, for the terminal.
    """

    in_front: np.ndarray
    focus_depth: float
    tolerance: float
    where: str


def front_back(depth, *, focus_point=None, sigma=None) -> FrontBack:
    """Which pixels are in front of the subject, from a depth (or signed defocus) map.

    Parameters
    ----------
    depth : ndarray, HxW, float
        Values growing with the distance from the camera.
    focus_point : (int, int), optional, keyword-only
        (x, y) px on the subject: the focus depth is the median of ``depth`` in a window around it
        (half-width :data:`FOCUS_WINDOW_FRACTION` of the longer side, ≥ 2 px).
    sigma : ndarray, HxW, float, optional, keyword-only
        The defocus map (σ px): without ``focus_point`` the focus depth is the median of ``depth`` over its
        lowest :data:`SHARPEST_PERCENT` % (the sharpest region). One of the two is required.

    Returns
    -------
    FrontBack

    Notes
    -----
    With R the depths of the focus region and D_f = median(R), the tolerance is
    max(3 · 1.4826 · MAD(R), 10⁻³ · (P99 − P1 of the whole map)), and a pixel is in front when
    D < D_f − tolerance: the focus region's own spread (a tilted or rough subject) is not taken for a
    foreground.
    """
    depth = np.asarray(depth, dtype=np.float64)
    H, W = depth.shape
    if focus_point is not None:
        x, y = focus_point
        r = max(2, int(round(FOCUS_WINDOW_FRACTION * max(H, W))))
        region = depth[max(0, y - r):y + r + 1, max(0, x - r):x + r + 1].ravel()
        where = f"read at --focus-point {x},{y}"
    elif sigma is not None:
        sigma = np.asarray(sigma, dtype=np.float64)
        region = depth[sigma <= np.percentile(sigma, SHARPEST_PERCENT)]
        where = f"read where the defocus map is lowest (its sharpest {SHARPEST_PERCENT:g} %)"
    else:
        raise ValueError("front_back needs focus_point or sigma")
    focus = float(np.median(region))
    lo, hi = np.percentile(depth, [1.0, 99.0])
    tolerance = max(3.0 * 1.4826 * float(np.median(np.abs(region - focus))), 1e-3 * float(hi - lo))
    return FrontBack(depth < focus - tolerance, focus, tolerance, where)
