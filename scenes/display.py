"""Display transform: linear rendered radiance ↔ the sRGB-encoded image a camera delivers.

Uses colour-science's sRGB transfer functions (IEC 61966-2-1); nothing hand-written.
"""

from __future__ import annotations

import numpy as np

__all__ = ["linear_to_srgb", "srgb_to_linear", "camera_image"]


def linear_to_srgb(linear):
    """Encode linear values with the sRGB transfer function (values outside [0, 1] are clipped first).

    Parameters
    ----------
    linear : ndarray, any shape
        Linear radiance-like values; 1.0 is display white.

    Returns
    -------
    ndarray, float64, same shape, in [0, 1]
    """
    import colour

    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.clip(colour.cctf_encoding(x, function="sRGB"), 0.0, 1.0)


def srgb_to_linear(encoded):
    """Decode sRGB-encoded values in [0, 1] to linear values in [0, 1]."""
    import colour

    x = np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    return np.clip(colour.cctf_decoding(x, function="sRGB"), 0.0, 1.0)


def camera_image(linear_rgb, *, exposure=1.0, quantize_bits=None, encoding="srgb"):
    """The image the method sees: exposure-scaled, clipped, encoded, optionally quantised.

    Parameters
    ----------
    linear_rgb : ndarray, HxWx3 (or HxW), float
        Linear rendered radiance.
    exposure : float, keyword-only
        Multiplier applied before clipping to [0, 1].
    quantize_bits : int or None, keyword-only
        If given (e.g. 8), round to that many bits per channel, as a JPEG/PNG would store.
    encoding : {"srgb", "linear"}, keyword-only
        ``"srgb"`` (default) as a camera JPEG would be; ``"linear"`` keeps linear values.

    Returns
    -------
    ndarray, float64, same shape, in [0, 1]
    """
    x = np.asarray(linear_rgb, dtype=np.float64) * float(exposure)
    if encoding == "srgb":
        out = linear_to_srgb(x)
    elif encoding == "linear":
        out = np.clip(x, 0.0, 1.0)
    else:
        raise ValueError(f"unknown encoding {encoding!r}; choose 'srgb' or 'linear'")
    if quantize_bits is not None:
        levels = float(2**int(quantize_bits) - 1)
        out = np.round(out * levels) / levels
    return out
