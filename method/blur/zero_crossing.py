"""Elder–Zucker blur estimate: extrema of the 2nd derivative as zero crossings of the 3rd (Sec. 3.2 baseline).

The distance d between the two extrema (of opposite sign) of the 2nd-derivative response across a
blurred step gives σb = √((d/2)² − σ2²) (Eq. 2d). Elder & Zucker locate the extrema as zero
crossings of the 3rd derivative along the gradient direction; the paper (Fig. 4) shows this is
fragile near neighbouring edges, which motivates the model fit (:mod:`method.blur.model_fit`).
"""

from __future__ import annotations

import numba
import numpy as np

from .model_fit import blur_from_extrema_distance
from ..edges.elder_zucker import check_edge_inputs, edge_pixels_by_scale
from ..edges.gaussian_derivatives import GaussianDerivativeBank, nearest_axis_step, third_steering_weights

__all__ = ["estimate_blur_zero_crossing"]


@numba.njit(cache=True, nogil=True)
def _zc_kernel(ixxx, ixxy, ixyy, iyyy, rows, cols, cos_t, sin_t, max_steps, out_d):
    h, w = ixxx.shape
    for n in range(rows.shape[0]):
        out_d[n] = np.nan
        i0, j0 = rows[n], cols[n]
        c, s = cos_t[n], sin_t[n]
        di, dj, proj = nearest_axis_step(c, s)
        c3, c2s, cs2, s3 = third_steering_weights(c, s)
        # dark side: first k <= 0 (walking outward) with r3(k) <= 0 < r3(k − 1)
        z_dark = np.nan
        prev = c3 * ixxx[i0, j0] + c2s * ixxy[i0, j0] + cs2 * ixyy[i0, j0] + s3 * iyyy[i0, j0]
        centre = prev
        for k in range(1, max_steps + 1):
            ii, jj = i0 - k * di, j0 - k * dj
            if ii < 0 or ii >= h or jj < 0 or jj >= w:
                break
            cur = c3 * ixxx[ii, jj] + c2s * ixxy[ii, jj] + cs2 * ixyy[ii, jj] + s3 * iyyy[ii, jj]
            if prev <= 0.0 < cur:
                # linear zero between (−k, cur) and (−k + 1, prev)
                z_dark = -k + cur / (cur - prev)
                break
            prev = cur
        if z_dark != z_dark:
            continue
        # bright side: first k >= 0 with r3(k) <= 0 < r3(k + 1)
        z_bright = np.nan
        prev = centre
        for k in range(1, max_steps + 1):
            ii, jj = i0 + k * di, j0 + k * dj
            if ii < 0 or ii >= h or jj < 0 or jj >= w:
                break
            cur = c3 * ixxx[ii, jj] + c2s * ixxy[ii, jj] + cs2 * ixyy[ii, jj] + s3 * iyyy[ii, jj]
            if prev <= 0.0 < cur:
                z_bright = (k - 1) + (-prev) / (cur - prev)
                break
            prev = cur
        if z_bright != z_bright:
            continue
        out_d[n] = (z_bright - z_dark) * proj


def estimate_blur_zero_crossing(gray, edge_map, *, params):
    """Blur σb at edge pixels from the zero crossings of the 3rd derivative (Elder & Zucker 1998).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to ``detect_edges``).
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges``.
    params : BlurParams or DefocusParams, keyword-only
        Uses ``fit_window_max`` (search reaches (fit_window_max − 1)/2 px on each side) and
        ``max_sigma``.

    Returns
    -------
    ndarray, shape (H, W), float64
        σb in px at edge pixels, clipped to [0, max_sigma]; NaN elsewhere and where an extremum is
        not found within the search range.

    Notes
    -----
    Per edge pixel p, at its σ2:

    1. r3(k) = ∂³_θ I (steered with θ(p) from the 4 basis responses I_xxx, I_xxy, I_xyy, I_yyy)
       at p + k·e, e the one-pixel step along the image axis closest to θ (exact pixel samples).
    2. Dark-side extremum (positive lobe of ∂²_θ I): walking k = 0, −1, −2, …, the first sign
       change r3(k) ≤ 0 < r3(k − 1); bright-side extremum (negative lobe): walking k = 0, 1, 2, …,
       the first change r3(k) ≤ 0 < r3(k + 1). Both located sub-pixel by linear interpolation.
    3. d = (z_bright − z_dark)·max(|cos θ|, |sin θ|) (steps along the axis → px along θ);
       σb = √((d/2)² − σ2²) (Eq. 2d), clipped to [0, max_sigma].
    """
    img = check_edge_inputs(gray, edge_map)
    max_steps = max(1, (int(params.fit_window_max) - 1) // 2)
    out = np.full(img.shape, np.nan)
    groups = edge_pixels_by_scale(edge_map)
    if not groups:
        return out
    bank = GaussianDerivativeBank(img, groups[-1][0], precision="single")
    theta = np.asarray(edge_map.theta, dtype=np.float64)
    for sigma2, rows, cols in groups:
        ixxx, ixxy, ixyy, iyyy = bank.third(sigma2)
        th = theta[rows, cols]
        d = np.empty(rows.size)
        _zc_kernel(ixxx, ixxy, ixyy, iyyy, rows, cols, np.cos(th), np.sin(th), max_steps, d)
        out[rows, cols] = np.clip(blur_from_extrema_distance(d, sigma2), 0.0, float(params.max_sigma))
    return out
