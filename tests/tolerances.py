"""Every tolerance and golden number the tests use, as named constants in one place.

Each section belongs to one area of the code; append new constants to the section they belong to
(or add a section with a header comment). Say in a comment why the value is what it is.
"""

# --- thin-lens optics and cameras (scenes/thin_lens.py, scenes/camera.py) -----------------------
#: Relative agreement between closed forms evaluated two ways (float64 round-off only).
THIN_LENS_RTOL = 1e-12

# --- calibration: rendered thin-lens blur vs Eq. (5)/(6) (scenes/calibration.py; the test reads
#     fig10's and fig2's quick data) ----------------------------------------------------------------
#: Fitted disk diameter vs Eq. (5), relative. Measured: |err| <= 1.3 % (16 edges, 2.7-91 px,
#: 4096 spp x 8 rows); on fig10 + fig2 quick (12 + 4 edges, 13-286 px, 1024 spp) <= 0.08 %
#: (2026-12-03). 3 % leaves room for sampling noise on the smallest blurs.
CALIB_COC_RTOL = 0.03
#: Cases with Eq. (5) c below this (px) are reported, not asserted: a sub-2-px disk is hard to tell
#: from the 1-px box footprint at this noise level.
CALIB_MIN_COC_PX = 2.0
#: Ratio of the two sensors' relative blur c/X vs Eq. (6), relative. Measured <= 1.5 % (fig2 quick: 0.07 %).
CALIB_RATIO_RTOL = 0.03
#: Naive fov = 2 atan(W/2f) must render the blur (D - f)/D times Eq. (5); agreement with that factor.
CALIB_NAIVE_FACTOR_RTOL = 0.01
#: Second-moment σ of the line-spread vs sqrt(c^2/16 + 1/12), relative (reported convention check).
CALIB_SIGMA_2ND_RTOL = 0.03
#: The disk edge must sit on the optical axis (image centre) within this many px.
CALIB_EDGE_POSITION_PX = 0.1

# --- figures (experiments/, repro/figures.py) ----------------------------------------------------
#: fig10 quick mode: max relative error of measured c vs Eq. (5) over the plotted points.
FIG10_MAX_REL_ERR = 0.03

# --- cross-bilateral refinement, propagation, magnification (method/refine/cross_bilateral.py,
#     method/propagation/defocus.py, method/magnify/magnification.py) ------------------------------------------
#: Bilateral grid vs brute-force oracle, max |difference| as a fraction of the BM value range.
#: Cells of σ/3 with the tent⊛tent variance compensated measured ≤ 0.9 % over 18 cases.
BILATERAL_GRID_REL_TOL = 0.02
#: A constant blur measure must come back unchanged (weighted mean of equal values; round-off).
BILATERAL_CONSTANT_ATOL = 1e-9
#: Relative residual ‖A B − rhs‖/‖rhs‖ of the Eq. (4) normal equations after the exact AMG-PCG solve.
PROPAGATION_RESIDUAL_RTOL = 1e-5
#: AMG-PCG (tol 1e-8) vs sparse LU on a 40×50 image, max |difference| relative to the BM range.
PROPAGATION_DIRECT_RTOL = 1e-5
#: Rows of W sum to 1 (float64 round-off of a softmax over ≤ 48 terms).
PROPAGATION_ROW_SUM_ATOL = 1e-12
#: Coarse solve + refinement vs exact solve at 128² (s=2), RMS error / BM range (loose regression
#: bound; the tight bounds are PROPAGATION_DEFAULT_VS_EXACT_* below).
PROPAGATION_COARSE_RMS_RTOL = 0.01
#: Magnified blurred step: measured total σ vs factor·σ, relative (variance-exact interpolation).
MAGNIFY_SIGMA_RTOL = 0.01
#: "Never sharpens": gradient energy may exceed the input's by at most this relative round-off.
MAGNIFY_GRADIENT_ENERGY_RTOL = 1e-9

# --- scenes, ground truth, EXR, render CLI (scenes/library, scenes/ground_truth.py, scenes/render.py,
#     repro/render.py) ---------------------------------------------------------------------------
#: Depth of a fronto-parallel plane from lens-centre rays vs its true z, metres (float32 ray/plane
#: intersection; issue part 6 asks for 1e-4 at z = 2 m).
SCENE_DEPTH_ATOL_M = 1e-4
#: Lens-centre depth vs the analytic depth of the tilted plane z = z0 / (1 - slope·y/z), relative.
SCENE_TILTED_DEPTH_RTOL = 1e-4
#: σ_gt at the small preset, f/8: the in-focus floor is the box filter's 1/sqrt(12) px and the
#: largest blur must reach at least this many px (useful range for the estimators).
SCENE_SIGMA_FLOOR_PX = 0.2887
SCENE_SIGMA_FLOOR_ATOL_PX = 0.02
SCENE_SMALL_F8_MIN_MAX_SIGMA_PX = 1.2
#: f/4 vs f/8 CoC ratio: exactly 2 by Eq. (5) (float32 storage round-off only).
SCENE_F4_F8_COC_RATIO_RTOL = 1e-5
#: Emission-only render of an in-focus uniform texture region vs the texture value, linear, absolute
#: (anti-aliasing at 256 spp; multijitter).
SCENE_EMISSION_ATOL = 2e-2
#: Correlation of the in-focus region with the upright texture must beat the flipped/mirrored ones
#: by at least this much (orientation test).
SCENE_ORIENTATION_MARGIN = 0.2

# --- photo I/O, working resolution, photo CLIs (repro/photo_io/, method/magnify/upsampling.py,
#     repro/estimate.py, repro/magnify.py) ------------------------------------------------------
#: JPEG written at quality 95, 4:4:4, then read back, smooth saturated ramp: max and mean |difference|
#: (measured 5.4/255 and < 1/255; quantisation of DCT coefficients, worst at saturated corners).
PHOTO_JPEG_ROUNDTRIP_ATOL = 8.0 / 255.0
PHOTO_JPEG_ROUNDTRIP_MEAN_ATOL = 1.5 / 255.0
#: EXR round trip of an sRGB image: sRGB → linear float32 → sRGB (float32 mantissa, 2^-24 relative,
#: amplified by the sRGB curve's slope ≤ 12.92).
PHOTO_EXR_ROUNDTRIP_ATOL = 1e-5
#: Fused sparse downscaling vs Gaussian filter + linear resampling: both truncate the kernel at 4σ,
#: rounded differently (ceil vs round), measured 3e-6.
DOWNSCALE_REFERENCE_ATOL = 1e-5
#: Tiled vs whole-image magnification: identical data per core pixel, FFT round-off (measured 9e-16).
TILED_MAGNIFY_ATOL = 1e-9
#: The magnified value at p lies in the input's [min, max] over the blur kernel's window (convex
#: combination of input pixels); float round-off only.
MAGNIFY_LOCAL_RANGE_ATOL = 1e-12
#: Factor-1 magnification and a zero map return the input bit for bit.
MAGNIFY_IDENTITY_ATOL = 0.0
#: --highlights' curve (repro/photo_io/highlights.py), every registered tone curve, gains 1-1000:
#: |compress(expand(v)) − v| over 2·10⁵ display values and every 16-bit code, measured ≤ 1.0e-9
#: (gain 1000, linear; ≤ 6.3e-11 at the default gain 8): the inverse interpolates the curve tabulated at
#: 2¹⁸ display values above the knee, below the knee the curve's own encode (float64 round-off).
HIGHLIGHT_ROUNDTRIP_ATOL = 2e-9
#: The synthetic point magnified with --highlights: energy of its linear light vs GAIN (or vs the
#: decoded point), relative, and its per-axis variance vs σ_e² (the disk's sampled second moment).
#: Measured on every display curve, EXR and 16-bit PNG output: energy ≤ 0.01 %, variance −0.1 %.
HIGHLIGHT_ENERGY_RTOL = 0.01
HIGHLIGHT_VARIANCE_RTOL = 0.03
#: A piecewise-constant map upsampled by the guided filter must jump within this many full-res px
#: of the guide's edge (the filter's window is 2 working px; the jump should sit at the full-res edge).
GUIDED_EDGE_POSITION_PX = 1

# --- Sec. 3.1/3.2: Gaussian derivatives, edges, blur estimators (method/edges/gaussian_derivatives.py,
#     method/edges/noise_thresholds.py, method/edges/elder_zucker.py, method/blur/*.py, scenes/analytic/)
#: FFT (analytic transfer) vs direct convolution with the sampled Eq. (7)/(8) kernels, relative to
#: the response's max, σ >= 1.5 px on a smooth image (sampled-kernel aliasing exp(−2π²σ²)·(2π)^k
#: and truncation, measured ≤ 4e-5).
DERIV_VS_SAMPLED_RTOL = 2e-4
#: Same at σ = 1 px, where the sampled kernel aliases (measured 5e-3).
DERIV_VS_SAMPLED_SIGMA1_RTOL = 2e-2
#: Steered 1st/2nd/3rd derivative vs the analytic directional derivative of a Gaussian-blob image
#: blurred by σ (band-limit and border effects; measured ≤ 1e-6 of the max).
STEERED_VS_ANALYTIC_RTOL = 1e-5
#: Single- vs double-precision FFT bank, relative to the Eq. (9) thresholds (measured 3e-4).
SINGLE_PRECISION_VS_THRESHOLD = 1e-2
#: Closed-form thresholds evaluated two ways (float64 round-off).
THRESHOLD_RTOL = 1e-12
#: model_fit median |error| on clean edges, σ ∈ [1, 6]: max(abs, rel·σ) (the brief's target).
MODEL_FIT_CLEAN_ATOL_PX = 0.15
MODEL_FIT_CLEAN_RTOL = 0.10
#: model_fit median |error| with noise 2/255 and 8-bit quantisation, σ ∈ [1, 6]: max(abs, rel·σ).
#: Measured ≤ 0.15 px (4 % at σ = 4); the looser bound allows for the random draw.
MODEL_FIT_NOISY_ATOL_PX = 0.3
MODEL_FIT_NOISY_RTOL = 0.15
#: Curved edges (disks of radius >= 8σ + 16 px, clean), σ ∈ [1, 6]: curvature shifts the response
#: slightly; max(abs, rel·σ).
MODEL_FIT_DISK_ATOL_PX = 0.25
MODEL_FIT_DISK_RTOL = 0.10
#: Straight clean edges: fraction of ground-truth edge pixels (away from the border) found, and the
#: largest |distance| (px) of a detected edge pixel from the true edge line.
EDGE_RECALL_MIN = 0.98
EDGE_LOCALISATION_PX = 1.0
#: Gradient direction error at detected straight-edge pixels, radians (median).
EDGE_THETA_MEDIAN_RAD = 0.02
#: fig2 quick mode: measured large/small relative-blur ratio vs Eq. (6) (measured 0.07 %).
FIG2_RATIO_RTOL = 0.03

# --- golden regression numbers (tests/golden/*.json; `pytest --regen-goldens` rewrites) ----------
#: The render-based goldens (tests/golden/*_quick.json) have one tolerance per metric, derived from the
#: measured spread over llvm_ad_rgb/scalar_rgb × seeds 0/1 and recorded with how it was measured in
#: tests/golden/tolerances.json (tol = max(3 × spread, 1e-6 + 1e-5·|golden|); booleans and strings
#: exact). Rerun: `.venv/bin/python -m tests.golden --regenerate` (see tests/golden.py). The blanket
#: ±10 % + 0.02 drift they replace let e.g. a flipped "model_fit_better" or a 10 % MAE change pass.
#: Guided upsampling of a piecewise-constant map across a step edge: 3 px or more from the edge the
#: value stays within this fraction of the step of its side's level (measured ≤ 1 %; the guided
#: filter's 5×5 working-px window leaks a little across the edge).
GUIDED_EDGE_SPILL = 0.05

# --- fig4 / fig5 / repro.evaluate (experiments/fig4_estimators.py, experiments/fig5_cross_bilateral.py,
#     experiments/evaluation.py, repro/evaluate.py) ------------------------------------------------
#: Paper claim "model fit beats zero crossing near neighbouring edges", asserted only where it was
#: measured to hold: opposite-polarity bars with spacing D = 3σ and 4σ (clean and noisy), where the
#: two edges' 2nd-derivative lobes overlap. Quick mode measured model_fit 0.012–0.28 vs zero_crossing
#: 0.15–0.41 median relative error; the zero crossing must be visibly degraded there (≥ this).
FIG4_BAR_ZC_MIN_REL_ERROR = 0.10
#: Bar spacings (multiples of σ) on which the claim is asserted.
FIG4_BAR_CLAIM_SPACINGS = (3.0, 4.0)
#: σ_gt recomputed from coc_px (line_spread) vs the render's stored sigma_px: float32 storage.
EVAL_SIGMA_GT_ATOL = 1e-5
#: The convention effect bias(line_spread) − bias(erf_fit) = mean(σ_erf − σ_ls) over the same pixels
#: is ≥ 0 by construction; float round-off only.
FIG4_CONVENTION_EFFECT_ATOL = 1e-9
#: fig5 outlier scene: the sparse blur measure must have at least this in-focus outlier fraction
#: (shadow_gloss, small preset: measured 0.18 at f/8, 0.10 at f/4) for the bias claim to be tested.
FIG5_MIN_OUTLIERS_BEFORE = 0.05

# --- fig6 / fig7 / fig11 (experiments/fig6_alpha_sweep.py, fig7_doubled_defocus.py, fig11_gallery.py)
#: fig6's shared-stage α sweep vs estimate_defocus_map(alpha=0.5) under the same RNG seed, max |Δσ| px
#: (same stages and solver; measured 1.1e-7 px — AMG-PCG stopping at tol 1e-6 on slightly different
#: float paths).
FIG6_PIPELINE_MATCH_ATOL_PX = 1e-5
#: RMS |B − BM| at edges must not increase with α (exact minimiser: non-increasing); slack for the
#: iterative solve's tolerance and the [0, max_sigma] clip, px.
FIG6_FIDELITY_MONOTONE_ATOL_PX = 1e-4
#: With the Eq. (3) refinement upstream the four α maps are nearly identical (measured max |Δσ|
#: between α = 0.1 and 1: 0.21 px sRGB, 0.11 px linear on the quick portrait, local to a few pixels;
#: the MAE changes by < 0.002 px); a regression bound, px.
FIG6_REFINED_ALPHA_SPREAD_MAX_PX = 0.4
#: Filter-aware doubling of the truth √(k²σ_d² + σ_f²) vs σ_gt(f/4): float32 storage round-off, px.
FIG7_DOUBLED_TRUTH_ATOL_PX = 1e-4

# --- whole pipeline (method/pipeline.py) -----------------------------------------------------------
#: Median sparse σ on the blurred half of a two-region image vs the true σ = 3 px, relative:
#: model fit on 8-px blocks (neighbouring edges 8 px = 2.7σ apart) measured 2.97 px (1 % off).
PIPELINE_TWO_REGION_SIGMA_RTOL = 0.15

# --- propagation: default (coarse solve + two-level PCG refinement) vs exact solve -----------------
#: Default ``propagate_defocus`` (auto: coarse 4×, and downsample=2) vs the exact solve (tol 1e-10)
#: on a 320² textured synthetic image with 1 % of the pixels measured, px. Galerkin refinement
#: (24 iterations, the earlier default): measured 4.6e-5 px RMS / 2.1e-4 px p99 (4×) and
#: 3.3e-4 / 1.1e-3 px (2×); the re-discretised two-level refinement (80 / 40 iterations) 2.3e-6 /
#: 9.5e-6 and 3.6e-5 / 1.3e-4 px; the Jacobi-only refinement 2.8e-2 / 1.2e-1 px, so these bounds
#: fail on it. With 20 iterations (the default, ≈ 0.1 s less at 1 MP): 1.4e-4 /
#: 6.4e-4 px (4×) and 5.9e-4 / 2.7e-3 px (2×), so the bounds were raised from 5e-4 / 2e-3 (24
#: iterations) to 8e-4 / 3.5e-3; the Jacobi-only refinement stays ≥ 35× outside them.
#: On the astronaut photo the default is 0.0082 / 0.019 px RMS from the exact solve at
#: 512² / 1024² (method/propagation/defocus.py, propagate_defocus Notes).
PROPAGATION_DEFAULT_VS_EXACT_RMS_PX = 8e-4
PROPAGATION_DEFAULT_VS_EXACT_P99_PX = 3.5e-3
#: Restriction is the exact transpose of the bilinear prolongation: |⟨Pᵀu, v⟩ − ⟨u, Pv⟩| relative.
PROPAGATION_TRANSPOSE_RTOL = 1e-12

# --- fig5 bias-scale sweep (experiments/fig5_cross_bilateral.py: bias_sweep) -------------------------
#: The refined measure at each edge pixel is a weighted mean of BM under weights w_pq·exp(−BM_q/s),
#: an exponential tilt, so it is non-decreasing in s by construction; slack for float64 round-off and
#: the float32 storage of the (S, H, W) maps (σ ≤ 64 px → ≤ 4e-6 px), px.
FIG5_SWEEP_MONOTONE_ATOL_PX = 1e-4
#: The quick config must have at least this many blurry edges (σ_gt ≥ blurry_edge_px = 3 px, off
#: occlusion boundaries) over its cases for the blurry-edge monotonicity test to mean something
#: (measured: 90, all on planes_f4 at 160×120; the shadow_gloss cases have none ≥ 3 px).
FIG5_SWEEP_MIN_BLURRY_EDGES = 50
#: Sweep dense map at s = 2 / s = inf vs method.estimate_defocus_map with the same parameters
#: (same calls; the difference is float32 storage of the sweep maps), max |Δσ| px.
FIG5_SWEEP_PIPELINE_ATOL_PX = 1e-4

# --- model_fit_checked (method/blur/model_fit_checked.py): goodness-of-fit test on Eq. (2c) --------
#: Fraction of model_fit estimates at analytic step-edge pixels the checked estimator must keep
#: (DefocusParams.fit_max_residual = 0.05; measured 100 % noise-free and 100 % at noise 2/255 + 8 bits,
#: max ρ 0.0036 / 0.025).
MODEL_FIT_CHECKED_KEEP_CLEAN_MIN = 0.99
MODEL_FIT_CHECKED_KEEP_NOISY_MIN = 0.95
#: On bars (two opposite edges D = 2σ–4σ apart) and thin lines the fit is poor (measured ρ ≈ 0.11–0.13;
#: 0–63 % kept per case): the kept fraction there must be at most this, and below the clean-step one.
MODEL_FIT_CHECKED_KEEP_BAR_MAX = 0.5

#: model_fit on two fixed analytic images vs tests/golden/model_fit_regression.json (n, mean, median,
#: min, max of σ in px). The method is deterministic; the allowance covers FFT/library round-off.
MODEL_FIT_REGRESSION_RTOL = 1e-6
MODEL_FIT_REGRESSION_ATOL = 1e-9

# --- rendered reference (tests/test_render_reference.py, tests/references/*.exr) ------------------
#: RGB RMSE (linear) of the small planes render vs its reference. Same variant + seed renders are
#: bit-identical (0); a different seed — like the scalar vs llvm sample streams — measured 0.0055.
REF_RGB_RMSE = 0.011
#: Mean signed RGB difference (linear): sampling noise averages out; a real change (texture, light) does not.
REF_RGB_MAX_BIAS = 0.002
#: Camera-space depth from the lens-centre ray cast vs the reference, relative (float32 round-off).
REF_DEPTH_RTOL = 1e-5
#: σ_gt vs the reference, px (float32 round-off).
REF_SIGMA_ATOL_PX = 1e-5

# --- fig8 refocusing (method/magnify/refocusing.py, experiments/fig8_refocus.py) --------------------------
#: Minimum PSNR gain of deconvolve_defocus (default λ = 1e-2) with the true σ map over the blurred
#: input on the analytic test (periodic pattern, σ 0.5–3 px ramp, 8-bit): measured +2.7 dB ("wiener")
#: and +2.6 dB ("cls") at λ = 1e-2, +4.8 dB at the best λ ≈ 3e-4, dB.
FIG8_DECONV_MIN_GAIN_DB = 1.5
#: refocus with the new map equal to the old one reproduces the input (regularised deconvolution is
#: not an exact inverse; measured 46.6 dB at λ = 1e-3 and ≈ 42 dB at 1e-2 on the analytic test), dB.
FIG8_SAME_MAP_MIN_PSNR_DB = 35.0
#: Constant-σ deconvolution then re-blur with the same σ (no level blending difference): max |Δ|.
FIG8_CONSTANT_ROUNDTRIP_ATOL = 0.02
#: (Measured values behind the two constants above, correcting their comments: same-map refocus
#: 43.6 dB at λ = 1e-2; constant-σ 1.7 px round trip max |Δ| 0.014 more than 8 px from the border,
#: 0.025 including the border, so the test compares the interior.)

# --- presets and the robust preset's switches (method/presets.py PRESETS / ROBUST_CHANGES,
#     method/blur/model_fit.py apply_fit_rules, method/refine/cross_bilateral.py range_kernel="product" /
#     robust_iterations, method/propagation/defocus.py confidence=, experiments/stage_attribution.py) ------
#: The robust preset's blur estimator (model_fit_checked, ρ ≤ 0.03, with the fit rules and
#: fit_max_scale = 2 px) on straight step edges (σ = 1, 3, 6 px; 8-bit + noise 1/255; 4 angles),
#: median |σ_est − σ| at edge pixels ≤ this · σ. Measured 0.016 / 0.043 / 0.072 px (0.016σ, 0.014σ,
#: 0.012σ; at σ = 6 fit_max_scale moves the fit from σ2 = 4 to 2 px: paper 0.047 px), no rejections;
#: ~2× the measured.
ROBUST_FIT_STEP_RTOL = 0.025
#: Dense-map textured MAE on 48×192 dead-leaves mosaics (one row of four 48-px tiles, σ 0.5/1/2/4 px,
#: 8-bit + noise 1/255, seeds 0–2; tests/test_presets.py): the robust preset must beat the paper's,
#: seed mean, by at least this (measured paper 0.526 vs robust 0.311 px, i.e. 0.215 px; per seed
#: 0.268 / 0.253 / 0.125 px).
MOSAIC_ROBUST_VS_PAPER_MIN_GAIN_PX = 0.10
#: A switch that helps the dense map: turning it off (others on) must worsen the seed-mean dense
#: textured MAE by at least this (measured: estimator="model_fit_checked" +0.260, fit_max_scale
#: +0.039, fit_max_residual +0.028, fit_max_width_ratio +0.082 px).
MOSAIC_ABLATION_MIN_GAIN_PX = 0.015
#: "Does not improve by more than a small margin", and the no-effect band: measured fit_below_scale
#: +0.001 px; the refinement switches' −0.053 / −0.042 / −0.038 px are beyond it (recorded as negative
#: findings in tests/test_presets.py, DENSE_HURTS).
MOSAIC_ABLATION_MARGIN_PX = 0.02
#: A rule with no dense-map effect must lower the sparse-stage seed-mean MAE by at least this
#: (measured fit_below_scale +0.032 px; the other model-fit switches +0.060 … +0.315 px).
MOSAIC_SPARSE_MIN_GAIN_PX = 0.01
#: Issue target: σ_gt fed at the detected edges straight into the propagation (oracle_propagate)
#: gives a dense textured MAE ≤ this on the mosaic tiles (measured ≤ 0.008 px on the 96² and
#: 48×192 mosaics, robust preset).
STAGE_ORACLE_PROPAGATE_MAX_MAE_PX = 0.15
#: With perfect measures (oracle_refine), each refinement switch of the robust preset must lower
#: the seed-mean dense textured MAE by at least this (and on every seed). Measured on the 48×192
#: mosaic, seeds 0–2: robust 0.0169 px vs 0.0323 (sum kernel), 0.0744 (σs = 10 %), 0.0209 (bias on).
STAGE_ORACLE_REFINE_MIN_GAIN_PX = 0.002
#: Product-kernel bilateral grid vs its brute-force oracle, max |difference| as a fraction of the BM
#: range (tests/test_cross_bilateral.py's 18 cases). The 5-D grid's cells are 0.75σ
#: (GRID_CELL_PER_SIGMA_PRODUCT), much coarser than the 3-D grids' σ/3: measured ≤ 5.3 % (the sum
#: grid's ≤ 0.9 %); σ/2 cells gave ≤ 1.5 %, σ/3 ≤ 0.5 % on two of the cases.
BILATERAL_PRODUCT_GRID_REL_TOL = 0.08
#: Two colours that match in one channel (0.2, 0.2, 0.8) | (0.2, 0.8, 0.2), BM 1 | 5 px, no bias: the
#: sum kernel must leak at least this much (max |refined − own side's BM|; measured 0.75 px grid,
#: 0.75 px brute force — 1/3 of the weight crosses); the product kernel keeps both sides to round-off.
BILATERAL_SUM_LEAK_MIN_PX = 0.3
#: One 10-px outlier among 2-px measures on a uniform guide: after 2 re-weighted passes its residual
#: from 2 px must be at most this fraction of the one-pass residual (measured 0.016/0.588 = 0.026).
BILATERAL_ROBUST_RESIDUAL_FRACTION = 0.1
#: propagate_defocus(confidence=1) vs confidence=None (α·1 = α: measured bit-identical), px.
PROPAGATION_CONFIDENCE_ONES_ATOL = 1e-9
#: A measure with confidence 0 vs the same measure removed, max |Δσ| px: only the λ = 1e-6·α
#: regulariser's target mean(BM) still counts it (measured 8.5e-6 px, 30×36, while the same 9-px
#: measure at c = 1 moves the map by 5.8 px).
PROPAGATION_ZERO_CONFIDENCE_ATOL_PX = 1e-4

# --- the input's light (method/luma.py: estimate_defocus_map(encoding=...)) ---------------------
#: A linear image and its sRGB encoding (float, unquantised) give the same maps, px. Measured
#: 2026-12-06 on a 64×64 dead-leaves lens mosaic (σ 0.5–5 px) for paper, robust and zhuo_sim: max
#: |difference| 0 px in the sparse, refined and dense maps, identical edge sets (the sRGB round trip
#: of colour-science is exact to float64 round-off, and no threshold flips). Declaring the linear
#: image "srgb" instead moves the dense map by 1.3–3.2 px (robust's edges 427 → 228), so any
#: tolerance below ~0.1 px tells the two apart; 1e-6 px allows round-off on other platforms.
LIGHT_ENCODING_MAP_ATOL_PX = 1e-6

# --- signal-dependent noise model (method/blur/noise_model.py, method/luma.py decode_slope) ------------
#: Relative error of the predicted variance a·x + b (carried through the tone curve) against the sample
#: variance of 200×200 flat patches of scenes.display.camera_image: 4 standard errors of a sample
#: variance of N = 40 000 (4·√(2/N) = 2.8 %). Measured (seed 5, x = 0.15 / 0.3 / 0.6): ≤ 0.7 % but at
#: iso3200 through sRGB at x = 0.15 (+2.5 %, the second-order term the first-order tone-curve model
#: leaves out where the noise std is 20 % of the signal).
NOISE_MODEL_VARIANCE_RTOL = 0.028
#: Relative error of the estimated a and of the estimated variance a·x + b for x in [0.1, 0.9] on lens
#: mosaics (dead leaves, shading, photo crops; camera pipeline, 8 bits) at iso100 / iso800 / iso3200,
#: in linear and in display light. Measured (docs/noise.md): a within 0.98–1.08×, a·x + b within
#: 0.99–1.17× (worst: dead leaves, iso100, linear light, x = 0.1).
NOISE_ESTIMATE_A_RTOL = 0.15
NOISE_ESTIMATE_VARIANCE_RTOL = 0.25
#: |decode_slope − analytic sRGB derivative|: central differences of half-width 1e-4 on a C¹ curve.
DECODE_SLOPE_ATOL = 1e-6

# --- large blur: the model fit's scale following a coarse estimate (method/blur/scale_follow.py) ---
#: Isolated disk steps in linear light (320², ISO 100, 8 bits, seeds 0–1), robust + fit_follow_scale
#: 0.5 + σ2 16: share of edge pixels within max(2, σ/2) px of the step that measure, and |median
#: error| / σ. Measured 2026-12-06: coverage 0.97–1.00 and |median| ≤ 0.03 px at σ 12 and 16
#: (robust without it: coverage 0; with σ2 16 added but no re-fit, 0.18–0.23 at median −10 to −14 px).
LARGE_BLUR_MIN_COVERAGE = 0.9
LARGE_BLUR_MAX_REL_MEDIAN = 0.05
