"""The full-resolution propagation operator (LᵀL + diag a) of Eq. (4), applied matrix-free (numba kernels).

The normal-equations operator of :mod:`method.propagation.system` applied from the affinities
(:func:`method.propagation.system.padded_weights`) without assembling it, for the CG refinements of
:mod:`method.propagation.matrix_free`: :func:`apply_normal` (q = A p), :func:`direction_and_apply`
(p ← z + β·p fused with q = A p), unrolled 3×3-neighbourhood variants chosen by
:func:`operator_kernels`, and the diagonal :func:`normal_diagonal` (Jacobi).

Vectors live on a grid zero-padded by the neighbourhood radius r so the stencils need no bounds
checks; every kernel is row-parallel without shared writes and adds per-row partial sums in row
order, so the results are bit-identical for any number of threads.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["DOT_ROWS", "apply_normal", "direction_and_apply", "normal_diagonal", "operator_kernels", "row_dots"]


#: Rows per block of the fused matrix-free operator (each block recomputes a halo of r rows of L·p).
_ROW_BLOCK = 32


@numba.njit(cache=True, inline="always")
def _blocks(offs, hp, wp):
    """(r, H, W, number of row blocks) of padded (hp, wp) grids for the offsets ``offs`` (r: their radius)."""
    r = 0
    for j in range(offs.shape[0]):
        r = max(r, abs(offs[j, 0]), abs(offs[j, 1]))
    h = hp - 2 * r
    return r, h, wp - 2 * r, (h + _ROW_BLOCK - 1) // _ROW_BLOCK


@numba.njit(cache=True, inline="always")
def _l_row(weights, offs, src, sy, py, r, w, trow):
    """trow = (L p) on padded row py, p's rows read from ``src`` at row sy (the generic kernels)."""
    prow = src[sy, r:r + w]
    for i in range(w):
        trow[i] = prow[i]
    for j in range(offs.shape[0]):
        dy = offs[j, 0]
        dx = offs[j, 1]
        wrow = weights[j, py, r:r + w]
        nrow = src[sy + dy, r + dx:r + dx + w]
        for i in range(w):
            trow[i] -= wrow[i] * nrow[i]


@numba.njit(cache=True, inline="always")
def _lt_row(weights, offs, t, ty, py, r, w, prow, arow, qrow):
    """qrow = (Lᵀ t + a·p) on padded row py (gather form, t's row ty); returns Σ p·q (the generic kernels)."""
    trow = t[ty, r:r + w]
    for i in range(w):
        qrow[i] = trow[i] + arow[i] * prow[i]
    for j in range(offs.shape[0]):
        dy = offs[j, 0]
        dx = offs[j, 1]
        wrow = weights[j, py - dy, r - dx:r - dx + w]
        srow = t[ty - dy, r - dx:r - dx + w]
        for i in range(w):
            qrow[i] -= wrow[i] * srow[i]
    acc = 0.0
    for i in range(w):
        acc += prow[i] * qrow[i]
    return acc


@numba.njit(cache=True, parallel=True)
def apply_normal(p, weights, offs, a_diag, q, rowdot):
    """Matrix-free q = (LᵀL + diag a) p and the per-row dot products rowdot[y] = Σ_x p·q.

    All grids are zero-padded by r = neighbourhood radius on every side ((H+2r) x (W+2r); weights
    (K, H+2r, W+2r) are 0 at padded pixels and for out-of-image neighbours). Row blocks of
    :data:`_ROW_BLOCK` rows run in parallel; each computes t = L p for its rows plus an r-row halo into
    a private buffer, then q = t − Σ_j w[j, p − o_j]·t[p − o_j] + a ∘ p (Lᵀ as a gather). The inner
    loops run along a row with one offset at a time (SIMD-friendly). No write is shared between
    threads and every value has a fixed operation order, so q is independent of the thread count.
    """
    hp, wp = p.shape
    r, h, w, nblk = _blocks(offs, hp, wp)
    for b in numba.prange(nblk):
        y0 = b * _ROW_BLOCK
        y1 = min(h, y0 + _ROW_BLOCK)
        t = np.zeros((y1 - y0 + 2 * r, wp))  # image rows y0 − r … y1 + r − 1; 0 outside the image
        # (loops index 1-D row views from 0 so numba emits no negative-index checks and LLVM vectorises)
        for yy in range(max(0, y0 - r), min(h, y1 + r)):
            _l_row(weights, offs, p, yy + r, yy + r, r, w, t[yy - y0 + r, r:r + w])
        for y in range(y0, y1):
            py = y + r
            ty = y - y0 + r
            prow = p[py, r:r + w]
            rowdot[y] = _lt_row(weights, offs, t, ty, py, r, w, prow, a_diag[y], q[py, r:r + w])


@numba.njit(cache=True, parallel=True)
def normal_diagonal(weights, offs, a_diag, r, out):
    """diag(LᵀL + diag a)[p] = 1 + a_p + Σ_j w[j, p − o_j]² (gather, added in offset order), padded
    like the vectors. Rows in parallel; per row one pass per offset over a float64 row buffer
    (unsigned column indices, so LLVM vectorises it)."""
    k = offs.shape[0]
    h, w = a_diag.shape
    wu = np.uint64(w)
    ru = np.uint64(r)
    for y in numba.prange(h):
        py = y + r
        arow = a_diag[y]
        v = np.empty(w)
        for x in range(wu):
            v[x] = 1.0 + arow[x]
        for j in range(k):
            wrow = weights[j, py - offs[j, 0]]
            sh = np.uint64(r - offs[j, 1])
            for x in range(wu):
                wv = np.float64(wrow[x + sh])
                v[x] += wv * wv
        orow = out[py]
        for x in range(wu):
            orow[x + ru] = v[x]




@numba.njit(cache=True, parallel=True)
def direction_and_apply(z, p_old, beta, weights, offs, a_diag, p_new, q, rowdot):
    """p_new = z + β·p_old, q = (LᵀL + diag a) p_new and rowdot[y] = Σ_x p_new·q, in one parallel region.

    The same row blocks as :func:`apply_normal`; each block forms z + β·p_old for its rows plus a
    2r-row halo in a private buffer (so it never reads another block's output), computes L·p over its
    rows ± r, then q by the gather form of Lᵀ, and writes its own rows of ``p_new``. The values are
    bit-identical to p_new = z + β·p_old followed by :func:`apply_normal`. Padded grids (border r).
    """
    hp, wp = z.shape
    r, h, w, nblk = _blocks(offs, hp, wp)
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
            _l_row(weights, offs, pb, yy - y0 + 2 * r, yy + r, r, w, t[yy - y0 + r, r:r + w])
        for y in range(y0, y1):
            py = y + r
            ty = y - y0 + r
            prow = pb[y - y0 + 2 * r, r:r + w]
            outp = p_new[py, r:r + w]
            for i in range(w):
                outp[i] = prow[i]
            rowdot[y] = _lt_row(weights, offs, t, ty, py, r, w, prow, a_diag[y], q[py, r:r + w])


#: The 3×3 neighbourhood's offsets in the raster order of :func:`method.propagation.system._offsets`:
#: the order the unrolled kernels below hard-code.
_OFFSETS_3X3 = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)], dtype=np.int64)


def _is_3x3(offs) -> bool:
    return offs.shape == _OFFSETS_3X3.shape and bool(np.array_equal(offs, _OFFSETS_3X3))


@numba.njit(cache=True, inline="always")
def _l_row_3x3(weights, py, pm, pc, pp, tr, w):
    """tr[x] = (L p)[x] for one padded row py from the rows above / at / below (3×3, r = 1).

    The same products, subtracted in the same (offset) order, as the generic loops of
    :func:`apply_normal`, so the same bits; unrolled over the 8 offsets on contiguous rows.
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
def _lt_row_3x3(weights, py, pc, ar, tm, tc, tp, qr, vr, w):
    """qr[x] = vr[x] = (Lᵀ t + a ∘ p)[x] for one padded row py (gather form, 3×3).

    Offset j = (dy, dx) contributes w[j, p − o_j]·t[p − o_j], in the order of :func:`apply_normal`.
    ``vr`` (float64) keeps the unrounded values for Σ_x p·q (:func:`row_dots`); the loop carries no
    sum, so LLVM vectorises it.
    """
    g0 = weights[0, py + 1]
    g1 = weights[1, py + 1]
    g2 = weights[2, py + 1]
    g3 = weights[3, py]
    g4 = weights[4, py]
    g5 = weights[5, py - 1]
    g6 = weights[6, py - 1]
    g7 = weights[7, py - 1]
    for x in range(1, w + 1):
        v = (tc[x] + ar[x - 1] * pc[x] - g0[x + 1] * tp[x + 1] - g1[x] * tp[x] - g2[x - 1] * tp[x - 1]
             - g3[x + 1] * tc[x + 1] - g4[x - 1] * tc[x - 1] - g5[x + 1] * tm[x + 1] - g6[x] * tm[x]
             - g7[x - 1] * tm[x - 1])
        vr[x] = v
        qr[x] = v


#: Rows whose sums :func:`row_dots` accumulates side by side.
DOT_ROWS = 4


@numba.njit(cache=True, inline="always")
def _dot_row(a, b, lo, hi):
    """Σ_{x=lo}^{hi−1} a[x]·b[x] added from 0 in ascending x (``lo``, ``hi`` unsigned)."""
    acc = 0.0
    for x in range(lo, hi):
        acc += a[x] * b[x]
    return acc


@numba.njit(cache=True, inline="always")
def row_dots(a, ra, b, rb, n, lo, w, out, y0):
    """out[y0 + i] = Σ_{x=lo}^{lo+w−1} a[ra + i, x]·b[rb + i, x] for i < n, each from 0 in ascending x.

    The sums of :data:`DOT_ROWS` rows are accumulated in one loop as independent chains: each row's
    additions keep their order (the same bits as one row at a time, whatever the grouping), but the
    add latency no longer serialises the loop. ``a``/``b`` are 2-D; the products take the operands'
    types (float32·float32 is rounded to float32 before the float64 sum, as in ``acc += a[x]*b[x]``).
    """
    lo_u = np.uint64(lo)
    hi_u = np.uint64(lo + w)
    i = 0
    while i + DOT_ROWS <= n:
        a0 = a[ra + i]
        a1 = a[ra + i + 1]
        a2 = a[ra + i + 2]
        a3 = a[ra + i + 3]
        b0 = b[rb + i]
        b1 = b[rb + i + 1]
        b2 = b[rb + i + 2]
        b3 = b[rb + i + 3]
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        for x in range(lo_u, hi_u):
            s0 += a0[x] * b0[x]
            s1 += a1[x] * b1[x]
            s2 += a2[x] * b2[x]
            s3 += a3[x] * b3[x]
        out[y0 + i] = s0
        out[y0 + i + 1] = s1
        out[y0 + i + 2] = s2
        out[y0 + i + 3] = s3
        i += DOT_ROWS
    while i < n:
        out[y0 + i] = _dot_row(a[ra + i], b[rb + i], lo_u, hi_u)
        i += 1


@numba.njit(cache=True, parallel=True)
def _apply_normal_3x3(p, weights, offs, a_diag, q, rowdot):
    """:func:`apply_normal` for the 3×3 neighbourhood (offsets :data:`_OFFSETS_3X3`), bit-identical.

    The same row blocks, halo and operation order; the offsets are unrolled on contiguous rows
    (≈ 8× faster than the generic loops, whose runtime-offset slices LLVM does not vectorise).
    """
    hp, wp = p.shape
    _, h, w, nblk = _blocks(offs, hp, wp)  # r = 1
    for b in numba.prange(nblk):
        y0 = b * _ROW_BLOCK
        y1 = min(h, y0 + _ROW_BLOCK)
        t = np.zeros((y1 - y0 + 2, wp))  # image rows y0 − 1 … y1; 0 outside the image
        for yy in range(max(0, y0 - 1), min(h, y1 + 1)):
            py = yy + 1
            _l_row_3x3(weights, py, p[py - 1], p[py], p[py + 1], t[yy - y0 + 1], w)
        vb = np.empty((y1 - y0, wp))  # unrounded q rows for the dot products
        for y in range(y0, y1):
            py = y + 1
            ty = y - y0 + 1
            _lt_row_3x3(weights, py, p[py], a_diag[y], t[ty - 1], t[ty], t[ty + 1], q[py], vb[y - y0], w)
        row_dots(p, y0 + 1, vb, 0, y1 - y0, 1, w, rowdot, y0)


@numba.njit(cache=True, inline="always")
def _direction_row_3x3(weights, pb, t, a_diag, p_new, q, vb, y, y0, w):
    """Row y of :func:`_direction_and_apply_3x3`: p_new's row from the block buffer ``pb`` and q's row
    (unrounded into ``vb``) from the L·p rows ``t`` (block rows start at image row y0)."""
    py = y + 1
    ty = y - y0 + 1
    prow = pb[y - y0 + 2]
    outp = p_new[py]
    for x in range(1, w + 1):
        outp[x] = prow[x]
    _lt_row_3x3(weights, py, prow, a_diag[y], t[ty - 1], t[ty], t[ty + 1], q[py], vb[y - y0], w)


@numba.njit(cache=True, parallel=True)
def _direction_and_apply_3x3(z, p_old, beta, weights, offs, a_diag, p_new, q, rowdot):
    """:func:`direction_and_apply` for the 3×3 neighbourhood, bit-identical (see :func:`_apply_normal_3x3`)."""
    hp, wp = z.shape
    _, h, w, nblk = _blocks(offs, hp, wp)  # r = 1
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
        vb = np.empty((nb, wp))  # unrounded q rows for the dot products
        # q row y as soon as L·p rows y − 1 … y + 1 exist: the three weight rows it gathers were
        # just read for L·p and are still in cache (one pass over the affinities, not two)
        nxt = y0
        for yy in range(max(0, y0 - 1), min(h, y1 + 1)):
            by = yy - y0 + 2
            _l_row_3x3(weights, yy + 1, pb[by - 1], pb[by], pb[by + 1], t[yy - y0 + 1], w)
            while nxt < y1 and nxt < yy:
                _direction_row_3x3(weights, pb, t, a_diag, p_new, q, vb, nxt, y0, w)
                nxt += 1
        for y in range(nxt, y1):  # the image's last row (t row y1 is outside: zero)
            _direction_row_3x3(weights, pb, t, a_diag, p_new, q, vb, y, y0, w)
        row_dots(pb, 2, vb, 0, nb, 1, w, rowdot, y0)


def operator_kernels(offs):
    """(apply_normal, direction_and_apply) for these offsets: the unrolled 3×3 ones when they apply."""
    if _is_3x3(offs):
        return _apply_normal_3x3, _direction_and_apply_3x3
    return apply_normal, direction_and_apply

