"""Region blur by a Gaussian-scale-mixture likelihood (after Chakrabarti, Zickler & Freeman 2010; beyond the paper).

Chakrabarti, Zickler & Freeman, "Analyzing spatially-varying blur", CVPR 2010, model local Fourier
coefficients of derivative-filtered images as a Gaussian scale mixture: for a candidate kernel K the
blurred coefficients are zero-mean Gaussians of variance z·|K(ω)|²·S(ω) + noise, with the hidden
scale z drawn from a mixture, and each kernel is scored by the likelihood with z integrated out.

Here the same windowed ring spectra and exact leakage model as :mod:`method.blur.local_spectrum`
are used; the difference is the scale: one hidden z per window under a scale-invariant
(log-uniform) mixture prior, integrated by Laplace's method in log z, instead of maximised. The
paper's per-coefficient mixture with learned weights is not implemented (a measured variant).
"""

from __future__ import annotations

from .local_spectrum import PSF_MODELS, local_spectrum_grid, spread_to_pixels

__all__ = ["estimate_blur_gsm"]


def estimate_blur_gsm(gray, *, params, edge_psf=None):
    """Region blur σ and its information per pixel from the scale-mixture likelihood.

    Parameters
    ----------
    gray : ndarray, HxW, float in [0, 1]
        Luminance of the sRGB input.
    params : RegionParams or DefocusParams, keyword-only
        The ``region_*`` fields (as :func:`method.blur.local_spectrum.estimate_blur_local_spectrum`).
    edge_psf : {"gaussian", "disk"} or None, keyword-only
        The edge fit's PSF family, used with ``params.region_psf == "edges"``.

    Returns
    -------
    sigma : ndarray, HxW, float64
        Blur σ, px; NaN without a measure.
    information : ndarray, HxW, float64
        Fisher-information density of σ, 1/px² per pixel; 0 without a measure.

    Notes
    -----
    1. Ring spectra and model tables as in :func:`~method.blur.local_spectrum.local_spectrum_grid`.
    2. Per σ of the grid: −log p(P | σ) ≈ NLL(σ, ẑ) + ½ log(ẑ² I_zz) (log-uniform prior on z,
       Laplace's method in log z), then the grid minimum, a parabola, and the Fisher information.
    """
    psf = params.region_psf
    if psf == "edges":
        psf = edge_psf if edge_psf is not None else "gaussian"
    PSF_MODELS.check(psf, what="edge_psf")
    out = local_spectrum_grid(gray, psf=psf, noise_model=params.region_noise_model,
                              sigma_min=params.region_sigma_min, sigma_max=params.region_sigma_max,
                              window_min=params.region_window_min, window_max=params.region_window_max,
                              window_scale=params.region_window_scale, stride=params.region_stride,
                              likelihood="gsm")
    sigma, info = spread_to_pixels(out, gray.shape)
    return sigma, info / float(params.region_stride) ** 2
