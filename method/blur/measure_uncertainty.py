"""Each blur measure's own uncertainty: the standard deviation of σb from the Eq. (2c) fit (beyond the paper).

The model fit of Sec. 3.2 matches A·m_s(k) (Eq. 2c) to the sampled 2nd-derivative response r(k) of an
edge, with the amplitude A in closed form. Under noise of variance v per sample, the information that
the samples carry about the width s (A profiled out) is the curvature of the least-squares objective in
s over 2v: the Cramér–Rao bound

    Var(s) = v / (A² ‖P⊥ ∂m/∂s‖²),

P⊥ the projection off m (the amplitude's direction). This module evaluates it per measure from the fit's
own diagnostics (:func:`method.blur.model_fit.model_fit_diagnostics`) and the per-pixel noise variance,
carries it through Eq. (2d) to σb (:func:`measure_sd`) and turns it into the per-measure confidence of
Eq. (3) and Eq. (4) (:func:`uncertainty_confidence`) for ``DefocusParams.measure_weighting="uncertainty"``
(:data:`MEASURE_WEIGHTINGS`). Measurements: docs/presets.md.
"""

from __future__ import annotations

import numpy as np

from ..registry import Registry

__all__ = ["MEASURE_WEIGHTINGS", "UNCERTAINTY_MIN_CONFIDENCE", "measure_sd", "uncertainty_confidence",
           "width_information"]

#: ``DefocusParams.measure_weighting``: what gives each edge measure its confidence c_q in Eq. (3) and Eq. (4).
MEASURE_WEIGHTINGS = Registry("measure weighting", {
    "hand": "1, or relaxed_fit_weight for the measures admitted by the fit's noise allowance only",
    "uncertainty": "inverse variance of σb from the fit's residual and curvature under the noise "
                   "(method.blur.measure_uncertainty)",
})

#: Smallest confidence :func:`uncertainty_confidence` gives (Eq. 3 and Eq. 4 need c_q > 0).
UNCERTAINTY_MIN_CONFIDENCE = 1e-4
#: Below this g (:func:`width_information`) the window does not determine the width: g = 0, sd = inf.
_G_MIN = 1e-9


def width_information(width_samples, n_samples) -> np.ndarray:
    """g = s'² ‖P⊥ ∂m/∂s'‖² / ‖m‖² of the Eq. (2c) template on a window of ``n_samples`` unit-spaced samples.

    Parameters
    ----------
    width_samples : ndarray, any shape, float
        Template width s' in sampling steps (> 0; NaN gives NaN).
    n_samples : ndarray, same shape, int
        Samples in the fit window (centred on the edge; < 3 gives NaN).

    Returns
    -------
    ndarray, same shape, float64
        g, dimensionless: the relative information about s' per unit of the template's energy, so
        Var(s')/s'² = v / (g · A²‖m‖²). On an unbounded continuous window g = 3/2; truncation lowers it;
        0 where the window cannot tell the width from the amplitude (three centred samples).

    Notes
    -----
    m(k) = k·exp(−k²/(2s'²)) (Eq. 2c up to a factor A absorbs), ∂m/∂s' = m·(k²/s'² − 3)/s' for the
    normalised template, k = −(N−1)/2 … (N−1)/2. The edge position t0 is not a nuisance here: on a
    centred window ∂m/∂t0 is even and ∂m/∂s' odd, so they are orthogonal.
    """
    s = np.asarray(width_samples, dtype=np.float64)
    n = np.asarray(n_samples, dtype=np.float64)
    out = np.full(np.broadcast(s, n).shape, np.nan)
    ok = np.isfinite(s) & (s > 0) & (n >= 3)
    if not ok.any():
        return out
    sv, nv = np.broadcast_to(s, out.shape)[ok], np.broadcast_to(n, out.shape)[ok]
    # longest windows first: the measures a sample offset can reach are a prefix
    order = np.argsort(-nv, kind="stable")
    sv, nv = sv[order], nv[order]
    half = 0.5 * (nv - 1.0)
    shift = half - np.floor(half)  # an even window is centred between two samples
    k_max = int(np.ceil(half[0]))
    mm, md, dd = np.zeros(sv.size), np.zeros(sv.size), np.zeros(sv.size)
    for o in np.arange(-k_max, k_max + 1, dtype=np.float64):  # one sample offset at a time, vectorised
        # over the measures whose window reaches it (|o| − 1 < half; elsewhere m = d = 0 adds nothing)
        p = int(np.searchsorted(-half, 1.0 - abs(o), side="left"))
        k = o + shift[:p]
        inside = np.abs(k) <= half[:p] + 1e-9
        u = k / sv[:p]
        m = np.where(inside, k * np.exp(-0.5 * u * u), 0.0)
        d = m * (u * u - 3.0)  # s'·∂m/∂s'
        mm[:p] += m * m
        md[:p] += m * d
        dd[:p] += d * d
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.empty(sv.size)
        g[order] = (dd - md * md / mm) / mm
    # three centred samples (and any window where ∂m/∂s' ∥ m) cannot tell the width from the amplitude
    out[ok] = np.where(np.isfinite(g), np.where(g > _G_MIN, g, 0.0), np.nan)
    return out


def measure_sd(diagnostics, *, sample_noise_variance, proj) -> np.ndarray:
    """Standard deviation of each measure's σb, px, from the fit's residual and curvature under the noise.

    Parameters
    ----------
    diagnostics : dict of ndarray, (H, W)
        :func:`method.blur.model_fit.model_fit_diagnostics` (after the PSF choice): ``width`` s (px),
        ``sigma2`` (px), ``residual`` ρ, ``energy`` ‖r‖² ((image units / px²)²), ``window`` N.
    sample_noise_variance : ndarray, (H, W), float
        Variance of one response sample due to the sensor noise, (image units / px²)²
        (:func:`method.blur.model_fit_checked.steered_second_noise_variance` times the pixel's noise
        variance).
    proj : ndarray, (H, W), float
        max(|cos θ|, |sin θ|) of the edge normal: the responses are sampled along the nearest axis,
        so the template's width in sampling steps is s' = s / proj.

    Returns
    -------
    ndarray, (H, W), float64
        sd(σb), px; inf where the window cannot determine the width (:func:`width_information` 0,
        e.g. three samples); NaN where the fit has no width or no signal.

    Notes
    -----
    1. Noise per sample v = max(v_n, ρ‖r‖² / (N − 3)): the sensor's, or the fit's residual per degree
       of freedom (A, s, t0 fitted) when the model explains the response less well than the noise alone
       would (texture, a neighbouring edge).
    2. Signal energy A²‖m‖² = (1 − ρ)‖r‖² (the closed-form amplitude's share of ‖r‖²).
    3. Var(s)/s² = v / (g · (1 − ρ)‖r‖²), g from :func:`width_information` (3/2 on a long window): the
       Cramér–Rao bound of white samples, i.e. sd ∝ noise / contrast.
    4. Through Eq. (2d): sd(σb) = √((s + sd(s))² − σ2²) − σb, the change of σb when s is one standard
       deviation wider (s·sd(s)/σb for σb ≫ sd(s); √(2 s sd(s)) at σb = 0, where the bound is one-sided).

    The samples of a filtered response are correlated (over ≈ σ2), so the white-sample bound is a
    lower bound on the spread; the weighting uses only its ratios between measures. The disk model's
    fits use the same Gaussian template's g (their second moments match).
    """
    s = np.asarray(diagnostics["width"], dtype=np.float64)
    s2 = np.asarray(diagnostics["sigma2"], dtype=np.float64)
    rho = np.clip(np.asarray(diagnostics["residual"], dtype=np.float64), 0.0, 1.0)
    energy = np.asarray(diagnostics["energy"], dtype=np.float64)
    n = np.asarray(diagnostics["window"], dtype=np.float64)
    g = width_information(s / np.asarray(proj, dtype=np.float64), n)
    with np.errstate(invalid="ignore", divide="ignore"):
        v_res = rho * energy / np.maximum(n - 3.0, 1.0)
        v = np.fmax(np.asarray(sample_noise_variance, dtype=np.float64), v_res)
        rel_var = v / (g * (1.0 - rho) * energy)
        sd_s = s * np.sqrt(rel_var)
        sigma_b = np.sqrt(np.maximum(s * s - s2 * s2, 0.0))
        sd = np.sqrt(np.maximum((s + sd_s) ** 2 - s2 * s2, 0.0)) - sigma_b
    return np.where(sd >= 0, sd, np.nan)  # NaN stays NaN


def uncertainty_confidence(sd, measures) -> np.ndarray:
    """Per-measure confidence c_q ∝ 1/Var(σb), normalised so the image's median measure weighs 1.

    Parameters
    ----------
    sd : ndarray, (H, W), float
        sd(σb), px (:func:`measure_sd`).
    measures : ndarray, (H, W), bool
        The pixels that carry a measure (finite σb).

    Returns
    -------
    ndarray, (H, W), float64
        c_q = min(1, median_q' Var_q' / Var_q) in [:data:`UNCERTAINTY_MIN_CONFIDENCE`, 1] at the
        measures (a measure whose sd is infinite or unknown gets the minimum), NaN elsewhere.

    Notes
    -----
    Eq. (3) is a normalised average, so only the ratios of the c_q matter there: a measure the noise
    pins down k times less precisely (in px) weighs 1/k² as much. In Eq. (4) α_p = α·c_q: measures at
    least as precise as the image's median keep the paper's α, so the data term's scale against the
    smoothness term is the paper's where the measures are good.
    """
    measures = np.asarray(measures, dtype=bool)
    var = np.asarray(sd, dtype=np.float64) ** 2
    out = np.full(var.shape, np.nan)
    if not measures.any():
        return out
    good = measures & np.isfinite(var)
    ref = float(np.median(var[good])) if good.any() else 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.where(var > 0, ref / var, 1.0)
    c = np.clip(np.where(np.isfinite(c), c, 0.0), UNCERTAINTY_MIN_CONFIDENCE, 1.0)
    out[measures] = c[measures]
    return out
