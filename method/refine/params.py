"""Parameters of the refinement of the sparse measures: the biased cross-bilateral filter, Eq. (3) (Sec. 3.3).

Blur in px of the input image; σs and σr are fractions of the image size and value range as the paper
gives them. Measurements behind the values beyond the paper: docs/presets.md ("Per-field measurements").
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..registry import Registry
from ..validation import check_field_choice, invalid_field, is_integer, require_field
from .cross_bilateral import BILATERAL_METHODS, RANGE_KERNELS

__all__ = ["BIAS_REFERENCES", "BIAS_WEIGHTINGS", "RefineParams", "bias_strength"]

_INF = float("inf")

#: ``RefineParams.bias_reference``: the unit of ``bias_scale`` (Eq. 3's sharpness bias).
BIAS_REFERENCES = Registry("bias reference", {"px": "σ in px", "image_fraction": "a fraction of max(H, W)"})

#: ``RefineParams.bias_weighting``: where Eq. (3)'s sharpness bias acts.
BIAS_WEIGHTINGS = Registry("bias weighting", {
    "uniform": "b(BM) on every measure (the paper)",
    "uncertainty": "b(BM)^(1 − c_q): only as far as the measure is uncertain (c_q its confidence)",
})


@dataclasses.dataclass(frozen=True, kw_only=True)
class RefineParams:
    """The biased cross-bilateral filter of the sparse measures, Eq. (3) (Sec. 3.3).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``).
    """

    refine: bool = True
    # run the refinement of Eq. (3); False passes the sparse measures on unchanged (Zhuo & Sim's public
    # code has no correction step between its measures and the propagation).
    bilateral_sigma_spatial: float = 0.10
    # σs as a fraction of the image size max(H, W), dimensionless (Sec. 3.3: "10 % of the image size").
    bilateral_sigma_range: float = 0.10
    # σr as a fraction of the reference image's value range (Sec. 3.3: "10 % of the image range").
    sharpness_bias: bool = True
    # apply b(BM) = exp(−BM / bias_scale) (Eq. 3); False gives the plain cross-bilateral ablation.
    bias_scale: float = 2.0
    # denominator of the sharpness bias exp(−BM/2), px (Sec. 3.3), or a fraction of max(H, W) with
    # bias_reference "image_fraction".
    bilateral_method: str = "grid"
    # key of method.refine.cross_bilateral.BILATERAL_METHODS: "grid" (fast bilateral grid) or
    # "brute_force" (O(N·M) reference oracle).
    bilateral_range_kernel: str = "sum"
    # the colour term of w_pq in Eq. (3b) (key of RANGE_KERNELS): "sum" (paper: Σ_i g_σr(|C_i(p) − C_i(q)|))
    # or "product" (beyond the paper: Π_i g_σr(…) = g_σr(‖C(p) − C(q)‖), a joint-colour kernel; with the
    # sum a pixel that matches in one channel only still gets 1/3 of the weight).
    bias_reference: str = "px"
    # key of BIAS_REFERENCES, the unit of bias_scale: "px" (paper: BM in px, so the bias depends on the
    # image resolution) or "image_fraction" (beyond the paper: a fraction of max(H, W)).
    bias_weighting: str = "uniform"
    # key of BIAS_WEIGHTINGS, where the sharpness bias acts (sharpness_bias True): "uniform" (paper: every
    # measure's weight times b(BM)) or "uncertainty" (beyond the paper: times b(BM)^(1 − c_q), c_q the
    # measure's confidence in (0, 1] (measure_weighting="uncertainty"), so a measure the noise pins
    # down keeps its value and an uncertain one is pulled toward sharp as the paper does).
    refinement_robust_iterations: int = 0
    # beyond the paper: re-weighted iterations of Eq. (3) (an M-estimator): after each pass every measure
    # q is down-weighted by the Cauchy weight 1/(1 + (r_q / c)²) of its residual r_q from its refined
    # value, c = refinement_robust_scale·(bCBF_q + 0.5 px). 0: paper (one pass).
    refinement_robust_scale: float = 0.5
    # Cauchy scale of the re-weighting above, dimensionless (a fraction of the refined value plus 0.5 px:
    # relative errors, as blur grows with σ).

    def __post_init__(self):
        require_field(self, "refine", isinstance(self.refine, bool), "True or False")
        for name in ("bilateral_sigma_spatial", "bilateral_sigma_range", "bias_scale"):
            require_field(self, name, getattr(self, name) > 0, "> 0")
        check_field_choice(self, "bilateral_method", BILATERAL_METHODS)
        check_field_choice(self, "bilateral_range_kernel", RANGE_KERNELS)
        check_field_choice(self, "bias_reference", BIAS_REFERENCES)
        check_field_choice(self, "bias_weighting", BIAS_WEIGHTINGS)
        if self.bias_weighting != "uniform" and not self.sharpness_bias:
            raise invalid_field("bias_weighting", self.bias_weighting,
                                "'uniform' unless sharpness_bias=True (there is no bias to weigh)")
        require_field(self, "refinement_robust_iterations", is_integer(self.refinement_robust_iterations, 0),
                      "integer >= 0")
        require_field(self, "refinement_robust_scale", 0 < self.refinement_robust_scale < _INF, "finite and > 0")


def bias_strength(sparse_sigma, confidence, params):
    """Per-measure exponent 1 − c_q of Eq. (3)'s sharpness bias, or None for the paper's uniform bias.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at the measures; NaN elsewhere (gives the shape when ``confidence`` is None).
    confidence : ndarray, HxW, float in (0, 1], or None
        Per-measure confidence c_q (NaN off measures); None: every measure certain.
    params : RefineParams or DefocusParams
        ``bias_weighting`` and ``sharpness_bias``.

    Returns
    -------
    ndarray, HxW, float64, or None
        1 − c_q at the measures, 0 elsewhere, with ``bias_weighting="uncertainty"`` and the bias on;
        None otherwise (the bias of Eq. (3) acts on every measure alike).
    """
    if params.bias_weighting != "uncertainty" or not params.sharpness_bias:
        return None
    if confidence is None:
        return np.zeros(np.shape(sparse_sigma))
    return np.where(np.isfinite(confidence), 1.0 - np.asarray(confidence, dtype=np.float64), 0.0)
