"""Region blur from the local power spectrum of the image gradient (Zhu, Cohen, Schiller & Milanfar 2013; beyond the paper).

Zhu et al., "Estimating spatially varying defocus blur from a single image", IEEE TIP 22(12), 2013,
model the windowed Fourier responses of the image *gradient*: natural images have roughly 1/|ω|²
power spectra, so their gradient is roughly white with an unknown local scale s, and the expected
power of a windowed Fourier coefficient of a blurred window is

    E P(ω) = s · (|H_σ|² Q ⊛ |Ŵ|²)(ω) + v · (|D|² ⊛ |Ŵ|²)(ω),

with H_σ the blur's transfer function, Q the gradient operator's departure from an ideal derivative,
|Ŵ|² the window's own power spectrum (its leakage, modelled exactly: a periodogram fit that ignores
it reads leaked low-frequency power as sharpness and is biased low), |D|² the gradient operator's
response to white noise of variance v. Each measure is a maximum-likelihood fit of (σ, s) per window,
its confidence the Fisher information of σ with s profiled out.

Conventions: σ in px of the input image; for ``psf="disk"`` the kernel is a uniform disk of radius R
convolved with the 1-px box of the pixel (the harness's renders) and the reported σ is the harness's
σ_gt = √((R/2)² + 1/12), whose floor is 1/√12 ≈ 0.289 px.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.fft
from numpy.lib.stride_tricks import sliding_window_view
from scipy.special import j1

__all__ = [
    "LSB",
    "PSF_MODELS",
    "NOISE_MODELS",
    "estimate_blur_local_spectrum",
    "estimate_noise_variance",
    "local_spectrum_grid",
    "sigma_grid",
]

#: One grey level of 8-bit data in image units; its quantisation adds LSB²/12 of white noise.
LSB = 1.0 / 255.0
#: Blur kernels the likelihood models (``DefocusParams.region_psf`` also allows "edges").
PSF_MODELS = ("gaussian", "disk")
#: Noise models of the likelihood (``DefocusParams.region_noise_model``).
NOISE_MODELS = ("white", "spectrum", "spectrum_or_white")
#: Window sides the multi-window pass chooses from, px (each ≥ 16; the smallest ≥ 9·σ̂ is used).
WINDOW_SIZES = (16, 24, 32, 48, 64, 96, 128)
#: Window of the coarse pass that chooses each location's window, px.
COARSE_WINDOW = 32
#: Smallest log-likelihood-ratio 2·(L_noise − L_fit) for a measure; below it the window's spectrum
#: is explained by noise alone (flat or noise-only region): NaN, information 0.
MIN_LOG_LR = 25.0
#: Windows processed per FFT batch (bounds memory: 512 windows of 128² complex64 = 64 MB).
_BATCH = 512


def sigma_grid(sigma_min, sigma_max, psf):
    """The candidate σ of the grid search, px (reported convention).

    Parameters
    ----------
    sigma_min, sigma_max : float
        Range of reported σ, px (0 <= sigma_min < sigma_max). For ``psf="disk"`` values below
        1/√12 px (no disk, only the pixel's box) are raised to it.
    psf : {"gaussian", "disk"}

    Returns
    -------
    ndarray, (G,), float64
        Steps of 0.125 px up to 2 px, then a geometric ratio of 1.05.
    """
    lo = float(sigma_min)
    if psf == "disk":
        lo = max(lo, 1.0 / math.sqrt(12.0))
    fine = np.arange(lo, min(2.0, sigma_max), 0.125)
    start = max(2.0, lo)
    n_geo = max(2, int(math.ceil(math.log(sigma_max / start) / math.log(1.05))) + 1) if sigma_max > start else 0
    geo = np.geomspace(start, sigma_max, n_geo) if n_geo else np.array([float(sigma_max)])
    return np.unique(np.concatenate([fine, geo]))


def _hann(n):
    w = 0.5 - 0.5 * np.cos(2 * np.pi * (np.arange(n) + 0.5) / n)
    return np.outer(w, w)


def _rings(n):
    """Ring index of each DFT bin of an n×n window (round(|k|)), 0 at DC; (n², ) int, and the ring count."""
    k = np.fft.fftfreq(n) * n
    r = np.rint(np.hypot(k[:, None], k[None, :])).astype(np.int64).ravel()
    return r, int(r.max()) + 1


def _transfer_sq(psf, sig, wx, wy):
    """|H|² of the blur on the frequency grid (wx, wy, rad/px) for reported σ ``sig``."""
    w2 = wx ** 2 + wy ** 2
    if psf == "gaussian":
        return np.exp(-(sig ** 2) * w2)
    radius = 2.0 * math.sqrt(max(sig ** 2 - 1.0 / 12.0, 0.0))
    box = np.sinc(wx / (2 * np.pi)) * np.sinc(wy / (2 * np.pi))  # np.sinc(x) = sin(πx)/(πx)
    if radius <= 0:
        return box ** 2
    u = radius * np.sqrt(w2)
    with np.errstate(invalid="ignore", divide="ignore"):
        disk = np.where(u > 1e-8, 2.0 * j1(u) / u, 1.0)
    return (disk * box) ** 2


def _windowed_expectation(spectrum, n):
    """Exact expected periodogram of an n×n Hann-windowed stationary field of DTFT power ``spectrum``.

    ``spectrum`` is sampled on an L×L DFT grid (L ≥ 2n); its inverse FFT gives the autocorrelation at
    integer lags, which is multiplied by the window's autocorrelation (|τ| < n, exact) and folded
    modulo n: E|Σ w x e^{-iω_k x}|² = Σ_τ r_w(τ) R(τ) e^{-iω_k τ} at ω_k = 2πk/n.
    """
    L = spectrum.shape[0]
    acf = np.real(np.fft.ifft2(spectrum))
    w = _hann(n)
    pad = np.zeros((2 * n, 2 * n))
    pad[:n, :n] = w
    fw = np.fft.fft2(pad)
    rw = np.real(np.fft.ifft2(np.abs(fw) ** 2))  # r_w(τ) at lags τ mod 2n (|τ| < n nonzero)
    lags = np.concatenate([np.arange(0, n), np.arange(-n + 1, 0)])  # 2n−1 lags
    rw_l = rw[np.ix_(lags % (2 * n), lags % (2 * n))]
    r_l = acf[np.ix_(lags % L, lags % L)]
    c = rw_l * r_l
    folded = np.zeros((n, n))
    np.add.at(folded, np.ix_(lags % n, lags % n), c)
    return np.real(np.fft.fft2(folded))


@functools.lru_cache(maxsize=64)
def _model_tables(n, psf, grid):
    """Ring-summed expected periodograms of an n×n window: signal (G, B) per unit s, noise (B,) per unit v.

    Returns (A, dA, N, kappa, ring_of_bin): A[g, b] the expected ring-b power of the gradient of a
    blurred 1/|ω|² texture (s = 1) for σ = grid[g]; dA its σ-derivative (central differences); N[b]
    that of unit white noise; kappa[b] the effective Gamma shape of the ring sum (bins / window
    variance inflation).
    """
    grid = np.asarray(grid)
    L = max(4 * n, 128)
    w = 2 * np.pi * np.fft.fftfreq(L)
    wx, wy = w[None, :], w[:, None]
    d2 = 4 * np.sin(wx / 2) ** 2 + 4 * np.sin(wy / 2) ** 2  # |Dx|² + |Dy|² of forward differences
    w2 = wx ** 2 + wy ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(w2 > 0, d2 / np.where(w2 > 0, w2, 1.0), 1.0)
    ring, n_rings = _rings(n)
    keep = ring > 0

    def ring_sum(e):
        return np.bincount(ring[keep], weights=e.ravel()[keep], minlength=n_rings)[1:]

    A = np.stack([ring_sum(_windowed_expectation(q * _transfer_sq(psf, s, wx, wy), n)) for s in grid])
    dA = np.gradient(A, grid, axis=0)
    N = ring_sum(_windowed_expectation(d2, n))
    counts = np.bincount(ring[keep], minlength=n_rings)[1:].astype(np.float64)
    win = _hann(n)
    inflation = n * n * np.sum(win ** 4) / np.sum(win ** 2) ** 2
    kappa = counts / inflation
    return A, dA, N, kappa, ring


def estimate_noise_variance(gray, *, bits=8):
    """White-noise variance of an image from the MAD of its finest diagonal Haar coefficients, image units².

    Parameters
    ----------
    gray : ndarray, HxW, float
        Image in [0, 1].
    bits : int or None, keyword-only
        Bit depth of the data: the variance is at least LSB²/12 of that quantisation (None: no floor).

    Returns
    -------
    float
        max((median|d| / 0.6745)², LSB²/12), d = (a − b − c + e)/2 over disjoint 2×2 blocks (the db1
        diagonal detail of ``skimage.restoration.estimate_sigma``).
    """
    g = np.asarray(gray, dtype=np.float64)
    h, w = (g.shape[0] // 2) * 2, (g.shape[1] // 2) * 2
    b = g[:h, :w]
    d = (b[0::2, 0::2] - b[0::2, 1::2] - b[1::2, 0::2] + b[1::2, 1::2]) / 2.0
    v = (np.median(np.abs(d)) / 0.6744897501960817) ** 2 if d.size else 0.0
    floor = (1.0 / (2 ** bits - 1)) ** 2 / 12.0 if bits else 0.0
    return float(max(v, floor))


def _gradient_field(gray):
    g = np.asarray(gray, dtype=np.float32)
    gx = g[:-1, 1:] - g[:-1, :-1]
    gy = g[1:, :-1] - g[:-1, :-1]
    return gx + 1j * gy  # one complex FFT per window gives |Gx|² + |Gy|² summed over ±k (ring sums)


def _window_starts(centres, n, size):
    return np.clip(centres - n // 2, 0, size - n)


def _ring_powers(z, ys, xs, n):
    """Ring-summed periodograms (len(ys), B) of the n×n Hann windows of z starting at (ys, xs)."""
    win = _hann(n).astype(np.float32)
    ring, n_rings = _rings(n)
    onehot = np.zeros((n * n, n_rings - 1), dtype=np.float32)
    keep = ring > 0
    onehot[np.flatnonzero(keep), ring[keep] - 1] = 1.0
    view = sliding_window_view(z, (n, n))
    out = np.empty((len(ys), n_rings - 1), dtype=np.float64)
    for i in range(0, len(ys), _BATCH):
        patches = view[ys[i:i + _BATCH], xs[i:i + _BATCH]] * win
        f = scipy.fft.fft2(patches, axes=(-2, -1), overwrite_x=True)
        p = (f.real ** 2 + f.imag ** 2).reshape(len(patches), -1)
        out[i:i + _BATCH] = p @ onehot
    return out


def _fit(P, A, dA, N, kappa, *, iters=8, likelihood="profile"):
    """Maximum likelihood of M = s·A(σ) + N under independent Gamma(κ_b) ring sums, s profiled.

    Parameters: P (n, B) ring powers; A, dA (G, B); N (n, B) noise; kappa (B,). Returns σ index
    (fractional, parabolic refinement), ŝ, Fisher information of σ per unit of grid σ (caller maps
    it), log-likelihood ratio against noise only, and the grid NLL (n, G).
    """
    n, B = P.shape
    Pn = P[:, None, :]
    Nn = N[:, None, :]
    An = A[None, :, :]
    # start: weighted moment estimate s0 = Σκ(P − N)⁺ / ΣκA
    s = np.maximum(np.sum(kappa * np.maximum(Pn - Nn, 0.0), -1) / np.sum(kappa * An, -1), 1e-30)
    for _ in range(iters):  # Newton on the profile score in s (s >= 0)
        M = s[..., None] * An + Nn
        r = Pn / M
        g = np.sum(kappa * An / M * (1.0 - r), -1)
        h = np.sum(kappa * (An / M) ** 2 * (2.0 * r - 1.0), -1)
        step = np.where(h > 0, g / np.where(h > 0, h, 1.0), -s)
        s = np.maximum(s - step, s * 0.1)
    M = s[..., None] * An + Nn
    nll = np.sum(kappa * (Pn / M + np.log(M)), -1)  # (n, G)
    if likelihood == "gsm":  # s marginalised under a log-uniform mixture prior (Laplace, in log s)
        nll = nll + 0.5 * np.log(np.maximum(np.sum(kappa * (s[..., None] * An / M) ** 2, -1), 1e-300))
    nll0 = np.sum(kappa * (P / N + np.log(N)), -1)
    j = np.argmin(nll, axis=1)
    rows = np.arange(n)
    return j, s[rows, j], nll, 2.0 * (nll0 - nll[rows, j])


def _refine(grid, nll, j):
    """Parabolic vertex through the grid NLL at j−1, j, j+1 (clamped to the grid), px."""
    G = len(grid)
    jm = np.clip(j - 1, 0, G - 3)
    x = np.stack([grid[jm], grid[jm + 1], grid[jm + 2]], 1)
    y = np.take_along_axis(nll, np.stack([jm, jm + 1, jm + 2], 1), 1)
    x0, x1, x2 = x.T
    y0, y1, y2 = y.T
    d01 = (y1 - y0) / (x1 - x0)
    d12 = (y2 - y1) / (x2 - x1)
    curv = (d12 - d01) / (x2 - x0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = 0.5 * (x0 + x1) - d01 / (2.0 * curv)
    inner = (j > 0) & (j < G - 1) & (curv > 0)
    return np.where(inner, np.clip(v, grid[np.maximum(j - 1, 0)], grid[np.minimum(j + 1, G - 1)]), grid[j])


def _information(sig, s, grid, A, dA, N, kappa):
    """Fisher information of σ (s profiled), 1/px², at (σ̂, ŝ) with A, dA interpolated in σ."""
    G = len(grid)
    k = np.clip(np.searchsorted(grid, sig) - 1, 0, G - 2)
    t = ((sig - grid[k]) / (grid[k + 1] - grid[k]))[:, None]
    a = (1 - t) * A[k] + t * A[k + 1]
    da = (1 - t) * dA[k] + t * dA[k + 1]
    M = s[:, None] * a + N
    i_ss = np.sum(kappa * (a / M) ** 2, -1)
    i_sg = np.sum(kappa * a * s[:, None] * da / M ** 2, -1)
    i_gg = np.sum(kappa * (s[:, None] * da / M) ** 2, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        info = i_gg - i_sg ** 2 / i_ss
    return np.where(np.isfinite(info) & (info > 0), info, 0.0)


def _noise_rings(P, v_white, Nunit, model):
    """Per-window noise ring powers (n, B) for the chosen noise model."""
    white = np.broadcast_to(v_white * Nunit, P.shape)
    if model == "white":
        return white
    # noise floor read from the image's own spectrum: per ring, a low quantile of the windows' powers
    # (windows whose spectrum is noise there), never below the quantisation floor
    floor = np.quantile(P, 0.05, axis=0) if P.shape[0] >= 20 else np.min(P, axis=0)
    qfloor = (LSB ** 2 / 12.0) * Nunit
    spec = np.maximum(floor, qfloor)
    if model == "spectrum":
        return np.broadcast_to(spec, P.shape)
    return np.broadcast_to(np.minimum(spec, white[0]), P.shape)


def local_spectrum_grid(gray, *, psf="gaussian", noise_model="white", sigma_min=0.0, sigma_max=12.0,
                        window_min=16, window_max=96, window_scale=9.0, stride=16, noise_variance=None,
                        likelihood="profile"):
    """Per-window blur measures on a block grid of window centres (the kernel of :func:`estimate_blur_local_spectrum`).

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        Luminance.
    psf : {"gaussian", "disk"}, keyword-only
    noise_model : {"white", "spectrum", "spectrum_or_white"}, keyword-only
    sigma_min, sigma_max : float, keyword-only
        σ grid range, px.
    window_min, window_max : int, keyword-only
        Smallest / largest window side, px.
    window_scale : float, keyword-only
        Window side as a multiple of the coarse σ̂, dimensionless.
    stride : int, keyword-only
        Spacing of the window centres, px.
    noise_variance : float or None, keyword-only
        White-noise variance, image units²; None: :func:`estimate_noise_variance`.
    likelihood : {"profile", "gsm"}, keyword-only
        "profile": the scale s maximised out (Zhu et al.); "gsm": s marginalised under a
        log-uniform scale-mixture prior (:mod:`method.blur_gsm`).

    Returns
    -------
    dict
        ``cy``, ``cx`` (ny,), (nx,) centre rows / columns, px; ``sigma`` (ny, nx) px, NaN without a
        measure; ``information`` (ny, nx) 1/px², 0 without a measure; ``window`` (ny, nx) side used, px;
        ``noise_variance`` float.
    """
    g = np.asarray(gray, dtype=np.float64)
    H, W = g.shape
    z = _gradient_field(g)
    hz, wz = z.shape
    v = estimate_noise_variance(g) if noise_variance is None else float(noise_variance)
    cy = np.arange(stride // 2, H, stride)
    cx = np.arange(stride // 2, W, stride)
    ny, nx = len(cy), len(cx)
    sigma = np.full((ny, nx), np.nan)
    info = np.zeros((ny, nx))
    wins = np.zeros((ny, nx), dtype=np.int64)
    sizes = [s for s in WINDOW_SIZES if window_min <= s <= window_max and s <= min(hz, wz)]
    if not sizes:
        if min(hz, wz) >= 16:
            sizes = [min(hz, wz, window_max)]
        else:
            return dict(cy=cy, cx=cx, sigma=sigma, information=info, window=wins, noise_variance=v)
    grid = tuple(sigma_grid(sigma_min, sigma_max, psf))
    garr = np.asarray(grid)
    yy, xx = np.meshgrid(cy, cx, indexing="ij")
    yy, xx = yy.ravel(), xx.ravel()

    def run(n, idx):
        A, dA, Nu, kappa, _ = _model_tables(n, psf, grid)
        P = _ring_powers(z, _window_starts(yy[idx], n, hz), _window_starts(xx[idx], n, wz), n)
        N = np.ascontiguousarray(_noise_rings(P, v, Nu, noise_model))
        j, s, nll, lr = _fit(P, A, dA, N, kappa, likelihood=likelihood)
        sig = _refine(garr, nll, j)
        inf = _information(sig, s, garr, A, dA, N, kappa)
        ok = (lr > MIN_LOG_LR) & (inf > 0)
        return np.where(ok, sig, np.nan), np.where(ok, inf, 0.0)

    # coarse pass, then each location's window from its coarse σ̂ (median over the 3×3 neighbours)
    n0 = min(sizes, key=lambda s: abs(s - COARSE_WINDOW))
    all_idx = np.arange(ny * nx)
    s0, i0 = run(n0, all_idx)
    from scipy.ndimage import generic_filter  # small grid: a NaN-aware 3×3 median
    coarse = generic_filter(s0.reshape(ny, nx), np.nanmedian, size=3, mode="nearest").ravel()
    want = np.where(np.isfinite(coarse), window_scale * coarse, sizes[0])
    choice = np.array([next((s for s in sizes if s >= w_), sizes[-1]) for w_ in want])
    out_s, out_i = s0.copy(), i0.copy()
    for n in sizes:
        sel = np.flatnonzero(choice == n)
        if n == n0 or not sel.size:
            continue
        out_s[sel], out_i[sel] = run(n, sel)
    sigma[:] = out_s.reshape(ny, nx)
    info[:] = out_i.reshape(ny, nx)
    wins[:] = choice.reshape(ny, nx)
    return dict(cy=cy, cx=cx, sigma=sigma, information=info, window=wins, noise_variance=v)


def _linear_weights(centres, n):
    """(n, len(centres)) matrix of 1-D linear interpolation from the centres to 0..n−1 (clamped ends)."""
    x = np.arange(n, dtype=np.float64)
    k = np.clip(np.searchsorted(centres, x) - 1, 0, max(len(centres) - 2, 0))
    m = np.zeros((n, len(centres)))
    if len(centres) == 1:
        m[:, 0] = 1.0
        return m
    t = np.clip((x - centres[k]) / (centres[k + 1] - centres[k]), 0.0, 1.0)
    m[np.arange(n), k] = 1 - t
    m[np.arange(n), k + 1] += t
    return m


def spread_to_pixels(grid_out, shape):
    """Bilinear spread of a block grid's σ and information to every pixel (NaN where the nearest measures are missing).

    Parameters
    ----------
    grid_out : dict
        Output of :func:`local_spectrum_grid`.
    shape : (int, int)
        (H, W) of the image.

    Returns
    -------
    (ndarray, ndarray), HxW float64
        σ, px (NaN where under half the interpolation weight has a measure) and information, 1/px².
    """
    H, W = shape
    ry = _linear_weights(grid_out["cy"].astype(np.float64), H)
    rx = _linear_weights(grid_out["cx"].astype(np.float64), W)
    s = grid_out["sigma"]
    ok = np.isfinite(s)
    num = ry @ np.where(ok, s, 0.0) @ rx.T
    den = ry @ ok.astype(np.float64) @ rx.T
    info = ry @ grid_out["information"] @ rx.T
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = np.where(den >= 0.5, num / np.where(den > 0, den, 1.0), np.nan)
    return sigma, np.where(np.isfinite(sigma), info, 0.0)


def estimate_blur_local_spectrum(gray, *, params, edge_psf=None):
    """Region blur σ and its Fisher information per pixel, from windowed gradient spectra (Zhu et al. 2013).

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        Luminance of the sRGB input (``method.luma.luminance``).
    params : DefocusParams, keyword-only
        Uses ``region_psf``, ``region_noise_model``, ``region_sigma_min`` / ``region_sigma_max``,
        ``region_window_min`` / ``region_window_max`` / ``region_window_scale`` and ``region_stride``.
    edge_psf : {"gaussian", "disk"} or None, keyword-only
        The PSF family the edge fit chose; used when ``params.region_psf == "edges"`` (None there:
        "gaussian").

    Returns
    -------
    sigma : ndarray, HxW, float64
        Blur σ, px (reported convention, see the module docstring); NaN where no window measures it.
    information : ndarray, HxW, float64
        Information density, 1/px² per pixel (0 where σ is NaN): the Fisher information of σ of the
        windows around each pixel (bilinear in their centres) divided by stride², so its sum over a
        stride × stride block is one window's information.

    Notes
    -----
    1. Gradient z = ∂x I + i ∂y I by forward differences (one complex FFT per window gives the
       sum of both components' periodograms over each ring of ±k).
    2. Noise variance v from the MAD of the finest diagonal Haar detail, at least the 8-bit
       quantisation's LSB²/12 (``noise_model="white"``); or per ring the 5 % quantile of all windows'
       powers (``"spectrum"``, the image's own noise floor; ``"spectrum_or_white"`` the smaller).
    3. Hann windows on a grid of centres (stride px); per window the ring sums P_b of the periodogram.
    4. Model E P_b = s·A_b(σ) + N_b, A_b = Σ_ring (|H_σ|² Q ⊛ |Ŵ|²), computed exactly through the
       autocorrelations (window × field) at integer lags; ring sums Gamma(κ_b) distributed, κ_b the
       ring's bins / the window's variance inflation.
    5. Maximum likelihood: per σ of the grid, s by Newton steps on the profile score; the grid
       minimum refined by a parabola; "no measure" when 2·(L_noise − L_fit) < MIN_LOG_LR.
    6. Information: I_σσ − I_σs²/I_ss of the Gamma model at (σ̂, ŝ).
    7. Multi-window: a coarse 32-px pass; each centre then uses the smallest window of
       WINDOW_SIZES ≥ window_scale · σ̂ (3×3 median of the coarse σ̂), within [window_min, window_max].
    8. Spread to pixels by bilinear interpolation of the centres' values.
    """
    psf = params.region_psf
    if psf == "edges":
        psf = edge_psf if edge_psf is not None else "gaussian"
    if psf not in PSF_MODELS:
        raise ValueError(f"edge_psf={edge_psf!r} is invalid; allowed: {list(PSF_MODELS)}")
    g = np.asarray(gray, dtype=np.float64)
    out = local_spectrum_grid(g, psf=psf, noise_model=params.region_noise_model,
                              sigma_min=params.region_sigma_min, sigma_max=params.region_sigma_max,
                              window_min=params.region_window_min, window_max=params.region_window_max,
                              window_scale=params.region_window_scale, stride=params.region_stride)
    sigma, info = spread_to_pixels(out, g.shape)
    return sigma, info / float(params.region_stride) ** 2
