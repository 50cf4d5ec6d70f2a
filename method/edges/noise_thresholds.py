"""Noise thresholds of the multiscale edge detector, Eq. (9) (Appendix B, after Elder & Zucker 1998).

A filter response is *reliable* when it exceeds what sensor noise of standard deviation s_n would
produce anywhere in the image with probability above the image-wide tolerance α_I.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erfcinv

from ..registry import Registry

__all__ = [
    "SENSOR_NOISE_MODELS",
    "first_derivative_threshold",
    "per_pixel_false_positive_rate",
    "second_derivative_threshold",
]

#: ``EdgeParams.noise_model``: what the noise s_n of Eq. (9) and of the checked fit's residual test is.
SENSOR_NOISE_MODELS = Registry("noise model", {
    "constant": "one std noise_std everywhere, in the light measured (the paper's s_n)",
    "signal_dependent": "variance a·x + b in linear light carried through the tone curve, per pixel "
                        "(Foi et al. 2008; method.blur.noise_model)",
})


def _positive(value, name):
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name}={value!r} is invalid; allowed: finite values > 0")
    return arr


def _unit_open(value, name):
    v = float(value)
    if not 0.0 < v < 1.0:
        raise ValueError(f"{name}={value!r} is invalid; allowed: 0 < {name} < 1")
    return v


def per_pixel_false_positive_rate(false_positive_rate, n_pixels):
    """Per-pixel false-positive rate α_p = 1 − (1 − α_I)^(1/n), Eq. (9).

    Parameters
    ----------
    false_positive_rate : float
        Image-wide tolerance α_I, 0 < α_I < 1 (paper: 1e−6).
    n_pixels : int
        Number of pixels n (> 0).

    Returns
    -------
    float
        α_p, computed as −expm1(log1p(−α_I)/n) so that α_p ~ 1e−12 keeps full precision.
    """
    a = _unit_open(false_positive_rate, "false_positive_rate")
    n = int(n_pixels)
    if n < 1 or n != n_pixels:
        raise ValueError(f"n_pixels={n_pixels!r} is invalid; allowed: integer >= 1")
    return float(-math.expm1(math.log1p(-a) / n))


def first_derivative_threshold(sigma1, *, noise_std, alpha_p):
    """Gradient-magnitude threshold c1(σ1) = s_n √(−2 ln α_p) / (2√(2π) σ1²), Eq. (9).

    Parameters
    ----------
    sigma1 : float or ndarray
        Scale(s) σ1 of the 1st-derivative filters (Eq. 7), px.
    noise_std : float, keyword-only
        Sensor noise s_n in image units (paper: 2.5/255 on a [0, 1] image).
    alpha_p : float, keyword-only
        Per-pixel false-positive rate (:func:`per_pixel_false_positive_rate`).

    Returns
    -------
    float or ndarray
        c1 in image units / px.

    Notes
    -----
    Each component of the gradient of white noise has standard deviation s_n/(2√(2π)σ1²); the
    magnitude is Rayleigh-distributed, P(|∇| > c) = exp(−c²/(2·std²)) = α_p.
    """
    s1 = _positive(sigma1, "sigma1")
    sn = float(_positive(noise_std, "noise_std"))
    ap = _unit_open(alpha_p, "alpha_p")
    c = sn * math.sqrt(-2.0 * math.log(ap)) / (2.0 * math.sqrt(2.0 * math.pi) * s1 ** 2)
    return float(c) if c.ndim == 0 else c


def second_derivative_threshold(sigma2, *, noise_std, alpha_p):
    """2nd-derivative threshold c2(σ2) = s_n √2 erf⁻¹(1 − α_p) / (4√(π/3) σ2³), Eq. (9).

    Parameters
    ----------
    sigma2 : float or ndarray
        Scale(s) σ2 of the 2nd-derivative filters (Eq. 8), px.
    noise_std : float, keyword-only
        Sensor noise s_n in image units.
    alpha_p : float, keyword-only
        Per-pixel false-positive rate.

    Returns
    -------
    float or ndarray
        c2 in image units / px², > 0.

    Notes
    -----
    The steered 2nd-derivative response of white noise is normal with standard deviation
    s_n/(4√(π/3)σ2³); a two-sided test P(|r| > c) = α_p gives c = √2·std·erf⁻¹(1 − α_p). The
    extracted paper text reads erf⁻¹(α_p), which would give c2 ≈ 0 for α_p ~ 1e−12 (DIGEST.md).
    erf⁻¹(1 − α_p) is evaluated as erfc⁻¹(α_p) to avoid the cancellation in 1 − α_p.
    """
    s2 = _positive(sigma2, "sigma2")
    sn = float(_positive(noise_std, "noise_std"))
    ap = _unit_open(alpha_p, "alpha_p")
    c = sn * math.sqrt(2.0) * float(erfcinv(ap)) / (4.0 * math.sqrt(math.pi / 3.0) * s2 ** 3)
    return float(c) if c.ndim == 0 else c
