"""Edge detection (Sec. 3.1): Gaussian derivative filters, the noise thresholds of Eq. (7–9), the
Elder–Zucker multi-scale detector the paper uses, Canny (Zhuo & Sim's detector) and the isolation gate.

Modules: :mod:`.gaussian_derivatives` (sampled derivative kernels, steering), :mod:`.noise_thresholds`
(Eq. 7–9), :mod:`.elder_zucker` (the paper's detector), :mod:`.canny`, :mod:`.isolation`; the stage's
parameters :class:`.params.EdgeParams`; :mod:`.tone_curve` (beyond the paper: the input's tone curve
fitted from the point symmetry of its strongest edges, ``encoding="auto"``).
"""

from .canny import detect_edges_canny
from .elder_zucker import MIN_IMAGE_SIZE, EdgeMap, check_edge_inputs, detect_edges, edge_pixels_by_scale
from .gaussian_derivatives import GaussianDerivativeBank, gaussian_derivative, sampled_kernel
from .isolation import EDGE_ISOLATION_METHODS, isolation_weights
from .noise_thresholds import (NOISE_SPECTRA, NoiseSpectrum, first_derivative_threshold, per_pixel_false_positive_rate,
                               second_derivative_threshold)
from .params import EDGE_DETECTORS, EdgeParams
from .tone_curve import INPUT_ENCODINGS, ToneCurveFit, fit_encoding, resolve_encoding

__all__ = ["EDGE_DETECTORS", "EDGE_ISOLATION_METHODS", "INPUT_ENCODINGS", "MIN_IMAGE_SIZE", "NOISE_SPECTRA", "EdgeMap",
           "EdgeParams", "NoiseSpectrum",
           "GaussianDerivativeBank", "ToneCurveFit", "check_edge_inputs", "fit_encoding", "resolve_encoding",
           "detect_edges", "detect_edges_canny", "edge_pixels_by_scale", "first_derivative_threshold",
           "gaussian_derivative", "isolation_weights", "per_pixel_false_positive_rate", "sampled_kernel",
           "second_derivative_threshold"]
