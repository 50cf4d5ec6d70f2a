"""Analytic edges with known Gaussian blur, point-sampled from closed forms (Sec. 3.1 / 3.2 ground truth).

* :func:`step_edge` — a straight step at any orientation and sub-pixel offset, profile
  ``low + (high − low)·Φ(t/σ)`` (Φ = standard normal CDF, i.e. an erf).
* :func:`blurred_disk` — a disk of radius R convolved with a 2-D Gaussian; the value at distance ρ
  from the centre is the non-central χ² CDF P(χ²₂(ρ²/σ²) ≤ R²/σ²) (exact).
* :func:`parallel_edges` — two parallel steps at a given spacing (a bar, or a two-step staircase).

Every image is *point-sampled* at pixel centres, so the ground-truth blur is exactly the Gaussian σ
(px) that was applied — no discretisation or pixel-area blur. Edges blurred the way a lens blurs
(a disk in linear light, integrated over the pixel) are :func:`scenes.analytic.lens.lens_step_edge`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.special import chndtr, ndtr

from ._common import check_levels, check_shape, check_sigma, degrade

__all__ = ["AnalyticImage", "blurred_disk", "parallel_edges", "step_edge"]


@dataclasses.dataclass(frozen=True)
class AnalyticImage:
    """An analytic test image and its ground truth.

    Attributes
    ----------
    image : ndarray, shape (H, W), float64
        The image in [0, 1] (after optional noise and quantisation).
    sigma : float
        Ground-truth Gaussian blur σ of every edge, px.
    edge_distance : ndarray, shape (H, W), float64
        Signed distance (px) from each pixel centre to the nearest edge, positive on the bright side.
    edge_mask : ndarray, shape (H, W), bool
        Pixels "on" an edge: |edge_distance| < max(|cos θ|, |sin θ|)/2 (one pixel per row or
        column across the edge — the thin digital curve an ideal detector would mark).
    normal : ndarray, shape (H, W), float64
        Direction θ (radians, x right, y down) in which intensity increases across the nearest edge.
    """

    image: np.ndarray
    sigma: float
    edge_distance: np.ndarray
    edge_mask: np.ndarray
    normal: np.ndarray


def _profile(t, sigma):
    """Φ(t/σ) (a unit step for σ = 0, 1/2 exactly on the step)."""
    if sigma == 0:
        return np.where(t > 0, 1.0, np.where(t < 0, 0.0, 0.5))
    return ndtr(t / sigma)


def _grid(h, w, center):
    cy, cx = ((h - 1) / 2.0, (w - 1) / 2.0) if center is None else (float(center[0]), float(center[1]))
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    return x - cx, y - cy


def edge_pixels(dist, normal):
    half = 0.5 * np.maximum(np.abs(np.cos(normal)), np.abs(np.sin(normal)))
    return (dist >= -half) & (dist < half)


def step_edge(shape, *, sigma, angle=0.0, offset=0.0, center=None, low=0.2, high=0.8,
              noise_std=0.0, quantize_bits=None, rng=None):
    """A straight step edge blurred by a Gaussian of std ``sigma``, sampled exactly.

    Parameters
    ----------
    shape : (int, int)
        (H, W), px.
    sigma : float, keyword-only
        Blur σ, px (0 = unblurred step).
    angle : float, keyword-only
        Normal direction θ, radians (x right, y down): intensity rises along (cos θ, sin θ).
    offset : float, keyword-only
        Signed distance (px) of the edge line from ``center`` along the normal (sub-pixel shifts).
    center : (float, float) or None, keyword-only
        (row, col) of the reference point; default the image centre.
    low, high : float, keyword-only
        Intensities on the dark and bright side, in [0, 1].
    noise_std, quantize_bits, rng : keyword-only
        See :func:`degrade`.

    Returns
    -------
    AnalyticImage
        ``sigma`` is the blur; ``edge_distance`` = (x, y)·u − offset.

    Notes
    -----
    1. t = (x − cx) cos θ + (y − cy) sin θ − offset at every pixel centre.
    2. I = low + (high − low)·Φ(t/σ).
    3. Optional noise and quantisation (:func:`degrade`).
    """
    h, w = check_shape(shape)
    s = check_sigma(sigma)
    check_levels(low, high)
    x, y = _grid(h, w, center)
    t = x * np.cos(angle) + y * np.sin(angle) - offset
    img = low + (high - low) * _profile(t, s)
    img = degrade(img, noise_std=noise_std, quantize_bits=quantize_bits, rng=rng)
    normal = np.full((h, w), float(np.arctan2(np.sin(angle), np.cos(angle))))
    if high < low:
        normal = np.arctan2(-np.sin(normal), -np.cos(normal))
    dist = t if high > low else -t
    return AnalyticImage(image=img, sigma=s, edge_distance=dist, edge_mask=edge_pixels(dist, normal), normal=normal)


def blurred_disk(shape, *, sigma, radius, center=None, inside=0.8, outside=0.2,
                 noise_std=0.0, quantize_bits=None, rng=None):
    """A disk (curved edge) of radius ``radius`` convolved with a 2-D Gaussian of std ``sigma``.

    Parameters
    ----------
    shape : (int, int)
        (H, W), px.
    sigma : float, keyword-only
        Blur σ, px.
    radius : float, keyword-only
        Disk radius R, px (> 0).
    center : (float, float) or None, keyword-only
        (row, col) of the disk centre; default the image centre (sub-pixel values allowed).
    inside, outside : float, keyword-only
        Intensities inside and outside the disk, in [0, 1].
    noise_std, quantize_bits, rng : keyword-only
        See :func:`degrade`.

    Returns
    -------
    AnalyticImage
        ``edge_distance`` = (R − ρ) if the disk is brighter, else (ρ − R).

    Notes
    -----
    1. ρ = distance of each pixel centre from the disk centre.
    2. (disk ∗ g_σ)(ρ) = P(|X + ρ| ≤ R), X ~ N(0, σ²I₂) = chndtr(R²/σ², 2, ρ²/σ²), the CDF of a
       non-central χ² with 2 degrees of freedom — exact. Evaluated only where |ρ − R| < 12σ
       (elsewhere it is 0 or 1 to double precision).
    3. Optional noise and quantisation.
    """
    h, w = check_shape(shape)
    s = check_sigma(sigma)
    check_levels(inside, outside)
    r = float(radius)
    if not r > 0:
        raise ValueError(f"radius={radius!r} is invalid; allowed: > 0 px")
    x, y = _grid(h, w, center)
    rho = np.hypot(x, y)
    if s == 0:
        frac = np.where(rho < r, 1.0, np.where(rho > r, 0.0, 0.5))
    else:
        frac = (rho < r).astype(np.float64)
        band = np.abs(rho - r) < 12.0 * s
        frac[band] = chndtr((r / s) ** 2, 2.0, (rho[band] / s) ** 2)
    img = outside + (inside - outside) * frac
    img = degrade(img, noise_std=noise_std, quantize_bits=quantize_bits, rng=rng)
    inward = np.arctan2(-y, -x)  # direction towards the centre
    if inside > outside:
        normal, dist = inward, r - rho
    else:
        normal, dist = np.arctan2(y, x), rho - r
    return AnalyticImage(image=img, sigma=s, edge_distance=dist, edge_mask=edge_pixels(dist, normal), normal=normal)


def parallel_edges(shape, *, sigma, spacing, angle=0.0, offset=0.0, kind="bar", center=None,
                   low=0.2, high=0.8, noise_std=0.0, quantize_bits=None, rng=None):
    """Two parallel blurred steps ``spacing`` px apart (the neighbouring-edge case of Fig. 4).

    Parameters
    ----------
    shape : (int, int)
        (H, W), px.
    sigma : float, keyword-only
        Blur σ of both edges, px.
    spacing : float, keyword-only
        Distance D between the two edge lines, px (> 0).
    angle : float, keyword-only
        Direction θ of the first edge's normal (intensity rises along it), radians.
    offset : float, keyword-only
        Position of the midline between the edges along the normal, px from ``center``.
    kind : {"bar", "staircase"}, keyword-only
        "bar": a bright bar of width D (rise then fall: the two edges have opposite polarity);
        "staircase": two rises, low → mid → high (same polarity).
    center : (float, float) or None, keyword-only
        (row, col) reference point; default the image centre.
    low, high : float, keyword-only
        Background and peak intensities in [0, 1].
    noise_std, quantize_bits, rng : keyword-only
        See :func:`degrade`.

    Returns
    -------
    AnalyticImage
        ``edge_distance`` is the signed distance to the nearer edge line (positive on its bright
        side); ``normal`` is the rising direction across that edge.

    Notes
    -----
    1. t = (x, y)·u − offset; edges at t = ±D/2.
    2. bar: I = low + (high − low)(Φ((t + D/2)/σ) − Φ((t − D/2)/σ));
       staircase: I = low + (high − low)/2·(Φ((t + D/2)/σ) + Φ((t − D/2)/σ)).
    """
    h, w = check_shape(shape)
    s = check_sigma(sigma)
    check_levels(low, high)
    if not spacing > 0:
        raise ValueError(f"spacing={spacing!r} is invalid; allowed: > 0 px")
    if kind not in ("bar", "staircase"):
        raise ValueError(f"kind={kind!r} is invalid; allowed: 'bar', 'staircase'")
    x, y = _grid(h, w, center)
    t = x * np.cos(angle) + y * np.sin(angle) - offset
    half = spacing / 2.0
    a, b = _profile(t + half, s), _profile(t - half, s)
    if kind == "bar":
        img = low + (high - low) * (a - b)
    else:
        img = low + 0.5 * (high - low) * (a + b)
    img = degrade(img, noise_std=noise_std, quantize_bits=quantize_bits, rng=rng)
    th = float(np.arctan2(np.sin(angle), np.cos(angle)))
    first = t < 0  # nearer to the edge at −D/2
    if kind == "bar":
        # first edge rises along u, the second rises along −u
        dist = np.where(first, t + half, half - t)
        normal = np.where(first, th, np.arctan2(-np.sin(th), -np.cos(th)))
    else:
        dist = np.where(first, t + half, t - half)
        normal = np.full((h, w), th)
    if high < low:
        dist = -dist
        normal = np.arctan2(-np.sin(normal), -np.cos(normal))
    return AnalyticImage(image=img, sigma=s, edge_distance=dist, edge_mask=edge_pixels(dist, normal), normal=normal)
