"""Galerkin coarse operator Pᵀ A P of the full-resolution Eq. (4) system (a preconditioner's coarse level).

The two-level refinement of :func:`method.propagation.defocus.propagate_defocus` corrects the smooth part of
the CG residual on an s-times coarser grid with the *Galerkin* operator ``A_c = Pᵀ A P`` of the bilinear
interpolation P (separable, :func:`method.propagation.matrix_free.bilinear_1d`): the projection of the
fine operator itself. The two-grid theory (e.g. Trottenberg, Oosterlee & Schüller, *Multigrid*, 2001,
Sec. 3.2) makes the coarse correction A-orthogonal to the coarse space, so the convergence does not
depend on how well a coarse guide describes the fine edges; a *re-discretised* coarse problem (Eq. 4
rebuilt from the block-averaged guide) is cheap, but across colour edges a different operator from the
fine one, so its correction is wrong exactly where the map has to change. Measured on the astronaut photo at 1024², paper
preset's measures, from the same start map (RMS px from the exact solve): re-discretised coarse at
s = 4: 0.047 after 20 iterations, 0.014 after 30; Galerkin at s = 8: 0.021 after 20, 0.008 after 30.

A = LᵀL + diag(a) is never assembled: :func:`galerkin_coarse_operator` forms, for every fine pixel
p, the row (L P)[p, :] (at most 3×3 coarse entries for the 3×3 neighbourhood) and adds its outer
product and a_p·P[p, :]ᵀP[p, :] into a (2R+1)² coarse stencil, since

    Pᵀ A P = (L P)ᵀ (L P) + Pᵀ diag(a) P = Σ_p (L P)[p]ᵀ (L P)[p] + a_p P[p]ᵀ P[p].
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp

from .matrix_free import bilinear_1d

__all__ = ["galerkin_coarse_operator", "prolong", "restrict"]


def _coarse_span(ptr, idx, n, r):
    """Per fine index i: lowest coarse index P₁ touches in rows [i−r, i+r] ∩ [0, n); and the widest span."""
    lo_row = idx[ptr[:-1]]      # CSR rows have sorted indices: first = lowest, last = highest
    hi_row = idx[ptr[1:] - 1]
    pad_lo = np.pad(lo_row, r, mode="edge")
    pad_hi = np.pad(hi_row, r, mode="edge")
    win_lo = np.min(np.lib.stride_tricks.sliding_window_view(pad_lo, 2 * r + 1), axis=1)
    win_hi = np.max(np.lib.stride_tricks.sliding_window_view(pad_hi, 2 * r + 1), axis=1)
    return win_lo, int(np.max(win_hi - win_lo)) + 1


def _window_tables(ptr, idx, val, lo, n, r, m):
    """T[i, d + r, k] = P₁[i + d, lo[i] + k]: the interpolation rows of the neighbours i + d of fine
    index i (|d| ≤ r) on i's m-wide coarse window; 0 for neighbours outside [0, n)."""
    table = np.zeros((n, 2 * r + 1, m))
    rows = np.repeat(np.arange(n), np.diff(ptr))          # fine index of every CSR entry
    for d in range(-r, r + 1):
        i = rows - d                                       # entry of row q = i + d, seen from i
        ok = (i >= 0) & (i < n)
        np.add.at(table, (i[ok], d + r, idx[ok] - lo[i[ok]]), val[ok])
    return table


@numba.njit(cache=True, inline="always")
def _flush(gram, stencil, y0, x0, m, big):
    """Add the local Gram matrix of the m×m window at coarse (y0, x0) into the stencil; zero it."""
    mm = m * m
    for a in range(mm):
        ia = a // m
        ja = a - ia * m
        for b in range(mm):
            g = gram[a, b] if a <= b else gram[b, a]
            if g != 0.0:
                ib = b // m
                stencil[y0 + ia, x0 + ja, ib - ia + big, b - ib * m - ja + big] += g
    for a in range(mm):
        for b in range(mm):
            gram[a, b] = 0.0


@numba.njit(cache=True, inline="always")
def _add_outer(gram, v, u, d, mm):
    """gram[i, j] += v_i v_j + d·u_i u_j for i ≤ j (upper triangle): one fine pixel's Gram terms.

    Rows with v_i = d·u_i = 0 are skipped: they would add exact zeros.
    """
    for i in range(mm):
        vi = v[i]
        ui = d * u[i]
        if vi == 0.0 and ui == 0.0:
            continue
        for j in range(i, mm):
            gram[i, j] += vi * v[j] + ui * u[j]


@numba.njit(cache=True, parallel=True)
def _galerkin_stencil(weights, offs, a_diag, r, py_ptr, py_idx, py_val, px_ptr, px_idx, px_val,
                      ylo, xlo, m, block_rows, stride, stencil):
    """Accumulate Σ_p (LP)[p]ᵀ(LP)[p] + a_p P[p]ᵀP[p] into ``stencil`` (H_c, W_c, 2R+1, 2R+1).

    Fine rows are grouped by coarse block row (``block_rows[i]`` = first fine row of block i, plus
    the end); blocks i ≡ c (mod ``stride``) run in parallel in pass c, and ``stride`` is chosen so
    that no two blocks of a pass write the same stencil rows. Within a block, one thread walks its
    fine pixels in raster order and sums each run of pixels that share a coarse window into a local
    Gram matrix (upper triangle) before adding it to the stencil: the sums, and the bytes, do not
    depend on the machine's thread count. ``ylo``/``xlo``: first coarse index of each fine row's /
    column's m×m window (see :func:`_coarse_span`); R = m − 1.
    """
    h, w = a_diag.shape
    k = offs.shape[0]
    big = m - 1
    mm = m * m
    nblocks = block_rows.shape[0] - 1
    for colour in range(stride):
        for bi in numba.prange((nblocks - colour + stride - 1) // stride):
            blk = colour + bi * stride
            v = np.zeros(mm)
            u = np.zeros(mm)
            gram = np.zeros((mm, mm))
            for y in range(block_rows[blk], block_rows[blk + 1]):
                y0 = ylo[y]
                cur = -1
                for x in range(w):
                    x0 = xlo[x]
                    if x0 != cur:
                        if cur >= 0:
                            _flush(gram, stencil, y0, cur, m, big)
                        cur = x0
                    for i in range(mm):
                        v[i] = 0.0
                        u[i] = 0.0
                    # P[p, :] (the centre's coefficient 1 in L; also the data term's u = P[p, :])
                    for a in range(py_ptr[y], py_ptr[y + 1]):
                        for b in range(px_ptr[x], px_ptr[x + 1]):
                            idx = (py_idx[a] - y0) * m + px_idx[b] - x0
                            pv = py_val[a] * px_val[b]
                            v[idx] += pv
                            u[idx] += pv
                    # − Σ_o w_o(p) P[p + o, :]
                    for kk in range(k):
                        qy = y + offs[kk, 0]
                        qx = x + offs[kk, 1]
                        if qy < 0 or qy >= h or qx < 0 or qx >= w:
                            continue
                        wt = np.float64(weights[kk, y + r, x + r])
                        if wt == 0.0:
                            continue
                        for a in range(py_ptr[qy], py_ptr[qy + 1]):
                            for b in range(px_ptr[qx], px_ptr[qx + 1]):
                                v[(py_idx[a] - y0) * m + px_idx[b] - x0] -= wt * py_val[a] * px_val[b]
                    _add_outer(gram, v, u, a_diag[y, x], mm)
                _flush(gram, stencil, y0, cur, m, big)


#: Sizes of the specialised kernel :func:`_galerkin_stencil_3x3` (3×3 neighbourhood, r = 1: each
#: fine pixel's row of L P spans a 3×3 window of coarse cells for every s ≥ 2). Module constants,
#: so numba unrolls the small loops: 0.09 s instead of 0.33 s CPU at 1 MP, identical sums.
_M3 = 3
_MM3 = 9


@numba.njit(cache=True, parallel=True)
def _galerkin_stencil_3x3(weights, offs, a_diag, ytab, xtab, ylo, xlo, block_rows, stride, stencil):
    """:func:`_galerkin_stencil` for the 3×3 neighbourhood, from separable interpolation tables.

    With c(p) the 3×3 stencil of row p of L (1 at the centre, −w_o(p) at offset o) and
    ``ytab``/``xtab`` from :func:`_window_tables`, the local row is
    v = Σ_dy ytab[y, dy] ⊗ (Σ_dx c[dy, dx]·xtab[x, dx]) and u = P[p, :] = ytab[y, 1] ⊗ xtab[x, 1]:
    dense products of fixed size (no scatter). Same blocks, colours, raster order and local Gram
    matrices as the generic kernel, so the same determinism; its operator equals the generic
    kernel's to round-off (the products are summed in another order; identical bytes on the
    astronaut photo at 1 MP).
    """
    w = a_diag.shape[1]
    m = _M3
    mm = _MM3
    big = m - 1
    nblocks = block_rows.shape[0] - 1
    for colour in range(stride):
        for bi in numba.prange((nblocks - colour + stride - 1) // stride):
            blk = colour + bi * stride
            v = np.zeros(mm)
            u = np.zeros(mm)
            t = np.zeros(m)
            c = np.zeros((m, m))
            gram = np.zeros((mm, mm))
            for y in range(block_rows[blk], block_rows[blk + 1]):
                y0 = ylo[y]
                cur = -1
                for x in range(w):
                    x0 = xlo[x]
                    if x0 != cur:
                        if cur >= 0:
                            _flush(gram, stencil, y0, cur, m, big)
                        cur = x0
                    c[1, 1] = 1.0
                    for kk in range(8):
                        c[offs[kk, 0] + 1, offs[kk, 1] + 1] = -np.float64(weights[kk, y + 1, x + 1])
                    for i in range(mm):
                        v[i] = 0.0
                    for dy in range(m):
                        for j in range(m):
                            t[j] = c[dy, 0] * xtab[x, 0, j] + c[dy, 1] * xtab[x, 1, j] + c[dy, 2] * xtab[x, 2, j]
                        for i in range(m):
                            yv = ytab[y, dy, i]
                            for j in range(m):
                                v[i * m + j] += yv * t[j]
                    d = a_diag[y, x]
                    for i in range(m):
                        for j in range(m):
                            u[i * m + j] = ytab[y, 1, i] * xtab[x, 1, j]
                    _add_outer(gram, v, u, d, mm)
                _flush(gram, stencil, y0, cur, m, big)


def galerkin_coarse_operator(weights, offs, a_diag, *, s, coarse_shape) -> sp.csr_matrix:
    """The Galerkin coarse operator Pᵀ (LᵀL + diag a) P of the matrix-free Eq. (4) system.

    Parameters
    ----------
    weights : ndarray, (K, H+2r, W+2r), float32 or float64
        Affinities w_pq of Eq. (4c) on the zero-padded grid
        (:func:`method.propagation.system.padded_weights`); L = I − W.
    offs : ndarray, (K, 2), int64
        Neighbour offsets (dy, dx) of the K weights.
    a_diag : ndarray, (H, W), float64
        Diagonal data term α_p + λ (≥ 0).
    s : int, keyword-only
        Coarsening factor of the block-centred coarse grid (≥ 2).
    coarse_shape : tuple of int, keyword-only
        (H_c, W_c) = (⌈H/s⌉, ⌈W/s⌉).

    Returns
    -------
    scipy.sparse.csr_matrix, (H_c·W_c, H_c·W_c), float64
        Pᵀ A P with P = P_y ⊗ P_x the bilinear interpolation of
        :func:`method.propagation.matrix_free.bilinear_1d` (row-major coarse index cy·W_c + cx);
        symmetric positive (semi-)definite, sorted indices, explicit zeros removed.

    Notes
    -----
    1. For every fine pixel p, the local row v = (L P)[p, :] = P[p, :] − Σ_o w_o(p) P[p + o, :]
       on an m×m window of coarse cells (m = 3 for the 3×3 neighbourhood and s ≥ 2) and u = P[p, :].
    2. Add v ⊗ v + a_p·u ⊗ u into the coarse stencil (offsets up to R = m − 1 each way).
    3. Scatter the stencil into CSR. O(H·W·m⁴) work; blocks of s fine rows in parallel, coloured so
       that no two write the same coarse rows, with a fixed summation order (deterministic).
    """
    weights = np.asarray(weights)
    offs = np.ascontiguousarray(offs, dtype=np.int64)
    a_diag = np.ascontiguousarray(a_diag, dtype=np.float64)
    h, w = a_diag.shape
    hc, wc = (int(v) for v in coarse_shape)
    r = int(np.max(np.abs(offs)))
    if weights.shape != (offs.shape[0], h + 2 * r, w + 2 * r):
        raise ValueError(f"weights has shape {weights.shape}, expected {(offs.shape[0], h + 2 * r, w + 2 * r)}")
    if (hc, wc) != (-(-h // s), -(-w // s)):
        raise ValueError(f"coarse_shape {coarse_shape} does not match {(h, w)} at s={s}")
    (py_ptr, py_idx, py_val), _ = bilinear_1d(h, hc, s)
    (px_ptr, px_idx, px_val), _ = bilinear_1d(w, wc, s)
    ylo, my = _coarse_span(py_ptr, py_idx, h, r)
    xlo, mx = _coarse_span(px_ptr, px_idx, w, r)
    m = max(my, mx)
    big = m - 1
    stencil = np.zeros((hc, wc, 2 * big + 1, 2 * big + 1))
    # blocks of fine rows per coarse row; the stencil rows block i writes: [min ylo, max ylo + m − 1]
    block_rows = np.minimum(np.arange(hc + 1, dtype=np.int64) * s, h)
    lo = np.array([ylo[block_rows[i]:block_rows[i + 1]].min() for i in range(hc)])
    hi = np.array([ylo[block_rows[i]:block_rows[i + 1]].max() for i in range(hc)]) + m - 1
    stride = 1
    while stride < hc and np.any(hi[:-stride] >= lo[stride:]):
        stride += 1
    if r == 1 and m == _M3 and offs.shape[0] == 8:
        ytab = _window_tables(py_ptr, py_idx, py_val, ylo, h, r, m)
        xtab = _window_tables(px_ptr, px_idx, px_val, xlo, w, r, m)
        _galerkin_stencil_3x3(weights, offs, a_diag, ytab, xtab, ylo, xlo, block_rows, stride, stencil)
    else:
        _galerkin_stencil(weights, offs, a_diag, r, py_ptr, py_idx, py_val, px_ptr, px_idx, px_val,
                          ylo, xlo, m, block_rows, stride, stencil)
    # stencil → CSR: entry (cy, cx, dy + R, dx + R) is A_c[(cy, cx), (cy + dy, cx + dx)]
    cy, cx, dy, dx = np.meshgrid(np.arange(hc), np.arange(wc), np.arange(-big, big + 1),
                                 np.arange(-big, big + 1), indexing="ij")
    ty, tx = cy + dy, cx + dx
    keep = (stencil != 0.0) & (ty >= 0) & (ty < hc) & (tx >= 0) & (tx < wc)
    rows = (cy * wc + cx)[keep]
    cols = (ty * wc + tx)[keep]
    A_c = sp.csr_matrix((stencil[keep], (rows, cols)), shape=(hc * wc, hc * wc))
    A_c.sum_duplicates()
    A_c.sort_indices()
    return A_c


def _p1(n, n_c, s):
    (ptr, idx, val), _ = bilinear_1d(n, n_c, s)
    return sp.csr_matrix((val, idx, ptr), shape=(n, n_c))


def prolong(coarse, *, s, shape) -> np.ndarray:
    """P e: bilinear interpolation of a block-centred (H_c, W_c) map onto the (H, W) fine grid.

    The P of :func:`galerkin_coarse_operator` (P_y e P_xᵀ, :func:`method.propagation.matrix_free.bilinear_1d`).
    """
    h, w = shape
    hc, wc = coarse.shape
    return np.asarray(_p1(h, hc, s) @ (_p1(w, wc, s) @ np.asarray(coarse, dtype=np.float64).T).T)


def restrict(fine, *, s, coarse_shape) -> np.ndarray:
    """Pᵀ r: the transpose of :func:`prolong`, (H, W) → (H_c, W_c)."""
    h, w = fine.shape
    hc, wc = coarse_shape
    return np.asarray(_p1(h, hc, s).T @ (_p1(w, wc, s).T @ np.asarray(fine, dtype=np.float64).T).T)
