"""Canny edges as an :class:`~method.edges.elder_zucker.EdgeMap` (the edge set of Zhuo & Sim 2011).

Zhuo & Sim ("Defocus map estimation from a single image", Pattern Recognition 44(9), 2011) read
their gradient ratio at Canny edges (J. Canny, "A computational approach to edge detection", IEEE
TPAMI 8(6), 1986); the public port of their method calls ``skimage.feature.canny(gray, 1)`` with
scikit-image's default thresholds. This module wraps that function so the pipeline's blur stage can
take Canny edges in place of the Elder–Zucker edges of Sec. 3.1 (``DefocusParams.edge_detector``).
"""

from __future__ import annotations

import math

import numpy as np

from .elder_zucker import MIN_IMAGE_SIZE, EdgeMap
from .gaussian_derivatives import GaussianDerivativeBank, check_gray_image

__all__ = ["CANNY_HIGH_THRESHOLD", "CANNY_LOW_THRESHOLD", "CANNY_SIGMA", "detect_edges_canny"]

#: σ of Canny's Gaussian smoothing, px (scikit-image's default and the public Zhuo & Sim code's).
CANNY_SIGMA = 1.0
#: Hysteresis thresholds on scikit-image's Sobel gradient magnitude of the smoothed image: 10 % and
#: 20 % of a float image's range, scikit-image's defaults (used by the public Zhuo & Sim code).
CANNY_LOW_THRESHOLD = 0.1
CANNY_HIGH_THRESHOLD = 0.2


def _check_options(sigma, low_threshold, high_threshold):
    s = float(sigma)
    if not (math.isfinite(s) and s > 0):
        raise ValueError(f"sigma={sigma!r} is invalid; allowed: finite σ > 0 px")
    lo, hi = float(low_threshold), float(high_threshold)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi):
        raise ValueError(f"low_threshold={low_threshold!r}, high_threshold={high_threshold!r} are invalid; "
                         "allowed: finite 0 <= low_threshold <= high_threshold")
    return s, lo, hi


def detect_edges_canny(gray, *, sigma=CANNY_SIGMA, low_threshold=CANNY_LOW_THRESHOLD,
                       high_threshold=CANNY_HIGH_THRESHOLD):
    """Canny edges of a grey image, with the gradient fields of an :class:`EdgeMap`.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (finite; H, W >= :data:`method.edges.elder_zucker.MIN_IMAGE_SIZE`).
    sigma : float, keyword-only
        σ of the Gaussian smoothing before the Sobel gradient, px (> 0).
    low_threshold, high_threshold : float, keyword-only
        Hysteresis thresholds (0 <= low <= high) on scikit-image's gradient magnitude of the
        smoothed image, i.e. the hypotenuse of its two Sobel responses (≈ 8 × |∇I| in image units
        per px; a step of contrast A blurred by σ_b peaks at ≈ 8A / (√(2π) √(σ_b² + sigma²))).

    Returns
    -------
    EdgeMap
        ``edges`` from :func:`skimage.feature.canny` (one pixel wide, no image-border pixel);
        ``theta`` and ``gradient_magnitude`` (image units / px) of the Gaussian-derivative gradient
        at ``sigma`` (Eq. 7) at the edge pixels, 0 elsewhere; ``sigma1`` = ``sigma`` at the edge pixels
        and NaN elsewhere; ``sigma2`` all NaN (Canny has no 2nd-derivative scale).

    Raises
    ------
    ValueError
        Bad image or an option out of range (the message names the allowed values).

    Notes
    -----
    1. :func:`skimage.feature.canny`: Gaussian smoothing at ``sigma`` (``mode="constant"`` with
       scikit-image's border compensation), Sobel gradients, non-maximum suppression along the
       gradient direction, hysteresis between the two thresholds.
    2. At the edge pixels, θ = atan2(I_y, I_x) and |∇I| from the Gaussian-derivative gradient at
       ``sigma`` (Eq. 7; :class:`method.edges.gaussian_derivatives.GaussianDerivativeBank`).
    """
    from skimage.feature import canny  # imported on first use: `import method` stays light

    img = check_gray_image(gray, "gray", MIN_IMAGE_SIZE)
    s, lo, hi = _check_options(sigma, low_threshold, high_threshold)
    edges = np.asarray(canny(img, sigma=s, low_threshold=lo, high_threshold=hi), dtype=bool)
    theta = np.zeros(img.shape)
    gmag = np.zeros(img.shape)
    sigma1 = np.full(img.shape, np.nan)
    if edges.any():
        gx, gy = GaussianDerivativeBank(img, s).gradient(s)
        theta[edges] = np.arctan2(gy[edges], gx[edges])
        gmag[edges] = np.hypot(gx[edges], gy[edges])
        sigma1[edges] = s
    return EdgeMap(edges=edges, theta=theta, gradient_magnitude=gmag, sigma1=sigma1,
                   sigma2=np.full(img.shape, np.nan))
