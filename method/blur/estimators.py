"""Registry of blur estimators at edge pixels (Sec. 3.2 and baselines), chosen by name.

Every estimator has the signature ``fn(gray, edge_map, *, params) -> ndarray`` and returns a
float64 (H, W) map of the Gaussian blur σ in px at edge pixels, NaN elsewhere and NaN where that
estimator fails at an edge pixel.

Adding an estimator is one new function plus one registry line, e.g.::

    # method/blur/my_idea.py
    def estimate_blur_my_idea(gray, edge_map, *, params):
        out = np.full(gray.shape, np.nan)
        out[edge_map.edges] = ...          # σ in px
        return out

    # here, in BLUR_ESTIMATORS:
    "my_idea": Entry(estimate_blur_my_idea, "what it measures (reference)"),

and then ``DefocusParams(estimator="my_idea")`` or ``estimate_blur(..., method="my_idea")``.

Optional capabilities (:class:`method.registry.Entry` ``capabilities`` / ``hooks``):

- ``"detector_hessians"``: the estimator samples the detector's 2nd-derivative responses again (the
  pipeline then keeps them from the edge detector);
- ``"confidence"``: hook ``fn(gray, edge_map, *, params) -> (σ, c)`` with c in (0, 1] per measure, plus
  hook ``"confidence_used"``: ``asks(params) -> bool`` whether these ``params`` use it; the confidence
  multiplies each measure's weight in Eq. (3) and its α_p in Eq. (4) (:mod:`method.pipeline`);
- ``"psf_model"``: hook ``fn(gray, edge_map, *, params) -> (σ, c or None, psf_disk)`` for a fit that
  chooses the edge-response (PSF) model of ``DefocusParams.fit_psf``, so
  :func:`estimate_blur_measures` (and ``DefocusResult.psf_disk``) can say which model measured each edge.
"""

from __future__ import annotations

import numpy as np

from .gradient_ratio import estimate_blur_gradient_ratio
from .model_fit import estimate_blur_model_fit, estimate_blur_model_fit_psf
from .model_fit_checked import (estimate_blur_model_fit_checked, estimate_blur_model_fit_checked_confidence,
                                     estimate_blur_model_fit_checked_psf, relaxed_confidence_used)
from .zero_crossing import estimate_blur_zero_crossing
from ..edges.elder_zucker import check_edge_inputs
from ..registry import Entry, Registry

__all__ = ["BLUR_ESTIMATORS", "estimate_blur", "estimate_blur_measures", "estimate_blur_with_confidence",
           "uses_measure_confidence"]


def _model_fit_with_psf(gray, edge_map, *, params):
    sigma, psf_disk = estimate_blur_model_fit_psf(gray, edge_map, params=params)
    return sigma, None, psf_disk  # the paper's fit weighs every measure 1


#: name -> estimator fn(gray, edge_map, *, params) -> (H, W) float64 σ in px, NaN off edges; each
#: entry's capabilities and hooks as in the module docstring. With the ``"psf_model"`` hook, σ (and
#: the confidence, when there is one) equal the plain entry's.
BLUR_ESTIMATORS = Registry("blur estimator", {
    "model_fit": Entry(estimate_blur_model_fit, "the paper's brute-force fit of Eq. (2c)",
                       capabilities={"detector_hessians"}, hooks={"psf_model": _model_fit_with_psf}),
    "model_fit_checked": Entry(estimate_blur_model_fit_checked, "model_fit, NaN where the fit is poor",
                               capabilities={"detector_hessians"},
                               hooks={"confidence": estimate_blur_model_fit_checked_confidence,
                                      "confidence_used": relaxed_confidence_used,
                                      "psf_model": estimate_blur_model_fit_checked_psf}),
    "zero_crossing": Entry(estimate_blur_zero_crossing, "Elder & Zucker 1998: 3rd-derivative zero crossings"),
    "gradient_ratio": Entry(estimate_blur_gradient_ratio, "Zhuo & Sim 2011: re-blur gradient ratio"),
})


def estimate_blur(gray, edge_map, *, params, method=None):
    """Blur σ at edge pixels with a registered estimator (sparse blur measure BM, Sec. 3.2).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (the image given to ``detect_edges``).
    edge_map : EdgeMap
        Output of :func:`method.edges.elder_zucker.detect_edges` for ``gray``.
    params : DefocusParams, keyword-only
        Pipeline parameters (window sizes, max_sigma, default estimator).
    method : str or None, keyword-only
        Key of :data:`BLUR_ESTIMATORS`; None uses ``params.estimator``.

    Returns
    -------
    ndarray, shape (H, W), float64
        σ in px at edge pixels; NaN elsewhere and where the estimator fails.

    Raises
    ------
    ValueError
        Unknown method name (the message lists the registered names), or bad inputs.

    Notes
    -----
    1. Resolve the name; 2. validate (gray, edge_map); 3. call the estimator; 4. force NaN off
    the edge pixels and check the output shape.
    """
    name = params.estimator if method is None else method
    fn = BLUR_ESTIMATORS.resolve(name, what="method" if method is not None else "DefocusParams.estimator")
    img = check_edge_inputs(gray, edge_map)
    out = np.asarray(fn(img, edge_map, params=params), dtype=np.float64)
    if out.shape != img.shape:
        raise ValueError(f"estimator {name!r} returned shape {out.shape}; expected {img.shape}")
    return _nan_off_edges(out, edge_map)


def uses_measure_confidence(params) -> bool:
    """Whether ``params`` ask for a per-measure confidence (beyond the paper; docs/presets.md).

    True when the entry of ``params.estimator`` has the ``"confidence"`` capability and its
    ``"confidence_used"`` hook is true for ``params`` (``model_fit_checked``: ``measure_weighting``
    "uncertainty", or ``fit_residual_noise`` > 0 and ``relaxed_fit_weight`` < 1).
    """
    hooks = BLUR_ESTIMATORS.entry(params.estimator).hooks
    return "confidence" in hooks and bool(hooks["confidence_used"](params))


def estimate_blur_with_confidence(gray, edge_map, *, params):
    """:func:`estimate_blur` plus a per-measure confidence c_q in (0, 1] (None when all are 1).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Output of :func:`method.edges.elder_zucker.detect_edges` for ``gray``.
    params : DefocusParams, keyword-only

    Returns
    -------
    sigma : ndarray, shape (H, W), float64
        As :func:`estimate_blur` (σ in px, NaN off edges and where the estimator fails).
    confidence : ndarray, shape (H, W), float64, or None
        None unless :func:`uses_measure_confidence`; then the registered estimator's confidence
        (its ``"confidence"`` hook; ``model_fit_checked``: 1 for the measures passing the strict
        residual test, ``params.relaxed_fit_weight`` for those admitted by the noise allowance
        only; with ``measure_weighting="uncertainty"`` ∝ 1/Var(σb)), NaN where ``sigma`` is NaN. σ and the confidence come from one call.
    """
    if not uses_measure_confidence(params):
        return estimate_blur(gray, edge_map, params=params), None
    img = check_edge_inputs(gray, edge_map)
    sigma, conf = BLUR_ESTIMATORS.hook(params.estimator, "confidence")(img, edge_map, params=params)
    sigma = _nan_off_edges(sigma, edge_map)
    return sigma, np.where(np.isfinite(sigma), conf, np.nan)


def _nan_off_edges(sigma, edge_map):
    """A float64 copy of an estimator's σ map with NaN off the edge pixels."""
    sigma = np.asarray(sigma, dtype=np.float64).copy()
    sigma[~np.asarray(edge_map.edges, dtype=bool)] = np.nan
    return sigma


def estimate_blur_measures(gray, edge_map, *, params):
    """σ at the edges, its confidence and which PSF model measured each edge, from one fit.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Output of :func:`method.edges.elder_zucker.detect_edges` for ``gray``.
    params : DefocusParams, keyword-only

    Returns
    -------
    sigma, confidence
        As :func:`estimate_blur_with_confidence` (bit-identical).
    psf_disk : ndarray, shape (H, W), bool, or None
        For estimators with the ``"psf_model"`` hook: True at the measures fitted with the disk-blurred
        step (``params.fit_psf`` "disk", "best" or "auto"), False elsewhere (all False for
        ``fit_psf="gaussian"``, the paper's Eq. 2c). None for estimators that fit no PSF model.

    Notes
    -----
    With ``fit_psf="gaussian"`` or an estimator without the ``"psf_model"`` hook this is
    :func:`estimate_blur_with_confidence` (the paper's path is untouched); otherwise the registered
    hook runs once and its confidence is kept only when :func:`uses_measure_confidence`.
    """
    fn = BLUR_ESTIMATORS.hook(params.estimator, "psf_model")
    if fn is None or params.fit_psf == "gaussian":
        sigma, conf = estimate_blur_with_confidence(gray, edge_map, params=params)
        return sigma, conf, None if fn is None else np.zeros(np.shape(sigma), dtype=bool)
    img = check_edge_inputs(gray, edge_map)
    sigma, conf, disk = fn(img, edge_map, params=params)
    sigma = _nan_off_edges(sigma, edge_map)
    finite = np.isfinite(sigma)
    conf = np.where(finite, conf, np.nan) if conf is not None and uses_measure_confidence(params) else None
    return sigma, conf, np.asarray(disk, dtype=bool) & finite
