"""The model fit's scale and window following a coarse estimate of the blur (beyond the paper).

The robust preset fits Eq. (2c) at a filter scale σ2 capped at ``fit_max_scale`` (fine scales see
fewer neighbouring texture edges). A very blurry edge seen at a fine σ2 has a weak, wide
2nd-derivative response whose extrema noise displaces towards the edge: the fit window walks to a
noise extremum, the fitted width is too small or the fit is declined (an isolated disk step of
σ 8 px at σ2 = 2 px: 59 % of its edge pixels measured, median −4.9 px; docs/presets.md). The paper's
fit at the detector's own σ2(p) sees such an edge well but over-estimates σb where σ2 approaches σb
(Eq. 2d) and where the wide window spans neighbouring edges. :func:`follow_scale_diagnostics`
lets the scale follow the blur: a coarse fit at σ2(p) picks the scale, a re-fit there measures.
"""

from __future__ import annotations

import math

import numpy as np

from .fit_templates import FIT_KAPPA
from ..edges.elder_zucker import pixels_by_scale
from .model_fit import model_fit_diagnostics

__all__ = ["FOLLOW_WINDOW_SPAN", "follow_scale_diagnostics", "follow_window_max"]

#: Extremum distance of the re-fit's response, in units of the blur σb it was chosen for: a disk of
#: diameter 4σb has its response extrema near its rim (±2σb), a Gaussian near ±√(σb² + σ2²); 2.5
#: leaves room for both and for the coarse estimate's error.
FOLLOW_WINDOW_SPAN = 2.5


def follow_window_max(sigma2, ratio, window_max) -> int:
    """Largest fit window of the re-fit at scale σ2 chosen by ``ratio``, px (odd).

    Parameters
    ----------
    sigma2 : float
        The re-fit's filter scale, px.
    ratio : float
        ``fit_follow_scale`` (σ2 / σ̂, dimensionless): the re-fit is meant for σb ≈ σ2 / ratio.
    window_max : int
        ``fit_window_max``, px: the window is never smaller than the first fit's.

    Returns
    -------
    int
        max(window_max, 2·⌈FIT_KAPPA · FOLLOW_WINDOW_SPAN · σ2 / ratio⌉ + 1), px: the window that holds
        both response lobes of a blur of σ2 / ratio and their tails (the walk to the extrema then
        decides the actual window, as in the first fit).
    """
    half = math.ceil(FIT_KAPPA * FOLLOW_WINDOW_SPAN * float(sigma2) / float(ratio))
    return max(int(window_max), 2 * half + 1)


def _groups(flat, sigma2, width):
    """The fit's pixel groups of the raster indices ``flat`` (ascending), fitted at ``sigma2`` (px, per pixel)."""
    rows, cols = np.divmod(flat, width)
    return pixels_by_scale(rows, cols, sigma2)


def _nearest_scale(values, scales):
    """The value of ``scales`` (px) nearest each of ``values`` (px) in log scale; NaN where not > 0.

    The values are the scales themselves (not exp(log(scale))), so the detector's responses at that
    scale (``EdgeMap.hessians``) serve the re-fit.
    """
    scales = np.asarray(sorted(scales), dtype=np.float64)
    grid = np.log(scales)
    values = np.asarray(values, dtype=np.float64)
    out = np.full(values.shape, np.nan)
    ok = np.isfinite(values) & (values > 0)  # the edge pixels only (values are NaN off edges)
    logv = np.log(values[ok])
    out[ok] = scales[np.argmin(np.abs(logv[:, None] - grid), axis=-1)]
    return out


def _fits(diag, rho_max):
    """Where the fit of ``diag`` has normalised residual ρ ≤ ``rho_max`` (all True for ``rho_max`` ≥ 1)."""
    if rho_max >= 1.0:
        return True
    with np.errstate(invalid="ignore"):
        return diag["residual"] <= rho_max


def follow_scale_diagnostics(gray, edge_map, *, params):
    """:func:`method.blur.model_fit.model_fit_diagnostics`, re-fitted at a scale that follows a coarse σ̂.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to the edge detector).
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 (px) from the detector.
    params : DefocusParams, keyword-only
        Everything the model fit uses, ``fit_follow_scale`` = r (dimensionless, in (0, 1], or None:
        the model fit's diagnostics unchanged) and ``fit_follow_max_residual`` = ρf (dimensionless,
        in [0, 1]; 1: no test).

    Returns
    -------
    dict of ndarray, shape (H, W)
        As :func:`~method.blur.model_fit.model_fit_diagnostics`; at the re-fitted edge pixels every
        entry (σb, ρ, window, width, σ2, energy, disk) is the re-fit's.

    Notes
    -----
    1. First fit, as without this option: at σf = min(σ2(p), ``fit_max_scale``) (and
       ``fit_scale_ratio``).
    2. Coarse estimate: the edge pixels whose detector scale σ2(p) exceeds σf are fitted at σ2(p)
       (the paper's scale), with the PSF model of ``fit_psf`` (``"auto"``: the disk where the first
       fit chose it for the image; else the coarse and the re-fitted edges choose, once per pass:
       resolved large blur shows the PSF's shape that the fine-scale fits may have too few edges
       to decide on) and a window up to :func:`follow_window_max` of σ2(p) → σ̂c.
    3. Scale: σ2* = the value of ``sigma2_scales`` nearest min(σ2(p), r·σ̂c) in log scale. Where
       σ2* > σf and the coarse fit's normalised residual ρc ≤ ρf (the coarse estimate is that of a
       blurred step: an isolated disk step of σ 8–16 px gives ρc ≤ 0.001, in-focus texture
       widened by neighbouring edges 0.03–0.24) the pixel is re-fitted at σ2* (window up to
       :func:`follow_window_max` of σ2*) → σ̂*, ρ*.
    4. The re-fit replaces the first fit where it measured, fits (ρ* ≤ ρf) and agrees that the
       blur is large: the scale nearest r·σ̂* is σ2* or coarser (the scale choice is a fixed
       point); elsewhere the first fit stays (so every edge the detector resolved at σ2(p) ≤ σf,
       and every edge whose coarse or re-fitted σ̂ is small or poorly fitted, keeps today's
       measure exactly).

    The plausibility rules and the residual test of the checked fit then apply to the merged
    diagnostics as to the first fit's. The coarse fit serves only to choose a scale: its own σ̂c is
    biased up where σ2(p) approaches σb (Eq. 2d) and where its wide window spans neighbouring edges.
    """
    diag = model_fit_diagnostics(gray, edge_map, params=params)
    ratio = params.fit_follow_scale
    if ratio is None:
        return diag
    ratio = float(ratio)
    # on the list of fitted edge pixels (raster order, as the edge map's groups), not the whole image
    width = diag["sigma2"].shape[1]
    fitted = np.flatnonzero(np.isfinite(diag["sigma2"]))
    s2_fit = diag["sigma2"].ravel()[fitted]
    s2_det = np.asarray(edge_map.sigma2, dtype=np.float64).ravel()[fitted]
    with np.errstate(invalid="ignore"):
        sel = np.asarray(edge_map.edges, dtype=bool).ravel()[fitted] & np.isfinite(s2_det) & (s2_det > s2_fit)
    if not sel.any():
        return diag
    flat, s2_det, s2_fit = fitted[sel], s2_det[sel], s2_fit[sel]
    psf = params.fit_psf
    if psf == "auto" and diag["disk"].any():  # the image's choice; else the re-fitted edges decide it
        psf = "disk"
    base = params.replace(fit_max_scale=None, fit_scale_ratio=1.0, fit_psf=psf)
    coarse = model_fit_diagnostics(
        gray, edge_map, groups=_groups(flat, s2_det, width),
        params=base.replace(fit_window_max=follow_window_max(np.max(s2_det), 1.0, params.fit_window_max)))
    coarse = {name: coarse[name].ravel()[flat] for name in ("sigma_b", "residual")}
    rho_max = float(params.fit_follow_max_residual)
    with np.errstate(invalid="ignore"):
        target = _nearest_scale(np.minimum(s2_det, ratio * coarse["sigma_b"]), params.sigma2_scales)
        sel = np.isfinite(target) & (target > s2_fit) & _fits(coarse, rho_max)
    if not sel.any():
        return diag
    flat, target = flat[sel], target[sel]
    fine = model_fit_diagnostics(
        gray, edge_map, groups=_groups(flat, target, width),
        params=base.replace(fit_window_max=follow_window_max(np.max(target), ratio, params.fit_window_max)))
    fine = {name: values.ravel()[flat] for name, values in fine.items()}
    with np.errstate(invalid="ignore"):
        keep = (_nearest_scale(ratio * fine["sigma_b"], params.sigma2_scales) >= target) & _fits(fine, rho_max)
    for name, values in diag.items():
        np.put(values, flat[keep], fine[name][keep])
    return diag
