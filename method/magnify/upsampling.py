"""Defocus estimation at a reduced working resolution, with edge-aware upsampling of the map.

A 24-megapixel photo is too big for the estimator's time and memory budget (≤ 5 s and ≤ 3 GiB at
1 MP, see ``repro.bench``), and the map it produces is smooth anyway (Eq. 4 propagates it, Sec. 5
blurs it by 0.5 % of the image size before magnifying). So the map is estimated on a downscaled
copy of the photo and brought back to full resolution with a *guided filter* whose guide is the
full-resolution photo: the upsampled map follows the photo's own edges, not the blocky working grid.

Units: a blur σ measured at linear scale ``s`` (working px) is ``σ / s`` px of the full-resolution
photo. Downscaling also adds a known Gaussian prefilter (anti-aliasing) of
``σ_pre = (1/s − 1) / 2`` full-resolution px, which :func:`working_to_full_sigma` removes in
quadrature: ``σ_full = √max((σ_w / s)² − σ_pre², 0)``.

Pure numerics: arrays in, arrays out. No file I/O.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from scipy import ndimage

from ..luma import LUMA_WEIGHTS, light_of, to_light
from ..edges.tone_curve import INPUT_ENCODINGS
from ..validation import MIN_IMAGE_SIDE, validate_image, validate_map

__all__ = ["DEFAULT_MAX_WORKING_PIXELS", "GUIDED_EPS", "GUIDED_RADIUS", "ScaledDefocusResult",
           "downscale_image", "estimate_defocus_map_at_scale", "guided_upsample", "magnify_defocus_tiled",
           "prefilter_sigma", "upsample_defocus_map", "working_shape", "working_to_full_sigma"]

#: Default working-resolution budget, px (≈ 1.5 MP, e.g. 1500 × 1000). The estimator's target is
#: ≤ 5 s and ≤ 3 GiB at 1 MP, growing about linearly with the pixel count, so 1.5 MP stays within
#: ≈ 8 s and 4.5 GiB on an idle machine. Measured (repro.estimate on a 24 MP JPEG, 2 cores shared
#: with other jobs, load ≈ 4.5): pipeline 19 s (propagation 15 s), peak RSS 1.25 GiB for the whole
#: run. 1.5 MP still resolves σ to ≈ 1/s px of a 24 MP photo (s = 0.25), finer than the 0.5 %-of-size
#: smoothing (30 px at 6000 px) the magnifier applies to the map anyway (Sec. 5).
DEFAULT_MAX_WORKING_PIXELS = 1_500_000

#: Guided-filter window radius, working px (window (2r+1)²): small, so the filter only re-aligns the
#: map to the guide's edges and does not smooth it (Sec. 5 smooths it later, by 0.5 % of the size).
GUIDED_RADIUS = 2

#: Guided-filter regulariser, in squared guide units (luminance in [0, 1]): edges with a local
#: luminance std above √eps ≈ 0.03 are followed, weaker texture is averaged over.
GUIDED_EPS = 1e-3


_STRIP_ROWS = 512  # rows of the full-resolution output computed at once (bounds temporary memory)


@dataclasses.dataclass(frozen=True)
class ScaledDefocusResult:
    """A defocus map estimated at a working resolution and upsampled to the photo's.

    Attributes
    ----------
    defocus_map : ndarray, HxW, float64
        Dense blur σ, px of the full-resolution photo, ≥ 0.
    scale : float
        Working / full linear scale s, 0 < s ≤ 1 (1: estimated at full resolution).
    working_shape : tuple of int
        (h, w) of the working image.
    working_result : DefocusResult
        The pipeline's result at working resolution (σ in *working* px).
    """

    defocus_map: np.ndarray
    scale: float
    working_shape: tuple[int, int]
    working_result: object


def working_shape(shape, *, max_working_pixels=DEFAULT_MAX_WORKING_PIXELS) -> tuple[tuple[int, int], float]:
    """The working resolution for a photo: the largest same-aspect size within the pixel budget.

    Parameters
    ----------
    shape : tuple of int
        (H, W, ...) of the full-resolution photo, px.
    max_working_pixels : int, keyword-only
        Budget h·w, px; ≥ MIN_IMAGE_SIDE².

    Returns
    -------
    (h, w) : tuple of int
        Working size, px (the photo's own size when it fits the budget).
    scale : float
        Linear scale s = √(h·w / (H·W)) ≤ 1.

    Raises
    ------
    ValueError
        Bad budget or a photo side below MIN_IMAGE_SIDE.
    """
    h_full, w_full = int(shape[0]), int(shape[1])
    if min(h_full, w_full) < MIN_IMAGE_SIDE:
        raise ValueError(f"image is {w_full}x{h_full} px; the smallest supported side is {MIN_IMAGE_SIDE} px")
    if not (isinstance(max_working_pixels, (int, np.integer)) or float(max_working_pixels).is_integer()) \
            or max_working_pixels < MIN_IMAGE_SIDE**2:
        raise ValueError(f"max_working_pixels={max_working_pixels!r} invalid; allowed: integer >= {MIN_IMAGE_SIDE**2}")
    max_working_pixels = int(max_working_pixels)
    if h_full * w_full <= max_working_pixels:
        return (h_full, w_full), 1.0
    s = math.sqrt(max_working_pixels / (h_full * w_full))
    h, w = max(MIN_IMAGE_SIDE, int(h_full * s)), max(MIN_IMAGE_SIDE, int(w_full * s))
    return (h, w), math.sqrt(h * w / (h_full * w_full))


def prefilter_sigma(scale: float) -> float:
    """Anti-aliasing Gaussian σ applied before downscaling by ``scale``, px of the full image.

    ``(1/s − 1) / 2`` (the usual choice, also scikit-image's); 0 for s = 1.
    """
    if not 0 < scale <= 1:
        raise ValueError(f"scale={scale!r} invalid; allowed: 0 < s <= 1")
    return max(0.0, (1.0 / scale - 1.0) / 2.0)


def _resize_axis(a: np.ndarray, n_out: int, axis: int) -> np.ndarray:
    """Linear interpolation along one axis, pixel centres aligned (edge values repeated)."""
    n_in = a.shape[axis]
    if n_in == n_out:
        return a
    x = (np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5
    x = np.clip(x, 0.0, n_in - 1.0)
    i0 = np.floor(x).astype(np.intp)
    i1 = np.minimum(i0 + 1, n_in - 1)
    t = x - i0
    shape = [1] * a.ndim
    shape[axis] = n_out
    t = t.reshape(shape)
    return np.take(a, i0, axis=axis) * (1.0 - t) + np.take(a, i1, axis=axis) * t


def _downscale_matrix(n_in: int, n_out: int, sigma: float):
    """Sparse (n_out × n_in) matrix: Gaussian prefilter (σ px, nearest edges) then linear resampling."""
    import scipy.sparse as sp

    radius = int(math.ceil(4.0 * sigma)) if sigma > 0 else 0
    taps = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 * (taps / sigma) ** 2) if sigma > 0 else np.ones(1)
    kernel /= kernel.sum()
    x = np.clip((np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5, 0.0, n_in - 1.0)
    i0 = np.floor(x).astype(np.intp)
    t = x - i0
    i1 = np.minimum(i0 + 1, n_in - 1)
    rows = np.repeat(np.arange(n_out), 2 * taps.size)
    cols = np.concatenate([i0[:, None] + taps[None, :], i1[:, None] + taps[None, :]], axis=1)
    vals = np.concatenate([(1 - t)[:, None] * kernel[None, :], t[:, None] * kernel[None, :]], axis=1)
    cols = np.clip(cols, 0, n_in - 1).ravel()
    return sp.csr_matrix((vals.ravel(), (rows, cols)), shape=(n_out, n_in))


def downscale_image(image, shape) -> np.ndarray:
    """Downscale an image to ``shape`` with a Gaussian anti-aliasing prefilter.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
    shape : tuple of int
        (h, w) ≤ (H, W), px.

    Returns
    -------
    ndarray, hxw or hxwx3, float64 in [0, 1]

    Notes
    -----
    1. Along y: Gaussian prefilter of σ = (H/h − 1)/2 px (edge samples repeated, 4σ support)
       followed by linear interpolation at the working rows' centres, fused into one sparse
       h×H matrix (only the h needed rows are ever filtered: no full-size temporary).
    2. The same along x with σ = (W/w − 1)/2 px.
    """
    image = np.asarray(image, dtype=np.float64)
    h, w = int(shape[0]), int(shape[1])
    H, W = image.shape[:2]
    if (h, w) == (H, W):
        return image.copy()
    if h > H or w > W or h < 1 or w < 1:
        raise ValueError(f"target shape {(h, w)} invalid for an image of {(H, W)}; allowed: 1 <= h <= H, 1 <= w <= W")
    my = _downscale_matrix(H, h, max(0.0, (H / h - 1) / 2))
    mx = _downscale_matrix(W, w, max(0.0, (W / w - 1) / 2))
    c = 1 if image.ndim == 2 else image.shape[2]
    rows = my @ image.reshape(H, W * c)                                   # (h, W·c)
    cols = mx @ rows.reshape(h, W, c).transpose(1, 0, 2).reshape(W, h * c)  # (w, h·c)
    res = cols.reshape(w, h, c).transpose(1, 0, 2)
    res = np.ascontiguousarray(res[..., 0] if image.ndim == 2 else res)
    return np.clip(res, 0.0, 1.0)


def working_to_full_sigma(sigma_working, scale: float, *, remove_prefilter=True) -> np.ndarray:
    """Convert blur σ measured on the downscaled photo to px of the full-resolution photo.

    Parameters
    ----------
    sigma_working : ndarray, float
        σ in working px, ≥ 0 (NaN allowed: passed through).
    scale : float
        Working / full linear scale s, 0 < s ≤ 1.
    remove_prefilter : bool, keyword-only
        Subtract the downscaling prefilter's σ (:func:`prefilter_sigma`) in quadrature.

    Returns
    -------
    ndarray, float64
        ``σ_w / s``, or ``√max((σ_w/s)² − σ_pre², 0)`` with ``remove_prefilter``.
    """
    sigma = np.asarray(sigma_working, dtype=np.float64) / scale
    if remove_prefilter and scale < 1:
        pre = prefilter_sigma(scale)
        with np.errstate(invalid="ignore"):
            sigma = np.sqrt(np.maximum(sigma * sigma - pre * pre, 0.0))
    return sigma


def _box(a: np.ndarray, r: int) -> np.ndarray:
    return ndimage.uniform_filter(a, size=2 * r + 1, mode="reflect")


def _guide(image: np.ndarray) -> np.ndarray:
    return image if image.ndim == 2 else image @ np.asarray(LUMA_WEIGHTS)


def guided_upsample(low_map, low_image, full_image, *, radius=GUIDED_RADIUS, eps=GUIDED_EPS) -> np.ndarray:
    """Upsample a smooth map to full resolution along the edges of the full-resolution image.

    The "fast guided filter" (He & Sun 2015): the guided filter's linear coefficients
    ``q = a·I + b`` are fitted at low resolution, bilinearly upsampled, and applied to the
    full-resolution guide ``I`` (the photo's luminance).

    Parameters
    ----------
    low_map : ndarray, hxw, float
        The map at working resolution (any unit; σ in px of the full photo here). Finite.
    low_image : ndarray, hxw or hxwx3, float in [0, 1]
        The working-resolution photo the map was estimated on.
    full_image : ndarray, HxW or HxWx3, float in [0, 1]
        The full-resolution photo (H ≥ h, W ≥ w).
    radius : int, keyword-only
        Window radius, working px (window (2r+1)²), ≥ 1.
    eps : float, keyword-only
        Regulariser, squared luminance units, > 0.

    Returns
    -------
    ndarray, HxW, float64
        Clipped to [min(low_map), max(low_map)] (a guided filter may overshoot at strong edges).

    Notes
    -----
    1. Guides: luminance (Rec. 709) of both images.
    2. At low res: box means of I, p, I·p, I·I over (2r+1)² windows; a = cov(I, p)/(var(I) + eps),
       b = mean(p) − a·mean(I); then box means of a and b.
    3. Full res, in strips of rows: bilinear upsampling of mean(a), mean(b); q = a·I_full + b.
    """
    low_image = np.asarray(low_image, dtype=np.float64)
    full_image = np.asarray(full_image, dtype=np.float64)
    p = validate_map(np.asarray(low_map, dtype=np.float64), low_image.shape, name="low_map", allow_negative=True)
    H, W = full_image.shape[:2]
    h, w = p.shape
    if H < h or W < w:
        raise ValueError(f"full_image {full_image.shape[:2]} is smaller than low_map {p.shape}")
    if not (isinstance(radius, (int, np.integer)) and radius >= 1):
        raise ValueError(f"radius={radius!r} invalid; allowed: integer >= 1")
    if not eps > 0:
        raise ValueError(f"eps={eps!r} invalid; allowed: > 0")
    lo, hi = float(p.min()), float(p.max())
    if hi == lo:
        return np.full((H, W), lo)
    g = _guide(low_image)
    mean_i, mean_p = _box(g, radius), _box(p, radius)
    cov = _box(g * p, radius) - mean_i * mean_p
    var = _box(g * g, radius) - mean_i * mean_i
    a = cov / (var + eps)
    b = mean_p - a * mean_i
    mean_a, mean_b = _box(a, radius), _box(b, radius)
    # rows first at low resolution (cheap), then per strip of full-resolution rows
    a_rows = _resize_axis(mean_a, H, 0) if H != h else mean_a
    b_rows = _resize_axis(mean_b, H, 0) if H != h else mean_b
    out = np.empty((H, W))
    for y0 in range(0, H, _STRIP_ROWS):
        y1 = min(H, y0 + _STRIP_ROWS)
        guide = _guide(full_image[y0:y1])
        out[y0:y1] = _resize_axis(a_rows[y0:y1], W, 1) * guide + _resize_axis(b_rows[y0:y1], W, 1)
    return np.clip(out, lo, hi, out=out)


def estimate_defocus_map_at_scale(image, params=None, *, encoding="srgb", max_working_pixels=DEFAULT_MAX_WORKING_PIXELS,
                                  progress: Callable[[str], None] | None = None,
                                  remove_prefilter=True) -> ScaledDefocusResult:
    """Estimate a photo's defocus map at a working resolution within a pixel budget.

    Parameters
    ----------
    image : ndarray, HxWx3 or HxW, float in [0, 1]
        The full-resolution photo, its values in ``encoding``. Sides ≥ MIN_IMAGE_SIDE.
    params : DefocusParams, optional
        Pipeline parameters (paper defaults when omitted). Scale-dependent ones (σ1/σ2 scales,
        window sizes) apply in working px.
    encoding : str, keyword-only
        Key of :data:`method.edges.tone_curve.INPUT_ENCODINGS` (default "srgb"), passed to :func:`method.pipeline.
        estimate_defocus_map` (which fits "auto" on the working image); the downscaling averages the values as given.
    max_working_pixels : int, keyword-only
        Estimate at full resolution when H·W fits; otherwise at the largest same-aspect size that
        does (:func:`working_shape`).
    progress : callable, optional, keyword-only
        Called with a stage name as each stage starts: ``"downscale"``, the pipeline's stages,
        ``"upsample"``.
    remove_prefilter : bool, keyword-only
        Remove the downscaling prefilter's blur from σ (:func:`working_to_full_sigma`).

    Returns
    -------
    ScaledDefocusResult
        ``defocus_map`` in px of the full-resolution photo, HxW, ≥ 0.

    Warns
    -----
    NoEdgesWarning
        From the pipeline, when the photo has no edges (the map is all zeros).

    Notes
    -----
    1. s = √(budget / (H·W)) when over budget; downscale with a Gaussian prefilter.
    2. :func:`method.pipeline.estimate_defocus_map` on the working image (deterministic: the same
       photo gives the same bytes run after run, with no global RNG seeding).
    3. σ → full-resolution px (÷ s, prefilter removed in quadrature).
    4. Edge-aware upsampling by :func:`guided_upsample` guided by the full photo.
    """
    from ..pipeline import estimate_defocus_map  # imported late: keeps this module light

    INPUT_ENCODINGS.check(encoding, what="encoding")
    image = validate_image(image)
    (h, w), scale = working_shape(image.shape, max_working_pixels=max_working_pixels)

    def note(stage):
        if progress is not None:
            progress(stage)

    if scale == 1.0:
        result = estimate_defocus_map(image, params, encoding=encoding, progress=progress)
        return ScaledDefocusResult(result.defocus_map, 1.0, (h, w), result)
    note("downscale")
    small = downscale_image(image, (h, w))
    result = estimate_defocus_map(small, params, encoding=encoding, progress=progress)
    note("upsample")
    full = upsample_defocus_map(result.defocus_map, small, image, scale=scale, remove_prefilter=remove_prefilter,
                                encoding=result.encoding)
    return ScaledDefocusResult(full, scale, (h, w), result)


def upsample_defocus_map(working_map, working_image, full_image, *, scale, remove_prefilter=True,
                         encoding="srgb") -> np.ndarray:
    """Bring a working-resolution defocus map to the full photo: σ conversion + guided upsampling.

    Parameters
    ----------
    working_map : ndarray, hxw, float
        σ in working px, ≥ 0, finite.
    working_image : ndarray, hxw or hxwx3, float in [0, 1]
        The downscaled photo the map was estimated on.
    full_image : ndarray, HxW or HxWx3, float in [0, 1]
        The full-resolution photo.
    scale : float, keyword-only
        Working / full linear scale s (from :func:`working_shape`).
    remove_prefilter : bool, keyword-only
        See :func:`working_to_full_sigma`.
    encoding : str, keyword-only
        Key of :data:`method.luma.ENCODINGS` of both images; the guide is their luma in display
        light (:func:`method.luma.to_light`), as for an sRGB photo.

    Returns
    -------
    ndarray, HxW, float64
        σ in px of the full photo, ≥ 0.
    """
    full_image = np.asarray(full_image)
    if scale == 1.0 and working_map.shape == full_image.shape[:2]:
        return np.asarray(working_map, dtype=np.float64).copy()
    sigma = working_to_full_sigma(working_map, scale, remove_prefilter=remove_prefilter)
    working_image, full_image = (to_light(im, "display", encoding=encoding) for im in (working_image, full_image))
    return np.maximum(guided_upsample(sigma, working_image, full_image), 0.0)


# ------------------------------------------------------------------------------------------------
# full-resolution magnification of large photos, in tiles
# ------------------------------------------------------------------------------------------------

#: Default pixel count of one magnification tile, halo included (≈ 4 MP). The blur stack of
#: :func:`method.magnify.magnification.magnify_defocus` needs ≈ 290 B per pixel (measured: 3.4 GiB for a
#: 12 MP photo with σ ≤ 8 px), so one tile stays near 1.1 GiB whatever the photo's size.
DEFAULT_TILE_PIXELS = 4_000_000


#: Tiles of the scatter renderer start on multiples of its coarsest block (method.magnify.scatter.MAX_LEVEL).
_SCATTER_ALIGN = 8


def _halo(sigma_extra_max: float, renderer: str = "gather") -> int:
    """Context (px) a tile needs on each side: the farthest reach of a pixel's blur, with margin.

    Gather: the stack's levels grow by √2 from 0.5 px and stop at the first ≥ max σ_e, so the
    largest level is ≤ max(√2·σ_e, 0.5); Gaussian kernels reach 4σ, disks 2σ. Scatter: a pixel's
    disk (or hexagon, ≤ 1.1 × the disk's radius) of radius ≈ 2σ_e, and the occlusion test looks no
    farther, plus two of its coarsest blocks (their splat and upsampling reach one block each way),
    rounded up to whole blocks so that every tile's blocks line up with the whole photo's.
    """
    if renderer == "scatter":
        return _SCATTER_ALIGN * math.ceil((2.5 * sigma_extra_max + 2 * _SCATTER_ALIGN + 3) / _SCATTER_ALIGN)
    return int(math.ceil(4.0 * max(math.sqrt(2.0) * sigma_extra_max, 0.5))) + 2


def magnify_defocus_tiled(image, defocus_map, *, factor=2.0, kernel=None, clip_percent=5.0,
                          smoothing=0.005, preprocess=True, tile_pixels=DEFAULT_TILE_PIXELS,
                          renderer="gather", aperture=None, encoding="srgb", light=None, in_front=None,
                          progress: Callable[[str], None] | None = None) -> np.ndarray:
    """:func:`method.magnify.magnification.magnify_defocus` for large photos, in overlapping tiles.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        The full-resolution photo.
    defocus_map : ndarray, HxW, float
        Dense blur σ, px of ``image``.
    factor, kernel, clip_percent, smoothing, preprocess, renderer, aperture, encoding, light : keyword-only
        As :func:`method.magnify.magnification.magnify_defocus` (factor ≥ 1).
    in_front : ndarray, HxW bool, optional, keyword-only
        As :func:`~method.magnify.magnification.magnify_defocus`, cut to each tile.
    tile_pixels : int, keyword-only
        Pixels of one tile, halo included; bounds the working memory (≈ 290 B/px). A photo that fits
        is magnified in one call, exactly as :func:`~method.magnify.magnification.magnify_defocus` does.
    progress : callable, optional, keyword-only
        Called with ``"magnify i/n"`` before each tile (``"magnify i/n: scatter layer j/m"`` within a scatter tile).

    Returns
    -------
    ndarray, same shape as ``image``, float64 in [0, 1] (≥ 0 with ``encoding="linear"``)

    Notes
    -----
    1. Preprocess the whole map once (Sec. 5: clip, clamp ≥ 0, blur σ = smoothing·max(H, W)): global, never per tile.
    2. Halo = the farthest reach of the blur the map needs (:func:`_halo`: gather 4·√2·max σ_e + 2 px, scatter
       2.5·max σ_e + 3 px).
    3. Square cores of side √tile_pixels − 2·halo (≥ 256 px); each core is magnified with its halo of real
       neighbouring pixels (``preprocess=False``) and the halo is dropped. Inside the photo a core pixel sees
       exactly the data the whole-image call would; at the photo's borders the magnifier's padding (gather) or
       renormalisation (scatter) is the same. Results agree with the whole-image call up to FFT round-off (and,
       for the gather, rarely, a blur-stack level a tile does not build: ≲ 1e-3 of a level difference).
    """
    from .magnification import check_extra_blur, magnify_defocus, preprocess_defocus_map

    m = np.asarray(defocus_map, dtype=np.float64)
    if preprocess:
        m = preprocess_defocus_map(m, clip_percent=clip_percent, smoothing=smoothing)
    if not (isinstance(tile_pixels, (int, np.integer)) and tile_pixels >= 256 * 256):
        raise ValueError(f"tile_pixels={tile_pixels!r} invalid; allowed: integer >= {256 * 256}")

    def call(img, mp, label, y0=0, x0=0):
        inner = None if progress is None else (lambda stage: progress(f"{label}: {stage}"))
        cut = None if in_front is None else np.asarray(in_front)[y0:y0 + mp.shape[0], x0:x0 + mp.shape[1]]
        return magnify_defocus(img, mp, factor=factor, kernel=kernel, preprocess=False, renderer=renderer,
                               aperture=aperture, encoding=encoding, light=light, progress=inner, in_front=cut)

    H, W = image.shape[:2]
    if H * W <= tile_pixels or m.shape != (H, W):
        if progress is not None:
            progress("magnify 1/1")
        return call(image, m, "magnify 1/1")  # validates everything (shape mismatch included)
    try:
        f = float(factor)
    except (TypeError, ValueError):
        return call(image, m, "magnify")  # let the magnifier word the error
    if not (np.isfinite(f) and f >= 1.0) or not np.all(np.isfinite(m)):
        return call(image, m, "magnify")
    check_extra_blur(f, m, image.shape)  # before sizing the halo (a huge factor would need huge tiles)
    halo = _halo(math.sqrt(f * f - 1.0) * float(m.max(initial=0.0)), renderer)
    core = max(256, int(math.isqrt(int(tile_pixels))) - 2 * halo)
    if renderer == "scatter":
        core -= core % _SCATTER_ALIGN
    ys, xs = range(0, H, core), range(0, W, core)
    n = len(ys) * len(xs)
    out = np.empty(image.shape, dtype=np.float64)
    i = 0
    for y0 in ys:
        for x0 in xs:
            i += 1
            if progress is not None:
                progress(f"magnify {i}/{n}")
            y1, x1 = min(H, y0 + core), min(W, x0 + core)
            a0, a1 = max(0, y0 - halo), min(H, y1 + halo)
            b0, b1 = max(0, x0 - halo), min(W, x1 + halo)
            tile = call(np.ascontiguousarray(image[a0:a1, b0:b1]), np.ascontiguousarray(m[a0:a1, b0:b1]),
                        f"magnify {i}/{n}", a0, b0)
            out[y0:y1, x0:x1] = tile[y0 - a0:y1 - a0, x0 - b0:x1 - b0]
    return out
