"""Argument checks, seeds and the image degradation shared by the analytic test images."""

from __future__ import annotations

import numpy as np

__all__ = ["degrade"]


def check_shape(shape):
    try:
        h, w = (int(v) for v in shape)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"shape={shape!r} is invalid; allowed: (H, W) with H, W >= 3") from exc
    if h < 3 or w < 3:
        raise ValueError(f"shape={shape!r} is invalid; allowed: (H, W) with H, W >= 3")
    return h, w


def check_levels(low, high):
    if not (0.0 <= low <= 1.0 and 0.0 <= high <= 1.0 and low != high):
        raise ValueError(f"low={low!r}, high={high!r} invalid; allowed: distinct values in [0, 1]")


def check_sigma(sigma):
    s = float(sigma)
    if not (s >= 0 and np.isfinite(s)):
        raise ValueError(f"sigma={sigma!r} is invalid; allowed: finite σ >= 0 px")
    return s


def degrade(image, *, noise_std=0.0, quantize_bits=None, rng=None):
    """Add Gaussian noise and/or quantise an image (then clip to [0, 1]).

    Parameters
    ----------
    image : ndarray
        Float image in [0, 1].
    noise_std : float, keyword-only
        Standard deviation of additive white Gaussian noise, image units (e.g. 2/255).
    quantize_bits : int or None, keyword-only
        Round to ``2**bits − 1`` levels (8 → 8-bit). None: no quantisation.
    rng : numpy.random.Generator or int or None, keyword-only
        Generator or seed (required for reproducible noise; default seed 0).

    Returns
    -------
    ndarray
        Degraded float64 image in [0, 1].
    """
    out = np.array(image, dtype=np.float64)
    if noise_std < 0:
        raise ValueError(f"noise_std={noise_std!r} is invalid; allowed: >= 0")
    if noise_std > 0:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
        out = out + gen.normal(0.0, noise_std, size=out.shape)
    out = np.clip(out, 0.0, 1.0)
    if quantize_bits is not None:
        bits = int(quantize_bits)
        if not 1 <= bits <= 16:
            raise ValueError(f"quantize_bits={quantize_bits!r} is invalid; allowed: 1..16 or None")
        levels = 2 ** bits - 1
        out = np.round(out * levels) / levels
    return out


def seed_entropy(rng, name="rng"):
    """A non-negative integer seed from a Generator, an int seed or None (seed 0)."""
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(0, 2 ** 63))
    if rng is None:
        return 0
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, (int, np.integer)) or rng < 0:
        raise ValueError(f"{name}={rng!r} is invalid; allowed: an int seed >= 0, a numpy Generator or None")
    return int(rng)


def check_supersample(supersample):
    if isinstance(supersample, (bool, np.bool_)) or not isinstance(supersample, (int, np.integer)) \
            or not 1 <= supersample <= 16:
        raise ValueError(f"supersample={supersample!r} is invalid; allowed: an int in 1..16")
    return int(supersample)


def check_radius_range(radius_range, supersample):
    try:
        r_min, r_max = (float(v) for v in radius_range)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"radius_range={radius_range!r} is invalid; allowed: (r_min, r_max) px with "
                         f"1/supersample <= r_min <= r_max <= 512") from exc
    if not (np.isfinite(r_min) and np.isfinite(r_max) and 1.0 / supersample <= r_min <= r_max <= 512.0):
        raise ValueError(f"radius_range={radius_range!r} is invalid; allowed: (r_min, r_max) px with "
                         f"1/supersample <= r_min <= r_max <= 512")
    return r_min, r_max


def check_value_range(value_range):
    bad = f"value_range={value_range!r} is invalid; allowed: (lo, hi) with 0 <= lo < hi <= 1"
    try:
        lo, hi = (float(v) for v in value_range)
    except (TypeError, ValueError) as exc:
        raise ValueError(bad) from exc
    if not 0.0 <= lo < hi <= 1.0:
        raise ValueError(bad)
    return lo, hi


def check_n_levels(n_levels):
    if n_levels is None:
        return None
    if isinstance(n_levels, (bool, np.bool_)) or not isinstance(n_levels, (int, np.integer)) or n_levels < 2:
        raise ValueError(f"n_levels={n_levels!r} is invalid; allowed: None or an int >= 2")
    return int(n_levels)


def check_bool(value, name):
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}={value!r} is invalid; allowed: True, False")
    return bool(value)


def check_sigmas(sigmas):
    bad = f"sigmas={sigmas!r} is invalid; allowed: a non-empty sequence of finite σ >= 0 px"
    try:
        vals = tuple(float(v) for v in sigmas)
    except (TypeError, ValueError) as exc:
        raise ValueError(bad) from exc
    if not vals or not all(np.isfinite(v) and v >= 0 for v in vals):
        raise ValueError(bad)
    return vals


def check_int(value, name, minimum):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}={value!r} is invalid; allowed: an int >= {minimum}")
    return int(value)


def check_band(boundary_band):
    """``boundary_band`` as a float (None stays None); ValueError unless finite and >= 0 px."""
    if boundary_band is None:
        return None
    bad_band = f"boundary_band={boundary_band!r} is invalid; allowed: None or a finite band >= 0 px"
    try:
        band_val = float(boundary_band)
    except (TypeError, ValueError) as exc:
        raise ValueError(bad_band) from exc
    if not (np.isfinite(band_val) and band_val >= 0):
        raise ValueError(bad_band)
    return band_val


def check_degrade(noise_std, quantize_bits):
    """ValueError unless ``noise_std`` >= 0 and ``quantize_bits`` is None or 1..16 (see :func:`degrade`)."""
    if not noise_std >= 0:
        raise ValueError(f"noise_std={noise_std!r} is invalid; allowed: >= 0")
    if quantize_bits is not None and not 1 <= int(quantize_bits) <= 16:
        raise ValueError(f"quantize_bits={quantize_bits!r} is invalid; allowed: 1..16 or None")
