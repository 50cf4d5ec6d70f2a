"""Analytic test images with known blur: ground truth without a renderer.

Gaussian blur, point-sampled from closed forms or on a supersampled lattice (Sec. 3.1 / 3.2):

* :mod:`.edges` — :func:`step_edge`, :func:`blurred_disk`, :func:`parallel_edges`;
* :mod:`.leaves` — :func:`dead_leaves`, the scale-invariant occlusion texture;
* :mod:`.mosaics` — :func:`texture_mosaic`: tiles of texture, each blurred by one known σ.

Conventions: pixel (row, col); x = column (right), y = row (down); an edge's normal angle θ is
the direction in which intensity increases, u = (cos θ, sin θ) in (x, y) — the same convention as
``method.edges.gaussian_derivatives``. Images are float64 in [0, 1].

This package must not import ``method`` (it is the ground truth the method is tested against).
"""

from ._common import degrade
from .leaves import dead_leaves
from .edges import AnalyticImage, blurred_disk, parallel_edges, step_edge
from .mosaics import (SKIMAGE_DOWNSAMPLE, SKIMAGE_IMAGES, SKIMAGE_INTRINSIC_SIGMA_PX, SKIMAGE_NATIVE_SIGMA_PX,
                      TEXTURES, TextureMosaic, texture_mosaic)

__all__ = [
    "SKIMAGE_DOWNSAMPLE",
    "SKIMAGE_IMAGES",
    "SKIMAGE_INTRINSIC_SIGMA_PX",
    "SKIMAGE_NATIVE_SIGMA_PX",
    "TEXTURES",
    "AnalyticImage",
    "TextureMosaic",
    "blurred_disk",
    "dead_leaves",
    "degrade",
    "parallel_edges",
    "step_edge",
    "texture_mosaic",
]
