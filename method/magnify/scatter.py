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
with blur σ px spreads over a disk of radius R ≈ 2σ (diameter ≈ 4σ; :func:`radius_for_sigma` makes the
sampled kernel's variance exactly σ²) or a regular hexagon of the same per-axis variance
(circumradius a = √(6/5)·R; flat top and bottom), sampled row by row: row dy
receives a horizontal segment, centred on the pixel, whose length is the shape's exact area between
dy − ½ and dy + ½, with area-weighted (anti-aliased) end pixels — a rim one pixel soft, and weights
that sum to the shape's area exactly, so after division by that sum the pixel's energy is conserved.
Radii are quantised to 1/:data:`RADIUS_STEPS_PER_PX` px (tabulated kernels). The cost grows with the
radius, so pixels whose disk is wider than :data:`COARSE_RADIUS` are spread as blocks of 2×2 (4×4,
8×8) pixels at half (quarter, eighth) resolution and upsampled, with the variance this adds removed
from the kernel: sums and centroids are kept, and the result stays within 50 dB PSNR of the
full-resolution scatter on a photo (tested).

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
from typing import NamedTuple

import numba
import numpy as np
from scipy import fft as sfft

from ..registry import Entry, Registry
from .scatter_kernels import add_upsampled, composite_layer, prefix_rows, scatter_sources, splat_down

__all__ = ["APERTURES", "COARSE_RADIUS", "FIRST_LAYER_SIGMA", "LAYER_RATIO", "Layers", "MAX_LEVEL",
           "RADIUS_STEPS_PER_PX", "aperture_kernel",
           "layer_index", "radius_for_sigma", "scatter_blur"]

#: Radii are quantised to 1/RADIUS_STEPS_PER_PX px (the kernels are tabulated per quantised radius).
RADIUS_STEPS_PER_PX = 64
#: Upper edge of the first (sharpest) occlusion layer: extra blur σ, px.
FIRST_LAYER_SIGMA = 0.5
#: Ratio between the edges of consecutive occlusion layers (σ in [0.5, 1), [1, 2), ... for 2).
LAYER_RATIO = 2.0**0.5
#: Sources whose radius is at least this (px) are spread at a coarser level (2×2 blocks, 4×4 from twice
#: this radius, 8×8 from four times): their cost grows with the radius, and blocks of b×b pixels of one
#: layer, spread with radius R/b and upsampled, cost ≈ 1/b³ as much.
COARSE_RADIUS = 12.0
#: Coarsest level (blocks of 2**MAX_LEVEL pixels).
MAX_LEVEL = 3
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
    grid, var = _variance_table(aperture, 2.0 * float(sigma.max(initial=0.0)) + 2.0)
    return np.interp(sigma * sigma, var, grid)


#: Per aperture: (radii, their kernels' variance) of the grid computed so far (grown on demand).
_VARIANCE_TABLES: dict = {}


def _variance_table(aperture, top):
    """Monotone (radius, variance) table of the kernels on the 1/:data:`RADIUS_STEPS_PER_PX` px grid up to ``top`` px."""
    n = int(math.ceil(top * RADIUS_STEPS_PER_PX)) + 1
    cached = _VARIANCE_TABLES.get(aperture)
    if cached is None or cached[0] < n:
        n = max(n, 2 * (cached[0] if cached else 0))
        grid = np.arange(n, dtype=np.float64) / RADIUS_STEPS_PER_PX
        var = np.maximum.accumulate(_kernel_variance(grid, aperture))
        keep = np.concatenate([[True], np.diff(var) > 0])
        cached = _VARIANCE_TABLES[aperture] = (n, grid[keep], var[keep])
    return cached[1], cached[2]


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
    h = half[0, np.abs(np.arange(-n, n + 1))][:, None]
    x = np.arange(-m, m + 1, dtype=np.float64)[None, :]
    return np.maximum(np.minimum(x + 0.5, h) - np.maximum(x - 0.5, -h), 0.0) * scale[0]


class Layers(NamedTuple):
    """Occlusion layers of an image (:func:`layer_index`)."""

    ids: np.ndarray     # HxW int32: each pixel's layer
    order: np.ndarray   # int32: the layers present, nearest first
    sigma: np.ndarray   # float64, per layer of ``order``: representative σ, px (middle of its bin)
    upper: np.ndarray   # float64, per layer of ``order``: upper edge of its bin, px (no member is blurrier)


def layer_index(sigma, *, in_front=None) -> Layers:
    """Occlusion layer of every pixel and the layers' order, nearest first.

    Parameters
    ----------
    sigma : ndarray, HxW, float, ≥ 0
        Blur σ of each pixel, px.
    in_front : ndarray of bool, HxW, optional, keyword-only
        Pixels in front of the focus plane.

    Returns
    -------
    Layers
        Behind the focus plane (every pixel without ``in_front``) bin b holds σ in [0, σ₀) for
        b = 0, else [σ₀·q^(b−1), σ₀·q^b), σ₀ = :data:`FIRST_LAYER_SIGMA`, q = :data:`LAYER_RATIO`, and
        sharper is nearer; pixels of ``in_front`` get layers of their own, blurrier first, all nearer
        than the others. A layer's representative σ is the geometric middle of its bin (σ₀/2 for the
        first).
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
    upper = FIRST_LAYER_SIGMA * LAYER_RATIO ** bins.astype(np.float64)
    return Layers(ids, order.astype(np.int32), rep.astype(np.float64), upper)


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
    3. Per layer: every pixel of the layer with R < :data:`COARSE_RADIUS` adds its value × weight and
       its weight to difference rows (four writes per row: two area-weighted end pixels and the run
       between), rows split in parallel chunks; a prefix sum along each row gives the layer's
       scattered radiance N and weight W (a pixel of radius 0 is added where it is, exactly). Pixels
       with R ≥ COARSE_RADIUS·2^(ℓ−1) (level ℓ ≤ :data:`MAX_LEVEL`, b = 2^ℓ) are splatted bilinearly
       onto the centres of b×b blocks (sums and centroids kept), spread there with the kernel of
       σ_b = √(mean σ² − v_b)/b (v_b: the variance the splat and the upsampling add), prefix-summed
       and added to N and W upsampled bilinearly: ≈ b³ times fewer writes for blurs this wide.
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
    src = np.concatenate([img, np.ones((h, w, 1))], axis=-1)  # values and the weight channel
    table = _KernelTable(r, aperture)
    with np.errstate(divide="ignore", invalid="ignore"):
        level = np.where(r < COARSE_RADIUS, 0,
                         np.minimum(MAX_LEVEL, 1 + np.floor(np.log2(np.maximum(r, COARSE_RADIUS) / COARSE_RADIUS))))
    layers = layer_index(sig, in_front=in_front)
    # rows a layer's pixels reach: those of its bin's blurriest kernel (+2 for the radius quantisation)
    reach = np.floor(APERTURES[aperture][1](radius_for_sigma(np.minimum(layers.upper, sig.max()), aperture=aperture))
                     + 0.5).astype(np.int64) + 2
    buf = np.zeros((h, w + 2 * table.pad + 1, c + 1))
    dense = np.zeros((h, w, c + 1)) if np.any(level > 0) else np.zeros((1, 1, c + 1))
    acc = np.zeros((h, w, c))
    trans = np.ones((h, w))
    hidden = _HiddenCoverage((h, w), float(layers.sigma.max(initial=0.0)), aperture)
    for i, layer in enumerate(layers.order):
        if progress is not None:
            progress(f"scatter layer {i + 1}/{len(layers.order)}")
        members = layers.ids == layer
        fine = members & (level == 0)
        direct = fine & (table.kidx == table.point)
        scatter_sources(buf, src, fine & ~direct, table.kidx, table.half, table.nrows, table.scale, int(reach[i]),
                        table.pad, _chunk_rows(h))
        coarse = np.unique(level[members & (level > 0)]).astype(int)
        if coarse.size:
            dense[...] = 0.0
            for lv in coarse:
                _scatter_coarse(dense, src, sig, members & (level == lv), 2**lv, aperture)
        composite_layer(buf, dense, bool(coarse.size), acc, trans, hidden.coverage(float(layers.sigma[i])), table.pad,
                        src, direct)
        if i + 1 < len(layers.order):
            hidden.add(members)
    covered = 1.0 - trans
    return acc / np.where(covered > 0, covered, 1.0)[..., None]


class _KernelTable:
    """Kernels of the radii present (quantised to 1/:data:`RADIUS_STEPS_PER_PX` px), each pixel's index into them."""

    def __init__(self, radius, aperture):
        steps = np.rint(radius * RADIUS_STEPS_PER_PX).astype(np.int64)
        present = np.flatnonzero(np.bincount(steps.ravel()))  # the quantised radii, without a sort
        lookup = np.zeros(int(present[-1]) + 1, dtype=np.int32)
        lookup[present] = np.arange(len(present), dtype=np.int32)
        self.kidx = lookup[steps]
        self.half, self.nrows, self.scale = _row_table(present / RADIUS_STEPS_PER_PX, aperture)
        self.point = 0 if present[0] == 0 else -1  # table index of radius 0 (present is sorted)
        self.pad = int(math.ceil(float(self.half.max(initial=0.5)))) + 2


def _level_variance(b: int) -> float:
    """Per-axis variance (full-res px²) a level of b×b blocks adds: the bilinear splat onto the block
    centres (b²·t(1 − t) for a source at fraction t between two centres, b²/6 on average) and the
    bilinear upsampling between them."""
    d = np.arange(-b, b) + 0.5  # full-res offsets of the pixels a block centre interpolates into
    wts = 1.0 - np.abs(d) / b
    return b * b / 6.0 + float(np.sum(wts * d * d) / np.sum(wts))


def _block_splat(src, sigma, members, b):
    """:func:`~method.magnify.scatter_kernels.splat_down` of the ``members``' values, weights and weighted σ²
    onto b×b block centres: (ceil(H/b), ceil(W/b), C + 2)."""
    h, w, c1 = src.shape
    out = np.empty((-(-h // b), -(-w // b), c1 + 1))
    splat_down(src, sigma, members, b, out)
    return out


def _scatter_coarse(dense, src, sigma, members, b, aperture):
    """Spread the ``members`` (HxW bool) as b×b blocks: value and weight splatted bilinearly onto the block
    centres, spread with the kernel of their mean σ² less :func:`_level_variance`, then added to ``dense``
    upsampled ×b."""
    splat = _block_splat(src, sigma, members, b)
    blocks = np.ascontiguousarray(splat[..., :-1])
    count = blocks[..., -1]
    occupied = count > 1e-12
    var = splat[..., -1] / np.where(occupied, count, 1.0)
    sigma_b = np.where(occupied, np.sqrt(np.maximum(var - _level_variance(b), 0.0)) / b, 0.0)
    table = _KernelTable(radius_for_sigma(sigma_b, aperture=aperture), aperture)
    hb, wb, c1 = blocks.shape
    buf = np.zeros((hb, wb + 2 * table.pad + 1, c1))
    scatter_sources(buf, blocks, occupied, table.kidx, table.half, table.nrows, table.scale,
                    int(table.nrows.max()) + 1, table.pad, _chunk_rows(hb))
    out = np.empty((hb, wb, c1))
    prefix_rows(buf, out, table.pad)
    add_upsampled(dense, out, b)
