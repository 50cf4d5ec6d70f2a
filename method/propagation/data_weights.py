"""The per-edge weight c_p of Eq. (4)'s data term (α_p = α·c_p), beyond the paper's constant α.

:func:`propagation_confidence` combines the estimator's per-measure confidence with, for
``DefocusParams.alpha_confidence="agreement"``, the agreement of the raw measures with their
Eq. (3) refinement (:func:`edge_confidence`). The pipeline (:func:`method.pipeline.propagate_stage`)
passes the result to the propagation.
"""

from __future__ import annotations

import numpy as np

from ..registry import Registry

__all__ = ["ALPHA_CONFIDENCES", "edge_confidence", "propagation_confidence"]

#: ``DefocusParams.alpha_confidence``: what scales α_p of Eq. (4) beyond the measure confidence.
ALPHA_CONFIDENCES = Registry("alpha confidence", {"none": "α_p = α (the paper)",
                                                  "agreement": "agreement of BM with bCBF (beyond the paper)"})


def edge_confidence(sparse_sigma, refined_sigma) -> np.ndarray:
    """Per-edge confidence of ``alpha_confidence="agreement"``: agreement of BM with bCBF (beyond the paper).

    Parameters
    ----------
    sparse_sigma, refined_sigma : ndarray, HxW, float
        Raw and refined blur σ, px (NaN off edges).

    Returns
    -------
    ndarray, HxW, float64 in [0, 1]
        c_p = exp(−(BM_p − bCBF_p)² / (2 τ_p²)), τ_p = 0.25·bCBF_p + 0.5 px; NaN off edges.
    """
    tau = 0.25 * np.maximum(refined_sigma, 0.0) + 0.5
    with np.errstate(invalid="ignore"):
        return np.exp(-0.5 * ((sparse_sigma - refined_sigma) / tau) ** 2)


def propagation_confidence(refined_sigma, *, params, sparse_sigma=None, confidence=None):
    """The per-edge weight c_p of Eq. (4)'s data term (α_p = α·c_p), or None for the paper's constant α.

    Parameters
    ----------
    refined_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels (after Eq. 3); NaN elsewhere.
    params : PropagationParams or DefocusParams, keyword-only
        Reads ``alpha_confidence``.
    sparse_sigma : ndarray, HxW, float, or None, keyword-only
        The raw measures (``alpha_confidence="agreement"``; None: refined used as raw).
    confidence : ndarray, HxW, float in (0, 1], or None, keyword-only
        The estimator's per-measure confidence (``DefocusResult.measure_confidence``).

    Returns
    -------
    ndarray, HxW, float64 in [0, 1] (NaN off the refined measures), or None
        The measure confidence times the agreement factor (:func:`edge_confidence`) when
        ``alpha_confidence="agreement"``, else the measure confidence; None when neither applies.
    """
    measure = None if confidence is None else np.asarray(confidence, dtype=np.float64)
    if params.alpha_confidence == "agreement":
        raw = refined_sigma if sparse_sigma is None else sparse_sigma
        agreement = np.where(np.isfinite(refined_sigma), edge_confidence(raw, refined_sigma), np.nan)
        return agreement if measure is None else agreement * measure
    if measure is not None:
        return np.where(np.isfinite(refined_sigma), measure, np.nan)
    return None
