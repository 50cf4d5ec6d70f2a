"""Error metrics of estimated blur maps against ground-truth σ, and image-quality metrics.

All blur quantities are Gaussian σ in pixels. Every function ignores pixels where either the
estimate or the ground truth is not finite (NaN marks "no estimate"; inf depth gives no σ).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "OUTLIER_THRESHOLD_PX",
    "RTF_SIGMA_CLIP_PX",
    "dense_metrics",
    "image_quality",
    "in_focus_outlier_fraction",
    "region_masks",
    "rtf_normalized_errors",
    "sparse_metrics",
    "textured_mask",
]

#: An estimate whose absolute error exceeds this is an outlier, px.
OUTLIER_THRESHOLD_PX = 1.0
#: σ clip of the RTF-style normalised errors, px (defocus-map literature convention).
RTF_SIGMA_CLIP_PX = 3.275


def _pairs(estimate, truth, mask):
    est = np.asarray(estimate, dtype=np.float64)
    gt = np.asarray(truth, dtype=np.float64)
    if est.shape != gt.shape:
        raise ValueError(f"estimate shape {est.shape} != ground truth shape {gt.shape}")
    ok = np.isfinite(est) & np.isfinite(gt)
    if mask is not None:
        ok &= np.asarray(mask, dtype=bool)
    return est[ok], gt[ok]


def sparse_metrics(estimate, truth, *, mask=None, outlier_px=OUTLIER_THRESHOLD_PX) -> dict:
    """Errors of blur estimates at the pixels where both are finite (e.g. edge pixels).

    Parameters
    ----------
    estimate, truth : ndarray, HxW, σ in px (NaN = no estimate)
    mask : ndarray of bool, HxW, optional, keyword-only
        Restrict to these pixels.
    outlier_px : float, keyword-only
        |error| above this (px) counts as an outlier.

    Returns
    -------
    dict
        ``n`` (pixels), ``mae``, ``median_ae``, ``rmse``, ``bias`` (mean signed error), all px;
        ``median_rel_error`` (median |e| / σ_gt); ``outlier_fraction``. NaN when ``n == 0``.
    """
    est, gt = _pairs(estimate, truth, mask)
    n = int(est.size)
    if n == 0:
        nan = float("nan")
        return {"n": 0, "mae": nan, "median_ae": nan, "rmse": nan, "bias": nan,
                "median_rel_error": nan, "outlier_fraction": nan}
    err = est - gt
    ae = np.abs(err)
    return {
        "n": n,
        "mae": float(ae.mean()),
        "median_ae": float(np.median(ae)),
        "rmse": float(np.sqrt(np.mean(err**2))),
        "bias": float(err.mean()),
        "median_rel_error": float(np.median(ae / np.maximum(gt, 1e-6))),
        "outlier_fraction": float(np.mean(ae > outlier_px)),
    }


def dense_metrics(estimate, truth, *, regions) -> dict:
    """:func:`sparse_metrics` of a dense map over each named region.

    Parameters
    ----------
    estimate, truth : ndarray, HxW, σ in px
    regions : Mapping[str, ndarray of bool]
        E.g. ``region_masks(...)``: ``{"all": ..., "edges": ..., "textured": ...}``.

    Returns
    -------
    dict
        ``{region: sparse_metrics(...)}``.
    """
    return {name: sparse_metrics(estimate, truth, mask=m) for name, m in regions.items()}


def rtf_normalized_errors(estimate, truth, *, mask=None, clip_px=RTF_SIGMA_CLIP_PX) -> dict:
    """Normalised MSE and MAE as in the defocus-map literature: σ clipped at ``clip_px``, ÷ ``clip_px``.

    Returns
    -------
    dict
        ``{"n", "nmse", "nmae"}`` (dimensionless; maps in [0, 1]).
    """
    est, gt = _pairs(estimate, truth, mask)
    if est.size == 0:
        return {"n": 0, "nmse": float("nan"), "nmae": float("nan")}
    e = np.clip(est, 0, clip_px) / clip_px
    g = np.clip(gt, 0, clip_px) / clip_px
    return {"n": int(e.size), "nmse": float(np.mean((e - g) ** 2)), "nmae": float(np.mean(np.abs(e - g)))}


def textured_mask(image, *, window=7, threshold=0.02) -> np.ndarray:
    """Pixels where defocus is observable: local standard deviation of luminance above ``threshold``.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
    window : int, keyword-only
        Side of the square window, px.
    threshold : float, keyword-only
        Minimum local std, image units (0.02 ≈ 5 grey levels of 8 bits, twice the paper's s_n).

    Returns
    -------
    ndarray of bool, HxW
    """
    from scipy.ndimage import uniform_filter

    img = np.asarray(image, dtype=np.float64)
    from method.luma import LUMA_WEIGHTS

    gray = img if img.ndim == 2 else img @ np.asarray(LUMA_WEIGHTS)
    mean = uniform_filter(gray, window, mode="reflect")
    var = np.maximum(uniform_filter(gray**2, window, mode="reflect") - mean**2, 0.0)
    return np.sqrt(var) > threshold


def region_masks(image, truth, *, edges=None, exclude=None, texture_threshold=0.02) -> dict:
    """Standard evaluation regions: ``all`` (finite ground truth), ``edges``, ``textured``.

    Parameters
    ----------
    image : ndarray, HxW(x3), float in [0, 1]
        The input the method saw (for the texture mask).
    truth : ndarray, HxW, σ_gt px (NaN/inf where undefined)
    edges : ndarray of bool, HxW, optional, keyword-only
        Edge pixels found by the method.
    exclude : ndarray of bool, HxW, optional, keyword-only
        Pixels removed from every region (e.g. occlusion boundaries, where σ_gt is ill-defined).
    """
    valid = np.isfinite(np.asarray(truth, dtype=np.float64))
    if exclude is not None:
        valid &= ~np.asarray(exclude, dtype=bool)
    out = {"all": valid, "textured": valid & textured_mask(image, threshold=texture_threshold)}
    if edges is not None:
        out["edges"] = valid & np.asarray(edges, dtype=bool)
    return out


def in_focus_outlier_fraction(estimate, truth, *, in_focus_px=1.0, blurry_px=2.0, mask=None) -> dict:
    """Fraction of in-focus pixels (σ_gt ≤ ``in_focus_px``) estimated blurry (σ > ``blurry_px``).

    The outliers the paper's biased cross-bilateral step removes (Sec. 3.3, Fig. 5).

    Returns
    -------
    dict
        ``{"n_in_focus", "n_blurry_estimates", "fraction"}``.
    """
    est, gt = _pairs(estimate, truth, mask)
    focus = gt <= in_focus_px
    n = int(focus.sum())
    bad = int(np.sum(est[focus] > blurry_px))
    return {"n_in_focus": n, "n_blurry_estimates": bad, "fraction": float(bad / n) if n else float("nan")}


def image_quality(test, reference) -> dict:
    """PSNR (dB) and SSIM of ``test`` against ``reference`` (float images in [0, 1]), via scikit-image."""
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    a = np.asarray(test, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image shapes differ: {a.shape} vs {b.shape}")
    channel_axis = -1 if a.ndim == 3 else None
    return {
        "psnr_db": float(peak_signal_noise_ratio(b, a, data_range=1.0)),
        "ssim": float(structural_similarity(b, a, data_range=1.0, channel_axis=channel_axis)),
    }
