"""The paper's model fit (Sec. 3.2, Eq. 2) with a goodness-of-fit test: poor fits give no measure.

Not in the paper. :func:`method.blur.model_fit.estimate_blur_model_fit` always returns the d of the
best template of Eq. (2c), even when no template explains the sampled 2nd-derivative response
(a window dominated by texture or by a neighbouring edge). At coarse minimum reliable scales σ2 the
conversion σb = √((d/2)² − σ2²) (Eq. 2d) amplifies any error in d, so such fits can give σb far too
high. This variant keeps the model fit's σb unchanged where the fit is good and returns NaN (no
measure; the later stages then ignore the pixel) where the normalised residual of the fit exceeds
``params.fit_max_residual``.
"""

from __future__ import annotations

import functools

import numpy as np

from .measure_uncertainty import measure_sd, uncertainty_confidence
from .model_fit import paper_rules, apply_fit_rules
from .noise_model import noise_variance_map
from .noise_spectrum import noise_spectrum_of
from .scale_follow import follow_scale_diagnostics
from .step_plateau import gate_step_pixels

__all__ = ["estimate_blur_model_fit_checked", "estimate_blur_model_fit_checked_confidence",
           "estimate_blur_model_fit_checked_psf", "estimate_blur_model_fit_checked_sd", "fit_measure_sd",
           "noise_residual_share", "relaxed_confidence_used", "steered_second_noise_variance"]


@functools.lru_cache(maxsize=32)
def _unit_noise_variance(sigma2: float) -> float:
    # mean over a 512² DFT grid of the θ-averaged |H(ω)|² = (3/8)|ω|⁴ exp(−σ2²|ω|²) (unit white noise)
    w = 2.0 * np.pi * np.fft.fftfreq(512)
    w2 = w[:, None] ** 2 + w[None, :] ** 2
    return float(np.mean(0.375 * w2 ** 2 * np.exp(-(sigma2 ** 2) * w2)))


def steered_second_noise_variance(sigma2, noise_std, noise_spectrum=None):
    """Variance of the steered 2nd-derivative response ∂²_θ(n ∗ g_σ2) to white noise n, averaged over θ.

    Parameters
    ----------
    sigma2 : ndarray or float
        Filter scale σ2, px (NaN or ≤ 0 gives NaN).
    noise_std : float
        Standard deviation of the white noise, image units.
    noise_spectrum : NoiseSpectrum or None
        The noise's spectrum relative to white noise of that std
        (:class:`method.edges.noise_thresholds.NoiseSpectrum`): each scale's variance times
        ``noise_spectrum.factor(2, σ2)``. None: white.

    Returns
    -------
    ndarray, same shape as ``sigma2``, float64
        Variance, (image units / px²)².

    Notes
    -----
    The responses are computed with the transfer function (iω_u)² exp(−σ2²|ω|²/2)
    (:mod:`method.edges.gaussian_derivatives`), so for unit white noise the variance is the mean of
    ω_u⁴ exp(−σ2²|ω|²) over the DFT frequency grid [−π, π)²; averaged over θ, ω_u⁴ → (3/8)|ω|⁴.
    For σ2 ≳ 1 px this is the continuous value 3/(16π σ2⁶) (tested).
    """
    s2 = np.asarray(sigma2, dtype=np.float64)
    out = np.full(s2.shape, np.nan)
    ok = np.isfinite(s2) & (s2 > 0)
    if ok.any():  # the distinct scales of the valid entries only (edge pixels: a few % of an image)
        values, inverse = np.unique(s2[ok], return_inverse=True)
        unit = np.array([_unit_noise_variance(float(v)) for v in values])
        if noise_spectrum is not None:
            unit = unit * np.array([noise_spectrum.factor(2, float(v)) for v in values])
        out[ok] = unit[inverse.ravel()]
    return out * float(noise_std) ** 2


def noise_residual_share(diagnostics, *, noise_std, noise_variance=None, noise_spectrum=None):
    """Expected share of the fit residual ρ that white sensor noise alone leaves: N · v_n(σ2) / ‖r‖².

    Parameters
    ----------
    diagnostics : dict of ndarray, (H, W)
        Output of :func:`method.blur.model_fit.model_fit_diagnostics` (``window``: samples N,
        ``sigma2``: px, ``energy``: ‖r‖² over the window).
    noise_std : float, keyword-only
        Noise std, image units (the pipeline's ``params.noise_std``).
    noise_variance : ndarray, (H, W), float, or None, keyword-only
        Per-pixel noise variance, image units² (``noise_model="signal_dependent"``:
        :func:`method.blur.noise_model.noise_variance_map`); replaces ``noise_std``² where given.
    noise_spectrum : NoiseSpectrum or None, keyword-only
        The noise's spectrum (:func:`method.blur.noise_spectrum.estimate_noise_spectrum`): v_n(σ2) is
        that of the correlated noise (:func:`steered_second_noise_variance`). None: white.

    Returns
    -------
    ndarray, (H, W), float64
        N · v_n(σ2) / ‖r‖² (dimensionless; 0 where not fitted). The noise adds about N · v_n to
        the residual sum of squares of a correct model, so a fixed ρ limit rejects noisy but
        correct fits; with s the response width, ‖r‖² ∝ A²/s³ and N ∝ s, so the share grows as ~s⁴:
        a fixed limit keeps blurry edges only when they are unusually narrow or contrasted.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        if noise_variance is None:
            v_n = steered_second_noise_variance(diagnostics["sigma2"], noise_std, noise_spectrum)
        else:
            v_n = steered_second_noise_variance(diagnostics["sigma2"], 1.0, noise_spectrum) * noise_variance
        share = diagnostics["window"] * v_n / diagnostics["energy"]
    return np.where(np.isfinite(share), share, 0.0)


def relaxed_confidence_used(params) -> bool:
    """Whether ``params`` give the measures a confidence other than 1: ``measure_weighting="uncertainty"``,
    or (``"hand"``) ``fit_residual_noise`` > 0 and ``relaxed_fit_weight`` < 1 (else every measure weighs 1)."""
    if params.measure_weighting == "uncertainty":
        return True
    return float(params.fit_residual_noise) > 0 and float(params.relaxed_fit_weight) < 1.0


def fit_measure_sd(diagnostics, edge_map, *, params, noise_variance=None):
    """sd(σb), px, of every fitted edge pixel (:func:`method.blur.measure_uncertainty.measure_sd`).

    Parameters
    ----------
    diagnostics : dict of ndarray, (H, W)
        :func:`method.blur.model_fit.model_fit_diagnostics` (after the PSF choice).
    edge_map : EdgeMap
        The detector's output (θ gives the sampling axis).
    params : DefocusParams, keyword-only
        ``noise_std`` (image units) where ``noise_variance`` is None.
    noise_variance : ndarray, (H, W), float, or None, keyword-only
        Per-pixel noise variance, image units² (``noise_model="signal_dependent"``).

    Returns
    -------
    ndarray, (H, W), float64
        sd(σb), px; NaN where not fitted.
    """
    fitted = np.isfinite(diagnostics["width"])  # measure_sd is NaN wherever the width is: evaluate the rest only
    fits = {name: np.asarray(diagnostics[name])[fitted] for name in ("width", "sigma2", "residual", "energy", "window")}
    v_pixel = float(params.noise_std) ** 2 if noise_variance is None else np.asarray(noise_variance)[fitted]
    out = np.full(fitted.shape, np.nan)
    out[fitted] = _measure_sd_at(fits, np.asarray(edge_map.theta, dtype=np.float64)[fitted], v_pixel)
    return out


def _measure_sd_at(fits, theta, v_pixel):
    """:func:`fit_measure_sd` of fitted pixels given as arrays of shape (n,): ``fits`` (the diagnostics
    :func:`~method.blur.measure_uncertainty.measure_sd` reads), θ (radians) and the noise variance
    (image units², array or float); sd(σb), px."""
    with np.errstate(invalid="ignore"):
        v_sample = steered_second_noise_variance(fits["sigma2"], 1.0) * v_pixel
    proj = np.maximum(np.abs(np.cos(theta)), np.abs(np.sin(theta)))
    return measure_sd(fits, sample_noise_variance=v_sample, proj=proj)


def estimate_blur_model_fit_checked_sd(gray, edge_map, *, params):
    """:func:`estimate_blur_model_fit_checked` and each measure's standard deviation, from the same fit.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges(gray, ...)``.
    params : DefocusParams, keyword-only
        As :func:`estimate_blur_model_fit_checked`.

    Returns
    -------
    sigma_b : ndarray, shape (H, W), float64
        Identical to :func:`estimate_blur_model_fit_checked` (px).
    sd : ndarray, shape (H, W), float64
        sd(σb), px, from the fit's residual and its curvature in s under the pixel's noise variance
        (:func:`fit_measure_sd`); NaN where ``sigma_b`` is NaN.
    """
    diagnostics = follow_scale_diagnostics(gray, edge_map, params=params)
    noise_variance = _noise_variance(gray, edge_map, params)
    sigma_b, _ = _checked(diagnostics, params, gray, edge_map, noise_variance)
    sd = fit_measure_sd(diagnostics, edge_map, params=params, noise_variance=noise_variance)
    return sigma_b, np.where(np.isfinite(sigma_b), sd, np.nan)


def estimate_blur_model_fit_checked(gray, edge_map, *, params):
    """Blur σb at edge pixels by the Eq. (2c) fit, NaN where the fit's normalised residual is large.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to :func:`method.edges.elder_zucker.detect_edges`).
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges(gray, ...)``.
    params : DefocusParams, keyword-only
        Uses everything :func:`~method.blur.model_fit.estimate_blur_model_fit` uses
        (``fit_window_min``, ``fit_window_max``, px; ``max_sigma``, px) and ``fit_max_residual``
        (dimensionless, in [0, 1]).

    Returns
    -------
    ndarray, shape (H, W), float64
        σb in px at edge pixels, bit-identical to ``estimate_blur_model_fit`` where the fit's
        normalised residual ρ ≤ ``params.fit_max_residual``; NaN where ρ is larger, where the fit
        fails, and off edges.

    Notes
    -----
    1. Run the model fit of Eq. (2c) exactly as ``estimate_blur_model_fit`` does (same private
       kernel, same window, same brute-force search; σb from Eq. 2d), which also reports, per edge
       pixel, the normalised residual of its best template m (amplitude A fitted in closed form)
       over the fit window of samples r(k):

           ρ = ‖r − A·m‖² / ‖r‖² = 1 − (r·m)² / (‖r‖² ‖m‖²),   0 ≤ ρ ≤ 1,

       i.e. one minus the squared normalised correlation between the response and the model; it
       does not depend on the edge contrast.
    2. With any of the model fit's plausibility rules switched on (``fit_max_scale``,
       ``fit_min_samples``, ``fit_max_width_ratio``, ``fit_below_scale``; the robust preset), apply
       them (:func:`~method.blur.model_fit.apply_fit_rules`).
    3. Keep σb where ρ ≤ ``params.fit_max_residual``; NaN elsewhere.
    4. ``params.fit_residual_noise`` = k > 0 (beyond the paper; robust preset: k = 2): the limit is
       ``fit_max_residual`` + k · :func:`noise_residual_share` (per pixel), i.e. the residual the
       sensor noise ``params.noise_std`` is expected to leave is allowed on top. With
       ``params.noise_model="signal_dependent"`` the noise is the edge pixel's own variance
       (``edge_map.noise_variance``, else :func:`method.blur.noise_model.noise_variance_map` of ``gray``).
    5. ``params.fit_follow_scale`` (beyond the paper): step 1's fit is re-done at a scale that
       follows a coarse estimate of the blur where that blur is large
       (:func:`method.blur.scale_follow.follow_scale_diagnostics`); None: off.
    6. ``params.fit_step_gate`` other than ``"none"`` (beyond the paper): NaN where the profile across
       the edge is not that of a blurred step (:func:`method.blur.step_plateau.gate_step_measures`).

    For a blurred step edge the model is exact up to sampling, noise and the window's truncation
    (measured ρ ≤ 0.004 noise-free, ≤ 0.03 with noise 2.5/255 + 8 bits); two opposite edges 1–3σ
    apart (a bar or thin line) give median ρ ≈ 0.12–0.13, 4σ apart 0.04–0.12. Two same-polarity
    edges closer than ~3σ look like one wider step (small ρ) and are not caught. ρ is that of the
    best (s', t0) grid template, before the parabolic refinement of s'. A small ρ does not
    guarantee a good σb: at coarse σ2 a well-fitting d can still give a large σb error through
    Eq. (2d).
    """
    return estimate_blur_model_fit_checked_confidence(gray, edge_map, params=params)[0]


def estimate_blur_model_fit_checked_confidence(gray, edge_map, *, params):
    """:func:`estimate_blur_model_fit_checked` plus a per-measure confidence from the same single fit.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges(gray, ...)``.
    params : DefocusParams, keyword-only
        As :func:`estimate_blur_model_fit_checked`, plus ``relaxed_fit_weight`` (dimensionless,
        in (0, 1]).

    Returns
    -------
    sigma_b : ndarray, shape (H, W), float64
        Identical to :func:`estimate_blur_model_fit_checked`.
    confidence : ndarray, shape (H, W), float64
        1 where the measure passes the strict test ρ ≤ ``fit_max_residual``;
        ``relaxed_fit_weight`` where it passes only thanks to the noise allowance
        (``fit_residual_noise`` > 0, Notes 4 of :func:`estimate_blur_model_fit_checked`);
        NaN where ``sigma_b`` is NaN. With ``params.measure_weighting="uncertainty"`` instead
        c_q ∝ 1 / Var(σb) in (0, 1] (:func:`method.blur.measure_uncertainty.uncertainty_confidence`
        of :func:`fit_measure_sd`; ``relaxed_fit_weight`` is not used).

    Notes
    -----
    Beyond the paper (measurements: docs/presets.md). The confidence multiplies each measure's weight in Eq. (3) and its
    α_p in Eq. (4) (:func:`method.pipeline.refine_stage`, :func:`method.pipeline.propagate_stage`),
    so the relaxed measures (fits of blurry edges, but also of in-focus low-contrast edges fitted
    too wide) decide the map only where no strict measure is near. The fit runs once.
    """
    return _checked(follow_scale_diagnostics(gray, edge_map, params=params), params, gray, edge_map,
                    _noise_variance(gray, edge_map, params))


def estimate_blur_model_fit_checked_psf(gray, edge_map, *, params):
    """:func:`estimate_blur_model_fit_checked_confidence` plus, from the same fit, which measures used the disk.

    Returns
    -------
    sigma_b, confidence : ndarray, shape (H, W), float64
        As :func:`estimate_blur_model_fit_checked_confidence`.
    psf_disk : ndarray, shape (H, W), bool
        True at the measures (finite ``sigma_b``) whose edge response was fitted with the disk model
        (``params.fit_psf``: :func:`method.blur.model_fit.select_psf_model`); False elsewhere.
    """
    diagnostics = follow_scale_diagnostics(gray, edge_map, params=params)
    sigma_b, confidence = _checked(diagnostics, params, gray, edge_map, _noise_variance(gray, edge_map, params))
    return sigma_b, confidence, diagnostics["disk"] & np.isfinite(sigma_b)


def _noise_variance(gray, edge_map, params):
    """Per-pixel noise variance of the residual test: the detector's, else from ``gray``; None if constant."""
    if params.noise_model == "constant":
        return None
    return edge_map.noise_variance if edge_map.noise_variance is not None else noise_variance_map(gray, params)


def _noise_spectrum(gray, edge_map, params):
    """The noise spectrum of the residual test: the detector's, else from ``gray``; None if white."""
    if params.noise_model == "constant" or params.noise_spectrum == "white":
        return None
    return edge_map.noise_spectrum if edge_map.noise_spectrum is not None else noise_spectrum_of(gray, params)


def _checked(diagnostics, params, gray, edge_map, noise_variance=None):
    """(σb, confidence) of the checked fit from the model fit's diagnostics (Notes of the estimator),
    then ``params.fit_step_gate`` (:func:`method.blur.step_plateau.gate_step_pixels`).

    Every rule only removes measures, so it runs on the list of pixels with a fitted σb (raster order)."""
    shape = diagnostics["sigma_b"].shape
    fitted = np.flatnonzero(np.isfinite(diagnostics["sigma_b"]))
    fits = {name: np.asarray(values).reshape(-1)[fitted] for name, values in diagnostics.items()}
    if noise_variance is not None:
        noise_variance = np.broadcast_to(np.asarray(noise_variance), shape).reshape(-1)[fitted]
    sigma_b, residual = fits["sigma_b"], fits["residual"]
    if not paper_rules(params):  # the beyond-the-paper plausibility rules (robust preset) first
        sigma_b = apply_fit_rules(fits, params=params)
    strict_limit = float(params.fit_max_residual)
    limit = strict_limit
    k = float(params.fit_residual_noise)
    if k > 0:  # beyond the paper: allow the residual that the sensor noise alone leaves (Notes, 4)
        limit = limit + k * noise_residual_share(fits, noise_std=params.noise_std, noise_variance=noise_variance,
                                                 noise_spectrum=_noise_spectrum(gray, edge_map, params))
    with np.errstate(invalid="ignore"):
        good = residual <= limit  # False where residual is NaN
        strict = residual <= strict_limit
    sigma_b = np.where(good, sigma_b, np.nan)
    measured = np.isfinite(sigma_b)
    rows, cols = np.divmod(fitted[measured], shape[1])
    theta = np.asarray(edge_map.theta, dtype=np.float64)
    keep = gate_step_pixels(gray, rows, cols, theta[rows, cols], sigma_b[measured], params=params)
    sigma_b[np.flatnonzero(measured)[~keep]] = np.nan
    if params.measure_weighting == "uncertainty":  # c_q ∝ 1 / Var(σb) (method.blur.measure_uncertainty)
        sd = np.full(fitted.size, np.nan)
        w = np.isfinite(fits["width"])
        v_pixel = float(params.noise_std) ** 2 if noise_variance is None else noise_variance[w]
        sd[w] = _measure_sd_at({name: values[w] for name, values in fits.items()},
                               theta.reshape(-1)[fitted[w]], v_pixel)
        confidence = uncertainty_confidence(sd, np.isfinite(sigma_b))
    else:
        confidence = np.where(strict, 1.0, float(params.relaxed_fit_weight))
        confidence[~np.isfinite(sigma_b)] = np.nan
    out = np.full(shape, np.nan), np.full(shape, np.nan)
    out[0].reshape(-1)[fitted] = sigma_b
    out[1].reshape(-1)[fitted] = confidence
    return out
