"""Parameters of the defocus-estimation pipeline, with the paper's defaults.

One frozen dataclass; every field carries its unit and the paper section it comes from.
Images are floats in [0, 1]; every blur quantity is a Gaussian σ in pixels of the input image.
"""

from __future__ import annotations

import dataclasses

from .blur.estimators import BLUR_ESTIMATORS
from .blur.model_fit import FIT_PSF_MODELS
from .blur.local_spectrum import REGION_GATES
from .blur.region_estimators import REGION_ESTIMATORS, REGION_NOISE_MODELS, REGION_PSFS
from .edges.isolation import EDGE_ISOLATION_METHODS
from .luma import MEASURE_LIGHTS
from .magnify.magnification import MAP_FLOOR_MODES
from .propagation.cue_fusion import REGION_PLACEMENTS
from .propagation.defocus import PROPAGATION_REFINEMENTS, PROPAGATION_SOLVERS
from .propagation.matting import MATTING_DATA_WEIGHTS
from .propagation.methods import PROPAGATION_METHODS
from .refine.cross_bilateral import BILATERAL_METHODS, RANGE_KERNELS
from .registry import Registry

__all__ = ["ALPHA_CONFIDENCES", "BELOW_SCALE_RULES", "BIAS_REFERENCES", "EDGE_DETECTORS", "DefocusParams"]

#: ``DefocusParams.edge_detector`` (read by :func:`method.pipeline.edges_stage`).
EDGE_DETECTORS = Registry("edge detector", {
    "elder_zucker": "Elder & Zucker 1998 multi-scale detector, Eq. (7)-(9) (the paper)",
    "canny": "Canny edges (Zhuo & Sim's edge set); only with estimator='gradient_ratio'",
})
#: ``DefocusParams.bias_reference``: the unit of ``bias_scale`` (Eq. 3's sharpness bias).
BIAS_REFERENCES = Registry("bias reference", {"px": "σ in px", "image_fraction": "a fraction of max(H, W)"})
#: ``DefocusParams.fit_below_scale``: a fitted blur narrower than the σ2 that detected the edge.
BELOW_SCALE_RULES = Registry("below-scale rule", {"zero": "kept (the paper)", "nan": "dropped as unresolved"})
#: ``DefocusParams.alpha_confidence``: what scales α_p of Eq. (4) beyond the measure confidence.
ALPHA_CONFIDENCES = Registry("alpha confidence", {"none": "α_p = α (the paper)",
                                                  "agreement": "agreement of BM with bCBF (beyond the paper)"})


@dataclasses.dataclass(frozen=True, kw_only=True)
class DefocusParams:
    """Paper defaults for Bae & Durand 2007 (Sec. 3–5, Appendix B)."""

    # --- 3.1 multiscale edge detection (Elder & Zucker 1998, Appendix B) -------------------
    sigma1_scales: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
    # σ1 of the steerable 1st-derivative filters, px (Sec. 3.1); searched smallest first. Robust:
    # 0.5 … 16 (with sigma2_scales ≤ 8 the σ1 = 32, 64 passes added no measure on any test image;
    # the detector's FFT bank then needs no 64-px padding level: edge stage 0.81 → 0.47 s at 1 MP).
    sigma2_scales: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
    # σ2 of the steerable 2nd-derivative filters, px (Sec. 3.1); searched smallest first. Robust:
    # 0.5 … 8 (it fits at min(σ2, fit_max_scale = 2 px) anyway; measurements: docs/presets.md).
    noise_std: float = 2.5 / 255.0
    # sensor noise s_n in image units ([0, 1] scale): 2.5 grey levels of 8 bits (Sec. 3.1).
    measure_light: str = "display"
    # the light in which edges are detected and their blur measured (key of
    # method.luma.MEASURE_LIGHTS): "display" (the encoded values, paper) or "linear" (sRGB decoded
    # first: a lens blurs linear radiance; noise_std is then in linear units). The region cue, Eq. (3)
    # and Eq. (4) read the encoded image either way.
    false_positive_rate: float = 1e-6
    # image-wide false-positive tolerance α_I = 0.0001 % (Sec. 3.1, Eq. 9).

    # --- 3.2 blur at edges ----------------------------------------------------------------
    estimator: str = "model_fit"
    # key of method.BLUR_ESTIMATORS: "model_fit" (paper), "zero_crossing" (Elder–Zucker),
    # "gradient_ratio" (Zhuo & Sim 2011 baseline).
    # --- edge set and gradient ratio of the Zhuo & Sim 2011 baseline (not in Bae & Durand) ----------
    edge_detector: str = "elder_zucker"
    # where the blur is measured: "elder_zucker" (Sec. 3.1, the paper) or "canny" (Canny 1986 via
    # skimage.feature.canny, as Zhuo & Sim 2011 and their public code; method.edges.canny; only with
    # estimator "gradient_ratio", the other estimators read the detector's σ2 scales). zhuo_sim: "canny".
    canny_sigma: float = 1.0
    # σ of Canny's Gaussian smoothing, px (edge_detector="canny"; Zhuo & Sim's public code: 1).
    canny_low_threshold: float = 0.1
    canny_high_threshold: float = 0.2
    # Canny hysteresis thresholds on skimage's Sobel magnitude of the smoothed image (≈ 8·|∇I|, image
    # units/px); 0.1, 0.2 = skimage's defaults for float images, as the public code uses them.
    ratio_gradient_sigma: float = 0.5
    # σ of the Gaussian-derivative gradient |∇I| of estimator "gradient_ratio", px (Eq. 7 kernels).
    # 0.5: the harness's reading (the smallest Elder–Zucker scale). zhuo_sim: 1 (public code).
    ratio_reblur_sigma: float = 1.0
    # σ0 of Zhuo & Sim's re-blur, px: R = |∇I|_σg / |∇I|_√(σg² + σ0²), σ = √(σ0²/(R² − 1) − σg²).
    # 1: their paper's σ0. zhuo_sim: √1.25 (the public code's gradients at 1 and 1.5 px).
    ratio_max_sigma: float | None = None
    # largest σ "gradient_ratio" reports, px; larger estimates are clipped to it. None: max_sigma.
    # zhuo_sim: 5 (public code).
    ratio_zero_is_measure: bool = True
    # whether a "gradient_ratio" estimate of 0 px (R ≥ √(σg² + σ0²)/σg: sharper than the gradient
    # resolves) is a measure (True) or no measure, NaN (False: as the public code's propagation, whose
    # data weight is σ̂ itself, and the authors' release, which keeps σ > 1e-4 only). R ≤ 1 (noise, or
    # a very blurry edge) is NaN either way (the public code writes 0 there: the same when False).
    # zhuo_sim: False (dense MAE on 128² dead-leaves tiles, σ 1–4: 0.62 → 0.55 px; docs/zhuo-sim.md).
    fit_window_min: int = 3
    # smallest model-fit window, px (Sec. 3.2: "window sizes from 3×3 to 71×71").
    fit_window_max: int = 71
    # largest model-fit window, px (Sec. 3.2).
    max_sigma: float = 64.0
    # largest blur σ reported, px; estimates are clipped to [0, max_sigma].
    fit_max_residual: float = 0.05
    # used by estimator "model_fit_checked" only: largest normalised residual ρ of the Eq. (2c) fit
    # (residual sum of squares / energy of the sampled response in the fit window; dimensionless,
    # in [0, 1]) for which a σb is returned; a poorer fit gives NaN (no measure). Not in the paper.
    # Analytic steps (σ 0.5–8 px) give ρ ≤ 0.03 with noise 2.5/255 + 8 bits; bars whose edges are
    # 1–3σ apart ≈ 0.12. Robust: 0.03 (measurements: docs/presets.md). 1 keeps every estimate.
    fit_residual_noise: float = 0.0
    # beyond the paper (estimator "model_fit_checked"): k, dimensionless; the residual test becomes
    # ρ ≤ fit_max_residual + k · N · v_n(σ2) / ‖r‖², with N the samples in the fit window, ‖r‖² their
    # energy and v_n(σ2) the variance of the steered 2nd-derivative response to white noise of std
    # noise_std (method.blur.model_fit_checked.noise_residual_share): the noise's expected share of
    # ρ, which grows as ~s⁴ with the response width s, so a fixed ρ limit keeps only the narrower
    # (lower) fits of blurry edges. 0: a fixed limit (fit_max_residual alone; paper). k = 2 alone
    # lowers the dead-leaves mosaic's σ 5 / σ 6 dense MAE 0.70 / 1.34 → 0.39 / 0.80 px (2/255, seeds 0–1)
    # but admits fits +0.5–1.3 px too wide of in-focus low-contrast render edges (small tabletop renders
    # 0.44 → 0.48 px, shadow_gloss 0.34/0.45 → 0.39/0.54); robust: k = 2 with relaxed_fit_weight 0.1.
    relaxed_fit_weight: float = 1.0
    # beyond the paper (used only with estimator "model_fit_checked" and fit_residual_noise
    # > 0): confidence c_q, dimensionless in (0, 1], of the measures that pass the residual test only
    # thanks to the noise allowance (fit_max_residual < ρ ≤ fit_max_residual + k·share); measures with
    # ρ ≤ fit_max_residual have c_q = 1. c_q multiplies each measure's weight in Eq. (3) (the
    # cross-bilateral sum) and its α_p in Eq. (4), so relaxed measures decide the map only where no
    # strict measure is near. 1: off (every measure counts fully; paper). Robust: 0.02 with
    # fit_residual_noise 2 (robust alone → +both, 2/255 seeds 0–1 dense MAE): dead-leaves σ 6
    # 1.34 → 1.23 px (1/255: 0.86 → 0.80), skimage σ 6 1.03 → 0.90 (0.88 → 0.81); small renders' mean
    # dense MAE tabletop_stress 0.401 → 0.393, paper_cameras 0.237 → 0.234, shadow_gloss f/8, f/4 0.340,
    # 0.445 → 0.338, 0.395 px. Larger c gains more on the mosaics but loses on the renders (c = 0.1:
    # tabletop 0.404, shadow_gloss 0.353/0.460; c = 1: 0.425, 0.390/0.536). Measured with
    # fit_psf="auto" (the renders' disk-blurred edges now fitted by the disk model, so fewer of their
    # measures are relaxed ones): robust 0.1. Accuracy-bench fails (dead-leaves + skimage mosaics, 1/255
    # and 2/255, σ ≤ 6 bins) / small renders' mean dense MAE tabletop, paper_cameras: c = 0.02 14 /
    # 0.370, 0.208 px; 0.1 13 / 0.370, 0.209; 0.2 12 / 0.368, 0.212; 0.4 10 / 0.369, 0.217; 1 11 /
    # 0.371, 0.227. At 0.2 its gain on the quick ablation mosaic (0.015 px) is at the ablation test's
    # margin; 0.1 keeps 0.017.
    fit_scale_ratio: float = 1.0
    # beyond the paper: the Eq. (2c) fit samples the responses at min(σ2(p), max(fit_scale_ratio ·
    # σ2(p), min(sigma2_scales))) px (then capped by fit_max_scale), dimensionless; 1: the detector's
    # minimum reliable σ2(p) (paper). Measured and not in the robust preset: 0.5 lowers the
    # edge MAE of edges detected at σ2 = 1–2 px (renders 0.24 → 0.17, 0.51 → 0.34 px) and the
    # tabletop renders' dense mean 0.44 → 0.41 px, but raises the dead-leaves σ 3 tile 0.26 → 0.38 px
    # (2/255) and the paper_cameras renders' mean 0.237 → 0.246 px.
    fit_max_scale: float | None = None
    # beyond the paper (robust preset): fit Eq. (2c) to the responses at min(σ2(p), fit_max_scale) px
    # instead of the detector's minimum reliable σ2(p). At coarse σ2 (4–16 px) the fit window spans
    # neighbouring texture edges that widen the response (model fit +2.6 px bias at σ2 = 8 on the
    # rendered scenes); the least-squares fit over the window averages the extra noise of the finer
    # scale. None: the paper (fit at σ2(p)).
    fit_min_samples: int = 3
    # beyond the paper: fewest response samples in the fit window for a measure (NaN below). 3 (the
    # smallest window, paper) fits (s, t0) exactly and lets noise choose any width (MAE 6.9 px on
    # 3-sample windows of the rendered scenes). Robust: 5.
    fit_max_width_ratio: float = float("inf")
    # beyond the paper: largest fitted width s = d/2 as a fraction of the fit window's half-length;
    # wider fits extrapolate beyond the samples (MAE 4.4–38 px where s > half-window). inf: paper.
    fit_below_scale: str = "zero"
    # what d/2 ≤ σ2 gives (Eq. 2d has no real root): "zero" (paper: σb = 0) or "nan" (no measure
    # unless σ2 is the finest scale, where it is a sharp edge).
    fit_psf: str = "gaussian"
    # the blur model whose step response the fit matches (method.blur.model_fit.FIT_PSF_MODELS):
    # "gaussian" (Eq. 2c, the paper), "disk" (a uniform disk, the thin lens's defocus;
    # method.blur.disk_edge_response), "best" (both, per edge the smaller residual) or "auto" (both, one
    # model per image: method.blur.model_fit.select_psf_model). Every model reports the per-axis std
    # of its PSF through Eq. (2d) (a disk of diameter c: c/4). Robust: "auto" (docs/presets.md).

    # --- region (spectral) blur, beyond the paper (method.blur.region_estimators) -------------
    region_estimator: str | None = None
    # key of method.blur.region_estimators.REGION_ESTIMATORS: "local_spectrum" (Zhu et al., IEEE TIP 2013)
    # or "gsm" (Chakrabarti et al., CVPR 2010); None: no region measure (paper).
    region_psf: str = "gaussian"
    # blur kernel of the region likelihood: "gaussian", "disk" (disk ⊗ 1-px box, reports
    # √((R/2)² + 1/12) px) or "edges" (the family the edge fit chose; gaussian if unknown).
    region_gate: str = "none"
    # which region fits are measures (key of method.blur.local_spectrum.REGION_GATES): "none" (every
    # fit above the noise) or "adequacy" (the 1/f² model fits and pins σ down; docs/region-blur.md).
    region_noise_model: str = "white"
    # noise term: "white" (variance from the image's quietest blocks, ≥ 8-bit LSB²/12), "spectrum"
    # (per-frequency floor read from the image's own spectrum; fails on blurry texture,
    # docs/region-blur.md) or "spectrum_or_white" (the smaller of the two per frequency).
    region_window_min: int = 16
    # smallest analysis window side, px (Zhu et al. 2013 use ≈ 41 px filters).
    region_window_max: int = 96
    # largest analysis window side, px.
    region_window_scale: float = 12.0
    # window side / coarse σ̂, dimensionless (12: disk σ 2–6 MAE 0.38–1.07 → 0.19–0.28 px vs 9).
    region_sigma_min: float = 0.0
    # smallest σ of the likelihood's grid, px.
    region_sigma_max: float = 12.0
    # largest σ of the likelihood's grid, px.
    region_stride: int = 32
    # spacing of the window centres, px (docs/region-blur.md: 16 → 32 halves the time, same MAE).

    # --- 3.3 biased cross-bilateral refinement (Eq. 3) ------------------------------------
    refine: bool = True
    # run the refinement of Eq. (3); False passes the sparse measures on unchanged (the public
    # Zhuo & Sim code has no correction step between its measures and the propagation).
    bilateral_sigma_spatial: float = 0.10
    # σs as a fraction of the image size max(H, W) (Sec. 3.3: "10 % of the image size"). Robust: 0.05
    # (with the checked fit, blurry regions have few measures and a wide σs lets the many measures of
    # sharp neighbours dominate them: mosaic dense MAE 0.34 → 0.22 px, renders unchanged in sum).
    bilateral_sigma_range: float = 0.10
    # σr as a fraction of the reference image's value range (Sec. 3.3: "10 % of the image range").
    sharpness_bias: bool = True
    # apply b(BM) = exp(−BM / bias_scale) (Eq. 3); False gives the plain cross-bilateral ablation.
    bias_scale: float = 2.0
    # denominator of the sharpness bias exp(−BM/2), px (Sec. 3.3).
    bilateral_method: str = "grid"
    # "grid" (fast bilateral grid) or "brute_force" (O(N·M) reference oracle).
    bilateral_range_kernel: str = "sum"
    # the colour term of w_pq in Eq. (3b): "sum" (paper: Σ_i g_σr(|C_i(p) − C_i(q)|)) or "product"
    # (beyond the paper: Π_i g_σr(...) = g_σr(‖C(p) − C(q)‖), a joint-colour kernel; with the sum a
    # pixel that matches in one channel only still gets 1/3 of the weight, so sharp foreground
    # measures leak into the background).
    bias_reference: str = "px"
    # unit of bias_scale: "px" (paper: exp(−BM/2) with BM in px, so the bias depends on the image
    # resolution) or "image_fraction" (beyond the paper: bias_scale is a fraction of max(H, W)).
    refinement_robust_iterations: int = 0
    # beyond the paper: re-weighted iterations of Eq. (3) (an M-estimator): after each pass every
    # measure q is down-weighted by the Cauchy weight 1/(1 + (r_q / c)²) of its residual r_q from
    # its refined value, c = refinement_robust_scale. 0: paper (one pass).
    refinement_robust_scale: float = 0.5
    # Cauchy scale c of the re-weighting above, as a fraction of the refined value plus 0.5 px
    # (c = refinement_robust_scale · (bCBF_q + 0.5 px)): relative errors, as blur grows with σ.

    # --- 4 propagation (Eq. 4) -------------------------------------------------------------
    propagation: str = "colorization"
    # key of method.PROPAGATION_METHODS: "colorization" (paper, Eq. 4: Levin et al. 2004 affinities)
    # or "matting_laplacian" (Zhuo & Sim 2011: closed-form matting Laplacian of Levin et al. 2008).
    alpha_confidence: str = "none"
    # per-edge data weight α_p (Sec. 4.1 sets α_p = α at every edge): "none" (paper) or "agreement"
    # (beyond the paper: α_p = α · exp(−(BM_p − bCBF_p)² / (2 (0.25·bCBF_p + 0.5 px)²)), the agreement
    # of the raw measure with its refined value).
    matting_lambda: float = 0.005
    # λ of Zhuo & Sim's (L + λD) d = λ D d̂ (propagation="matting_laplacian"), dimensionless.
    matting_epsilon: float = 1e-5
    # ε of the matting Laplacian (Levin et al. 2008), image units², for propagation="matting_laplacian".
    matting_data_weight: str = "constant"
    # D of (L + λD) d = λ D d̂: "constant" (1 at every measure, Zhuo & Sim's equation) or "sigma"
    # (D = diag(d̂), as the public Zhuo & Sim code builds it: larger σ̂ weigh more), dimensionless.
    alpha: float = 0.5
    # data-term weight α_p at edge pixels; 0 elsewhere (Sec. 4.1, Fig. 6 sweeps 0.1–1).
    propagation_window: int = 7
    # side of the square window, px, over which σ_ip (per-channel std) is computed (Sec. 4.1: "7×7").
    propagation_neighborhood: int = 3
    # side of the square neighbourhood N(p), px (not given by the paper; 3 = Levin et al. 2004;
    # 7 = the "one 7×7 window defines both" reading). See method/propagation/defocus/defocus.py.
    propagation_tol: float = 1e-6
    # relative residual at which the preconditioned CG solve of the normal equations stops.
    propagation_solver: str = "amg_pcg"
    # "amg_pcg" (multigrid-preconditioned CG) or "direct" (sparse LU; small images / tests only).
    propagation_downsample: int | str = "auto"
    # "auto": exact solve up to 2¹⁵ px (≈ 181²; method.propagation.defocus.AUTO_MAX_EXACT_PIXELS), else solve
    # on a grid coarsened 4× while that grid has ≤ 2¹³ px (up to ≈ 362²), else by the smallest power of
    # two s ≥ 8 that brings it to ≤ 2¹⁵ px (8× at 512², 1 MP and the photo tools' 1.5 MP) with the
    # Galerkin coarse operator, interpolate and refine with max(⌈2.5·s⌉, 20) iterations of two-level-
    # preconditioned CG (Jacobi + coarse-grid correction) on the exact full-resolution system: paper
    # 0.016 / 0.019 px RMS, 0.069 / 0.082 px p99, robust 0.032 / 0.026 px RMS, 0.15 / 0.092 px p99 from
    # the exact solve on a photo at 512² / 1024² (method/propagation/defocus/defocus.py, docs/performance.md);
    # 1 = exact full-resolution solve; 2, 4, … = that coarsening factor.
    propagation_refinement: str = "galerkin"
    # refinement of the upsampled coarse solution (key of method.propagation.defocus.PROPAGATION_REFINEMENTS):
    # "galerkin" (the one, above; the earlier refinements and their distances: docs/performance.md).

    # --- beyond the paper: edge isolation and cue fusion in Eq. (4) -------------------------------
    edge_isolation: str | None = None
    # how much an edge measure is trusted given its neighbours (key of
    # method.edges.isolation.EDGE_ISOLATION_METHODS, or None: every measure weighs fully, paper):
    # "normal" — weight 1 when no other edge pixel lies within isolation_radius·max(σ̂, 1 px) along the
    # edge's gradient normal (both sides; its own segment runs along the tangent), less when one does
    # (a bar's two edges widen each other's response and bias the fit); "persistence" — weight 1 when
    # the edge is still detected at a detector scale ≈ its own σ̂ (Karaali & Jung 2018: edges that
    # vanish at coarse scales have close neighbours). The weight multiplies the measure's confidence
    # c_q (Eq. 3 and α_p of Eq. 4).
    isolation_radius: float = 3.0
    # distance, in units of the measure's max(σ̂, 1 px), within which another edge down-weights it.
    isolation_floor: float = 0.1
    # weight in (0, 1] of a measure whose neighbour edge touches it; rises as (d / radius)² to 1.
    fusion_edge_error_rel: float = 0.5
    # relative error ε_e (dimensionless) of an edge measure σ_e in the fusion's error model:
    # variance (ε_e·σ_e + 0.1 px)² / c_e. Used only when region measures are fused (region_estimator).
    fusion_region_error_rel: float = 0.3
    # relative model error ε_r (dimensionless) of a region measure σ_r, added to its Fisher variance:
    # variance 1/I + (ε_r·σ_r)² + (0.1 px)².
    fusion_region_weight: float = 1.0
    # scale W_r (dimensionless, > 0) of the region measures' data weight in Eq. (4) against an edge
    # measure of the same σ: α_r = α·W_r·v_e(σ_r)/v_r (a region term stands for a whole window of
    # pixels, an edge term for one).
    fusion_region_placement: str = "centres"
    # where a region measure enters Eq. (4) (method.propagation.cue_fusion.REGION_PLACEMENTS): "centres" — at the
    # pixels the region estimator gave it (its window centres); "blocks" — spread to the pixels nearest
    # to it (its block of the grid), its weight shared among them.
    fusion_island_weight: float = 1.0
    # factor in [0, 1] on the weight of a region measure in a "blur island" (method.propagation.cue_fusion.blur_islands):
    # a block without high-frequency texture (fine-scale detail energy ≤ 4× the noise's) that has such
    # texture within fusion_island_radius px, or no texture at its own blur scale either (a smooth
    # in-focus ramp beside sharp edges of the same surface). 1: off; 0: such measures are dropped.
    # Far from an edge the smoothness of Eq. (4) is very soft, so even a weak data term decides
    # there: on a ramp crossed by sharp lines (tests/test_cue_fusion.py) a factor 1e-3 still lets
    # σ 6 region terms lift the ramp between the lines to ≈ 4–6 px, 1e-5 to ≈ 1.2, 0 keeps ≈ 0.6.
    fusion_island_radius: float = 24.0
    # radius, px, of the neighbourhood searched for high-frequency texture by the island test.
    fusion_straddle_weight: float = 1.0
    # factor in [0, 1] on the weight of a region measure whose window holds an isolated edge (≥ half
    # its side of edge measures with no other edge within isolation_radius·σ̂ along their normal;
    # method.propagation.cue_fusion.straddled_windows): the edge fit measures such a window's blur better. 1: off.

    # --- 5 magnification ------------------------------------------------------------------
    map_clip_percent: float = 5.0
    # clip the lower and upper percentile of the defocus map before blurring, % (Sec. 5).
    map_smoothing: float = 0.005
    # Gaussian blur radius (σ) of the map as a fraction of the image size max(H, W) (Sec. 5).
    map_floor: str = "clamp"
    # how Sec. 5's "clamp its minimum value to 0" is read (key of method.magnify.magnification.MAP_FLOOR_MODES;
    # used by magnify_defocus, not by the estimation pipeline): "clamp" = max(σ, 0) px, the literal
    # reading (keeps the in-focus floor σ ≈ 0.3–0.7 px, which magnification then enlarges); "subtract"
    # = remove the lower-percentile value p_lo px in quadrature, √(max(σ² − p_lo², 0)), so sharp
    # regions stay sharp; "shift" = max(σ − p_lo, 0).

    def __post_init__(self):
        for name in ("sigma1_scales", "sigma2_scales"):  # normalised: sorted tuple of float px
            try:
                scales = tuple(sorted(float(v) for v in getattr(self, name)))
            except (TypeError, ValueError):
                scales = ()
            if not scales or any(not (v > 0) for v in scales):
                _bad(self, name, "non-empty tuple of positive scales (px)")
            object.__setattr__(self, name, scales)
        for check in _STAGE_CHECKS:
            check(self)

    def replace(self, **changes) -> "DefocusParams":
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def preset(cls, name: str, **changes) -> "DefocusParams":
        """A named parameter set of :data:`PRESETS` (``"paper"``, ``"robust"``, ``"zhuo_sim"``), optionally changed.

        Parameters
        ----------
        name : str
            Key of :data:`PRESETS`.
        **changes
            Fields to override (validated).

        Raises
        ------
        ValueError
            Unknown name (the message lists the presets) or bad field values.
        """
        from .presets import PRESETS  # at call time: the presets are instances of this class

        params = PRESETS.resolve(name, what="preset")
        return params.replace(**changes) if changes else params

    def changes_from(self, other: "DefocusParams") -> dict:
        """Fields whose value differs from ``other``: {name: (value here, value in other)}."""
        return {f.name: (getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self)
                if getattr(self, f.name) != getattr(other, f.name)}


# --------------------------------------------------------------------------------------------
# validation, one function per pipeline stage (Sec. 3.1, 3.2, Eq. 3, Eq. 4, Sec. 5)
# --------------------------------------------------------------------------------------------
_INF = float("inf")


def _bad(p, name, allowed):
    raise ValueError(f"DefocusParams.{name}={getattr(p, name)!r} is invalid; allowed: {allowed}")


def _need(p, name, ok, allowed):
    """Raise :func:`_bad` for field ``name`` unless ``ok``."""
    if not ok:
        _bad(p, name, allowed)


def _choice(p, name, registry, *, optional=False):
    registry.check(getattr(p, name), what=f"DefocusParams.{name}", optional=optional)


def _is_int(v, minimum):
    return isinstance(v, int) and not isinstance(v, bool) and v >= minimum


def _check_edges(p):
    """Sec. 3.1 (and the Canny and isolation options beyond the paper)."""
    _need(p, "noise_std", p.noise_std > 0, "> 0")
    _choice(p, "measure_light", MEASURE_LIGHTS)
    _need(p, "false_positive_rate", 0 < p.false_positive_rate < 1, "0 < α_I < 1")
    _choice(p, "edge_detector", EDGE_DETECTORS)
    _need(p, "canny_sigma", 0 < p.canny_sigma < _INF, "finite and > 0 (px)")
    if not (0 <= p.canny_low_threshold <= p.canny_high_threshold < _INF):
        _bad(p, "canny_low_threshold", "finite 0 <= canny_low_threshold <= canny_high_threshold")
    _choice(p, "edge_isolation", EDGE_ISOLATION_METHODS, optional=True)
    _need(p, "isolation_radius", 0 < p.isolation_radius < _INF, "finite and > 0 (units of σ̂)")
    _need(p, "isolation_floor", 0 < p.isolation_floor <= 1, "0 < weight <= 1")


def _check_edge_blur(p):
    """Sec. 3.2: the estimator at edges and its fit options."""
    _choice(p, "estimator", BLUR_ESTIMATORS)
    if p.edge_detector == "canny" and p.estimator != "gradient_ratio":
        _bad(p, "edge_detector", "'canny' only with estimator='gradient_ratio' (the other estimators read the "
                                 "Elder–Zucker σ2 scales); else 'elder_zucker'")
    _need(p, "fit_window_min", _is_int(p.fit_window_min, 3), "integer >= 3")
    if not (_is_int(p.fit_window_max, 3) and p.fit_window_max >= p.fit_window_min):
        _bad(p, "fit_window_max", "integer >= fit_window_min")
    _need(p, "max_sigma", p.max_sigma > 0, "> 0")
    _need(p, "fit_max_residual", 0 <= p.fit_max_residual <= 1, "0 <= ρ_max <= 1 (dimensionless normalised residual)")
    _need(p, "fit_residual_noise", 0 <= p.fit_residual_noise < _INF, "finite and >= 0 (dimensionless)")
    _need(p, "relaxed_fit_weight", 0 < p.relaxed_fit_weight <= 1, "0 < c <= 1 (dimensionless confidence)")
    _need(p, "fit_scale_ratio", 0 < p.fit_scale_ratio <= 1, "0 < ratio <= 1 (dimensionless)")
    if p.fit_max_scale is not None and not p.fit_max_scale > 0:
        _bad(p, "fit_max_scale", "None or > 0 (px)")
    _need(p, "fit_min_samples", _is_int(p.fit_min_samples, 3), "integer >= 3")
    _need(p, "fit_max_width_ratio", p.fit_max_width_ratio > 0, "> 0 (inf: no limit)")
    _choice(p, "fit_below_scale", BELOW_SCALE_RULES)
    _choice(p, "fit_psf", FIT_PSF_MODELS)
    for name in ("ratio_gradient_sigma", "ratio_reblur_sigma"):
        _need(p, name, 0 < getattr(p, name) < _INF, "finite and > 0 (px)")
    if p.ratio_max_sigma is not None and not (0 < p.ratio_max_sigma < _INF):
        _bad(p, "ratio_max_sigma", "None or finite and > 0 (px)")
    _need(p, "ratio_zero_is_measure", isinstance(p.ratio_zero_is_measure, bool), "True or False")


def _check_region(p):
    """The region (local-spectrum) estimator beyond the paper."""
    _choice(p, "region_estimator", REGION_ESTIMATORS, optional=True)
    _choice(p, "region_psf", REGION_PSFS)
    _choice(p, "region_noise_model", REGION_NOISE_MODELS)
    _choice(p, "region_gate", REGION_GATES)
    for name in ("region_window_min", "region_window_max"):
        _need(p, name, _is_int(getattr(p, name), 16), "integer >= 16 (px)")
    _need(p, "region_stride", _is_int(p.region_stride, 1), "integer >= 1 (px)")
    if p.region_window_max < p.region_window_min:
        _bad(p, "region_window_max", "integer >= region_window_min (px)")
    _need(p, "region_window_scale", 0 < p.region_window_scale < _INF, "finite and > 0 (dimensionless)")
    if not (0 <= p.region_sigma_min < p.region_sigma_max < _INF):
        _bad(p, "region_sigma_max" if p.region_sigma_min >= 0 else "region_sigma_min",
             "0 <= region_sigma_min < region_sigma_max < inf (px)")


def _check_refine(p):
    """Eq. (3): the biased cross-bilateral filter."""
    _need(p, "refine", isinstance(p.refine, bool), "True or False")
    for name in ("bilateral_sigma_spatial", "bilateral_sigma_range", "bias_scale"):
        _need(p, name, getattr(p, name) > 0, "> 0")
    _choice(p, "bilateral_method", BILATERAL_METHODS)
    _choice(p, "bilateral_range_kernel", RANGE_KERNELS)
    _choice(p, "bias_reference", BIAS_REFERENCES)
    _need(p, "refinement_robust_iterations", _is_int(p.refinement_robust_iterations, 0), "integer >= 0")
    _need(p, "refinement_robust_scale", 0 < p.refinement_robust_scale < _INF, "finite and > 0")


def _check_propagation(p):
    """Eq. (4): the propagation, its solver and the matting-Laplacian alternative."""
    _choice(p, "alpha_confidence", ALPHA_CONFIDENCES)
    for name in ("matting_lambda", "matting_epsilon", "alpha"):
        _need(p, name, getattr(p, name) > 0, "> 0")
    _choice(p, "matting_data_weight", MATTING_DATA_WEIGHTS)
    _choice(p, "propagation", PROPAGATION_METHODS)
    if p.propagation == "matting_laplacian" and p.alpha_confidence != "none":
        _bad(p, "alpha_confidence", "'none' with propagation='matting_laplacian' (its data term has no per-edge weight)")
    for name in ("propagation_window", "propagation_neighborhood"):
        _need(p, name, _is_int(getattr(p, name), 3) and getattr(p, name) % 2 == 1, "odd integer >= 3")
    _need(p, "propagation_tol", 0 < p.propagation_tol < 1, "0 < tol < 1")
    ds = p.propagation_downsample
    if not (ds == "auto" or (_is_int(ds, 1) and (ds & (ds - 1)) == 0)):
        _bad(p, "propagation_downsample", "'auto' or a power of two >= 1")
    _choice(p, "propagation_refinement", PROPAGATION_REFINEMENTS)
    _choice(p, "propagation_solver", PROPAGATION_SOLVERS)


def _check_fusion(p):
    """The inverse-variance fusion of edge and region measures in Eq. (4) (beyond the paper)."""
    for name in ("fusion_edge_error_rel", "fusion_region_error_rel"):
        _need(p, name, 0 <= getattr(p, name) < _INF, "finite and >= 0 (dimensionless relative error)")
    _need(p, "fusion_region_weight", 0 < p.fusion_region_weight < _INF, "finite and > 0 (dimensionless)")
    _choice(p, "fusion_region_placement", REGION_PLACEMENTS)
    if not (0 <= p.fusion_island_weight <= 1):
        _bad(p, "fusion_island_weight", "0 <= factor <= 1 (1: off; 0: island measures dropped)")
    _need(p, "fusion_straddle_weight", 0 <= p.fusion_straddle_weight <= 1, "0 <= factor <= 1 (1: off)")
    _need(p, "fusion_island_radius", 0 < p.fusion_island_radius < _INF, "finite and > 0 (px)")
    if p.region_estimator is not None and p.propagation != "colorization":
        _bad(p, "propagation", "'colorization' when region_estimator is set (the fusion needs per-pixel "
             "data weights in Eq. 4)")


def _check_magnify(p):
    """Sec. 5: the map's preprocessing before magnification."""
    _need(p, "map_clip_percent", 0 <= p.map_clip_percent < 50, "0 <= p < 50")
    _need(p, "map_smoothing", p.map_smoothing >= 0, ">= 0")
    _choice(p, "map_floor", MAP_FLOOR_MODES)


#: Checks run by ``DefocusParams.__post_init__``, in pipeline order.
_STAGE_CHECKS = (_check_edges, _check_edge_blur, _check_region, _check_refine, _check_propagation, _check_fusion,
                 _check_magnify)
