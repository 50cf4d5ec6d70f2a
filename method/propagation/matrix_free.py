"""Matrix-free preconditioned CG on the full-resolution propagation system (Eq. 4), numba kernels.

The refinement of :func:`method.propagation.defocus.propagate_defocus`'s coarse mode: CG on the exact
full-resolution normal equations ``(LᵀL + diag a) x = rhs`` without assembling them (the operator is
applied from the affinities, :func:`method.propagation.system.padded_weights`), preconditioned by

* :func:`two_level_pcg` (default): Jacobi + a coarse-grid correction (bilinear P, Pᵀ and one V-cycle
  / LU solve of the coarse level of :mod:`method.propagation.solvers`: the Galerkin operator of
  :mod:`method.propagation.galerkin` by default, or the re-discretised coarse system);
* :func:`jacobi_pcg`: Jacobi alone (the earlier refinement, kept as the comparison).

Vectors live on a grid zero-padded by the neighbourhood radius r so the stencils need no bounds
checks; every kernel is row-parallel without shared writes and adds per-row partial sums in row
order, so the iterates are bit-identical for any number of threads.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp

# OpenMP wait policy: numba's "omp" worker threads busy-wait after every parallel region by default,
# and the refinement runs ~3 regions per CG iteration with the serial coarse V-cycle in between. The
# entry points (``repro``, see repro/__init__.py) set OMP_WAIT_POLICY=PASSIVE; this pure-numerics
# package leaves the process environment alone (a library user can set it before the first call).

__all__ = ["bilinear_1d", "jacobi_pcg", "two_level_pcg"]


# --------------------------------------------------------------------------------------------
# matrix-free full-resolution operator (numba) for the refinement after a coarse solve
# --------------------------------------------------------------------------------------------
#: Rows per block of the fused matrix-free operator (each block recomputes a halo of r rows of L·p).
_ROW_BLOCK = 32


@numba.njit(cache=True, parallel=True)
def _new_direction(z, p, beta, r):
    """p = z + β·p in place on the image rows of the padded grid (rows in parallel)."""
    hp, wp = p.shape
    w = wp - 2 * r
    for py in numba.prange(r, hp - r):
        prow = p[py, r:r + w]
        zrow = z[py, r:r + w]
        for i in range(w):
            prow[i] = zrow[i] + beta * prow[i]


@numba.njit(cache=True, parallel=True)
def _apply_normal(p, weights, offs, a_diag, q, rowdot):
    """Matrix-free q = (LᵀL + diag a) p and the per-row dot products rowdot[y] = Σ_x p·q.

    All grids are zero-padded by r = neighbourhood radius on every side ((H+2r) x (W+2r); weights
    (K, H+2r, W+2r) are 0 at padded pixels and for out-of-image neighbours). Row blocks of
    :data:`_ROW_BLOCK` rows run in parallel; each computes t = L p for its rows plus an r-row halo into
    a private buffer, then q = t − Σ_j w[j, p − o_j]·t[p − o_j] + a ∘ p (Lᵀ as a gather). The inner
    loops run along a row with one offset at a time (SIMD-friendly). No write is shared between
    threads and every value has a fixed operation order, so q is independent of the thread count.
    """
    k = offs.shape[0]
    hp, wp = p.shape
    r = 0
    for j in range(k):
        r = max(r, abs(offs[j, 0]), abs(offs[j, 1]))
    h = hp - 2 * r
    w = wp - 2 * r
    nblk = (h + _ROW_BLOCK - 1) // _ROW_BLOCK
    for b in numba.prange(nblk):
        y0 = b * _ROW_BLOCK
        y1 = min(h, y0 + _ROW_BLOCK)
        t = np.zeros((y1 - y0 + 2 * r, wp))  # image rows y0 − r … y1 + r − 1; 0 outside the image
        # (loops index 1-D row views from 0 so numba emits no negative-index checks and LLVM vectorises)
        for yy in range(max(0, y0 - r), min(h, y1 + r)):
            py = yy + r
            trow = t[yy - y0 + r, r:r + w]
            prow = p[py, r:r + w]
            for i in range(w):
                trow[i] = prow[i]
            for j in range(k):
                dy = offs[j, 0]
                dx = offs[j, 1]
                wrow = weights[j, py, r:r + w]
                nrow = p[py + dy, r + dx:r + dx + w]
                for i in range(w):
                    trow[i] -= wrow[i] * nrow[i]
        for y in range(y0, y1):
            py = y + r
            ty = y - y0 + r
            qrow = q[py, r:r + w]
            prow = p[py, r:r + w]
            arow = a_diag[y]
            trow = t[ty, r:r + w]
            for i in range(w):
                qrow[i] = trow[i] + arow[i] * prow[i]
            for j in range(k):
                dy = offs[j, 0]
                dx = offs[j, 1]
                wrow = weights[j, py - dy, r - dx:r - dx + w]
                srow = t[ty - dy, r - dx:r - dx + w]
                for i in range(w):
                    qrow[i] -= wrow[i] * srow[i]
            acc = 0.0
            for i in range(w):
                acc += prow[i] * qrow[i]
            rowdot[y] = acc


@numba.njit(cache=True, parallel=True)
def _cg_update(x, res, z, p, q, dinv, step, r, rowsums):
    """x += step·p, res −= step·q, z = dinv ∘ res; rowsums[y] = (Σ res·z, Σ res²) per image row."""
    hp, wp = x.shape
    h = hp - 2 * r
    w = wp - 2 * r
    for y in numba.prange(h):
        py = y + r
        xr = x[py, r:r + w]
        rr_ = res[py, r:r + w]
        zr = z[py, r:r + w]
        pr = p[py, r:r + w]
        qr = q[py, r:r + w]
        dr = dinv[py, r:r + w]
        rz = 0.0
        rr = 0.0
        for i in range(w):
            xr[i] += step * pr[i]
            rv = rr_[i] - step * qr[i]
            rr_[i] = rv
            zv = dr[i] * rv
            zr[i] = zv
            rz += rv * zv
            rr += rv * rv
        rowsums[y, 0] = rz
        rowsums[y, 1] = rr


@numba.njit(cache=True, parallel=True)
def _normal_diagonal(weights, offs, a_diag, r, out):
    """diag(LᵀL + diag a)[p] = 1 + a_p + Σ_j w[j, p − o_j]² (gather), padded like the vectors."""
    k = offs.shape[0]
    h, w = a_diag.shape
    for y in numba.prange(h):
        py = y + r
        for x in range(w):
            px = x + r
            v = 1.0 + a_diag[y, x]
            for j in range(k):
                wv = np.float64(weights[j, py - offs[j, 0], px - offs[j, 1]])
                v += wv * wv
            out[py, px] = v


def jacobi_pcg(weights, offs, a_diag, rhs, x0, *, maxiter, tol):
    """CG on (LᵀL + diag a) x = rhs with the Jacobi preconditioner; returns (x, relative residual).

    Parameters
    ----------
    weights : ndarray, (K, H+2r, W+2r), float32 or float64
        Affinities from :func:`method.propagation.system.padded_weights` (zero padding).
    offs : ndarray, (K, 2), int64
    a_diag : ndarray, (H, W), float64
        Diagonal data term α_p + λ.
    rhs, x0 : ndarray, (H, W), float64
    maxiter : int
    tol : float
        Stop when ‖res‖ ≤ tol·‖rhs‖.

    Notes
    -----
    Vectors live on a zero-padded grid (border r = neighbourhood radius) so the numba stencils need no
    bounds checks. Three row-parallel numba kernels per iteration (:func:`_new_direction`;
    :func:`_apply_normal`: operator product with p·q per row; :func:`_cg_update`: x, residual, preconditioned
    residual and r·z, r·r per row). The per-row partial sums are added in row order, so the iterates
    are bit-identical for any number of threads.
    """
    h, w = x0.shape
    r = int(np.max(np.abs(offs)))
    inner = (slice(r, r + h), slice(r, r + w))
    shape = (h + 2 * r, w + 2 * r)

    def padded(a):
        out = np.zeros(shape)
        out[inner] = a
        return out

    apply_normal, direction_and_apply = _operator_kernels(offs)
    diag = np.zeros(shape)
    _normal_diagonal(weights, offs, a_diag, r, diag)
    dinv = np.zeros(shape)
    dinv[inner] = 1.0 / diag[inner]
    x = padded(x0)
    p = np.zeros(shape)
    q = np.zeros(shape)
    rowdot = np.zeros(h)
    rowsums = np.zeros((h, 2))
    apply_normal(x, weights, offs, a_diag, q, rowdot)  # residual of the initial guess
    res = padded(rhs)
    res[inner] -= q[inner]
    z = dinv * res
    rz = float(np.sum(res[inner] * z[inner], axis=1).sum())
    rnorm = float(np.sqrt(np.sum(res[inner] ** 2, axis=1).sum()))
    bnorm = float(np.sqrt(np.sum(rhs * rhs, axis=1).sum())) or 1.0  # no BLAS: thread-count independent
    beta = 0.0
    for _ in range(maxiter):
        if rnorm <= tol * bnorm:
            break
        _new_direction(z, p, beta, r)
        apply_normal(p, weights, offs, a_diag, q, rowdot)
        pq = float(rowdot.sum())
        if not pq > 0:
            break
        step = rz / pq
        _cg_update(x, res, z, p, q, dinv, step, r, rowsums)
        rz_new = float(rowsums[:, 0].sum())
        rnorm = float(np.sqrt(rowsums[:, 1].sum()))
        beta = rz_new / rz
        rz = rz_new
    return x[inner].copy(), rnorm / bnorm

# --------------------------------------------------------------------------------------------
# two-level preconditioner: coarse-grid correction (bilinear P, Pᵀ) + Jacobi, matrix-free fine level
# --------------------------------------------------------------------------------------------
def bilinear_1d(n, n_c, s):
    """1-D bilinear interpolation from n_c block-centred coarse samples to n fine pixel centres.

    Fine pixel i sits at coarse coordinate (i + 0.5)/s − 0.5; it takes (1 − f) of the coarse sample
    below and f of the one above, indices clamped to [0, n_c − 1] (edge replication, as
    :func:`method.propagation.defocus._upsample`).

    Returns
    -------
    forward : tuple of ndarray
        CSR (indptr (n+1,), indices, data) of the n x n_c matrix P₁ (rows: fine pixels).
    transpose : tuple of ndarray
        CSR of P₁ᵀ (rows: coarse samples, fine indices ascending), for the restriction.
    """
    pos = (np.arange(n) + 0.5) / s - 0.5
    lo = np.floor(pos)
    frac = pos - lo
    lo = lo.astype(np.int64)
    rows = np.repeat(np.arange(n), 2)
    cols = np.clip(np.stack([lo, lo + 1], axis=1), 0, n_c - 1).ravel()
    vals = np.stack([1.0 - frac, frac], axis=1).ravel()
    P1 = sp.csr_matrix((vals, (rows, cols)), shape=(n, n_c))
    P1.sum_duplicates()
    P1.sort_indices()
    T1 = P1.T.tocsr()
    T1.sum_duplicates()
    T1.sort_indices()
    as_tuple = lambda m: (m.indptr.astype(np.int64), m.indices.astype(np.int64), m.data.astype(np.float64))
    return as_tuple(P1), as_tuple(T1)


@numba.njit(cache=True, parallel=True)
def _direction_and_apply(z, p_old, beta, weights, offs, a_diag, p_new, q, rowdot):
    """p_new = z + β·p_old, q = (LᵀL + diag a) p_new and rowdot[y] = Σ_x p_new·q, in one parallel region.

    The same row blocks as :func:`_apply_normal`; each block forms z + β·p_old for its rows plus a
    2r-row halo in a private buffer (so it never reads another block's output), computes L·p over its
    rows ± r, then q by the gather form of Lᵀ, and writes its own rows of ``p_new``. The values are
    bit-identical to :func:`_new_direction` followed by :func:`_apply_normal`. Padded grids (border r).
    """
    k = offs.shape[0]
    hp, wp = z.shape
    r = 0
    for j in range(k):
        r = max(r, abs(offs[j, 0]), abs(offs[j, 1]))
    h = hp - 2 * r
    w = wp - 2 * r
    nblk = (h + _ROW_BLOCK - 1) // _ROW_BLOCK
    for b in numba.prange(nblk):
        y0 = b * _ROW_BLOCK
        y1 = min(h, y0 + _ROW_BLOCK)
        nb = y1 - y0
        pb = np.zeros((nb + 4 * r, wp))  # p rows y0 − 2r … y1 + 2r − 1 (padded columns); 0 outside
        for yy in range(max(0, y0 - 2 * r), min(h, y1 + 2 * r)):
            brow = pb[yy - y0 + 2 * r, r:r + w]
            zrow = z[yy + r, r:r + w]
            orow = p_old[yy + r, r:r + w]
            for i in range(w):
                brow[i] = zrow[i] + beta * orow[i]
        t = np.zeros((nb + 2 * r, wp))  # L·p for rows y0 − r … y1 + r − 1; 0 outside the image
        for yy in range(max(0, y0 - r), min(h, y1 + r)):
            py = yy + r
            by = yy - y0 + 2 * r
            trow = t[yy - y0 + r, r:r + w]
            prow = pb[by, r:r + w]
            for i in range(w):
                trow[i] = prow[i]
            for j in range(k):
                dy = offs[j, 0]
                dx = offs[j, 1]
                wrow = weights[j, py, r:r + w]
                nrow = pb[by + dy, r + dx:r + dx + w]
                for i in range(w):
                    trow[i] -= wrow[i] * nrow[i]
        for y in range(y0, y1):
            py = y + r
            ty = y - y0 + r
            prow = pb[y - y0 + 2 * r, r:r + w]
            outp = p_new[py, r:r + w]
            for i in range(w):
                outp[i] = prow[i]
            qrow = q[py, r:r + w]
            arow = a_diag[y]
            trow = t[ty, r:r + w]
            for i in range(w):
                qrow[i] = trow[i] + arow[i] * prow[i]
            for j in range(k):
                dy = offs[j, 0]
                dx = offs[j, 1]
                wrow = weights[j, py - dy, r - dx:r - dx + w]
                srow = t[ty - dy, r - dx:r - dx + w]
                for i in range(w):
                    qrow[i] -= wrow[i] * srow[i]
            acc = 0.0
            for i in range(w):
                acc += prow[i] * qrow[i]
            rowdot[y] = acc


#: The 3×3 neighbourhood's offsets in the raster order of :func:`method.propagation.system._offsets`:
#: the order the unrolled kernels below hard-code.
_OFFSETS_3X3 = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)], dtype=np.int64)


def _is_3x3(offs) -> bool:
    return offs.shape == _OFFSETS_3X3.shape and bool(np.array_equal(offs, _OFFSETS_3X3))


@numba.njit(cache=True, inline="always")
def _l_row_3x3(weights, py, pm, pc, pp, tr, w):
    """tr[x] = (L p)[x] for one padded row py from the rows above / at / below (3×3, r = 1).

    The same products, subtracted in the same (offset) order, as the generic loops of
    :func:`_apply_normal`, so the same bits; unrolled over the 8 offsets on contiguous rows.
    """
    w0 = weights[0, py]
    w1 = weights[1, py]
    w2 = weights[2, py]
    w3 = weights[3, py]
    w4 = weights[4, py]
    w5 = weights[5, py]
    w6 = weights[6, py]
    w7 = weights[7, py]
    for x in range(1, w + 1):
        tr[x] = (pc[x] - w0[x] * pm[x - 1] - w1[x] * pm[x] - w2[x] * pm[x + 1] - w3[x] * pc[x - 1]
                 - w4[x] * pc[x + 1] - w5[x] * pp[x - 1] - w6[x] * pp[x] - w7[x] * pp[x + 1])


@numba.njit(cache=True, inline="always")
def _lt_row_3x3(weights, py, pc, ar, tm, tc, tp, qr, w):
    """qr[x] = (Lᵀ t + a ∘ p)[x] for one padded row py (gather form, 3×3); returns Σ_x p·q.

    Offset j = (dy, dx) contributes w[j, p − o_j]·t[p − o_j], in the order of :func:`_apply_normal`.
    """
    g0 = weights[0, py + 1]
    g1 = weights[1, py + 1]
    g2 = weights[2, py + 1]
    g3 = weights[3, py]
    g4 = weights[4, py]
    g5 = weights[5, py - 1]
    g6 = weights[6, py - 1]
    g7 = weights[7, py - 1]
    acc = 0.0
    for x in range(1, w + 1):
        v = (tc[x] + ar[x - 1] * pc[x] - g0[x + 1] * tp[x + 1] - g1[x] * tp[x] - g2[x - 1] * tp[x - 1]
             - g3[x + 1] * tc[x + 1] - g4[x - 1] * tc[x - 1] - g5[x + 1] * tm[x + 1] - g6[x] * tm[x]
             - g7[x - 1] * tm[x - 1])
        qr[x] = v
        acc += pc[x] * v
    return acc


@numba.njit(cache=True, parallel=True)
def _apply_normal_3x3(p, weights, offs, a_diag, q, rowdot):
    """:func:`_apply_normal` for the 3×3 neighbourhood (offsets :data:`_OFFSETS_3X3`), bit-identical.

    The same row blocks, halo and operation order; the offsets are unrolled on contiguous rows
    (≈ 8× faster than the generic loops, whose runtime-offset slices LLVM does not vectorise).
    """
    hp, wp = p.shape
    h = hp - 2
    w = wp - 2
    nblk = (h + _ROW_BLOCK - 1) // _ROW_BLOCK
    for b in numba.prange(nblk):
        y0 = b * _ROW_BLOCK
        y1 = min(h, y0 + _ROW_BLOCK)
        t = np.zeros((y1 - y0 + 2, wp))  # image rows y0 − 1 … y1; 0 outside the image
        for yy in range(max(0, y0 - 1), min(h, y1 + 1)):
            py = yy + 1
            _l_row_3x3(weights, py, p[py - 1], p[py], p[py + 1], t[yy - y0 + 1], w)
        for y in range(y0, y1):
            py = y + 1
            ty = y - y0 + 1
            rowdot[y] = _lt_row_3x3(weights, py, p[py], a_diag[y], t[ty - 1], t[ty], t[ty + 1], q[py], w)


@numba.njit(cache=True, parallel=True)
def _direction_and_apply_3x3(z, p_old, beta, weights, offs, a_diag, p_new, q, rowdot):
    """:func:`_direction_and_apply` for the 3×3 neighbourhood, bit-identical (see :func:`_apply_normal_3x3`)."""
    hp, wp = z.shape
    h = hp - 2
    w = wp - 2
    nblk = (h + _ROW_BLOCK - 1) // _ROW_BLOCK
    for b in numba.prange(nblk):
        y0 = b * _ROW_BLOCK
        y1 = min(h, y0 + _ROW_BLOCK)
        nb = y1 - y0
        pb = np.zeros((nb + 4, wp))  # p rows y0 − 2 … y1 + 1 (padded columns); 0 outside
        for yy in range(max(0, y0 - 2), min(h, y1 + 2)):
            brow = pb[yy - y0 + 2]
            zrow = z[yy + 1]
            orow = p_old[yy + 1]
            for x in range(1, w + 1):
                brow[x] = zrow[x] + beta * orow[x]
        t = np.zeros((nb + 2, wp))  # L·p for rows y0 − 1 … y1; 0 outside the image
        for yy in range(max(0, y0 - 1), min(h, y1 + 1)):
            by = yy - y0 + 2
            _l_row_3x3(weights, yy + 1, pb[by - 1], pb[by], pb[by + 1], t[yy - y0 + 1], w)
        for y in range(y0, y1):
            py = y + 1
            ty = y - y0 + 1
            prow = pb[y - y0 + 2]
            outp = p_new[py]
            for x in range(1, w + 1):
                outp[x] = prow[x]
            rowdot[y] = _lt_row_3x3(weights, py, prow, a_diag[y], t[ty - 1], t[ty], t[ty + 1], q[py], w)


def _operator_kernels(offs):
    """(apply_normal, direction_and_apply) for these offsets: the unrolled 3×3 ones when they apply."""
    if _is_3x3(offs):
        return _apply_normal_3x3, _direction_and_apply_3x3
    return _apply_normal, _direction_and_apply


@numba.njit(cache=True, parallel=True)
def _step_and_restrict(x, res_old, res_new, p, q, step, r, s, ty_ptr, ty_idx, ty_val,
                       tx_ptr, tx_idx, tx_val, tmp, r_c, rowsq):
    """CG update and restriction of the new residual, in one parallel region over coarse rows.

    Coarse row i owns the fine rows [i·s, (i+1)·s) ∩ [0, H): x += step·p, res_new = res_old − step·q,
    rowsq[y] = Σ_x res_new². It also forms r_c[i, :] = (Pᵀ res_new)[i, :] with P = P_y ⊗ P_x
    (bilinear, :func:`bilinear_1d`), recomputing res_old − step·q for the fine rows it reads (the
    same operation, so the same bits as the stored res_new) instead of reading rows another thread
    writes. ``tmp`` (H_c, W) holds P_yᵀ res_new per coarse row. Fixed summation orders: the result
    does not depend on the thread count. Padded fine grids (border r); ``r_c`` is (H_c, W_c).
    """
    hc, wc = r_c.shape
    w = tmp.shape[1]
    h = x.shape[0] - 2 * r
    # (full-row views indexed xx + r: contiguous 1-D rows that LLVM vectorises; slices r:r + w were
    # ~5x slower. Same operations in the same order.)
    for i in numba.prange(hc):
        for y in range(i * s, min((i + 1) * s, h)):
            py = y + r
            xr = x[py]
            ro = res_old[py]
            rn = res_new[py]
            pr = p[py]
            qr = q[py]
            acc = 0.0
            for xx in range(r, r + w):
                xr[xx] += step * pr[xx]
                rv = ro[xx] - step * qr[xx]
                rn[xx] = rv
                acc += rv * rv
            rowsq[y] = acc
        trow = tmp[i]
        for xx in range(w):
            trow[xx] = 0.0
        for kk in range(ty_ptr[i], ty_ptr[i + 1]):
            v = ty_val[kk]
            py = ty_idx[kk] + r
            ro = res_old[py]
            qr = q[py]
            for xx in range(w):
                trow[xx] += v * (ro[xx + r] - step * qr[xx + r])
        for j in range(wc):
            acc = 0.0
            for kk in range(tx_ptr[j], tx_ptr[j + 1]):
                acc += tx_val[kk] * trow[tx_idx[kk]]
            r_c[i, j] = acc


@numba.njit(cache=True)
def _interpolate_x(e_c, px_ptr, px_idx, px_val, out):
    """out[i, :] = P_x e_c[i, :] for every coarse row (serial: H_c·W values, no parallel region)."""
    hc = e_c.shape[0]
    w = out.shape[1]
    for i in range(hc):
        erow = e_c[i]
        orow = out[i]
        for xx in range(w):
            acc = 0.0
            for m in range(px_ptr[xx], px_ptr[xx + 1]):
                acc += px_val[m] * erow[px_idx[m]]
            orow[xx] = acc


@numba.njit(cache=True, parallel=True)
def _precondition(res, dinv, e_x, r, py_ptr, py_idx, py_val, z, rowdot):
    """z = dinv ∘ res + P_y e_x (additive two-level preconditioner) and rowdot[y] = Σ_x res·z.

    ``e_x`` (H_c, W) is the coarse correction already interpolated along x (:func:`_interpolate_x`);
    each fine row (in parallel) adds its ≤ 2 weighted coarse rows. Padded grids (border r) as in
    :func:`_apply_normal`; the padding of z is left untouched (zero).
    """
    w = z.shape[1] - 2 * r
    h = z.shape[0] - 2 * r
    for y in numba.prange(h):
        py = y + r
        zr = z[py]
        rr_ = res[py]
        dr = dinv[py]
        for xx in range(r, r + w):
            zr[xx] = dr[xx] * rr_[xx]
        for kk in range(py_ptr[y], py_ptr[y + 1]):
            v = py_val[kk]
            erow = e_x[py_idx[kk]]
            for xx in range(w):
                zr[xx + r] += v * erow[xx]
        acc = 0.0
        for xx in range(r, r + w):
            acc += rr_[xx] * zr[xx]
        rowdot[y] = acc


def two_level_pcg(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol, coarse_scale=None,
                  vector_dtype=np.float64):
    """CG on the full-resolution Eq. (4) system, preconditioned by Jacobi + a coarse-grid correction.

    Parameters
    ----------
    weights : ndarray, (K, H+2r, W+2r), float32 or float64
        Affinities from :func:`method.propagation.system.padded_weights` (zero padding).
    offs : ndarray, (K, 2), int64
    a_diag : ndarray, (H, W), float64
        Diagonal data term α_p + λ.
    rhs, x0 : ndarray, (H, W), float64
        Right-hand side α·BM + λ·mean(BM) and starting map (σ, px).
    coarse : method.propagation.solvers.CoarseLevel
        Coarse system A_c (the re-discretised Eq. 4 on the s-times coarser grid) with its
        approximate inverse (one AMG V-cycle, or the LU solve).
    s : int
        Coarsening factor.
    coarse_shape : tuple of int
        (H_c, W_c) = (⌈H/s⌉, ⌈W/s⌉).
    maxiter : int
    tol : float
        Stop early when ‖res‖ ≤ tol·‖rhs‖.
    vector_dtype : numpy dtype, keyword-only
        Storage of the CG vectors (x, residuals, directions, D⁻¹, a); CG scalars and per-row sums are
        float64 whatever it is. float64 (default) or float32 (the driver's choice: half the memory
        traffic of the memory-bound iterations).
    coarse_scale : float or None, keyword-only
        Factor c of the coarse correction c·P Ã_c⁻¹ Pᵀ: None = s², for the re-discretised coarse
        system (A_c ≈ s²·PᵀAP); 1 for the Galerkin operator A_c = PᵀAP
        (:func:`method.propagation.galerkin.galerkin_coarse_operator`).

    Returns
    -------
    x : ndarray, (H, W), float64
    relative_residual : float

    Notes
    -----
    Preconditioner M⁻¹ r = D⁻¹ r + c·P Ã_c⁻¹ Pᵀ r (additive two-level; c = s² or 1, see
    ``coarse_scale``):

    1. D = diag(LᵀL + diag a) (Jacobi), damping the oscillatory error the coarse grid cannot see;
    2. Pᵀ r: restriction by the transpose of the bilinear interpolation P used for the start map
       (:func:`bilinear_1d`, separable);
    3. Ã_c⁻¹: the coarse approximate inverse. Either the Galerkin operator A_c = PᵀAP (c = 1), or the
       re-discretised coarse system built with α_c = s²·Σ_block α, so A_c ≈ s²·PᵀAP (see
       :func:`method.propagation.defocus.propagate_defocus`, Notes) and s²·P A_c⁻¹ Pᵀ ≈ P (PᵀAP)⁻¹ Pᵀ;
    4. prolongation P and the sum with step 1.

    M is symmetric positive definite and the same linear map at every iteration, so plain
    (non-flexible) CG applies. The fine operator stays matrix-free; CG scalars are float64, vectors
    ``vector_dtype``. One iteration = three row-parallel numba regions plus the serial coarse part:

    a. :func:`_direction_and_apply`: p ← z + β·p, q = A p, p·q per row;
    b. :func:`_step_and_restrict`: x += step·p, res −= step·q, ‖res‖² per row, r_c = Pᵀ res;
    c. coarse V-cycle on r_c (single-threaded), :func:`_interpolate_x`, then :func:`_precondition`:
       z = D⁻¹ res + P e_c, res·z per row.

    Few parallel regions matter on a shared machine (every region ends in a barrier). Per-row
    partial sums are added in row order and the coarse part runs single-threaded (sparse products,
    BLAS limited to one thread), so the iterates are bit-identical for any number of threads. The
    preconditioner is not applied after the last iteration. Double buffers for p and res keep the
    fused regions free of read/write races.
    """
    from threadpoolctl import threadpool_limits

    h, w = x0.shape
    hc, wc = coarse_shape
    r = int(np.max(np.abs(offs)))
    inner = (slice(r, r + h), slice(r, r + w))
    shape = (h + 2 * r, w + 2 * r)
    (py_ptr, py_idx, py_val), (ty_ptr, ty_idx, ty_val) = bilinear_1d(h, hc, s)
    (px_ptr, px_idx, px_val), (tx_ptr, tx_idx, tx_val) = bilinear_1d(w, wc, s)
    scale = float(s * s) if coarse_scale is None else float(coarse_scale)

    vdt = np.dtype(vector_dtype)

    def padded(a):
        out = np.zeros(shape, vdt)
        out[inner] = a
        return out

    apply_normal, direction_and_apply = _operator_kernels(offs)
    diag = np.zeros(shape)
    _normal_diagonal(weights, offs, a_diag, r, diag)
    dinv = np.zeros(shape, vdt)
    dinv[inner] = 1.0 / diag[inner]
    a_diag = np.ascontiguousarray(a_diag, dtype=vdt)
    x = padded(x0)
    p, p_next = np.zeros(shape, vdt), np.zeros(shape, vdt)
    res_next = np.zeros(shape, vdt)
    q = np.zeros(shape, vdt)
    z = np.zeros(shape, vdt)
    rowdot = np.zeros(h)
    rowsq = np.zeros(h)
    tmp = np.zeros((hc, w))
    r_c = np.zeros((hc, wc))

    def precondition(res, r_c):
        """z = M⁻¹ res from the restricted residual r_c; returns Σ res·z."""
        e_c = scale * coarse.apply_inverse(r_c.ravel()).reshape(hc, wc)
        _interpolate_x(e_c, px_ptr, px_idx, px_val, tmp)
        _precondition(res, dinv, tmp, r, py_ptr, py_idx, py_val, z, rowdot)
        return float(rowdot.sum())

    with threadpool_limits(limits=1, user_api="blas"):
        apply_normal(x, weights, offs, a_diag, q, rowdot)  # residual of the initial guess
        res = padded(rhs)
        res[inner] -= q[inner]
        rnorm = float(np.sqrt(np.sum(res[inner] ** 2, axis=1).sum()))
        bnorm = float(np.sqrt(np.sum(rhs * rhs, axis=1).sum())) or 1.0  # no BLAS: thread-count independent
        if maxiter > 0 and rnorm > tol * bnorm:
            # restriction of the initial residual: the step kernel with step 0 leaves x and res as they are
            _step_and_restrict(x, res, res_next, p, q, 0.0, r, s, ty_ptr, ty_idx, ty_val,
                               tx_ptr, tx_idx, tx_val, tmp, r_c, rowsq)
            res, res_next = res_next, res
            rz = precondition(res, r_c)
        beta = 0.0
        for it in range(maxiter):
            if rnorm <= tol * bnorm:
                break
            direction_and_apply(z, p, beta, weights, offs, a_diag, p_next, q, rowdot)  # p ← z + βp; q = A p
            p, p_next = p_next, p
            pq = float(rowdot.sum())
            if not pq > 0:
                break
            step = rz / pq
            _step_and_restrict(x, res, res_next, p, q, step, r, s, ty_ptr, ty_idx, ty_val,
                               tx_ptr, tx_idx, tx_val, tmp, r_c, rowsq)  # x, res updated; r_c = Pᵀ res
            res, res_next = res_next, res
            rnorm = float(np.sqrt(rowsq.sum()))
            if it == maxiter - 1 or rnorm <= tol * bnorm:
                break
            rz_new = precondition(res, r_c)
            beta = rz_new / rz
            rz = rz_new
    return x[inner].astype(np.float64), rnorm / bnorm



