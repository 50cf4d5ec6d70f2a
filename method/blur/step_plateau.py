"""Shading told from defocus at the edge measures: does the profile across the edge have plateaus?

Not in the paper. The Eq. (2c) fit matches the 2nd-derivative response of a *blurred step*; smooth
shading (a cosine band, the shading of a curved surface) also gives responses it fits, and reads as a
large σb. What tells them apart, on the luminance the fit measured (``gray``) along the edge normal at
the scale of the measure σb: a blurred step is monotone and flat beyond about 1.5σ on both sides (a
Gaussian step is at 93 % of its contrast at 1.5σ and 99.9 % at 3σ; a disk step at 93 % at 1.5σ and
100 % from its radius 2σ; a linear ramp, which is a box-blurred step, at 100 % from √3 σ). Smooth
periodic shading read as blur σ has its extrema near ±σ and turns back beyond them (no plateau is
*reached*); a shading gradient that keeps rising past the fitted edge is not *flat* there.

What the profile cannot tell: an untextured penumbra between two lit levels *is* a blurred step, and
these tests keep it. A penumbra on a textured surface is rarely measured at all (the texture's edges
spoil the fit's residual test). Measurements: docs/presets.md.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..registry import Entry, Registry

__all__ = ["GAUSSIAN_STEP_REACH", "PLATEAU_FLATNESS", "PLATEAU_MIN_SIGMA", "STEP_GATES", "gate_step_measures",
           "gate_step_pixels", "plateau_profile"]

#: Smallest measure σb (px) the tests judge: below it the plateaus lie within 2 px of the edge, where the
#: pixel filter and the 1-px pre-smoothing shape the profile more than the blur does.
PLATEAU_MIN_SIGMA = 1.0
#: Reach (dimensionless) of a Gaussian step, the smallest of a blurred step's: the mean level over 1.5σ–3σ
#: from the edge, measured from the profile's midpoint, over the level at σ (:func:`plateau_profile`). A
#: disk step gives 1.60, a linear ramp 1.70; a cosine read as blur σ (period ≈ 4σ) −0.27. The smallest
#: reach a kept measure has is ``params.fit_plateau_reach``.
GAUSSIAN_STEP_REACH = 1.401
#: Largest flatness (dimensionless) of a kept measure, on each side: |I(3σb) − I(1.5σb)| over the level
#: at σb (from the midpoint). A Gaussian step gives 0.19, a disk step 0.24, a linear ramp 0.23; a linear
#: shading gradient that continues past the edge 1.5.
PLATEAU_FLATNESS = 0.6

_REACH_U = np.linspace(1.5, 3.0, 7)  # plateau samples, in units of σb from the edge (first and last: flatness)
_SMOOTH = 1.0  # pre-smoothing, px (the smoothed noise std is 1/(2√π) of the pixel's)


def plateau_profile(gray, rows, cols, theta, sigma_b, *, noise_std):
    """Per edge pixel and side, the reach and flatness of the profile across the edge, in units of its core.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance the fit measured, image units.
    rows, cols : ndarray of int, shape (n,)
        Edge pixels.
    theta : ndarray, shape (n,), float
        Gradient direction, radians (intensity rises along (cos θ, sin θ); x right, y down).
    sigma_b : ndarray, shape (n,), float
        The measure σb, px (the test's scale: w = √(max(σb, 1)² + 1), the σ of the step after the 1-px
        pre-smoothing).
    noise_std : float, keyword-only
        Noise std of ``gray``, image units.

    Returns
    -------
    reach, flatness : ndarray, shape (n, 2), float64
        Per side (column 0 dark, 1 bright), with I the luminance smoothed by 1 px and sampled along the
        normal, m = (I(w) + I(−w))/2 and a = (I(w) − I(−w))/2 (the core's half-contrast):
        reach = (mean of ±(I(±u·w) − m) over u ∈ [1.5, 3] + δ) / a and flatness =
        max(|I(±3w) − I(±1.5w)| − δ, 0) / a, with δ three times the smoothed noise std (a noise
        allowance in favour of a step). Dimensionless; :data:`GAUSSIAN_STEP_REACH`, :data:`PLATEAU_FLATNESS`.
    evident : ndarray, shape (n,), bool
        a > 2δ: the core rises above the noise (a measure without that evidence is never rejected).
    """
    smooth = ndimage.gaussian_filter(np.asarray(gray, dtype=np.float64), _SMOOTH, mode="nearest")
    w = np.hypot(np.maximum(np.asarray(sigma_b, dtype=np.float64), 1.0), _SMOOTH)  # the smoothed step's σ
    c, s = np.cos(theta), np.sin(theta)
    u = np.concatenate([[-1.0, 1.0], -_REACH_U, _REACH_U])
    t = w[:, None] * u[None, :]
    y = rows[:, None] + t * s[:, None]
    x = cols[:, None] + t * c[:, None]
    prof = ndimage.map_coordinates(smooth, [y.ravel(), x.ravel()], order=1, mode="nearest").reshape(t.shape)
    m = 0.5 * (prof[:, 0] + prof[:, 1])
    a = 0.5 * (prof[:, 1] - prof[:, 0])
    k = _REACH_U.size
    sides = (m[:, None] - prof[:, 2:2 + k], prof[:, 2 + k:] - m[:, None])  # towards each side, from m
    delta = 3.0 * float(noise_std) / (2.0 * np.sqrt(np.pi) * _SMOOTH)
    with np.errstate(invalid="ignore", divide="ignore"):
        reach = np.stack([(v.mean(axis=1) + delta) / a for v in sides], axis=1)
        flat = np.stack([np.maximum(np.abs(v[:, -1] - v[:, 0]) - delta, 0.0) / a for v in sides], axis=1)
    return reach, flat, a > 2.0 * delta


def _keep(gray, rows, cols, theta, sigma_b, params, *, flat):
    keep = np.ones(rows.size, dtype=bool)
    judged = sigma_b >= PLATEAU_MIN_SIGMA
    if judged.any():
        reach, flatness, evident = plateau_profile(gray, rows[judged], cols[judged], theta[judged],
                                                   sigma_b[judged], noise_std=float(params.noise_std))
        bad = (reach < float(params.fit_plateau_reach)).any(axis=1)
        if flat:
            bad |= (flatness > PLATEAU_FLATNESS).any(axis=1)
        keep[judged] = ~(evident & bad)
    return keep


def _keep_all(gray, rows, cols, theta, sigma_b, params):
    return np.ones(rows.size, dtype=bool)


def _keep_reached(gray, rows, cols, theta, sigma_b, params):
    return _keep(gray, rows, cols, theta, sigma_b, params, flat=False)


def _keep_flat(gray, rows, cols, theta, sigma_b, params):
    return _keep(gray, rows, cols, theta, sigma_b, params, flat=True)


#: name -> fn(gray, rows, cols, theta, sigma_b, params) -> (n,) bool, True where the measure is kept
#: (``BlurParams.fit_step_gate``).
STEP_GATES = Registry("step gate", {
    "none": Entry(_keep_all, "every measure of the fit kept (the paper)"),
    "plateau": Entry(_keep_reached, "no measure where a side's plateau is not reached by 1.5σ–3σ (shading bands)"),
    "plateau_flat": Entry(_keep_flat, "plateau, and no measure where a side keeps changing at 1.5σ–3σ (gradients)"),
})


def gate_step_measures(gray, edge_map, sigma_b, *, params):
    """σb with NaN ("no measure") where the profile across the edge has no plateaus (shading, not defocus).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance the fit measured, in [0, 1].
    edge_map : EdgeMap
        Edges and θ (radians) from ``detect_edges(gray, ...)``.
    sigma_b : ndarray, shape (H, W), float
        The fit's σb, px; NaN where there is no measure.
    params : DefocusParams, keyword-only
        ``fit_step_gate`` (key of :data:`STEP_GATES`), ``fit_plateau_reach`` (dimensionless) and
        ``noise_std`` (image units).

    Returns
    -------
    ndarray, shape (H, W), float64
        ``sigma_b`` itself when the gate is ``"none"``; else a copy, NaN where the gate rejects.

    Notes
    -----
    At each measure with σb ≥ :data:`PLATEAU_MIN_SIGMA` (:func:`plateau_profile`), where the core rises
    above the noise:

    1. ``"plateau"``: rejected where a side's reach is below ``params.fit_plateau_reach``;
    2. ``"plateau_flat"``: 1, and also where a side's flatness exceeds :data:`PLATEAU_FLATNESS`.
    """
    if params.fit_step_gate == "none":
        STEP_GATES.resolve("none", what="DefocusParams.fit_step_gate")
        return sigma_b
    sigma_b = np.array(sigma_b, dtype=np.float64, copy=True)
    rows, cols = np.nonzero(np.isfinite(sigma_b))
    theta = np.asarray(edge_map.theta, dtype=np.float64)[rows, cols]
    keep = gate_step_pixels(gray, rows, cols, theta, sigma_b[rows, cols], params=params)
    sigma_b[rows[~keep], cols[~keep]] = np.nan
    return sigma_b


def gate_step_pixels(gray, rows, cols, theta, sigma_b, *, params):
    """:func:`gate_step_measures` on a list of measures: True where the measure is kept.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance the fit measured, in [0, 1].
    rows, cols : ndarray of int, shape (n,)
        The measures' pixels.
    theta, sigma_b : ndarray, shape (n,), float
        Their gradient direction (radians) and σb (px, finite).
    params : DefocusParams, keyword-only
        As :func:`gate_step_measures`.

    Returns
    -------
    ndarray, shape (n,), bool
    """
    fn = STEP_GATES.resolve(params.fit_step_gate, what="DefocusParams.fit_step_gate")
    if not rows.size:
        return np.ones(0, dtype=bool)
    return fn(np.asarray(gray, dtype=np.float64), rows, cols, theta, sigma_b, params)
