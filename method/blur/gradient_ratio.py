"""Gradient-ratio blur baseline (Zhuo & Sim, "Defocus map estimation from a single image", Pattern
Recognition 44(9), 2011), implemented from its description.

Re-blurring a step blurred by σ with a Gaussian of known σ0 lowers the peak gradient from
A/(√(2π)σ) to A/(√(2π)√(σ² + σ0²)); the ratio R = |∇I| / |∇I_reblurred| at the edge gives
σ = σ0 / √(R² − 1).

The scales, the clipping and what an unusable ratio gives are :class:`~method.params.DefocusParams`
fields (``ratio_*``); their defaults are the harness's reading (gradient at 0.5 px, σ0 = 1 px, NaN
where R ≤ 1), and the ``zhuo_sim`` preset sets those of the authors' method as its public port runs
it (gradients at 1 and 1.5 px at Canny edges, σ clipped to [0, 5] px, an estimate of 0 px no
measure).
"""

from __future__ import annotations

import math

import numpy as np

from ..edges.elder_zucker import check_edge_inputs
from ..edges.gaussian_derivatives import GaussianDerivativeBank

__all__ = ["GRADIENT_SIGMA", "REBLUR_SIGMA", "estimate_blur_gradient_ratio"]

#: Default σ0 of the re-blurring Gaussian, px (Zhuo & Sim use σ0 = 1); ``DefocusParams.ratio_reblur_sigma``.
REBLUR_SIGMA = 1.0
#: Default scale of the Gaussian-derivative gradient operator, px (the smallest Elder–Zucker scale);
#: ``DefocusParams.ratio_gradient_sigma``.
GRADIENT_SIGMA = 0.5


def estimate_blur_gradient_ratio(gray, edge_map, *, params):
    """Blur σ at edge pixels from the gradient ratio after re-blurring (Zhuo & Sim 2011).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Only ``edge_map.edges`` is used (the edge set: the Elder–Zucker edges of Sec. 3.1 by
        default, so that all estimators are compared on the same pixels; Zhuo & Sim's Canny edges
        with ``params.edge_detector="canny"``, :func:`method.edges.canny.detect_edges_canny`).
    params : BlurParams or DefocusParams, keyword-only
        Uses ``ratio_gradient_sigma`` σg (px), ``ratio_reblur_sigma`` σ0 (px), ``ratio_max_sigma``
        (px; None: ``max_sigma``) and ``ratio_zero_is_measure``.

    Returns
    -------
    ndarray, shape (H, W), float64
        σ in px at edge pixels, clipped to [0, ratio_max_sigma]; NaN elsewhere, where R ≤ 1 (no
        measurable blur change, e.g. noise) or R is undefined, and, with
        ``ratio_zero_is_measure=False``, where σ = 0.

    Notes
    -----
    1. Gradients by Gaussian derivatives (Eq. 7) at σg: |∇I| at σg, and |∇(I ∗ g_σ0)| = |∇I| at
       σr = √(σg² + σ0²) (Gaussians compose).
    2. R = |∇I|_σg / |∇I|_σr at edge pixels.
    3. σe = σ0 / √(R² − 1) is the blur seen by the gradient operator, √(σ² + σg²); so
       σ = √(σe² − σg²), 0 if negative (R ≥ σr/σg: sharper than the operator resolves). With
       σg → 0 this is exactly Zhuo & Sim's formula; σg regularises the derivative of a sampled
       image and is removed again here. (The same σ as (R²σg² − σr²)/(1 − R²), the form of the
       public code, which reads gradients at σg = 1 and σr = 1.5 px.)
    4. R ≤ 1 or non-finite: NaN; σ = 0: NaN unless ``ratio_zero_is_measure``.
    5. Clip to [0, ratio_max_sigma].
    """
    img = check_edge_inputs(gray, edge_map)
    out = np.full(img.shape, np.nan)
    edges = np.asarray(edge_map.edges, dtype=bool)
    if not edges.any():
        return out
    s_g = float(params.ratio_gradient_sigma)
    s_0 = float(params.ratio_reblur_sigma)
    s_r = math.sqrt(s_g ** 2 + s_0 ** 2)
    max_sigma = float(params.max_sigma if params.ratio_max_sigma is None else params.ratio_max_sigma)
    bank = GaussianDerivativeBank(img, s_r)
    gx, gy = bank.gradient(s_g)
    g1 = np.hypot(gx[edges], gy[edges])
    gx, gy = bank.gradient(s_r)
    g2 = np.hypot(gx[edges], gy[edges])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = g1 / g2
        sigma_e2 = s_0 ** 2 / (ratio ** 2 - 1.0)
        sigma = np.sqrt(np.maximum(sigma_e2 - s_g ** 2, 0.0))
    sigma[~(ratio > 1.0) | ~np.isfinite(sigma)] = np.nan
    if not params.ratio_zero_is_measure:
        sigma[sigma == 0.0] = np.nan
    out[edges] = np.clip(sigma, 0.0, max_sigma)
    return out
