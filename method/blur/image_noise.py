"""White-noise variance of an image from its quietest blocks (the region estimators' noise model)."""

from __future__ import annotations

import functools

import numba
import numpy as np

__all__ = ["block_energies", "estimate_noise_variance", "noise_quantile_bias"]


#: 3×3 high-pass of the noise estimate (second differences in x and y): its response to white
#: noise of variance v has variance 36·v, and it is 0 on any linear ramp.
_NOISE_MASK = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
#: Block side (px) and quantile of the block energies of the noise estimate.
_NOISE_BLOCK = 8
_NOISE_QUANTILE = 0.1


def _second_differences(g):
    """The 3×3 :data:`_NOISE_MASK` response on the valid (H − 2)×(W − 2) pixels, float64."""
    g = np.asarray(g, dtype=np.float64)
    if g.shape[0] < 3 or g.shape[1] < 3:
        return np.zeros((max(g.shape[0] - 2, 0), max(g.shape[1] - 2, 0)))
    return _second_differences_kernel(g)


@numba.njit(cache=True, nogil=True)
def _second_differences_kernel(g):
    """The sum of the nine shifted images, one pass: the same roundings in the same order as NumPy's
    ``g[:-2, :-2] - 2 * g[:-2, 1:-1] + g[:-2, 2:] - 2 * g[1:-1, :-2] + 4 * g[1:-1, 1:-1] - ...`` (left to
    right, each product exact), so the same bytes without its sixteen temporaries."""
    h, w = g.shape[0] - 2, g.shape[1] - 2
    out = np.empty((h, w))
    for i in range(h):
        for j in range(w):
            t = g[i, j] - 2.0 * g[i, j + 1]
            t = t + g[i, j + 2]
            t = t - 2.0 * g[i + 1, j]
            t = t + 4.0 * g[i + 1, j + 1]
            t = t - 2.0 * g[i + 1, j + 2]
            t = t + g[i + 2, j]
            t = t - 2.0 * g[i + 2, j + 1]
            out[i, j] = t + g[i + 2, j + 2]
    return out


def _block_energy_quantile(g):
    h = _second_differences(g)
    b = _NOISE_BLOCK
    hh, ww = (h.shape[0] // b) * b, (h.shape[1] // b) * b
    if hh == 0 or ww == 0:
        return float(np.mean(h ** 2)) if h.size else 0.0
    e = (h[:hh, :ww] ** 2).reshape(hh // b, b, ww // b, b).mean(axis=(1, 3))
    return float(np.quantile(e, _NOISE_QUANTILE))


def block_energies(gray):
    """Mean squared 3×3 second-difference response and mean level of each 8×8 block.

    Parameters
    ----------
    gray : ndarray, HxW, float
        Image in [0, 1], sides ≥ 10 px.

    Returns
    -------
    energy : ndarray, (n,), float64
        Mean squared response per block, image units² (36·v on white noise of variance v).
    level : ndarray, (n,), float64
        Mean of the image over the block (its signal level), image units.
    """
    g = np.asarray(gray, dtype=np.float64)
    h = _second_differences(g)
    m = g[1:-1, 1:-1]
    b = _NOISE_BLOCK
    hh, ww = (h.shape[0] // b) * b, (h.shape[1] // b) * b

    def blocks(a):
        return a[:hh, :ww].reshape(hh // b, b, ww // b, b).mean(axis=(1, 3)).ravel()

    return blocks(h ** 2), blocks(m)


def noise_quantile_bias() -> float:
    """10 % quantile of the 8×8 block energies of unit white noise, / 36 (:func:`block_energies`)."""
    return _noise_quantile_bias()


@functools.lru_cache(maxsize=1)
def _noise_quantile_bias():
    """Block-energy quantile of unit white noise / 36 (a seeded 256² noise image; measured once)."""
    z = np.random.default_rng(12345).standard_normal((258, 258))
    return _block_energy_quantile(z) / 36.0


def estimate_noise_variance(gray, *, bits=8):
    """White-noise variance of an image from its quietest blocks of second differences, image units².

    Parameters
    ----------
    gray : ndarray, HxW, float
        Image in [0, 1].
    bits : int or None, keyword-only
        Bit depth of the data: the variance is at least LSB²/12 of that quantisation (None: no floor).

    Returns
    -------
    float
        max(q₁₀ / (36·b), LSB²/12): q₁₀ the 10 % quantile of the mean squared 3×3 second-difference
        response over 8×8 blocks, b the same quantile's value for unit white noise (so pure white
        noise gives its variance); texture raises few of the quietest blocks.
    """
    g = np.asarray(gray, dtype=np.float64)
    if min(g.shape) < 3:
        v = 0.0
    else:
        v = _block_energy_quantile(g) / (36.0 * _noise_quantile_bias())
    floor = (1.0 / (2 ** bits - 1)) ** 2 / 12.0 if bits else 0.0
    return float(max(v, floor))
