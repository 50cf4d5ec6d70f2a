"""Defocus magnification and refocusing (Sec. 5), and the working-resolution wrapper for large photos.

Modules: :mod:`.magnification` (blur by the magnified map), :mod:`.refocusing` (deconvolution and
re-blur, Fig. 8), :mod:`.upsampling` (estimate at a working resolution, guided upsampling).
"""

from .magnification import MAGNIFICATION_KERNELS, MAP_FLOOR_MODES, magnify_defocus, preprocess_defocus_map
from .refocusing import DECONVOLUTION_METHODS, deconvolve_defocus, refocus

__all__ = ["DECONVOLUTION_METHODS", "MAGNIFICATION_KERNELS", "MAP_FLOOR_MODES", "deconvolve_defocus",
           "magnify_defocus", "preprocess_defocus_map", "refocus"]
