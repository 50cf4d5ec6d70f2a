"""The Eq. (2c) response model and the brute-force template search of the model fit (Sec. 3.2).

:func:`response_model` is r(t) of Eq. (2c); :func:`blur_from_extrema_distance` is Eq. (2d).
:func:`template_table` tabulates the templates m_{s'}(k − t0) on the fit's (s', t0) grid and
:func:`run_fit_kernel` fits them (and, beyond the paper, the disk-blurred step's templates of
:mod:`method.blur.disk_edge_response`) to the 2nd-derivative responses sampled along θ at the edge
pixels of one σ2, in a parallel numba kernel. :func:`method.blur.model_fit.model_fit_diagnostics`
drives it.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from .disk_edge_response import DISK_RHO_MAX, rho_row
from ..edges.gaussian_derivatives import nearest_axis_step, second_steering_weights

__all__ = [
    "COARSE_STRIDE",
    "EMPTY_DISK_TABLE",
    "FIT_KAPPA",
    "S_GRID_RATIO",
    "T0_GRID_STEP",
    "blur_from_extrema_distance",
    "response_model",
    "run_fit_kernel",
    "template_table",
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
def template_table(half_window, s_max):
    """Model templates T[i, j, k] = m_{s'_i}(k − t0_j), k = −K…K, their cumulative energy over k, T as [j, k, i]
    and its every COARSE_STRIDE-th s' (the coarse pass's)."""
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
    # the same values ordered (t0, k, s'), and every COARSE_STRIDE-th s' of them: the search's passes
    # along s' read contiguous rows
    table_t = np.ascontiguousarray(table.transpose(1, 2, 0))
    cum_t = np.ascontiguousarray(cum.transpose(1, 2, 0))
    table_c = np.ascontiguousarray(table_t[:, :, ::COARSE_STRIDE])
    cum_c = np.ascontiguousarray(cum_t[:, :, ::COARSE_STRIDE])
    for a in (table, cum, table_t, cum_t, table_c, cum_c):
        a.setflags(write=False)
    return s_grid, t0_grid, table, cum, table_t, cum_t, table_c, cum_c


@numba.njit(cache=True, nogil=True, inline="always")
def _finish(dot, cum, i, j, a, b, K):
    """:func:`_score` of template (i, j) from its dot product with r[a..b]."""
    if dot <= 0.0:
        return 0.0
    energy = cum[i, j, b + K + 1] - cum[i, j, a + K]
    if energy <= 0.0:
        return 0.0
    return dot * dot / energy


@numba.njit(cache=True, nogil=True)
def _score(r, a, b, K, table, cum, i, j):
    """Least-squares fit of r[a..b] by A·T[i, j]: returns (r·T)²/(T·T) (0 if A would be ≤ 0)."""
    dot = 0.0
    for k in range(a, b + 1):
        dot += r[k + K] * table[i, j, k + K]
    return _finish(dot, cum, i, j, a, b, K)


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
def _t0_start_index(k0, t0_grid):
    """Index of the t0 grid value nearest ``k0`` (samples), clipped to the grid: the search's start."""
    jc = int(round((k0 - t0_grid[0]) / (t0_grid[1] - t0_grid[0])))
    return max(0, min(t0_grid.shape[0] - 1, jc))


@numba.njit(cache=True, nogil=True)
def _parabola_offset(e_m, e_0, e_p):
    """Step 5: vertex of the parabola through the squared errors at grid steps −1, 0, +1, clipped to ±0.5
    (0 where the three points are not convex)."""
    den = e_m - 2.0 * e_0 + e_p
    if den > 0.0:
        return max(-0.5, min(0.5, 0.5 * (e_m - e_p) / den))
    return 0.0


@numba.njit(cache=True, nogil=True)
def _best_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, coarse_stride, disk, sig_p,
                   dvalues, doffsets, dlengths, dsteps, i_lo, i_hi):
    """Steps 4–5 of the fit: brute-force (s', t0) search and parabolic refinement; (s', best score) or (NaN, 0).

    The coarse pass scans s' indices i_lo, i_lo + stride, … < i_hi (the whole grid for Eq. 2c)."""
    n_s = s_grid.shape[0]
    n_t = t0_grid.shape[0]
    jc = _t0_start_index(k0, t0_grid)
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
        pos += _parabola_offset(e_m, e_0, e_p)
    return s_grid[0] * (s_grid[1] / s_grid[0]) ** pos, best


@numba.njit(cache=True, nogil=True)
def _scores_along_s(r, a, b, K, table_t, cum_t, j, i0, n, out):
    """out[m] = :func:`_score` of T[i0 + m, j] for m < n (T[i, j, k] = table_t[j, k, i], cum likewise).

    Each dot product is summed in ascending k as in :func:`_score` (the same bytes); the n sums
    advance together, so they are independent chains the CPU overlaps and vectorises.
    """
    for m in range(n):
        out[m] = 0.0
    for k in range(a, b + 1):
        rk = r[k + K]
        row = table_t[j, k + K]
        for m in range(n):
            out[m] += rk * row[i0 + m]
    hi, lo = cum_t[j, b + K + 1], cum_t[j, a + K]
    for m in range(n):
        dot = out[m]
        energy = hi[i0 + m] - lo[i0 + m]
        out[m] = 0.0 if dot <= 0.0 or energy <= 0.0 else dot * dot / energy


@numba.njit(cache=True, nogil=True)
def _dots_along_t0(r, a, b, K, table, i, j0, n, out):
    """out[m] = r[a..b]·T[i, j0 + m] for m < n, each summed in ascending k as in :func:`_score`."""
    for m in range(n):
        out[m] = 0.0
    for k in range(a, b + 1):
        rk = r[k + K]
        for m in range(n):
            out[m] += rk * table[i, j0 + m, k + K]


@numba.njit(cache=True, nogil=True)
def _best_gaussian_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, table_t, cum_t, table_c, cum_c,
                            coarse_stride, buf):
    """:func:`_best_template` for Eq. (2c) alone (``disk`` False, whole grid): the same search and result.

    Each pass computes its templates' scores together (:func:`_scores_along_s`, :func:`_dots_along_t0`)
    and then scans them in the order of :func:`_best_template`; every score is the same float as
    :func:`_score`'s, so the chosen template and (s', best score) are identical. ``table_t``, ``cum_t``
    and ``table_c``, ``cum_c`` are :func:`template_table`'s T and its cumulative energy as [j, k, i],
    all s' and every ``coarse_stride``-th (:data:`COARSE_STRIDE`); ``buf`` is scratch of length
    ≥ max(⌈n_s / coarse_stride⌉, 2·coarse_stride + 1, 9).
    """
    n_s = s_grid.shape[0]
    n_t = t0_grid.shape[0]
    jc = _t0_start_index(k0, t0_grid)
    best_i, best = -1, 0.0
    n = (n_s + coarse_stride - 1) // coarse_stride
    _scores_along_s(r, a, b, K, table_c, cum_c, jc, 0, n, buf)
    for m in range(n):
        if buf[m] > best:
            best, best_i = buf[m], m * coarse_stride
    if best_i < 0:
        return np.nan, 0.0
    bi, bj = best_i, jc
    lo, hi = max(0, best_i - coarse_stride), min(n_s, best_i + coarse_stride + 1)
    _scores_along_s(r, a, b, K, table_t, cum_t, jc, lo, hi - lo, buf)
    for m in range(hi - lo):
        if buf[m] > best:
            best, bi = buf[m], lo + m
    i_mid = bi
    lo, hi = max(0, jc - 4), min(n_t, jc + 5)
    _dots_along_t0(r, a, b, K, table, i_mid, lo, hi - lo, buf)
    for m in range(hi - lo):
        sc = _finish(buf[m], cum, i_mid, lo + m, a, b, K)
        if sc > best:
            best, bj = sc, lo + m
    j_mid = bj
    lo, hi = max(0, i_mid - 3), min(n_s, i_mid + 4)
    _scores_along_s(r, a, b, K, table_t, cum_t, j_mid, lo, hi - lo, buf)
    for m in range(hi - lo):
        if buf[m] > best:
            best, bi = buf[m], lo + m
    pos = float(bi)
    if 0 < bi < n_s - 1:
        e_m = energy_r - _score(r, a, b, K, table, cum, bi - 1, bj)
        e_0 = energy_r - best
        e_p = energy_r - _score(r, a, b, K, table, cum, bi + 1, bj)
        pos += _parabola_offset(e_m, e_0, e_p)
    return s_grid[0] * (s_grid[1] / s_grid[0]) ** pos, best


EMPTY_DISK_TABLE = (np.zeros(1), np.zeros(1, dtype=np.int64), np.ones(1, dtype=np.int64), np.ones(1))


#: Edge pixels per parallel chunk of :func:`_fit_kernel`.
_FIT_CHUNK = 256


@numba.njit(cache=True, nogil=True, parallel=True)
def _fit_kernel(ixx, ixy, iyy, rows, cols, cos_t, sin_t, w_min, w_max, kappa,
                s_grid, t0_grid, table, cum, table_t, cum_t, table_c, cum_c, coarse_stride, out_s, out_res, out_win, out_energy,
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
        buf = np.empty(max(n_s, 2 * coarse_stride + 1, 9))
        for n in range(chunk * _FIT_CHUNK, min(nrows, (chunk + 1) * _FIT_CHUNK)):
            out_s[n] = np.nan
            out_res[n] = np.nan
            out_sd[n] = np.nan
            out_resd[n] = np.nan
            out_win[n] = 0
            out_energy[n] = np.nan
            i0, j0 = rows[n], cols[n]
            c, s = cos_t[n], sin_t[n]
            di, dj, proj = nearest_axis_step(c, s)
            cc, cs2, ss = second_steering_weights(c, s)
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
            s_prime, best = _best_gaussian_template(r, a, b, K, k0, energy_r, s_grid, t0_grid, table, cum, table_t,
                                                    cum_t, table_c, cum_c, coarse_stride, buf)
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


def run_fit_kernel(hessian, rows, cols, theta, w_min, w_max, templates, sigma2, disk_min_width, disk_table):
    """:func:`_fit_kernel` on the edge pixels (rows, cols) of one σ2: (s, ρ, window, energy, s_disk, ρ_disk)."""
    n = rows.size
    s_est, r_est, e_est, sd_est, rd_est = (np.empty(n) for _ in range(5))
    w_est = np.empty(n, dtype=np.int64)
    _fit_kernel(*hessian, rows, cols, np.cos(theta), np.sin(theta), w_min, w_max, FIT_KAPPA,
                *templates, COARSE_STRIDE, s_est, r_est, w_est, e_est,
                float(sigma2), float(disk_min_width), *disk_table, sd_est, rd_est)
    return s_est, r_est, w_est, e_est, sd_est, rd_est
