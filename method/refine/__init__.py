"""Refinement of the sparse blur measures (Eq. 3): the biased cross-bilateral filter and its parameters
(:class:`.params.RefineParams`)."""

from .cross_bilateral import BILATERAL_METHODS, RANGE_KERNELS, biased_cross_bilateral, sharpness_bias
from .params import BIAS_REFERENCES, RefineParams

__all__ = ["BIAS_REFERENCES", "BILATERAL_METHODS", "RANGE_KERNELS", "RefineParams", "biased_cross_bilateral", "sharpness_bias"]
