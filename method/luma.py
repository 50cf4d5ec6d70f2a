"""The input's light: what an image's values are (its encoding) and the light each stage works in.

One vocabulary across :mod:`method`, the harness and the CLIs:

* an **encoding** (:data:`ENCODINGS`) says what the values of an image *are*: ``"srgb"`` (display
  values, sRGB-encoded as a camera delivers them), ``"linear"`` (linear radiance, as a renderer or
  an OpenEXR file holds it), or display values under another tone curve (``"gamma1.8"``,
  ``"gamma2.2"``, ``"filmic"``; each entry's ``decode`` / ``encode`` hooks are its curve, the same
  names and formulas as :data:`scenes.display.ENCODINGS`);
* a **light** (:data:`LIGHTS`) is the space a stage measures or blends in: ``"display"`` (the
  sRGB-encoded values; the paper's edges, Eq. 3 and Eq. 4 all read these) or ``"linear"`` (linear
  light, in which a lens blurs). An ``"srgb"`` (or other tone-curve) image is in display light, a
  ``"linear"`` one in linear light.

:func:`to_light` converts an image from its encoding into a light (at most one transfer: the
encoding's curve decoded, or a linear image sRGB-encoded, IEC 61966-2-1 from colour-science; none
when they already agree), :func:`measure_input` gives what every
stage of :func:`method.pipeline.estimate_defocus_map` reads, and :data:`LUMA_WEIGHTS` is the one
definition of the luma weights.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .registry import Entry, Registry

__all__ = ["ENCODINGS", "LIGHTS", "LUMA_WEIGHTS", "MEASURE_LIGHTS", "MeasuredInput", "decode", "decode_slope", "encode", "light_of",
           "luminance", "measure_input", "measure_luminance", "to_light"]

#: Rec. 709 luma weights (R, G, B), applied to the RGB values in the light at hand: the edge
#: detector's input (:func:`method.pipeline.estimate_defocus_map`), the guided upsampling's guide and
#: the harness's texture mask all use these.
LUMA_WEIGHTS = (0.2126, 0.7152, 0.0722)

#: Lights a stage measures or blends in (``DefocusParams.measure_light``, the magnifier's ``light``).
LIGHTS = Registry("light", {
    "display": Entry(None, "sRGB-encoded display values (the paper's)"),
    "linear": Entry(None, "linear light: a lens blurs linear radiance"),
})

#: The lights the edge and blur stages can measure in (``DefocusParams.measure_light``): :data:`LIGHTS`.
MEASURE_LIGHTS = LIGHTS

#: Narkowicz's fit of the ACES reference rendering transform, f(x) = x(Ax + B) / (x(Cx + D) + E)
#: (K. Narkowicz, "ACES Filmic Tone Mapping Curve", 2016): the "filmic" curve's toe and shoulder.
_ACES_FIT = (2.51, 0.03, 2.43, 0.59, 0.14)


def _srgb(x, *, inverse: bool):
    import colour

    curve = colour.cctf_decoding if inverse else colour.cctf_encoding
    return np.clip(curve(np.clip(x, 0.0, 1.0), function="sRGB"), 0.0, 1.0)


def _aces_fit(x):
    a, b, c, d, e = _ACES_FIT
    return x * (a * x + b) / (x * (c * x + d) + e)


def _filmic_encode(x):
    """sRGB(f(x) / f(1)), f the ACES fit (strictly increasing on [0, ∞)), x in [0, 1]."""
    return _srgb(_aces_fit(np.clip(x, 0.0, 1.0)) / _aces_fit(1.0), inverse=False)


def _filmic_decode(y):
    """Inverse of :func:`_filmic_encode`: sRGB-decode, then the positive root of (A − tC)x² + (B − tD)x − tE = 0."""
    a, b, c, d, e = _ACES_FIT
    t = _srgb(y, inverse=True) * _aces_fit(1.0)
    qa, qb = a - t * c, b - t * d
    return np.clip((-qb + np.sqrt(qb * qb + 4.0 * qa * t * e)) / (2.0 * qa), 0.0, 1.0)


def _gamma(exponent: float):
    def curve(x):
        return np.clip(np.clip(x, 0.0, 1.0) ** exponent, 0.0, 1.0)
    return curve


def _identity(x):
    return np.clip(x, 0.0, 1.0)


def _curve(decode_fn, encode_fn):
    return {"decode": decode_fn, "encode": encode_fn}


#: What an input image's values are; each entry's value is the light (key of :data:`LIGHTS`) they are
#: in, its ``decode`` hook maps its values in [0, 1] to linear light and ``encode`` back (:func:`decode`,
#: :func:`encode`). The tone curves are :data:`scenes.display.ENCODINGS`' (same names and formulas).
ENCODINGS = Registry("encoding", {
    "srgb": Entry("display", "sRGB-encoded display values in [0, 1], as a camera delivers them (IEC 61966-2-1)",
                  hooks=_curve(lambda y: _srgb(y, inverse=True), lambda x: _srgb(x, inverse=False))),
    "linear": Entry("linear", "linear radiance in [0, 1] (a render's, an OpenEXR file's)",
                    hooks=_curve(_identity, _identity)),
    "gamma1.8": Entry("display", "display values of the power law y = x^(1/1.8)",
                      hooks=_curve(_gamma(1.8), _gamma(1.0 / 1.8))),
    "gamma2.2": Entry("display", "display values of the power law y = x^(1/2.2)",
                      hooks=_curve(_gamma(2.2), _gamma(1.0 / 2.2))),
    "filmic": Entry("display", "display values of a filmic S-curve: sRGB after the ACES fit of Narkowicz 2016",
                    hooks=_curve(_filmic_decode, _filmic_encode)),
})


def decode(values, encoding: str) -> np.ndarray:
    """Values of ``encoding`` (clipped to [0, 1]) → linear light in [0, 1], by its tone curve.

    Parameters
    ----------
    values : ndarray, any shape, float
    encoding : str
        Key of :data:`ENCODINGS`.

    Returns
    -------
    ndarray, float64, same shape, in [0, 1]

    Raises
    ------
    ValueError
        Unknown ``encoding`` (the message names the allowed ones).
    """
    ENCODINGS.check(encoding, what="encoding")
    return ENCODINGS.entry(encoding).hooks["decode"](np.asarray(values, dtype=np.float64))


def encode(linear, encoding: str) -> np.ndarray:
    """Linear light in [0, 1] (clipped first) → values of ``encoding`` in [0, 1]: the inverse of :func:`decode`."""
    ENCODINGS.check(encoding, what="encoding")
    return ENCODINGS.entry(encoding).hooks["encode"](np.asarray(linear, dtype=np.float64))


def light_of(encoding: str) -> str:
    """The light (key of :data:`LIGHTS`) an image of ``encoding`` is in: "linear" → "linear", a tone curve → "display".

    Raises
    ------
    ValueError
        ``encoding=... is invalid (unknown encoding); allowed: 'linear', 'srgb'``.
    """
    return ENCODINGS.resolve(encoding, what="encoding")


def to_light(image, light: str, *, encoding: str = "srgb") -> np.ndarray:
    """An image of ``encoding`` expressed in ``light``: unchanged, or one sRGB transfer (colour-science).

    Parameters
    ----------
    image : ndarray, any shape, float in [0, 1]
        Values in ``encoding``.
    light : str
        Key of :data:`LIGHTS`.
    encoding : str, keyword-only
        Key of :data:`ENCODINGS`.

    Returns
    -------
    ndarray, same shape, float64 in [0, 1]
        The input itself (as float64) when its encoding is already in ``light``; else decoded by the
        encoding's tone curve (display → linear, :func:`decode`) or sRGB-encoded (linear → display,
        IEC 61966-2-1), clipped to [0, 1].

    Raises
    ------
    ValueError
        Unknown ``encoding`` or ``light`` (the message names the allowed ones).
    """
    source = light_of(encoding)
    LIGHTS.check(light, what="light")
    x = np.asarray(image, dtype=np.float64)
    if source == light:
        return x
    return decode(x, encoding) if light == "linear" else encode(x, "srgb")


def decode_slope(values, encoding: str = "srgb", *, step: float = 1e-4) -> np.ndarray:
    """Slope decode′(y) of an encoding's decoding (encoded value → linear light), by central differences.

    Parameters
    ----------
    values : ndarray or float, any shape
        Encoded values y in [0, 1] (clipped).
    encoding : str
        Key of :data:`ENCODINGS`; its decoding is :func:`to_light` (..., "linear", encoding=...), so
        every registered curve has a slope.
    step : float, keyword-only
        Half-width of the difference, encoded units (one-sided at 0 and 1).

    Returns
    -------
    ndarray, same shape, float64
        d(linear)/d(encoded), dimensionless (1 for "linear"; sRGB: 0.077 at 0, 0.31 at y = 0.2, 1.98 at
        y = 0.9, 2.27 at 1). Noise of variance v in linear light has variance v / decode′(y)² in the
        encoded values, to first order.
    """
    y = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    lo, hi = np.clip(y - step, 0.0, 1.0), np.clip(y + step, 0.0, 1.0)
    return (to_light(hi, "linear", encoding=encoding) - to_light(lo, "linear", encoding=encoding)) / (hi - lo)


def luminance(image) -> np.ndarray:
    """Grey image of the Rec. 709 weights on the RGB values as given (in whatever light they are).

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        An HxW image is returned as is (float64).

    Returns
    -------
    ndarray, HxW, float64 in [0, 1]

    Notes
    -----
    Y = 0.2126 R + 0.7152 G + 0.0722 B, clipped to [0, 1] (the weights sum to 1, so only round-off
    is clipped). On display values this is luma Y′ (the paper's edge input); on linear values,
    relative luminance.
    """
    image = np.asarray(image, dtype=np.float64)
    if image.ndim == 2:
        return image
    return np.clip(image @ np.asarray(LUMA_WEIGHTS), 0.0, 1.0)


def measure_luminance(image, light: str = "display", *, encoding: str = "srgb") -> np.ndarray:
    """The luminance the edge and blur stages read: Rec. 709 weights on the image in ``light``.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        The photo, its values in ``encoding``.
    light : str
        Key of :data:`MEASURE_LIGHTS`: "display" (the sRGB-encoded values: luma) or "linear" (linear
        RGB: relative luminance).
    encoding : str, keyword-only
        Key of :data:`ENCODINGS`: what the values of ``image`` are (default "srgb").

    Returns
    -------
    ndarray, HxW, float64 in [0, 1]

    Notes
    -----
    The image is converted once (:func:`to_light`), then weighted. A lens blurs linear radiance, so
    in linear light a defocused step is the symmetric integral of the PSF's line spread; the camera's
    tone curve makes it asymmetric (steeper on the dark side), which an edge model of a symmetric
    PSF fits too wide or rejects. The conversion assumes the curve ``encoding`` names; a camera's
    own curve departs from sRGB (contrast S-curves): :mod:`method.edges.tone_curve` chooses one per image.
    """
    return luminance(to_light(image, MEASURE_LIGHTS.check(light, what="measure_light"), encoding=encoding))


@dataclasses.dataclass(frozen=True)
class MeasuredInput:
    """What the stages of :func:`method.pipeline.estimate_defocus_map` read of one input image.

    Attributes
    ----------
    rgb : ndarray, HxWx3, float64 in [0, 1]
        The image in display light (sRGB-encoded; a grey input repeated to 3 channels): the
        reference image of Eq. (3) and of the propagation affinities of Eq. (4).
    gray : ndarray, HxW, float64 in [0, 1]
        Luma of ``rgb`` (display light): the region cue's input and the fusion's island test.
    seen : ndarray, HxW, float64 in [0, 1]
        Luminance in ``params.measure_light``: what the edge detector and the blur estimator read.
    """

    rgb: np.ndarray
    gray: np.ndarray
    seen: np.ndarray


def measure_input(image, params, *, encoding: str = "srgb") -> MeasuredInput:
    """The input converted once into the light each stage measures in.

    Parameters
    ----------
    image : ndarray, HxWx3 or HxW, float in [0, 1]
        The photo, its values in ``encoding`` (sides ≥ 8 px).
    params : DefocusParams
        Reads ``measure_light``.
    encoding : str, keyword-only
        Key of :data:`ENCODINGS`: "srgb" (display values, as a camera delivers them; default) or
        "linear" (linear radiance).

    Returns
    -------
    MeasuredInput

    Raises
    ------
    ValueError
        Unknown encoding, or a bad image (:func:`method.validation.validate_image`).

    Notes
    -----
    1. ``rgb`` = the image in display light (:func:`to_light`: a linear input is sRGB-encoded once,
       an sRGB one is used as given), since Eq. (3) and Eq. (4) are the paper's on display values.
    2. ``gray`` = Rec. 709 luma of ``rgb`` (a grey input: its display values themselves).
    3. ``seen`` = ``gray`` when ``measure_light`` is "display"; else the Rec. 709 luminance of the
       image in linear light (a linear input as given, an sRGB one decoded once).
    """
    from .validation import validate_image

    light_of(encoding)  # an unknown encoding is refused before the image is looked at
    image = validate_image(image)
    display = to_light(image, "display", encoding=encoding)
    rgb = display if display.ndim == 3 else np.repeat(display[..., None], 3, axis=2)
    gray = luminance(display)
    light = MEASURE_LIGHTS.check(params.measure_light, what="measure_light")
    seen = gray if light == "display" else measure_luminance(image, light, encoding=encoding)
    return MeasuredInput(rgb=rgb, gray=gray, seen=seen)
