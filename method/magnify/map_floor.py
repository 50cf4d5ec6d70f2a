"""The defocus map before magnification: Sec. 5's preprocessing and the in-focus floor.

Sec. 5 prepares the map by "cropping the upper and lower 5 % of the defocus map and clamping its
minimum value to 0". An estimated map never reads 0 on a sharp subject: its in-focus regions read an
in-focus floor (σ ≈ 0.3–1 px of pixel-filter / sensor blur and estimator bias, which does not scale
with the aperture), so the literal reading adds √(k² − 1)·floor of blur to the subject. The readings
(:data:`MAP_FLOOR_MODES`):

* ``"clamp"`` (the literal reading): B ← max(B, 0).
* ``"subtract"``: the lower-percentile value p_lo is removed in quadrature, B ← √(max(B² − p_lo², 0))
  (a Gaussian floor adds to the defocus blur in quadrature, B² = σ_d² + p_lo²).
* ``"shift"``: B ← max(B − p_lo, 0) (over-corrects every defocused value; for comparison).
* ``"auto"``: the floor f and its uncertainty u are estimated per photo from the smoothed map's
  distribution (:func:`estimate_floor`: its sharpest mode), or read at a ``focus_point``; pixels at or
  below t = f + u get no extra blur, above it the blur grows smoothly (:func:`soft_floor`, a C¹ ramp
  in variance that tends to subtracting the floor in quadrature), after the Sec. 5 smoothing so that
  the smoothing does not spread the background's blur back onto the subject.

``keep_sharp`` (a mask of the subject) zeroes the map inside the mask and feathers it outside
(:func:`keep_sharp_weight`), in every mode.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import ndimage

from ..registry import Entry, Registry
from ..validation import validate_map

__all__ = ["FloorEstimate", "MAP_FLOOR_MODES", "estimate_floor", "floor_at_point", "keep_sharp_weight",
           "preprocess_defocus_map", "soft_floor"]

#: The density of log σ the floor is read from (:func:`estimate_floor`): bins, smoothing (bins), the
#: height of the in-focus mode relative to the highest one, the largest threshold relative to the floor.
DENSITY_BINS = 64
DENSITY_SMOOTHING_BINS = 3.0
MODE_MIN_HEIGHT = 0.25
MAX_THRESHOLD_RATIO = 3.0
#: Values at or below this σ are left out of the density, px: below the pixel filter's own σ (1/√12 px) no
#: lens image reads, so they are the estimate's undershoots, not a mode of the scene.
MIN_DENSITY_SIGMA_PX = 0.25
#: Smallest uncertainty of an estimated floor, as a fraction of the floor (and at least MIN_UNCERTAINTY_PX).
MIN_UNCERTAINTY_REL = 0.15
MIN_UNCERTAINTY_PX = 0.05
#: Radius of the window a focus point's floor is read in, as a fraction of max(H, W) (at least 2 px).
FOCUS_WINDOW_FRACTION = 0.01


def _floor_clamp(m, floor):
    """Literal Sec. 5 reading: max(m, 0) px (``floor`` is not used)."""
    return np.maximum(m, 0.0)


def _floor_subtract(m, floor):
    """Remove a Gaussian floor of σ ``floor`` px in quadrature: √(max(m² − floor², 0))."""
    m = np.maximum(m, 0.0)
    return np.sqrt(np.maximum(m * m - floor * floor, 0.0))


def _floor_shift(m, floor):
    """Shift the map so that ``floor`` px becomes 0: max(m − floor, 0)."""
    return np.maximum(m - floor, 0.0)


@dataclasses.dataclass(frozen=True)
class FloorEstimate:
    """An in-focus floor: ``floor`` f px, ``uncertainty`` u px; no extra blur at or below f + u."""

    floor: float
    uncertainty: float

    @property
    def threshold(self) -> float:
        """t = f + u, px."""
        return self.floor + self.uncertainty


def soft_floor(m, estimate: FloorEstimate) -> np.ndarray:
    """Remove an in-focus floor softly: 0 at or below t = f + u, growing C¹-smoothly above it.

    Parameters
    ----------
    m : ndarray, HxW, float, ≥ 0
        Blur σ, px.
    estimate : FloorEstimate
        Floor f and uncertainty u, px.

    Returns
    -------
    ndarray, HxW, float64, ≥ 0
        σ' px: with v = m² − t² and the ramp width W = 2·t·u + u² px² (the variance between t and
        t + u), σ'² = v³/(3W²) for 0 ≤ v ≤ W and v − 2W/3 above, 0 for v ≤ 0: σ'² is C², so σ' and
        dσ'/dm are continuous (dσ'/dm = 0 at t: no seam where the added blur starts). Far above the
        threshold σ'² = m² − (t² + 2W/3), the floor removed in quadrature; dσ'/dm ≤ (t + u)·√3/√W
        everywhere (bounded).
    """
    m = np.maximum(np.asarray(m, dtype=np.float64), 0.0)
    t, u = estimate.threshold, max(estimate.uncertainty, 1e-6)
    width = 2.0 * t * u + u * u
    v = m * m - t * t
    v2 = np.where(v <= 0.0, 0.0, np.where(v <= width, v**3 / (3.0 * width * width), v - 2.0 * width / 3.0))
    return np.sqrt(v2)


def _uncertainty(floor: float, spread: float) -> float:
    return max(float(spread), MIN_UNCERTAINTY_REL * floor, MIN_UNCERTAINTY_PX)


def estimate_floor(m) -> FloorEstimate:
    """The in-focus floor of a (smoothed) map from its distribution: its sharpest mode.

    Parameters
    ----------
    m : ndarray, HxW, float, ≥ 0
        Blur σ, px.

    Returns
    -------
    FloorEstimate
        The density of log σ (a histogram of :data:`DENSITY_BINS` bins between the 0.5th and 99.5th
        percentiles, smoothed by a Gaussian of :data:`DENSITY_SMOOTHING_BINS` bins) is read from the
        sharp end (values ≤ :data:`MIN_DENSITY_SIGMA_PX` left out): its first peak at or below the
        median holding at least :data:`MODE_MIN_HEIGHT` of the highest one there is the in-focus mode
        (a blurry background's mode may be the highest of all), and the first minimum after it
        (the valley before the next mode) its upper end e. The floor f is the median of the pixels ≤ e;
        the uncertainty u = min(e, :data:`MAX_THRESHOLD_RATIO`·f) − f, at least
        max(:data:`MIN_UNCERTAINTY_REL`·f, :data:`MIN_UNCERTAINTY_PX`) px: pixels of the in-focus mode
        get no extra blur. A map without spread (constant) gives f = its value.
    """
    v = np.asarray(m, dtype=np.float64).ravel()
    x = np.log(v[v > MIN_DENSITY_SIGMA_PX])
    lo, hi = np.percentile(x, [0.5, 99.5]) if x.size else (0.0, 0.0)
    if not hi > lo:
        f = float(np.median(v))
        return FloorEstimate(f, _uncertainty(f, 0.0))
    hist, edges = np.histogram(np.clip(x, lo, hi), bins=DENSITY_BINS, range=(lo, hi))
    dens = ndimage.gaussian_filter1d(hist.astype(np.float64), DENSITY_SMOOTHING_BINS, mode="nearest")
    # the in-focus mode lies in the sharper half of the map (a blurry background mode may be the highest)
    sharp_half = (edges[:-1] + edges[1:]) / 2 <= np.median(x)
    sharp_half[0] = True
    top = dens[sharp_half].max()
    is_peak = (dens >= np.r_[-1.0, dens[:-1]]) & (dens >= np.r_[dens[1:], -1.0]) & (dens >= MODE_MIN_HEIGHT * top)
    ip = int(np.argmax(is_peak & sharp_half)) if np.any(is_peak & sharp_half) else 0
    iv = ip
    while iv + 1 < len(dens) and dens[iv + 1] < dens[iv]:
        iv += 1
    end = float(np.exp(edges[iv + 1]))
    f = float(np.median(v[v <= end]))
    return FloorEstimate(f, _uncertainty(f, min(end, MAX_THRESHOLD_RATIO * f) - f))


def _check_focus_point(focus_point, shape):
    try:
        x, y = (float(c) for c in focus_point)
    except (TypeError, ValueError):
        raise ValueError(f"focus_point={focus_point!r} is invalid; allowed: (x, y) pixel coordinates") from None
    h, w = shape
    if not (np.isfinite(x) and np.isfinite(y) and 0 <= x <= w - 1 and 0 <= y <= h - 1):
        raise ValueError(f"focus_point={focus_point!r} is outside the image; allowed: 0 <= x <= {w - 1}, "
                         f"0 <= y <= {h - 1} (pixels of the {w}x{h} image)")
    return int(round(x)), int(round(y))


def floor_at_point(m, focus_point) -> FloorEstimate:
    """The floor read at the map around ``focus_point`` = (x, y) px (column, row).

    f = the median of the map in a square window of radius max(2, FOCUS_WINDOW_FRACTION·max(H, W)) px
    around the point, u = 2 × 1.4826 × the window's median absolute deviation (at least
    max(MIN_UNCERTAINTY_REL·f, MIN_UNCERTAINTY_PX)). ValueError for a point outside the image.
    """
    x, y = _check_focus_point(focus_point, m.shape)
    r = max(2, int(round(FOCUS_WINDOW_FRACTION * max(m.shape))))
    win = m[max(0, y - r):y + r + 1, max(0, x - r):x + r + 1]
    f = float(np.median(win))
    return FloorEstimate(f, _uncertainty(f, 2.0 * 1.4826 * float(np.median(np.abs(win - f)))))


def keep_sharp_weight(keep_sharp, shape, feather_px: float) -> np.ndarray:
    """Weight in [0, 1] by which the map is multiplied: 0 inside the mask, feathered to 1 outside it.

    Parameters
    ----------
    keep_sharp : ndarray, HxW, bool or float in [0, 1]
        Where no blur is added (a float mask: 1 = none, 0 = all of it).
    shape : tuple
        (H, W) of the map.
    feather_px : float
        Width of the feather outside the mask (where the mask ≥ ½), px: the weight rises from 0 at the
        mask's edge to 1 at that distance as a smoothstep (C¹, no seam).

    Raises
    ------
    ValueError
        Not HxW of ``shape``, not bool or real, NaN, values outside [0, 1].
    """
    k = np.asarray(keep_sharp)
    if k.shape != tuple(shape[:2]):
        raise ValueError(f"keep_sharp has shape {k.shape}; allowed: the image's {tuple(shape[:2])} (HxW)")
    if k.dtype != bool and not (np.issubdtype(k.dtype, np.number) and not np.iscomplexobj(k)):
        raise ValueError(f"keep_sharp must be a bool or float mask, got dtype {k.dtype}")
    k = k.astype(np.float64)
    if not np.all(np.isfinite(k)) or (k.size and (k.min() < 0 or k.max() > 1)):
        raise ValueError("keep_sharp must hold values in [0, 1] (1 = keep sharp), without NaN")
    core = k >= 0.5
    if not core.any():
        return 1.0 - k
    d = ndimage.distance_transform_edt(~core)
    s = np.clip(d / max(float(feather_px), 1.0), 0.0, 1.0)
    return np.minimum(1.0 - k, s * s * (3.0 - 2.0 * s))


#: How the map's floor is removed, by name: (clipped map px, floor p_lo px ≥ 0, or a
#: :class:`FloorEstimate` for the entries with the "estimated" capability) → map px ≥ 0.
MAP_FLOOR_MODES = Registry("map floor", {
    "clamp": Entry(_floor_clamp, "max(σ, 0), the literal Sec. 5 reading"),
    "subtract": Entry(_floor_subtract, "remove the floor in quadrature"),
    "shift": Entry(_floor_shift, "max(σ − floor, 0)"),
    "auto": Entry(soft_floor, "estimate the in-focus floor per photo; no blur added within its uncertainty, "
                              "growing smoothly above", capabilities={"estimated"}),
})


def preprocess_defocus_map(defocus_map, *, clip_percent=5.0, smoothing=0.005, floor="clamp", focus_point=None,
                           keep_sharp=None) -> np.ndarray:
    """Prepare a defocus map for magnification as the paper does before lens blur (Sec. 5).

    Parameters
    ----------
    defocus_map : ndarray, HxW, float
        Dense blur σ, px (may hold small negative overshoots).
    clip_percent : float, keyword-only
        Clip values below the ``clip_percent`` and above the ``100 − clip_percent`` percentile, %
        (paper: 5). In [0, 50).
    smoothing : float, keyword-only
        σ of the Gaussian blur of the map as a fraction of max(H, W) (paper: 0.5 % → 0.005). ≥ 0.
    floor : str, keyword-only
        Key of :data:`MAP_FLOOR_MODES` (module docstring): ``"clamp"`` (default, literal), ``"subtract"``,
        ``"shift"`` (with p_lo = max(P_clip, 0) px) or ``"auto"`` (estimated floor, soft).
    focus_point : (float, float), optional, keyword-only
        (x, y) px, column and row of a pixel of the subject: the floor is read there
        (:func:`floor_at_point`) and removed softly (:func:`soft_floor`), whatever ``floor`` says.
    keep_sharp : ndarray, HxW, bool or float in [0, 1], optional, keyword-only
        Where no blur is added: the map is multiplied by :func:`keep_sharp_weight` (feathered over
        2 × the smoothing σ, at least 2 px).

    Returns
    -------
    ndarray, HxW, float64, ≥ 0
        Processed σ map, px.

    Raises
    ------
    ValueError
        Bad map (not HxW, NaN/Inf), clip_percent outside [0, 50), smoothing < 0, unknown floor, a
        focus point outside the image, a keep_sharp mask of another shape or outside [0, 1].

    Notes
    -----
    1. Clip to [P_clip, P_(100−clip)] (percentiles of the map's values, px).
    2. ``"clamp"``, ``"subtract"``, ``"shift"``: the floor (p_lo = max(P_clip, 0) px) removed as
       the mode says, then a Gaussian blur with σ = smoothing·max(H, W) px (reflecting borders).
       ``"auto"`` or a focus point: max(B, 0), the Gaussian blur, then :func:`soft_floor` with the
       floor of :func:`estimate_floor` (or :func:`floor_at_point`) of the smoothed map.
    3. ``keep_sharp``: multiplied by :func:`keep_sharp_weight`.
    """
    m = validate_map(defocus_map, name="defocus_map", allow_negative=True)
    clip_percent = float(clip_percent)
    if not 0.0 <= clip_percent < 50.0:
        raise ValueError(f"clip_percent={clip_percent!r} is invalid; allowed: 0 <= p < 50")
    smoothing = float(smoothing)
    if not (np.isfinite(smoothing) and smoothing >= 0):
        raise ValueError(f"smoothing={smoothing!r} is invalid; allowed: finite and >= 0")
    floor = MAP_FLOOR_MODES.check(floor, what="floor")
    if focus_point is not None:
        _check_focus_point(focus_point, m.shape)
    sigma = smoothing * max(m.shape)
    weight = None if keep_sharp is None else keep_sharp_weight(keep_sharp, m.shape, max(2.0 * sigma, 2.0))
    lo, hi = np.percentile(m, [clip_percent, 100.0 - clip_percent])
    soft = focus_point is not None or "estimated" in MAP_FLOOR_MODES.entry(floor).capabilities
    m = np.clip(m, lo, hi)
    m = np.maximum(m, 0.0) if soft else MAP_FLOOR_MODES[floor](m, max(float(lo), 0.0))
    if sigma > 0:
        m = ndimage.gaussian_filter(m, sigma, mode="reflect")
    m = np.maximum(m, 0.0)
    if soft:
        m = soft_floor(m, floor_at_point(m, focus_point) if focus_point is not None else estimate_floor(m))
    return m if weight is None else m * weight
