"""Fast kernels of the scatter renderer (numba), behind :func:`method.magnify.scatter.scatter_blur`.

Arrays here are trusted (shapes and values checked by the wrapper). Images carry C value channels and
a last weight channel (1 for a pixel, the member count for a block of pixels), so radiance and
coverage are spread by the same writes. Every kernel is row-parallel with no write shared between
threads, in a fixed order: results do not depend on the thread count.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["add_upsampled", "composite_layer", "prefix_rows", "scatter_sources", "splat_down"]


@numba.njit(cache=True, inline="always")
def _splat(buf, src, sy, sx, half, n, scale, y0, y1, pad):
    """Add source (sy, sx)'s row segments to the difference rows y0 ≤ y < y1 of ``buf``.

    Row dy gets the segment [sx − h, sx + h], h = ``half[|dy|]``, with area-weighted end pixels:
    four writes per channel (two partial end pixels and the run between, as differences).
    """
    c1 = src.shape[2]
    for dy in range(max(-n, y0 - sy), min(n, y1 - 1 - sy) + 1):
        h = half[abs(dy)]
        if h <= 0.0:
            continue
        left = sx - h
        right = sx + h
        xa = int(math.floor(left + 0.5))
        xb = int(math.floor(right + 0.5))
        row = buf[sy + dy]
        if xa == xb:
            d0 = 2.0 * h * scale
            d1 = 0.0
            d2 = 0.0
            d3 = -d0
        else:
            fa = (xa + 0.5 - left) * scale
            fb = (right - xb + 0.5) * scale
            d0 = fa
            d1 = scale - fa
            d2 = fb - scale
            d3 = -fb
        for k in range(c1):
            v = src[sy, sx, k]
            row[xa + pad, k] += d0 * v
            row[xa + 1 + pad, k] += d1 * v
            row[xb + pad, k] += d2 * v
            row[xb + 1 + pad, k] += d3 * v


@numba.njit(cache=True, parallel=True)
def scatter_sources(buf, src, active, kidx, half, nrows, scale, reach, pad, chunk):
    """Difference rows of every ``active`` source; row chunks in parallel, each writing only its own rows.

    ``buf`` (H, W + 2·pad + 1, C+1) float64, zero on entry; ``src`` (H, W, C+1); ``active`` (H, W)
    bool; ``kidx`` (H, W) index into the kernel table ``half`` (n_radii, rows) / ``nrows`` / ``scale``;
    ``reach``: rows any active source reaches + 1.
    """
    h, w = active.shape
    nchunks = (h + chunk - 1) // chunk
    for ci in numba.prange(nchunks):
        y0 = ci * chunk
        y1 = min(h, y0 + chunk)
        for sy in range(max(0, y0 - reach), min(h, y1 + reach)):
            for sx in range(w):
                if active[sy, sx]:
                    k = kidx[sy, sx]
                    _splat(buf, src, sy, sx, half[k], nrows[k], scale[k], y0, y1, pad)


@numba.njit(cache=True, parallel=True)
def prefix_rows(buf, out, pad):
    """out[y, x] = Σ_{x' ≤ x + pad} buf[y, x'] (the prefix sums of the difference rows); zeroes ``buf``."""
    h, wp, c1 = buf.shape
    w = out.shape[1]
    for y in numba.prange(h):
        run = np.zeros(c1)
        for xp in range(wp):
            for k in range(c1):
                run[k] += buf[y, xp, k]
                buf[y, xp, k] = 0.0
            x = xp - pad
            if 0 <= x < w:
                for k in range(c1):
                    out[y, x, k] = run[k]


@numba.njit(cache=True, inline="always")
def _tent(y, b, n):
    """(i0, i1, 1 − t, t): the two block centres (clamped to 0..n−1) fine index y lies between, and its weights."""
    u = (y + 0.5) / b - 0.5
    i = int(math.floor(u))
    t = u - i
    return min(max(i, 0), n - 1), min(max(i + 1, 0), n - 1), 1.0 - t, t


@numba.njit(cache=True, parallel=True)
def splat_down(src, sigma, members, b, out):
    """Splat the ``members`` onto the b×b block centres with bilinear weights: out (ceil(H/b), ceil(W/b),
    C+2) holds the sums of ``src`` (H, W, C+1: values and weight) and, last, of weight·σ² (``sigma``
    HxW px). Sums are kept, and so are centroids (away from the borders, where the weights are clamped).
    """
    h, w, c1 = src.shape
    hc, wc = out.shape[0], out.shape[1]
    rows = np.zeros((h, wc, c1 + 1))
    for y in numba.prange(h):
        for x in range(w):
            if not members[y, x]:
                continue
            j0, j1, w0, w1 = _tent(x, b, wc)
            for k in range(c1):
                v = src[y, x, k]
                rows[y, j0, k] += w0 * v
                rows[y, j1, k] += w1 * v
            v = src[y, x, c1 - 1] * sigma[y, x] * sigma[y, x]
            rows[y, j0, c1] += w0 * v
            rows[y, j1, c1] += w1 * v
    for i in numba.prange(hc):
        for j in range(wc):
            for k in range(c1 + 1):
                out[i, j, k] = 0.0
        for y in range(max(0, b * (i - 1)), min(h, b * (i + 2))):
            i0, i1, w0, w1 = _tent(y, b, hc)
            wy = (w0 if i0 == i else 0.0) + (w1 if i1 == i else 0.0)
            if wy != 0.0:
                for j in range(wc):
                    for k in range(c1 + 1):
                        out[i, j, k] += wy * rows[y, j, k]


@numba.njit(cache=True, parallel=True)
def add_upsampled(dense, coarse, b):
    """dense += coarse upsampled ×b (bilinear between block centres, edges held) / b² (sums → densities).

    ``coarse`` (ceil(H/b), ceil(W/b), C+1) holds sums over b×b blocks whose centres sit at full-res
    b·i + (b − 1)/2; each full-res pixel interpolates the four nearest centres.
    """
    h, w, c1 = dense.shape
    hc, wc = coarse.shape[0], coarse.shape[1]
    inv = 1.0 / (b * b)
    for y in numba.prange(h):
        ia, ib, wa, wb = _tent(y, b, hc)
        for x in range(w):
            ja, jb, va, vb = _tent(x, b, wc)
            for k in range(c1):
                top = va * coarse[ia, ja, k] + vb * coarse[ia, jb, k]
                bottom = va * coarse[ib, ja, k] + vb * coarse[ib, jb, k]
                dense[y, x, k] += inv * (wa * top + wb * bottom)


@numba.njit(cache=True, parallel=True)
def composite_layer(buf, dense, use_dense, acc, trans, hidden, pad, src, direct):
    """Prefix-sum the difference rows (zeroing them) and composite the layer under what is in front.

    Per pixel: N, W = the prefix sums, plus ``dense`` (the coarse levels, when ``use_dense``), plus the
    pixel's own ``src`` where ``direct`` (radius 0: added exactly, so a sharp pixel nothing covers
    keeps its value bit for bit); colour N/W and opacity α = min(W / max(1 − f, W), 1), f =
    ``hidden``; acc += T·α·N/W, T ← T·(1 − α).
    """
    h, wp, c1 = buf.shape
    w = acc.shape[1]
    c = c1 - 1
    for y in numba.prange(h):
        run = np.zeros(c1)
        tot = np.zeros(c1)
        for xp in range(wp):
            for k in range(c1):
                run[k] += buf[y, xp, k]
                buf[y, xp, k] = 0.0
            x = xp - pad
            if x < 0 or x >= w:
                continue
            for k in range(c1):
                tot[k] = run[k]
            if use_dense:
                for k in range(c1):
                    tot[k] += dense[y, x, k]
            if direct[y, x]:
                for k in range(c1):
                    tot[k] += src[y, x, k]
            wsum = tot[c]
            if wsum <= 1e-12:
                continue
            alpha = min(wsum / max(1.0 - hidden[y, x], wsum, 1e-12), 1.0)
            s = trans[y, x] * alpha / wsum
            for k in range(c):
                acc[y, x, k] += s * tot[k]
            trans[y, x] *= 1.0 - alpha
