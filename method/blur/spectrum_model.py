"""The expected windowed periodograms of the region-blur likelihood (:mod:`method.blur.local_spectrum`).

For an n×n Hann window of the gradient of a blurred 1/|ω|² texture (unit scale s) and of unit white
noise: the expected power per frequency ring, exactly including the window's leakage
(:func:`model_tables`), on the candidate σ grid (:func:`sigma_grid`). The blur's transfer function is
a Gaussian or a pixel-integrated uniform disk (``psf``).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.fft
from scipy.special import j1

__all__ = ["RING_MERGE", "hann_window", "model_tables", "ring_matrix", "sigma_grid"]


def sigma_grid(sigma_min, sigma_max, psf):
    """The candidate σ of the grid search, px (reported convention).

    Parameters
    ----------
    sigma_min, sigma_max : float
        Range of reported σ, px (0 <= sigma_min < sigma_max). For ``psf="disk"`` values below
        1/√12 px (no disk, only the pixel's box) are raised to it.
    psf : {"gaussian", "disk"}

    Returns
    -------
    ndarray, (G,), float64
        Steps of 0.125 px up to 2 px, then a geometric ratio of 1.05.
    """
    lo = float(sigma_min)
    if psf == "disk":
        lo = max(lo, 1.0 / math.sqrt(12.0))
    fine = np.arange(lo, min(2.0, sigma_max), 0.125)
    start = max(2.0, lo)
    n_geo = max(2, int(math.ceil(math.log(sigma_max / start) / math.log(1.05))) + 1) if sigma_max > start else 0
    geo = np.geomspace(start, sigma_max, n_geo) if n_geo else np.array([float(sigma_max)])
    return np.unique(np.concatenate([fine, geo]))


def hann_window(n):
    """Separable n×n Hann window (periodic samples at pixel centres), dimensionless."""
    w = 0.5 - 0.5 * np.cos(2 * np.pi * (np.arange(n) + 0.5) / n)
    return np.outer(w, w)


#: Rings above this index are merged in pairs, above twice it in fours (bounds the bands per window).
RING_MERGE = 16


def _rings(n):
    """Band index of each DFT bin of an n×n window, 0 at DC, and the band count.

    Band = ring round(|k|) (k in DFT index units) up to RING_MERGE; beyond it rings are merged in
    pairs, beyond 2·RING_MERGE in fours (their expected powers vary slowly there).
    """
    k = np.fft.fftfreq(n) * n
    r = np.rint(np.hypot(k[:, None], k[None, :])).astype(np.int64).ravel()
    m = RING_MERGE
    band = np.where(r <= m, r, np.where(r <= 2 * m, m + (r - m + 1) // 2, m + m // 2 + (r - 2 * m + 3) // 4))
    return band, int(band.max()) + 1


def _transfer_sq(psf, sig, wx, wy):
    """|H|² of the blur on the frequency grid (wx, wy, rad/px) for reported σ ``sig``."""
    w2 = wx ** 2 + wy ** 2
    if psf == "gaussian":
        return np.exp(-(sig ** 2) * w2)
    radius = 2.0 * math.sqrt(max(sig ** 2 - 1.0 / 12.0, 0.0))
    box = np.sinc(wx / (2 * np.pi)) * np.sinc(wy / (2 * np.pi))  # np.sinc(x) = sin(πx)/(πx)
    if radius <= 0:
        return box ** 2
    u = radius * np.sqrt(w2)
    with np.errstate(invalid="ignore", divide="ignore"):
        disk = np.where(u > 1e-8, 2.0 * j1(u) / u, 1.0)
    return (disk * box) ** 2


def _windowed_expectation(spectra, n):
    """Exact expected periodograms of n×n Hann-windowed stationary fields of DTFT powers ``spectra``.

    ``spectra`` (..., L, L) real and even, sampled on an L×L DFT grid (L ≥ 2n); their inverse FFT
    gives the autocorrelations R at integer lags (:func:`_windowed_expectation_acf`). Returns (..., n, n).
    """
    L = spectra.shape[-1]
    return _windowed_expectation_acf(scipy.fft.irfft2(spectra[..., : L // 2 + 1], s=(L, L)), n)


def _windowed_expectation_acf(acf, n):
    """Expected periodograms of n×n Hann windows from autocorrelations ``acf`` (..., L, L) at lags mod L.

    R is multiplied by the window's autocorrelation r_w (|τ| < n, exact) and folded modulo n:
    E|Σ_x w(x) f(x) e^{-iω_k·x}|² = Σ_τ r_w(τ) R(τ) e^{-iω_k·τ} at ω_k = 2πk/n.
    """
    L = acf.shape[-1]
    pad = np.zeros((2 * n, 2 * n))
    pad[:n, :n] = hann_window(n)
    rw = np.real(scipy.fft.ifft2(np.abs(scipy.fft.fft2(pad)) ** 2))  # r_w at lags mod 2n; 0 at |τ| = n
    lag = np.concatenate([np.arange(0, n + 1), np.arange(-n + 1, 0)])  # circular order mod 2n
    c = rw * acf[..., (lag % L)[:, None], (lag % L)[None, :]]
    folded = c[..., :n, :] + c[..., n:, :]
    folded = folded[..., :, :n] + folded[..., :, n:]
    return np.real(scipy.fft.fft2(folded))


@functools.lru_cache(maxsize=8)
def _acf_tables(psf, grid, L):
    """Autocorrelations at integer lags (mod L) of the model's gradient fields: signal (G, L, L) per σ, noise (L, L).

    Signal: DTFT |H_σ|²·Q (Q = (|Dx|² + |Dy|²)/|ω|², the forward-difference gradient of a 1/|ω|²
    texture); noise: |Dx|² + |Dy|² (the gradient of unit white noise). Shared by every window size.
    """
    w = 2 * np.pi * np.fft.fftfreq(L)
    wx, wy = w[None, : L // 2 + 1], w[:, None]  # the half plane of a real inverse FFT
    d2 = 4 * np.sin(wx / 2) ** 2 + 4 * np.sin(wy / 2) ** 2  # |Dx|² + |Dy|² of forward differences
    w2 = wx ** 2 + wy ** 2
    q = np.where(w2 > 0, d2 / np.where(w2 > 0, w2, 1.0), 1.0)
    spectra = np.stack([q * _transfer_sq(psf, s, wx, wy) for s in grid])
    return scipy.fft.irfft2(spectra, s=(L, L)), scipy.fft.irfft2(d2, s=(L, L))


@functools.lru_cache(maxsize=64)
def model_tables(n, psf, grid):
    """Ring-summed expected periodograms of an n×n window: signal (G, B) per unit s, noise (B,) per unit v.

    Returns (A, dA, N, kappa): A[g, b] the expected ring-b power of the gradient of a blurred
    1/|ω|² texture (s = 1) for σ = grid[g]; dA its σ-derivative (central differences); N[b] that of
    unit white noise; kappa[b] the effective Gamma shape of the ring sum (bins / window variance
    inflation).
    """
    grid_arr = np.asarray(grid)
    L = 128 if 2 * n <= 128 else 256 * (-(-2 * n // 256))  # ≥ 2n; R(τ ≥ 64) < 1e-3 R(0) at σ ≤ 12
    acf, acf_noise = _acf_tables(psf, grid, L)
    onehot = ring_matrix(n).astype(np.float64)
    A = _windowed_expectation_acf(acf, n).reshape(len(grid), -1) @ onehot
    dA = np.gradient(A, grid_arr, axis=0)
    N = _windowed_expectation_acf(acf_noise, n).ravel() @ onehot
    win = hann_window(n)
    inflation = n * n * np.sum(win ** 4) / np.sum(win ** 2) ** 2
    kappa = onehot.sum(0) / inflation
    return A, dA, N, kappa

@functools.lru_cache(maxsize=16)
def ring_matrix(n):
    ring, n_rings = _rings(n)
    keep = ring > 0
    onehot = np.zeros((n * n, n_rings - 1), dtype=np.float32)
    onehot[np.flatnonzero(keep), ring[keep] - 1] = 1.0
    return onehot
