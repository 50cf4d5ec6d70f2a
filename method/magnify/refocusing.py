"""Refocusing with a defocus map: spatially varying deconvolution, then re-blur (Sec. 5 / Fig. 8).

The paper's Fig. 8 "perform[s] deconvolution using our defocus map and appl[ies] lens blur" so the
photo looks focused elsewhere. It gives no algorithm for either step; this module does:

1. :func:`deconvolve_defocus` — non-blind, spatially varying deconvolution by a σ-stack: the image is
   deconvolved with a Gaussian of each σ level (levels and kernels of the magnification blur stack,
   :mod:`method.magnify.magnification`) in the Fourier domain, and each pixel blends the two levels whose
   kernel variances bracket its σ² (linear in variance, as the blur stack does).
2. :func:`refocus` — deconvolve to an (approximately) all-in-focus image, then blur it with the
   spatially varying σ of a new ("virtual focus") map with the magnification blur stack.

Deconvolution filters (:data:`DECONVOLUTION_METHODS`), for a kernel spectrum K and a regularisation
weight λ (``nsr``, the noise-to-signal power ratio, dimensionless):

* ``"wiener"`` (default): H = K* / (|K|² + λ) — Wiener filter with a flat (white) signal spectrum.
* ``"cls"``: H = K* / (|K|² + λ·|L|²), L the 5-point Laplacian's spectrum (constrained least
  squares): leaves low frequencies unregularised and damps high ones more, i.e. less ringing on
  noise-free smooth regions at the same λ.

The PSF model is the paper's Gaussian. A disk PSF (radius 2σ) with the same per-level blending was
tried and rings badly: a disk's spectral zeros move with its radius, so blending the inverses of two
neighbouring levels does not invert the disk in between.

Both are linear, so blending levels per pixel is a spatially varying linear filter; a pixel whose σ
is exactly 0 is passed through unchanged (level 0 is the image itself).
"""

from __future__ import annotations

import numpy as np

from .magnification import MAGNIFICATION_KERNELS, blur_stack_apply
from ..validation import validate_image, validate_map
from ..registry import Entry, Registry

__all__ = ["DECONVOLUTION_METHODS", "DEFAULT_NSR", "deconvolve_defocus", "refocus"]

#: Default regularisation λ (noise-to-signal power ratio, dimensionless). With a Gaussian blur of the
#: exact σ and 8-bit noise (variance 1/(12·255²) ≈ 1.3e-6 against a texture power ≈ 1e-2) the best λ
#: is ≈ 3e-4 (analytic test of tests/test_fig8_refocus.py: +4.8 dB; λ = 1e-2 still +2.7 dB). Real
#: blur is not that Gaussian — a thin-lens PSF is a disk, whose spectrum falls more slowly and then
#: changes sign — and the map's σ is uncertain, so a small λ rings: on the small portrait render of
#: experiments/fig8_refocus.py, deconvolving with the true σ scores −6.2 dB against the near-pinhole
#: render at λ = 1e-3, −1.5 dB at 1e-2 and −0.3 dB at 3e-2 (its λ sweep; no λ gains there).
#: 1e-2 is a compromise between the two, not tuned on either.
DEFAULT_NSR = 1e-2


def _wiener(khat, shape, nsr):
    """Wiener filter K* / (|K|² + λ)."""
    return np.conj(khat) / (np.abs(khat) ** 2 + nsr)


def _laplacian_power(shape):
    """|L(ω)|² of the 5-point Laplacian on an fh x fw FFT grid (rfft2 layout: fh x fw//2+1)."""
    fh, fw = shape
    wy = 2.0 * np.pi * np.fft.fftfreq(fh)[:, None]
    wx = 2.0 * np.pi * np.fft.rfftfreq(fw)[None, :]
    lap = 4.0 - 2.0 * np.cos(wy) - 2.0 * np.cos(wx)
    return lap * lap


def _cls(khat, shape, nsr):
    """Constrained least squares K* / (|K|² + λ|L|²)."""
    return np.conj(khat) / (np.abs(khat) ** 2 + nsr * _laplacian_power(shape))


#: Deconvolution filters by name: (kernel spectrum, FFT shape, λ) → filter spectrum.
DECONVOLUTION_METHODS = Registry("deconvolution method", {
    "wiener": Entry(_wiener, "Wiener filter, constant noise-to-signal ratio"),
    "cls": Entry(_cls, "constrained least squares, Laplacian regulariser"),
})


def _check_image(image):
    return validate_image(image, min_side=1)


def _check_sigma_map(m, shape, name):
    return validate_map(m, shape, name=name)


def _check_options(method, nsr):
    DECONVOLUTION_METHODS.check(method, what="method")
    try:
        nsr = float(nsr)
    except (TypeError, ValueError):
        raise ValueError(f"nsr={nsr!r} is invalid; allowed: finite number > 0") from None
    if not (np.isfinite(nsr) and nsr > 0):
        raise ValueError(f"nsr={nsr!r} is invalid; allowed: finite and > 0")
    return method, nsr


def _deconvolve(img3, sigma, method, nsr):
    """Unvalidated kernel: HxWxC float64 image, HxW σ ≥ 0 → HxWxC deconvolved (not clipped)."""
    if not np.any(sigma > 0):
        return img3.copy()
    filt = DECONVOLUTION_METHODS[method]
    out = blur_stack_apply(img3, sigma, "gaussian", spectral_filter=lambda khat, shape: filt(khat, shape, nsr))
    return np.where((sigma == 0)[..., None], img3, out)


def deconvolve_defocus(image, defocus_map, *, method="wiener", nsr=DEFAULT_NSR, clip=True) -> np.ndarray:
    """Remove a spatially varying Gaussian blur of known σ (non-blind deconvolution, Sec. 5 / Fig. 8).

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        The blurred photo.
    defocus_map : ndarray, HxW, float ≥ 0
        Blur σ of each pixel, px (e.g. a preprocessed defocus map).
    method : str, keyword-only
        Key of :data:`DECONVOLUTION_METHODS`: ``"wiener"`` (default) or ``"cls"``.
    nsr : float, keyword-only
        Regularisation λ > 0 (noise-to-signal power ratio, dimensionless; default
        :data:`DEFAULT_NSR`). Larger: less ringing and noise, less sharpening.
    clip : bool, keyword-only
        Clip the result to [0, 1] (deconvolution overshoots at edges).

    Returns
    -------
    ndarray, same shape as ``image``, float64 (in [0, 1] if ``clip``)

    Raises
    ------
    ValueError
        Bad image (shape, dtype, NaN/Inf, outside [0, 1]), map shape mismatch, NaN/Inf or negative
        map, unknown method, nsr ≤ 0 or not finite.

    Notes
    -----
    1. σ levels 0, 0.5, 0.5·√2, … px up to max σ (:mod:`method.magnify.magnification`'s blur stack) with
       their sampled, normalised Gaussian kernels K_ℓ.
    2. Level ℓ ≥ 1: the image (symmetrically padded by the largest kernel radius) filtered in the
       Fourier domain with H_ℓ = K_ℓ* / (|K_ℓ|² + λ) (``"wiener"``) or K_ℓ* / (|K_ℓ|² + λ|L|²)
       (``"cls"``). Level 0 is the image.
    3. Per pixel, blend the two levels whose kernel variances bracket σ², linearly in variance.
       Pixels with σ = 0 are returned bit for bit; a zero map returns a copy of the image.
    4. Optionally clip to [0, 1]. Cost O(N·levels) FFT work, levels ≈ 2·log₂(max σ / 0.5 px) + 2.
    """
    img = _check_image(image)
    m = _check_sigma_map(defocus_map, img.shape, "defocus_map")
    method, nsr = _check_options(method, nsr)
    img3 = img if img.ndim == 3 else img[..., None]
    out = _deconvolve(img3, m, method, nsr)
    if clip:
        out = np.clip(out, 0.0, 1.0)
    return out if img.ndim == 3 else out[..., 0]


def refocus(image, defocus_map, new_blur_map, *, method="wiener", nsr=DEFAULT_NSR, kernel="gaussian") -> np.ndarray:
    """Synthesise a different focus: deconvolve with the defocus map, re-blur with a new map (Fig. 8).

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        The photo.
    defocus_map : ndarray, HxW, float ≥ 0
        Blur σ of each pixel in ``image``, px.
    new_blur_map : ndarray, HxW, float ≥ 0
        Total blur σ each pixel should have after refocusing (the virtual-focus map), px.
    method, nsr : keyword-only
        Deconvolution filter and λ, see :func:`deconvolve_defocus`.
    kernel : str, keyword-only
        Key of :data:`method.magnify.magnification.MAGNIFICATION_KERNELS` for the re-blur (``"gaussian"``
        or ``"disk"`` of radius 2σ).

    Returns
    -------
    ndarray, same shape as ``image``, float64 in [0, 1]

    Raises
    ------
    ValueError
        As :func:`deconvolve_defocus`, plus a bad ``new_blur_map`` or an unknown kernel.

    Notes
    -----
    1. Deconvolve with ``defocus_map`` (:func:`deconvolve_defocus`), clip to [0, 1] (radiance is
       non-negative; clipping also bounds the ringing that the re-blur would spread).
    2. Blur with the magnification blur stack so each pixel gets σ = ``new_blur_map``: levels of the
       deconvolved image blurred with ``kernel``, blended per pixel linearly in variance; pixels with
       new σ = 0 keep the deconvolved value.
    3. Clip to [0, 1]. Both maps zero → the input bit for bit; new map = old map → approximately the
       input (exact only without regularisation and for a constant map).
    """
    img = _check_image(image)
    m = _check_sigma_map(defocus_map, img.shape, "defocus_map")
    m_new = _check_sigma_map(new_blur_map, img.shape, "new_blur_map")
    method, nsr = _check_options(method, nsr)
    MAGNIFICATION_KERNELS.check(kernel, what="kernel")
    img3 = img if img.ndim == 3 else img[..., None]
    sharp = np.clip(_deconvolve(img3, m, method, nsr), 0.0, 1.0)
    if np.any(m_new > 0):
        out = blur_stack_apply(sharp, m_new, kernel)
        out = np.where((m_new == 0)[..., None], sharp, out)
    else:
        out = sharp
    out = np.clip(out, 0.0, 1.0)
    return out if img.ndim == 3 else out[..., 0]
