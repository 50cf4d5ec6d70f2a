"""Registry of blur estimators at edge pixels (Sec. 3.2 and baselines), chosen by name.

Every estimator has the signature ``fn(gray, edge_map, *, params) -> ndarray`` and returns a
float64 (H, W) map of the Gaussian blur σ in px at edge pixels, NaN elsewhere and NaN where that
estimator fails at an edge pixel.

Adding an estimator is one new function plus one registry line, e.g.::

    # method/blur_my_idea.py
    def estimate_blur_my_idea(gray, edge_map, *, params):
        out = np.full(gray.shape, np.nan)
        out[edge_map.edges] = ...          # σ in px
        return out

    # here, in BLUR_ESTIMATORS:
    "my_idea": estimate_blur_my_idea,

and then ``DefocusParams(estimator="my_idea")`` or ``estimate_blur(..., method="my_idea")``.

Two optional capabilities, each one more registry line:

- an estimator that samples the detector's 2nd-derivative responses again lists its name in
  :data:`USES_DETECTOR_HESSIANS` (the pipeline then keeps them from the edge detector);
- an estimator that can weigh its own measures registers ``(fn_with_confidence, asks)`` in
  :data:`MEASURE_CONFIDENCE`: ``fn_with_confidence(gray, edge_map, *, params) -> (σ, c)`` with c in
  (0, 1] per measure, and ``asks(params) -> bool`` whether these ``params`` use it; the confidence
  multiplies each measure's weight in Eq. (3) and its α_p in Eq. (4) (:mod:`method.pipeline`);
- an estimator whose fit chooses the edge-response (PSF) model of ``DefocusParams.fit_psf`` registers
  ``fn_with_psf(gray, edge_map, *, params) -> (σ, c or None, psf_disk)`` in :data:`FITS_PSF_MODEL`,
  so :func:`estimate_blur_measures` (and ``DefocusResult.psf_disk``) can say which model measured
  each edge.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .gradient_ratio import estimate_blur_gradient_ratio
from .model_fit import estimate_blur_model_fit, estimate_blur_model_fit_psf
from .model_fit_checked import (estimate_blur_model_fit_checked, estimate_blur_model_fit_checked_confidence,
                                     estimate_blur_model_fit_checked_psf, relaxed_confidence_used)
from .zero_crossing import estimate_blur_zero_crossing
from ..edges.elder_zucker import check_edge_inputs

__all__ = ["BLUR_ESTIMATORS", "FITS_PSF_MODEL", "MEASURE_CONFIDENCE", "USES_DETECTOR_HESSIANS", "estimate_blur",
           "estimate_blur_measures", "estimate_blur_with_confidence", "uses_measure_confidence"]

#: name -> estimator fn(gray, edge_map, *, params) -> (H, W) float64 σ in px, NaN off edges.
BLUR_ESTIMATORS: dict[str, Callable[..., np.ndarray]] = {
    "model_fit": estimate_blur_model_fit,          # the paper's brute-force fit of Eq. (2c)
    "model_fit_checked": estimate_blur_model_fit_checked,  # model_fit, NaN where the fit is poor
    "zero_crossing": estimate_blur_zero_crossing,  # Elder & Zucker: 3rd-derivative zero crossings
    "gradient_ratio": estimate_blur_gradient_ratio,  # Zhuo & Sim 2011 re-blur gradient ratio
}

#: Estimators that sample the edge detector's 2nd-derivative responses (``EdgeMap.hessians``) again.
USES_DETECTOR_HESSIANS: frozenset[str] = frozenset({"model_fit", "model_fit_checked"})

#: name -> (fn(gray, edge_map, *, params) -> (σ, confidence), asks(params) -> bool): estimators of
#: :data:`BLUR_ESTIMATORS` that can also weigh their own measures (c_q in (0, 1], NaN where σ is NaN);
#: ``asks`` says whether ``params`` use that confidence. Every other estimator's measures weigh 1.
MEASURE_CONFIDENCE: dict[str, tuple[Callable[..., tuple[np.ndarray, np.ndarray]], Callable[..., bool]]] = {
    "model_fit_checked": (estimate_blur_model_fit_checked_confidence, relaxed_confidence_used),
}


def _model_fit_with_psf(gray, edge_map, *, params):
    sigma, psf_disk = estimate_blur_model_fit_psf(gray, edge_map, params=params)
    return sigma, None, psf_disk  # the paper's fit weighs every measure 1


#: name -> fn(gray, edge_map, *, params) -> (σ, confidence or None, psf_disk): estimators of
#: :data:`BLUR_ESTIMATORS` whose fit chooses its PSF model by ``params.fit_psf`` (Eq. 2c's Gaussian or
#: the disk of :mod:`method.blur.disk_edge_response`); ``psf_disk`` (bool, H x W) marks the measures fitted
#: with the disk. σ (and the confidence, when :data:`MEASURE_CONFIDENCE` has one) equal the plain entries'.
FITS_PSF_MODEL: dict[str, Callable[..., tuple]] = {
    "model_fit": _model_fit_with_psf,
    "model_fit_checked": estimate_blur_model_fit_checked_psf,
}


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
    fn = BLUR_ESTIMATORS.get(name)
    if fn is None:
        raise ValueError(f"unknown blur estimator {name!r}; allowed: {sorted(BLUR_ESTIMATORS)}")
    img = check_edge_inputs(gray, edge_map)
    out = np.asarray(fn(img, edge_map, params=params), dtype=np.float64)
    if out.shape != img.shape:
        raise ValueError(f"estimator {name!r} returned shape {out.shape}; expected {img.shape}")
    return _nan_off_edges(out, edge_map)


def uses_measure_confidence(params) -> bool:
    """Whether ``params`` ask for a per-measure confidence (beyond the paper; docs/presets.md).

    True when ``params.estimator`` is registered in :data:`MEASURE_CONFIDENCE` and its ``asks(params)``
    is true (``model_fit_checked``: ``fit_residual_noise`` > 0 and ``relaxed_fit_weight`` < 1).
    """
    entry = MEASURE_CONFIDENCE.get(params.estimator)
    return entry is not None and bool(entry[1](params))


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
        (:data:`MEASURE_CONFIDENCE`; ``model_fit_checked``: 1 for the measures passing the strict
        residual test, ``params.relaxed_fit_weight`` for those admitted by the noise allowance
        only), NaN where ``sigma`` is NaN. σ and the confidence come from one call.
    """
    if not uses_measure_confidence(params):
        return estimate_blur(gray, edge_map, params=params), None
    img = check_edge_inputs(gray, edge_map)
    sigma, conf = MEASURE_CONFIDENCE[params.estimator][0](img, edge_map, params=params)
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
        For estimators of :data:`FITS_PSF_MODEL`: True at the measures fitted with the disk-blurred
        step (``params.fit_psf`` "disk", "best" or "auto"), False elsewhere (all False for
        ``fit_psf="gaussian"``, the paper's Eq. 2c). None for estimators that fit no PSF model.

    Notes
    -----
    With ``fit_psf="gaussian"`` or an estimator outside :data:`FITS_PSF_MODEL` this is
    :func:`estimate_blur_with_confidence` (the paper's path is untouched); otherwise the registered
    ``fn_with_psf`` runs once and its confidence is kept only when :func:`uses_measure_confidence`.
    """
    fn = FITS_PSF_MODEL.get(params.estimator)
    if fn is None or params.fit_psf == "gaussian":
        sigma, conf = estimate_blur_with_confidence(gray, edge_map, params=params)
        return sigma, conf, None if fn is None else np.zeros(np.shape(sigma), dtype=bool)
    img = check_edge_inputs(gray, edge_map)
    sigma, conf, disk = fn(img, edge_map, params=params)
    sigma = _nan_off_edges(sigma, edge_map)
    finite = np.isfinite(sigma)
    conf = np.where(finite, conf, np.nan) if conf is not None and uses_measure_confidence(params) else None
    return sigma, conf, np.asarray(disk, dtype=bool) & finite
