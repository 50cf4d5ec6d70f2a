"""Parameters of the blur stages: σ at the edges (Sec. 3.2, Eq. 2) and, beyond the paper, σ over textured
regions from the local spectrum (the region cue fused into Eq. 4).

Every blur quantity is a Gaussian σ in px of the input image. Measurements behind the values beyond
the paper: docs/presets.md ("Per-field measurements"), docs/region-blur.md, docs/zhuo-sim.md.
"""

from __future__ import annotations

import dataclasses

from ..registry import Registry
from ..validation import check_field_choice, invalid_field, is_integer, require_field
from .estimators import BLUR_ESTIMATORS
from .local_spectrum import REGION_GATES
from .measure_uncertainty import MEASURE_WEIGHTINGS
from .model_fit import FIT_PSF_MODELS
from .region_estimators import REGION_ESTIMATORS, REGION_NOISE_MODELS, REGION_PSFS
from .step_plateau import GAUSSIAN_STEP_REACH, STEP_GATES

__all__ = ["BELOW_SCALE_RULES", "BlurParams", "RegionParams"]

_INF = float("inf")

#: ``BlurParams.fit_below_scale``: a fitted blur narrower than the σ2 that detected the edge.
BELOW_SCALE_RULES = Registry("below-scale rule", {"zero": "kept (the paper)", "nan": "dropped as unresolved"})


@dataclasses.dataclass(frozen=True, kw_only=True)
class BlurParams:
    """The blur estimator at edge pixels and its fit options (Sec. 3.2).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``).
    """

    estimator: str = "model_fit"
    # key of method.blur.estimators.BLUR_ESTIMATORS: "model_fit" (Eq. 2c, paper), "model_fit_checked"
    # (with a residual test), "zero_crossing" (Elder–Zucker), "gradient_ratio" (Zhuo & Sim 2011).
    fit_window_min: int = 3
    # smallest model-fit window, px (Sec. 3.2: "window sizes from 3×3 to 71×71").
    fit_window_max: int = 71
    # largest model-fit window, px (Sec. 3.2).
    max_sigma: float = 64.0
    # largest blur σ reported, px; estimates (and the dense map of Eq. 4) are clipped to [0, max_sigma].
    fit_max_residual: float = 0.05
    # beyond the paper (estimator "model_fit_checked"): largest normalised residual ρ of the Eq. (2c)
    # fit (residual sum of squares / energy of the sampled response in the fit window; dimensionless,
    # in [0, 1]) for which a σb is returned; a poorer fit gives NaN. 1 keeps every estimate.
    fit_residual_noise: float = 0.0
    # beyond the paper (estimator "model_fit_checked"): k, dimensionless; the residual test becomes
    # ρ ≤ fit_max_residual + k·N·v_n(σ2)/‖r‖² (N samples in the window, ‖r‖² their energy, v_n(σ2) the
    # variance of the steered 2nd-derivative response to white noise of std noise_std;
    # method.blur.model_fit_checked.noise_residual_share): the noise's expected share of ρ, which grows
    # with the response width, so a fixed limit would keep only the narrower fits of blurry edges.
    # 0: a fixed limit (fit_max_residual alone).
    relaxed_fit_weight: float = 1.0
    # beyond the paper (estimator "model_fit_checked" with fit_residual_noise > 0): confidence c_q,
    # dimensionless in (0, 1], of the measures that pass the residual test only thanks to the noise
    # allowance; the others have c_q = 1. c_q multiplies the measure's weight in Eq. (3) and its α_p in
    # Eq. (4), so relaxed measures decide the map only where no strict measure is near. 1: off.
    measure_weighting: str = "hand"
    # beyond the paper (estimator "model_fit_checked"; other estimators report no fit to weigh, so it has no
    # effect with them): what gives each measure its confidence c_q in
    # Eq. (3) and in α_p of Eq. (4) (key of method.blur.measure_uncertainty.MEASURE_WEIGHTINGS): "hand"
    # (1, or relaxed_fit_weight as above; the paper: every c_q = 1) or "uncertainty" (c_q ∝ 1/Var(σb), the
    # Cramér–Rao variance of the fit's width from its residual and curvature under the pixel's noise,
    # normalised to the image's median measure; relaxed_fit_weight unused).
    fit_scale_ratio: float = 1.0
    # beyond the paper: the Eq. (2c) fit samples the responses at min(σ2(p), max(fit_scale_ratio·σ2(p),
    # min(sigma2_scales))) px (then capped by fit_max_scale), dimensionless; 1: the detector's minimum
    # reliable σ2(p) (paper).
    fit_max_scale: float | None = None
    # beyond the paper: fit Eq. (2c) to the responses at min(σ2(p), fit_max_scale) px: at coarse σ2 the
    # fit window spans neighbouring texture edges that widen the response. None: the paper (σ2(p)).
    fit_follow_scale: float | None = None
    # beyond the paper (estimator "model_fit_checked"): r = σ2 / σ̂, dimensionless in (0, 1]; where the
    # detector's σ2(p) exceeds the capped fit scale, a coarse fit at σ2(p) gives σ̂c and the edge is
    # re-fitted at the sigma2_scales value nearest r·σ̂c (in log), its window grown to hold the response
    # (method.blur.scale_follow): large blur is fitted at a scale that sees it. None: off.
    fit_follow_max_residual: float = 1.0
    # beyond the paper (with fit_follow_scale): largest normalised residual ρ (dimensionless, in [0, 1];
    # as fit_max_residual, no noise allowance) of the coarse fit for an edge to be re-fitted, and of the
    # re-fit for its measure to replace the first fit's: a blurred step fits both almost exactly
    # (ρ ≤ 0.005 at σ 8–16 px), in-focus texture widened by its neighbours at coarse σ2 does not
    # (ρ ≈ 0.03–0.26). 1: no test.
    fit_min_samples: int = 3
    # beyond the paper: fewest response samples in the fit window for a measure (NaN below); 3 (the
    # smallest window, paper) fits (s, t0) exactly and lets noise choose any width.
    fit_max_width_ratio: float = float("inf")
    # beyond the paper: largest fitted width s = d/2 as a fraction of the fit window's half-length
    # (wider fits extrapolate beyond the samples), dimensionless. inf: paper.
    fit_below_scale: str = "zero"
    # key of BELOW_SCALE_RULES, what d/2 ≤ σ2 gives (Eq. 2d has no real root): "zero" (paper: σb = 0) or
    # "nan" (no measure unless σ2 is the finest scale, where it is a sharp edge).
    fit_psf: str = "gaussian"
    # the blur model whose step response the fit matches (key of method.blur.model_fit.FIT_PSF_MODELS):
    # "gaussian" (Eq. 2c, paper), "disk" (a uniform disk, the thin lens's defocus;
    # method.blur.disk_edge_response), "best" (both, per edge the smaller residual) or "auto" (both, one
    # model per image: method.blur.model_fit.select_psf_model). Every model reports the per-axis std of
    # its PSF through Eq. (2d) (a disk of diameter c: c/4).
    fit_step_gate: str = "none"
    # beyond the paper (estimator "model_fit_checked"): the test of the image profile across each measured
    # edge that tells shading and shadows from a defocus-blurred step (key of
    # method.blur.step_plateau.STEP_GATES): "none" (paper), "plateau" (no measure where the profile has no
    # plateau 1.5σb–3σb from the edge) or "plateau_flat" (also where a side keeps changing there).
    fit_plateau_reach: float = 0.5
    # beyond the paper (fit_step_gate other than "none"): smallest reach of a kept measure on each side,
    # dimensionless: the mean level 1.5σb–3σb from the edge over the level at σb, both from the profile's
    # midpoint (method.blur.step_plateau.plateau_profile; a Gaussian step 1.40, a cosine read as blur −0.27;
    # 0.5 chosen on dev over 1: docs/presets.md).
    ratio_gradient_sigma: float = 0.5
    # σg of the Gaussian-derivative gradient |∇I| of estimator "gradient_ratio", px (Eq. 7 kernels);
    # 0.5: the smallest Elder–Zucker scale (Zhuo & Sim's public code: 1).
    ratio_reblur_sigma: float = 1.0
    # σ0 of Zhuo & Sim's re-blur, px: R = |∇I|_σg / |∇I|_√(σg² + σ0²), σ = √(σ0²/(R² − 1) − σg²); 1: their
    # paper's σ0 (their public code: √1.25).
    ratio_max_sigma: float | None = None
    # largest σ "gradient_ratio" reports, px (larger estimates are clipped to it); None: max_sigma.
    ratio_zero_is_measure: bool = True
    # whether a "gradient_ratio" estimate of 0 px (R ≥ √(σg² + σ0²)/σg: sharper than the gradient
    # resolves) is a measure (True) or NaN (False: as Zhuo & Sim's public propagation, whose data weight
    # is σ̂ itself). R ≤ 1 (noise, or a very blurry edge) is NaN either way.

    def __post_init__(self):
        check_field_choice(self, "estimator", BLUR_ESTIMATORS)
        require_field(self, "fit_window_min", is_integer(self.fit_window_min, 3), "integer >= 3")
        require_field(self, "fit_window_max", is_integer(self.fit_window_max, 3)
                      and self.fit_window_max >= self.fit_window_min, "integer >= fit_window_min")
        require_field(self, "max_sigma", self.max_sigma > 0, "> 0")
        require_field(self, "fit_max_residual", 0 <= self.fit_max_residual <= 1,
                      "0 <= ρ_max <= 1 (dimensionless normalised residual)")
        require_field(self, "fit_residual_noise", 0 <= self.fit_residual_noise < _INF,
                      "finite and >= 0 (dimensionless)")
        require_field(self, "relaxed_fit_weight", 0 < self.relaxed_fit_weight <= 1,
                      "0 < c <= 1 (dimensionless confidence)")
        check_field_choice(self, "measure_weighting", MEASURE_WEIGHTINGS)
        require_field(self, "fit_scale_ratio", 0 < self.fit_scale_ratio <= 1, "0 < ratio <= 1 (dimensionless)")
        if self.fit_max_scale is not None and not self.fit_max_scale > 0:
            raise invalid_field("fit_max_scale", self.fit_max_scale, "None or > 0 (px)")
        if self.fit_follow_scale is not None and not 0 < self.fit_follow_scale <= 1:
            raise invalid_field("fit_follow_scale", self.fit_follow_scale, "None or 0 < r <= 1 (dimensionless)")
        require_field(self, "fit_follow_max_residual", 0 <= self.fit_follow_max_residual <= 1,
                      "0 <= ρ <= 1 (dimensionless normalised residual; 1: no test)")
        require_field(self, "fit_min_samples", is_integer(self.fit_min_samples, 3), "integer >= 3")
        require_field(self, "fit_max_width_ratio", self.fit_max_width_ratio > 0, "> 0 (inf: no limit)")
        check_field_choice(self, "fit_below_scale", BELOW_SCALE_RULES)
        check_field_choice(self, "fit_psf", FIT_PSF_MODELS)
        check_field_choice(self, "fit_step_gate", STEP_GATES)
        require_field(self, "fit_plateau_reach", 0 <= self.fit_plateau_reach < GAUSSIAN_STEP_REACH,
                      f"0 <= reach < {GAUSSIAN_STEP_REACH} (dimensionless; a Gaussian step's reach)")
        for name in ("ratio_gradient_sigma", "ratio_reblur_sigma"):
            require_field(self, name, 0 < getattr(self, name) < _INF, "finite and > 0 (px)")
        if self.ratio_max_sigma is not None and not (0 < self.ratio_max_sigma < _INF):
            raise invalid_field("ratio_max_sigma", self.ratio_max_sigma, "None or finite and > 0 (px)")
        require_field(self, "ratio_zero_is_measure", isinstance(self.ratio_zero_is_measure, bool), "True or False")


@dataclasses.dataclass(frozen=True, kw_only=True)
class RegionParams:
    """The region (spectral) blur estimator, beyond the paper (method.blur.region_estimators).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``).
    """

    region_estimator: str | None = None
    # key of method.blur.region_estimators.REGION_ESTIMATORS: "local_spectrum" (Zhu et al., IEEE TIP
    # 2013) or "gsm" (Chakrabarti et al., CVPR 2010); None: no region measure (paper).
    region_psf: str = "gaussian"
    # blur kernel of the region likelihood (key of REGION_PSFS): "gaussian", "disk" (disk ⊗ 1-px box,
    # reports √((R/2)² + 1/12) px) or "edges" (the family the edge fit chose; gaussian if unknown).
    region_gate: str = "none"
    # which region fits are measures (key of method.blur.local_spectrum.REGION_GATES): "none" (every fit
    # above the noise) or "adequacy" (the 1/f² model fits and pins σ down; docs/region-blur.md).
    region_noise_model: str = "white"
    # noise term (key of REGION_NOISE_MODELS): "white" (variance from the image's quietest blocks,
    # ≥ 8-bit LSB²/12), "spectrum" (per-frequency floor read from the image's own spectrum) or
    # "spectrum_or_white" (the smaller of the two per frequency); docs/region-blur.md.
    region_window_min: int = 16
    # smallest analysis window side, px (Zhu et al. 2013 use ≈ 41 px filters).
    region_window_max: int = 96
    # largest analysis window side, px.
    region_window_scale: float = 12.0
    # window side / coarse σ̂, dimensionless (docs/presets.md).
    region_sigma_min: float = 0.0
    # smallest σ of the likelihood's grid, px.
    region_sigma_max: float = 12.0
    # largest σ of the likelihood's grid, px.
    region_stride: int = 32
    # spacing of the window centres, px (docs/region-blur.md).

    def __post_init__(self):
        check_field_choice(self, "region_estimator", REGION_ESTIMATORS, optional=True)
        check_field_choice(self, "region_psf", REGION_PSFS)
        check_field_choice(self, "region_noise_model", REGION_NOISE_MODELS)
        check_field_choice(self, "region_gate", REGION_GATES)
        for name in ("region_window_min", "region_window_max"):
            require_field(self, name, is_integer(getattr(self, name), 16), "integer >= 16 (px)")
        require_field(self, "region_stride", is_integer(self.region_stride, 1), "integer >= 1 (px)")
        require_field(self, "region_window_max", self.region_window_max >= self.region_window_min,
                      "integer >= region_window_min (px)")
        require_field(self, "region_window_scale", 0 < self.region_window_scale < _INF,
                      "finite and > 0 (dimensionless)")
        if not (0 <= self.region_sigma_min < self.region_sigma_max < _INF):
            name = "region_sigma_max" if self.region_sigma_min >= 0 else "region_sigma_min"
            raise invalid_field(name, getattr(self, name), "0 <= region_sigma_min < region_sigma_max < inf (px)")
