"""Isolation weights of edge blur measures (beyond the paper): close edges bias a fit, so they weigh less.

An edge fit (Eq. 2) models one step. Where another edge lies within ≈ 3σ̂ — the two sides of a
bar, the dense edges of blurry texture — the responses overlap and the fitted width is wrong. The
weight of each measure here says how far it is from that case; it multiplies the measure's
confidence c_q, hence its weight in Eq. (3) and its α_p in Eq. (4).

Methods (:data:`EDGE_ISOLATION_METHODS`, chosen by ``DefocusParams.edge_isolation``):

* ``"normal"`` — the distance d from the measure to the nearest *other* edge pixel along its
  gradient normal (both sides). The measure's own edge segment runs along the tangent, so a ray
  along the normal leaves it at once; the search starts 1.5 px out.
* ``"persistence"`` — after Karaali & Jung, "Edge-based defocus blur estimation with adaptive scale
  selection", IEEE TIP 2018: an edge that is still found (Canny, within 1.5 px) when the image is
  smoothed at a scale ≈ its search radius has no close neighbour; the edges of a bar move apart
  (to ±s at scale s ≫ the bar's width) and are lost at their position. Weight 1 when it persists,
  the floor otherwise.
"""

from __future__ import annotations

import numpy as np

from ..registry import Entry, Registry

__all__ = ["EDGE_ISOLATION_METHODS", "isolation_weights"]

#: First sample of the normal ray, px: past the measure's own (≈ 1-px thick) edge line.
NORMAL_RAY_START_PX = 1.5
#: Step of the normal ray, px.
NORMAL_RAY_STEP_PX = 0.5
#: Smallest σ̂ the search radius is scaled by, px (an in-focus edge's response is ≈ 1 px wide).
MIN_SCALE_PX = 1.0
#: Distance, px, within which a coarse-scale Canny edge counts as the same edge ("persistence").
PERSISTENCE_TOLERANCE_PX = 1.5


def _normal_distance(edges, theta, ys, xs, radius):
    """Distance, px, along ±(cos θ, sin θ) to the first other edge pixel within ``radius`` (inf: none)."""
    h, w = edges.shape
    c, s = np.cos(theta), np.sin(theta)
    d = np.full(ys.shape, np.inf)
    t_max = float(np.max(radius)) if radius.size else 0.0
    for t in np.arange(NORMAL_RAY_START_PX, t_max + 1e-9, NORMAL_RAY_STEP_PX):
        open_ = np.isinf(d) & (t <= radius)
        if not open_.any():
            break
        for sign in (1.0, -1.0):
            yy = np.rint(ys + sign * t * s).astype(np.intp)
            xx = np.rint(xs + sign * t * c).astype(np.intp)
            inside = open_ & (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
            hit = np.zeros(ys.shape, dtype=bool)
            hit[inside] = edges[yy[inside], xx[inside]]
            d[hit & np.isinf(d)] = t
    return d


def _weights_normal(gray, edges, theta, sigma, *, radius, floor):
    ys, xs = np.nonzero(np.isfinite(sigma))
    r = radius * np.maximum(sigma[ys, xs], MIN_SCALE_PX)
    d = _normal_distance(edges, theta[ys, xs], ys.astype(np.float64), xs.astype(np.float64), r)
    w = np.where(np.isfinite(d), floor + (1.0 - floor) * np.minimum(d / r, 1.0) ** 2, 1.0)
    out = np.full(sigma.shape, np.nan)
    out[ys, xs] = w
    return out


def _weights_persistence(gray, edges, theta, sigma, *, radius, floor):
    from scipy import ndimage
    from skimage.feature import canny

    out = np.full(sigma.shape, np.nan)
    finite = np.isfinite(sigma)
    if not finite.any():
        return out
    # one Canny scale per octave of the search radius R·max(σ̂, 1) / 2 (the scale at which a
    # neighbour at distance R·σ̂ merges), measures assigned to the nearest octave
    scale = radius * np.maximum(sigma, MIN_SCALE_PX) / 2.0
    octave = np.where(finite, np.rint(np.log2(np.where(finite, scale, 1.0))), 0.0)
    for k in np.unique(octave[finite]):
        sel = finite & (octave == k)
        coarse = canny(gray, sigma=float(2.0 ** k))
        near = ndimage.distance_transform_edt(~coarse) <= PERSISTENCE_TOLERANCE_PX
        out[sel] = np.where(near[sel], 1.0, floor)
    return out


#: name -> fn(gray, edges, theta, sigma, *, radius, floor) -> HxW weights (NaN off measures).
EDGE_ISOLATION_METHODS = Registry("edge isolation method", {
    "normal": Entry(_weights_normal, "distance to the next edge along the gradient normal"),
    "persistence": Entry(_weights_persistence, "survives at a coarse Canny scale (Karaali & Jung 2018)"),
})


def isolation_weights(gray, edges, theta, sigma, *, method="normal", radius=3.0, floor=0.1) -> np.ndarray:
    """Weight in (0, 1] of every edge blur measure by its isolation from other edges.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (used by ``"persistence"``).
    edges : ndarray, shape (H, W), bool
        Edge pixels (:attr:`method.edges.elder_zucker.EdgeMap.edges`).
    theta : ndarray, shape (H, W), float
        Gradient direction, rad (:attr:`~method.edges.elder_zucker.EdgeMap.theta`).
    sigma : ndarray, shape (H, W), float
        Blur measures σ̂, px, NaN where none.
    method : str, keyword-only
        Key of :data:`EDGE_ISOLATION_METHODS`.
    radius : float, keyword-only
        Search radius in units of max(σ̂, 1 px) (≈ 3: the reach of a blurred edge's response), > 0.
    floor : float, keyword-only
        Weight of a measure whose neighbour edge touches it, in (0, 1].

    Returns
    -------
    ndarray, shape (H, W), float64
        Weight in [floor, 1] at the finite measures of ``sigma``, NaN elsewhere.

    Raises
    ------
    ValueError
        Unknown method (the message lists the allowed ones), shapes that differ, radius ≤ 0 or a
        floor outside (0, 1].

    Notes
    -----
    ``"normal"``:

    1. For each measure p, r_p = radius·max(σ̂_p, 1 px) and the unit normal n_p = (cos θ_p, sin θ_p).
    2. Walk p ± t·n_p for t = 1.5, 2, …, r_p px (nearest pixel); d_p = the first t that lands on an
       edge pixel (the own segment lies along the tangent and is not met), ∞ if none.
    3. w_p = floor + (1 − floor)·min(d_p / r_p, 1)², and 1 when d_p = ∞.

    ``"persistence"``:

    1. s_p = radius·max(σ̂_p, 1 px) / 2, rounded to the nearest octave 2^k.
    2. Per octave, Canny edges of ``gray`` at σ = 2^k (scikit-image).
    3. w_p = 1 where a Canny edge lies within 1.5 px of p, else ``floor``.
    """
    gray = np.asarray(gray, dtype=np.float64)
    edges = np.asarray(edges, dtype=bool)
    theta = np.asarray(theta, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    if gray.ndim != 2 or not (gray.shape == edges.shape == theta.shape == sigma.shape):
        raise ValueError(f"gray, edges, theta and sigma must share one (H, W) shape; got {gray.shape}, "
                         f"{edges.shape}, {theta.shape}, {sigma.shape}")
    fn = EDGE_ISOLATION_METHODS.resolve(method, what="method")
    if not (0 < radius < np.inf):
        raise ValueError(f"radius={radius!r} is invalid; allowed: finite and > 0")
    if not (0 < floor <= 1):
        raise ValueError(f"floor={floor!r} is invalid; allowed: 0 < floor <= 1")
    return fn(gray, edges, theta, sigma, radius=float(radius), floor=float(floor))
