"""Noise thresholds of the multiscale edge detector, Eq. (9) (Appendix B, after Elder & Zucker 1998).

A filter response is *reliable* when it exceeds what sensor noise of standard deviation s_n would
produce anywhere in the image with probability above the image-wide tolerance α_I.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from scipy.special import erfcinv

from ..registry import Registry

__all__ = [
    "NOISE_SPECTRA",
    "band_shares",
    "radial_frequency",
    "NoiseSpectrum",
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


#: ``EdgeParams.noise_spectrum``: how the noise of ``noise_model="signal_dependent"`` is spread over frequency.
NOISE_SPECTRA = Registry("noise spectrum", {
    "white": "white noise: every filter scale sees the variance the pixel-scale estimate reads",
    "estimated": "the noise's power spectrum estimated per octave band from the image "
                 "(resizing, demosaicking, JPEG correlate neighbouring pixels; method.blur.noise_spectrum): "
                 "Eq. (9) and the fit's residual test use the variance each filter scale sees",
})

#: Side of the DFT grid on which the filters' power is summed per band.
_SPECTRUM_GRID = 256


@functools.lru_cache(maxsize=1)
def radial_frequency():
    """|ω| (rad/px) on the 256² DFT grid of :func:`band_shares` (one shared array: do not modify)."""
    w = 2.0 * np.pi * np.fft.fftfreq(_SPECTRUM_GRID)
    return np.hypot(w[:, None], w[None, :])


def band_shares(power, band_edges):
    """Share of a filter's power in each frequency band: (n_bands,) summing to 1.

    Parameters
    ----------
    power : ndarray, (256, 256), float
        The filter's squared transfer function on the DFT grid ω ∈ [−π, π)² (:func:`radial_frequency`).
    band_edges : tuple of float
        Band boundaries in |ω|, rad/px, decreasing; band 0 lies above the first, the last band below the last.

    Returns
    -------
    ndarray, (len(band_edges) + 1,), float64
    """
    idx = np.searchsorted(-np.asarray(band_edges, dtype=np.float64), -radial_frequency())
    shares = np.bincount(idx.ravel(), weights=np.asarray(power, dtype=np.float64).ravel(),
                         minlength=len(band_edges) + 1)
    return shares / shares.sum()


@functools.lru_cache(maxsize=256)
def _derivative_shares(order, sigma, band_edges):
    r2 = radial_frequency() ** 2
    return band_shares(r2 ** order * np.exp(-(sigma ** 2) * r2), band_edges)


@dataclasses.dataclass(frozen=True)
class NoiseSpectrum:
    """Power spectrum of the image noise per frequency band, relative to white noise of the pixel-scale variance.

    Attributes
    ----------
    band_edges : tuple of float
        Band boundaries in |ω|, rad/px, decreasing (band 0: the highest frequencies, up to the
        grid's corner π√2; the last band: down to 0).
    levels : tuple of float
        Power spectral density in each band (len(band_edges) + 1 values, ≥ 0), in units of the
        variance the pixel-scale estimate reads (:func:`method.blur.image_noise.block_energies`):
        all 1 for white noise.

    Notes
    -----
    A Gaussian-derivative filter of order k at scale σ has squared transfer function
    |ω|^{2k} exp(−σ²|ω|²) (θ-averaged up to a constant; :mod:`method.edges.gaussian_derivatives`).
    Its response to noise of this spectrum has the variance of its response to white noise
    times :meth:`factor`, the filter's power-weighted mean of ``levels``.
    """

    band_edges: tuple
    levels: tuple

    def __post_init__(self):
        edges = tuple(float(e) for e in self.band_edges)
        levels = tuple(float(v) for v in self.levels)
        if (len(levels) != len(edges) + 1 or any(not (math.isfinite(v) and v >= 0) for v in levels)
                or any(not (e > 0) for e in edges) or any(a <= b for a, b in zip(edges, edges[1:]))):
            raise ValueError(f"NoiseSpectrum(band_edges={self.band_edges!r}, levels={self.levels!r}) is invalid; "
                             "allowed: decreasing edges > 0 rad/px and one finite level >= 0 more than edges")
        object.__setattr__(self, "band_edges", edges)
        object.__setattr__(self, "levels", levels)

    def factor(self, order, sigma):
        """Variance of the order-``order`` Gaussian derivative at ``sigma`` (px) over its white-noise value.

        Parameters
        ----------
        order : int
            1 (gradient, Eq. 7) or 2 (second derivative, Eq. 8).
        sigma : float
            Filter scale, px (> 0).

        Returns
        -------
        float
            Σ_b share_b · level_b, dimensionless (1 for white noise).
        """
        return float(_derivative_shares(int(order), float(sigma), self.band_edges) @ np.asarray(self.levels))


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
