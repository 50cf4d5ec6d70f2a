"""Edge profiles of a step blurred by a thin lens, and the fits that read its blur (of :mod:`scenes.calibration`).

:func:`disk_edge_profile` is the exact image of a step blurred by a uniform disk of diameter c and
integrated over the box pixel footprint; :func:`fit_disk_edge` fits it (c), :func:`fit_erf_edge` fits a
Gaussian edge (σ at pixel centres) and :func:`second_moment_sigma` measures the line-spread second
moment: the two "σ" conventions of :data:`scenes.thin_lens.SIGMA_CONVENTIONS`. Positions and blur in
pixels.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["disk_edge_profile", "fit_disk_edge", "fit_erf_edge", "second_moment_sigma"]


def _disk_esf_antiderivative(t):
    """∫ F(t) dt of the unit-radius disk's edge-spread function F, with H(t) = 0 for t ≤ −1.

    F(t) = 1/2 + (t·√(1 − t²) + asin t)/π on [−1, 1] (fraction of the disk left of t), so
    H(t) = t/2 + (t·asin t + √(1 − t²) − (1 − t²)^{3/2}/3)/π, and H(t) = t for t ≥ 1.
    """
    t = np.asarray(t, dtype=np.float64)
    u = np.clip(t, -1.0, 1.0)
    s = np.sqrt(np.maximum(1.0 - u * u, 0.0))
    inside = u / 2.0 + (u * np.arcsin(u) + s - s**3 / 3.0) / np.pi
    return np.where(t <= -1.0, 0.0, np.where(t >= 1.0, t, inside))


def _disk_esf_correction(t):
    # h(t) = H(t) − max(t, 0): bounded, zero outside (−1, 1); avoids cancellation of large H.
    t = np.asarray(t, dtype=np.float64)
    return np.where(np.abs(t) < 1.0, _disk_esf_antiderivative(t) - np.maximum(t, 0.0), 0.0)


def _disk_edge_profile(x, edge, coc):
    # Box-averaged disk ESF: (1/1px)·∫_{x−½}^{x+½} F((u − x0)/r) du = r·[H(b) − H(a)],
    # split as [max(u, 0)] over the pixel (a ramp in px, exact) + r·[h(b) − h(a)].
    r = max(float(coc) / 2.0, 1e-9)
    lo, hi = x - 0.5 - edge, x + 0.5 - edge
    ramp = np.maximum(hi, 0.0) - np.maximum(lo, 0.0)
    return ramp + r * (_disk_esf_correction(hi / r) - _disk_esf_correction(lo / r))


def disk_edge_profile(x_px, *, edge_px, coc_px):
    """Image of a unit step blurred by a uniform disk and integrated over a 1-px box pixel.

    Exact model of a defocused straight edge rendered with a ``box`` reconstruction filter:
    the disk's edge-spread function (the fraction of a disk of diameter ``coc_px`` lying on the
    bright side) averaged over the pixel footprint [x − ½, x + ½]. Dark (0) for x ≪ edge,
    bright (1) for x ≫ edge.

    Parameters
    ----------
    x_px : ndarray, shape (n,)
        Pixel-centre positions, px.
    edge_px : float, keyword-only
        Position of the sharp edge, px.
    coc_px : float, keyword-only
        Circle-of-confusion diameter c, px (≥ 0; 0 gives the box-averaged step).

    Returns
    -------
    ndarray, shape (n,)
        Profile values in [0, 1].
    """
    if not (math.isfinite(coc_px) and coc_px >= 0):
        raise ValueError(f"coc_px={coc_px!r} is invalid; allowed: finite >= 0")
    return _disk_edge_profile(np.asarray(x_px, dtype=np.float64), float(edge_px), float(coc_px))


def _check_profile(profile):
    p = np.asarray(profile, dtype=np.float64)
    if p.ndim != 1 or p.size < 8 or not np.all(np.isfinite(p)):
        raise ValueError(f"profile must be a finite 1-D array with >= 8 samples, got shape {p.shape}")
    return p


def _initial_guess(p):
    """Edge position, a width estimate (px), low and high levels of a monotone-ish edge profile."""
    n = p.size
    k = max(2, n // 16)
    left, right = float(np.median(p[:k])), float(np.median(p[-k:]))
    lo, hi = min(left, right), max(left, right)
    q = (p - lo) / (hi - lo if hi > lo else 1.0)
    if left > right:
        q = 1.0 - q
    x = np.arange(n) + 0.5
    # 10 % and 90 % crossings of the rising profile (counted, robust to noise).
    x10 = float(np.sum(q < 0.1))
    x90 = float(np.sum(q < 0.9))
    x50 = float(np.interp(0.5, np.sort(q), x)) if np.all(np.diff(q) >= 0) else float(np.sum(q < 0.5))
    return x50, max(x90 - x10, 0.5), left, right


def _edge_fit_result(solution, width_name):
    """The fit of an edge model p ≈ B + A·G(x; x0, w) as a dict; ``solution.x`` = (x0, w, A, B)."""
    x0, width, a, b = solution.x
    return {
        width_name: float(abs(width)),
        "edge_px": float(x0),
        "amplitude": float(a),
        "offset": float(b),
        "rms_residual": float(np.sqrt(np.mean(solution.fun**2))),
    }


def fit_disk_edge(profile):
    """Fit the disk-blurred, box-integrated step (:func:`disk_edge_profile`) to an edge profile.

    Model: p(x) ≈ B + A·G(x; x0, c), with pixel i centred at x = i + ½. A may be negative
    (bright side on the left, as Mitsuba's camera frame puts world +x on the image left).

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Edge profile (row average of a rendered edge), any linear intensity unit; n ≥ 8.

    Returns
    -------
    dict
        ``coc_px`` (fitted c, px), ``edge_px`` (x0, px), ``amplitude`` A, ``offset`` B,
        ``rms_residual`` (same unit as the profile).

    Notes
    -----
    1. Initial edge and width from the 10/50/90 % crossings (the disk's 10–90 % width ≈ 0.61·c).
    2. Levenberg–Marquardt (``scipy.optimize.least_squares``) over (x0, c, A, B), c ≥ 0.
    """
    from scipy.optimize import least_squares

    p = _check_profile(profile)
    x = np.arange(p.size) + 0.5
    x50, width, left, right = _initial_guess(p)
    a0, b0 = right - left, left  # G runs 0 → 1 left → right; A < 0 when the bright side is left

    def resid(theta):
        x0, c, a, b = theta
        return b + a * _disk_edge_profile(x, x0, abs(c)) - p

    best = None
    for c_start in (width / 0.61, width / 0.61 * 0.5, width / 0.61 * 1.5, 0.5):
        sol = least_squares(resid, [x50, max(c_start, 0.05), a0, b0], method="lm", x_scale="jac")
        if best is None or sol.cost < best.cost:
            best = sol
    return _edge_fit_result(best, "coc_px")


def fit_erf_edge(profile):
    """Least-squares fit of a Gaussian-blurred step (erf) sampled at pixel centres.

    p(x) ≈ B + A·Φ((x − x0)/σ), Φ the standard normal CDF. The fitted σ includes the pixel
    footprint (≈ √(σ_blur² + 1/12) for a box filter); for a disk edge σ_blur ≈ 0.273·c
    (``coc_to_sigma(convention="erf_fit")``).

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Edge profile.

    Returns
    -------
    dict
        ``sigma_px`` (σ, px), ``edge_px``, ``amplitude``, ``offset``, ``rms_residual``.
    """
    from scipy.optimize import least_squares
    from scipy.special import ndtr

    p = _check_profile(profile)
    x = np.arange(p.size) + 0.5
    x50, width, left, right = _initial_guess(p)

    def resid(theta):
        x0, s, a, b = theta
        return b + a * ndtr((x - x0) / max(abs(s), 1e-6)) - p

    sol = least_squares(resid, [x50, max(width / 2.563, 0.3), right - left, left], method="lm",
                        x_scale="jac")
    return _edge_fit_result(sol, "sigma_px")


def second_moment_sigma(profile, *, edge_px, half_window_px):
    """Standard deviation of the edge's line-spread function (second moment), px.

    The LSF is estimated by differencing adjacent pixels, which samples LSF ⊗ pixel-box ⊗ box
    at the pixel boundaries; the extra differencing box (variance 1/12 px²) is subtracted, so
    the result estimates √(c²/16 + 1/12) for a disk of diameter c rendered with a box filter
    (``coc_to_sigma(c, convention="line_spread")``).

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Edge profile.
    edge_px : float, keyword-only
        Edge position (px) — the window centre, e.g. from :func:`fit_disk_edge`.
    half_window_px : float, keyword-only
        Half-width of the window the moment is taken over, px (> 0); e.g. c/2 + 4.

    Returns
    -------
    float
        σ in px (NaN when the windowed LSF has no mass).
    """
    p = _check_profile(profile)
    if not half_window_px > 0:
        raise ValueError(f"half_window_px={half_window_px!r} is invalid; allowed: > 0")
    d = np.diff(p)
    xb = np.arange(1, p.size, dtype=np.float64)  # boundary between pixel i−1 and i
    keep = np.abs(xb - edge_px) <= half_window_px
    w = d[keep]
    w = w * np.sign(w.sum()) if w.sum() != 0 else w
    total = w.sum()
    if not total > 0:
        return float("nan")
    mu = float(np.sum(w * xb[keep]) / total)
    var = float(np.sum(w * (xb[keep] - mu) ** 2) / total) - 1.0 / 12.0
    return float(np.sqrt(max(var, 0.0)))
