"""Luminance of an RGB image: the one definition of the luma weights used by :mod:`method` and the harness."""

from __future__ import annotations

import numpy as np

__all__ = ["LUMA_WEIGHTS", "luminance"]

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
