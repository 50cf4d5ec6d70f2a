"""The noise's power spectrum per octave band, from the image's quietest blocks at each level of a pyramid.

Resizing, demosaicking, JPEG and a renderer's pixel filter correlate neighbouring pixels' noise: the
pixel-scale second difference (:func:`method.blur.image_noise.block_energies`) then reads a variance
far below the one the detector's filters see at their scales (a 2× bilinear upsampling of white noise:
≈ 1/1000 of it at σ 8 px). Eq. (9) needs the variance of each filter's response, so the spectrum
is measured where those filters look: the same 3×3 second difference on 2×2 area-averaged copies of
the image (each level an octave lower), each level's 10 % block-energy quantile over that of white
noise; white noise reads the same variance at every level (an area average of white noise is
white), correlated noise reads more at the coarse levels.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import optimize

from ..edges.noise_thresholds import NoiseSpectrum, band_shares, radial_frequency
from .image_noise import block_energies, noise_quantile_bias

__all__ = ["SPECTRUM_LEVELS", "estimate_noise_spectrum", "noise_spectrum_of", "white_noise_spectrum"]

#: Pyramid levels measured beyond the full resolution (level L: 2^L × 2^L area means, an octave per level).
SPECTRUM_LEVELS = 1
#: Intensity bins (equal width) and fewest 8×8 blocks per bin of a level's quantile.
_BINS = 8
_MIN_BLOCKS = 16
#: Fewest blocks of a coarse level, over the bins with a ratio (a 160×120 image has 63 at level 1: too few to
#: tell its texture from its noise; white is assumed then).
_MIN_LEVEL_BLOCKS = 128
#: Quantile over the intensity bins of a level's ratio (texture only raises some bins' ratios).
_BIN_QUANTILE = 0.0
#: 10 % quantile of the block energies, as the pixel-scale estimate.
_QUANTILE = 0.1


def _area_half(g):
    h, w = (g.shape[0] // 2) * 2, (g.shape[1] // 2) * 2
    return 0.25 * (g[0:h:2, 0:w:2] + g[1:h:2, 0:w:2] + g[0:h:2, 1:w:2] + g[1:h:2, 1:w:2])


@functools.lru_cache(maxsize=SPECTRUM_LEVELS + 1)
def _level_power(level):
    """|transfer|² on the DFT grid of level ``level``'s filter: 2^L box mean, then the 3×3 mask at stride 2^L."""
    w = 2.0 * np.pi * np.fft.fftfreq(radial_frequency().shape[0])
    d = 2 ** level
    with np.errstate(invalid="ignore", divide="ignore"):
        box = np.where(np.abs(w) < 1e-12, 1.0, np.sin(d * w / 2) / (d * np.sin(w / 2))) ** 2
    mask = (2.0 - 2.0 * np.cos(d * w)) ** 2 * box
    return mask[:, None] * mask[None, :]


@functools.lru_cache(maxsize=SPECTRUM_LEVELS + 1)
def _band_edges(n_levels):
    """Band boundaries (rad/px, decreasing): geometric means of consecutive levels' centre frequencies."""
    r = radial_frequency()
    ok = r > 0
    centres = [np.exp(np.sum(p[ok] * np.log(r[ok])) / np.sum(p[ok])) for p in map(_level_power, range(n_levels))]
    return tuple(float(np.sqrt(a * b)) for a, b in zip(centres, centres[1:]))


def white_noise_spectrum() -> NoiseSpectrum:
    """The white spectrum: one band, level 1 (every :meth:`NoiseSpectrum.factor` is 1)."""
    return NoiseSpectrum(band_edges=(), levels=(1.0,))


def _quiet_energy_by_bin(g):
    """10 % block-energy quantile per intensity bin (NaN where a bin has too few blocks or may clip), and
    each bin's number of blocks."""
    energy, level = block_energies(g)
    idx = np.minimum((np.clip(level, 0.0, 1.0) * _BINS).astype(int), _BINS - 1)
    out = np.full(_BINS, np.nan)
    counts = np.bincount(idx, minlength=_BINS)
    for k in range(_BINS):
        sel = idx == k
        if counts[k] >= _MIN_BLOCKS:
            q = float(np.quantile(energy[sel], _QUANTILE))
            sd = np.sqrt(q / (36.0 * noise_quantile_bias()))
            quiet = level[sel & (energy <= q)]
            if q > 0 and quiet.min() - 3 * sd > 0 and quiet.max() + 3 * sd < 1:  # clipping truncates the noise
                out[k] = q
    return out, counts


def _level_ratios(gray):
    """Each pyramid level's reading over the full resolution's (white noise: 1), level 0 first.

    Per intensity bin (the noise depends on the level) the ratio of the levels' quiet-block
    energies × 4^L; the lowest over the bins both levels measure. Stops at the first level whose
    bins with a ratio hold fewer than :data:`_MIN_LEVEL_BLOCKS` blocks, or with under 10 px of image.
    """
    g = np.asarray(gray, dtype=np.float64)
    if min(g.shape) < 10:
        return np.ones(0)
    base, _ = _quiet_energy_by_bin(g)
    out = [1.0]
    for level in range(1, SPECTRUM_LEVELS + 1):
        g = _area_half(g)
        if min(g.shape) < 10:
            break
        energy, counts = _quiet_energy_by_bin(g)
        ratio = 4.0 ** level * energy / base
        ok = np.isfinite(ratio)
        if counts[ok].sum() < _MIN_LEVEL_BLOCKS:
            break
        ratio = ratio[ok]
        out.append(float(np.quantile(ratio, _BIN_QUANTILE)))
    return np.array(out) if np.isfinite(base).any() else np.ones(0)


def estimate_noise_spectrum(gray) -> NoiseSpectrum:
    """The image noise's power spectrum per octave band, relative to the pixel-scale variance.

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        The luminance the detector reads.

    Returns
    -------
    NoiseSpectrum
        One band per pyramid level measured (1 + :data:`SPECTRUM_LEVELS` at most), levels relative to
        the full-resolution reading (white noise: ≈ 1 in every band). White when no coarse level can be
        measured (fewer than 128 blocks of 8×8 in its usable intensity bins: images under ≈ 180² px) or
        the image reads no noise at full resolution.

    Notes
    -----
    1. Level L (0 … :data:`SPECTRUM_LEVELS`): the image averaged over 2^L × 2^L blocks; per
       intensity bin (8 equal bins, ≥ 16 blocks, bins whose quiet blocks' level ± 3 noise std leaves
       [0, 1] dropped) the 10 % quantile of the 8×8-block energies of its 3×3 second difference.
       Each level's filter (box of 2^L, then the mask at stride 2^L) passes an octave band, centred
       at 3.4 and 2.0 rad/px for L = 0, 1.
    2. Level L's reading: its quantile × 4^L over level 0's, per bin (white noise: 1, an area mean of
       white noise being white), the lowest over the bins (texture only raises a bin's ratio).
    3. Bands: split at the geometric means of consecutive levels' centre frequencies (power-weighted
       mean log |ω|), the last band held down to ω = 0; each level's reading is the band levels
       weighted by its filter's power in each band, a linear system solved for non-negative band
       levels (NNLS).
    Texture that survives in every bin's quiet blocks of a level reads as noise there: one coarse
    level only (a second one read the photos' texture as noise; docs/noise.md).
    """
    v = _level_ratios(gray)
    if v.size < 2:
        return white_noise_spectrum()
    edges = _band_edges(v.size)
    a = np.array([band_shares(_level_power(level), edges) for level in range(v.size)])
    s, _ = optimize.nnls(a, v)
    return NoiseSpectrum(band_edges=edges, levels=tuple(s))


def noise_spectrum_of(gray, params):
    """The noise spectrum the stages read: estimated from ``gray``, or None (white noise).

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        Luminance in ``params.measure_light``.
    params : DefocusParams or EdgeParams
        Reads ``noise_model`` and ``noise_spectrum``: :func:`estimate_noise_spectrum` of ``gray`` when
        they are "signal_dependent" and "estimated", else None.

    Returns
    -------
    NoiseSpectrum or None
    """
    if params.noise_model != "signal_dependent" or params.noise_spectrum == "white":
        return None
    return estimate_noise_spectrum(gray)
