"""Propagation of the sparse blur measure to a dense defocus map, Eq. (4) (Sec. 4, after Levin et al. 2004).

Energy (Eq. 4a–4c)::

    E(B) = Σ_p (B(p) − Σ_{q∈N(p)} w_pq B(q))²  +  Σ_p α_p (B(p) − BM(p))²
    w_pq ∝ Σ_{i∈RGB} exp(−(C_i(p) − C_i(q))² / (2 σ_ip²)),   Σ_q w_pq = 1

with ``α_p = alpha`` at edge pixels (finite BM) and 0 elsewhere. Its minimiser solves the sparse
symmetric positive (semi-)definite system ``(LᵀL + diag α) B = diag(α) BM`` with ``L = I − W``.

Reading of the paper's "window size 7×7" (the README paragraph says the same)
---------------------------------------------------------------------------
The paper attaches "window" to σ_ip: "σ_p is the standard deviation of the intensities and colors of
neighboring pixels in a window around p. The window size used is 7×7." It never gives the size of
the affinity neighbourhood N(p); the method it follows (Levin et al. 2004) uses the 8 neighbours of a
3×3 window. We therefore expose two parameters:

* ``window`` (default 7): side of the square window, centred on p and clipped to the image, over
  which the per-channel standard deviation σ_ip is computed (p itself included);
* ``neighborhood`` (default 3): side of the square N(p) (p excluded, clipped to the image).

``neighborhood=7`` is the other reading ("one 7×7 window defines both"); it is supported by every
solver, but LᵀL then has a 13×13 stencil (169 non-zeros per row, ≈ 2 GB at 1 MP), so the exact
solver is only feasible on small images; the fast solver stays matrix-free at the fine level.

Solving (see :func:`propagate_defocus`, Notes)
----------------------------------------------
Images up to 256² px are solved exactly (pyamg smoothed-aggregation multigrid + CG). Larger ones are
solved on a grid coarsened 2× or 4×; its bilinearly interpolated solution starts a CG on the exact
full-resolution system, preconditioned by Jacobi plus a coarse-grid correction through the same
coarse hierarchy (two-level, matrix-free fine level), 20·s iterations. On the astronaut photo the
default is 0.012 px RMS / 0.07 px p99 (512²) and 0.014 px RMS / 0.07 px p99 (1024²) from the exact
solve (docs/performance.md, "after two-level PCG").
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy import ndimage

__all__ = [
    "PROPAGATION_REFINEMENTS",
    "PROPAGATION_SOLVERS",
    "colorization_matrix",
    "colorization_weights",
    "normal_equations",
    "propagate_defocus",
]

#: Largest number of pixels solved at full resolution by ``downsample="auto"``; bigger images are
#: solved on a grid coarsened by a power of two to at most this many pixels, then refined.
AUTO_MAX_COARSE_PIXELS = 256 * 256

#: Default number of full-resolution CG iterations after a coarse solve, per refinement (keys of
#: :data:`PROPAGATION_REFINEMENTS`), per unit of the coarsening factor s: the two-level
#: preconditioner's condition number grows like s² (the band of frequencies between the coarse grid
#: and the Jacobi smoother widens), so CG needs ∝ s iterations for the same accuracy. Two-level:
#: 20·s, i.e. 40 at 512² (s = 2) and 80 at 1024² (s = 4), which leave the astronaut photo
#: ≈ 0.012 / 0.014 px RMS and 0.07 px p99 from the exact solve (docs/performance.md). Jacobi:
#: the earlier fixed 60 iterations (0.08 / 0.15 px RMS).
DEFAULT_REFINE_ITERATIONS = {"two_level": (20, "per_factor"), "jacobi": (60, "fixed")}


def _default_refine_iterations(refinement: str, s: int) -> int:
    n, kind = DEFAULT_REFINE_ITERATIONS[refinement]
    return n * s if kind == "per_factor" else n


# --------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------
def _as_reference(reference) -> np.ndarray:
    if not isinstance(reference, np.ndarray):
        raise ValueError(f"reference must be a numpy array, got {type(reference).__name__}")
    if reference.ndim == 2:
        reference = reference[..., None]
    if reference.ndim != 3 or reference.shape[2] not in (1, 3):
        raise ValueError(f"reference must have shape HxW or HxWx3, got {reference.shape}")
    if not np.issubdtype(reference.dtype, np.floating):
        raise ValueError(f"reference must be a float array in [0, 1], got dtype {reference.dtype}")
    if min(reference.shape[:2]) < 2:
        raise ValueError(f"reference must be at least 2x2 px, got {reference.shape[:2]}")
    if not np.all(np.isfinite(reference)):
        raise ValueError("reference contains NaN or Inf values")
    return reference.astype(np.float64, copy=False)


def _check_odd(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum or value % 2 == 0:
        raise ValueError(f"{name}={value!r} is invalid; allowed: odd integer >= {minimum}")
    return int(value)


def _check_positive(name, value, *, allow_zero=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={value!r} is invalid; allowed: a finite number > 0") from None
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name}={value!r} is invalid; allowed: finite and {'>=' if allow_zero else '>'} 0")
    return v


# --------------------------------------------------------------------------------------------
# affinities, Eq. (4c)
# --------------------------------------------------------------------------------------------
def _offsets(neighborhood: int) -> np.ndarray:
    r = neighborhood // 2
    offs = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1) if (dy, dx) != (0, 0)]
    return np.asarray(offs, dtype=np.int64)


def _local_variance(ref: np.ndarray, window: int) -> np.ndarray:
    """Per-channel variance over a window×window box clipped to the image (p included), HxWxC."""
    out = np.empty(ref.shape)
    _box_variance_kernel(np.ascontiguousarray(ref), window // 2, out)
    return out


@numba.njit(cache=True, parallel=True)
def _box_variance_kernel(ref, r, out):
    """Separable box sums of C and C² over the clipped (2r+1)² window → variance (rows in parallel).

    Every output pixel is computed by one thread from the same operations in the same order, so the
    result does not depend on the number of threads.
    """
    h, w, c = ref.shape
    vs = np.empty((h, w, c))
    vs2 = np.empty((h, w, c))
    for y in numba.prange(h):
        y0 = max(0, y - r)
        y1 = min(h - 1, y + r)
        for x in range(w):
            for ch in range(c):
                s = 0.0
                s2 = 0.0
                for yy in range(y0, y1 + 1):
                    v = ref[yy, x, ch]
                    s += v
                    s2 += v * v
                vs[y, x, ch] = s
                vs2[y, x, ch] = s2
    for y in numba.prange(h):
        ny = min(h - 1, y + r) - max(0, y - r) + 1
        for x in range(w):
            x0 = max(0, x - r)
            x1 = min(w - 1, x + r)
            cnt = float(ny * (x1 - x0 + 1))
            for ch in range(c):
                s = 0.0
                s2 = 0.0
                for xx in range(x0, x1 + 1):
                    s += vs[y, xx, ch]
                    s2 += vs2[y, xx, ch]
                mean = s / cnt
                out[y, x, ch] = max(s2 / cnt - mean * mean, 0.0)


def colorization_weights(reference, *, window=7, neighborhood=3, eps=1e-6):
    """Normalised affinities w_pq of Eq. (4c) for every pixel p and offset q − p.

    Parameters
    ----------
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image C (the RGB input photo).
    window : int, keyword-only
        Odd side, px, of the window over which σ_ip (per-channel std) is computed.
    neighborhood : int, keyword-only
        Odd side, px, of the square neighbourhood N(p) (p excluded).
    eps : float, keyword-only
        Floor on σ_ip², image units², so flat windows do not divide by zero.

    Returns
    -------
    weights : ndarray, K x H x W, float64
        ``weights[k, y, x]`` = w_pq for p = (y, x), q = p + offsets[k]; 0 where q is outside the
        image. Each pixel's weights sum to 1.
    offsets : ndarray, K x 2, int64
        (dy, dx) of each neighbour, raster order.

    Notes
    -----
    1. σ_ip² = max(var of channel i over the clipped window around p, eps).
    2. e_qi = −(C_i(p) − C_i(q))² / (2 σ_ip²) for q ∈ N(p) and each channel i; M = max of all e_qi.
    3. w_pq = Σ_i exp(e_qi − M) / Σ_q' Σ_i exp(e_q'i − M): exactly the normalised Eq. (4c), computed
       with the per-pixel maximum subtracted so rows whose raw affinities underflow still sum to 1.
    """
    ref = _as_reference(reference)
    window = _check_odd("window", window, 1)
    neighborhood = _check_odd("neighborhood", neighborhood, 3)
    eps = _check_positive("eps", eps)
    return _weights(ref, window, neighborhood, eps)


def _weights(ref, window, neighborhood, eps, *, out=None):
    """Affinities (K, H, W) into ``out`` (any float dtype / strided view; float64 when None)."""
    inv2var = np.ascontiguousarray(0.5 / np.maximum(_local_variance(ref, window), eps))
    offs = _offsets(neighborhood)
    weights = np.empty((len(offs),) + ref.shape[:2]) if out is None else out
    _weights_kernel(np.ascontiguousarray(ref), inv2var, offs, weights)
    return weights, offs


@numba.njit(cache=True, parallel=True)
def _weights_kernel(ref, inv2var, offs, out):
    """Normalised Eq. (4c) affinities per pixel (rows in parallel, each pixel by one thread).

    With e_qi = −(C_i(p) − C_i(q))²/(2σ_ip²) and M = max over q ∈ N(p) and i of e_qi,
    w_pq = Σ_i exp(e_qi − M) / Σ_q' Σ_i exp(e_q'i − M): exactly the normalised Eq. (4c), and the
    largest term is exp(0) = 1, so rows whose raw affinities underflow still sum to 1. Computed in
    float64, stored in ``out``'s dtype (any float, may be a strided view).
    """
    h, w, c = ref.shape
    k = offs.shape[0]
    for y in numba.prange(h):
        e = np.empty((k, c))
        raw = np.empty(k)
        for x in range(w):
            m = -np.inf
            for j in range(k):
                qy = y + offs[j, 0]
                qx = x + offs[j, 1]
                if qy < 0 or qy >= h or qx < 0 or qx >= w:
                    for i in range(c):
                        e[j, i] = -np.inf
                    continue
                for i in range(c):
                    d = ref[y, x, i] - ref[qy, qx, i]
                    v = -d * d * inv2var[y, x, i]
                    e[j, i] = v
                    if v > m:
                        m = v
            total = 0.0
            for j in range(k):
                acc = 0.0
                if e[j, 0] > -np.inf:
                    for i in range(c):
                        acc += np.exp(e[j, i] - m)
                raw[j] = acc
                total += acc
            for j in range(k):
                out[j, y, x] = raw[j] / total


def _csr_from_weights(weights, offs, shape) -> sp.csr_matrix:
    """L = I − W as canonical CSR (columns sorted per row), built without a COO sort."""
    h, w = shape
    n = h * w
    k = len(offs)
    centre = int(np.searchsorted(offs[:, 0] * (w + 1) + offs[:, 1], 0))  # where (0, 0) slots in
    shifts = offs[:, 0] * w + offs[:, 1]
    idx = np.arange(n, dtype=np.int64)
    vals = np.empty((n, k + 1))
    cols = np.empty((n, k + 1), dtype=np.int64)
    valid = np.empty((n, k + 1), dtype=bool)
    yy, xx = np.divmod(idx, w)
    for j in range(k + 1):
        if j == centre:
            vals[:, j] = 1.0
            cols[:, j] = idx
            valid[:, j] = True
            continue
        kk = j if j < centre else j - 1
        dy, dx = offs[kk]
        vals[:, j] = -weights[kk].ravel()
        cols[:, j] = idx + shifts[kk]
        valid[:, j] = (yy + dy >= 0) & (yy + dy < h) & (xx + dx >= 0) & (xx + dx < w)
    counts = valid.sum(axis=1)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    index_dtype = np.int32 if indptr[-1] < 2**31 else np.int64
    return sp.csr_matrix((vals[valid], cols[valid].astype(index_dtype), indptr.astype(index_dtype)), shape=(n, n))


def colorization_matrix(reference, *, window=7, neighborhood=3, eps=1e-6) -> sp.csr_matrix:
    """The matrix L = I − W of Eq. (4a), pixels in raster (row-major) order.

    Parameters
    ----------
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image C.
    window : int, keyword-only
        Odd side, px, of the σ_ip window (paper: 7).
    neighborhood : int, keyword-only
        Odd side, px, of N(p) (default 3, Levin et al.; 7 for the "one 7×7 window" reading).
    eps : float, keyword-only
        Floor on σ_ip², image units².

    Returns
    -------
    scipy.sparse.csr_matrix, (H·W) x (H·W), float64
        Unit diagonal, −w_pq off the diagonal; every row sums to 0 (W rows sum to 1).

    Notes
    -----
    1. Affinities by :func:`colorization_weights` (Eq. 4c).
    2. Rows assembled directly in CSR order (no Python loop over pixels, no COO sort).
    """
    ref = _as_reference(reference)
    window = _check_odd("window", window, 1)
    neighborhood = _check_odd("neighborhood", neighborhood, 3)
    eps = _check_positive("eps", eps)
    weights, offs = _weights(ref, window, neighborhood, eps)
    return _csr_from_weights(weights, offs, ref.shape[:2])


# --------------------------------------------------------------------------------------------
# system assembly
# --------------------------------------------------------------------------------------------
def _data_term(sparse_sigma, alpha, regularization, confidence=None):
    """α per pixel (× confidence where given), right-hand side and the regulariser's target (mean BM)."""
    edge = np.isfinite(sparse_sigma)
    a = (np.where(edge, alpha, 0.0) if confidence is None else np.where(edge, alpha * confidence, 0.0)).ravel()
    bm = np.where(edge, sparse_sigma, 0.0).ravel()
    target = float(np.mean(sparse_sigma[edge])) if edge.any() else 0.0
    lam = regularization * alpha
    rhs = a * bm + lam * target
    return a, rhs, lam, target


def normal_equations(sparse_sigma, reference, *, alpha=0.5, window=7, neighborhood=3, eps=1e-6,
                     regularization=1e-6):
    """The assembled system ``A B = rhs`` of Eq. (4): A = LᵀL + diag(α) + λI, rhs = α·BM + λ·mean(BM).

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels; NaN elsewhere.
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
    alpha, window, neighborhood, eps, regularization : see :func:`propagate_defocus`.

    Returns
    -------
    A : scipy.sparse.csr_matrix, (H·W) x (H·W)
    rhs : ndarray, H·W
    """
    sparse_sigma, ref = _validate_inputs(sparse_sigma, reference)
    window, neighborhood, eps, alpha, regularization = _validate_options(
        window, neighborhood, eps, alpha, regularization)
    L = colorization_matrix(ref, window=window, neighborhood=neighborhood, eps=eps)
    a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization)
    return _assemble(L, a, lam), rhs


def _assemble(L, a, lam):
    A = (L.T @ L).tocsr()
    A = A + sp.diags(a + lam, format="csr")
    A.sort_indices()
    return A


# --------------------------------------------------------------------------------------------
# solvers on the full-resolution assembled system
# --------------------------------------------------------------------------------------------
def _solve_direct(A, rhs, *, x0=None, tol=1e-6):
    """Sparse LU (SuperLU); small images and tests only."""
    if A.shape[0] > 200_000:
        raise ValueError(f"solver='direct' is for small images (<= 200000 px), got {A.shape[0]} px")
    return spla.spsolve(A.tocsc(), rhs)


#: Prolongation smoother of the AMG hierarchy. pyamg's default Jacobi smoother scales by a spectral
#: radius estimated from a random start vector drawn from NumPy's *global* RNG (so results differed
#: ~1e-7 px run to run); ``weighting="local"`` uses each row's Gershgorin bound instead, which is
#: deterministic, touches no RNG and never under-damps.
AMG_PROLONGATION_SMOOTHER = ("jacobi", {"omega": 4.0 / 3.0, "weighting": "local"})


def _amg_hierarchy(A):
    """pyamg smoothed-aggregation hierarchy of ``A`` (deterministic setup, single-threaded BLAS)."""
    import pyamg
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return pyamg.smoothed_aggregation_solver(A, symmetry="symmetric", max_coarse=500,
                                                 smooth=AMG_PROLONGATION_SMOOTHER)


def _amg_solve(ml, rhs, x0, tol):
    """CG preconditioned by V-cycles of the hierarchy ``ml`` to relative residual ``tol``."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        x = ml.solve(rhs, x0=x0, tol=tol, accel="cg", maxiter=500)
    return np.asarray(x, dtype=np.float64)


def _solve_amg_pcg(A, rhs, *, x0=None, tol=1e-6):
    """Smoothed-aggregation multigrid (pyamg) as preconditioner of CG, single-threaded BLAS.

    Deterministic: no random numbers (see :data:`AMG_PROLONGATION_SMOOTHER`) and BLAS limited to one
    thread, so the result is bit-identical across runs, processes and core counts.
    """
    return _amg_solve(_amg_hierarchy(A), rhs, x0, tol)


#: Solvers of the assembled normal equations, chosen with ``solver="..."``.
PROPAGATION_SOLVERS: dict[str, Callable] = {
    "amg_pcg": _solve_amg_pcg,
    "direct": _solve_direct,
}


class _CoarseLevel:
    """The coarse Eq. (4) system of the two-level scheme: its solve and an approximate inverse.

    Attributes
    ----------
    solve : callable (rhs (n_c,), x0 (n_c,), tol) -> (n_c,)
        Solution of the coarse system to relative residual ``tol``.
    apply_inverse : callable (r (n_c,)) -> (n_c,)
        Symmetric positive definite approximation of A_c⁻¹ r, the same linear map at every call
        (one multigrid V-cycle from zero, or the exact LU solve).
    """

    def __init__(self, solve, apply_inverse):
        self.solve = solve
        self.apply_inverse = apply_inverse


def _amg_vcycle(ml, b):
    """One V-cycle of the hierarchy ``ml`` from a zero start: x ≈ A⁻¹ b (symmetric, linear in b).

    Pre-smoother, restriction of the residual, recursion, prolongation, post-smoother on every level,
    ``ml.coarse_solver`` on the last; with pyamg's default symmetric Gauss–Seidel smoothers this is an
    SPD preconditioner. (``ml.solve(..., maxiter=1)`` would also compute two residual norms per call.)
    """
    levels = ml.levels
    x = np.zeros_like(b)

    def cycle(lvl, x, b):
        lev = levels[lvl]
        if lvl == len(levels) - 1:
            x[:] = ml.coarse_solver(lev.A, b)
            return
        lev.presmoother(lev.A, x, b)
        bc = lev.R @ (b - lev.A @ x)
        xc = np.zeros_like(bc)
        cycle(lvl + 1, xc, bc)
        x += lev.P @ xc
        lev.postsmoother(lev.A, x, b)

    cycle(0, x, b)
    return x


def _coarse_amg(A_c):
    ml = _amg_hierarchy(A_c)
    return _CoarseLevel(lambda rhs, x0, tol: _amg_solve(ml, rhs, x0, tol),
                        lambda r: _amg_vcycle(ml, r))


def _coarse_direct(A_c):
    lu = spla.splu(A_c.tocsc())
    return _CoarseLevel(lambda rhs, x0, tol: lu.solve(rhs), lu.solve)


#: Set-up of the coarse level of ``downsample`` > 1, per ``solver`` name (same keys as
#: :data:`PROPAGATION_SOLVERS`): the hierarchy / factorisation is built once and serves both the
#: coarse solve and the coarse-grid correction of the two-level preconditioner.
_COARSE_SETUPS: dict[str, Callable] = {
    "amg_pcg": _coarse_amg,
    "direct": _coarse_direct,
}


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


def _padded_weights(ref, window, neighborhood, eps, dtype=np.float32):
    """Affinities on a grid zero-padded by the neighbourhood radius: (K, H+2r, W+2r) of ``dtype``."""
    h, w = ref.shape[:2]
    r = neighborhood // 2
    k = neighborhood * neighborhood - 1
    out = np.zeros((k, h + 2 * r, w + 2 * r), dtype=dtype)
    _, offs = _weights(ref, window, neighborhood, eps, out=out[:, r:r + h, r:r + w])
    return out, offs


def _jacobi_pcg_matrix_free(weights, offs, a_diag, rhs, x0, *, maxiter, tol):
    """CG on (LᵀL + diag a) x = rhs with the Jacobi preconditioner; returns (x, relative residual).

    Parameters
    ----------
    weights : ndarray, (K, H+2r, W+2r), float32 or float64
        Affinities from :func:`_padded_weights` (zero padding).
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

    diag = np.zeros(shape)
    _normal_diagonal(weights, offs, a_diag, r, diag)
    dinv = np.zeros(shape)
    dinv[inner] = 1.0 / diag[inner]
    x = padded(x0)
    p = np.zeros(shape)
    q = np.zeros(shape)
    rowdot = np.zeros(h)
    rowsums = np.zeros((h, 2))
    _apply_normal(x, weights, offs, a_diag, q, rowdot)  # residual of the initial guess
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
        _apply_normal(p, weights, offs, a_diag, q, rowdot)
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
def _bilinear_1d(n, n_c, s):
    """1-D bilinear interpolation from n_c block-centred coarse samples to n fine pixel centres.

    Fine pixel i sits at coarse coordinate (i + 0.5)/s − 0.5; it takes (1 − f) of the coarse sample
    below and f of the one above, indices clamped to [0, n_c − 1] (edge replication, as
    :func:`_upsample`).

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


@numba.njit(cache=True, parallel=True)
def _step_and_restrict(x, res_old, res_new, p, q, step, r, s, ty_ptr, ty_idx, ty_val,
                       tx_ptr, tx_idx, tx_val, tmp, r_c, rowsq):
    """CG update and restriction of the new residual, in one parallel region over coarse rows.

    Coarse row i owns the fine rows [i·s, (i+1)·s) ∩ [0, H): x += step·p, res_new = res_old − step·q,
    rowsq[y] = Σ_x res_new². It also forms r_c[i, :] = (Pᵀ res_new)[i, :] with P = P_y ⊗ P_x
    (bilinear, :func:`_bilinear_1d`), recomputing res_old − step·q for the fine rows it reads (the
    same operation, so the same bits as the stored res_new) instead of reading rows another thread
    writes. ``tmp`` (H_c, W) holds P_yᵀ res_new per coarse row. Fixed summation orders: the result
    does not depend on the thread count. Padded fine grids (border r); ``r_c`` is (H_c, W_c).
    """
    hc, wc = r_c.shape
    w = tmp.shape[1]
    h = x.shape[0] - 2 * r
    for i in numba.prange(hc):
        for y in range(i * s, min((i + 1) * s, h)):
            py = y + r
            xr = x[py, r:r + w]
            ro = res_old[py, r:r + w]
            rn = res_new[py, r:r + w]
            pr = p[py, r:r + w]
            qr = q[py, r:r + w]
            acc = 0.0
            for xx in range(w):
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
            ro = res_old[py, r:r + w]
            qr = q[py, r:r + w]
            for xx in range(w):
                trow[xx] += v * (ro[xx] - step * qr[xx])
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
        zr = z[py, r:r + w]
        rr_ = res[py, r:r + w]
        dr = dinv[py, r:r + w]
        for xx in range(w):
            zr[xx] = dr[xx] * rr_[xx]
        for kk in range(py_ptr[y], py_ptr[y + 1]):
            v = py_val[kk]
            erow = e_x[py_idx[kk]]
            for xx in range(w):
                zr[xx] += v * erow[xx]
        acc = 0.0
        for xx in range(w):
            acc += rr_[xx] * zr[xx]
        rowdot[y] = acc


def _two_level_pcg_matrix_free(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol):
    """CG on the full-resolution Eq. (4) system, preconditioned by Jacobi + a coarse-grid correction.

    Parameters
    ----------
    weights : ndarray, (K, H+2r, W+2r), float32 or float64
        Affinities from :func:`_padded_weights` (zero padding).
    offs : ndarray, (K, 2), int64
    a_diag : ndarray, (H, W), float64
        Diagonal data term α_p + λ.
    rhs, x0 : ndarray, (H, W), float64
        Right-hand side α·BM + λ·mean(BM) and starting map (σ, px).
    coarse : _CoarseLevel
        Coarse system A_c (the re-discretised Eq. 4 on the s-times coarser grid) with its
        approximate inverse (one AMG V-cycle, or the LU solve).
    s : int
        Coarsening factor.
    coarse_shape : tuple of int
        (H_c, W_c) = (⌈H/s⌉, ⌈W/s⌉).
    maxiter : int
    tol : float
        Stop early when ‖res‖ ≤ tol·‖rhs‖.

    Returns
    -------
    x : ndarray, (H, W), float64
    relative_residual : float

    Notes
    -----
    Preconditioner M⁻¹ r = D⁻¹ r + s²·P Ã_c⁻¹ Pᵀ r (additive two-level):

    1. D = diag(LᵀL + diag a) (Jacobi), damping the oscillatory error the coarse grid cannot see;
    2. Pᵀ r: restriction by the transpose of the bilinear interpolation P used for the start map
       (:func:`_bilinear_1d`, separable);
    3. Ã_c⁻¹: the coarse approximate inverse. The coarse system is built with α_c = s²·Σ_block α, so
       A_c ≈ s²·PᵀAP (see :func:`propagate_defocus`, Notes) and s²·P A_c⁻¹ Pᵀ ≈ P (PᵀAP)⁻¹ Pᵀ;
    4. prolongation P and the sum with step 1.

    M is symmetric positive definite and the same linear map at every iteration, so plain
    (non-flexible) CG applies. The fine operator stays matrix-free; vectors and CG scalars are
    float64. One iteration = three row-parallel numba regions plus the serial coarse part:

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
    (py_ptr, py_idx, py_val), (ty_ptr, ty_idx, ty_val) = _bilinear_1d(h, hc, s)
    (px_ptr, px_idx, px_val), (tx_ptr, tx_idx, tx_val) = _bilinear_1d(w, wc, s)
    scale = float(s * s)

    def padded(a):
        out = np.zeros(shape)
        out[inner] = a
        return out

    diag = np.zeros(shape)
    _normal_diagonal(weights, offs, a_diag, r, diag)
    dinv = np.zeros(shape)
    dinv[inner] = 1.0 / diag[inner]
    x = padded(x0)
    p, p_next = np.zeros(shape), np.zeros(shape)
    res_next = np.zeros(shape)
    q = np.zeros(shape)
    z = np.zeros(shape)
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
        _apply_normal(x, weights, offs, a_diag, q, rowdot)  # residual of the initial guess
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
            _direction_and_apply(z, p, beta, weights, offs, a_diag, p_next, q, rowdot)  # p ← z + βp; q = A p
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
    return x[inner].copy(), rnorm / bnorm



def _refine_two_level(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol):
    return _two_level_pcg_matrix_free(weights, offs, a_diag, rhs, x0, coarse=coarse, s=s,
                                      coarse_shape=coarse_shape, maxiter=maxiter, tol=tol)


def _refine_jacobi(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol):
    return _jacobi_pcg_matrix_free(weights, offs, a_diag, rhs, x0, maxiter=maxiter, tol=tol)


#: Full-resolution refinements after a coarse solve (``downsample`` > 1), chosen with
#: ``refinement="..."``: ``"two_level"`` (default) = CG preconditioned by Jacobi + the coarse-grid
#: correction (:func:`_two_level_pcg_matrix_free`); ``"jacobi"`` = the earlier, cheaper Jacobi-only
#: CG (:func:`_jacobi_pcg_matrix_free`), which leaves the coarse grid's smooth error almost intact.
PROPAGATION_REFINEMENTS: dict[str, Callable] = {
    "two_level": _refine_two_level,
    "jacobi": _refine_jacobi,
}


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------
def _validate_inputs(sparse_sigma, reference):
    ref = _as_reference(reference)
    if not isinstance(sparse_sigma, np.ndarray):
        raise ValueError(f"sparse_sigma must be a numpy array, got {type(sparse_sigma).__name__}")
    if sparse_sigma.shape != ref.shape[:2]:
        raise ValueError(f"sparse_sigma has shape {sparse_sigma.shape}, expected {ref.shape[:2]} (reference's HxW)")
    if not np.issubdtype(sparse_sigma.dtype, np.floating):
        raise ValueError(f"sparse_sigma must be float (NaN off edges), got dtype {sparse_sigma.dtype}")
    if np.any(np.isinf(sparse_sigma)):
        raise ValueError("sparse_sigma contains Inf; use NaN to mark non-edge pixels")
    finite = sparse_sigma[np.isfinite(sparse_sigma)]
    if finite.size and float(finite.min()) < 0:
        raise ValueError(f"sparse_sigma must be >= 0 (blur σ, px), got min {float(finite.min()):.6g}")
    return sparse_sigma.astype(np.float64, copy=False), ref


def _validate_options(window, neighborhood, eps, alpha, regularization):
    return (_check_odd("window", window, 1), _check_odd("neighborhood", neighborhood, 3),
            _check_positive("eps", eps), _check_positive("alpha", alpha),
            _check_positive("regularization", regularization, allow_zero=True))


def _auto_downsample(h, w, max_pixels):
    s = 1
    while (-(-h // s)) * (-(-w // s)) > max_pixels:
        s *= 2
    return s


def _coarse_problem(sparse_sigma, ref, s, alpha, confidence=None):
    """Block-average the guide, α-weighted block mean of BM, α_c = s²·Σ_block α (see Notes)."""
    h, w = sparse_sigma.shape
    hc, wc = -(-h // s), -(-w // s)
    ph, pw = hc * s - h, wc * s - w
    refp = np.pad(ref, ((0, ph), (0, pw), (0, 0)), mode="edge")
    sig = np.pad(sparse_sigma, ((0, ph), (0, pw)), constant_values=np.nan)
    edge = np.isfinite(sig)
    ref_c = refp.reshape(hc, s, wc, s, -1).mean(axis=(1, 3))
    if confidence is not None:  # α_p = α·c_p: c-weighted block mean, α_c = s²·α·Σ_block c
        conf = np.pad(np.where(np.isfinite(sparse_sigma), confidence, 0.0), ((0, ph), (0, pw)))
        cw = conf.reshape(hc, s, wc, s).sum(axis=(1, 3))
        tw = np.where(edge, sig * conf, 0.0).reshape(hc, s, wc, s).sum(axis=(1, 3))
        return ref_c, np.where(cw > 0, tw / np.where(cw > 0, cw, 1.0), 0.0), (s * s) * alpha * cw
    count = edge.reshape(hc, s, wc, s).sum(axis=(1, 3))
    total = np.where(edge, sig, 0.0).reshape(hc, s, wc, s).sum(axis=(1, 3))
    bm_c = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    a_c = (s * s) * alpha * count.astype(np.float64)
    return ref_c, bm_c, a_c


def _upsample(coarse, s, shape):
    """Bilinear interpolation of a block-centred coarse map onto the fine pixel centres."""
    h, w = shape
    ys = (np.arange(h) + 0.5) / s - 0.5
    xs = (np.arange(w) + 0.5) / s - 0.5
    return ndimage.map_coordinates(coarse, np.meshgrid(ys, xs, indexing="ij"), order=1, mode="nearest")


def propagate_defocus(sparse_sigma, reference, *, alpha=0.5, window=7, neighborhood=3, eps=1e-6,
                      regularization=1e-6, tol=1e-6, solver="amg_pcg", downsample="auto",
                      refinement="two_level", refine_iterations=None,
                      max_coarse_pixels=AUTO_MAX_COARSE_PIXELS, confidence=None) -> np.ndarray:
    """Dense defocus map B minimising Eq. (4), from sparse blur σ at edge pixels.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels (BM, e.g. after Eq. 3); NaN at every other pixel.
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image C of Eq. (4c) (the RGB input photo).
    alpha : float, keyword-only
        Data weight α_p at edge pixels (paper: 0.5; 0 elsewhere). > 0.
    window : int, keyword-only
        Odd side, px, of the σ_ip window (paper: "7×7"; see the module docstring).
    neighborhood : int, keyword-only
        Odd side, px, of N(p) (default 3 as Levin et al.; 7 = "7×7 defines both").
    eps : float, keyword-only
        Floor on σ_ip², image units².
    regularization : float, keyword-only
        λ/α of the guard term λ·Σ_p (B(p) − mean BM)² that makes the system positive definite when a
        region has no edge pixel and is cut off by strong colour edges (default 1e-6: it moves a
        well-determined map by ~1e-6 relative). 0 disables it.
    tol : float, keyword-only
        Relative residual ‖A B − rhs‖ / ‖rhs‖ at which the iterative solves stop.
    solver : str, keyword-only
        Key of :data:`PROPAGATION_SOLVERS`: ``"amg_pcg"`` (pyamg smoothed aggregation + CG) or
        ``"direct"`` (sparse LU; small images). With ``downsample`` > 1 it solves the coarse system
        and provides the coarse-grid correction of the two-level refinement (one V-cycle / LU solve).
    downsample : int or "auto", keyword-only
        1 = exact: solve the full-resolution system with ``solver`` to ``tol``. s > 1 (power of two or
        any integer): solve the problem on an s-times coarser grid with ``solver``, interpolate
        bilinearly and refine with ``refine_iterations`` iterations of preconditioned CG on the exact
        full-resolution system (approximate; see Notes). ``"auto"`` (default): 1 when
        H·W ≤ ``max_coarse_pixels``, else the smallest power of two that brings the coarse grid under it.
    refinement : str, keyword-only
        Key of :data:`PROPAGATION_REFINEMENTS` (used when s > 1): ``"two_level"`` (default; CG
        preconditioned by Jacobi + the coarse-grid correction) or ``"jacobi"`` (the earlier, cheaper
        Jacobi-only CG, ≈ 20× further from the exact solve on photos).
    refine_iterations : int or None, keyword-only
        Full-resolution CG iterations after a coarse solve (≥ 0; they stop earlier once the relative
        residual reaches ``tol``). None: :data:`DEFAULT_REFINE_ITERATIONS` of ``refinement``
        (20·s for ``"two_level"`` — 40 at s = 2, 80 at s = 4 —, 60 for ``"jacobi"``).
    max_coarse_pixels : int, keyword-only
        Pixel budget of the ``"auto"`` coarse grid.
    confidence : ndarray, HxW, float in [0, 1], or None, keyword-only
        Beyond the paper: per-edge confidence c_p, so α_p = alpha·c_p at edge pixels (None: the
        paper's α_p = alpha). Ignored off edges.

    Returns
    -------
    ndarray, HxW, float64
        Dense blur σ, px. Not clipped (the quadratic smoothness can overshoot slightly; the pipeline
        clips to [0, max_sigma]). All zeros when no pixel is finite in ``sparse_sigma``.

    Raises
    ------
    ValueError
        Shapes disagree, NaN/Inf in the reference, Inf or negative σ, bad options.

    Notes
    -----
    1. Affinities w_pq (Eq. 4c) with σ_ip from a ``window``-side box and N(p) a ``neighborhood``-side
       box (:func:`colorization_weights`); L = I − W.
    2. α_p = alpha where BM is finite; system (LᵀL + diag α + λI) B = α·BM + λ·mean(BM), λ = regularization·alpha.
    3. Exact mode (``downsample=1``; ``"auto"`` up to ``max_coarse_pixels``): assemble and solve with
       ``solver`` (AMG-PCG to ``tol``).
    4. Coarse mode (s > 1): guide block-averaged over s×s blocks; BM_c = mean of the block's edge
       values; α_c = s²·Σ_block α_p — for a smooth map, (L_c B)² is s⁴ times (L B)² on s⁻² as many
       pixels, so the smoothness energy grows by s² and α is scaled alike to keep their ratio.
       Build the coarse solver once (AMG hierarchy or LU), solve the coarse Eq. (4) to ``tol`` and
       interpolate bilinearly (P) to get the start map.
    5. Refinement (``refinement="two_level"``): ``refine_iterations`` iterations of CG on the exact
       full-resolution system (matrix-free, numba, float64 vectors and scalars, affinities stored in
       float32: the map moves by < 1e-6 px against float64), preconditioned by
       M⁻¹ = D⁻¹ + s²·P Ã_c⁻¹ Pᵀ — Jacobi for the oscillatory error plus a coarse-grid correction
       (restriction Pᵀ, one V-cycle of the coarse hierarchy, prolongation P) for the smooth error
       the Jacobi-only CG could not remove (:func:`_two_level_pcg_matrix_free`). Cost O(H·W) per
       iteration plus one V-cycle on the (fixed-size) coarse grid; 20·s iterations by default.
       Error against the exact solve on the astronaut photo (docs/performance.md):
       0.012 px RMS / 0.070 px p99 / 0.13 px max at 512² (coarse 2×, 40 iterations) and
       0.014 / 0.066 / 0.16 px at 1024² (coarse 4×, 80 iterations); the Jacobi-only refinement
       (``refinement="jacobi"``, 60 iterations) leaves 0.083 / 0.49 / 0.88 and 0.152 / 0.73 / 1.18 px.
       ``tests/test_propagation.py`` bounds the error on a 320² synthetic image.
    6. Determinism: the AMG setup draws no random numbers (:data:`AMG_PROLONGATION_SMOOTHER`) and
       runs with single-threaded BLAS; the numba kernels are row-parallel without shared writes and
       add per-row partial sums in row order; the coarse-grid correction is single-threaded. Same
       inputs give the same bytes in any process and for any thread count; NumPy's global RNG is
       neither used nor reseeded.
    """
    sparse_sigma, ref = _validate_inputs(sparse_sigma, reference)
    window, neighborhood, eps, alpha, regularization = _validate_options(
        window, neighborhood, eps, alpha, regularization)
    if solver not in PROPAGATION_SOLVERS:
        raise ValueError(f"solver={solver!r} is unknown; allowed: {sorted(PROPAGATION_SOLVERS)}")
    tol = _check_positive("tol", tol)
    if not tol < 1:
        raise ValueError(f"tol={tol!r} is invalid; allowed: 0 < tol < 1")
    if not isinstance(refinement, str) or refinement not in PROPAGATION_REFINEMENTS:
        raise ValueError(f"refinement={refinement!r} is unknown; allowed: {sorted(PROPAGATION_REFINEMENTS)}")
    if refine_iterations is not None and (
            isinstance(refine_iterations, bool) or not isinstance(refine_iterations, (int, np.integer)) or refine_iterations < 0):
        raise ValueError(f"refine_iterations={refine_iterations!r} is invalid; allowed: None or integer >= 0")
    if isinstance(max_coarse_pixels, bool) or not isinstance(max_coarse_pixels, (int, np.integer)) or max_coarse_pixels < 16:
        raise ValueError(f"max_coarse_pixels={max_coarse_pixels!r} is invalid; allowed: integer >= 16")
    h, w = sparse_sigma.shape
    if downsample == "auto":
        s = _auto_downsample(h, w, int(max_coarse_pixels))
    elif (isinstance(downsample, (int, np.integer)) and not isinstance(downsample, bool)
          and (downsample == 1 or 2 <= downsample <= min(h, w) // 2)):
        s = int(downsample)
    else:
        raise ValueError(f"downsample={downsample!r} is invalid; allowed: 'auto' or integer in [1, min(H, W)/2]")

    if refine_iterations is None:
        refine_iterations = _default_refine_iterations(refinement, s)

    if confidence is not None:
        confidence = np.asarray(confidence, dtype=np.float64)
        if confidence.shape != (h, w):
            raise ValueError(f"confidence has shape {confidence.shape}, expected {(h, w)}")
        cf = confidence[np.isfinite(sparse_sigma)]
        if not np.all(np.isfinite(cf)) or (cf.size and (cf.min() < 0 or cf.max() > 1)):
            raise ValueError("confidence must be finite and in [0, 1] at edge pixels")
    edge = np.isfinite(sparse_sigma)
    if not edge.any():
        return np.zeros((h, w))
    fill = float(np.mean(sparse_sigma[edge]))
    if np.ptp(sparse_sigma[edge]) == 0:
        return np.full((h, w), fill)  # constant data: B = const solves Eq. (4) exactly (L·1 = 0)

    solve = PROPAGATION_SOLVERS[solver]
    if s == 1:
        L = colorization_matrix(ref, window=window, neighborhood=neighborhood, eps=eps)
        a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization, confidence)
        A = _assemble(L, a, lam)
        x0 = np.full(h * w, fill)
        return solve(A, rhs, x0=x0, tol=tol).reshape(h, w)

    # --- coarse solve + full-resolution refinement --------------------------------------------
    ref_c, bm_c, a_c = _coarse_problem(sparse_sigma, ref, s, alpha, confidence)
    hc, wc = bm_c.shape
    L_c = colorization_matrix(ref_c, window=window, neighborhood=neighborhood, eps=eps)
    lam_c = regularization * alpha * s * s
    target = float(np.sum(a_c * bm_c) / np.sum(a_c))
    A_c = _assemble(L_c, a_c.ravel(), lam_c)
    del L_c
    rhs_c = (a_c * bm_c).ravel() + lam_c * target
    coarse_level = _COARSE_SETUPS[solver](A_c)
    coarse = coarse_level.solve(rhs_c, np.full(hc * wc, target), tol).reshape(hc, wc)
    x0 = _upsample_crop(coarse, s, (h, w))
    if refine_iterations == 0:
        return x0
    weights, offs = _padded_weights(ref, window, neighborhood, eps)
    a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization, confidence)
    a_diag = (a + lam).reshape(h, w)
    x, _res = PROPAGATION_REFINEMENTS[refinement](
        weights, offs, a_diag, rhs.reshape(h, w), x0, coarse=coarse_level, s=s, coarse_shape=(hc, wc),
        maxiter=int(refine_iterations), tol=tol)
    return x


def _upsample_crop(coarse, s, shape):
    h, w = shape
    hp, wp = coarse.shape[0] * s, coarse.shape[1] * s
    return _upsample(coarse, s, (hp, wp))[:h, :w]
