"""Blur at edge pixels by fitting the 2nd-derivative response model (Sec. 3.2, Eq. 2; the paper's estimator).

Across a step of amplitude A blurred by σb, the response to the 2nd-derivative filter at scale σ2 is
(Eq. 2c, 2d)

    r(t) = −A·t / (√(2π)·s³) · exp(−t² / (2 s²)),    s = d/2,   s² = σb² + σ2²,

with t the signed distance from the edge along the gradient direction; d is the distance between
its two extrema. The paper fits this model by brute force over d to the responses in a window
around the edge pixel, along the gradient direction, using both the bright and the dark side.

Beyond the paper, ``DefocusParams.fit_psf`` (:data:`FIT_PSF_MODELS`) can also fit, on the same
window and with the same search, the response of a step blurred by a uniform disk — a thin lens's
defocus, :mod:`method.blur.disk_edge_response` — whose second moment gives σb through the same Eq. (2d).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numba
import numpy as np

from .disk_edge_response import DISK_RHO_MAX, response_table, rho_row
from ..edges.elder_zucker import check_edge_inputs, edge_pixels_by_scale
from ..edges.gaussian_derivatives import GaussianDerivativeBank
from ..registry import Registry

__all__ = [
    "FIT_KAPPA",
    "apply_fit_rules",
    "S_GRID_RATIO",
    "T0_GRID_STEP",
    "blur_from_extrema_distance",
    "estimate_blur_model_fit",
    "estimate_blur_model_fit_psf",
    "response_model",
]

#: Fine grid of the model width s' (px along the sampling axis): geometric, ratio 1.02 (2 %).
#: Parabolic refinement of the least-squares error on log s' brings the error well below that.
S_GRID_RATIO = 1.02
#: Smallest model width s' on the grid, px (s ≥ σ2 ≥ 0.5 px, and s = s'·proj with proj ≥ 1/√2).
S_GRID_MIN = 0.3
#: Step of the sub-pixel edge-position grid t0, in sampling steps (± T0_GRID_HALF around 0).
T0_GRID_STEP = 0.05
T0_GRID_HALF = 0.6
#: Coarse pass of the brute-force search uses every COARSE_STRIDE-th s' (ratio 1.02^8 ≈ 1.17).
COARSE_STRIDE = 8
#: Window half-width = FIT_KAPPA × (distance of the farther discrete extremum of the response),
#: clipped to the params' window range: the window covers both lobes and part of their tails.
FIT_KAPPA = 2.0



def response_model(t, *, s, amplitude=1.0):
    """The 2nd-derivative response across a blurred step, Eq. (2c).

    Parameters
    ----------
    t : ndarray
        Signed distance from the edge along the gradient direction, px.
    s : float
        Width s = d/2 = √(σb² + σ2²), px (> 0).
    amplitude : float, keyword-only
        Step amplitude A (image units).

    Returns
    -------
    ndarray
        r(t) = −A t/(√(2π) s³) exp(−t²/(2s²)), image units / px².
    """
    t = np.asarray(t, dtype=np.float64)
    return -amplitude * t / (math.sqrt(2 * math.pi) * s ** 3) * np.exp(-0.5 * (t / s) ** 2)


def blur_from_extrema_distance(d, sigma2):
    """σb = √((d/2)² − σ2²), Eq. (2d); 0 where d/2 < σ2, NaN where d is NaN.

    Parameters
    ----------
    d : ndarray or float
        Distance between the two extrema of the 2nd-derivative response, px.
    sigma2 : ndarray or float
        Scale of the 2nd-derivative filter, px.

    Returns
    -------
    ndarray
        σb, px.
    """
    d = np.asarray(d, dtype=np.float64)
    s2 = np.asarray(sigma2, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.maximum((0.5 * d) ** 2 - s2 ** 2, 0.0))


@functools.lru_cache(maxsize=4)
def _template_table(half_window, s_max):
    """Model templates T[i, j, k] = m_{s'_i}(k − t0_j), k = −K…K, and their cumulative energy."""
    n_s = int(math.ceil(math.log(s_max / S_GRID_MIN) / math.log(S_GRID_RATIO))) + 1
    s_grid = S_GRID_MIN * S_GRID_RATIO ** np.arange(n_s)
    n_t = int(round(2 * T0_GRID_HALF / T0_GRID_STEP)) + 1
    t0_grid = -T0_GRID_HALF + T0_GRID_STEP * np.arange(n_t)
    k = np.arange(-half_window, half_window + 1, dtype=np.float64)
    x = k[None, None, :] - t0_grid[None, :, None]
    s = s_grid[:, None, None]
    # Amplitude is fitted in closed form, so the normalisation only needs to be well scaled.
    table = -(x / s) * np.exp(-0.5 * (x / s) ** 2) / s ** 2
    cum = np.concatenate([np.zeros((n_s, n_t, 1)), np.cumsum(table ** 2, axis=2)], axis=2)
    table.setflags(write=False)
    cum.setflags(write=False)
    return s_grid, t0_grid, table, cum


@numba.njit(cache=True, nogil=True)
def _score(r, a, b, K, table, cum, i, j):
    """Least-squares fit of r[a..b] by A·T[i, j]: returns (r·T)²/(T·T) (0 if A would be ≤ 0)."""
    dot = 0.0
    for k in range(a, b + 1):
        dot += r[k + K] * table[i, j, k + K]
    if dot <= 0.0:
        return 0.0
    energy = cum[i, j, b + K + 1] - cum[i, j, a + K]
    if energy <= 0.0:
        return 0.0
    return dot * dot / energy


@numba.njit(cache=True, nogil=True)
def _score_disk(r, a, b, K, s_prime, t0, sig_p, dvalues, doffsets, dlengths, dsteps):
    """As :func:`_score` for the disk-blurred template of width s' at filter scale σ' (sampling steps).

    The template m(k) = G((k − t0)/R'; σ'/R') with R' = 2√(s'² − σ'²) (method.blur.disk_edge_response),
    linear in log ρ between two table rows and linear in v within each (the same interpolation as
    ``disk_edge_response._disk_value``, with the per-row index scale hoisted out of the loop).
    """
    radius = 2.0 * math.sqrt(s_prime * s_prime - sig_p * sig_p)
    row, wt = rho_row(dlengths, sig_p / radius)
    o0, o1 = doffsets[row], doffsets[row + 1]
    n0, n1 = dlengths[row] - 1, dlengths[row + 1] - 1
    c0 = 1.0 / (radius * dsteps[row])  # table index per sample
    c1 = 1.0 / (radius * dsteps[row + 1])
    w0 = 1.0 - wt
    dot = 0.0
    energy = 0.0
    for k in range(a, b + 1):
        u = k - t0
        sign = 1.0
        if u < 0.0:
            u, sign = -u, -1.0
        m = 0.0
        f = u * c0
        i = int(f)
        if i < n0:
            q = f - i
            m += w0 * ((1.0 - q) * dvalues[o0 + i] + q * dvalues[o0 + i + 1])
        f = u * c1
        i = int(f)
        if i < n1:
            q = f - i
            m += wt * ((1.0 - q) * dvalues[o1 + i] + q * dvalues[o1 + i + 1])
        m *= sign
        dot += r[k + K] * m
        energy += m * m
    if dot <= 0.0 or energy <= 0.0:
        return 0.0
    return dot * dot / energy


@numba.njit(cache=True, nogil=True)
def _score_family(r, a, b, K, table, cum, i, j, disk, sig_p, s_grid, t0_grid, dvalues, doffsets, dlengths,
                  dsteps):
    """Score of grid template (i, j): Eq. (2c) (``disk`` False, or where the disk is negligible) or the disk model."""
    if disk:
        s_prime = s_grid[i]
        # a disk narrower than 1/DISK_RHO_MAX of σ' (or none, s' ≤ σ') is the Gaussian model
        if s_prime * s_prime > sig_p * sig_p * (1.0 + 0.25 / (DISK_RHO_MAX * DISK_RHO_MAX)):
            return _score_disk(r, a, b, K, s_prime, t0_grid[j], sig_p, dvalues, doffsets, dlengths, dsteps)
    return _score(r, a, b, K, table, cum, i, j)


@numba.njit(cache=True, nogil=True)
def _best_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, coarse_stride, disk, sig_p,
                   dvalues, doffsets, dlengths, dsteps, i_lo, i_hi):
    """Steps 4–5 of the fit: brute-force (s', t0) search and parabolic refinement; (s', best score) or (NaN, 0).

    The coarse pass scans s' indices i_lo, i_lo + stride, … < i_hi (the whole grid for Eq. 2c)."""
    n_s = s_grid.shape[0]
    n_t = t0_grid.shape[0]
    t0_min = t0_grid[0]
    t0_step = t0_grid[1] - t0_grid[0]
    jc = int(round((k0 - t0_min) / t0_step))
    jc = max(0, min(n_t - 1, jc))
    best_i, best = -1, 0.0
    for i in range(i_lo, min(n_s, i_hi), coarse_stride):
        sc = _score_family(r, a, b, K, table, cum, i, jc, disk, sig_p, s_grid, t0_grid, dvalues, doffsets,
                           dlengths, dsteps)
        if sc > best:
            best, best_i = sc, i
    if best_i < 0:
        return np.nan, 0.0
    # fine pass by coordinate descent: s' around the coarse optimum, then t0, then s' again
    bi, bj = best_i, jc
    for i in range(max(0, best_i - coarse_stride), min(n_s, best_i + coarse_stride + 1)):
        sc = _score_family(r, a, b, K, table, cum, i, jc, disk, sig_p, s_grid, t0_grid, dvalues, doffsets,
                           dlengths, dsteps)
        if sc > best:
            best, bi = sc, i
    i_mid = bi
    for j in range(max(0, jc - 4), min(n_t, jc + 5)):
        sc = _score_family(r, a, b, K, table, cum, i_mid, j, disk, sig_p, s_grid, t0_grid, dvalues, doffsets,
                           dlengths, dsteps)
        if sc > best:
            best, bj = sc, j
    j_mid = bj
    for i in range(max(0, i_mid - 3), min(n_s, i_mid + 4)):
        sc = _score_family(r, a, b, K, table, cum, i, j_mid, disk, sig_p, s_grid, t0_grid, dvalues, doffsets,
                           dlengths, dsteps)
        if sc > best:
            best, bi = sc, i
    # 5. parabolic refinement of the squared error on the log-s' grid
    pos = float(bi)
    if 0 < bi < n_s - 1:
        e_m = energy_r - _score_family(r, a, b, K, table, cum, bi - 1, bj, disk, sig_p, s_grid, t0_grid, dvalues,
                                       doffsets, dlengths, dsteps)
        e_0 = energy_r - best
        e_p = energy_r - _score_family(r, a, b, K, table, cum, bi + 1, bj, disk, sig_p, s_grid, t0_grid, dvalues,
                                       doffsets, dlengths, dsteps)
        den = e_m - 2.0 * e_0 + e_p
        if den > 0.0:
            delta = 0.5 * (e_m - e_p) / den
            pos += max(-0.5, min(0.5, delta))
    return s_grid[0] * (s_grid[1] / s_grid[0]) ** pos, best


#: The edge-blur models the fit can use (``DefocusParams.fit_psf``): name -> what it fits.
FIT_PSF_MODELS = Registry("fit PSF model", {
    "gaussian": "Eq. (2c): a Gaussian-blurred step (the paper)",
    "disk": "a step blurred by a uniform disk, the thin lens's defocus (method.blur.disk_edge_response)",
    "best": "both on the same window; per edge pixel the one with the smaller residual",
    "auto": "both on the same window; one model for the whole image (select_psf_model)",
})
_EMPTY_DISK_TABLE = (np.zeros(1), np.zeros(1, dtype=np.int64), np.ones(1, dtype=np.int64), np.ones(1))

#: Edge pixels per parallel chunk of :func:`_fit_kernel`.
_FIT_CHUNK = 256


@numba.njit(cache=True, nogil=True, parallel=True)
def _fit_kernel(ixx, ixy, iyy, rows, cols, cos_t, sin_t, w_min, w_max, kappa,
                s_grid, t0_grid, table, cum, coarse_stride, out_s, out_res, out_win, out_energy,
                sigma2, disk_min_width, dvalues, doffsets, dlengths, dsteps, out_sd, out_resd):
    # out_res[n]: normalised residual (‖r‖² − best score)/‖r‖² of the best grid fit, in [0, 1]
    # (NaN where out_s is NaN); out_win[n]: number of samples b − a + 1 in the fit window (0 where
    # no window); out_energy[n]: ‖r‖² over the fit window, (image units / px²)² (NaN where out_s is
    # NaN). All three are only written, never read: out_s does not depend on them. Where
    # disk_min_width ≥ 0 and the Gaussian width exceeds disk_min_width · sigma2, out_sd / out_resd
    # are the width and residual of the disk-blurred templates (same window and search;
    # :mod:`method.blur.disk_edge_response`) at filter scale σ' = sigma2 / proj (NaN otherwise).
    # Edge pixels are independent: chunks of _FIT_CHUNK run in parallel, each with its own sample
    # buffer r (only r[kmin..kmax] of the current pixel is ever read), so the results are the same
    # bytes for any thread count.
    h, w = ixx.shape
    K = (table.shape[2] - 1) // 2
    nrows = rows.shape[0]
    n_s = s_grid.shape[0]
    log_ratio = math.log(s_grid[1] / s_grid[0])
    bracket_lo = math.log(2.0) / log_ratio
    bracket_hi = math.log(1.25) / log_ratio
    for chunk in numba.prange((nrows + _FIT_CHUNK - 1) // _FIT_CHUNK):
        r = np.zeros(2 * K + 1)
        for n in range(chunk * _FIT_CHUNK, min(nrows, (chunk + 1) * _FIT_CHUNK)):
            out_s[n] = np.nan
            out_res[n] = np.nan
            out_sd[n] = np.nan
            out_resd[n] = np.nan
            out_win[n] = 0
            out_energy[n] = np.nan
            i0, j0 = rows[n], cols[n]
            c, s = cos_t[n], sin_t[n]
            if abs(c) >= abs(s):
                di, dj, proj = 0, (1 if c >= 0 else -1), abs(c)
            else:
                di, dj, proj = (1 if s >= 0 else -1), 0, abs(s)
            cc, cs2, ss = c * c, 2.0 * c * s, s * s
            # 1. sample r(k) along the dominant axis (exact pixel values, steered with θ of the edge)
            kmin, kmax = 0, 0
            for k in range(1, w_max + 1):
                ii, jj = i0 - k * di, j0 - k * dj
                if ii < 0 or ii >= h or jj < 0 or jj >= w:
                    break
                kmin = -k
            for k in range(1, w_max + 1):
                ii, jj = i0 + k * di, j0 + k * dj
                if ii < 0 or ii >= h or jj < 0 or jj >= w:
                    break
                kmax = k
            if kmin > -1 or kmax < 1:
                continue
            for k in range(kmin, kmax + 1):
                ii, jj = i0 + k * di, j0 + k * dj
                r[k + K] = cc * ixx[ii, jj] + cs2 * ixy[ii, jj] + ss * iyy[ii, jj]
            # 2. sub-pixel zero crossing k0 (sampling steps) from r(−1), r(0), r(1)
            rm, r0, rp = r[K - 1], r[K], r[K + 1]
            if r0 > 0.0 and rp < 0.0:
                k0 = r0 / (r0 - rp)
            elif r0 < 0.0 and rm > 0.0:
                k0 = -1.0 + rm / (rm - r0)
            else:
                k0 = 0.0
            # 3. window: walk to the discrete extrema on the dark (k<0) and bright (k>0) sides
            kd = -1
            while kd - 1 >= kmin and r[kd - 1 + K] >= r[kd + K]:
                kd -= 1
            kb = 1
            while kb + 1 <= kmax and r[kb + 1 + K] <= r[kb + K]:
                kb += 1
            # walk on past each extremum while the response keeps decaying with the same sign: the
            # first local minimum of |r| is where a neighbouring edge's response takes over
            ed = kd
            while ed - 1 >= kmin and r[ed - 1 + K] > 0.0 and r[ed - 1 + K] <= r[ed + K]:
                ed -= 1
            eb = kb
            while eb + 1 <= kmax and r[eb + 1 + K] < 0.0 and r[eb + 1 + K] >= r[eb + K]:
                eb += 1
            ha = int(math.ceil(kappa * max(-kd, kb)))
            hb = ha
            ha = max(w_min, min(w_max, ha, -ed))
            hb = max(w_min, min(w_max, hb, eb))
            a = max(-ha, kmin)
            b = min(hb, kmax)
            if b - a + 1 < 3:
                continue
            out_win[n] = b - a + 1
            energy_r = 0.0
            for k in range(a, b + 1):
                energy_r += r[k + K] * r[k + K]
            # 4.–5. brute-force search over (s', t0) and parabolic refinement (_best_template)
            s_prime, best = _best_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, coarse_stride,
                                           False, 0.0, dvalues, doffsets, dlengths, dsteps, 0, n_s)
            if not (s_prime == s_prime):  # no positive-amplitude template
                continue
            out_s[n] = s_prime * proj
            out_energy[n] = energy_r
            if energy_r > 0.0:
                out_res[n] = max(0.0, energy_r - best) / energy_r
            if disk_min_width >= 0.0 and s_prime * proj > disk_min_width * sigma2:
                # the same window fitted with the disk-blurred templates (beyond the paper); the disk's
                # width lies within [s'/2, 1.25 s'] of the Gaussian's (Gaussian fits of disk-blurred
                # steps are ≤ 30 % wide, disk fits of Gaussian steps ≤ 25 % narrow), so the coarse
                # pass scans only that bracket
                i_g = math.log(s_prime / s_grid[0]) / log_ratio
                sd, bestd = _best_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, coarse_stride,
                                           True, sigma2 / proj, dvalues, doffsets, dlengths, dsteps,
                                           max(0, int(i_g - bracket_lo)), int(i_g + bracket_hi) + 1)
                if sd == sd and energy_r > 0.0:
                    out_sd[n] = sd * proj
                    out_resd[n] = max(0.0, energy_r - bestd) / energy_r


def estimate_blur_model_fit(gray, edge_map, *, params):
    """Blur σb at edge pixels by least-squares fit of Eq. (2c) (Sec. 3.2, the paper's method).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to :func:`method.edges.elder_zucker.detect_edges`).
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges(gray, ...)``.
    params : DefocusParams, keyword-only
        Uses ``fit_window_min``, ``fit_window_max`` (window lengths, px) and ``max_sigma``.

    Returns
    -------
    ndarray, shape (H, W), float64
        σb in px at edge pixels, clipped to [0, max_sigma]; NaN elsewhere and where the fit fails
        (fewer than 3 samples inside the image, or no positive-amplitude fit).

    Notes
    -----
    Per edge pixel p (vectorised over all edge pixels of one σ2 in a numba kernel):

    0. The 2nd-derivative responses at each σ2 come from ``edge_map.hessians`` when the detector
       kept them (``detect_edges(..., keep_hessians=True)``, as the pipeline does), else from a
       single-precision FFT bank (:class:`~method.edges.gaussian_derivatives.GaussianDerivativeBank`) set
       up like the detector's (largest σ of ``params.sigma1_scales``/``sigma2_scales``, hence the
       same padding), so both paths give bit-identical responses.
    1. Sampling along θ: r(k) = ∂²_θ I at σ2(p) (Eq. 8d, steered with θ(p)) at the pixels
       p + k·e, k = −K…K, where e is the one-pixel step along the image axis closest to θ. These
       are exact filter outputs (no interpolation). Along that axis a straight edge is crossed at
       t = k·proj with proj = max(|cos θ|, |sin θ|), so r(k) ∝ m_{s'}(k − k0) with s' = s/proj:
       the same model, in sampling steps.
    2. Sub-pixel edge position k0 from the linear zero crossing of r(−1), r(0), r(1).
    3. Window: walk outward to the first discrete local maximum (dark side, k < 0) and minimum
       (bright side, k > 0) of r; half-width = ⌈FIT_KAPPA · farther extremum⌉, clipped to
       [(fit_window_min − 1)/2, (fit_window_max − 1)/2] (the paper's 3…71 px windows; they grow
       with the response width s ≥ σ2, i.e. with scale) and to the image. On each side the window
       also stops where |r| stops decaying past the extremum (first local minimum of |r| or sign
       change): beyond it a neighbouring edge's response dominates. Both sides are used.
    4. Brute force over d = 2s (Eq. 2c): templates m_{s'}(k − t0) on a geometric s' grid (ratio
       :data:`S_GRID_RATIO`) × a t0 grid (step :data:`T0_GRID_STEP`): a coarse pass over s'
       (every :data:`COARSE_STRIDE`-th value) at the t0 nearest k0, then a fine pass by coordinate
       descent (s', then t0 within ±0.2 steps, then s' again).
       For each template the amplitude A is the closed-form least-squares value
       A = (r·m)/(m·m) (constrained A > 0), so the squared error is ‖r‖² − (r·m)²/(m·m). We use
       the least-squares A rather than "A from the local extrema" because it uses every sample of
       the window (less noise) and does not depend on locating the extrema — the step the paper
       says is unreliable; for a clean edge both give the same A.
    5. Parabolic refinement of the error over log s'; s = s'·proj; σb = √(s² − σ2²) (Eq. 2d),
       clipped to [0, max_sigma].
    6. Beyond the paper, ``params.fit_psf`` ≠ "gaussian": steps 4–5 again with the disk-blurred
       templates at filter scale σ' = σ2/proj, the coarse pass limited to s' within [s'_G/2,
       1.25 s'_G] of the Gaussian optimum s'_G; "disk" keeps those fits, "best" the smaller
       residual per edge, "auto" one model per image (:func:`select_psf_model`, decided on a sample
       of at most :data:`PSF_SELECT_SAMPLE` resolved edges; the disk is then fitted on the rest).
    """
    if paper_rules(params):
        return _model_fit_with_residual(gray, edge_map, params=params)[0]
    return apply_fit_rules(model_fit_diagnostics(gray, edge_map, params=params), params=params)


def estimate_blur_model_fit_psf(gray, edge_map, *, params):
    """:func:`estimate_blur_model_fit` plus, from the same fit, which measures used the disk model.

    Returns
    -------
    sigma_b : ndarray, shape (H, W), float64
        Identical to :func:`estimate_blur_model_fit`.
    psf_disk : ndarray, shape (H, W), bool
        True at the measures (finite ``sigma_b``) fitted with the disk-blurred step
        (``params.fit_psf``); False elsewhere (all False for ``fit_psf="gaussian"``, the paper).
    """
    diagnostics = model_fit_diagnostics(gray, edge_map, params=params)
    sigma_b = apply_fit_rules(diagnostics, params=params)
    return sigma_b, diagnostics["disk"] & np.isfinite(sigma_b)


def paper_rules(params) -> bool:
    """True when every beyond-the-paper model-fit switch of ``params`` is off."""
    return (getattr(params, "fit_max_scale", None) is None and getattr(params, "fit_min_samples", 3) <= 3
            and getattr(params, "fit_scale_ratio", 1.0) == 1.0
            and not np.isfinite(getattr(params, "fit_max_width_ratio", np.inf))
            and getattr(params, "fit_below_scale", "zero") == "zero")


def apply_fit_rules(diagnostics, *, params) -> np.ndarray:
    """σb of the model fit with the beyond-the-paper plausibility rules of ``params`` applied.

    Parameters
    ----------
    diagnostics : dict of ndarray, (H, W)
        Output of :func:`model_fit_diagnostics` (``sigma_b``, ``window``, ``width``, ``sigma2``).
    params : DefocusParams, keyword-only
        ``fit_min_samples`` (samples), ``fit_max_width_ratio`` (dimensionless),
        ``fit_below_scale`` ("zero" | "nan") and ``sigma2_scales`` (px).

    Returns
    -------
    ndarray, (H, W), float64
        σb, px; NaN where a rule rejects the fit ("no measure").

    Notes
    -----
    1. ``fit_min_samples``: fewer samples than this in the fit window → NaN (with 3 samples the
       two-parameter fit (s, t0) is exactly determined and noise alone can give any width).
    2. ``fit_max_width_ratio``: a fitted width s = d/2 above this fraction of the window's
       half-length extrapolates the model beyond the samples → NaN.
    3. ``fit_below_scale="nan"``: d/2 ≤ σ2 means the blur is below what σ2 resolves; at the
       finest σ2 that is a sharp edge (σb = 0 is kept), at a coarser σ2 it is no measure (NaN)
       instead of the paper's σb = 0.
    """
    sb = np.array(diagnostics["sigma_b"], dtype=np.float64, copy=True)
    win = diagnostics["window"]
    width = diagnostics["width"]
    s2 = diagnostics["sigma2"]
    with np.errstate(invalid="ignore"):
        bad = win < int(params.fit_min_samples)
        ratio = float(params.fit_max_width_ratio)
        if np.isfinite(ratio):
            bad |= width > ratio * 0.5 * (win - 1)
        if params.fit_below_scale == "nan":
            bad |= (width <= s2) & (s2 > min(params.sigma2_scales))
    sb[bad & np.isfinite(sb)] = np.nan
    return sb


def fit_scales(edge_map, *, params):
    """``edge_map`` with σ2 replaced by the scale the Eq. (2c) fit samples (beyond-the-paper rules).

    Parameters
    ----------
    edge_map : EdgeMap
        Output of ``detect_edges``; ``sigma2`` (px) is each edge pixel's minimum reliable σ2.
    params : DefocusParams, keyword-only
        ``fit_scale_ratio`` (dimensionless), ``fit_max_scale`` (px or None), ``sigma2_scales`` (px).

    Returns
    -------
    EdgeMap
        ``edge_map`` itself when both rules are off (the paper: fit at σ2(p)); else a copy whose
        σ2 is min(σ2(p), max(fit_scale_ratio · σ2(p), min(sigma2_scales)), fit_max_scale).
    """
    ratio = float(getattr(params, "fit_scale_ratio", 1.0))
    max_scale = getattr(params, "fit_max_scale", None)
    if ratio == 1.0 and max_scale is None:
        return edge_map
    s2 = np.asarray(edge_map.sigma2)
    with np.errstate(invalid="ignore"):
        fit = s2 if ratio == 1.0 else np.minimum(s2, np.maximum(ratio * s2, min(params.sigma2_scales)))
        if max_scale is not None:
            fit = np.minimum(fit, float(max_scale))
    return dataclasses.replace(edge_map, sigma2=np.where(np.isfinite(s2), fit, s2))


def _model_fit_with_residual(gray, edge_map, *, params):
    """Private hook: :func:`estimate_blur_model_fit`'s σb map plus the normalised fit residual.

    Returns
    -------
    sigma_b, residual : ndarray, shape (H, W), float64
        See :func:`model_fit_diagnostics`.
    """
    d = model_fit_diagnostics(gray, edge_map, params=params)
    return d["sigma_b"], d["residual"]


def model_fit_diagnostics(gray, edge_map, *, params):
    """Private hook: :func:`estimate_blur_model_fit`'s σb map plus per-pixel fit diagnostics.

    Returns
    -------
    dict of ndarray, shape (H, W)
    sigma_b : float64
        Exactly the output of :func:`estimate_blur_model_fit` (same code path), px.
    residual : float64
        ρ = (‖r‖² − (r·m)²/(m·m)) / ‖r‖² of the best grid template m of Eq. (2c) over the fit
        window (dimensionless, in [0, 1]; 1 − ρ is the squared normalised correlation); NaN where
        σb is NaN or off edges.
    window : int64
        Number of response samples in the fit window (0 off edges and where the fit failed).
    width : float64
        Fitted model width s = d/2 = √(σb² + σ2²) before Eq. (2d), px; NaN off edges / failed fits.
    sigma2 : float64
        The σ2 of the responses that were fitted (the edge's minimum reliable σ2), px; NaN off edges.
    energy : float64
        ‖r‖² of the sampled response over the fit window, (image units / px²)²; NaN where σb is NaN.
    """
    img = check_edge_inputs(gray, edge_map)
    w_min = (int(params.fit_window_min) - 1) // 2
    w_max = (int(params.fit_window_max) - 1) // 2
    w_min = max(1, w_min)
    out = np.full(img.shape, np.nan)
    res = np.full(img.shape, np.nan)
    win = np.zeros(img.shape, dtype=np.int64)
    width = np.full(img.shape, np.nan)
    s2_map = np.full(img.shape, np.nan)
    energy = np.full(img.shape, np.nan)
    diag = {"sigma_b": out, "residual": res, "window": win, "width": width, "sigma2": s2_map,
            "energy": energy, "disk": np.zeros(img.shape, dtype=bool)}
    psf = getattr(params, "fit_psf", "gaussian")
    FIT_PSF_MODELS.check(psf, what="fit_psf")
    disk_table = response_table() if psf != "gaussian" else _EMPTY_DISK_TABLE
    disk_width = np.full(img.shape, np.nan) if psf != "gaussian" else None
    disk_res = np.full(img.shape, np.nan) if psf != "gaussian" else None
    edge_map = fit_scales(edge_map, params=params)
    groups = edge_pixels_by_scale(edge_map)
    if not groups:
        return diag
    s_max = math.sqrt(float(params.max_sigma) ** 2 + max(g[0] for g in groups) ** 2) * math.sqrt(2.0)
    s_grid, t0_grid, table, cum = _template_table(w_max, float(np.float32(max(s_max, 1.0))))
    cached = edge_map.hessians or {}
    bank = None
    theta = np.asarray(edge_map.theta, dtype=np.float64)
    # "disk" and "best" fit the disk model on every edge in the same pass; "auto" fits it first on a
    # sample of the edges that can decide (select_psf_model), and on all edges only if it chose it;
    # "gaussian" (the paper) keeps no disk state
    first_min_width = 0.0 if psf in ("disk", "best") else -1.0
    fitted = []
    for sigma2, rows, cols in groups:
        if sigma2 in cached:
            ixx, ixy, iyy = cached[sigma2]
        else:
            if bank is None:  # the detector's bank: same padding levels, so the same responses
                bank = GaussianDerivativeBank(
                    img, max(max(params.sigma1_scales), max(params.sigma2_scales), groups[-1][0]),
                    precision="single")
            ixx, ixy, iyy = bank.hessian(sigma2)
        th = theta[rows, cols]
        s_est, r_est, w_est, e_est, sd_est, rd_est = _run_fit_kernel(
            (ixx, ixy, iyy), rows, cols, th, w_min, w_max, (s_grid, t0_grid, table, cum), sigma2,
            first_min_width, disk_table)
        sigma_b = blur_from_extrema_distance(2.0 * s_est, sigma2)
        out[rows, cols] = np.clip(sigma_b, 0.0, float(params.max_sigma))
        res[rows, cols] = r_est
        win[rows, cols] = w_est
        width[rows, cols] = s_est
        energy[rows, cols] = e_est
        s2_map[rows, cols] = sigma2
        if psf != "gaussian":
            disk_width[rows, cols] = sd_est
            disk_res[rows, cols] = rd_est
        if psf == "auto":
            fitted.append((sigma2, rows, cols, th, (ixx, ixy, iyy)))

    def fit_disk(select):  # disk fits on the edge pixels where select(group's rows, cols) is True
        for sigma2, rows, cols, th, hessian in fitted:
            sel = select(rows, cols)
            if sel.any():
                rr, cc = rows[sel], cols[sel]
                *_, sd_est, rd_est = _run_fit_kernel(hessian, rr, cc, th[sel], w_min, w_max,
                                                     (s_grid, t0_grid, table, cum), sigma2, 0.0, disk_table)
                disk_width[rr, cc] = sd_est
                disk_res[rr, cc] = rd_est

    if psf == "auto":
        sample = _psf_selection_sample(width, s2_map)
        fit_disk(lambda rr, cc: sample[rr, cc])
        if select_psf_model(diag, disk_width, disk_res) == "disk":
            fit_disk(lambda rr, cc: np.isfinite(width[rr, cc]) & ~np.isfinite(disk_width[rr, cc]))
            _choose_psf(diag, disk_width, disk_res, psf="disk", max_sigma=float(params.max_sigma))
    elif psf in ("disk", "best"):
        _choose_psf(diag, disk_width, disk_res, psf=psf, max_sigma=float(params.max_sigma))
    return diag


def _psf_selection_sample(width, sigma2):
    """Edge pixels whose disk fit ``select_psf_model`` needs: resolved blur, at most PSF_SELECT_SAMPLE of them.

    Candidates have a finite Gaussian width s > PSF_SELECT_MIN_WIDTH · σ2; beyond PSF_SELECT_SAMPLE
    candidates every k-th one in raster order is kept (deterministic; the statistic is a mean).
    """
    with np.errstate(invalid="ignore"):
        cand = np.isfinite(width) & (width > PSF_SELECT_MIN_WIDTH * sigma2)
    idx = np.flatnonzero(cand)
    if idx.size > PSF_SELECT_SAMPLE:
        cand = np.zeros_like(cand)
        cand.flat[idx[:: int(math.ceil(idx.size / PSF_SELECT_SAMPLE))]] = True
    return cand


def _run_fit_kernel(hessian, rows, cols, theta, w_min, w_max, templates, sigma2, disk_min_width, disk_table):
    """:func:`_fit_kernel` on the edge pixels (rows, cols) of one σ2: (s, ρ, window, energy, s_disk, ρ_disk)."""
    n = rows.size
    s_est, r_est, e_est, sd_est, rd_est = (np.empty(n) for _ in range(5))
    w_est = np.empty(n, dtype=np.int64)
    _fit_kernel(*hessian, rows, cols, np.cos(theta), np.sin(theta), w_min, w_max, FIT_KAPPA,
                *templates, COARSE_STRIDE, s_est, r_est, w_est, e_est,
                float(sigma2), float(disk_min_width), *disk_table, sd_est, rd_est)
    return s_est, r_est, w_est, e_est, sd_est, rd_est


def _choose_psf(diag, disk_width, disk_res, *, psf, max_sigma):
    """Replace the Gaussian fits of ``diag`` by the disk fits where ``psf`` selects the disk (in place)."""
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(disk_width)
        take = finite if psf == "disk" else finite & ~(diag["residual"] <= disk_res)  # "best": per edge
    diag["width"] = np.where(take, disk_width, diag["width"])
    diag["residual"] = np.where(take, disk_res, diag["residual"])
    sigma_b = np.clip(blur_from_extrema_distance(2.0 * diag["width"], diag["sigma2"]), 0.0, max_sigma)
    diag["sigma_b"] = np.where(np.isfinite(diag["width"]), sigma_b, np.nan)
    diag["disk"] = take


#: "auto" decides on the edges whose blur is resolved (fitted width s > PSF_SELECT_MIN_WIDTH · σ2,
#: i.e. σb > 1.1 σ2) and that one of the two models fits closely (residual < PSF_SELECT_MAX_RESIDUAL):
#: isolated edges, where the PSF's shape shows; texture interference dominates the other residuals.
PSF_SELECT_MIN_WIDTH = 1.5
PSF_SELECT_MAX_RESIDUAL = 0.01
PSF_SELECT_MIN_EDGES = 5
#: At most this many candidate edges get the disk fit before "auto" decides (a deterministic sample).
PSF_SELECT_SAMPLE = 4000


def select_psf_model(diag, disk_width, disk_res) -> str:
    """The blur model of ``fit_psf="auto"``: "disk" or "gaussian", one for the whole image.

    Parameters
    ----------
    diag : dict of ndarray, (H, W)
        The Gaussian fit's diagnostics (:func:`model_fit_diagnostics` with ``fit_psf="gaussian"``:
        ``residual``, ``width``, px, ``sigma2``, px).
    disk_width, disk_res : ndarray, (H, W)
        Width s (px) and normalised residual of the disk model's fit on the same windows.

    Returns
    -------
    str
        "disk" when the geometric mean of the disk model's residual over the selecting edges (Notes)
        is below that of Eq. (2c), else "gaussian" (also with fewer than
        :data:`PSF_SELECT_MIN_EDGES` selecting edges: the paper's model by default).

    Notes
    -----
    The PSF's shape is a property of the lens, not of an edge, so the choice is made once per image.
    Per edge the two residuals differ little except on isolated, resolved edges, and even there noise
    decides a per-edge choice often (``fit_psf="best"``). Selecting edges: both fits finite, the
    Gaussian width s > :data:`PSF_SELECT_MIN_WIDTH` · σ2 and min(ρ_gauss, ρ_disk) <
    :data:`PSF_SELECT_MAX_RESIDUAL`. Statistic: the mean of log((ρ_disk + ε)/(ρ_gauss + ε)), ε = 1e-4;
    an energy-weighted sum of residuals was dominated by a few edges and chose wrongly on one of the
    accuracy bench's Gaussian mosaics. Measured (accuracy-bench mosaics, 8 bits + noise 1–2/255,
    seeds 0–1): mean log ratio +0.63 … +3.9 on the 12 Gaussian-blurred mosaics; −0.71 … +0.27 on the
    18 small renders (thin-lens disks), disk chosen on 11 of them.
    """
    with np.errstate(invalid="ignore"):
        sel = (np.isfinite(diag["residual"]) & np.isfinite(disk_res)
               & (diag["width"] > PSF_SELECT_MIN_WIDTH * diag["sigma2"])
               & (np.minimum(diag["residual"], disk_res) < PSF_SELECT_MAX_RESIDUAL))
    if int(sel.sum()) < PSF_SELECT_MIN_EDGES:
        return "gaussian"
    log_ratio = np.log((disk_res[sel] + 1e-4) / (diag["residual"][sel] + 1e-4))
    return "disk" if float(np.mean(log_ratio)) < 0.0 else "gaussian"
