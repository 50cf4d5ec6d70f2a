"""The input's light: what an image's values are (its encoding) and the light each stage works in.

One vocabulary across :mod:`method`, the harness and the CLIs:

* an **encoding** (:data:`ENCODINGS`) says what the values of an image *are*: ``"srgb"`` (display
  values, sRGB-encoded as a camera delivers them) or ``"linear"`` (linear radiance, as a renderer or
  an OpenEXR file holds it);
* a **light** (:data:`LIGHTS`) is the space a stage measures or blends in: ``"display"`` (the
  sRGB-encoded values; the paper's edges, Eq. 3 and Eq. 4 all read these) or ``"linear"`` (linear
  light, in which a lens blurs). An ``"srgb"`` image is in display light, a ``"linear"`` one in
  linear light.

:func:`to_light` converts an image from its encoding into a light (at most one sRGB transfer, IEC
61966-2-1 from colour-science; none when they already agree), :func:`measure_input` gives what every
stage of :func:`method.pipeline.estimate_defocus_map` reads, and :data:`LUMA_WEIGHTS` is the one
definition of the luma weights.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .registry import Entry, Registry

__all__ = ["ENCODINGS", "LIGHTS", "LUMA_WEIGHTS", "MEASURE_LIGHTS", "MeasuredInput", "decode_slope", "light_of",
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

#: What an input image's values are; each entry's value is the light (key of :data:`LIGHTS`) they are in.
ENCODINGS = Registry("encoding", {
    "srgb": Entry("display", "sRGB-encoded display values in [0, 1], as a camera delivers them"),
    "linear": Entry("linear", "linear radiance in [0, 1] (a render's, an OpenEXR file's)"),
})


def light_of(encoding: str) -> str:
    """The light (key of :data:`LIGHTS`) an image of ``encoding`` is in: "srgb" → "display", "linear" → "linear".

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
        The input itself (as float64) when its encoding is already in ``light``; else sRGB-decoded
        (display → linear) or sRGB-encoded (linear → display), IEC 61966-2-1, clipped to [0, 1].

    Raises
    ------
    ValueError
        Unknown ``encoding`` or ``light`` (the message names the allowed ones).
    """
    import colour

    source = light_of(encoding)
    LIGHTS.check(light, what="light")
    x = np.asarray(image, dtype=np.float64)
    if source == light:
        return x
    curve = colour.cctf_decoding if light == "linear" else colour.cctf_encoding
    return np.clip(curve(np.clip(x, 0.0, 1.0), function="sRGB"), 0.0, 1.0)


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
    PSF fits too wide or rejects. The conversion assumes the sRGB curve (IEC 61966-2-1); a camera's
    own curve departs from it (contrast S-curves), which this does not model.
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
