"""Analytic images blurred the way a lens blurs: a PSF of :mod:`.psfs` in linear light, then a camera.

A lens blurs the scene's *linear* radiance, with a disk (or polygonal, or aberrated) PSF, before the
pixel integrates it and the camera adds noise, applies its tone curve, quantises and compresses
(../shared/research/LENS-AND-CAMERA.md). These images follow that order:

1. sharp texture on a lattice ``s`` times finer than the pixels (a family of :mod:`.families`, or a
   step edge), display values decoded to linear light (sRGB, colour-science);
2. convolution with the PSF's fine-lattice kernel (:func:`scenes.analytic.psfs.psf_kernel`, FFT);
3. the pixel's box: the mean of its s×s fine samples;
4. the camera pipeline (:func:`scenes.display.camera_image`: Poisson–Gaussian noise in linear units,
   the tone curve ``encoding`` (sRGB by default; any of :data:`scenes.display.ENCODINGS`),
   quantisation, optional JPEG).

The reported σ_gt is the per-axis std of the whole PSF (kernel ⊗ pixel box), the harness's
convention for every PSF (a disk of diameter c: √((c/4)² + 1/12)), combined in quadrature with the
texture's own blur (the ``photo`` family's). ``light="display"`` blurs the display values instead
(the blur the Gaussian mosaics of :mod:`.mosaics` apply), for comparison. The sharp textures' values
are display values of the tone curve ``encoding``: they are decoded by that curve into linear light.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.signal import fftconvolve

from ._common import check_band, check_int, check_levels, check_shape, check_sigmas, seed_entropy
from .edges import AnalyticImage, edge_pixels
from .families import TEXTURE_FAMILIES, check_family, family_texture
from .mosaics import boundary_mask, tile_layout
from .psfs import check_psf, psf_kernel
from ..display import camera_image, check_encoding, check_noise_level, decode

__all__ = ["LIGHTS", "LensMosaic", "lens_mosaic", "lens_step_edge"]

#: Where the blur acts: "linear" (a lens: on linear radiance, before the tone curve) or "display"
#: (on the sRGB-encoded values, as the Gaussian mosaics do).
LIGHTS = ("linear", "display")
#: Sub-samples per fine cell and axis for the anti-aliased step of :func:`lens_step_edge`.
_STEP_SUBSAMPLES = 16


@dataclasses.dataclass(frozen=True)
class LensMosaic:
    """A mosaic of textured tiles, each blurred by one known lens PSF, and its ground truth.

    Attributes
    ----------
    image : ndarray, (H, W, 3), float64
        What the camera delivers: display values in [0, 1] after noise, tone curve, quantisation, JPEG.
    linear : ndarray, (H, W, 3), float64
        The noise-free blurred linear radiance (before the camera).
    sigma : ndarray, (H, W), float64
        σ_gt, px, of each pixel's tile: √(σ_t² + intrinsic_sigma²), σ_t including the pixel box.
    tile_index : ndarray, (H, W), int64
    boundary : ndarray, (H, W), bool
        Pixels within the mixing band of a seam with another tile (exclude them from metrics).
    sigmas : tuple of float
        The PSF's σ_t per tile, px (kernel ⊗ pixel box).
    family, psf, light : str
    noise : dict
        The sensor noise variances {"a": …, "b": …} (variance a·x + b, linear units).
    intrinsic_sigma : float
        The texture's own blur, px (the family's).
    """

    image: np.ndarray
    linear: np.ndarray
    sigma: np.ndarray
    tile_index: np.ndarray
    boundary: np.ndarray
    sigmas: tuple
    family: str
    psf: str
    light: str
    noise: dict
    intrinsic_sigma: float


def _check_light(light):
    if light not in LIGHTS:
        raise ValueError(f"light={light!r} is invalid; allowed: {', '.join(LIGHTS)}")
    return light


def _check_supersample(s):
    if isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) or not 1 <= s <= 8:
        raise ValueError(f"supersample={s!r} is invalid; allowed: an int in 1..8")
    return int(s)


def _box_mean(fine, s):
    """Mean of each s×s block of a fine array (H·s, W·s[, C]) → (H, W[, C]): the pixel's box."""
    h, w = fine.shape[0] // s, fine.shape[1] // s
    return fine.reshape(h, s, w, s, *fine.shape[2:]).mean(axis=(1, 3))


def _camera(linear, noise, quantize_bits, jpeg_quality, rng, encoding):
    return camera_image(linear, encoding=encoding, noise=noise, quantize_bits=quantize_bits,
                        jpeg_quality=jpeg_quality, rng=rng)


def lens_step_edge(shape, *, sigma, psf="disk", angle=0.0, offset=0.0, low=0.2, high=0.8, light="linear",
                   supersample=4, noise="none", quantize_bits=None, jpeg_quality=None, rng=None,
                   encoding="srgb") -> AnalyticImage:
    """A straight step edge blurred by a lens PSF in linear light, integrated over the pixel, then a camera.

    Parameters
    ----------
    shape : (int, int)
        (H, W), px.
    sigma : float, keyword-only
        Reported blur σ, px (the PSF ⊗ the pixel box), >= 1/√12.
    psf : str, keyword-only
        Key of :data:`scenes.analytic.psfs.PSFS`.
    angle, offset : float, keyword-only
        Normal direction θ (radians, x right, y down; intensity rises along it) and the edge line's
        signed distance from the image centre along it, px (as :func:`scenes.analytic.step_edge`).
    low, high : float, keyword-only
        Display values (of the curve ``encoding``) of the two sides, in [0, 1].
    light : {"linear", "display"}, keyword-only
        Blur the linear radiance (a lens) or the display values.
    supersample : int, keyword-only
        Fine samples per px (1..8).
    noise, quantize_bits, jpeg_quality, rng : keyword-only
        The camera (:func:`scenes.display.camera_image`); the defaults give the exact noise-free
        display values.
    encoding : str, keyword-only
        The camera's tone curve, a key of :data:`scenes.display.ENCODINGS` (default "srgb").

    Returns
    -------
    AnalyticImage
        ``image`` the camera's output (H, W) in [0, 1]; ``sigma`` the reported σ; ``edge_distance``,
        ``edge_mask`` and ``normal`` as :func:`scenes.analytic.step_edge`.

    Notes
    -----
    1. On the fine lattice (spacing 1/s px) each cell holds the step's coverage of the cell (16×16
       sub-samples in the cells the edge crosses): the sharp step, cell-averaged.
    2. Convolution with the discrete PSF kernel, then the mean of each pixel's s×s cells. The cells
       tile the pixel, so the result is the step ⊗ kernel ⊗ the pixel's box exactly (to the kernel's
       discretisation), whose per-axis second moment is σ².
    3. ``light="linear"``: the two levels are decoded by ``encoding`` first and the result encoded after
       (:func:`scenes.display.camera_image`); ``"display"``: the display values are blurred.
    """
    h, w = check_shape(shape)
    check_levels(low, high)
    _check_light(light)
    s = _check_supersample(supersample)
    check_noise_level(noise)
    check_encoding(encoding)
    kernel = psf_kernel(check_psf(psf), sigma=sigma, supersample=s)
    rad = kernel.shape[0] // 2
    lo, hi = (decode(np.array([low, high]), encoding) if light == "linear" else (float(low), float(high)))
    # fine sample (k, l) sits at (x, y) = ((l + ½)/s − ½ − cx, (k + ½)/s − ½ − cy) px, k from −rad
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    ky = (np.arange(-rad, h * s + rad) + 0.5) / s - 0.5 - cy
    kx = (np.arange(-rad, w * s + rad) + 0.5) / s - 0.5 - cx
    c, sn = np.cos(angle), np.sin(angle)
    t = kx[None, :] * c + ky[:, None] * sn - offset
    cover = (t > 0).astype(np.float64)
    near = np.abs(t) < 0.75 / s  # cells the edge line can cross (half-diagonal < 0.71 cell)
    if np.any(near):
        m = _STEP_SUBSAMPLES
        sub = ((np.arange(m) + 0.5) / m - 0.5) / s
        dt = (sub[:, None] * c + sub[None, :] * sn).ravel()  # sub-sample offsets along the normal (dx, dy)
        cover[near] = np.mean(t[near][:, None] + dt[None, :] > 0, axis=1)
    fine = fftconvolve(cover, kernel, mode="valid")
    frac = np.clip(_box_mean(fine, s), 0.0, 1.0)
    value = lo + (hi - lo) * frac
    if light == "display":
        value = decode(value, encoding)
    img = _camera(value, noise, quantize_bits, jpeg_quality, rng, encoding)
    xg, yg = np.meshgrid(np.arange(w) - cx, np.arange(h) - cy)
    tc = xg * c + yg * sn - offset
    normal = np.full((h, w), float(np.arctan2(sn, c)))
    if high < low:
        normal = np.arctan2(-np.sin(normal), -np.cos(normal))
    dist = tc if high > low else -tc
    return AnalyticImage(image=img, sigma=float(sigma), edge_distance=dist, edge_mask=edge_pixels(dist, normal),
                         normal=normal)


def _tile_layer(family, entropy, t, rect, shape, kernel, s, light, encoding):
    """One tile's layer on its output window.

    Returns ((a0, a1, b0, b1) output window, box(K ∗ (M·T)) (h, w, 3), box(K ∗ M) (h, w)).
    """
    r0, r1, c0, c1 = rect
    H, W = shape
    rad = kernel.shape[0] // 2
    q = -(-rad // s) + 1  # output px of support beyond the tile
    a0, a1, b0, b1 = max(0, r0 - q), min(H, r1 + q), max(0, c0 - q), min(W, c1 + q)
    fy0, fx0 = a0 * s - rad, b0 * s - rad  # sharp window, fine samples (absolute)
    ny, nx = (a1 - a0) * s + 2 * rad, (b1 - b0) * s + 2 * rad
    sharp = family_texture(family, (ny, nx), s=s, seed=entropy, key=(t,), origin=(fy0 - r0 * s, fx0 - c0 * s))
    if light == "linear":
        sharp = decode(sharp, encoding)
    # the tile's indicator M_t on the fine samples (tiles on the canvas border extend beyond it)
    iy, ix = np.arange(fy0, fy0 + ny), np.arange(fx0, fx0 + nx)
    my = ((iy >= r0 * s) | (r0 == 0)) & ((iy < r1 * s) | (r1 == H))
    mx = ((ix >= c0 * s) | (c0 == 0)) & ((ix < c1 * s) | (c1 == W))
    m = np.outer(my, mx).astype(np.float64)
    num = np.stack([_box_mean(fftconvolve(m * sharp[..., c], kernel, mode="valid"), s) for c in range(3)], axis=-1)
    den = _box_mean(fftconvolve(m, kernel, mode="valid"), s)
    return (a0, a1, b0, b1), num, den


def lens_mosaic(*, family="dead_leaves", psf="disk", sigmas=(0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0), tile=96,
                cols=4, light="linear", supersample=4, noise="none", quantize_bits=8, jpeg_quality=None, rng=0,
                boundary_band=None, encoding="srgb") -> LensMosaic:
    """Tiles of one texture family, tile t blurred by a lens PSF of σ_t, as abutting fronto-parallel planes.

    Parameters
    ----------
    family : str, keyword-only
        Key of :data:`scenes.analytic.families.TEXTURE_FAMILIES`; each tile is its own plane of it.
    psf : str, keyword-only
        Key of :data:`scenes.analytic.psfs.PSFS`.
    sigmas : sequence of float, keyword-only
        Reported σ_t (px, PSF ⊗ pixel box, >= 1/√12) per tile, row-major.
    tile, cols : int, keyword-only
        Tile side (px, >= 16) and tiles per row (an incomplete last row is widened).
    light : {"linear", "display"}, keyword-only
        Blur linear radiance (a lens; default) or display values.
    supersample : int, keyword-only
        Fine samples per px (1..8; the ``photo`` family is at native resolution at 4).
    noise, quantize_bits, jpeg_quality : keyword-only
        The camera (:func:`scenes.display.camera_image`): noise level name or (a, b), bits (default
        8), JPEG quality or None.
    rng : int or numpy.random.Generator or None, keyword-only
        Seed of the textures (and, derived from it, of the noise); same seed → identical output.
    boundary_band : float or None, keyword-only
        Half-width (px) of the band flagged on each side of a seam; None: ⌈3·max σ_gt⌉ + 2 px.
    encoding : str, keyword-only
        The camera's tone curve, a key of :data:`scenes.display.ENCODINGS` (default "srgb"); the
        textures' display values are decoded by it.

    Returns
    -------
    LensMosaic

    Notes
    -----
    Image formation in linear light, normalised blurred layers (as :func:`scenes.analytic.texture_mosaic`):
    I = box(Σ_t K_t ∗ (M_t·T_t)) / box(Σ_t K_t ∗ M_t), then the camera.
    1. Per tile t, the sharp window covers its output window (tile + the kernel's support) plus one
       more support; T_t is plane (seed, t) of the family on the fine lattice, decoded to linear.
    2. K_t = :func:`scenes.analytic.psfs.psf_kernel` (σ_t); FFT convolution of M_t·T_t and of M_t.
    3. box: the mean of each pixel's s×s fine samples; accumulate numerators and denominators.
    4. Normalise (interior pixels: exactly box(K_t ∗ T_t)), then the camera pipeline.
    5. σ_gt = √(σ_t² + σ₀²), σ₀ the family's intrinsic blur. Textures are point-sampled on the fine
       lattice: their edges are located to 1/s px, an rms jitter of 1/(s√12) px, which the pixel
       box's 1/12 of the σ convention counts (the s×s mean of point samples has (1 − 1/s²)/12).
    """
    fam = check_family(family)
    check_psf(psf)
    _check_light(light)
    s = _check_supersample(supersample)
    sig = check_sigmas(sigmas)
    tile = check_int(tile, "tile", 16)
    cols = check_int(cols, "cols", 1)
    band_val = check_band(boundary_band)
    noise_ab = check_noise_level(noise)
    check_encoding(encoding)
    entropy = seed_entropy(rng)
    kernels = [psf_kernel(psf, sigma=v, supersample=s) for v in sig]  # validates σ >= 1/√12
    rects, (h, w) = tile_layout(len(sig), tile, cols)
    num = np.zeros((h, w, 3))
    den = np.zeros((h, w))
    for t, (rect, kernel) in enumerate(zip(rects, kernels)):
        (a0, a1, b0, b1), n_t, d_t = _tile_layer(fam, entropy, t, rect, (h, w), kernel, s, light, encoding)
        num[a0:a1, b0:b1] += n_t
        den[a0:a1, b0:b1] += d_t
    blurred = np.clip(num / den[..., None], 0.0, 1.0)
    linear = blurred if light == "linear" else decode(blurred, encoding)
    image = _camera(linear, noise_ab, quantize_bits, jpeg_quality,
                    np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(2,))), encoding)
    tile_index = np.zeros((h, w), dtype=np.int64)
    for t, (r0, r1, c0, c1) in enumerate(rects):
        tile_index[r0:r1, c0:c1] = t
    sigma0 = TEXTURE_FAMILIES[fam].intrinsic_sigma  # one native photo px is 1/4 output px at any s
    gt = np.sqrt(np.asarray(sig) ** 2 + sigma0 ** 2)
    band = (lambda a, b: band_val) if band_val is not None else (lambda a, b: np.ceil(3.0 * max(gt[a], gt[b])) + 2.0)
    return LensMosaic(image=image, linear=linear, sigma=gt[tile_index], tile_index=tile_index,
                      boundary=boundary_mask(rects, (h, w), band), sigmas=sig, family=fam, psf=psf, light=light,
                      noise={"a": noise_ab[0], "b": noise_ab[1]}, intrinsic_sigma=float(sigma0))

