"""Input validation shared by the public entry points of :mod:`method`."""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_IMAGE_SIDE", "validate_image", "validate_map"]

#: Smallest accepted image side, px: below this even the finest derivative filter (σ = 0.5 px,
#: support ±3σ plus the one-pixel zero-crossing test) and the 7×7 propagation window do not fit.
MIN_IMAGE_SIDE = 8

#: Values may exceed [0, 1] by this much (float round-off from colour transforms) and are clipped.
RANGE_SLACK = 1e-6


def validate_image(image, *, name="image") -> np.ndarray:
    """Check an image and return it as float64 (HxW or HxWx3, values in [0, 1]).

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float
        Values in [0, 1].
    name : str, keyword-only
        What to call the array in error messages.

    Raises
    ------
    ValueError
        Not a numpy array; wrong number of dimensions or channels; not a floating dtype;
        NaN or Inf; values outside [0, 1]; a side shorter than :data:`MIN_IMAGE_SIDE`.
    """
    if not isinstance(image, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(image).__name__}")
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] != 3):
        raise ValueError(f"{name} must have shape HxW or HxWx3, got {image.shape}")
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(
            f"{name} must be a float array with values in [0, 1], got dtype {image.dtype} "
            "(divide integer images by their maximum code value, e.g. 255)"
        )
    h, w = image.shape[:2]
    if min(h, w) < MIN_IMAGE_SIDE:
        raise ValueError(f"{name} is {w}x{h} px; the smallest supported side is {MIN_IMAGE_SIDE} px")
    if not np.all(np.isfinite(image)):
        raise ValueError(f"{name} contains NaN or Inf values")
    lo, hi = float(image.min()), float(image.max())
    if lo < -RANGE_SLACK or hi > 1 + RANGE_SLACK:
        raise ValueError(f"{name} values must lie in [0, 1], got [{lo:.6g}, {hi:.6g}]")
    return np.clip(image.astype(np.float64, copy=False), 0.0, 1.0)


def validate_map(defocus_map, shape, *, name="defocus_map") -> np.ndarray:
    """Check a dense blur map (HxW, finite, ≥ 0, matching ``shape[:2]``) and return it as float64."""
    if not isinstance(defocus_map, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(defocus_map).__name__}")
    if defocus_map.shape != tuple(shape[:2]):
        raise ValueError(f"{name} has shape {defocus_map.shape}, expected {tuple(shape[:2])}")
    if not np.issubdtype(defocus_map.dtype, np.number):
        raise ValueError(f"{name} must be numeric, got dtype {defocus_map.dtype}")
    if not np.all(np.isfinite(defocus_map)):
        raise ValueError(f"{name} contains NaN or Inf values")
    if float(np.min(defocus_map)) < 0:
        raise ValueError(f"{name} must be >= 0 (blur σ in px), got min {float(np.min(defocus_map)):.6g}")
    return defocus_map.astype(np.float64, copy=False)
