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

import dataclasses
import math

import numpy as np
import scipy.fft
from numpy.lib.stride_tricks import sliding_window_view

from .image_noise import estimate_noise_variance
from .spectrum_model import hann_window, model_tables, ring_matrix, sigma_grid
from ..registry import Entry, Registry

__all__ = [
    "LSB",
    "PSF_MODELS",
    "NOISE_MODELS",
    "REGION_GATES",
    "AdequacyGate",
    "estimate_blur_local_spectrum",
    "estimate_noise_variance",
    "local_spectrum_grid",
    "sigma_grid",
]

#: One grey level of 8-bit data in image units; its quantisation adds LSB²/12 of white noise.
LSB = 1.0 / 255.0
#: Blur kernels the likelihood models (``DefocusParams.region_psf`` also allows "edges").
PSF_MODELS = Registry("PSF model", {"gaussian": "Gaussian of σ", "disk": "uniform disk of radius 2σ"})
#: Noise models of the likelihood (``DefocusParams.region_noise_model``).
NOISE_MODELS = Registry("noise model", ("white", "spectrum", "spectrum_or_white"))
#: Window sides the multi-window pass chooses from, px (each ≥ 16; the smallest ≥ 9·σ̂ is used).
WINDOW_SIZES = (16, 24, 32, 48, 64, 96, 128)
#: Window of the coarse pass that chooses each location's window, px.
COARSE_WINDOW = 32
#: Smallest log-likelihood-ratio 2·(L_noise − L_fit) for a measure; below it the window's spectrum
#: is explained by noise alone (flat or noise-only region): NaN, information 0.
MIN_LOG_LR = 25.0


@dataclasses.dataclass(frozen=True)
class AdequacyGate:
    """When a window's fit is a measure: the model explains its spectrum and pins σ down.

    Attributes
    ----------
    max_deviance : float
        Largest mean Gamma deviance per band of the fitted spectrum (≈ 1 when the 1/|ω|² texture model
        fits; periodic textures and text give peaks far above it), dimensionless.
    max_rel_std : float
        Largest relative standard deviation 1/(σ̂·√I) of σ̂ (I its Fisher information, the scale
        profiled out): a window whose likelihood is flat in σ (smooth shading, a single edge, a
        texture with little high-frequency power) gives no measure, dimensionless.
    top_margin : float
        σ̂ ≥ sigma_max / top_margin is a bound at the top of the grid, not a measure (smooth shading
        reads as "as blurry as the grid allows"), dimensionless ≥ 1.
    """

    max_deviance: float = math.inf
    max_rel_std: float = math.inf
    top_margin: float = 1.0


#: ``DefocusParams.region_gate``: which fits are measures. The "adequacy" thresholds were chosen on
#: lens mosaics of eight texture families (disk PSF in linear light, ISO 100; docs/region-blur.md).
REGION_GATES = Registry("region gate", {
    "none": Entry(AdequacyGate(), "every fit with evidence above the noise (2·ΔL > 25) is a measure"),
    "adequacy": Entry(AdequacyGate(max_deviance=2.0, max_rel_std=0.05, top_margin=1.1),
                      "also: the model fits (deviance ≤ 2 per band), σ̂ is pinned down (rel. std ≤ 5 %), "
                      "not at the grid's top"),
})
#: Windows processed per FFT batch (bounds memory: 512 windows of 128² complex64 = 64 MB).
_BATCH = 512


def _gradient_field(gray):
    g = np.asarray(gray, dtype=np.float32)
    gx = g[:-1, 1:] - g[:-1, :-1]
    gy = g[1:, :-1] - g[:-1, :-1]
    return gx + 1j * gy  # one complex FFT per window gives |Gx|² + |Gy|² summed over ±k (ring sums)


def _window_starts(centres, n, size):
    return np.clip(centres - n // 2, 0, size - n)


def _ring_powers(z, ys, xs, n):
    """Ring-summed periodograms (len(ys), B) of the n×n Hann windows of z starting at (ys, xs)."""
    win = hann_window(n).astype(np.float32)
    onehot = ring_matrix(n)
    view = sliding_window_view(z, (n, n))
    out = np.empty((len(ys), onehot.shape[1]), dtype=np.float32)
    batch = max(1, (_BATCH * 64 * 64) // (n * n))
    for i in range(0, len(ys), batch):
        patches = view[ys[i:i + batch], xs[i:i + batch]] * win
        f = scipy.fft.fft2(patches, axes=(-2, -1), overwrite_x=True)
        p = (f.real ** 2 + f.imag ** 2).reshape(len(patches), -1)
        out[i:i + batch] = p @ onehot
    return out


def _profile_nll(P, A, N, kappa, *, iters=3, likelihood="profile"):
    """NLL of the Gamma model M = s·A + N with s maximised (or marginalised), per window and σ.

    P (n, B) ring powers, A (1 or n, G, B) per-σ signal tables, N (n, B) noise, kappa (B,).
    Returns (nll (n, G) to minimise, s (n, G), profile nll (n, G)).
    """
    Pn = P[:, None, :]
    Nn = N[:, None, :]
    # start: weighted least squares of P − N ≈ s·A with weights κ/P² (closed form), then Newton
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        wgt = kappa / np.maximum(Pn, np.float32(1e-15)) ** 2
        s = np.sum(wgt * A * (Pn - Nn), -1) / np.sum(wgt * A * A, -1)
    s = np.where(np.isfinite(s), s, 0.0)
    s = np.maximum(s, 1e-6 * np.sum(Nn, -1) / np.maximum(np.sum(A, -1), 1e-30))
    for _ in range(iters):  # Newton on the score in s, kept > 0
        M = s[..., None] * A + Nn
        am = A / M
        r = Pn / M
        g = np.sum(kappa * am * (1.0 - r), -1)
        h = np.sum(kappa * am * am * (2.0 * r - 1.0), -1)
        step = np.where(h > 0, g / np.where(h > 0, h, 1.0), 0.0)
        s = np.clip(s - step, 0.1 * s, 10.0 * s)
    M = s[..., None] * A + Nn
    nll = np.sum(kappa * (Pn / M + np.log(M)), -1)
    if likelihood == "gsm":  # s marginalised under a log-uniform mixture prior (Laplace, in log s)
        return nll + 0.5 * np.log(np.maximum(np.sum(kappa * (s[..., None] * A / M) ** 2, -1), 1e-30)), s, nll
    return nll, s, nll


#: The final pass searches σ within [σ̂_c / COARSE_RANGE − 0.5, σ̂_c · COARSE_RANGE + 0.5] px of the
#: coarse pass's 3×3 median σ̂_c (the disk's likelihood is multimodal: its transfer function has zeros).
COARSE_RANGE = 1.6
#: The grid search evaluates every COARSE_STEP-th σ of the grid, then all σ within ±COARSE_STEP
#: grid steps of the coarse minimum.
COARSE_STEP = 3


def _fit(P, A, N, kappa, *, likelihood="profile", allowed=None):
    """Grid maximum likelihood of σ (coarse, then fine around the minimum) for each window.

    ``allowed`` (n, G) bool or None: the grid σ each window may take (the others get +inf NLL).

    Returns (j, s, nll_fine, j_fine_idx, lr): best grid index, its ŝ, the fine NLL (n, F) at grid
    indices j_fine_idx (n, F), and the log-likelihood ratio 2·(L_noise − L_fit) of the profile
    likelihood at the chosen σ (for both likelihoods).
    """
    n, B = P.shape
    G = A.shape[0]
    coarse = np.arange(0, G, COARSE_STEP)
    nll_c, _, _ = _profile_nll(P, A[coarse][None], N, kappa, likelihood=likelihood)
    rows = np.arange(n)
    if allowed is not None:
        nll_c = np.where(allowed[:, coarse], nll_c, np.inf)
    jc = coarse[np.argmin(nll_c, 1)]
    offs = np.arange(-COARSE_STEP, COARSE_STEP + 1)
    jf = np.clip(jc[:, None] + offs[None], 0, G - 1)  # (n, F) (duplicates at the ends are harmless)
    nll_f, s_f, prof_f = _profile_nll(P, A[jf], N, kappa, likelihood=likelihood)
    if allowed is not None:
        nll_f = np.where(allowed[rows[:, None], jf], nll_f, np.inf)
    k = np.argmin(nll_f, 1)
    nll0 = np.sum(kappa * (P / N + np.log(N)), -1)
    return jf[rows, k], s_f[rows, k], nll_f, jf, 2.0 * (nll0 - prof_f[rows, k])


def _refine(grid, nll_f, jf, j):
    """Parabolic vertex through the NLL at grid indices j−1, j, j+1 (from the fine search), px."""
    G = len(grid)
    rows = np.arange(len(j))

    def at(idx):  # NLL at grid index idx (inside the fine window by construction)
        col = np.argmax(jf == idx[:, None], axis=1)
        return nll_f[rows, col]

    jm = np.clip(j - 1, 0, G - 3)
    x0, x1, x2 = grid[jm], grid[jm + 1], grid[jm + 2]
    y0, y1, y2 = at(jm), at(jm + 1), at(jm + 2)
    d01 = (y1 - y0) / (x1 - x0)
    d12 = (y2 - y1) / (x2 - x1)
    curv = (d12 - d01) / (x2 - x0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = 0.5 * (x0 + x1) - d01 / (2.0 * curv)
    inner = (j > 0) & (j < G - 1) & (curv > 0) & np.isfinite(v)
    return np.where(inner, np.clip(v, grid[np.maximum(j - 1, 0)], grid[np.minimum(j + 1, G - 1)]), grid[j])


def _model_at(sig, s, grid, A, dA, N):
    """(a, da, M): A and dA interpolated linearly in σ at σ̂, and the expected powers M = ŝ·a + N."""
    G = len(grid)
    k = np.clip(np.searchsorted(grid, sig) - 1, 0, G - 2)
    t = ((sig - grid[k]) / (grid[k + 1] - grid[k]))[:, None]
    a = (1 - t) * A[k] + t * A[k + 1]
    da = (1 - t) * dA[k] + t * dA[k + 1]
    return a, da, s[:, None] * a + N


def _deviance(P, M, kappa):
    """Mean Gamma deviance per band, 2·Σ κ_b (P_b/M_b − ln(P_b/M_b) − 1) / B: ≈ 1 when the model fits."""
    r = np.maximum(P, 1e-30) / M
    return 2.0 * np.sum(kappa * (r - np.log(r) - 1.0), -1) / P.shape[-1]


def _information(sig, s, grid, A, dA, N, kappa):
    """Fisher information of σ (s profiled), 1/px², at (σ̂, ŝ) with A, dA interpolated in σ."""
    a, da, M = _model_at(sig, s, grid, A, dA, N)
    i_ss = np.sum(kappa * (a / M) ** 2, -1)
    i_sg = np.sum(kappa * a * s[:, None] * da / M ** 2, -1)
    i_gg = np.sum(kappa * (s[:, None] * da / M) ** 2, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        info = i_gg - i_sg ** 2 / i_ss
    return np.where(np.isfinite(info) & (info > 0), info, 0.0)


#: Quantile of the windows' ring powers read as the image's own noise floor (noise_model "spectrum").
SPECTRUM_QUANTILE = 0.05


def _noise_rings(P, v_white, Nunit, model):
    """Per-window noise ring powers (n, B) for the chosen noise model."""
    white = v_white * Nunit
    if model != "white":
        # the image's own noise floor: per ring, a low quantile of the windows' powers (the windows
        # whose spectrum there is noise), never below the quantisation floor
        floor = np.quantile(P, SPECTRUM_QUANTILE, axis=0) if P.shape[0] >= 20 else np.min(P, axis=0)
        spec = np.maximum(floor, (LSB ** 2 / 12.0) * Nunit)
        white = spec if model == "spectrum" else np.minimum(spec, white)
    return np.ascontiguousarray(np.broadcast_to(white.astype(np.float32), P.shape))


def _nan_median3(a):
    """NaN-aware 3×3 median of a 2-D grid (edges replicated); NaN where all nine are NaN."""
    p = np.pad(a, 1, mode="edge")
    v = sliding_window_view(p, (3, 3)).reshape(a.shape + (9,))
    v = np.sort(v, axis=-1)  # NaN sort last
    cnt = np.sum(np.isfinite(v), axis=-1)
    idx = np.maximum(cnt - 1, 0) // 2
    out = np.take_along_axis(v, idx[..., None], -1)[..., 0]
    return np.where(cnt > 0, out, np.nan)


def local_spectrum_grid(gray, *, psf="gaussian", noise_model="white", sigma_min=0.0, sigma_max=12.0,
                        window_min=16, window_max=96, window_scale=12.0, stride=32, noise_variance=None,
                        likelihood="profile", gate=AdequacyGate()):
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
        log-uniform scale-mixture prior (:mod:`method.blur.gsm`).
    gate : AdequacyGate, keyword-only
        Which fits are measures beyond the noise test (default: all; :data:`REGION_GATES`).

    Returns
    -------
    dict
        ``cy``, ``cx`` (ny,), (nx,) centre rows / columns, px; ``sigma`` (ny, nx) px, NaN without a
        measure; ``information`` (ny, nx) 1/px², 0 without a measure; ``window`` (ny, nx) side used, px
        (0 where none fits); ``noise_variance`` float; ``deviance`` (ny, nx) the fit's mean Gamma
        deviance per band (NaN without a measure).
    """
    g = np.asarray(gray, dtype=np.float64)
    H, W = g.shape
    v = estimate_noise_variance(g) if noise_variance is None else float(noise_variance)
    cy = np.arange(stride // 2, H, stride)
    cx = np.arange(stride // 2, W, stride)
    ny, nx = len(cy), len(cx)
    sigma = np.full((ny, nx), np.nan)
    info = np.zeros((ny, nx))
    wins = np.zeros((ny, nx), dtype=np.int64)
    deviance = np.full((ny, nx), np.nan)
    out = dict(cy=cy, cx=cx, sigma=sigma, information=info, window=wins, noise_variance=v, deviance=deviance)
    z = _gradient_field(g)
    hz, wz = z.shape
    sizes = [s for s in WINDOW_SIZES if window_min <= s <= window_max and s <= min(hz, wz)]
    if not sizes:
        return out
    grid = tuple(float(x) for x in sigma_grid(sigma_min, sigma_max, psf))
    garr = np.asarray(grid)
    yy, xx = np.meshgrid(cy, cx, indexing="ij")
    yy, xx = yy.ravel(), xx.ravel()

    def run(n, idx, prior=None, gated=True):
        A, dA, Nu, kappa = model_tables(n, psf, grid)
        P = _ring_powers(z, _window_starts(yy[idx], n, hz), _window_starts(xx[idx], n, wz), n)
        N = _noise_rings(P, v, Nu, noise_model)
        allowed = None
        if prior is not None:  # σ within a factor COARSE_RANGE of the neighbourhood's coarse σ̂
            p = prior[idx][:, None]
            allowed = ~np.isfinite(p) | ((garr[None] >= p / COARSE_RANGE - 0.5) & (garr[None] <= p * COARSE_RANGE + 0.5))
        j, s, nll_f, jf, lr = _fit(P, A.astype(np.float32), N, kappa.astype(np.float32), likelihood=likelihood,
                                   allowed=allowed)
        sig = _refine(garr, nll_f.astype(np.float64), jf, j)
        s64, n64 = s.astype(np.float64), N.astype(np.float64)
        inf = _information(sig, s64, garr, A, dA, n64, kappa)
        dev = _deviance(P.astype(np.float64), _model_at(sig, s64, garr, A, dA, n64)[2], kappa)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel_std = 1.0 / (sig * np.sqrt(inf))
        ok = (lr > MIN_LOG_LR) & (inf > 0)
        if gated:  # the coarse pass only chooses window sizes: every fit above the noise counts there
            ok &= (dev <= gate.max_deviance) & (rel_std <= gate.max_rel_std)
            if gate.top_margin > 1.0:
                ok &= sig < garr[-1] / gate.top_margin
        return np.where(ok, sig, np.nan), np.where(ok, inf, 0.0), np.where(ok, dev, np.nan)

    # coarse pass on every other centre, then each centre's window from its coarse σ̂ (3×3 median)
    n0 = min(sizes, key=lambda s: abs(s - COARSE_WINDOW))
    sub = (slice(None, None, 2), slice(None, None, 2))
    idx0 = np.arange(ny * nx).reshape(ny, nx)[sub].ravel()
    s0, _, _ = run(n0, idx0, gated=False)
    coarse_sub = _nan_median3(s0.reshape(np.arange(ny * nx).reshape(ny, nx)[sub].shape))
    coarse = np.repeat(np.repeat(coarse_sub, 2, 0), 2, 1)[:ny, :nx].ravel()
    want = np.where(np.isfinite(coarse), window_scale * coarse, sizes[0])
    size_arr = np.asarray(sizes)
    choice = size_arr[np.minimum(np.searchsorted(size_arr, want), len(sizes) - 1)]
    res_s = np.full(ny * nx, np.nan)
    res_i = np.zeros(ny * nx)
    res_d = np.full(ny * nx, np.nan)
    iy, ix = np.divmod(np.arange(ny * nx), nx)

    def final_pass(which, prior):
        for n in sizes:
            sel = which[choice[which] == n]
            if not sel.size:
                continue
            f = max(1, n // (2 * stride))  # windows ≥ 2·stride: one measure per f×f centres (≥ 50 % overlap)
            if f == 1:
                res_s[sel], res_i[sel], res_d[sel] = run(n, sel, prior)
                continue
            rep = np.minimum(iy[sel] // f * f + f // 2, ny - 1) * nx + np.minimum(ix[sel] // f * f + f // 2, nx - 1)
            uniq, inv = np.unique(rep, return_inverse=True)
            s_u, i_u, d_u = run(n, uniq, prior)
            res_s[sel], res_i[sel], res_d[sel] = s_u[inv], i_u[inv], d_u[inv]

    final_pass(np.arange(ny * nx), coarse)
    # one more pass where the final σ̂ (3×3 median) asks for a larger window than the coarse one gave
    # (a 32-px window under-reads σ ≳ 4, most of all for the disk)
    again = _nan_median3(res_s.reshape(ny, nx)).ravel()
    want2 = np.where(np.isfinite(again), window_scale * again, 0.0)
    choice2 = size_arr[np.minimum(np.searchsorted(size_arr, want2), len(sizes) - 1)]
    grow = np.flatnonzero(choice2 > choice)
    if grow.size:
        choice[grow] = choice2[grow]
        final_pass(grow, again)
    sigma[:] = res_s.reshape(ny, nx)
    info[:] = res_i.reshape(ny, nx)
    wins[:] = choice.reshape(ny, nx)
    deviance[:] = res_d.reshape(ny, nx)
    return out


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
    params : RegionParams or DefocusParams, keyword-only
        Uses ``region_psf``, ``region_noise_model``, ``region_gate``, ``region_sigma_min`` / ``region_sigma_max``,
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
    2. Noise variance v from the quietest 8×8 blocks of 3×3 second differences
       (:func:`estimate_noise_variance`), at least the 8-bit quantisation's LSB²/12 (``noise_model="white"``); or per ring the 5 % quantile of all windows'
       powers (``"spectrum"``, the image's own noise floor; ``"spectrum_or_white"`` the smaller).
    3. Hann windows on a grid of centres (stride px); per window the ring sums P_b of the periodogram.
    4. Model E P_b = s·A_b(σ) + N_b, A_b = Σ_ring (|H_σ|² Q ⊛ |Ŵ|²), computed exactly through the
       autocorrelations (window × field) at integer lags; ring sums Gamma(κ_b) distributed, κ_b the
       ring's bins / the window's variance inflation.
    5. Maximum likelihood: per σ of the grid, s by Newton steps on the profile score; the grid
       minimum refined by a parabola; "no measure" when 2·(L_noise − L_fit) < MIN_LOG_LR, and with
       ``params.region_gate`` "adequacy" also where the model does not fit the window's spectrum
       (mean Gamma deviance per band > 2: periodic texture, text), where σ̂ is not pinned down
       (relative std 1/(σ̂√I) > 5 %: shading, lone edges) or where σ̂ is at the grid's top.
    6. Information: I_σσ − I_σs²/I_ss of the Gamma model at (σ̂, ŝ).
    7. Multi-window: a coarse 32-px pass on every other centre; each centre then uses the smallest
       window of WINDOW_SIZES ≥ window_scale · σ̂ (3×3 median of the coarse σ̂), within
       [window_min, window_max], searching σ within COARSE_RANGE of σ̂; a window of n ≥ 2·stride px
       is evaluated once per ⌊n/(2·stride)⌋² centres (they still overlap by ≥ 50 %); where the
       result's 3×3 median asks for a larger window, that centre is measured once more with it.
    8. Spread to pixels by bilinear interpolation of the centres' values.
    """
    psf = params.region_psf
    if psf == "edges":
        psf = edge_psf if edge_psf is not None else "gaussian"
    PSF_MODELS.check(psf, what="edge_psf")
    g = np.asarray(gray, dtype=np.float64)
    out = local_spectrum_grid(g, psf=psf, noise_model=params.region_noise_model,
                              sigma_min=params.region_sigma_min, sigma_max=params.region_sigma_max,
                              window_min=params.region_window_min, window_max=params.region_window_max,
                              window_scale=params.region_window_scale, stride=params.region_stride,
                              gate=REGION_GATES[params.region_gate])
    sigma, info = spread_to_pixels(out, g.shape)
    return sigma, info / float(params.region_stride) ** 2
