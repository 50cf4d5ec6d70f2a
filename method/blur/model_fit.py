"""Blur at edge pixels by fitting the 2nd-derivative response model (Sec. 3.2, Eq. 2; the paper's estimator).

Across a step of amplitude A blurred by σb, the response to the 2nd-derivative filter at scale σ2 is
(Eq. 2c, 2d)

    r(t) = −A·t / (√(2π)·s³) · exp(−t² / (2 s²)),    s = d/2,   s² = σb² + σ2²,

with t the signed distance from the edge along the gradient direction; d is the distance between
its two extrema. The paper fits this model by brute force over d to the responses in a window
around the edge pixel, along the gradient direction, using both the bright and the dark side.

Beyond the paper, ``DefocusParams.fit_psf`` (:data:`FIT_PSF_MODELS`) can also fit, on the same
window and with the same search, the response of a step blurred by a uniform disk — a thin lens's
defocus, :mod:`method.blur.disk_edge_response` — whose second moment gives σb through the same Eq. (2d).

The templates and the numba search are in :mod:`method.blur.fit_templates`; the choice between the
two models (``fit_psf``) in :mod:`method.blur.psf_selection`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .disk_edge_response import response_table
from .fit_templates import (COARSE_STRIDE, EMPTY_DISK_TABLE, FIT_KAPPA, S_GRID_RATIO, T0_GRID_STEP,
                            blur_from_extrema_distance, response_model, run_fit_kernel, template_table)
from .psf_selection import PSF_SELECT_MIN_EDGES, choose_psf, psf_selection_sample, select_psf_model
from ..edges.elder_zucker import check_edge_inputs, edge_pixels_by_scale
from ..edges.gaussian_derivatives import GaussianDerivativeBank
from ..registry import Registry

__all__ = [
    "COARSE_STRIDE",
    "FIT_KAPPA",
    "FIT_PSF_MODELS",
    "PSF_SELECT_MIN_EDGES",
    "S_GRID_RATIO",
    "T0_GRID_STEP",
    "apply_fit_rules",
    "blur_from_extrema_distance",
    "estimate_blur_model_fit",
    "estimate_blur_model_fit_psf",
    "fit_scales",
    "model_fit_diagnostics",
    "paper_rules",
    "response_model",
    "select_psf_model",
]


#: The edge-blur models the fit can use (``DefocusParams.fit_psf``): name -> what it fits.
FIT_PSF_MODELS = Registry("fit PSF model", {
    "gaussian": "Eq. (2c): a Gaussian-blurred step (the paper)",
    "disk": "a step blurred by a uniform disk, the thin lens's defocus (method.blur.disk_edge_response)",
    "best": "both on the same window; per edge pixel the one with the smaller residual",
    "auto": "both on the same window; one model for the whole image (select_psf_model)",
})


def estimate_blur_model_fit(gray, edge_map, *, params):
    """Blur σb at edge pixels by least-squares fit of Eq. (2c) (Sec. 3.2, the paper's method).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to :func:`method.edges.elder_zucker.detect_edges`).
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges(gray, ...)``.
    params : DefocusParams, keyword-only
        Uses ``fit_window_min``, ``fit_window_max`` (window lengths, px) and ``max_sigma``.

    Returns
    -------
    ndarray, shape (H, W), float64
        σb in px at edge pixels, clipped to [0, max_sigma]; NaN elsewhere and where the fit fails
        (fewer than 3 samples inside the image, or no positive-amplitude fit).

    Notes
    -----
    Per edge pixel p (vectorised over all edge pixels of one σ2 in a numba kernel):

    0. The 2nd-derivative responses at each σ2 come from ``edge_map.hessians`` when the detector
       kept them (``detect_edges(..., keep_hessians=True)``, as the pipeline does), else from a
       single-precision FFT bank (:class:`~method.edges.gaussian_derivatives.GaussianDerivativeBank`) set
       up like the detector's (largest σ of ``params.sigma1_scales``/``sigma2_scales``, hence the
       same padding), so both paths give bit-identical responses.
    1. Sampling along θ: r(k) = ∂²_θ I at σ2(p) (Eq. 8d, steered with θ(p)) at the pixels
       p + k·e, k = −K…K, where e is the one-pixel step along the image axis closest to θ. These
       are exact filter outputs (no interpolation). Along that axis a straight edge is crossed at
       t = k·proj with proj = max(|cos θ|, |sin θ|), so r(k) ∝ m_{s'}(k − k0) with s' = s/proj:
       the same model, in sampling steps.
    2. Sub-pixel edge position k0 from the linear zero crossing of r(−1), r(0), r(1).
    3. Window: walk outward to the first discrete local maximum (dark side, k < 0) and minimum
       (bright side, k > 0) of r; half-width = ⌈FIT_KAPPA · farther extremum⌉, clipped to
       [(fit_window_min − 1)/2, (fit_window_max − 1)/2] (the paper's 3…71 px windows; they grow
       with the response width s ≥ σ2, i.e. with scale) and to the image. On each side the window
       also stops where |r| stops decaying past the extremum (first local minimum of |r| or sign
       change): beyond it a neighbouring edge's response dominates. Both sides are used.
    4. Brute force over d = 2s (Eq. 2c): templates m_{s'}(k − t0) on a geometric s' grid (ratio
       :data:`S_GRID_RATIO`) × a t0 grid (step :data:`T0_GRID_STEP`): a coarse pass over s'
       (every :data:`COARSE_STRIDE`-th value) at the t0 nearest k0, then a fine pass by coordinate
       descent (s', then t0 within ±0.2 steps, then s' again).
       For each template the amplitude A is the closed-form least-squares value
       A = (r·m)/(m·m) (constrained A > 0), so the squared error is ‖r‖² − (r·m)²/(m·m). We use
       the least-squares A rather than "A from the local extrema" because it uses every sample of
       the window (less noise) and does not depend on locating the extrema — the step the paper
       says is unreliable; for a clean edge both give the same A.
    5. Parabolic refinement of the error over log s'; s = s'·proj; σb = √(s² − σ2²) (Eq. 2d),
       clipped to [0, max_sigma].
    6. Beyond the paper, ``params.fit_psf`` ≠ "gaussian": steps 4–5 again with the disk-blurred
       templates at filter scale σ' = σ2/proj, the coarse pass limited to s' within [s'_G/2,
       1.25 s'_G] of the Gaussian optimum s'_G; "disk" keeps those fits, "best" the smaller
       residual per edge, "auto" one model per image (:func:`select_psf_model`, decided on a sample
       of at most :data:`PSF_SELECT_SAMPLE` resolved edges; the disk is then fitted on the rest).
    """
    if paper_rules(params):
        return _model_fit_with_residual(gray, edge_map, params=params)[0]
    return apply_fit_rules(model_fit_diagnostics(gray, edge_map, params=params), params=params)


def estimate_blur_model_fit_psf(gray, edge_map, *, params):
    """:func:`estimate_blur_model_fit` plus, from the same fit, which measures used the disk model.

    Returns
    -------
    sigma_b : ndarray, shape (H, W), float64
        Identical to :func:`estimate_blur_model_fit`.
    psf_disk : ndarray, shape (H, W), bool
        True at the measures (finite ``sigma_b``) fitted with the disk-blurred step
        (``params.fit_psf``); False elsewhere (all False for ``fit_psf="gaussian"``, the paper).
    """
    diagnostics = model_fit_diagnostics(gray, edge_map, params=params)
    sigma_b = apply_fit_rules(diagnostics, params=params)
    return sigma_b, diagnostics["disk"] & np.isfinite(sigma_b)


def paper_rules(params) -> bool:
    """True when every beyond-the-paper model-fit switch of ``params`` is off."""
    return (params.fit_max_scale is None and params.fit_min_samples <= 3 and params.fit_scale_ratio == 1.0
            and not np.isfinite(params.fit_max_width_ratio) and params.fit_below_scale == "zero")


def apply_fit_rules(diagnostics, *, params) -> np.ndarray:
    """σb of the model fit with the beyond-the-paper plausibility rules of ``params`` applied.

    Parameters
    ----------
    diagnostics : dict of ndarray, (H, W)
        Output of :func:`model_fit_diagnostics` (``sigma_b``, ``window``, ``width``, ``sigma2``).
    params : DefocusParams, keyword-only
        ``fit_min_samples`` (samples), ``fit_max_width_ratio`` (dimensionless),
        ``fit_below_scale`` ("zero" | "nan") and ``sigma2_scales`` (px).

    Returns
    -------
    ndarray, (H, W), float64
        σb, px; NaN where a rule rejects the fit ("no measure").

    Notes
    -----
    1. ``fit_min_samples``: fewer samples than this in the fit window → NaN (with 3 samples the
       two-parameter fit (s, t0) is exactly determined and noise alone can give any width).
    2. ``fit_max_width_ratio``: a fitted width s = d/2 above this fraction of the window's
       half-length extrapolates the model beyond the samples → NaN.
    3. ``fit_below_scale="nan"``: d/2 ≤ σ2 means the blur is below what σ2 resolves; at the
       finest σ2 that is a sharp edge (σb = 0 is kept), at a coarser σ2 it is no measure (NaN)
       instead of the paper's σb = 0.
    """
    sb = np.array(diagnostics["sigma_b"], dtype=np.float64, copy=True)
    win = diagnostics["window"]
    width = diagnostics["width"]
    s2 = diagnostics["sigma2"]
    with np.errstate(invalid="ignore"):
        bad = win < int(params.fit_min_samples)
        ratio = float(params.fit_max_width_ratio)
        if np.isfinite(ratio):
            bad |= width > ratio * 0.5 * (win - 1)
        if params.fit_below_scale == "nan":
            bad |= (width <= s2) & (s2 > min(params.sigma2_scales))
    sb[bad & np.isfinite(sb)] = np.nan
    return sb


def fit_scales(edge_map, *, params):
    """``edge_map`` with σ2 replaced by the scale the Eq. (2c) fit samples (beyond-the-paper rules).

    Parameters
    ----------
    edge_map : EdgeMap
        Output of ``detect_edges``; ``sigma2`` (px) is each edge pixel's minimum reliable σ2.
    params : DefocusParams, keyword-only
        ``fit_scale_ratio`` (dimensionless), ``fit_max_scale`` (px or None), ``sigma2_scales`` (px).

    Returns
    -------
    EdgeMap
        ``edge_map`` itself when both rules are off (the paper: fit at σ2(p)); else a copy whose
        σ2 is min(σ2(p), max(fit_scale_ratio · σ2(p), min(sigma2_scales)), fit_max_scale).
    """
    ratio = float(params.fit_scale_ratio)
    max_scale = params.fit_max_scale
    if ratio == 1.0 and max_scale is None:
        return edge_map
    s2 = np.asarray(edge_map.sigma2)
    with np.errstate(invalid="ignore"):
        fit = s2 if ratio == 1.0 else np.minimum(s2, np.maximum(ratio * s2, min(params.sigma2_scales)))
        if max_scale is not None:
            fit = np.minimum(fit, float(max_scale))
    return dataclasses.replace(edge_map, sigma2=np.where(np.isfinite(s2), fit, s2))


def _model_fit_with_residual(gray, edge_map, *, params):
    """Private hook: :func:`estimate_blur_model_fit`'s σb map plus the normalised fit residual.

    Returns
    -------
    sigma_b, residual : ndarray, shape (H, W), float64
        See :func:`model_fit_diagnostics`.
    """
    d = model_fit_diagnostics(gray, edge_map, params=params)
    return d["sigma_b"], d["residual"]


def model_fit_diagnostics(gray, edge_map, *, params, groups=None):
    """Private hook: :func:`estimate_blur_model_fit`'s σb map plus per-pixel fit diagnostics.

    ``groups`` (list of (σ2 px, rows, cols), as :func:`~method.edges.elder_zucker.pixels_by_scale`
    gives them; None: the edge pixels of ``edge_map`` at their :func:`fit_scales` σ2) are the pixels
    fitted and the scale of each (``fit_max_scale`` and ``fit_scale_ratio`` then do not apply).

    Returns
    -------
    dict of ndarray, shape (H, W)
    sigma_b : float64
        Exactly the output of :func:`estimate_blur_model_fit` (same code path), px.
    residual : float64
        ρ = (‖r‖² − (r·m)²/(m·m)) / ‖r‖² of the best grid template m of Eq. (2c) over the fit
        window (dimensionless, in [0, 1]; 1 − ρ is the squared normalised correlation); NaN where
        σb is NaN or off edges.
    window : int64
        Number of response samples in the fit window (0 off edges and where the fit failed).
    width : float64
        Fitted model width s = d/2 = √(σb² + σ2²) before Eq. (2d), px; NaN off edges / failed fits.
    sigma2 : float64
        The σ2 of the responses that were fitted (the edge's minimum reliable σ2), px; NaN off edges.
    energy : float64
        ‖r‖² of the sampled response over the fit window, (image units / px²)²; NaN where σb is NaN.
    """
    img = check_edge_inputs(gray, edge_map)
    w_min = (int(params.fit_window_min) - 1) // 2
    w_max = (int(params.fit_window_max) - 1) // 2
    w_min = max(1, w_min)
    out = np.full(img.shape, np.nan)
    res = np.full(img.shape, np.nan)
    win = np.zeros(img.shape, dtype=np.int64)
    width = np.full(img.shape, np.nan)
    s2_map = np.full(img.shape, np.nan)
    energy = np.full(img.shape, np.nan)
    diag = {"sigma_b": out, "residual": res, "window": win, "width": width, "sigma2": s2_map,
            "energy": energy, "disk": np.zeros(img.shape, dtype=bool)}
    psf = params.fit_psf
    FIT_PSF_MODELS.check(psf, what="fit_psf")
    disk_table = response_table() if psf != "gaussian" else EMPTY_DISK_TABLE
    disk_width = np.full(img.shape, np.nan) if psf != "gaussian" else None
    disk_res = np.full(img.shape, np.nan) if psf != "gaussian" else None
    if groups is None:
        edge_map = fit_scales(edge_map, params=params)
        groups = edge_pixels_by_scale(edge_map)
    if not groups:
        return diag
    s_max = math.sqrt(float(params.max_sigma) ** 2 + max(g[0] for g in groups) ** 2) * math.sqrt(2.0)
    templates = template_table(w_max, float(np.float32(max(s_max, 1.0))))
    cached = edge_map.hessians or {}
    bank = None
    theta = np.asarray(edge_map.theta, dtype=np.float64)
    # "disk" and "best" fit the disk model on every edge in the same pass; "auto" fits it first on a
    # sample of the edges that can decide (select_psf_model), and on all edges only if it chose it;
    # "gaussian" (the paper) keeps no disk state
    first_min_width = 0.0 if psf in ("disk", "best") else -1.0
    fitted = []
    for sigma2, rows, cols in groups:
        if sigma2 in cached:
            ixx, ixy, iyy = cached[sigma2]
        else:
            if bank is None:  # the detector's bank: same padding levels, so the same responses
                bank = GaussianDerivativeBank(
                    img, max(max(params.sigma1_scales), max(params.sigma2_scales), groups[-1][0]),
                    precision="single")
            ixx, ixy, iyy = bank.hessian(sigma2)
        th = theta[rows, cols]
        s_est, r_est, w_est, e_est, sd_est, rd_est = run_fit_kernel(
            (ixx, ixy, iyy), rows, cols, th, w_min, w_max, templates, sigma2,
            first_min_width, disk_table)
        sigma_b = blur_from_extrema_distance(2.0 * s_est, sigma2)
        out[rows, cols] = np.clip(sigma_b, 0.0, float(params.max_sigma))
        res[rows, cols] = r_est
        win[rows, cols] = w_est
        width[rows, cols] = s_est
        energy[rows, cols] = e_est
        s2_map[rows, cols] = sigma2
        if psf != "gaussian":
            disk_width[rows, cols] = sd_est
            disk_res[rows, cols] = rd_est
        if psf == "auto":
            fitted.append((sigma2, rows, cols, th, (ixx, ixy, iyy)))

    def fit_disk(select):  # disk fits on the edge pixels where select(group's rows, cols) is True
        for sigma2, rows, cols, th, hessian in fitted:
            sel = select(rows, cols)
            if sel.any():
                rr, cc = rows[sel], cols[sel]
                *_, sd_est, rd_est = run_fit_kernel(hessian, rr, cc, th[sel], w_min, w_max,
                                                     templates, sigma2, 0.0, disk_table)
                disk_width[rr, cc] = sd_est
                disk_res[rr, cc] = rd_est

    if psf == "auto":  # decided on the fitted pixels (all in the groups), in raster order as on the image
        flat = np.sort(np.concatenate([rows * img.shape[1] + cols for _, rows, cols in groups]))
        fits = {name: diag[name].ravel()[flat] for name in ("residual", "width", "sigma2")}
        sample = np.zeros(img.shape, dtype=bool)
        sample.ravel()[flat] = psf_selection_sample(fits["width"], fits["sigma2"])
        fit_disk(lambda rr, cc: sample[rr, cc])
        if select_psf_model(fits, disk_width.ravel()[flat], disk_res.ravel()[flat]) == "disk":
            fit_disk(lambda rr, cc: np.isfinite(width[rr, cc]) & ~np.isfinite(disk_width[rr, cc]))
            choose_psf(diag, disk_width, disk_res, psf="disk", max_sigma=float(params.max_sigma))
    elif psf in ("disk", "best"):
        choose_psf(diag, disk_width, disk_res, psf=psf, max_sigma=float(params.max_sigma))
    return diag

