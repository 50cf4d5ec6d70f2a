"""Thin-lens optics: circle of confusion (Eq. 5, 6) and the blur σ the method should recover.

All distances are in metres unless a name says otherwise (``*_mm``, ``*_px``).

References
----------
Bae & Durand, "Defocus Magnification", Eurographics 2007, Appendix A.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np

__all__ = [
    "BOX_FILTER_SIGMA_PX",
    "GAUSSIAN_FILTER_SIGMA_PX",
    "SIGMA_CONVENTIONS",
    "circle_of_confusion",
    "coc_to_sigma",
    "lens_sensor_distance",
    "relative_circle_of_confusion",
]

#: Standard deviation (px) of Mitsuba's ``box`` reconstruction filter: a unit-width box, 1/sqrt(12).
BOX_FILTER_SIGMA_PX = 1.0 / np.sqrt(12.0)
#: Standard deviation (px) of Mitsuba's default ``gaussian`` reconstruction filter (RENDERING-FACTS.md).
GAUSSIAN_FILTER_SIGMA_PX = 0.5


def lens_sensor_distance(focal_length, focus_distance):
    """Lens-to-sensor distance v of a thin lens focused at ``focus_distance``.

    From 1/f = 1/v + 1/D (Appendix A): v = f·D / (D − f).

    Parameters
    ----------
    focal_length : float or ndarray
        Focal length f in metres, > 0.
    focus_distance : float or ndarray
        Focus distance D in metres, > f.

    Returns
    -------
    float or ndarray
        v in metres.
    """
    f = np.asarray(focal_length, dtype=np.float64)
    d = np.asarray(focus_distance, dtype=np.float64)
    if np.any(f <= 0) or np.any(d <= f):
        raise ValueError("need 0 < focal_length < focus_distance")
    return f * d / (d - f)


def circle_of_confusion(object_distance, *, focal_length, f_number, focus_distance):
    """Circle-of-confusion diameter on the sensor, Eq. (5).

    c = |S − D| / S · f² / (N (D − f))

    Parameters
    ----------
    object_distance : float or ndarray, any shape
        S in metres (camera-space depth of the point), > 0. ``inf`` gives the limit f²/(N(D−f)).
    focal_length : float
        f in metres.
    f_number : float
        N, dimensionless, > 0.
    focus_distance : float
        D in metres, > f.

    Returns
    -------
    ndarray, same shape as ``object_distance``
        c in metres on the sensor.
    """
    if f_number <= 0:
        raise ValueError(f"f_number must be > 0, got {f_number}")
    if focal_length <= 0 or focus_distance <= focal_length:
        raise ValueError("need 0 < focal_length < focus_distance")
    s = np.asarray(object_distance, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isinf(s), 1.0, np.abs(s - focus_distance) / s)
    return ratio * focal_length**2 / (f_number * (focus_distance - focal_length))


def relative_circle_of_confusion(
    object_distance, *, relative_focal_length, sensor_width, f_number, focus_distance
):
    """Circle of confusion as a fraction of the sensor width, Eq. (6).

    c' = c / X = |S − D| / S · f'² X / (N (D − f' X)),  with f' = f / X.

    Two cameras with the same f' have the same field of view; to first order c' is
    proportional to the sensor width X.

    Parameters
    ----------
    object_distance : float or ndarray
        S in metres.
    relative_focal_length : float
        f' = f / X, dimensionless.
    sensor_width : float
        X in metres.
    f_number : float
        N, dimensionless.
    focus_distance : float
        D in metres.

    Returns
    -------
    ndarray
        c', dimensionless (multiply by the image width in pixels for pixels).
    """
    f = relative_focal_length * sensor_width
    return circle_of_confusion(
        object_distance, focal_length=f, f_number=f_number, focus_distance=focus_distance
    ) / sensor_width


def _sigma_line_spread(coc_px):
    # Second moment of a uniform disk's line-spread function: sigma = c / 4.
    return coc_px / 4.0


def _sigma_erf_fit(coc_px):
    # Least-squares erf fit to a disk-blurred step edge: sigma ~= 0.273 c
    # (theory 0.2714 c; RENDERING-FACTS.md measured 0.273).
    return 0.273 * coc_px


#: Registered CoC-diameter → Gaussian-σ conventions (both in pixels).
SIGMA_CONVENTIONS: Mapping[str, Callable[[np.ndarray], np.ndarray]] = MappingProxyType(
    {"line_spread": _sigma_line_spread, "erf_fit": _sigma_erf_fit}
)


def coc_to_sigma(coc_px, *, convention="line_spread", filter_sigma_px=BOX_FILTER_SIGMA_PX):
    """Gaussian blur σ (px) equivalent to a disk of diameter ``coc_px`` plus the pixel filter.

    σ = sqrt(σ_disk(c)² + σ_filter²), σ_disk from ``SIGMA_CONVENTIONS[convention]``.

    Parameters
    ----------
    coc_px : float or ndarray
        Circle-of-confusion diameter in pixels, ≥ 0 (NaN passes through).
    convention : {"line_spread", "erf_fit"}, keyword-only
        ``"line_spread"`` (default): σ = c/4, the standard deviation of the disk's line-spread
        function. ``"erf_fit"``: σ = 0.273·c, the σ of a least-squares erf fit to a disk edge.
    filter_sigma_px : float, keyword-only
        σ of the renderer's pixel reconstruction filter in pixels, combined in quadrature.

    Returns
    -------
    ndarray
        σ in pixels.
    """
    try:
        fn = SIGMA_CONVENTIONS[convention]
    except KeyError:
        raise ValueError(
            f"unknown sigma convention {convention!r}; choose one of {sorted(SIGMA_CONVENTIONS)}"
        ) from None
    if filter_sigma_px < 0:
        raise ValueError(f"filter_sigma_px must be >= 0, got {filter_sigma_px}")
    c = np.asarray(coc_px, dtype=np.float64)
    return np.sqrt(fn(c) ** 2 + filter_sigma_px**2)
