"""Multiscale edge detection with minimum reliable scale (Sec. 3.1, Appendix B; Elder & Zucker 1998).

Every pixel gets the smallest scale at which its gradient is reliable (σ1, Eq. 7 and 9), the
gradient direction θ there, the smallest scale at which its 2nd derivative along θ is reliable
(σ2, Eq. 8 and 9) and an edge flag: reliable gradient + a zero crossing of the 2nd derivative
along θ at the minimum reliable σ2, localised to one pixel across the edge.

Angle convention: x = column index (right), y = row index (down), θ = gradient direction =
atan2(I_y, I_x); see :mod:`method.edges.gaussian_derivatives`.
"""

from __future__ import annotations

import dataclasses

import numba
import numpy as np

from .gaussian_derivatives import GaussianDerivativeBank, check_gray_image, nearest_axis_step, second_steering_weights
from .noise_thresholds import (
    NoiseSpectrum,
    first_derivative_threshold,
    per_pixel_false_positive_rate,
    second_derivative_threshold,
)

__all__ = [
    "EdgeMap",
    "MIN_IMAGE_SIZE",
    "check_edge_inputs",
    "detect_edges",
    "edge_pixels_by_scale",
    "pixels_by_scale",
]

#: Smallest accepted image side, px (the 2nd-derivative test needs a pixel on both sides).
MIN_IMAGE_SIZE = 3

_DEFAULT_SIGMA1 = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
_DEFAULT_SIGMA2 = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)


@dataclasses.dataclass(frozen=True)
class EdgeMap:
    """Output of :func:`detect_edges`; all arrays have the image's shape (H, W).

    Attributes
    ----------
    edges : ndarray of bool
        Edge pixels.
    theta : ndarray of float64
        Gradient direction at the minimum reliable σ1, radians in (−π, π], x right, y down;
        intensity increases along (cos θ, sin θ). 0 where the gradient is unreliable.
    gradient_magnitude : ndarray of float64
        |∇| at the minimum reliable σ1, image units / px; 0 where unreliable.
    sigma1 : ndarray of float64
        Minimum reliable σ1, px; NaN where no scale is reliable.
    sigma2 : ndarray of float64
        Minimum reliable σ2, px, of the 2nd-derivative zero-crossing test (see
        :func:`detect_edges`); NaN where none (always NaN where ``sigma1`` is NaN).
    hessians : dict or None
        Optional cache for the blur estimators: σ2 (px) → (I_xx, I_xy, I_yy), each (H, W) float32,
        image units / px² (Eq. 8a, 8c, 8b, from the detector's single-precision FFT bank), for every
        σ2 at which at least one edge pixel was found. ``None`` (the default, and after
        :func:`method.pipeline.estimate_defocus_map` returns) means "recompute". Not compared.
    noise_variance : ndarray or None
        The per-pixel noise variance the thresholds used, (H, W) float64, image units²
        (``detect_edges(noise_variance=...)``), read again by the checked fit's residual test; None:
        the constant ``noise_std``. Not compared.
    noise_spectrum : NoiseSpectrum or None
        The noise's spectrum the thresholds used (``detect_edges(noise_spectrum=...)``), read again by
        the checked fit's residual test; None: white. Not compared.
    """

    edges: np.ndarray
    theta: np.ndarray
    gradient_magnitude: np.ndarray
    sigma1: np.ndarray
    sigma2: np.ndarray
    hessians: dict | None = dataclasses.field(default=None, repr=False, compare=False)
    noise_variance: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)
    noise_spectrum: NoiseSpectrum | None = dataclasses.field(default=None, repr=False, compare=False)


@numba.njit(cache=True, nogil=True)
def _gradient_pass(ix, iy, c1, noise, scale, sigma1, theta, gmag):
    """Assign σ1 = scale, θ and |∇| to unresolved pixels whose |∇| exceeds c1·noise; count the rest.

    Every pixel reads and writes only itself. One thread: the passes run while the bank's threads
    compute the next scale's responses (:meth:`GaussianDerivativeBank.responses`).
    """
    h, w = ix.shape
    left = 0
    for i in range(h):
        for j in range(w):
            if sigma1[i, j] == sigma1[i, j]:  # already resolved (not NaN)
                continue
            gx = np.float64(ix[i, j])
            gy = np.float64(iy[i, j])
            m = np.sqrt(gx * gx + gy * gy)
            if m > c1 * noise[i, j]:
                sigma1[i, j] = scale
                theta[i, j] = np.arctan2(gy, gx)
                gmag[i, j] = m
            else:
                left += 1
    return left


@numba.njit(cache=True, nogil=True)
def _zero_crossing_pass(ixx, ixy, iyy, cos_t, sin_t, c2, noise, scale, level, sigma1, sigma2, edge_level):
    """One σ2 scale of the 2nd-derivative test for every undecided pixel with a reliable gradient.

    A pixel is decided at this scale (σ2 := scale) when the responses along θ at both neighbours
    across the edge, p ± e, are reliable (|r| > c2 times the noise std factor there). It becomes an
    edge (edge_level := level) if moreover r(p − e) > 0 > r(p + e), the linearly interpolated crossing lies in [−1/2, 1/2)
    steps of p, and neither neighbour became an edge at a smaller scale. Returns the number of
    pixels still undecided and the number of new edge pixels.

    A pixel writes only its own σ2 and edge level and reads its neighbours' edge levels only for
    levels below this one (set by earlier passes). One thread, as :func:`_gradient_pass`.
    """
    h, w = ixx.shape
    left = 0
    new = 0
    for i in range(h):
        for j in range(w):
            if sigma1[i, j] != sigma1[i, j] or sigma2[i, j] == sigma2[i, j]:
                continue
            c = cos_t[i, j]
            s = sin_t[i, j]
            di, dj, _ = nearest_axis_step(c, s)
            im, jm, ip, jp = i - di, j - dj, i + di, j + dj
            if im < 0 or im >= h or jm < 0 or jm >= w or ip < 0 or ip >= h or jp < 0 or jp >= w:
                left += 1
                continue
            cc, cs2, ss = second_steering_weights(c, s)
            vm = cc * ixx[im, jm] + cs2 * ixy[im, jm] + ss * iyy[im, jm]
            vp = cc * ixx[ip, jp] + cs2 * ixy[ip, jp] + ss * iyy[ip, jp]
            if abs(vm) <= c2 * noise[im, jm] or abs(vp) <= c2 * noise[ip, jp]:
                left += 1
                continue
            sigma2[i, j] = scale
            if not (vm > 0.0 and vp < 0.0):
                continue
            v0 = cc * ixx[i, j] + cs2 * ixy[i, j] + ss * iyy[i, j]
            if v0 > 0.0:
                z = v0 / (v0 - vp)          # crossing in (0, 1)
            elif v0 < 0.0:
                z = -1.0 + vm / (vm - v0)   # crossing in (−1, 0)
            else:
                z = 0.0
            if not (-0.5 <= z < 0.5):
                continue
            lm = edge_level[im, jm]
            lp = edge_level[ip, jp]
            if (lm != 0 and lm < level) or (lp != 0 and lp < level):
                continue
            edge_level[i, j] = level
            new += 1
    return left, new


def _noise_factor(noise_variance, noise_std, shape):
    """(per-pixel noise std factor (H, W), the s_n it multiplies, the variance kept or None) of :func:`detect_edges`."""
    if noise_variance is None:  # c·1.0 == c: the paper's constant thresholds, bit for bit
        return np.ones(shape), noise_std, None
    var = np.asarray(noise_variance, dtype=np.float64)
    if var.shape != shape or not (np.all(np.isfinite(var)) and np.all(var > 0)):
        raise ValueError(f"noise_variance (shape {var.shape}) is invalid; allowed: None or finite values > 0 "
                         f"of the image's shape {shape}")
    return np.sqrt(var), 1.0, var


def _scales(scales, name):
    try:
        vals = tuple(sorted(float(s) for s in scales))
    except TypeError as exc:
        raise ValueError(f"{name}={scales!r} is invalid; allowed: non-empty sequence of σ > 0 px") from exc
    if not vals or any(not (v > 0 and np.isfinite(v)) for v in vals):
        raise ValueError(f"{name}={scales!r} is invalid; allowed: non-empty sequence of σ > 0 px")
    return vals


def detect_edges(gray, *, sigma1_scales=_DEFAULT_SIGMA1, sigma2_scales=_DEFAULT_SIGMA2,
                 noise_std=2.5 / 255, false_positive_rate=1e-6, keep_hessians=False, noise_variance=None,
                 noise_spectrum=None):
    """Elder–Zucker multiscale edges with minimum reliable scale (Sec. 3.1, Eq. 7–9).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (finite; H, W >= :data:`MIN_IMAGE_SIZE`).
    sigma1_scales : sequence of float, keyword-only
        Scales σ1 of the gradient filters, px; searched smallest first (paper: 0.5 … 64).
    sigma2_scales : sequence of float, keyword-only
        Scales σ2 of the 2nd-derivative filters, px; searched smallest first (paper: 0.5 … 32).
    noise_std : float, keyword-only
        Sensor noise s_n in image units (paper: 2.5/255).
    false_positive_rate : float, keyword-only
        Image-wide false-positive tolerance α_I (paper: 1e−6).
    keep_hessians : bool, keyword-only
        Keep the 2nd-derivative responses of every σ2 that produced edge pixels in
        ``EdgeMap.hessians`` so the model-fit estimator does not recompute them (≈ 12 MB per σ2 at
        1 MP). Default False.
    noise_variance : ndarray, shape (H, W), float, or None, or a callable returning one, keyword-only
        Beyond the paper: the per-pixel noise variance, image units² (> 0; e.g.
        :func:`method.blur.noise_model.noise_variance_map`); the thresholds of Eq. (9) then use the
        pixel's own s_n = √variance instead of ``noise_std``. None (default): ``noise_std`` everywhere.
        A callable (no argument) is called once the first gradient responses are under way, so an
        estimate from the image overlaps their transforms.
    noise_spectrum : NoiseSpectrum or None, or a callable returning one, keyword-only
        Beyond the paper: the noise's power spectrum relative to white noise of that variance
        (:func:`method.blur.noise_spectrum.estimate_noise_spectrum`); each threshold of scale σ is then
        multiplied by √``noise_spectrum.factor(k, σ)`` (k = 1 for c1, 2 for c2): the std of that
        filter's response to the correlated noise. None (default): white noise. A callable: as for
        ``noise_variance``.

    Returns
    -------
    EdgeMap

    Raises
    ------
    ValueError
        Bad image (ndim, dtype, non-finite, too small) or bad option.

    Notes
    -----
    1. α_p from α_I and n = H·W; thresholds c1(σ1), c2(σ2) (Eq. 9). With ``noise_variance`` the
       thresholds are those of unit noise times the pixel's √variance (c2: at each of p ± e); with
       ``noise_spectrum`` each scale's threshold also times √factor (the filter's share of the
       correlated noise's power).
    2. Gradient, smallest σ1 first (Eq. 7, FFT bank in single precision — its round-off is
       < 1e−3 of the thresholds): the first σ1 with |∇| > c1(σ1) is the pixel's
       minimum reliable σ1; θ = atan2(I_y, I_x) and |∇| are taken at that scale.
    3. Second derivative along θ, smallest σ2 first (Eq. 8): at each pixel with a reliable gradient,
       r = ∂²_θ I is evaluated at the two neighbours across the edge, p ± e, where e is the one-pixel
       step along the image axis closest to θ (no interpolation: exact pixel samples, the same
       sampling the blur estimators use), steered with the pixel's own θ. The pixel's minimum
       reliable σ2 is the first scale at which both |r(p − e)| and |r(p + e)| exceed c2(σ2).
       (At the edge itself r ≈ 0 at every scale, so the paper's pixelwise test "|r(p)| > c2" can
       never hold exactly at an edge; requiring reliability of the two flanks is Elder & Zucker's
       "reliable responses of opposite sign on either side of the zero crossing".)
    4. At that scale the pixel is an edge if r(p − e) > 0 > r(p + e) (the sign pattern of a step
       rising along θ: positive lobe on the dark side) and the linearly interpolated zero crossing
       of r(p − e), r(p), r(p + e) lies in [−1/2, 1/2) steps of p: exactly one pixel per row (or
       column) across the edge, i.e. a thin digital curve. Scales are processed smallest first and
       a pixel whose neighbour p ± e is already an edge (found at a smaller, better-localised scale)
       is not marked: a coarse scale only fills gaps, it does not thicken the curve.
    5. Pixels without a reliable gradient, or with no reliable σ2, are never edges.
    6. With ``keep_hessians``, the (I_xx, I_xy, I_yy) of each σ2 that produced edges are kept on the
       EdgeMap for the blur estimators (Sec. 3.2 samples the same responses).
    7. Threads: the passes of steps 2–4 run on one thread while the next scales' responses are
       computed ahead on :func:`numba.get_num_threads` threads (one FFT thread each;
       :meth:`GaussianDerivativeBank.responses`); the result does not depend on the thread count.
    """
    img = check_gray_image(gray, "gray", MIN_IMAGE_SIZE)
    s1 = _scales(sigma1_scales, "sigma1_scales")
    s2 = _scales(sigma2_scales, "sigma2_scales")
    h, w = img.shape
    alpha_p = per_pixel_false_positive_rate(false_positive_rate, h * w)
    if not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std={noise_std!r} is invalid; allowed: > 0 (image units)")
    threads = numba.get_num_threads()
    bank = GaussianDerivativeBank(img, max(s1[-1], s2[-1]), precision="single", workers=1)
    sigma1 = np.full((h, w), np.nan)
    theta = np.zeros((h, w))
    gmag = np.zeros((h, w))
    with bank.responses([(s, *orders) for s in s1 for orders in ((1, 0), (0, 1))], threads=threads) as gradients:
        # a lazy noise estimate runs while the first gradients are transformed
        noise, s_n, var = _noise_factor(noise_variance() if callable(noise_variance) else noise_variance,
                                        noise_std, (h, w))
        noise_spectrum = noise_spectrum() if callable(noise_spectrum) else noise_spectrum
        for s in s1:
            c1 = first_derivative_threshold(s, noise_std=s_n, alpha_p=alpha_p)
            if noise_spectrum is not None:
                c1 = c1 * np.sqrt(noise_spectrum.factor(1, s))
            ix, iy = next(gradients), next(gradients)
            if _gradient_pass(ix, iy, float(c1), noise, float(s), sigma1, theta, gmag) == 0:
                break

    sigma2 = np.full((h, w), np.nan)
    edge_level = np.zeros((h, w), dtype=np.int32)
    hessians = {}
    if np.isfinite(sigma1).any():
        with bank.responses([(s, *orders) for s in s2 for orders in ((2, 0), (1, 1), (0, 2))],
                            threads=threads) as second:
            cos_t, sin_t = np.cos(theta), np.sin(theta)
            for level, s in enumerate(s2, start=1):
                c2 = second_derivative_threshold(s, noise_std=s_n, alpha_p=alpha_p)
                if noise_spectrum is not None:
                    c2 = c2 * np.sqrt(noise_spectrum.factor(2, s))
                ixx, ixy, iyy = next(second), next(second), next(second)
                left, new = _zero_crossing_pass(ixx, ixy, iyy, cos_t, sin_t, float(c2), noise, float(s), level,
                                                sigma1, sigma2, edge_level)
                if keep_hessians and new:
                    hessians[float(s)] = (ixx, ixy, iyy)
                if left == 0:
                    break
    edges = edge_level > 0
    return EdgeMap(edges=edges, theta=theta, gradient_magnitude=gmag, sigma1=sigma1, sigma2=sigma2,
                   hessians=hessians if keep_hessians else None, noise_variance=var, noise_spectrum=noise_spectrum)


def check_edge_inputs(gray, edge_map):
    """Validate a (gray, EdgeMap) pair for the blur estimators; return gray as float64.

    Raises
    ------
    ValueError
        ``gray`` is not a finite 2-D float image, ``edge_map`` is not an :class:`EdgeMap`, or the
        shapes differ.
    """
    img = check_gray_image(gray, "gray", MIN_IMAGE_SIZE)
    if not isinstance(edge_map, EdgeMap):
        raise ValueError(f"edge_map must be an EdgeMap (from detect_edges); got {type(edge_map).__name__}")
    for name in ("edges", "theta", "gradient_magnitude", "sigma1", "sigma2"):
        arr = getattr(edge_map, name)
        if np.shape(arr) != img.shape:
            raise ValueError(f"edge_map.{name} has shape {np.shape(arr)}; expected the image shape {img.shape}")
    return img


def edge_pixels_by_scale(edge_map):
    """Group the edge pixels of an :class:`EdgeMap` by their minimum reliable σ2.

    Returns
    -------
    list of (float, ndarray, ndarray)
        (σ2 in px, rows, cols) per distinct σ2, smallest σ2 first; edge pixels with NaN σ2 (not
        produced by :func:`detect_edges`) are left out.
    """
    edges = np.asarray(edge_map.edges, dtype=bool)
    s2 = np.asarray(edge_map.sigma2, dtype=np.float64)
    rows, cols = np.nonzero(edges & np.isfinite(s2))
    return pixels_by_scale(rows, cols, s2[rows, cols])


def pixels_by_scale(rows, cols, vals):
    """Group pixels (``rows``, ``cols``: int arrays, shape (n,)) by their σ2 ``vals`` (px, shape (n,), finite).

    Returns
    -------
    list of (float, ndarray, ndarray)
        (σ2 in px, rows, cols) per distinct σ2, smallest σ2 first; each group keeps the pixels' order.
    """
    groups = []
    for v in np.unique(vals):
        sel = vals == v
        groups.append((float(v), rows[sel], cols[sel]))
    return groups
