"""Highlight recovery for display-encoded photos (of :mod:`repro.photo_io`): an inverse tone curve that
gives clipped highlights back some of the light the 8/16-bit file lost, and its exact inverse.

A camera's file stores display values clipped at 1: a specular point many times brighter than white
is stored as 1, so a lens blur of its sRGB-decoded value spreads the light of a white pixel only and
the point fades into a dim grey disk instead of blooming. :func:`expand_highlights` maps display
values to linear light with the sRGB decoding of colour-science (IEC 61966-2-1) times a smooth boost
that is 1 up to the knee and reaches ``gain`` at 1:

    L(v) = srgb_decode(v) · (1 + (gain − 1)·s(t)),   t = clip((v − knee) / (1 − knee), 0, 1),
    s(t) = 3t² − 2t³ (smoothstep: the curve and its slope are continuous at the knee, no visible seam).

L is strictly increasing on [0, 1] (a product of two increasing positive factors), so
:func:`compress_highlights` inverts it exactly (tabulated, linear interpolation) and maps linear light
above L(1) = gain to display white. Each channel is mapped on its own. Both directions interpolate the
curve tabulated at every 16-bit code value (exact at the codes of 8- and 16-bit files) and its inverse
tabulated on 2²⁰ uniformly spaced linear values.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["DEFAULT_HIGHLIGHT_GAIN", "HIGHLIGHT_KNEE", "compress_highlights", "expand_highlights"]

#: Linear light of a display value of 1 after expansion, in units of display white (``--highlights``'s default).
DEFAULT_HIGHLIGHT_GAIN = 8.0
#: Display value at which the boost starts (values at or below it are only sRGB-decoded).
HIGHLIGHT_KNEE = 0.9
#: Samples of the tabulated curve (display values k / (N − 1): every 16-bit code) and of its inverse
#: (linear light uniformly spaced in [0, gain]).
_TABLE_SAMPLES = 65536
_INVERSE_SAMPLES = 2**20


def _check(gain, knee) -> tuple[float, float]:
    gain, knee = float(gain), float(knee)
    if not (np.isfinite(gain) and gain >= 1.0):
        raise ValueError(f"gain={gain!r} is invalid; allowed: a finite number >= 1 (1 = no highlight recovery)")
    if not 0.0 <= knee < 1.0:
        raise ValueError(f"knee={knee!r} is invalid; allowed: 0 <= knee < 1")
    return gain, knee


@functools.lru_cache(maxsize=8)
def _tables(gain, knee) -> tuple[np.ndarray, np.ndarray]:
    """(L at display values k / (N − 1), v at linear light gain · j / (M − 1)): the curve and its inverse."""
    import colour

    v = np.linspace(0.0, 1.0, _TABLE_SAMPLES)
    t = np.clip((v - knee) / (1.0 - knee), 0.0, 1.0)
    curve = colour.cctf_decoding(v, function="sRGB") * (1.0 + (gain - 1.0) * t * t * (3.0 - 2.0 * t))
    return curve, np.interp(np.linspace(0.0, gain, _INVERSE_SAMPLES), curve, v)


def _lookup(x, top, table) -> np.ndarray:
    """Linear interpolation of ``table`` (samples of [0, top], uniformly spaced) at x, clamped to its ends."""
    pos = np.clip(np.asarray(x, dtype=np.float64) * ((len(table) - 1) / top), 0.0, len(table) - 1)
    i = np.minimum(pos.astype(np.intp), len(table) - 2)
    pos -= i
    return table[i] * (1.0 - pos) + table[i + 1] * pos


def expand_highlights(image, *, gain=DEFAULT_HIGHLIGHT_GAIN, knee=HIGHLIGHT_KNEE) -> np.ndarray:
    """Display values → linear light with the clipped highlights expanded.

    Parameters
    ----------
    image : ndarray, any shape, float in [0, 1]
        sRGB-encoded display values (values outside [0, 1] are clipped first).
    gain : float, keyword-only
        Linear light of a display value of 1, in units of display white; ≥ 1 (1: plain sRGB decoding).
    knee : float, keyword-only
        Display value where the boost starts, in [0, 1).

    Returns
    -------
    ndarray, same shape, float64, in [0, gain]
        Linear light (module docstring: L(v)); values outside [0, 1] map to L(0) = 0 and L(1) = gain.

    Raises
    ------
    ValueError
        ``gain`` < 1 or not finite; ``knee`` outside [0, 1).
    """
    gain, knee = _check(gain, knee)
    return _lookup(image, 1.0, _tables(gain, knee)[0])


def compress_highlights(linear, *, gain=DEFAULT_HIGHLIGHT_GAIN, knee=HIGHLIGHT_KNEE) -> np.ndarray:
    """Linear light → display values, the inverse of :func:`expand_highlights` (same ``gain``, ``knee``).

    Parameters
    ----------
    linear : ndarray, any shape, float ≥ 0
        Linear light in units of display white.
    gain, knee : float, keyword-only
        As given to :func:`expand_highlights`.

    Returns
    -------
    ndarray, same shape, float64 in [0, 1]
        v with L(v) = ``linear`` (1 where ``linear`` ≥ gain, 0 where ≤ 0); round-trip error ≤ 1e-6.
    """
    gain, knee = _check(gain, knee)
    return _lookup(linear, gain, _tables(gain, knee)[1])
