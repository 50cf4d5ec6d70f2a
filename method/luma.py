"""Luminance of an RGB image: the one definition of the luma weights used by :mod:`method` and the harness."""

from __future__ import annotations

import numpy as np

from .registry import Entry, Registry

__all__ = ["LUMA_WEIGHTS", "MEASURE_LIGHTS", "luminance", "measure_luminance"]

#: Rec. 709 luma weights (R, G, B), applied to the (encoded) RGB values: the edge detector's input
#: (:func:`method.pipeline.estimate_defocus_map`), the guided upsampling's guide and the harness's
#: texture mask all use these.
LUMA_WEIGHTS = (0.2126, 0.7152, 0.0722)


def luminance(image) -> np.ndarray:
    """Grey image the edge detector sees: Rec. 709 weights on the given (encoded) RGB values.

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
    is clipped).
    """
    image = np.asarray(image, dtype=np.float64)
    if image.ndim == 2:
        return image
    return np.clip(image @ np.asarray(LUMA_WEIGHTS), 0.0, 1.0)


def _decode_srgb(image):
    """sRGB-encoded values in [0, 1] → linear light (IEC 61966-2-1, colour-science)."""
    import colour

    return np.clip(colour.cctf_decoding(np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0), function="sRGB"),
                   0.0, 1.0)


#: The light in which edges are detected and their blur is measured (``DefocusParams.measure_light``):
#: each entry's value maps the (encoded) image to the luminance the edge and blur stages read.
MEASURE_LIGHTS = Registry("measure light", {
    "display": Entry(luminance, "the encoded values as given (the paper)"),
    "linear": Entry(lambda image: luminance(_decode_srgb(image)),
                    "sRGB decoded to linear light first: a lens blurs linear radiance (photos assumed sRGB)"),
})


def measure_luminance(image, light: str = "display") -> np.ndarray:
    """The luminance the edge and blur stages read: Rec. 709 luma of the image in ``light``.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        The photo as given (sRGB-encoded, as a camera delivers it).
    light : str
        Key of :data:`MEASURE_LIGHTS`: "display" (the encoded values) or "linear" (the sRGB transfer
        function decoded first, then the luma weights on linear RGB: relative luminance).

    Returns
    -------
    ndarray, HxW, float64 in [0, 1]

    Notes
    -----
    A lens blurs linear radiance, so in linear light a defocused step is the symmetric integral of the
    PSF's line spread; the camera's tone curve then makes it asymmetric (steeper on the dark side),
    which an edge model of a symmetric PSF fits too wide or rejects. Decoding assumes the sRGB curve
    (IEC 61966-2-1); a camera's own curve departs from it (contrast S-curves), which this does not
    model.
    """
    return MEASURE_LIGHTS.resolve(light, what="measure_light")(image)
