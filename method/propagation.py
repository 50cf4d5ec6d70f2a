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
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy import ndimage

__all__ = [
    "PROPAGATION_SOLVERS",
    "colorization_matrix",
    "colorization_weights",
    "normal_equations",
    "propagate_defocus",
]

#: Largest number of pixels solved at full resolution by ``downsample="auto"``; bigger images are
#: solved on a grid coarsened by a power of two to at most this many pixels, then refined.
AUTO_MAX_COARSE_PIXELS = 256 * 256

#: Default number of Jacobi-preconditioned CG iterations at full resolution after a coarse solve.
DEFAULT_REFINE_ITERATIONS = 60


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
    h, w, c = ref.shape

    def box(a):  # box sum with zero padding = sum over in-image pixels only
        return ndimage.uniform_filter(a, size=window, mode="constant", cval=0.0) * (window * window)

    count = box(np.ones((h, w)))
    var = np.empty_like(ref)
    for i in range(c):
        mean = box(ref[..., i]) / count
        var[..., i] = np.maximum(box(ref[..., i] ** 2) / count - mean * mean, 0.0)
    return var


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
    2. log a_pq = logsumexp_i(−(C_i(p) − C_i(q))² / (2 σ_ip²)) (sum over channels of Eq. 4c).
    3. w_pq = softmax over q ∈ N(p) of log a_pq: exactly the normalised Eq. (4c), computed with the
       per-row maximum subtracted so rows whose raw affinities underflow still sum to 1.
    """
    ref = _as_reference(reference)
    window = _check_odd("window", window, 1)
    neighborhood = _check_odd("neighborhood", neighborhood, 3)
    eps = _check_positive("eps", eps)
    return _weights(ref, window, neighborhood, eps)


def _weights(ref, window, neighborhood, eps):
    inv2var = np.ascontiguousarray(0.5 / np.maximum(_local_variance(ref, window), eps))
    offs = _offsets(neighborhood)
    weights = np.empty((len(offs),) + ref.shape[:2])
    _weights_kernel()(np.ascontiguousarray(ref), inv2var, offs, weights)
    return weights, offs


_WEIGHTS_KERNEL = None


def _weights_kernel():
    """numba kernel: per pixel, log-affinities (logsumexp over channels), then softmax over N(p)."""
    global _WEIGHTS_KERNEL
    if _WEIGHTS_KERNEL is None:
        import numba

        @numba.njit(cache=True)
        def kernel(ref, inv2var, offs, out):
            h, w, c = ref.shape
            k = offs.shape[0]
            logw = np.empty(k)
            a = np.empty(c)
            for y in range(h):
                for x in range(w):
                    best = -np.inf
                    for j in range(k):
                        qy = y + offs[j, 0]
                        qx = x + offs[j, 1]
                        if qy < 0 or qy >= h or qx < 0 or qx >= w:
                            logw[j] = -np.inf
                            continue
                        amax = -np.inf
                        for i in range(c):
                            d = ref[y, x, i] - ref[qy, qx, i]
                            a[i] = -d * d * inv2var[y, x, i]
                            if a[i] > amax:
                                amax = a[i]
                        acc = 0.0
                        for i in range(c):
                            acc += np.exp(a[i] - amax)
                        logw[j] = amax + np.log(acc)
                        if logw[j] > best:
                            best = logw[j]
                    total = 0.0
                    for j in range(k):
                        v = np.exp(logw[j] - best)
                        out[j, y, x] = v
                        total += v
                    for j in range(k):
                        out[j, y, x] /= total

        _WEIGHTS_KERNEL = kernel
    return _WEIGHTS_KERNEL


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
def _data_term(sparse_sigma, alpha, regularization):
    """α per pixel, right-hand side and the regulariser's target (mean of the finite BM)."""
    edge = np.isfinite(sparse_sigma)
    a = np.where(edge, alpha, 0.0).ravel()
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


def _solve_amg_pcg(A, rhs, *, x0=None, tol=1e-6):
    """Smoothed-aggregation multigrid (pyamg) as preconditioner of CG, single-threaded BLAS."""
    import pyamg
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        ml = pyamg.smoothed_aggregation_solver(A, symmetry="symmetric", max_coarse=500)
        x = ml.solve(rhs, x0=x0, tol=tol, accel="cg", maxiter=500)
    return np.asarray(x, dtype=np.float64)


#: Solvers of the assembled normal equations, chosen with ``solver="..."``.
PROPAGATION_SOLVERS: dict[str, Callable] = {
    "amg_pcg": _solve_amg_pcg,
    "direct": _solve_direct,
}


# --------------------------------------------------------------------------------------------
# matrix-free full-resolution operator (numba) for the refinement after a coarse solve
# --------------------------------------------------------------------------------------------
def _numba_kernels():
    import numba

    @numba.njit(cache=True)
    def apply_normal(xp, weights, offs, a_diag, outp, tmp):
        # Padded arrays (border r = neighbourhood radius, zeros outside the image; weights are 0
        # for out-of-image neighbours): tmp = L x ; out = Lᵀ tmp + a_diag ∘ x.
        k, h, w = weights.shape
        r = (xp.shape[0] - h) // 2
        for y in range(h):
            for xx in range(w):
                s = xp[y + r, xx + r]
                for j in range(k):
                    s -= weights[j, y, xx] * xp[y + r + offs[j, 0], xx + r + offs[j, 1]]
                tmp[y, xx] = s
        outp[:] = 0.0
        for y in range(h):
            for xx in range(w):
                t = tmp[y, xx]
                outp[y + r, xx + r] += t + a_diag[y, xx] * xp[y + r, xx + r]
                for j in range(k):
                    outp[y + r + offs[j, 0], xx + r + offs[j, 1]] -= weights[j, y, xx] * t

    @numba.njit(cache=True)
    def normal_diagonal(weights, offs, a_diag, outp):
        k, h, w = weights.shape
        r = (outp.shape[0] - h) // 2
        outp[:] = 0.0
        for y in range(h):
            for xx in range(w):
                outp[y + r, xx + r] += 1.0 + a_diag[y, xx]
                for j in range(k):
                    outp[y + r + offs[j, 0], xx + r + offs[j, 1]] += weights[j, y, xx] ** 2

    return apply_normal, normal_diagonal


_KERNELS = None


def _kernels():
    global _KERNELS
    if _KERNELS is None:
        _KERNELS = _numba_kernels()
    return _KERNELS


def _jacobi_pcg_matrix_free(weights, offs, a_diag, rhs, x0, *, maxiter, tol):
    """CG on (LᵀL + diag a) x = rhs with the Jacobi preconditioner; returns (x, relative residual).

    Vectors live on a zero-padded grid (border = neighbourhood radius) so the numba stencils need no
    bounds checks; the padding stays 0 because the operator never writes non-zeros there that CG
    keeps (they are cropped after every product).
    """
    apply_normal, normal_diagonal = _kernels()
    h, w = x0.shape
    r = int(np.max(np.abs(offs)))
    inner = (slice(r, r + h), slice(r, r + w))

    def padded(a):
        out = np.zeros((h + 2 * r, w + 2 * r))
        out[inner] = a
        return out

    tmp = np.empty((h, w))
    buf = np.zeros((h + 2 * r, w + 2 * r))
    diag = np.zeros_like(buf)
    normal_diagonal(weights, offs, a_diag, diag)
    dinv = padded(1.0 / diag[inner])
    x = padded(x0)
    b = padded(rhs)
    apply_normal(x, weights, offs, a_diag, buf, tmp)
    res = b - buf
    res[:r] = 0.0
    res[-r:] = 0.0
    res[:, :r] = 0.0
    res[:, -r:] = 0.0
    bnorm = float(np.linalg.norm(rhs)) or 1.0
    z = dinv * res
    p = z.copy()
    rz = float(np.vdot(res, z))
    for _ in range(maxiter):
        if np.linalg.norm(res) <= tol * bnorm:
            break
        apply_normal(p, weights, offs, a_diag, buf, tmp)
        buf[:r] = 0.0
        buf[-r:] = 0.0
        buf[:, :r] = 0.0
        buf[:, -r:] = 0.0
        pap = float(np.vdot(p, buf))
        if not pap > 0:
            break
        step = rz / pap
        x += step * p
        res -= step * buf
        np.multiply(dinv, res, out=z)
        rz_new = float(np.vdot(res, z))
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x[inner].copy(), float(np.linalg.norm(res)) / bnorm


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


def _coarse_problem(sparse_sigma, ref, s, alpha):
    """Block-average the guide, α-weighted block mean of BM, α_c = s²·Σ_block α (see Notes)."""
    h, w = sparse_sigma.shape
    hc, wc = -(-h // s), -(-w // s)
    ph, pw = hc * s - h, wc * s - w
    refp = np.pad(ref, ((0, ph), (0, pw), (0, 0)), mode="edge")
    sig = np.pad(sparse_sigma, ((0, ph), (0, pw)), constant_values=np.nan)
    edge = np.isfinite(sig)
    ref_c = refp.reshape(hc, s, wc, s, -1).mean(axis=(1, 3))
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
                      refine_iterations=DEFAULT_REFINE_ITERATIONS,
                      max_coarse_pixels=AUTO_MAX_COARSE_PIXELS) -> np.ndarray:
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
        ``"direct"`` (sparse LU; small images).
    downsample : int or "auto", keyword-only
        1 = exact: solve the full-resolution system with ``solver`` to ``tol``. s > 1 (power of two or
        any integer): solve the problem on an s-times coarser grid with ``solver``, interpolate
        bilinearly and refine with ``refine_iterations`` Jacobi-PCG iterations of the exact
        full-resolution system (approximate; see Notes). ``"auto"`` (default): 1 when
        H·W ≤ ``max_coarse_pixels``, else the smallest power of two that brings the coarse grid under it.
    refine_iterations : int, keyword-only
        Full-resolution CG iterations after a coarse solve (≥ 0).
    max_coarse_pixels : int, keyword-only
        Pixel budget of the ``"auto"`` coarse grid.

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
    3. Exact mode (``downsample=1``): assemble and solve with ``solver`` (AMG-PCG to ``tol``).
    4. Coarse mode (s > 1): guide block-averaged over s×s blocks; BM_c = mean of the block's edge
       values; α_c = s²·Σ_block α_p — for a smooth map, (L_c B)² is s⁴ times (L B)² on s⁻² as many
       pixels, so the smoothness energy grows by s² and α is scaled alike to keep their ratio.
       Solve the coarse Eq. (4) exactly, interpolate bilinearly, then run ``refine_iterations``
       iterations of Jacobi-preconditioned CG on the exact full-resolution system (matrix-free,
       numba), which restores the colour-edge-aligned detail the coarse grid cannot represent.
       Error against the exact solution is measured in ``tests/test_propagation.py`` and the README.
    """
    sparse_sigma, ref = _validate_inputs(sparse_sigma, reference)
    window, neighborhood, eps, alpha, regularization = _validate_options(
        window, neighborhood, eps, alpha, regularization)
    if solver not in PROPAGATION_SOLVERS:
        raise ValueError(f"solver={solver!r} is unknown; allowed: {sorted(PROPAGATION_SOLVERS)}")
    tol = _check_positive("tol", tol)
    if not tol < 1:
        raise ValueError(f"tol={tol!r} is invalid; allowed: 0 < tol < 1")
    if isinstance(refine_iterations, bool) or not isinstance(refine_iterations, (int, np.integer)) or refine_iterations < 0:
        raise ValueError(f"refine_iterations={refine_iterations!r} is invalid; allowed: integer >= 0")
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

    edge = np.isfinite(sparse_sigma)
    if not edge.any():
        return np.zeros((h, w))
    fill = float(np.mean(sparse_sigma[edge]))
    if np.ptp(sparse_sigma[edge]) == 0:
        return np.full((h, w), fill)  # constant data: B = const solves Eq. (4) exactly (L·1 = 0)

    solve = PROPAGATION_SOLVERS[solver]
    if s == 1:
        L = colorization_matrix(ref, window=window, neighborhood=neighborhood, eps=eps)
        a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization)
        A = _assemble(L, a, lam)
        x0 = np.full(h * w, fill)
        return solve(A, rhs, x0=x0, tol=tol).reshape(h, w)

    # --- coarse solve + full-resolution refinement --------------------------------------------
    ref_c, bm_c, a_c = _coarse_problem(sparse_sigma, ref, s, alpha)
    hc, wc = bm_c.shape
    L_c = colorization_matrix(ref_c, window=window, neighborhood=neighborhood, eps=eps)
    lam_c = regularization * alpha * s * s
    target = float(np.sum(a_c * bm_c) / np.sum(a_c))
    A_c = _assemble(L_c, a_c.ravel(), lam_c)
    rhs_c = (a_c * bm_c).ravel() + lam_c * target
    coarse = solve(A_c, rhs_c, x0=np.full(hc * wc, target), tol=tol).reshape(hc, wc)
    del A_c, L_c
    x0 = _upsample_crop(coarse, s, (h, w))
    if refine_iterations == 0:
        return x0
    weights, offs = _weights(ref, window, neighborhood, eps)
    a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization)
    a_diag = (a + lam).reshape(h, w)
    x, _res = _jacobi_pcg_matrix_free(weights, offs, a_diag, rhs.reshape(h, w), x0,
                                      maxiter=int(refine_iterations), tol=tol)
    return x


def _upsample_crop(coarse, s, shape):
    h, w = shape
    hp, wp = coarse.shape[0] * s, coarse.shape[1] * s
    return _upsample(coarse, s, (hp, wp))[:h, :w]
