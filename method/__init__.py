"""Bae & Durand 2007, "Defocus Magnification": the method as pure numerics (arrays in, arrays out).

>>> from method import DefocusParams, estimate_defocus_map, magnify_defocus
>>> result = estimate_defocus_map(image, DefocusParams())          # doctest: +SKIP
>>> out = magnify_defocus(image, result.defocus_map, factor=2.0)  # doctest: +SKIP

Subpackages, in the order of the paper's pipeline (:func:`estimate_defocus_map` runs them):
:mod:`method.edges` (Sec. 3.1, Eq. 7–9), :mod:`method.blur` (Sec. 3.2: σ at edges and over textured
regions), :mod:`method.refine` (Eq. 3), :mod:`method.propagation` (Eq. 4 and the cue fusion),
:mod:`method.magnify` (Sec. 5: magnification, refocusing, working resolution); each stage's parameters
are a frozen dataclass in its subpackage (``params.py``). :mod:`method.params` holds :class:`DefocusParams`,
which composes them, :mod:`method.presets` the named parameter sets (:data:`PRESETS`), and
:mod:`method.registry` the :class:`~method.registry.Registry` type every choice by name is a key of.
:mod:`method.luma` holds the input's light: what an image's values are (``ENCODINGS``: ``"srgb"``,
``"linear"``, ``"gamma1.8"``, ``"gamma2.2"``, ``"filmic"``; ``estimate_defocus_map(image, params,
encoding=...)``, which also takes ``"auto"``: the curve fitted per image, :mod:`method.edges.tone_curve`)
and the lights the stages measure or blend in (``LIGHTS``: ``"display"``, ``"linear"``).
"""

from .blur import BLUR_ESTIMATORS, REGION_ESTIMATORS, estimate_blur, estimate_region_blur
from .edges import EdgeMap, detect_edges
from .magnify import (DECONVOLUTION_METHODS, MAGNIFICATION_KERNELS, MAGNIFICATION_RENDERERS, deconvolve_defocus,
                      magnify_defocus, preprocess_defocus_map, refocus)
from .params import DefocusParams
from .presets import PRESETS
from .pipeline import DefocusResult, NoEdgesWarning, estimate_defocus_map, luminance
from .propagation import PROPAGATION_METHODS, PROPAGATION_SOLVERS, propagate_blur_measures, propagate_defocus
from .refine import BILATERAL_METHODS, biased_cross_bilateral
from .registry import Entry, Registry

__all__ = [
    "BILATERAL_METHODS",
    "BLUR_ESTIMATORS",
    "DECONVOLUTION_METHODS",
    "MAGNIFICATION_KERNELS",
    "MAGNIFICATION_RENDERERS",
    "PRESETS",
    "PROPAGATION_METHODS",
    "PROPAGATION_SOLVERS",
    "REGION_ESTIMATORS",
    "DefocusParams",
    "Entry",
    "Registry",
    "DefocusResult",
    "EdgeMap",
    "NoEdgesWarning",
    "biased_cross_bilateral",
    "deconvolve_defocus",
    "detect_edges",
    "estimate_blur",
    "estimate_defocus_map",
    "estimate_region_blur",
    "luminance",
    "magnify_defocus",
    "preprocess_defocus_map",
    "propagate_blur_measures",
    "propagate_defocus",
    "refocus",
]
