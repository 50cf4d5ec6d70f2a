"""Highlight recovery for display-encoded photos (of :mod:`repro.photo_io`): an inverse tone curve that
gives clipped highlights back some of the light the 8/16-bit file lost, and its exact inverse.

A camera's file stores display values clipped at 1: a specular point many times brighter than white
is stored as 1, so a lens blur of its decoded value spreads the light of a white pixel only and the
point fades into a dim grey disk instead of blooming. :func:`expand_highlights` maps display values
to linear light with the photo's tone curve (``encoding``, a key of :data:`method.luma.ENCODINGS`:
its ``decode``, :func:`method.luma.decode`) times a smooth boost that is 1 up to the knee and reaches
``gain`` at 1:

    L(v) = decode(v) · (1 + (gain − 1)·s(t)),   t = clip((v − knee) / (1 − knee), 0, 1),
    s(t) = 3t² − 2t³ (smoothstep: the curve and its slope are continuous at the knee, no visible seam).

Every registered curve decodes 1 to 1, so L(1) = gain whatever the curve. L is strictly increasing on
[0, 1] (a product of two increasing positive factors), so :func:`compress_highlights` inverts it
exactly: at or below L(knee) by the curve's own ``encode`` (:func:`method.luma.encode`), above it by
interpolating L tabulated for that curve, gain and knee (2¹⁸ display values uniformly spaced in
[knee, 1]; linear interpolation in linear light, so the inverse's error does not grow with the
slope of the boost); linear light above L(1) = gain maps to display white. Each
channel is mapped on its own. ``"auto"`` is not a curve: resolve it first (the curve the estimator
chose, ``DefocusResult.encoding``; :func:`method.edges.tone_curve.resolve_encoding`).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["DEFAULT_HIGHLIGHT_GAIN", "HIGHLIGHT_KNEE", "compress_highlights", "expand_highlights"]

#: Linear light of a display value of 1 after expansion, in units of display white (``--highlights``'s default).
DEFAULT_HIGHLIGHT_GAIN = 8.0
#: Display value at which the boost starts (values at or below it are only decoded by the photo's curve).
HIGHLIGHT_KNEE = 0.9
#: Samples of the curve above the knee that :func:`compress_highlights` interpolates (display values
#: uniformly spaced in [knee, 1]).
_CURVE_SAMPLES = 2**18


def _check(gain, knee, encoding) -> tuple[float, float, str]:
    from method.luma import ENCODINGS

    gain, knee = float(gain), float(knee)
    if not (np.isfinite(gain) and gain >= 1.0):
        raise ValueError(f"gain={gain!r} is invalid; allowed: a finite number >= 1 (1 = no highlight recovery)")
    if not 0.0 <= knee < 1.0:
        raise ValueError(f"knee={knee!r} is invalid; allowed: 0 <= knee < 1")
    return gain, knee, ENCODINGS.check(encoding, what="encoding")


def _curve(v, gain, knee, encoding) -> np.ndarray:
    """L(v) of the module docstring (v in [0, 1], float64)."""
    from method.luma import decode

    t = np.clip((v - knee) / (1.0 - knee), 0.0, 1.0)
    return decode(v, encoding) * (1.0 + (gain - 1.0) * t * t * (3.0 - 2.0 * t))


@functools.lru_cache(maxsize=16)
def _inverse_table(gain, knee, encoding) -> tuple[np.ndarray, np.ndarray]:
    """(L at display values v_j, v_j) for v_j uniformly spaced in [knee, 1]: the curve above the knee, increasing."""
    v = np.linspace(knee, 1.0, _CURVE_SAMPLES)
    return _curve(v, gain, knee, encoding), v


def expand_highlights(image, *, gain=DEFAULT_HIGHLIGHT_GAIN, knee=HIGHLIGHT_KNEE, encoding="srgb") -> np.ndarray:
    """Display values → linear light with the clipped highlights expanded.

    Parameters
    ----------
    image : ndarray, any shape, float in [0, 1]
        Display values under the tone curve ``encoding`` (values outside [0, 1] are clipped first).
    gain : float, keyword-only
        Linear light of a display value of 1, in units of display white; ≥ 1 (1: the curve's plain decoding).
    knee : float, keyword-only
        Display value where the boost starts, in [0, 1).
    encoding : str, keyword-only
        The photo's tone curve, a key of :data:`method.luma.ENCODINGS` (default "srgb").

    Returns
    -------
    ndarray, same shape, float64, in [0, gain]
        Linear light (module docstring: L(v)); values outside [0, 1] map to L(0) = 0 and L(1) = gain.

    Raises
    ------
    ValueError
        ``gain`` < 1 or not finite; ``knee`` outside [0, 1); ``encoding`` not a registered curve ("auto" included).
    """
    gain, knee, encoding = _check(gain, knee, encoding)
    return _curve(np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0), gain, knee, encoding)


def compress_highlights(linear, *, gain=DEFAULT_HIGHLIGHT_GAIN, knee=HIGHLIGHT_KNEE, encoding="srgb") -> np.ndarray:
    """Linear light → display values, the inverse of :func:`expand_highlights` (same ``gain``, ``knee``, ``encoding``).

    Parameters
    ----------
    linear : ndarray, any shape, float ≥ 0
        Linear light in units of display white.
    gain, knee, encoding : keyword-only
        As given to :func:`expand_highlights`.

    Returns
    -------
    ndarray, same shape, float64 in [0, 1]
        v with L(v) = ``linear`` (1 where ``linear`` ≥ gain, 0 where ≤ 0): the curve's ``encode`` at or
        below L(knee), the tabulated inverse above. Round-trip error |compress(expand(v)) − v| ≤ 1e-9
        for gains up to 100 on every registered curve (``tests/test_magnify_highlights.py`` states the measure).

    Raises
    ------
    ValueError
        As :func:`expand_highlights`.
    """
    from method.luma import encode

    gain, knee, encoding = _check(gain, knee, encoding)
    x = np.asarray(linear, dtype=np.float64)
    curve, v = _inverse_table(gain, knee, encoding)
    high = x > curve[0]
    out = np.empty(x.shape)
    out[~high] = encode(x[~high], encoding)
    out[high] = np.interp(x[high], curve, v)  # 1 above L(1) = gain
    return out
