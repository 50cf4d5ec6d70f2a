"""Scatter blur: every pixel spreads its radiance over its own aperture-shaped disk, with occlusion by layers.

A lens blurs by spreading each scene point's light over a circle of confusion; a gather blur (a
blur stack interpolated per pixel, :mod:`method.magnify.magnification`) instead averages every
pixel's neighbourhood whatever lies in front of what, so a blurry background bleeds over a sharp
subject and the subject leaks a halo into the background. This module follows the published
descriptions of synthetic depth of field — Wadhwa et al., "Synthetic depth-of-field with a
single-camera mobile phone" (SIGGRAPH 2018: per-pixel scatter of linear radiance, composited in
depth layers) and the classical renderer of BokehMe (Peng et al., CVPR 2022: per-pixel scatter with
a soft disk edge, normalised by the accumulated weight); the code is this project's own.

Kernel (σ convention of the harness: a uniform disk of diameter c has per-axis std c/4). A pixel
with blur σ px spreads over a disk of radius R = 2σ (diameter 4σ) or a regular hexagon of the same
per-axis variance (circumradius a = √(6/5)·R; flat top and bottom), sampled row by row: row dy
receives a horizontal segment, centred on the pixel, whose length is the shape's exact area between
dy − ½ and dy + ½, with area-weighted (anti-aliased) end pixels — a rim one pixel soft, and weights
that sum to the shape's area exactly, so after division by that sum the pixel's energy is conserved.
Radii are quantised to 1/:data:`RADIUS_STEPS_PER_PX` px (tabulated kernels).

Occlusion (:func:`layer_index`). Rule: in a photo with one focus plane and the scene behind it, a
pixel is sharper where it is nearer. Pixels are binned into layers by σ (edges σ₀·q^b,
:data:`FIRST_LAYER_SIGMA`, :data:`LAYER_RATIO`) and composited front to back, sharpest first. A
layer's scattered radiance N and scattered weight W (the coverage of its disks) give it the colour
N/W; it is taken to continue behind what is nearer, so where the nearer layers' pixels fill a fraction
f of its kernel around a pixel, its opacity there is α = min(W / (1 − f), 1). A sharp subject
therefore receives no background radiance (its own opacity is 1 up to its silhouette), a blurry layer
still spreads over the blurrier ones behind it, and the background next to a subject is the
renormalised average of the visible background. What remains uncovered (image borders) is
normalised by the accumulated weight. Limits: (1) a blurry object *in front of* the focus plane
(a foreground branch) is taken for background: it is cut off at its silhouette instead of
spreading over what is behind it — ``in_front`` marks such pixels (nearer than every other pixel,
blurrier = nearer among them); (2) what a nearer object hides is unknown and filled with the
visible pixels of the layer behind; (3) the input is already blurred, so the edge pixels of a blurry
object hold some of what is behind it, which spreads with the object; (4) pixels of one layer do not
occlude each other.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np
from scipy import fft as sfft
from scipy import ndimage

from ..registry import Entry, Registry

__all__ = ["APERTURES", "FIRST_LAYER_SIGMA", "LAYER_RATIO", "RADIUS_STEPS_PER_PX", "aperture_kernel",
           "layer_index", "radius_for_sigma", "scatter_blur"]

#: Radii are quantised to 1/RADIUS_STEPS_PER_PX px (the kernels are tabulated per quantised radius).
RADIUS_STEPS_PER_PX = 64
#: Upper edge of the first (sharpest) occlusion layer: extra blur σ, px.
FIRST_LAYER_SIGMA = 0.5
#: Ratio between the edges of consecutive occlusion layers (σ in [0.5, 1), [1, 2), ... for 2).
LAYER_RATIO = 2.0**0.5
#: Hexagon circumradius / disk radius of the same per-axis variance: a²·5/24 = R²/4.
HEXAGON_RADIUS_RATIO = math.sqrt(6.0 / 5.0)


def _disk_cumulative(radius, y):
    """∫ from −R to y of the disk's chord length 2√(R² − t²): area below height y, px² (y, R arrays)."""
    r = np.maximum(radius, 1e-300)
    t = np.clip(y, -radius, radius)
    return t * np.sqrt(np.maximum(radius * radius - t * t, 0.0)) + r * r * np.arcsin(np.clip(t / r, -1.0, 1.0))


def _hexagon_cumulative(radius, y):
    """Area of the flat-topped regular hexagon of the disk-equivalent radius R below height y (odd in y), px²."""
    a = HEXAGON_RADIUS_RATIO * radius
    t = np.clip(y, -a * math.sqrt(3.0) / 2.0, a * math.sqrt(3.0) / 2.0)
    return 2.0 * a * t - t * np.abs(t) / math.sqrt(3.0)


def _disk_extent(radius):
    return radius


def _hexagon_extent(radius):
    return HEXAGON_RADIUS_RATIO * radius * math.sqrt(3.0) / 2.0


#: Aperture shapes, by name: value = (cumulative area below height y, half-height) as functions of
#: the disk-equivalent radius R px (both shapes have per-axis variance R²/4).
APERTURES = Registry("aperture", {
    "disk": Entry((_disk_cumulative, _disk_extent), "uniform disk of radius R = 2σ, a thin lens's circle of confusion"),
    "hexagon": Entry((_hexagon_cumulative, _hexagon_extent),
                     "regular hexagon (six-blade iris, flat top) with the disk's per-axis variance"),
})


def _row_table(radii, aperture):
    """Per radius: half-length (px) of the segment of each row |dy| = 0..n, rows n, and 1 / total area.

    Row dy's segment is as long as the shape's area between dy − ½ and dy + ½; R = 0 is one pixel.
    """
    cumulative, extent = APERTURES[aperture]
    radii = np.asarray(radii, dtype=np.float64)
    nrows = np.floor(extent(radii) + 0.5).astype(np.int64)
    j = np.arange(int(nrows.max(initial=0)) + 1, dtype=np.float64)[None, :]
    r = radii[:, None]
    strips = cumulative(r, j + 0.5) - cumulative(r, j - 0.5)
    strips[radii == 0.0, 0] = 1.0
    strips = np.where(j <= nrows[:, None], np.maximum(strips, 0.0), 0.0)
    total = strips[:, 0] + 2.0 * strips[:, 1:].sum(axis=1)
    return 0.5 * strips, nrows, 1.0 / total


def _kernel_variance(radii, aperture):
    """Per-axis variance (mean of x and y) of the tabulated kernels of ``radii`` (px), px²."""
    half, nrows, scale = _row_table(radii, aperture)
    dy = np.arange(half.shape[1], dtype=np.float64)[None, :]
    rows = 2.0 * half * np.where(dy > 0, 2.0, 1.0)  # strip areas, rows ±dy counted together
    var_y = np.sum(rows * dy * dy, axis=1)
    n = np.floor(half + 0.5)  # the pixel holding the segment's end: Σ_x coverage·x² in closed form
    x_moment = np.where(n >= 1, (n - 1) * n * (2 * n - 1) / 3.0 + 2.0 * n * n * (half - n + 0.5), 0.0)
    var_x = np.sum(x_moment * np.where(dy > 0, 2.0, 1.0), axis=1)
    return 0.5 * (var_x + var_y) * scale


def radius_for_sigma(sigma, *, aperture: str = "disk") -> np.ndarray:
    """Disk-equivalent radius R (px) whose tabulated kernel has per-axis variance σ².

    For R ≫ 1 px, R ≈ 2σ (a disk of diameter c has per-axis std c/4); for small σ the pixel grid
    adds variance, so R is found by inverting the measured variance of the kernels on a grid of
    1/:data:`RADIUS_STEPS_PER_PX` px (monotone; σ below the first kernel wider than one pixel gives R < ½,
    one pixel).

    Parameters
    ----------
    sigma : ndarray, float, ≥ 0
        Per-axis std of the kernel, px.
    aperture : str, keyword-only
        Key of :data:`APERTURES`.

    Returns
    -------
    ndarray, float64, same shape, ≥ 0
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    top = 2.0 * float(sigma.max(initial=0.0)) + 2.0
    grid = np.arange(0.0, top + 1.0 / RADIUS_STEPS_PER_PX, 1.0 / RADIUS_STEPS_PER_PX)
    var = np.maximum.accumulate(_kernel_variance(grid, aperture))
    keep = np.concatenate([[True], np.diff(var) > 0])
    return np.interp(sigma * sigma, var[keep], grid[keep])


def aperture_kernel(sigma: float, *, aperture: str = "disk") -> np.ndarray:
    """The normalised 2-D kernel a pixel of extra blur σ is spread with, as :func:`scatter_blur` writes it.

    Parameters
    ----------
    sigma : float
        Per-axis std of the kernel, px, ≥ 0 (its radius: :func:`radius_for_sigma`).
    aperture : str, keyword-only
        Key of :data:`APERTURES`.

    Returns
    -------
    ndarray, (2n+1) x (2m+1), float64, sums to 1
        Centred on the middle pixel.
    """
    APERTURES.check(aperture, what="aperture")
    sigma = float(sigma)
    if not (math.isfinite(sigma) and sigma >= 0.0):
        raise ValueError(f"sigma={sigma!r} is invalid; allowed: finite and >= 0 (px)")
    radius = float(radius_for_sigma(np.array([sigma]), aperture=aperture)[0])
    half, nrows, scale = _row_table(np.array([round(radius * RADIUS_STEPS_PER_PX) / RADIUS_STEPS_PER_PX]), aperture)
    n = int(nrows[0])
    m = int(math.ceil(half[0].max())) + 1
    k = np.zeros((2 * n + 1, 2 * m + 1))
    x = np.arange(-m, m + 1, dtype=np.float64)
    for dy in range(-n, n + 1):
        h = half[0, abs(dy)]
        k[dy + n] = np.clip(np.minimum(x + 0.5, h) - np.maximum(x - 0.5, -h), 0.0, None)
    return k * scale[0]


def layer_index(sigma, *, in_front=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Occlusion layer of every pixel and the layers' order, nearest first.

    Parameters
    ----------
    sigma : ndarray, HxW, float, ≥ 0
        Blur σ of each pixel, px.
    in_front : ndarray of bool, HxW, optional, keyword-only
        Pixels in front of the focus plane.

    Returns
    -------
    (ndarray of int32, HxW; ndarray of int32; ndarray of float64)
        Layer ids; the ids present, nearest first; and each of those layers' representative σ, px
        (the geometric middle of its bin, σ₀/2 for the first). Behind the focus plane (every pixel
        without ``in_front``) bin b holds σ in [0, σ₀) for b = 0, else [σ₀·q^(b−1), σ₀·q^b), σ₀ =
        :data:`FIRST_LAYER_SIGMA`, q = :data:`LAYER_RATIO`, and sharper is nearer; pixels of
        ``in_front`` get layers of their own, blurrier first, all nearer than the others.
    """
    s = np.asarray(sigma, dtype=np.float64)
    b = np.where(s < FIRST_LAYER_SIGMA, 0,
                 1 + np.floor(np.log(np.maximum(s, FIRST_LAYER_SIGMA) / FIRST_LAYER_SIGMA) / math.log(LAYER_RATIO)))
    b = b.astype(np.int32)
    if in_front is None or not in_front.any():
        ids, bins = b, np.unique(b)
        order = bins
    else:
        top = int(b.max()) + 1
        ids = np.where(in_front, top + b, b).astype(np.int32)
        front = np.unique(b[in_front])[::-1]
        behind = np.unique(b[~in_front])
        order = np.concatenate([top + front, behind])
        bins = np.concatenate([front, behind])
    rep = np.where(bins == 0, 0.5 * FIRST_LAYER_SIGMA, FIRST_LAYER_SIGMA * LAYER_RATIO ** (bins - 0.5))
    return ids, order.astype(np.int32), rep.astype(np.float64)


@numba.njit(cache=True, inline="always")
def _splat(buf, img, sy, sx, half, n, scale, y0, y1, pad):
    """Add pixel (sy, sx)'s row segments to the difference rows y0 ≤ y < y1 of ``buf`` (last channel: weight)."""
    c = img.shape[2]
    for dy in range(max(-n, y0 - sy), min(n, y1 - 1 - sy) + 1):
        h = half[abs(dy)]
        if h <= 0.0:
            continue
        left = sx - h
        right = sx + h
        xa = int(math.floor(left + 0.5))
        xb = int(math.floor(right + 0.5))
        row = buf[sy + dy]
        if xa == xb:
            d0 = 2.0 * h * scale
            d1 = 0.0
            d2 = 0.0
            d3 = -d0
        else:
            fa = (xa + 0.5 - left) * scale
            fb = (right - xb + 0.5) * scale
            d0 = fa
            d1 = scale - fa
            d2 = fb - scale
            d3 = -fb
        for k in range(c):
            v = img[sy, sx, k]
            row[xa + pad, k] += d0 * v
            row[xa + 1 + pad, k] += d1 * v
            row[xb + pad, k] += d2 * v
            row[xb + 1 + pad, k] += d3 * v
        row[xa + pad, c] += d0
        row[xa + 1 + pad, c] += d1
        row[xb + pad, c] += d2
        row[xb + 1 + pad, c] += d3


@numba.njit(cache=True, parallel=True)
def _scatter_layer(buf, img, layer_of, layer, kidx, half, nrows, scale, reach, pad, chunk, point):
    """Difference rows of every pixel of ``layer``; row chunks in parallel, each writing only its own rows.

    Pixels of radius 0 (table index ``point``) are left to :func:`_composite_layer`, which adds them
    where they are, exactly.
    """
    h, w = layer_of.shape
    nchunks = (h + chunk - 1) // chunk
    for ci in numba.prange(nchunks):
        y0 = ci * chunk
        y1 = min(h, y0 + chunk)
        for sy in range(max(0, y0 - reach), min(h, y1 + reach)):
            for sx in range(w):
                if layer_of[sy, sx] != layer:
                    continue
                k = kidx[sy, sx]
                if k != point:
                    _splat(buf, img, sy, sx, half[k], nrows[k], scale[k], y0, y1, pad)


@numba.njit(cache=True, parallel=True)
def _composite_layer(buf, acc, trans, hidden, pad, img, layer_of, layer, kidx, point):
    """Prefix-sum the difference rows (zeroing them) and composite the layer under what is in front.

    Per pixel: N, W = the prefix sums plus, for a pixel of this layer with radius 0, its own value and
    weight 1 (added exactly, so a sharp pixel nothing covers keeps its value bit for bit); colour N/W
    and opacity α = min(W / max(1 − f, W), 1), f = ``hidden``; acc += T·α·N/W, T ← T·(1 − α).
    """
    h, wp, c1 = buf.shape
    w = acc.shape[1]
    c = c1 - 1
    for y in numba.prange(h):
        run = np.zeros(c1)
        for xp in range(wp):
            for k in range(c1):
                run[k] += buf[y, xp, k]
                buf[y, xp, k] = 0.0
            x = xp - pad
            if x < 0 or x >= w:
                continue
            own = layer_of[y, x] == layer and kidx[y, x] == point
            wsum = run[c] + 1.0 if own else run[c]
            if wsum <= 1e-12:
                continue
            alpha = min(wsum / max(1.0 - hidden[y, x], wsum, 1e-12), 1.0)
            s = trans[y, x] * alpha / wsum
            for k in range(c):
                acc[y, x, k] += s * (run[k] + img[y, x, k] if own else run[k])
            trans[y, x] *= 1.0 - alpha


class _HiddenCoverage:
    """Coverage of the pixels composited so far (the nearer layers) by a layer's kernel, by FFT (float32).

    A layer is taken to continue behind what is nearer: where a nearer layer hides a fraction f of a
    pixel's disk, the layer's own scattered weight W covers the rest, so its opacity is
    min(W / (1 − f), 1) and the colour it shows there is the renormalised N/W of its visible pixels.
    """

    def __init__(self, shape, sigma_max, aperture):
        self.shape = shape
        self.aperture = aperture
        k = aperture_kernel(sigma_max, aperture=aperture).shape  # the largest kernel: no wrap-around
        self.fft_shape = tuple(sfft.next_fast_len(n + m, real=True) for n, m in zip(shape, k))
        self.spectrum = None

    def add(self, members):
        spec = sfft.rfft2(members.astype(np.float32), s=self.fft_shape, workers=-1)
        self.spectrum = spec if self.spectrum is None else self.spectrum + spec

    def coverage(self, sigma):
        """HxW float32 in [0, 1]: the nearer pixels' coverage by the kernel of σ px (zeros before any layer)."""
        if self.spectrum is None:
            return np.zeros(self.shape, dtype=np.float32)
        k = aperture_kernel(sigma, aperture=self.aperture).astype(np.float32)
        ky, kx = k.shape[0] // 2, k.shape[1] // 2
        kpad = np.zeros(self.fft_shape, dtype=np.float32)
        kpad[:k.shape[0], :k.shape[1]] = k
        kpad = np.roll(kpad, (-ky, -kx), axis=(0, 1))
        out = sfft.irfft2(self.spectrum * sfft.rfft2(kpad, workers=-1), s=self.fft_shape, workers=-1)
        return np.clip(out[:self.shape[0], :self.shape[1]], 0.0, 1.0)


def _chunk_rows(h: int) -> int:
    """Rows per parallel chunk: about four chunks per thread, at least 16 rows."""
    return max(16, -(-h // (4 * max(1, numba.get_num_threads()))))


def scatter_blur(image, sigma, *, aperture: str = "disk", in_front=None,
                 progress: Callable[[str], None] | None = None) -> np.ndarray:
    """Spread every pixel's value over its own aperture of per-axis std ``sigma``, with occlusion by layers.

    Parameters
    ----------
    image : ndarray, HxWxC, float
        Linear radiance (≥ 0, may exceed 1: highlights are not clipped here).
    sigma : ndarray, HxW, float, ≥ 0
        Blur σ of each pixel (the kernel's per-axis std), px: a disk of radius R ≈ 2σ
        (:func:`radius_for_sigma`).
    aperture : str, keyword-only
        Key of :data:`APERTURES`: ``"disk"`` or ``"hexagon"``.
    in_front : ndarray of bool, HxW, optional, keyword-only
        Pixels in front of the focus plane (:func:`layer_index`); default none.
    progress : callable, optional, keyword-only
        Called with ``"scatter layer i/n"`` before each layer.

    Returns
    -------
    ndarray, HxWxC, float64
        The blurred radiance (not clipped).

    Raises
    ------
    ValueError
        Shapes that do not match, a negative or non-finite σ, an unknown aperture.

    Notes
    -----
    1. Radius per pixel: the R whose kernel has per-axis variance σ² (:func:`radius_for_sigma`),
       quantised to 1/:data:`RADIUS_STEPS_PER_PX` px; tabulate, per radius present, the half-length
       of each row's segment (the shape's area in that row) and 1 / the total area.
    2. Bin the pixels into occlusion layers (:func:`layer_index`) and order them nearest first.
    3. Per layer: every pixel of the layer adds its value × weight and its weight to difference rows
       (four writes per row: two area-weighted end pixels and the run between), rows split in
       parallel chunks; a prefix sum along each row gives the layer's scattered radiance N and
       weight W.
    4. Fraction f hidden by the nearer layers: their pixels' mask convolved with the kernel of the
       layer's representative σ (:func:`layer_index`; FFT, float32; 0 for the first layer).
    5. Composite front to back: α = min(W / max(1 − f, W), 1), acc += T·α·N/W, T ← T·(1 − α),
       T = 1 at the start.
    6. Normalise by the accumulated weight: acc / (1 − T) (> 0: every pixel covers itself).
    """
    img = np.ascontiguousarray(image, dtype=np.float64)
    sig = np.asarray(sigma, dtype=np.float64)
    if img.ndim != 3 or sig.shape != img.shape[:2]:
        raise ValueError(f"sigma has shape {sig.shape}; allowed: the image's HxW {img.shape[:2]}")
    if not np.all(np.isfinite(sig)) or (sig.size and float(sig.min()) < 0):
        raise ValueError("sigma must be finite and >= 0 (px)")
    APERTURES.check(aperture, what="aperture")
    r = radius_for_sigma(sig, aperture=aperture)
    if in_front is not None:
        in_front = np.asarray(in_front, dtype=bool)
        if in_front.shape != sig.shape:
            raise ValueError(f"in_front has shape {in_front.shape}; allowed: the image's HxW {sig.shape}")
    h, w, c = img.shape
    steps = np.rint(r * RADIUS_STEPS_PER_PX).astype(np.int64)
    present = np.flatnonzero(np.bincount(steps.ravel()))  # the quantised radii, without a sort
    lookup = np.zeros(int(present[-1]) + 1, dtype=np.int32)
    lookup[present] = np.arange(len(present), dtype=np.int32)
    kidx = lookup[steps]
    half, nrows, scale = _row_table(present / RADIUS_STEPS_PER_PX, aperture)
    point = 0 if present[0] == 0 else -1  # table index of radius 0 (present is sorted)
    layer_of, order, layer_sigma = layer_index(sig, in_front=in_front)
    reach = np.asarray(ndimage.maximum(nrows[kidx], labels=layer_of, index=order), dtype=np.int64) + 1
    pad = int(math.ceil(float(half.max(initial=0.5)))) + 2
    buf = np.zeros((h, w + 2 * pad + 1, c + 1))
    acc = np.zeros((h, w, c))
    trans = np.ones((h, w))
    chunk = _chunk_rows(h)
    hidden = _HiddenCoverage((h, w), float(layer_sigma.max(initial=0.0)), aperture)
    for i, layer in enumerate(order):
        if progress is not None:
            progress(f"scatter layer {i + 1}/{len(order)}")
        _scatter_layer(buf, img, layer_of, np.int32(layer), kidx, half, nrows, scale, int(reach[i]), pad, chunk,
                       point)
        _composite_layer(buf, acc, trans, hidden.coverage(float(layer_sigma[i])), pad, img, layer_of,
                         np.int32(layer), kidx, point)
        if i + 1 < len(order):
            hidden.add(layer_of == layer)
    covered = 1.0 - trans
    return acc / np.where(covered > 0, covered, 1.0)[..., None]
