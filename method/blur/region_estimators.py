"""Registry of region (spectral) blur estimators, chosen by ``DefocusParams.region_estimator``.

The edge estimators of :mod:`method.blur.estimators` measure σ at edge pixels with a confidence in
(0, 1]; a region estimator measures σ over windows of texture and weighs each measure by its Fisher
information. Every entry has the signature ``fn(gray, *, params, edge_psf=None) -> (sigma,
information)``, both float64 HxW: σ in px (NaN where there is no measure: flat or noise-only
regions) and the information density of σ in 1/px² per pixel (0 where σ is NaN).
"""

from __future__ import annotations

import numpy as np

from .gsm import estimate_blur_gsm
from .local_spectrum import NOISE_MODELS, PSF_MODELS, estimate_blur_local_spectrum
from ..registry import Entry, Registry

__all__ = ["REGION_ESTIMATORS", "REGION_NOISE_MODELS", "REGION_PSFS", "estimate_region_blur"]

#: name -> fn(gray, *, params, edge_psf=None) -> (σ px, information 1/px²), both float64 HxW.
REGION_ESTIMATORS = Registry("region estimator", {
    "local_spectrum": Entry(estimate_blur_local_spectrum,
                            "Zhu et al. 2013: profiled ML of windowed gradient spectra"),
    "gsm": Entry(estimate_blur_gsm, "Chakrabarti et al. 2010: scale-mixture likelihood"),
})
#: Allowed ``DefocusParams.region_psf``: the likelihood's kernels, or "edges" (the edge fit's choice).
REGION_PSFS = Registry("region PSF", {**{n: PSF_MODELS.entry(n) for n in PSF_MODELS},
                                      "edges": "the PSF family the edge fit chose"})
#: Allowed ``DefocusParams.region_noise_model``.
REGION_NOISE_MODELS = NOISE_MODELS


def estimate_region_blur(gray, *, params, edge_psf=None):
    """Region blur σ and its information, by the estimator ``params.region_estimator``.

    Parameters
    ----------
    gray : ndarray, HxW (or HxWx3: its ``method.luma.luminance`` is used), float in [0, 1]
        Luminance of the sRGB input, as the edge fit sees it.
    params : RegionParams or DefocusParams, keyword-only
        ``region_estimator`` must be a key of :data:`REGION_ESTIMATORS` (not None).
    edge_psf : {"gaussian", "disk"} or None, keyword-only
        The PSF family the edge fit chose (used with ``params.region_psf == "edges"``).

    Returns
    -------
    sigma : ndarray, HxW, float64
        Blur σ, px; NaN where there is no measure.
    information : ndarray, HxW, float64
        Fisher-information density of σ, 1/px² per pixel; 0 where σ is NaN.

    Raises
    ------
    ValueError
        ``params.region_estimator`` None or unknown, ``edge_psf`` not allowed, or a bad image
        (not 2-D / HxWx3, non-finite, or smaller than 17×17 px).

    Notes
    -----
    1. Validate the options and the image (luminance if colour).
    2. Dispatch to ``REGION_ESTIMATORS[params.region_estimator]``.
    3. Check the contract: shapes, NaN/0 agreement, information ≥ 0.
    """
    from ..luma import luminance

    name = params.region_estimator
    REGION_ESTIMATORS.check(name, what="region_estimator")
    PSF_MODELS.check(edge_psf, what="edge_psf", optional=True)
    g = np.asarray(gray)
    if not (g.ndim == 2 or (g.ndim == 3 and g.shape[2] == 3)):
        raise ValueError(f"gray has shape {g.shape}; allowed: HxW or HxWx3")
    g = luminance(g.astype(np.float64, copy=False))
    if min(g.shape) < 17:
        raise ValueError(f"gray has shape {g.shape}; allowed: at least 17x17 px (one 16-px gradient window)")
    if not np.all(np.isfinite(g)):
        raise ValueError("gray has non-finite values; allowed: finite values in [0, 1]")
    sigma, info = REGION_ESTIMATORS[name](g, params=params, edge_psf=edge_psf)
    sigma = np.asarray(sigma, dtype=np.float64)
    info = np.asarray(info, dtype=np.float64)
    assert sigma.shape == g.shape and info.shape == g.shape
    info = np.where(np.isfinite(sigma), np.maximum(info, 0.0), 0.0)
    return sigma, info
