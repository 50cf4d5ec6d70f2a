"""The paper's model fit (Sec. 3.2, Eq. 2) with a goodness-of-fit test: poor fits give no measure.

Not in the paper. :func:`method.blur_model_fit.estimate_blur_model_fit` always returns the d of the
best template of Eq. (2c), even when no template explains the sampled 2nd-derivative response
(a window dominated by texture or by a neighbouring edge). At coarse minimum reliable scales σ2 the
conversion σb = √((d/2)² − σ2²) (Eq. 2d) amplifies any error in d, so such fits can give σb far too
high. This variant keeps the model fit's σb unchanged where the fit is good and returns NaN (no
measure; the later stages then ignore the pixel) where the normalised residual of the fit exceeds
``params.fit_max_residual``.
"""

from __future__ import annotations

import numpy as np

from .blur_model_fit import _model_fit_diagnostics, _paper_rules, apply_fit_rules

__all__ = ["estimate_blur_model_fit_checked"]


def estimate_blur_model_fit_checked(gray, edge_map, *, params):
    """Blur σb at edge pixels by the Eq. (2c) fit, NaN where the fit's normalised residual is large.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to :func:`method.elder_zucker_edges.detect_edges`).
    edge_map : EdgeMap
        Edges, θ and minimum reliable σ2 from ``detect_edges(gray, ...)``.
    params : DefocusParams, keyword-only
        Uses everything :func:`~method.blur_model_fit.estimate_blur_model_fit` uses
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
       them (:func:`~method.blur_model_fit.apply_fit_rules`).
    3. Keep σb where ρ ≤ ``params.fit_max_residual``; NaN elsewhere.

    For a blurred step edge the model is exact up to sampling, noise and the window's truncation
    (measured ρ ≤ 0.004 noise-free, ≤ 0.03 with noise 2.5/255 + 8 bits); two opposite edges 1–3σ
    apart (a bar or thin line) give median ρ ≈ 0.12–0.13, 4σ apart 0.04–0.12. Two same-polarity
    edges closer than ~3σ look like one wider step (small ρ) and are not caught. ρ is that of the
    best (s', t0) grid template, before the parabolic refinement of s'. A small ρ does not
    guarantee a good σb: at coarse σ2 a well-fitting d can still give a large σb error through
    Eq. (2d).
    """
    diagnostics = _model_fit_diagnostics(gray, edge_map, params=params)
    sigma_b, residual = diagnostics["sigma_b"], diagnostics["residual"]
    if not _paper_rules(params):  # the beyond-the-paper plausibility rules (robust preset) first
        sigma_b = apply_fit_rules(diagnostics, params=params)
    with np.errstate(invalid="ignore"):
        good = residual <= float(params.fit_max_residual)  # False where residual is NaN
    return np.where(good, sigma_b, np.nan)
