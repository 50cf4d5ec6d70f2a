"""Signal-dependent sensor noise: variance a·x + b in linear light, estimated per intensity level.

A camera's raw noise is Poisson–Gaussian (Foi et al., "Practical Poissonian-Gaussian noise modeling
and fitting for single-image raw-data", IEEE TIP 17(10), 2008): a signal x in linear light [0, 1] has
noise variance a·x + b (a: shot-noise gain, b: read-noise variance). A tone curve y = encode(x)
rescales it: to first order the encoded values have variance (a·x + b) / decode′(y)².

This module estimates (a, b) from one image (:func:`estimate_noise_levels`), gives the per-pixel
variance in the light a stage measures (:func:`noise_variance`) and the map the edge detector's
thresholds (Eq. 9) and the checked fit's residual test read (:func:`noise_variance_map`).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage, optimize

from ..luma import LIGHTS, decode_slope, light_of, to_light
from .image_noise import block_energies, estimate_noise_variance, noise_quantile_bias

__all__ = ["NOISE_LEVEL_BINS", "display_curve", "estimate_noise_levels", "noise_variance", "noise_variance_map"]

#: Intensity bins (equal width in the light measured) of :func:`estimate_noise_levels`.
NOISE_LEVEL_BINS = 16
#: Fewest 8×8 blocks for a bin's variance estimate.
_MIN_BLOCKS = 12
#: A bin whose estimate exceeds the fitted line by this factor is texture, not noise, and is refitted without.
_OUTLIER_FACTOR = 1.5
#: σ (px) of the smoothing that gives the signal level at each pixel, and of the variance map itself.
_LEVEL_SIGMA = 1.0
_MAP_SIGMA = 2.0
#: Levels of the grid on which :func:`noise_variance` evaluates a tone curve for a whole image.
_LUT_SIZE = 4097
#: Smallest variance of the map, image units² (keeps Eq. 9's thresholds positive on a noise-free image).
_MIN_VARIANCE = 1e-12


def display_curve(encoding: str) -> str:
    """The tone curve (key of :data:`method.luma.ENCODINGS`) of the display light of an input of ``encoding``.

    An input in display light is measured in its own encoding; a linear one is sRGB-encoded for
    display (:func:`method.luma.to_light`), so its display values follow "srgb".
    """
    return encoding if light_of(encoding) == "display" else "srgb"


def noise_variance(level, a: float, b: float, *, light: str, encoding: str = "srgb") -> np.ndarray:
    """Noise variance at signal ``level`` in ``light`` of a sensor with linear-light variance a·x + b.

    Parameters
    ----------
    level : ndarray or float, any shape
        Noise-free signal in ``light``, [0, 1] (clipped).
    a, b : float
        Shot-noise gain and read-noise variance of the linear signal, image units (≥ 0).
    light : str
        Key of :data:`method.luma.LIGHTS`: "linear" (the level is x) or "display" (the level is
        y = encode(x) with the tone curve of ``encoding``).
    encoding : str, keyword-only
        The input's encoding (key of :data:`method.luma.ENCODINGS`); its display curve
        (:func:`display_curve`) is the one of ``light="display"``.

    Returns
    -------
    ndarray, same shape, float64
        Variance in ``light``, image units²: a·x + b in linear light; (a·decode(y) + b) / decode′(y)²
        in display light (for more than 4097 values, interpolated linearly from a grid of 4097 levels).
    """
    LIGHTS.check(light, what="light")
    y = np.clip(np.asarray(level, dtype=np.float64), 0.0, 1.0)
    if light == "linear":
        return a * y + b
    curve = display_curve(encoding)
    if y.size > _LUT_SIZE:  # a whole image: the curve once on a grid (colour-science per pixel is slow)
        grid = np.linspace(0.0, 1.0, _LUT_SIZE)
        return np.interp(y, grid, noise_variance(grid, a, b, light=light, encoding=encoding))
    return (a * to_light(y, "linear", encoding=curve) + b) / decode_slope(y, curve) ** 2


def _bin_variances(gray, bins):
    """(level, variance, count) per intensity bin of the 8×8 blocks' 10 % energy quantile."""
    energy, level = block_energies(gray)
    bias = 36.0 * noise_quantile_bias()
    idx = np.minimum((level * bins).astype(int), bins - 1)
    out = []
    for k in range(bins):
        sel = idx == k
        if np.count_nonzero(sel) >= _MIN_BLOCKS:
            q = float(np.quantile(energy[sel], 0.1))
            quiet = sel & (energy <= q)  # the level of the blocks that set the quantile
            out.append((float(np.mean(level[quiet])), q / bias, int(np.count_nonzero(sel))))
    return np.array(out, dtype=np.float64).reshape(-1, 3)


def _line_fit(x, v, n):
    """Non-negative (a, b) of v ≈ a·x + b, weighted by the bins' relative errors (√n / v), outliers dropped."""
    keep = np.ones(x.size, dtype=bool)
    a = b = 0.0
    for _ in range(4):
        w = np.sqrt(n[keep]) / v[keep]
        (a, b), _ = optimize.nnls(np.column_stack([x[keep], np.ones(keep.sum())]) * w[:, None], v[keep] * w)
        fit = a * x + b
        new = v <= _OUTLIER_FACTOR * np.maximum(fit, _MIN_VARIANCE)
        if np.array_equal(new, keep) or new.sum() < 2:
            break
        keep = new
    return float(a), float(b)


def estimate_noise_levels(gray, *, light: str = "linear", encoding: str = "srgb") -> tuple[float, float]:
    """Poisson–Gaussian levels (a, b) of an image's noise, variance a·x + b in linear light (Foi et al. 2008).

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        The image in ``light`` (the luminance a stage measures).
    light : str, keyword-only
        Key of :data:`method.luma.LIGHTS`: the light ``gray`` is in.
    encoding : str, keyword-only
        The input's encoding: its display curve (:func:`display_curve`) maps display values to
        linear light.

    Returns
    -------
    (float, float)
        a ≥ 0 (linear units) and b ≥ 0 (linear units²). With fewer than two usable intensity bins,
        a = 0 and b = the image's single white-noise variance
        (:func:`method.blur.image_noise.estimate_noise_variance`, 8-bit floor off) taken to linear
        light at the median level.

    Notes
    -----
    1. Local estimates: the 3×3 second-difference response (zero on any linear ramp) over 8×8
       blocks, each block's mean squared response and mean level.
    2. Per intensity bin (:data:`NOISE_LEVEL_BINS` equal bins of ``light``, ≥ 12 blocks): the
       10 % quantile of the block energies over that of unit white noise (the smooth blocks; texture
       only raises energies), as :func:`~method.blur.image_noise.estimate_noise_variance` does for
       the whole image.
    3. Bins whose level ± 3 noise std leaves [0, 1] are dropped (clipping truncates the noise).
    4. Each bin's variance is taken to linear light, × decode′(y)² (display light), at the
       linear level x = decode(y).
    5. A non-negative weighted line fit v = a·x + b (weights √n / v: each estimate's relative error
       falls as 1/√n), refitted without the bins more than 1.5× above the line (texture).
    """
    g = np.asarray(gray, dtype=np.float64)
    LIGHTS.check(light, what="light")
    curve = display_curve(encoding)
    table = _bin_variances(g, NOISE_LEVEL_BINS) if min(g.shape) >= 10 else np.zeros((0, 3))
    y, v, n = table.T
    sd = np.sqrt(v)
    ok = (y - 3 * sd > 0) & (y + 3 * sd < 1) & (v > 0)
    y, v, n = y[ok], v[ok], n[ok]
    if light == "display":
        v = v * decode_slope(y, curve) ** 2
        y = to_light(y, "linear", encoding=curve)
    if y.size >= 2:
        return _line_fit(y, v, n)
    level = float(np.median(g)) if g.size else 0.5
    v0 = estimate_noise_variance(g, bits=None)
    scale = decode_slope(level, curve) ** 2 if light == "display" else 1.0
    return 0.0, float(v0 * scale)


def noise_variance_map(gray, params, *, encoding: str = "srgb"):
    """Per-pixel noise variance of the luminance a stage measures, or None for the constant model.

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        Luminance in ``params.measure_light`` (what the edge detector and the blur fit read).
    params : DefocusParams or EdgeParams
        Reads ``noise_model`` ("constant": None is returned, every stage uses ``noise_std``;
        "signal_dependent": this map), ``noise_a``, ``noise_b`` (linear-light levels; None:
        estimated from ``gray``, :func:`estimate_noise_levels`) and ``measure_light``.
    encoding : str, keyword-only
        The input's encoding (key of :data:`method.luma.ENCODINGS`).

    Returns
    -------
    ndarray, HxW, float64, or None
        Variance, image units² of ``measure_light``, ≥ 1e-12.

    Notes
    -----
    The signal level at each pixel is the image smoothed with a Gaussian of σ 1 px; its variance
    (:func:`noise_variance`) is smoothed with σ 2 px, the reach of the finest derivative filters, so
    a pixel beside a step sees the noise of both sides.
    """
    if params.noise_model == "constant":
        return None
    g = np.asarray(gray, dtype=np.float64)
    light = params.measure_light
    if params.noise_a is None:
        a, b = estimate_noise_levels(g, light=light, encoding=encoding)
    else:
        a, b = float(params.noise_a), float(params.noise_b)
    if light == "linear":  # the variance is linear in the level: one Gaussian of σ √(1² + 2²) px
        v = noise_variance(ndimage.gaussian_filter(g, np.hypot(_LEVEL_SIGMA, _MAP_SIGMA), mode="nearest"), a, b,
                           light=light)
    else:
        level = ndimage.gaussian_filter(g, _LEVEL_SIGMA, mode="nearest")
        v = ndimage.gaussian_filter(noise_variance(level, a, b, light=light, encoding=encoding), _MAP_SIGMA,
                                    mode="nearest")
    return np.maximum(v, _MIN_VARIANCE)
