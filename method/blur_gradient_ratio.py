"""Gradient-ratio blur baseline (Zhuo & Sim, "Defocus map estimation from a single image", Pattern
Recognition 44(9), 2011), implemented from its description.

Re-blurring a step blurred by σ with a Gaussian of known σ0 lowers the peak gradient from
A/(√(2π)σ) to A/(√(2π)√(σ² + σ0²)); the ratio R = |∇I| / |∇I_reblurred| at the edge gives
σ = σ0 / √(R² − 1).
"""

from __future__ import annotations

import math

import numpy as np

from .elder_zucker_edges import check_edge_inputs
from .gaussian_derivatives import GaussianDerivativeBank

__all__ = ["GRADIENT_SIGMA", "REBLUR_SIGMA", "estimate_blur_gradient_ratio"]

#: σ0 of the re-blurring Gaussian, px (Zhuo & Sim use σ0 = 1).
REBLUR_SIGMA = 1.0
#: Scale of the Gaussian-derivative gradient operator, px (the smallest Elder–Zucker scale).
GRADIENT_SIGMA = 0.5


def estimate_blur_gradient_ratio(gray, edge_map, *, params):
    """Blur σ at edge pixels from the gradient ratio after re-blurring (Zhuo & Sim 2011).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Only ``edge_map.edges`` is used (the edge set; Zhuo & Sim used Canny edges — we use the
        Elder–Zucker edges so that all estimators are compared on the same pixels).
    params : DefocusParams, keyword-only
        Uses ``max_sigma``.

    Returns
    -------
    ndarray, shape (H, W), float64
        σ in px at edge pixels, clipped to [0, max_sigma]; NaN elsewhere and where R ≤ 1
        (no measurable blur change, e.g. noise).

    Notes
    -----
    1. Gradients by Gaussian derivatives (Eq. 7) at σg = :data:`GRADIENT_SIGMA`: |∇I| at σg, and
       |∇(I ∗ g_σ0)| = |∇I| at √(σg² + σ0²) (Gaussians compose), σ0 = :data:`REBLUR_SIGMA`.
    2. R = |∇I|_σg / |∇I|_√(σg²+σ0²) at edge pixels.
    3. σe = σ0 / √(R² − 1) is the blur seen by the gradient operator, √(σ² + σg²); so
       σ = √(σe² − σg²) (0 if negative). With σg → 0 this is exactly Zhuo & Sim's formula; the
       small σg regularises the derivative of a sampled image and is removed again here.
    4. Clip to [0, max_sigma].
    """
    img = check_edge_inputs(gray, edge_map)
    out = np.full(img.shape, np.nan)
    edges = np.asarray(edge_map.edges, dtype=bool)
    if not edges.any():
        return out
    s_g = GRADIENT_SIGMA
    s_r = math.sqrt(GRADIENT_SIGMA ** 2 + REBLUR_SIGMA ** 2)
    bank = GaussianDerivativeBank(img, s_r)
    gx, gy = bank.gradient(s_g)
    g1 = np.hypot(gx[edges], gy[edges])
    gx, gy = bank.gradient(s_r)
    g2 = np.hypot(gx[edges], gy[edges])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = g1 / g2
        sigma_e2 = REBLUR_SIGMA ** 2 / (ratio ** 2 - 1.0)
        sigma = np.sqrt(np.maximum(sigma_e2 - s_g ** 2, 0.0))
    sigma[~(ratio > 1.0) | ~np.isfinite(sigma)] = np.nan
    out[edges] = np.clip(sigma, 0.0, float(params.max_sigma))
    return out
