"""Fusion of edge and region blur measures as data terms of Eq. (4), by inverse variance (beyond the paper).

Eq. (4) has one data term per edge pixel, α_p (B(p) − BM(p))². A region (spectral) estimator adds
measures σ_r with a Fisher information I (px⁻²) at its window centres. Both enter the same energy

    E(B) = smoothness + Σ_e α·w_e (B(e) − σ_e)² + Σ_r α·w_r (B(r) − σ_r)²,

with weights proportional to each measure's inverse variance. The edge measures keep today's weight
w_e = c_e (their confidence); a region measure is weighed against an edge measure of the same σ:

    w_r = W_r · g_r · v_e(σ_r) / v_r,   v_e(σ) = (ε_e σ + δ)²,   v_r = 1/I + (ε_r σ_r)² + δ²,

δ = :data:`ERROR_FLOOR_PX`, W_r = ``fusion_region_weight`` (a region term stands for a window of
pixels), ε_e / ε_r the relative model errors of the two cues and g_r the blur-island factor below.
Two data terms at one pixel are one term at their inverse-variance-weighted mean with the summed
weight: w_e (B − σ_e)² + w_r (B − σ_r)² = (w_e + w_r)(B − σ̄)² + const, σ̄ = (w_e σ_e + w_r σ_r) /
(w_e + w_r); :func:`fuse_measures` does exactly that, so the solver still sees one term per pixel.

Blur islands: a wide smooth ramp (in-focus soft shading) has no fine detail, so a spectral fit reads
it as blur; the sharp edges of the same surface say otherwise. A region measure whose block has no
high-frequency texture and either has such texture within ``fusion_island_radius`` px or has no
texture at its own blur scale either (:func:`blur_islands`) has its weight multiplied by
``fusion_island_weight``.

Straddled windows: a region window holding an isolated strong edge reads that edge's spectrum, not
a texture's; the edge fit is exact there, so such region measures are multiplied by
``fusion_straddle_weight`` (:func:`straddled_windows`).
"""

from __future__ import annotations

import numpy as np

from ..registry import Entry, Registry

__all__ = ["ERROR_FLOOR_PX", "REGION_PLACEMENTS", "blur_islands", "fuse_cues", "fuse_measures",
           "region_data_term", "straddled_windows"]

#: Absolute error floor δ of both cues' error models, px (8-bit quantisation, sub-pixel sampling).
ERROR_FLOOR_PX = 0.1
#: Gaussian σ, px, of the fine-scale detail d = I − G_σ ∗ I of the island test.
ISLAND_DETAIL_SIGMA_PX = 1.0
#: Gaussian σ, px, over which the detail energy d² is averaged (a block's neighbourhood).
ISLAND_AVERAGE_SIGMA_PX = 4.0
#: A pixel has high-frequency texture when its averaged detail energy exceeds this × the energy the
#: image noise alone gives (noise_std² · Σ(δ − g)²).
ISLAND_TEXTURE_FACTOR = 4.0
#: Smallest std of the band at the blur's own scale that counts as texture there, image units
#: (2 grey levels of 8 bits).
ISLAND_BAND_MIN_STD = 2.0 / 255
#: Reach of the band test, in units of its scale s: the band G_s − G_2s averaged by G_2s sees
#: detail up to ≈ 6 s away, so fine texture that near also counts as "around" the measure.
ISLAND_BAND_REACH = 6.0


def _detail_noise_gain(sigma: float) -> float:
    """Σ (δ − g_σ)² over the kernel: the variance of I − G_σ ∗ I for unit white noise."""
    from scipy import ndimage

    n = 2 * int(np.ceil(4 * sigma)) + 1
    impulse = np.zeros((n, n))
    impulse[n // 2, n // 2] = 1.0
    k = impulse - ndimage.gaussian_filter(impulse, sigma, mode="constant")
    return float(np.sum(k * k))


def blur_islands(gray, *, noise_std, radius, sigma=None) -> np.ndarray:
    """Blur islands: pixels without fine texture whose blur reading has no support around them.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    noise_std : float, keyword-only
        Image noise std, image units (``DefocusParams.noise_std``), > 0.
    radius : float, keyword-only
        Neighbourhood radius, px, > 0.
    sigma : ndarray, shape (H, W), float, or None, keyword-only
        The blur σ_r, px, read at each pixel (NaN: not tested); None: only the neighbourhood test.

    Returns
    -------
    ndarray, shape (H, W), bool

    Notes
    -----
    1. Fine detail d = I − G_1 ∗ I (σ = :data:`ISLAND_DETAIL_SIGMA_PX`); energy e = G_4 ∗ d²
       (:data:`ISLAND_AVERAGE_SIGMA_PX`); fine texture: e > :data:`ISLAND_TEXTURE_FACTOR` ·
       noise_std² · Σ(δ − g_1)².
    2. Where there is no fine texture, the pixel is an island when fine texture lies within
       max(``radius``, 6 s) px (sharp detail of the same surface beside it), or — with ``sigma`` — when the
       image has no texture at the blur's own scale either: band energy G_{2s} ∗ (G_s ∗ I − G_{2s} ∗
       I)² at s = max(σ_r, 1 px) (octaves) ≤ :data:`ISLAND_TEXTURE_FACTOR` × the noise's, or ≤
       (:data:`ISLAND_BAND_MIN_STD`)². A blurred texture keeps that band; a wide smooth ramp (linear
       over the band's reach) has none.
    """
    from scipy import ndimage

    gray = np.asarray(gray, dtype=np.float64)
    if gray.ndim != 2:
        raise ValueError(f"gray must be (H, W); got shape {gray.shape}")
    if not noise_std > 0:
        raise ValueError(f"noise_std={noise_std!r} is invalid; allowed: > 0")
    if not (0 < radius < np.inf):
        raise ValueError(f"radius={radius!r} is invalid; allowed: finite and > 0 (px)")
    detail = gray - ndimage.gaussian_filter(gray, ISLAND_DETAIL_SIGMA_PX, mode="reflect")
    energy = ndimage.gaussian_filter(detail * detail, ISLAND_AVERAGE_SIGMA_PX, mode="reflect")
    textured = energy > ISLAND_TEXTURE_FACTOR * noise_std ** 2 * _detail_noise_gain(ISLAND_DETAIL_SIGMA_PX)
    dist = ndimage.distance_transform_edt(~textured) if textured.any() else np.full(gray.shape, np.inf)
    island = ~textured & (dist <= radius)
    if sigma is not None:
        sigma = np.asarray(sigma, dtype=np.float64)
        test = np.isfinite(sigma) & ~textured & ~island
        if test.any():
            octave = np.rint(np.log2(np.maximum(np.where(test, sigma, 1.0), 1.0)))
            for k in np.unique(octave[test]):
                band_s = float(2.0 ** k)
                # fine texture within the band's own reach (≈ 6 s) is "around" it too
                near = test & (octave == k) & (dist <= ISLAND_BAND_REACH * band_s)
                island[near] = True
                sel = test & (octave == k) & ~near
                g1 = ndimage.gaussian_filter(gray, band_s, mode="reflect")
                band = g1 - ndimage.gaussian_filter(g1, np.sqrt(3.0) * band_s, mode="reflect")  # G_s − G_2s
                e_b = ndimage.gaussian_filter(band * band, 2.0 * band_s, mode="reflect")
                thr = max(ISLAND_TEXTURE_FACTOR * noise_std ** 2 * _band_noise_gain(band_s),
                          ISLAND_BAND_MIN_STD ** 2)
                island[sel] = e_b[sel] <= thr
    return island


def _band_noise_gain(s: float) -> float:
    """Σ (g_s − g_2s)² over the kernel: the variance of the band G_s ∗ I − G_2s ∗ I for unit white noise."""
    from scipy import ndimage

    n = 2 * int(np.ceil(8 * s)) + 1
    impulse = np.zeros((n, n))
    impulse[n // 2, n // 2] = 1.0
    g1 = ndimage.gaussian_filter(impulse, s, mode="constant")
    k = g1 - ndimage.gaussian_filter(impulse, 2.0 * s, mode="constant")
    return float(np.sum(k * k))


def straddled_windows(isolated_edges, sigma, *, window_scale, window_min, window_max, min_fraction=0.5) -> np.ndarray:
    """Region measures whose window holds an isolated edge: the edge fit measures it better.

    Parameters
    ----------
    isolated_edges : ndarray, shape (H, W), bool
        Edge measures with no other edge within their isolation radius
        (:func:`method.edges.isolation.isolation_weights` = 1).
    sigma : ndarray, shape (H, W), float
        Region σ_r, px (NaN: not tested).
    window_scale, window_min, window_max : float, int, int, keyword-only
        The region estimator's window side: clip(window_scale·σ_r, window_min, window_max) px
        (``RegionParams.region_window_*``; no defaults, so they cannot drift from the estimator's).
    min_fraction : float, keyword-only
        A window is straddled when it holds ≥ min_fraction × its side of isolated edge pixels (a
        straight edge across it has ≈ one per row).

    Returns
    -------
    ndarray, shape (H, W), bool

    Notes
    -----
    A single strong edge in a window dominates its spectrum (1/f² along one direction only, not the
    isotropic texture the region likelihood assumes: on the accuracy bench's straight steps the
    region σ reads 15–25 % high), while the edge fit is exact there. Per octave of the window side,
    count the isolated edge pixels in the window (box filter) and flag the measures above the limit.
    """
    from scipy import ndimage

    iso = np.asarray(isolated_edges, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    out = np.zeros(sigma.shape, dtype=bool)
    test = np.isfinite(sigma)
    if not test.any() or not iso.any():
        return out
    side = np.clip(window_scale * np.where(test, sigma, 0.0), window_min, window_max)
    octave = np.rint(np.log2(side))
    for k in np.unique(octave[test]):
        sel = test & (octave == k)
        n = int(min(max(2.0 ** k, window_min), window_max)) | 1
        count = ndimage.uniform_filter(iso, size=n, mode="constant") * n * n
        out[sel] = count[sel] >= min_fraction * n
    return out


def _place_centres(sigma, weight, stride):
    """One term per stride block at its centre pixel, with the block's weight (density × stride²)."""
    finite = np.isfinite(sigma)
    if finite.mean() < 0.5:  # already sparse (measures at their centres): as given
        return sigma, weight
    centre = np.zeros(sigma.shape, dtype=bool)
    centre[stride // 2::stride, stride // 2::stride] = True
    keep = centre & finite
    return np.where(keep, sigma, np.nan), np.where(keep, weight * float(stride * stride), 0.0)


def _place_blocks(sigma, weight, stride):
    """Each measure's value to the pixels nearest to it (within one grid spacing), weight shared."""
    from scipy import ndimage

    finite = np.isfinite(sigma)
    n = int(finite.sum())
    if n == 0 or finite.all():
        return sigma, weight
    spacing = float(np.sqrt(sigma.size / n))  # mean grid step of the measures, px
    dist, (iy, ix) = ndimage.distance_transform_edt(~finite, return_indices=True)
    cell = dist <= spacing
    label = np.where(cell, iy * sigma.shape[1] + ix, -1)
    counts = np.bincount(label[cell], minlength=sigma.size)
    out_s = np.where(cell, sigma[iy, ix], np.nan)
    out_w = np.where(cell, weight[iy, ix] / np.maximum(counts[np.where(cell, label, 0)], 1), 0.0)
    return out_s, out_w


#: name -> fn(sigma, weight, stride) -> (sigma, weight): where the region measures enter Eq. (4). A
#: dense region map (every pixel of a block carries its window's measure, information a per-pixel
#: density) is already "blocks"; a sparse one (measures at window centres only) already "centres".
REGION_PLACEMENTS = Registry("region placement", {
    "centres": Entry(_place_centres, "one term per block, at its window centre"),
    "blocks": Entry(_place_blocks, "spread over the block of pixels nearest to each centre"),
})


def region_data_term(region_sigma, region_information, *, gray=None, edge_error_rel=0.5,
                     region_error_rel=0.3, region_weight=1.0, placement="centres", island_weight=1.0,
                     island_radius=24.0, noise_std=2.5 / 255, stride, isolated_edges=None,
                     straddle_weight=1.0, window):
    """Values and relative weights w_r of the region measures as data terms of Eq. (4).

    Parameters
    ----------
    region_sigma : ndarray, shape (H, W), float
        Region blur σ_r, px, NaN where there is no measure.
    region_information : ndarray, shape (H, W), float
        Fisher information I of σ_r, px⁻² (1 / variance), ≥ 0 at the measures.
    gray : ndarray, shape (H, W), float, optional, keyword-only
        Luminance in [0, 1]; needed when ``island_weight`` < 1.
    edge_error_rel, region_error_rel : float, keyword-only
        ε_e, ε_r of the error models (module docstring), dimensionless, ≥ 0.
    region_weight : float, keyword-only
        W_r, dimensionless, > 0.
    placement : str, keyword-only
        Key of :data:`REGION_PLACEMENTS`.
    island_weight : float, keyword-only
        g_r of a measure in a blur island (:func:`blur_islands`), in [0, 1]; 1: no island test,
        0: island measures dropped.
    island_radius : float, keyword-only
        Neighbourhood radius of the island test, px.
    noise_std : float, keyword-only
        Image noise std of the island test, image units.
    stride : int, keyword-only
        Spacing of the region estimator's window centres, px (``RegionParams.region_stride``; required,
        as ``window``: they describe the estimator's grid and must match it).
    isolated_edges : ndarray, shape (H, W), bool, or None, keyword-only
        Isolated edge measures (:func:`straddled_windows`); None: no straddle test.
    straddle_weight : float, keyword-only
        Factor in [0, 1] on the weight of a region measure whose window holds an isolated edge.
    window : (float, int, int), keyword-only
        (scale, min, max) of the region estimator's window side (``RegionParams.region_window_scale``,
        ``region_window_min``, ``region_window_max``; dimensionless, px, px).

    Returns
    -------
    sigma : ndarray, shape (H, W), float64
        σ_r, px, at the pixels carrying a region term; NaN elsewhere.
    weight : ndarray, shape (H, W), float64
        w_r ≥ 0 at those pixels (relative to an edge measure of confidence 1), 0 elsewhere.

    Raises
    ------
    ValueError
        Shapes that differ, negative σ or information, options out of range (named in the message).

    Notes
    -----
    1. v_r = 1/I + (ε_r σ_r)² + δ², v_e(σ_r) = (ε_e σ_r + δ)², δ = :data:`ERROR_FLOOR_PX`.
    2. w_r = W_r · v_e(σ_r) / v_r, times ``island_weight`` where :func:`blur_islands` holds and
       ``straddle_weight`` where :func:`straddled_windows` does.
    3. Placement (:data:`REGION_PLACEMENTS`): one term per block at its centre with the block's
       weight (``"centres"``), or a term at every pixel of the block with the per-pixel density
       (``"blocks"``); the block's total weight is the same.
    """
    s = np.asarray(region_sigma, dtype=np.float64)
    info = np.asarray(region_information, dtype=np.float64)
    if s.ndim != 2 or info.shape != s.shape:
        raise ValueError(f"region_sigma and region_information must share one (H, W) shape; got {s.shape}, "
                         f"{info.shape}")
    REGION_PLACEMENTS.check(placement, what="placement")
    for name, v in (("edge_error_rel", edge_error_rel), ("region_error_rel", region_error_rel)):
        if not (0 <= v < np.inf):
            raise ValueError(f"{name}={v!r} is invalid; allowed: finite and >= 0")
    if not (0 < region_weight < np.inf):
        raise ValueError(f"region_weight={region_weight!r} is invalid; allowed: finite and > 0")
    if not (0 <= island_weight <= 1):
        raise ValueError(f"island_weight={island_weight!r} is invalid; allowed: 0 <= weight <= 1")
    ok = np.isfinite(s) & (info > 0)  # NaN information: no measure; inf: exact (1/I = 0)
    if np.any(s[ok] < 0):
        raise ValueError("region_sigma must be >= 0 where finite")
    sig = np.where(ok, s, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        v_r = 1.0 / info + (region_error_rel * sig) ** 2 + ERROR_FLOOR_PX ** 2
        v_e = (edge_error_rel * sig + ERROR_FLOOR_PX) ** 2
        w = np.where(ok, region_weight * v_e / v_r, 0.0)
    if island_weight < 1 and ok.any():
        if gray is None:
            raise ValueError("gray is needed when island_weight < 1")
        gray = np.asarray(gray, dtype=np.float64)
        if gray.shape != s.shape:
            raise ValueError(f"gray has shape {gray.shape}; expected {s.shape}")
        islands = blur_islands(gray, noise_std=noise_std, radius=island_radius, sigma=np.where(ok, sig, np.nan))
        w = np.where(islands, w * island_weight, w)
    if not (0 <= straddle_weight <= 1):
        raise ValueError(f"straddle_weight={straddle_weight!r} is invalid; allowed: 0 <= weight <= 1")
    if straddle_weight < 1 and isolated_edges is not None and ok.any():
        scale, wmin, wmax = window
        straddled = straddled_windows(isolated_edges, np.where(ok, sig, np.nan), window_scale=scale,
                                      window_min=wmin, window_max=wmax)
        w = np.where(straddled, w * straddle_weight, w)
    return REGION_PLACEMENTS[placement](sig, w, int(stride))


def fuse_measures(edge_sigma, edge_weight, region_sigma, region_weight):
    """One Eq. (4) data term per pixel from two: the inverse-variance-weighted mean, weights summed.

    Parameters
    ----------
    edge_sigma : ndarray, shape (H, W), float
        Edge measures σ_e, px (after Eq. 3), NaN off edges.
    edge_weight : ndarray, shape (H, W), float, or None
        Their weights w_e ≥ 0 (the confidence c_e; None: 1).
    region_sigma : ndarray, shape (H, W), float
        Region measures σ_r, px, NaN where none.
    region_weight : ndarray, shape (H, W), float
        Their weights w_r ≥ 0 (:func:`region_data_term`).

    Returns
    -------
    sigma : ndarray, shape (H, W), float64
        σ̄ = (w_e σ_e + w_r σ_r) / (w_e + w_r) where either term exists (with weight > 0), NaN elsewhere.
    weight : ndarray, shape (H, W), float64
        w_e + w_r there, NaN elsewhere.

    Notes
    -----
    w_e (B − σ_e)² + w_r (B − σ_r)² = (w_e + w_r)(B − σ̄)² + w_e w_r (σ_e − σ_r)² / (w_e + w_r):
    the minimiser of Eq. (4) over B is unchanged by the swap (the last term does not depend on B).
    """
    es = np.asarray(edge_sigma, dtype=np.float64)
    rs = np.asarray(region_sigma, dtype=np.float64)
    if es.shape != rs.shape:
        raise ValueError(f"edge_sigma {es.shape} and region_sigma {rs.shape} must share one shape")
    e_ok = np.isfinite(es)
    ew = np.ones(es.shape) if edge_weight is None else np.asarray(edge_weight, dtype=np.float64)
    rw = np.asarray(region_weight, dtype=np.float64)
    we = np.where(e_ok, np.nan_to_num(ew, nan=0.0), 0.0)
    r_ok = np.isfinite(rs) & np.isfinite(rw) & (rw > 0)
    wr = np.where(r_ok, rw, 0.0)
    total = we + wr
    has = (e_ok & (we > 0)) | r_ok
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (we * np.where(e_ok, es, 0.0) + wr * np.where(r_ok, rs, 0.0)) / total
    # an edge measure of weight 0 stays a (zero-weight) term, as without fusion
    keep = has | e_ok
    sigma = np.where(has, mean, np.where(e_ok, es, np.nan))
    return np.where(keep, sigma, np.nan), np.where(keep, total, np.nan)


def fuse_cues(edge_sigma, edge_weight, region_sigma, region_information, *, gray, params,
              isolated_edges=None):
    """:func:`region_data_term` + :func:`fuse_measures` with the ``fusion_*`` fields of ``params``.

    Parameters
    ----------
    edge_sigma : ndarray, shape (H, W), float
        Refined edge measures, px (Eq. 3), NaN off edges.
    edge_weight : ndarray, shape (H, W), float, or None
        Their confidence c_e in [0, 1] (None: 1).
    region_sigma, region_information : ndarray, shape (H, W), float
        Region measures σ_r (px, NaN where none) and their Fisher information (px⁻²).
    gray : ndarray, shape (H, W), float, keyword-only
        Luminance in [0, 1] (island test).
    params : DefocusParams, keyword-only
    isolated_edges : ndarray, shape (H, W), bool, or None, keyword-only
        Isolated edge measures for the straddle test (``fusion_straddle_weight`` < 1).

    Returns
    -------
    sigma, weight : ndarray, shape (H, W), float64
        The fused data term (:func:`fuse_measures`): α_p = α·weight in Eq. (4).
    """
    rs, rw = region_data_term(
        region_sigma, region_information, gray=gray, edge_error_rel=params.fusion_edge_error_rel,
        region_error_rel=params.fusion_region_error_rel, region_weight=params.fusion_region_weight,
        placement=params.fusion_region_placement, island_weight=params.fusion_island_weight,
        island_radius=params.fusion_island_radius, noise_std=params.noise_std,
        stride=params.region_stride, isolated_edges=isolated_edges,
        straddle_weight=params.fusion_straddle_weight,
        window=(params.region_window_scale, params.region_window_min, params.region_window_max))
    return fuse_measures(edge_sigma, edge_weight, rs, rw)
