"""The camera pipeline: linear radiance → the encoded image a camera delivers (and back).

One pipeline for every synthetic or rendered image that a benchmark scores (the renders' encodings,
the lens mosaics of :mod:`scenes.analytic.lens`, the exported dataset), in the order a camera applies
it:

1. exposure (a multiplier on the linear radiance);
2. sensor noise, Poisson–Gaussian in linear units: variance a·x + b for a signal x in [0, 1] (Foi et
   al., IEEE TIP 17(10), 2008), at the named levels of :data:`NOISE_LEVELS`;
3. clipping to [0, 1] and the tone curve (:data:`ENCODINGS`: sRGB, IEC 61966-2-1, from colour-science;
   pure power laws of gamma 1.8 and 2.2; a filmic S-curve; or none);
4. quantisation to ``bits`` per channel;
5. optional JPEG compression at quality q (Pillow's encoder, 4:2:0 chroma subsampling for colour).

Facts behind the noise levels: ../shared/research/LENS-AND-CAMERA.md (Brooks et al., "Unprocessing
images for learned raw denoising", CVPR 2019: shot noise a log-uniform in [1e-4, 0.012], read noise
log b = 2.18·log a + 1.20, natural logarithms, a and b as variances of a linear [0, 1] signal).
"""

from __future__ import annotations

import io
import math
from types import MappingProxyType

import numpy as np

__all__ = ["ENCODINGS", "NOISE_LEVELS", "camera_image", "check_encoding", "check_jpeg_quality", "check_noise_level",
           "decode", "encode", "jpeg_roundtrip", "linear_to_srgb",
           "noise_parameters", "sensor_noise", "srgb_to_linear"]

#: Tone curves of :func:`camera_image` (:func:`encode`, :func:`decode`): "srgb" (as a camera JPEG,
#: IEC 61966-2-1), "linear" (no curve), "gamma1.8" and "gamma2.2" (pure power laws y = x^(1/γ), as
#: old Macintosh and many displays' nominal curves), "filmic" (a contrast S-curve: the sRGB curve after
#: the ACES filmic fit of Narkowicz 2016, :func:`_filmic_encode`). The names and formulas are
#: :data:`method.luma.ENCODINGS`' (a test checks they agree numerically).
ENCODINGS = ("srgb", "linear", "gamma1.8", "gamma2.2", "filmic")

#: Narkowicz's fit of the ACES reference rendering transform, f(x) = x(Ax + B) / (x(Cx + D) + E)
#: (K. Narkowicz, "ACES Filmic Tone Mapping Curve", 2016): a toe (slope B/E at 0) and a shoulder.
_ACES_FIT = (2.51, 0.03, 2.43, 0.59, 0.14)


def _aces_fit(x):
    a, b, c, d, e = _ACES_FIT
    return x * (a * x + b) / (x * (c * x + d) + e)


def _filmic_encode(linear):
    """The "filmic" curve: sRGB(f(x) / f(1)), f the ACES fit of :data:`_ACES_FIT`, x in [0, 1].

    f is strictly increasing on [0, ∞) (its derivative's numerator is (AD − BC)x² + 2AEx + BE > 0),
    so the curve is invertible (:func:`_filmic_decode`); normalised so that 0 → 0 and 1 → 1.
    """
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return linear_to_srgb(_aces_fit(x) / _aces_fit(1.0))


def _filmic_decode(encoded):
    """Inverse of :func:`_filmic_encode`: sRGB-decode, then the positive root of the ACES fit's quadratic.

    t = f(x) solves (A − tC)x² + (B − tD)x − tE = 0; A − tC > 0 for t ≤ f(1) < A/C.
    """
    a, b, c, d, e = _ACES_FIT
    t = srgb_to_linear(encoded) * _aces_fit(1.0)
    qa, qb = a - t * c, b - t * d
    return np.clip((-qb + np.sqrt(qb * qb + 4.0 * qa * t * e)) / (2.0 * qa), 0.0, 1.0)


def check_encoding(encoding) -> str:
    """``encoding`` if it is a key of :data:`ENCODINGS`, else ValueError naming the allowed ones."""
    if encoding not in ENCODINGS:
        raise ValueError(f"encoding={encoding!r} is invalid; allowed: {', '.join(ENCODINGS)}")
    return encoding


def encode(linear, encoding: str):
    """Linear values in [0, 1] (clipped first) → display values in [0, 1] by the tone curve ``encoding``.

    Parameters
    ----------
    linear : ndarray, any shape, float
    encoding : str
        Key of :data:`ENCODINGS`.

    Returns
    -------
    ndarray, float64, same shape, in [0, 1]
    """
    import colour

    check_encoding(encoding)
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    if encoding == "srgb":
        return linear_to_srgb(x)
    if encoding == "filmic":
        return _filmic_encode(x)
    if encoding == "linear":
        return x
    return np.clip(colour.gamma_function(x, 1.0 / float(encoding.removeprefix("gamma"))), 0.0, 1.0)


def decode(encoded, encoding: str):
    """Inverse of :func:`encode`: display values in [0, 1] (clipped first) → linear values in [0, 1]."""
    import colour

    check_encoding(encoding)
    y = np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    if encoding == "srgb":
        return srgb_to_linear(y)
    if encoding == "filmic":
        return _filmic_decode(y)
    if encoding == "linear":
        return y
    return np.clip(colour.gamma_function(y, float(encoding.removeprefix("gamma"))), 0.0, 1.0)


def _brooks_read_noise(a: float) -> float:
    """Read-noise variance b on the mean line of Brooks et al. 2019: log b = 2.18·log a + 1.20."""
    return math.exp(2.18 * math.log(a) + 1.20)


#: Named sensor noise levels → (a, b): variance a·x + b of a linear signal x in [0, 1]. The shot-noise
#: gain a is 2e-4 at ISO 100 (near the low end of Brooks et al.'s range [1e-4, 0.012]) and scales with
#: the ISO gain; b is on their mean read-noise line. Standard deviation at linear 0.2 (sRGB ≈ 0.48,
#: mid-grey): iso100 0.0063, iso800 0.018, iso3200 0.036 (≈ 1.7, 4.6 and 9.2 grey levels of 8-bit sRGB).
NOISE_LEVELS = MappingProxyType({
    "none": (0.0, 0.0),
    "iso100": (2e-4, _brooks_read_noise(2e-4)),
    "iso800": (1.6e-3, _brooks_read_noise(1.6e-3)),
    "iso3200": (6.4e-3, _brooks_read_noise(6.4e-3)),
})


def check_noise_level(noise) -> tuple[float, float]:
    """(a, b) of a noise level: a name of :data:`NOISE_LEVELS` or a pair of variances (a, b) >= 0.

    Raises
    ------
    ValueError
        An unknown name (the message lists the levels) or negative / non-finite (a, b).
    """
    if isinstance(noise, str):
        if noise not in NOISE_LEVELS:
            raise ValueError(f"noise={noise!r} is invalid (unknown noise level); allowed: "
                             f"{', '.join(NOISE_LEVELS)} or (a, b) variances >= 0")
        return NOISE_LEVELS[noise]
    try:
        a, b = (float(v) for v in noise)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"noise={noise!r} is invalid; allowed: {', '.join(NOISE_LEVELS)} "
                         "or (a, b) variances >= 0") from exc
    if not (math.isfinite(a) and math.isfinite(b) and a >= 0 and b >= 0):
        raise ValueError(f"noise={noise!r} is invalid; allowed: (a, b) finite variances >= 0 "
                         "(variance a·x + b of a linear signal x in [0, 1])")
    return a, b


def noise_parameters(noise) -> dict:
    """``{"a": a, "b": b}`` of a noise level (:func:`check_noise_level`), for metadata and tables."""
    a, b = check_noise_level(noise)
    return {"a": a, "b": b}


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


def sensor_noise(linear, noise, *, rng=None):
    """Poisson–Gaussian sensor noise on a linear signal: variance a·x + b.

    Parameters
    ----------
    linear : ndarray, any shape, float
        Linear signal x (exposure applied), nominally in [0, 1]; negative values count as 0 in the
        shot-noise term.
    noise : str or (float, float)
        A name of :data:`NOISE_LEVELS` or the variances (a, b).
    rng : numpy.random.Generator or int or None, keyword-only
        Generator or seed (None: seed 0).

    Returns
    -------
    ndarray, float64, same shape
        a·Poisson(x/a) + N(0, b) (mean x, variance a·x + b), not clipped.

    Notes
    -----
    1. Shot noise: a times a Poisson count of mean x/a (exact Poisson statistics; a = 0: none).
    2. Read noise: additive Gaussian of variance b.
    """
    a, b = check_noise_level(noise)
    x = np.asarray(linear, dtype=np.float64)
    if a == 0 and b == 0:
        return x.copy()
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
    out = a * gen.poisson(np.maximum(x, 0.0) / a) if a > 0 else x.copy()
    if b > 0:
        out = out + gen.normal(0.0, math.sqrt(b), size=x.shape)
    return out


def jpeg_roundtrip(image, quality: int):
    """Encode an 8-bit image as JPEG at ``quality`` (Pillow) and decode it again.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1] on the 8-bit grid (k/255)
    quality : int
        JPEG quality 1–100 (Pillow's scale; cameras use 75–95).

    Returns
    -------
    ndarray, same shape, float64 in [0, 1] (k/255)
    """
    from PIL import Image

    q = check_jpeg_quality(quality)
    arr = np.asarray(image, dtype=np.float64)
    u8 = np.round(np.clip(arr, 0.0, 1.0) * 255.0).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(u8).save(buf, format="JPEG", quality=q)
    buf.seek(0)
    with Image.open(buf) as im:
        out = np.asarray(im, dtype=np.float64) / 255.0
    return out.reshape(arr.shape)


def check_jpeg_quality(quality) -> int:
    """``quality`` as an int if it is a JPEG quality 1–100, else ValueError naming the range."""
    if isinstance(quality, (bool, np.bool_)) or not isinstance(quality, (int, np.integer)) or not 1 <= quality <= 100:
        raise ValueError(f"jpeg_quality={quality!r} is invalid; allowed: an integer 1..100")
    return int(quality)


def camera_image(linear_rgb, *, exposure=1.0, quantize_bits=None, encoding="srgb", noise="none", jpeg_quality=None,
                 rng=None):
    """The image the method sees: exposure, sensor noise, clipping, tone curve, quantisation, JPEG.

    Parameters
    ----------
    linear_rgb : ndarray, HxWx3 (or HxW), float
        Linear rendered radiance.
    exposure : float, keyword-only
        Multiplier applied before the noise and clipping.
    quantize_bits : int or None, keyword-only
        If given (e.g. 8), round to that many bits per channel, as a JPEG/PNG would store.
    encoding : str, keyword-only
        The tone curve, a key of :data:`ENCODINGS`: ``"srgb"`` (default) as a camera JPEG would be;
        ``"linear"`` keeps linear values; ``"gamma1.8"``, ``"gamma2.2"``, ``"filmic"`` (:func:`encode`).
    noise : str or (float, float), keyword-only
        Sensor noise level, a name of :data:`NOISE_LEVELS` (default "none") or variances (a, b).
    jpeg_quality : int or None, keyword-only
        JPEG quality 1–100 applied last (needs 8 bits: ``quantize_bits`` None or 8); None: no JPEG.
    rng : numpy.random.Generator or int or None, keyword-only
        The noise's generator or seed (None: seed 0).

    Returns
    -------
    ndarray, float64, same shape, in [0, 1]

    Raises
    ------
    ValueError
        Unknown encoding or noise level, negative noise variances, a JPEG quality outside 1–100 or
        with ``quantize_bits`` other than 8.

    Notes
    -----
    The steps of the module docstring, in that order; with ``noise="none"`` and no JPEG this is the
    deterministic exposure → clip → encode → quantise of a noise-free camera.
    """
    check_encoding(encoding)
    if jpeg_quality is not None:
        check_jpeg_quality(jpeg_quality)
        if quantize_bits not in (None, 8):
            raise ValueError(f"quantize_bits={quantize_bits!r} is invalid with jpeg_quality; allowed: 8 or None")
        quantize_bits = 8
    x = np.asarray(linear_rgb, dtype=np.float64) * float(exposure)
    x = sensor_noise(x, noise, rng=rng)
    out = encode(x, encoding)
    if quantize_bits is not None:
        levels = float(2**int(quantize_bits) - 1)
        out = np.round(out * levels) / levels
    if jpeg_quality is not None:
        out = jpeg_roundtrip(out, jpeg_quality)
    return out
