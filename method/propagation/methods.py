"""Registry of propagation methods (Sec. 4 and the Zhuo & Sim 2011 baseline), chosen by name.

Every method has the signature ``fn(sparse_sigma, reference, *, params, confidence) -> ndarray``:
sparse blur σ (px) at edge pixels, NaN elsewhere, and the RGB guide in, the dense HxW σ map (px)
out (not clipped). ``confidence`` is None or an HxW per-edge weight in [0, 1] (α_p = α·c_p).

* ``"colorization"`` — the paper's Eq. (4): Levin et al. 2004 colorization affinities
  (:func:`method.propagation.defocus.propagate_defocus`).
* ``"matting_laplacian"`` — Zhuo & Sim 2011: the closed-form matting Laplacian of Levin et al.
  2008 (:func:`method.propagation.matting.propagate_defocus_matting`).

Adding a method is one function plus one line in :data:`PROPAGATION_METHODS`.
"""

from __future__ import annotations

import numpy as np

from .defocus import propagate_defocus
from ..registry import Entry, Registry

__all__ = ["PROPAGATION_METHODS", "propagate_blur_measures"]


def _colorization(sparse_sigma, reference, *, params, confidence=None, max_confidence=1.0):
    return propagate_defocus(
        sparse_sigma, reference,
        alpha=params.alpha,
        window=params.propagation_window,
        neighborhood=params.propagation_neighborhood,
        tol=params.propagation_tol,
        solver=params.propagation_solver,
        downsample=params.propagation_downsample,
        refinement=params.propagation_refinement,
        confidence=confidence,
        max_confidence=max_confidence,
    )


def _matting_laplacian(sparse_sigma, reference, *, params, confidence=None, max_confidence=1.0):
    if confidence is not None:  # D of Zhuo & Sim's data term becomes diag(c_p)
        raise ValueError("propagation='matting_laplacian' does not take a per-edge confidence; "
                         "use alpha_confidence='none'")
    from .matting import propagate_defocus_matting
    return propagate_defocus_matting(sparse_sigma, reference, lam=params.matting_lambda,
                                     epsilon=params.matting_epsilon, tol=params.matting_tol,
                                     data_weight=params.matting_data_weight, step_tol=params.matting_step_tol)


#: name -> fn(sparse_sigma, reference, *, params, confidence) -> (H, W) float64 σ in px.
PROPAGATION_METHODS = Registry("propagation", {
    "colorization": Entry(_colorization, "Bae & Durand Eq. (4) (Levin et al. 2004 affinities)"),
    "matting_laplacian": Entry(_matting_laplacian, "Zhuo & Sim 2011 (Levin et al. 2008 matting Laplacian)"),
})


def propagate_blur_measures(sparse_sigma, reference, *, params, confidence=None, max_confidence=1.0) -> np.ndarray:
    """Dense blur map from sparse measures with the registered method ``params.propagation``.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels (e.g. after Eq. 3); NaN elsewhere.
    reference : ndarray, HxWx3, float in [0, 1]
        Guide image (the RGB photo).
    params : PropagationParams or DefocusParams, keyword-only
    confidence : ndarray, HxW, float in [0, 1], or None, keyword-only
        Per-edge confidence (α_p = α·c_p); None: the paper's constant α_p.
    max_confidence : float, keyword-only
        Largest accepted c_p (1; more for fused region terms, :mod:`method.propagation.cue_fusion`).

    Returns
    -------
    ndarray, HxW, float64
        Dense σ, px (not clipped).

    Raises
    ------
    ValueError
        Unknown method (the message lists :data:`PROPAGATION_METHODS`), or bad inputs.
    """
    fn = PROPAGATION_METHODS.resolve(params.propagation, what="DefocusParams.propagation")
    if max_confidence == 1.0:
        return np.asarray(fn(sparse_sigma, reference, params=params, confidence=confidence), dtype=np.float64)
    return np.asarray(fn(sparse_sigma, reference, params=params, confidence=confidence,
                         max_confidence=max_confidence), dtype=np.float64)
