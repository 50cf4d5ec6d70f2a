"""Matrix-free preconditioned CG on the full-resolution propagation system (Eq. 4), numba kernels.

The refinement of :func:`method.propagation.defocus.propagate_defocus`'s coarse mode: CG on the exact
full-resolution normal equations ``(LᵀL + diag a) x = rhs`` without assembling them (the operator is
applied from the affinities, :func:`method.propagation.system.padded_weights`), preconditioned by Jacobi + a coarse-grid correction (:func:`two_level_pcg`: bilinear P, Pᵀ and one
V-cycle / LU solve of the coarse level of :mod:`method.propagation.solvers`, the Galerkin operator of
:mod:`method.propagation.galerkin`).

The operator's kernels are in :mod:`method.propagation.normal_operator`. Vectors live on a grid
zero-padded by the neighbourhood radius r so the stencils need no bounds checks; every kernel is
row-parallel without shared writes and adds per-row partial sums in row order, so the iterates are
bit-identical for any number of threads.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp

from .normal_operator import DOT_ROWS, normal_diagonal, operator_kernels, row_dots

# OpenMP wait policy: numba's "omp" worker threads busy-wait after every parallel region by default,
# and the refinement runs ~3 regions per CG iteration with the serial coarse V-cycle in between. The
# entry points (``repro``, see repro/__init__.py) set OMP_WAIT_POLICY=PASSIVE; this pure-numerics
# package leaves the process environment alone (a library user can set it before the first call).

__all__ = ["bilinear_1d", "two_level_pcg"]


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
def _step_and_restrict(x, res_old, res_new, p, q, step, r, s, ty_ptr, ty_idx, ty_val,
                       tx_ptr, tx_idx, tx_val, tmp, r_c, rowsq):
    """CG update and restriction of the new residual, in one parallel region over coarse rows.

    Coarse row i owns the fine rows [i·s, (i+1)·s) ∩ [0, H): x += step·p, res_new = res_old − step·q,
    rowsq[y] = Σ_x res_new² (of the unrounded float64 values, added in ascending x; :func:`row_dots`).
    It also forms r_c[i, :] = (Pᵀ res_new)[i, :] with P = P_y ⊗ P_x (bilinear, :func:`bilinear_1d`)
    from those unrounded rows, recomputing res_old − step·q for the fine rows of neighbouring blocks
    it reads (the same operation, so the same bits) instead of reading rows another thread writes.
    ``tmp`` (H_c, W) holds P_yᵀ res_new per coarse row. Fixed summation orders: the result does not
    depend on the thread count. Padded fine grids (border r); ``r_c`` is (H_c, W_c).
    """
    hc, wc = r_c.shape
    w = tmp.shape[1]
    h = x.shape[0] - 2 * r
    # (unsigned column indices on full-row views: numba emits no negative-index wrap-around for
    # them, so LLVM vectorises the loops; same operations in the same order)
    wu = np.uint64(w)
    ru = np.uint64(r)
    for i in numba.prange(hc):
        y0 = i * s
        y1 = min((i + 1) * s, h)
        rv = np.empty((y1 - y0, w))  # unrounded res_new rows of this block
        for y in range(y0, y1):
            py = y + r
            xr = x[py]
            ro = res_old[py]
            rn = res_new[py]
            pr = p[py]
            qr = q[py]
            vr = rv[y - y0]
            for xx in range(wu):
                c = xx + ru
                xr[c] += step * pr[c]
                v = ro[c] - step * qr[c]
                rn[c] = v
                vr[xx] = v
        row_dots(rv, 0, rv, 0, y1 - y0, 0, w, rowsq, y0)
        trow = tmp[i]
        for xx in range(wu):
            trow[xx] = 0.0
        for kk in range(ty_ptr[i], ty_ptr[i + 1]):
            v = ty_val[kk]
            y = ty_idx[kk]
            if y0 <= y < y1:
                vr = rv[y - y0]
                for xx in range(wu):
                    trow[xx] += v * vr[xx]
            else:
                ro = res_old[y + r]
                qr = q[y + r]
                for xx in range(wu):
                    c = xx + ru
                    trow[xx] += v * (ro[c] - step * qr[c])
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
    each fine row adds its ≤ 2 weighted coarse rows; groups of :data:`DOT_ROWS` rows run in
    parallel (:func:`row_dots`: each row's sum in ascending x). Padded grids (border r) as in
    :func:`apply_normal`; the padding of z is left untouched (zero).
    """
    w = z.shape[1] - 2 * r
    h = z.shape[0] - 2 * r
    wu = np.uint64(w)
    ru = np.uint64(r)
    for g in numba.prange((h + DOT_ROWS - 1) // DOT_ROWS):
        y0 = g * DOT_ROWS
        y1 = min(h, y0 + DOT_ROWS)
        for y in range(y0, y1):
            py = y + r
            zr = z[py]
            rr_ = res[py]
            dr = dinv[py]
            for xx in range(ru, ru + wu):
                zr[xx] = dr[xx] * rr_[xx]
            for kk in range(py_ptr[y], py_ptr[y + 1]):
                v = py_val[kk]
                erow = e_x[py_idx[kk]]
                for xx in range(wu):
                    zr[xx + ru] += v * erow[xx]
        row_dots(res, y0 + r, z, y0 + r, y1 - y0, r, w, rowdot, y0)


def two_level_pcg(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol, coarse_scale=1.0,
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
        Coarse system A_c on the s-times coarser grid (the Galerkin operator) with its
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
    coarse_scale : float, keyword-only
        Factor c of the coarse correction c·P Ã_c⁻¹ Pᵀ: 1 (default) for the Galerkin operator
        A_c = PᵀAP (:func:`method.propagation.galerkin.galerkin_coarse_operator`); γ for a coarse
        operator A_c ≈ γ·PᵀAP (then γ·P A_c⁻¹ Pᵀ ≈ P (PᵀAP)⁻¹ Pᵀ).

    Returns
    -------
    x : ndarray, (H, W), float64
    relative_residual : float

    Notes
    -----
    Preconditioner M⁻¹ r = D⁻¹ r + c·P Ã_c⁻¹ Pᵀ r (additive two-level; c = ``coarse_scale``):

    1. D = diag(LᵀL + diag a) (Jacobi), damping the oscillatory error the coarse grid cannot see;
    2. Pᵀ r: restriction by the transpose of the bilinear interpolation P used for the start map
       (:func:`bilinear_1d`, separable);
    3. Ã_c⁻¹: the coarse approximate inverse of the Galerkin operator A_c = PᵀAP;
    4. prolongation P and the sum with step 1.

    M is symmetric positive definite and the same linear map at every iteration, so plain
    (non-flexible) CG applies. The fine operator stays matrix-free; CG scalars are float64, vectors
    ``vector_dtype``. One iteration = three row-parallel numba regions plus the serial coarse part:

    a. :func:`~method.propagation.normal_operator.direction_and_apply`: p ← z + β·p, q = A p, p·q per row;
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
    scale = float(coarse_scale)

    vdt = np.dtype(vector_dtype)

    def padded(a):
        out = np.zeros(shape, vdt)
        out[inner] = a
        return out

    apply_normal, direction_and_apply = operator_kernels(offs)
    diag = np.zeros(shape)
    normal_diagonal(weights, offs, a_diag, r, diag)
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


