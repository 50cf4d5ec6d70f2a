"""Defocus magnification and refocusing (Sec. 5), and the working-resolution wrapper for large photos.

Modules: :mod:`.magnification` (blur by the magnified map; the renderer registry and the gather),
:mod:`.map_floor` (Sec. 5's preprocessing of the map; its in-focus floor, the focus point and keep-sharp mask),
:mod:`.scatter` and :mod:`.scatter_kernels` (the scatter renderer: per-pixel disks in linear light with
occlusion layers), :mod:`.refocusing` (deconvolution and re-blur, Fig. 8), :mod:`.upsampling` (estimate
at a working resolution, guided upsampling, tiled magnification); :mod:`.params` (:class:`.params.MagnifyParams`).
"""

from .magnification import (MAGNIFICATION_KERNELS, MAGNIFICATION_RENDERERS, MAP_FLOOR_MODES,
                            magnify_defocus, preprocess_defocus_map)
from .refocusing import DECONVOLUTION_METHODS, deconvolve_defocus, refocus
from .scatter import APERTURES, scatter_blur
from .params import MagnifyParams

__all__ = ["APERTURES", "DECONVOLUTION_METHODS", "MAGNIFICATION_KERNELS",
           "MAGNIFICATION_RENDERERS", "MAP_FLOOR_MODES", "MagnifyParams", "deconvolve_defocus", "magnify_defocus",
           "preprocess_defocus_map", "refocus", "scatter_blur"]
