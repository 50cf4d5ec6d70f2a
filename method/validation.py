"""Input validation shared by the public entry points of :mod:`method`."""

from __future__ import annotations

import numpy as np

__all__ = [
    "MIN_IMAGE_SIDE",
    "check_field_choice",
    "check_odd",
    "check_positive",
    "invalid_field",
    "is_integer",
    "require_field",
    "validate_guide",
    "validate_image",
    "validate_map",
    "validate_propagation_inputs",
]

#: Smallest accepted image side, px: below this even the finest derivative filter (σ = 0.5 px,
#: support ±3σ plus the one-pixel zero-crossing test) and the 7×7 propagation window do not fit.
MIN_IMAGE_SIDE = 8

#: Values may exceed [0, 1] by this much (float round-off from colour transforms) and are clipped.
RANGE_SLACK = 1e-6


def validate_image(image, *, name="image", min_side=MIN_IMAGE_SIDE, channels=(3,), check_range=True) -> np.ndarray:
    """Check an image and return it as float64 (HxW or HxWxC, values in [0, 1]).

    The one image check of :mod:`method`: the pipeline's input, the guide of Eq. (3) and of the
    propagation, the magnified photo all go through it, so every entry point accepts and rejects
    the same arrays with the same messages.

    Parameters
    ----------
    image : ndarray, HxW or HxWxC, float
        Values in [0, 1] (up to :data:`RANGE_SLACK` round-off, clipped).
    name : str, keyword-only
        What to call the array in error messages.
    min_side : int, keyword-only
        Smallest accepted side, px (default :data:`MIN_IMAGE_SIDE`; a stage that works on any
        size, e.g. the cross-bilateral filter, passes a smaller one).
    channels : tuple of int, keyword-only
        Accepted channel counts C of a 3-D array (default: 3, RGB; empty: HxW only).
    check_range : bool, keyword-only
        Require (and clip to) [0, 1]; False for guides whose equations hold for any finite values
        (:func:`validate_guide`).

    Returns
    -------
    ndarray, float64, same shape

    Raises
    ------
    ValueError
        Not a numpy array; wrong number of dimensions or channels; not a floating dtype;
        NaN or Inf; values outside [0, 1]; a side shorter than ``min_side``.
    """
    if not isinstance(image, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(image).__name__}")
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in channels):
        shapes = "HxW" + (" or HxWx3" if 3 in channels else "") + "".join(f" (or HxWx{c})" for c in channels if c != 3)
        raise ValueError(f"{name} must have shape {shapes}, got {image.shape}")
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(
            f"{name} must be a float array with values in [0, 1], got dtype {image.dtype} "
            "(divide integer images by their maximum code value, e.g. 255)"
        )
    h, w = image.shape[:2]
    if min(h, w) < min_side:
        raise ValueError(f"{name} is {w}x{h} px; the smallest supported side is {min_side} px")
    if not np.all(np.isfinite(image)):
        raise ValueError(f"{name} contains NaN or Inf values")
    if not check_range:
        return image.astype(np.float64, copy=False)
    lo, hi = float(image.min()), float(image.max())
    if lo < -RANGE_SLACK or hi > 1 + RANGE_SLACK:
        raise ValueError(f"{name} values must lie in [0, 1], got [{lo:.6g}, {hi:.6g}]")
    return np.clip(image.astype(np.float64, copy=False), 0.0, 1.0)


def validate_sparse_sigma(sparse_sigma, shape, *, name="sparse_sigma") -> np.ndarray:
    """Check a sparse blur measure (HxW float, σ ≥ 0 px at edges, NaN elsewhere) and return it as float64.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels; NaN marks the other pixels.
    shape : tuple
        Shape of the image it belongs to (its first two entries must match).
    name : str, keyword-only

    Raises
    ------
    ValueError
        Not an array; shape mismatch; not floating; Inf; a negative σ.
    """
    if not isinstance(sparse_sigma, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(sparse_sigma).__name__}")
    if sparse_sigma.shape != tuple(shape[:2]):
        raise ValueError(f"{name} has shape {sparse_sigma.shape}, expected {tuple(shape[:2])} (the image's HxW)")
    if not np.issubdtype(sparse_sigma.dtype, np.floating):
        raise ValueError(f"{name} must be float (NaN off edges), got dtype {sparse_sigma.dtype}")
    if np.any(np.isinf(sparse_sigma)):
        raise ValueError(f"{name} contains Inf; use NaN to mark non-edge pixels")
    finite = sparse_sigma[np.isfinite(sparse_sigma)]
    if finite.size and float(finite.min()) < 0:
        raise ValueError(f"{name} must be >= 0 (blur σ, px), got min {float(finite.min()):.6g}")
    return sparse_sigma.astype(np.float64, copy=False)


def validate_map(defocus_map, shape=None, *, name="defocus_map", allow_negative=False) -> np.ndarray:
    """Check a dense blur map (HxW, real, finite, ≥ 0 unless ``allow_negative``) and return it as float64.

    Parameters
    ----------
    defocus_map : ndarray, HxW, real
        Blur σ, px.
    shape : tuple, optional
        Shape of the image it belongs to (its first two entries must match).
    name : str, keyword-only
        What to call the array in error messages.
    allow_negative : bool, keyword-only
        Accept negative values (a map that is clamped afterwards, e.g. Sec. 5's preprocessing).

    Raises
    ------
    ValueError
        Not an array; not HxW or not matching ``shape``; not real numeric; NaN or Inf; a negative
        value (unless ``allow_negative``).
    """
    if not isinstance(defocus_map, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(defocus_map).__name__}")
    if defocus_map.ndim != 2:
        raise ValueError(f"{name} must be HxW, got shape {defocus_map.shape}")
    if shape is not None and defocus_map.shape != tuple(shape[:2]):
        raise ValueError(f"{name} has shape {defocus_map.shape}, expected {tuple(shape[:2])} (the image's HxW)")
    if not np.issubdtype(defocus_map.dtype, np.number) or np.issubdtype(defocus_map.dtype, np.complexfloating):
        raise ValueError(f"{name} must be real numeric, got dtype {defocus_map.dtype}")
    if not np.all(np.isfinite(defocus_map)):
        raise ValueError(f"{name} contains NaN or Inf values")
    if not allow_negative and defocus_map.size and float(np.min(defocus_map)) < 0:
        raise ValueError(f"{name} must be >= 0 (blur σ, px), got min {float(np.min(defocus_map)):.6g}")
    return defocus_map.astype(np.float64, copy=False)


# --- the propagations' inputs (method.propagation.system / method.propagation.defocus, method.propagation.matting) ---

def validate_guide(reference, *, name="reference", min_side=1) -> np.ndarray:
    """Check a propagation guide image and return it as float64 HxWxC (C = 1 or 3).

    Parameters
    ----------
    reference : ndarray, HxW, HxWx1 or HxWx3, float
        Guide image C (values in [0, 1] by convention; the range is not checked: the affinities
        and the matting Laplacian are defined for any finite values).
    name : str, keyword-only
        What to call the array in error messages.
    min_side : int, keyword-only
        Smallest accepted side, px.

    Returns
    -------
    ndarray, HxWxC, float64
        An HxW guide gets a trailing channel axis (C = 1); no copy when already float64.

    Raises
    ------
    ValueError
        Not a numpy array; wrong shape; not a floating dtype; a side below ``min_side``; NaN or Inf.
    """
    ref = validate_image(reference, name=name, min_side=min_side, channels=(1, 3), check_range=False)
    return ref[..., None] if ref.ndim == 2 else ref


def validate_propagation_inputs(sparse_sigma, reference, *, min_side=1) -> tuple[np.ndarray, np.ndarray]:
    """Check the inputs of a propagation (sparse σ + guide); the one rule set of every propagation.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at pixels with a measure (finite, ≥ 0); NaN at every other pixel.
    reference : ndarray, HxW, HxWx1 or HxWx3, float
        Guide image (:func:`validate_guide`).
    min_side : int, keyword-only
        Smallest accepted image side, px.

    Returns
    -------
    sparse_sigma : ndarray, HxW, float64
    reference : ndarray, HxWxC, float64 (C = 1 or 3)

    Raises
    ------
    ValueError
        The guide fails :func:`validate_guide`; ``sparse_sigma`` is not a float array of the guide's
        HxW, holds Inf, or a negative σ.
    """
    ref = validate_guide(reference, min_side=min_side)
    return validate_sparse_sigma(sparse_sigma, ref.shape), ref


def check_positive(name, value, *, allow_zero=False) -> float:
    """``value`` as a finite float > 0 (≥ 0 with ``allow_zero``); ValueError naming ``name`` otherwise."""
    allowed = f"a finite number {'>=' if allow_zero else '>'} 0"
    if isinstance(value, bool):
        raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}") from None
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}")
    return v


def check_odd(name, value, minimum) -> int:
    """``value`` as an odd int ≥ ``minimum``; ValueError naming ``name`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum or value % 2 == 0:
        raise ValueError(f"{name}={value!r} is invalid; allowed: odd integer >= {minimum}")
    return int(value)


# --- parameter fields (the stage dataclasses of method.edges.params, method.blur.params, …) ---------------

def invalid_field(name: str, value, allowed: str) -> ValueError:
    """The error for a bad parameter field: ``DefocusParams.<name>=<value!r> is invalid; allowed: <allowed>``.

    Every stage's parameters (:class:`method.edges.params.EdgeParams`, …) name their fields as
    :class:`method.params.DefocusParams` spells them (one flat namespace), so the message is the same
    whether the field was set on the stage or on the whole parameter set.
    """
    return ValueError(f"DefocusParams.{name}={value!r} is invalid; allowed: {allowed}")


def require_field(params, name: str, ok: bool, allowed: str) -> None:
    """Raise :func:`invalid_field` for field ``name`` of ``params`` unless ``ok``."""
    if not ok:
        raise invalid_field(name, getattr(params, name), allowed)


def check_field_choice(params, name: str, registry, *, optional: bool = False) -> None:
    """Field ``name`` of ``params`` must be a key of ``registry`` (or None with ``optional``); the
    message comes from :meth:`method.registry.Registry.check`."""
    registry.check(getattr(params, name), what=f"DefocusParams.{name}", optional=optional)


def is_integer(value, minimum: int) -> bool:
    """True for an int (not a bool) ≥ ``minimum``."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= minimum
