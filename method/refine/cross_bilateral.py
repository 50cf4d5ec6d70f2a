"""Biased cross-bilateral refinement of the sparse blur measure, Eq. (3) (Sec. 3.3).

For an edge pixel p (finite BM)::

    bCBF(BM)_p = (1/k) Σ_{q∈BM} w_pq b(BM_q) BM_q,      k = Σ_{q∈BM} w_pq b(BM_q)
    w_pq = Σ_{i∈RGB} g_σs(‖p − q‖) g_σr(|C_i(p) − C_i(q)|),   g_σ(x) = exp(−x²/(2σ²))
    b(BM) = exp(−BM / bias_scale)                          (paper: bias_scale = 2 px)

σs = ``sigma_spatial``·max(H, W) px, σr = ``sigma_range``·(max C − min C) (the range over all
channels of the reference). Because w_pq is a *sum over channels* of products, the filter splits
into one 3-D (x, y, C_i) bilateral problem per channel whose numerators and denominators add up.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from scipy import ndimage

from ..validation import validate_image, validate_sparse_sigma
from ..registry import Entry, Registry

__all__ = ["BILATERAL_METHODS", "biased_cross_bilateral", "sharpness_bias"]

#: Bilateral-grid cell size as a fraction of the corresponding σ (spatial and range axes).
GRID_CELL_PER_SIGMA = 1.0 / 3.0
#: Threads that blur / slice the grids (scipy.ndimage releases the GIL). Each grid is processed by
#: one thread with the same calls as serially, and the results are combined in a fixed order, so
#: the output does not depend on this number (tested). 2 = this project's reference machine.
GRID_THREADS = 2


def _map_in_threads(fn, items):
    """``[fn(x) for x in items]`` on :data:`GRID_THREADS` threads, results in item order."""
    items = list(items)
    if GRID_THREADS <= 1 or len(items) <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=min(GRID_THREADS, len(items))) as pool:
        return list(pool.map(fn, items))


def sharpness_bias(blur_measure, *, scale=2.0) -> np.ndarray:
    """Sharpness bias b(BM) = exp(−BM / scale) of Eq. (3).

    Parameters
    ----------
    blur_measure : array_like, any shape, float
        Blur σ, px (NaN propagates).
    scale : float, keyword-only
        Denominator, px (paper: 2). > 0.

    Returns
    -------
    ndarray, same shape, float64 in (0, 1] for BM ≥ 0.
    """
    scale = float(scale)
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"scale={scale!r} is invalid; allowed: finite and > 0 (px)")
    return np.exp(-np.asarray(blur_measure, dtype=np.float64) / scale)


# --------------------------------------------------------------------------------------------
# kernels: both take edge coordinates, guide values at the edges, values and weights (bias)
# and return the filtered value at every edge pixel.
# --------------------------------------------------------------------------------------------
def _brute_force(ys, xs, colors, values, bias, sigma_s, sigma_r, shape, chunk=2048, product=False):
    """O(M²) oracle over the M edge pixels, vectorised in chunks of ``chunk`` outputs.

    ``product=False``: the paper's Σ_i g_σr(|ΔC_i|) range term; True: the joint-colour Π_i g_σr(|ΔC_i|).
    """
    m = len(values)
    out = np.empty(m)
    wv = bias * values
    for start in range(0, m, chunk):
        sl = slice(start, min(m, start + chunk))
        d2 = (ys[sl, None] - ys[None, :]) ** 2 + (xs[sl, None] - xs[None, :]) ** 2
        gs = np.exp(-d2 / (2 * sigma_s**2))
        gr = np.zeros_like(gs)
        for i in range(colors.shape[1]):
            dc2 = (colors[sl, None, i] - colors[None, :, i]) ** 2
            gr += dc2 if product else np.exp(-dc2 / (2 * sigma_r**2))
        wgt = gs * (np.exp(-gr / (2 * sigma_r**2)) if product else gr)
        out[sl] = (wgt @ wv) / (wgt @ bias)
    return out


def _grid(ys, xs, colors, values, bias, sigma_s, sigma_r, shape, cell=GRID_CELL_PER_SIGMA):
    """Bilateral grid (splat / blur / slice) per channel, with trilinear splat and slice.

    Splat and slice are both trilinear, which widens the effective kernel by a tent ⊛ tent of
    variance h²/3 per axis (h = cell size); the grid blur uses √(σ² − h²/3) to compensate.
    """
    hs, hr = cell * sigma_s, cell * sigma_r
    blur_s = np.sqrt(max(sigma_s**2 - hs**2 / 3, 0.0)) / hs
    blur_r = np.sqrt(max(sigma_r**2 - hr**2 / 3, 0.0)) / hr
    gy = ys / hs
    gx = xs / hs
    ny = int(np.floor(gy.max())) + 2
    nx = int(np.floor(gx.max())) + 2

    def channel(i):  # (numerator, denominator) sliced at the points, for channel i
        c0 = colors[:, i].min()
        gc = (colors[:, i] - c0) / hr
        nc = int(np.floor(gc.max())) + 2
        coords = np.stack([gy, gx, gc])
        base = np.floor(coords).astype(np.int64)
        frac = coords - base
        grid_n = np.zeros(ny * nx * nc)
        grid_d = np.zeros(ny * nx * nc)
        for corner in range(8):
            o = np.array([(corner >> 2) & 1, (corner >> 1) & 1, corner & 1])
            wgt = np.prod(np.where(o[:, None] == 1, frac, 1.0 - frac), axis=0)
            idx = np.ravel_multi_index(tuple(base + o[:, None]), (ny, nx, nc))
            grid_n += np.bincount(idx, weights=wgt * bias * values, minlength=grid_n.size)
            grid_d += np.bincount(idx, weights=wgt * bias, minlength=grid_d.size)
        sig = (blur_s, blur_s, blur_r)
        grid_n = ndimage.gaussian_filter(grid_n.reshape(ny, nx, nc), sig, mode="constant", truncate=4.0)
        grid_d = ndimage.gaussian_filter(grid_d.reshape(ny, nx, nc), sig, mode="constant", truncate=4.0)
        return (ndimage.map_coordinates(grid_n, coords, order=1, mode="nearest"),
                ndimage.map_coordinates(grid_d, coords, order=1, mode="nearest"))

    num = np.zeros(len(values))
    den = np.zeros(len(values))
    for n_i, d_i in _map_in_threads(channel, range(colors.shape[1])):  # summed in channel order
        num += n_i
        den += d_i
    return num / den


def _brute_force_product(ys, xs, colors, values, bias, sigma_s, sigma_r, shape, chunk=2048):
    """O(M²) oracle of the joint-colour (product-over-channels) range kernel."""
    return _brute_force(ys, xs, colors, values, bias, sigma_s, sigma_r, shape, chunk=chunk, product=True)


#: Cell size of the 5-D (y, x, R, G, B) grid of the product kernel, as a fraction of σ: coarser
#: than the 3-D grids' σ/3 to keep the grid small; its size does not grow with the image (σs is a
#: fraction of it). Measured against the brute-force oracle (128² astronaut, 10 % random measures
#: 0–4 px): σ/2 → 2.8 % max relative / 0.005 px RMS error in 3–4 s; 0.75σ → 7.6 % / 0.012 px in
#: 0.4–0.6 s (the value used); σ → 23 % / 0.026 px in 0.14 s (loaded 2-core machine).
GRID_CELL_PER_SIGMA_PRODUCT = 0.75


@numba.njit(cache=True, inline="always")
def _row_major_strides(dims):
    """Element strides of a C-order array of shape ``dims``."""
    nd = len(dims)
    strides = np.empty(nd, dtype=np.int64)
    acc = 1
    for k in range(nd - 1, -1, -1):
        strides[k] = acc
        acc *= dims[k]
    return strides


@numba.njit(cache=True)
def _splat_multilinear(base, frac, dims, wv, bias, grid_n, grid_d):
    """Multilinear splat of M points into two flat grids of shape ``dims`` (row-major).

    Point m adds Π_k (frac or 1 − frac) · (wv[m], bias[m]) to each of the 2^d corners of its cell;
    one serial pass in point order, corners in binary order (highest dimension = lowest bit), so
    the sums do not depend on the machine.
    """
    nd, m = base.shape
    strides = _row_major_strides(dims)
    for j in range(m):
        for corner in range(1 << nd):
            wgt = 1.0
            idx = 0
            for k in range(nd):
                bit = (corner >> (nd - 1 - k)) & 1
                f = frac[k, j]
                wgt *= f if bit == 1 else 1.0 - f
                idx += (base[k, j] + bit) * strides[k]
            grid_n[idx] += wgt * wv[j]
            grid_d[idx] += wgt * bias[j]


#: Columns per parallel work item of :func:`_blur_axis_pair` (the trailing axes of one block).
_BLUR_CHUNK = 256


def gaussian_taps(sigma, truncate):
    """Normalised sampled Gaussian exp(−x²/2σ²), x = −r … r, r = int(truncate·σ + ½) (scipy's rule)."""
    r = int(float(truncate) * float(sigma) + 0.5)
    x = np.arange(-r, r + 1, dtype=np.float64)
    taps = np.exp(-0.5 * (x / float(sigma)) ** 2)
    return taps / taps.sum()


@numba.njit(cache=True, parallel=True)
def _blur_axis_pair(src_n, src_d, dst_n, dst_d, outer, n, inner, taps):
    """One separable pass along the middle axis of two (outer, n, inner) arrays, zero outside.

    Work items are (outer block, chunk of ≤ :data:`_BLUR_CHUNK` inner columns) and run in parallel;
    an item whose input is all zero (most of a sparsely splatted grid) writes zeros and is skipped.
    Every output is Σ_j taps[j − i + r]·src[j] summed in ascending j, so the result does not
    depend on the number of threads.
    """
    r = (len(taps) - 1) // 2
    nch = (inner + _BLUR_CHUNK - 1) // _BLUR_CHUNK
    for q in numba.prange(outer * nch):
        a = q // nch
        b0 = (q % nch) * _BLUR_CHUNK
        b1 = min(inner, b0 + _BLUR_CHUNK)
        base = a * n * inner
        empty = True
        for i in range(n):
            row = base + i * inner
            for b in range(b0, b1):
                if src_n[row + b] != 0.0 or src_d[row + b] != 0.0:
                    empty = False
                    break
            if not empty:
                break
        for i in range(n):
            row = base + i * inner
            for b in range(b0, b1):
                dst_n[row + b] = 0.0
                dst_d[row + b] = 0.0
        if empty:
            continue
        if inner == 1:  # a contiguous line: scalar accumulators
            for i in range(n):
                acc_n = 0.0
                acc_d = 0.0
                for j in range(max(0, i - r), min(n - 1, i + r) + 1):
                    wgt = taps[j - i + r]
                    acc_n += wgt * src_n[base + j]
                    acc_d += wgt * src_d[base + j]
                dst_n[base + i] = acc_n
                dst_d[base + i] = acc_d
            continue
        # (unsigned indices: numba emits no negative-index wrap-around for them, so LLVM vectorises
        # the column loop; the same products added in the same order)
        bw = np.uint64(b1 - b0)
        for i in range(n):
            row = np.uint64(base + i * inner + b0)
            for j in range(max(0, i - r), min(n - 1, i + r) + 1):
                wgt = taps[j - i + r]
                src_row = np.uint64(base + j * inner + b0)
                for b in range(bw):
                    dst_n[row + b] += wgt * src_n[src_row + b]
                    dst_d[row + b] += wgt * src_d[src_row + b]


def _gaussian_blur_pair(grid_n, grid_d, dims, sigmas, truncate):
    """Separable Gaussian blur (zero outside) of two flat grids of shape ``dims``; returns both.

    The same kernel as ``scipy.ndimage.gaussian_filter(…, mode="constant", truncate=truncate)``
    (equal to ~1e-15 relative; tested), last axis first, so the first passes over a sparsely
    splatted grid skip its empty blocks; a σ of 0 skips that axis. Measured on robust's 5-D product
    grid of the 512² bench image (2.6·10⁶ cells, 2 % occupied after the splat), four passes for
    both grids: 0.17 s on 2 cores, against 0.145 s *per grid* for scipy's single-threaded
    ``gaussian_filter``. (float32 would save another 0.03 s but leaves ~1e-6 px of round-off on a
    constant field, which the tests hold to 1e-9.)
    """
    src_n = np.array(grid_n, dtype=np.float64).ravel()  # copies: the inputs are left as they are
    src_d = np.array(grid_d, dtype=np.float64).ravel()
    dst_n = np.empty_like(src_n)
    dst_d = np.empty_like(src_d)
    for axis in range(len(dims) - 1, -1, -1):
        if sigmas[axis] == 0:  # no blur along this axis (e.g. already applied while splatting)
            continue
        outer = int(np.prod(dims[:axis], dtype=np.int64))
        inner = int(np.prod(dims[axis + 1:], dtype=np.int64))
        _blur_axis_pair(src_n, src_d, dst_n, dst_d, outer, int(dims[axis]), inner,
                        gaussian_taps(sigmas[axis], truncate))
        src_n, dst_n = dst_n, src_n
        src_d, dst_d = dst_d, src_d
    return src_n.reshape(dims), src_d.reshape(dims)


@numba.njit(cache=True)
def _splat_blurred_last(base, frac, dims, wv, bias, taps, grid_n, grid_d):
    """:func:`_splat_multilinear` followed by the Gaussian pass along the last axis, in one scatter.

    Each point adds its multilinear corner weights over the first d − 1 axes times, along the last
    axis, its two tent weights spread by ``taps`` (zero outside the grid, as ``mode="constant"``):
    2^(d−1)·2·len(taps) cells per point instead of a pass over every cell of a mostly empty grid.
    One serial pass in point order, so the sums do not depend on the machine.
    """
    nd, m = base.shape
    r = (len(taps) - 1) // 2
    nlast = dims[nd - 1]
    strides = _row_major_strides(dims)
    for j in range(m):
        f_last = frac[nd - 1, j]
        c_last = base[nd - 1, j]
        for corner in range(1 << (nd - 1)):
            wgt = 1.0
            idx = 0
            for k in range(nd - 1):
                bit = (corner >> (nd - 2 - k)) & 1
                f = frac[k, j]
                wgt *= f if bit == 1 else 1.0 - f
                idx += (base[k, j] + bit) * strides[k]
            for t in range(-r, r + 2):  # cells c_last + t, fed by the tent corner c_last (t ≤ r) and c_last + 1 (t ≥ 1 − r)
                c = c_last + t
                if c < 0 or c >= nlast:
                    continue
                lw = 0.0
                if t <= r:
                    lw += (1.0 - f_last) * taps[t + r]
                if t >= 1 - r:
                    lw += f_last * taps[t - 1 + r]
                grid_n[idx + c] += wgt * lw * wv[j]
                grid_d[idx + c] += wgt * lw * bias[j]


def _grid_product(ys, xs, colors, values, bias, sigma_s, sigma_r, shape, cell=GRID_CELL_PER_SIGMA_PRODUCT):
    """Bilateral grid over (y, x, C_1, …, C_n) for the product kernel: multilinear splat/slice.

    The splat is one numba pass that also applies the blur along the last axis
    (:func:`_splat_blurred_last`; per-corner ``np.bincount`` calls into a grid of ~3·10⁶ cells cost
    ~0.5 s at any image size); the other axes are blurred by :func:`_gaussian_blur_pair`. At 512²
    (bench image, robust preset) this is 0.28 s → 0.18 s for the whole Eq. (3) stage.
    """
    hs, hr = cell * sigma_s, cell * sigma_r
    blur_s = np.sqrt(max(sigma_s**2 - hs**2 / 3, 0.0)) / hs
    blur_r = np.sqrt(max(sigma_r**2 - hr**2 / 3, 0.0)) / hr
    cols = [ys / hs, xs / hs] + [(colors[:, i] - colors[:, i].min()) / hr for i in range(colors.shape[1])]
    coords = np.stack(cols)
    dims = tuple(int(np.floor(c.max())) + 2 for c in cols)
    base = np.floor(coords).astype(np.int64)
    frac = coords - base
    size = int(np.prod(dims))
    grid_n = np.zeros(size)
    grid_d = np.zeros(size)
    nd = coords.shape[0]
    sig = (blur_s, blur_s) + (blur_r,) * (nd - 2)
    _splat_blurred_last(base, np.ascontiguousarray(frac), np.asarray(dims, dtype=np.int64),
                        np.ascontiguousarray(bias * values, dtype=np.float64),
                        np.ascontiguousarray(bias, dtype=np.float64), gaussian_taps(sig[-1], 3.0), grid_n, grid_d)
    grid_n, grid_d = _gaussian_blur_pair(grid_n, grid_d, dims, sig[:-1] + (0.0,), truncate=3.0)
    num, den = _map_in_threads(lambda g: ndimage.map_coordinates(g, coords, order=1, mode="nearest"),
                               (grid_n, grid_d))
    return num / den


#: Implementations of Eq. (3), chosen with ``method="..."``: (sum-over-channels kernel of the paper,
#: product-over-channels kernel).
BILATERAL_METHODS = Registry("bilateral method", {
    "grid": Entry(_grid, "bilateral grid", hooks={"product": _grid_product}),
    "brute_force": Entry(_brute_force, "direct sum over the window", hooks={"product": _brute_force_product}),
})

#: Range kernels of Eq. (3b): "sum" (the paper's Σ over channels) or "product" (joint colour); the
#: implementation of "product" is each bilateral method's ``"product"`` hook.
RANGE_KERNELS = Registry("range kernel", {"sum": "Σ over channels of the colour distance (the paper)",
                                          "product": "product over channels (joint colour)"})


def biased_cross_bilateral(sparse_sigma, reference, *, sigma_spatial=0.10, sigma_range=0.10,
                           sharpness_bias=True, bias_scale=2.0, method="grid", range_kernel="sum",
                           robust_iterations=0, robust_scale=0.5, weights=None, bias_strength=None) -> np.ndarray:
    """Biased cross-bilateral filter of the sparse blur measure, Eq. (3).

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels; NaN elsewhere. Finite values must be ≥ 0.
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image C (the RGB input).
    sigma_spatial : float, keyword-only
        σs as a fraction of max(H, W) (paper: 0.10).
    sigma_range : float, keyword-only
        σr as a fraction of the reference's value range max C − min C (paper: 0.10). A constant
        reference (range 0) makes every range weight 1.
    sharpness_bias : bool, keyword-only
        Apply b(BM) = exp(−BM / bias_scale); False gives the plain cross-bilateral ablation.
    bias_scale : float, keyword-only
        Denominator of the bias, px (paper: 2).
    method : str, keyword-only
        Key of :data:`BILATERAL_METHODS`: ``"grid"`` (bilateral grid, default) or ``"brute_force"``.
    range_kernel : {"sum", "product"}, keyword-only
        Colour term of w_pq: the paper's Σ_i g_σr(|ΔC_i|) or (beyond the paper) the joint-colour
        Π_i g_σr(|ΔC_i|) = g_σr(‖ΔC‖).
    robust_iterations : int, keyword-only
        Beyond the paper: extra re-weighted passes (0 = the paper's single pass). Each pass
        multiplies every measure's weight by the Cauchy weight 1/(1 + (r_q/c_q)²) of its residual
        r_q = BM_q − bCBF_q from the previous pass, c_q = robust_scale·(bCBF_q + 0.5 px).
    robust_scale : float, keyword-only
        Relative Cauchy scale of the re-weighting (dimensionless, > 0).
    weights : ndarray, HxW, float, or None, keyword-only
        Beyond the paper: per-measure confidence c_q in (0, 1] at the finite pixels of
        ``sparse_sigma`` (ignored elsewhere), multiplying b(BM_q) in the numerator and in k.
        None: every c_q = 1 (the paper; bit-identical).
    bias_strength : ndarray, HxW, float, or None, keyword-only
        Beyond the paper (with ``sharpness_bias``): per-measure exponent u_q in [0, 1] of the bias,
        b_q = exp(−u_q·BM_q / bias_scale): 0 no bias, 1 the paper's. None: every u_q = 1 (bit-identical).

    Returns
    -------
    ndarray, HxW, float64
        Refined σ, px, at the edge pixels; NaN elsewhere.

    Raises
    ------
    ValueError
        Shape mismatch, NaN/Inf or values outside [0, 1] in the reference (:func:`method.validation.validate_image`),
        Inf or negative σ (:func:`method.validation.validate_sparse_sigma`), bad options.

    Notes
    -----
    1. Collect the M edge pixels (finite BM), their coordinates, guide colours and values.
    2. Bias weights b_q = exp(−(BM_q − min BM)/bias_scale): the constant factor exp(min BM/scale)
       cancels between numerator and k, and avoids underflow for large σ.
    3. Per channel i: Σ_q g_σs g_σr,i b_q BM_q and Σ_q g_σs g_σr,i b_q at every edge p
       (brute force: O(M²); grid: splat on a (y, x, C_i) grid of cell σ/3, Gaussian blur, slice).
    4. Sum numerators and denominators over channels; divide.
    """
    BILATERAL_METHODS.check(method, what="method")
    RANGE_KERNELS.check(range_kernel, what="range_kernel")
    if isinstance(robust_iterations, bool) or not isinstance(robust_iterations, (int, np.integer)) \
            or robust_iterations < 0:
        raise ValueError(f"robust_iterations={robust_iterations!r} is invalid; allowed: integer >= 0")
    if not (isinstance(robust_scale, (int, float, np.floating, np.integer)) and np.isfinite(robust_scale)
            and robust_scale > 0):
        raise ValueError(f"robust_scale={robust_scale!r} is invalid; allowed: finite and > 0")
    ref = validate_image(reference, name="reference", min_side=1)
    sparse_sigma = validate_sparse_sigma(sparse_sigma, ref.shape)
    for name, v in (("sigma_spatial", sigma_spatial), ("sigma_range", sigma_range), ("bias_scale", bias_scale)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v > 0):
            raise ValueError(f"{name}={v!r} is invalid; allowed: finite and > 0")
    if ref.ndim == 2:
        ref = ref[..., None]
    h, w = sparse_sigma.shape
    out = np.full((h, w), np.nan)
    edge = np.isfinite(sparse_sigma)
    if not edge.any():
        return out
    values = sparse_sigma[edge]
    ys, xs = np.nonzero(edge)
    colors = ref[edge]
    if sharpness_bias and bias_strength is not None:
        u = np.asarray(bias_strength, dtype=np.float64)
        if u.shape != (h, w):
            raise ValueError(f"bias_strength has shape {u.shape}; expected {(h, w)}")
        u = u[edge]
        if not np.all(np.isfinite(u) & (u >= 0) & (u <= 1)):
            raise ValueError("bias_strength must be finite and in [0, 1] at the finite measures")
        bias = np.exp(-u * values / float(bias_scale))  # BM ≤ max_sigma: no underflow to guard
    else:
        bias = (np.exp(-(values - values.min()) / float(bias_scale)) if sharpness_bias
                else np.ones_like(values))
    if weights is not None:
        wq = np.asarray(weights, dtype=np.float64)
        if wq.shape != (h, w):
            raise ValueError(f"weights has shape {wq.shape}; expected {(h, w)}")
        wq = wq[edge]
        if not np.all(np.isfinite(wq) & (wq > 0) & (wq <= 1)):
            raise ValueError("weights must be finite and in (0, 1] at the finite measures")
        bias = bias * wq
    sigma_s = float(sigma_spatial) * max(h, w)
    span = float(ref.max() - ref.min())
    sigma_r = float(sigma_range) * span if span > 0 else 1.0
    if span == 0:
        colors = np.zeros_like(colors)
    kernel = BILATERAL_METHODS[method] if range_kernel == "sum" else BILATERAL_METHODS.hook(method, "product")
    ys, xs = ys.astype(np.float64), xs.astype(np.float64)
    refined = kernel(ys, xs, colors, values, bias, sigma_s, sigma_r, (h, w))
    for _ in range(int(robust_iterations)):
        scale = float(robust_scale) * (np.maximum(refined, 0.0) + 0.5)
        weight = bias / (1.0 + ((values - refined) / scale) ** 2)
        refined = kernel(ys, xs, colors, values, weight, sigma_s, sigma_r, (h, w))
    out[edge] = refined
    return out
