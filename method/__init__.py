"""Bae & Durand 2007, "Defocus Magnification": the method as pure numerics (arrays in, arrays out).

>>> from method import DefocusParams, estimate_defocus_map, magnify_defocus
>>> result = estimate_defocus_map(image, DefocusParams())          # doctest: +SKIP
>>> out = magnify_defocus(image, result.defocus_map, factor=2.0)  # doctest: +SKIP

Stages (one module each): :mod:`~method.gaussian_derivatives` and :mod:`~method.noise_thresholds`
(Eq. 7–9), :mod:`~method.elder_zucker_edges` (Sec. 3.1), :mod:`~method.blur_estimators`
(Sec. 3.2: ``model_fit``, ``zero_crossing``, ``gradient_ratio``), :mod:`~method.cross_bilateral`
(Eq. 3), :mod:`~method.propagation` (Eq. 4), :mod:`~method.magnification` (Sec. 5),
:mod:`~method.refocusing` (Sec. 5 / Fig. 8: deconvolution and re-blur).
"""

from .blur_estimators import BLUR_ESTIMATORS, estimate_blur
from .cross_bilateral import BILATERAL_METHODS, biased_cross_bilateral
from .elder_zucker_edges import EdgeMap, detect_edges
from .magnification import MAGNIFICATION_KERNELS, magnify_defocus, preprocess_defocus_map
from .params import PRESETS, DefocusParams
from .pipeline import DefocusResult, NoEdgesWarning, estimate_defocus_map, luminance
from .propagation import PROPAGATION_SOLVERS, propagate_defocus
from .propagation_methods import PROPAGATION_METHODS, propagate_blur_measures
from .refocusing import DECONVOLUTION_METHODS, deconvolve_defocus, refocus

__all__ = [
    "BILATERAL_METHODS",
    "BLUR_ESTIMATORS",
    "DECONVOLUTION_METHODS",
    "MAGNIFICATION_KERNELS",
    "PRESETS",
    "PROPAGATION_METHODS",
    "PROPAGATION_SOLVERS",
    "DefocusParams",
    "DefocusResult",
    "EdgeMap",
    "NoEdgesWarning",
    "biased_cross_bilateral",
    "deconvolve_defocus",
    "detect_edges",
    "estimate_blur",
    "estimate_defocus_map",
    "luminance",
    "magnify_defocus",
    "preprocess_defocus_map",
    "propagate_blur_measures",
    "propagate_defocus",
    "refocus",
]
