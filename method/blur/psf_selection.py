"""Beyond the paper: which edge-blur model the model fit keeps (``DefocusParams.fit_psf``).

``"disk"`` and ``"best"`` replace the Gaussian fits by the disk-blurred step's fits everywhere or per
edge (:func:`choose_psf`); ``"auto"`` decides once per image (:func:`select_psf_model`) on a sample of
the resolved edges (:func:`psf_selection_sample`).
"""

from __future__ import annotations

import math

import numpy as np

from .fit_templates import blur_from_extrema_distance

__all__ = ["PSF_SELECT_MAX_RESIDUAL", "PSF_SELECT_MIN_EDGES", "PSF_SELECT_MIN_WIDTH", "PSF_SELECT_SAMPLE",
           "choose_psf", "psf_selection_sample", "select_psf_model"]



#: "auto" decides on the edges whose blur is resolved (fitted width s > PSF_SELECT_MIN_WIDTH · σ2,
#: i.e. σb > 1.1 σ2) and that one of the two models fits closely (residual < PSF_SELECT_MAX_RESIDUAL):
#: isolated edges, where the PSF's shape shows; texture interference dominates the other residuals.
PSF_SELECT_MIN_WIDTH = 1.5
PSF_SELECT_MAX_RESIDUAL = 0.01
PSF_SELECT_MIN_EDGES = 5
#: At most this many candidate edges get the disk fit before "auto" decides (a deterministic sample).
PSF_SELECT_SAMPLE = 4000


def psf_selection_sample(width, sigma2):
    """Edge pixels whose disk fit ``select_psf_model`` needs: resolved blur, at most PSF_SELECT_SAMPLE of them.

    Candidates have a finite Gaussian width s > PSF_SELECT_MIN_WIDTH · σ2; beyond PSF_SELECT_SAMPLE
    candidates every k-th one in raster order is kept (deterministic; the statistic is a mean).
    ``width`` and ``sigma2`` (px) are the image's (H, W) or its fitted pixels' in raster order (N,):
    the same pixels are chosen (the others have no width).
    """
    with np.errstate(invalid="ignore"):
        cand = np.isfinite(width) & (width > PSF_SELECT_MIN_WIDTH * sigma2)
    idx = np.flatnonzero(cand)
    if idx.size > PSF_SELECT_SAMPLE:
        cand = np.zeros_like(cand)
        cand.flat[idx[:: int(math.ceil(idx.size / PSF_SELECT_SAMPLE))]] = True
    return cand

def choose_psf(diag, disk_width, disk_res, *, psf, max_sigma):
    """Replace the Gaussian fits of ``diag`` by the disk fits where ``psf`` selects the disk (in place)."""
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(disk_width)
        take = finite if psf == "disk" else finite & ~(diag["residual"] <= disk_res)  # "best": per edge
    diag["width"] = np.where(take, disk_width, diag["width"])
    diag["residual"] = np.where(take, disk_res, diag["residual"])
    sigma_b = np.clip(blur_from_extrema_distance(2.0 * diag["width"], diag["sigma2"]), 0.0, max_sigma)
    diag["sigma_b"] = np.where(np.isfinite(diag["width"]), sigma_b, np.nan)
    diag["disk"] = take



def select_psf_model(diag, disk_width, disk_res) -> str:
    """The blur model of ``fit_psf="auto"``: "disk" or "gaussian", one for the whole image.

    Parameters
    ----------
    diag : dict of ndarray, (H, W)
        The Gaussian fit's diagnostics (:func:`model_fit_diagnostics` with ``fit_psf="gaussian"``:
        ``residual``, ``width``, px, ``sigma2``, px).
    disk_width, disk_res : ndarray, (H, W)
        Width s (px) and normalised residual of the disk model's fit on the same windows. All four
        arrays may instead be the fitted pixels' in raster order, (N,): the same choice.

    Returns
    -------
    str
        "disk" when the geometric mean of the disk model's residual over the selecting edges (Notes)
        is below that of Eq. (2c), else "gaussian" (also with fewer than
        :data:`PSF_SELECT_MIN_EDGES` selecting edges: the paper's model by default).

    Notes
    -----
    The PSF's shape is a property of the lens, not of an edge, so the choice is made once per image.
    Per edge the two residuals differ little except on isolated, resolved edges, and even there noise
    decides a per-edge choice often (``fit_psf="best"``). Selecting edges: both fits finite, the
    Gaussian width s > :data:`PSF_SELECT_MIN_WIDTH` · σ2 and min(ρ_gauss, ρ_disk) <
    :data:`PSF_SELECT_MAX_RESIDUAL`. Statistic: the mean of log((ρ_disk + ε)/(ρ_gauss + ε)), ε = 1e-4;
    an energy-weighted sum of residuals was dominated by a few edges and chose wrongly on one of the
    accuracy bench's Gaussian mosaics. Measured (accuracy-bench mosaics, 8 bits + noise 1–2/255,
    seeds 0–1): mean log ratio +0.63 … +3.9 on the 12 Gaussian-blurred mosaics; −0.71 … +0.27 on the
    18 small renders (thin-lens disks), disk chosen on 11 of them.
    """
    with np.errstate(invalid="ignore"):
        sel = (np.isfinite(diag["residual"]) & np.isfinite(disk_res)
               & (diag["width"] > PSF_SELECT_MIN_WIDTH * diag["sigma2"])
               & (np.minimum(diag["residual"], disk_res) < PSF_SELECT_MAX_RESIDUAL))
    if int(sel.sum()) < PSF_SELECT_MIN_EDGES:
        return "gaussian"
    log_ratio = np.log((disk_res[sel] + 1e-4) / (diag["residual"][sel] + 1e-4))
    return "disk" if float(np.mean(log_ratio)) < 0.0 else "gaussian"
