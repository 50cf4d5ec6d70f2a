"""Refinement of the sparse blur measures (Eq. 3): the biased cross-bilateral filter."""

from .cross_bilateral import BILATERAL_METHODS, RANGE_KERNELS, biased_cross_bilateral, sharpness_bias

__all__ = ["BILATERAL_METHODS", "RANGE_KERNELS", "biased_cross_bilateral", "sharpness_bias"]
