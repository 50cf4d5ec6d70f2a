"""Named parameter sets of the pipeline: ``paper`` (the reproduction) and measured variants beyond it.

Each preset is a :class:`~method.params.DefocusParams`; a preset beyond the paper is written as its
changes from the paper's defaults, one named field each (flat field names, whatever stage holds them),
so each change is an ablation row of ``experiments.stage_attribution``. The measurements behind every
value: docs/presets.md. This module fills :data:`method.params.PRESETS` (the registry
:meth:`DefocusParams.preset` reads) and re-exports it.
"""

from __future__ import annotations

import math

from .params import PRESETS, DefocusParams
from .registry import Entry

__all__ = ["PRESETS", "REGION_CUE_CHANGES", "ROBUST_CHANGES", "ZHUO_SIM_CHANGES"]


#: The robust preset's departures from the paper, one named field each (so each is an ablation row
#: of ``experiments.stage_attribution``); the measurements behind every value: docs/presets.md.
ROBUST_CHANGES: dict = {
    "sigma1_scales": (0.5, 1.0, 2.0, 4.0, 8.0, 16.0),
    "sigma2_scales": (0.5, 1.0, 2.0, 4.0, 8.0),
    "estimator": "model_fit_checked",
    "fit_max_residual": 0.03,
    "fit_max_scale": 2.0,
    "fit_max_width_ratio": 0.75,
    "fit_below_scale": "nan",
    "fit_psf": "auto",
    "fit_residual_noise": 2.0,
    # each measure weighed in Eq. (3) and Eq. (4) by its own precision (1 / Var(σb) from the fit's
    # curvature under the pixel's noise; method.blur.measure_uncertainty) rather than a hand-set weight
    "measure_weighting": "uncertainty",
    # blurry edges re-fitted at a scale that follows a coarse estimate, only where the coarse fit and the
    # re-fit both explain the response as a blurred step (ρ ≤ 0.01; method.blur.scale_follow)
    "fit_follow_scale": 0.5,
    "fit_follow_max_residual": 0.01,
    "bilateral_range_kernel": "product",
    "bilateral_sigma_spatial": 0.05,
    "sharpness_bias": False,
    # no measure where the profile across the edge turns back before its plateaus (in-focus shading bands
    # read as blur; method.blur.step_plateau, reach limit fit_plateau_reach; docs/presets.md)
    "fit_step_gate": "plateau",
    # edges detected and their blur fitted in linear light (a lens blurs linear radiance; the sRGB
    # curve makes a blurred step asymmetric). The region cue (region_estimator) was measured and left
    # out: it did not improve the lens bench, the renders and the real photos at once (docs/presets.md).
    "measure_light": "linear",
    # magnification: the in-focus floor estimated per photo (the subject gets no extra blur), blurred by
    # the scatter (occlusion, linear light); measured in docs/magnification.md
    "map_floor": "auto",
    "magnify_renderer": "scatter",
    # the noise of Eq. (9) and of the fit's residual test per pixel: a·x + b in linear light, estimated
    # from the image per intensity level and carried through the tone curve (docs/presets.md, docs/noise.md).
    "noise_model": "signal_dependent",
    # that noise's spectrum estimated per octave band (resizing, demosaicking and JPEG correlate it): Eq. (9)
    # reads the variance each filter scale sees (docs/noise.md)
    "noise_spectrum": "estimated",
}

#: The region (spectral) cue as the robust preset fused it before it was judged on lens blur (Gaussian
#: model, no adequacy gate; docs/cue-fusion.md): an ablation row, not a preset.
REGION_CUE_CHANGES: dict = {
    "region_estimator": "local_spectrum",
    "fusion_edge_error_rel": 0.3,
    "fusion_island_weight": 0.001,
    "fusion_straddle_weight": 0.0,
}

#: Zhuo & Sim 2011 inside the harness: gradient-ratio blur at Canny edges as their public code
#: measures it (docs/zhuo-sim.md), a plain joint bilateral filter of the sparse map (their Sec. 3.2
#: error correction; no sharpness bias), matting-Laplacian propagation (their Sec. 4).
ZHUO_SIM_CHANGES: dict = {
    "estimator": "gradient_ratio",
    "edge_detector": "canny",
    "ratio_gradient_sigma": 1.0,
    "ratio_reblur_sigma": math.sqrt(1.25),
    "ratio_max_sigma": 5.0,
    "ratio_zero_is_measure": False,
    "matting_lambda": 0.001,
    "matting_epsilon": 9e-7,
    "matting_data_weight": "sigma",
    "refine": False,
    "sharpness_bias": False,
    "propagation": "matting_laplacian",
    # the matting system's CG stops at relative residual 1e-5, not 1e-6: the dense σ stays within 0.01 px
    # of the tol-1e-6 solve on the stages figure's renders with a margin (1e-4 reached 0.0095 px and 1e-3
    # 0.0104 px on the oracle systems; docs/figures.md). Eq. (4) keeps its own tolerance (propagation_tol).
    "matting_tol": 1e-5,
    # ... or once a CG step moved no pixel by more than 1e-4 px, whichever comes first: the error left was
    # ≤ 2.0e-3 px from the tol-1e-6 solve on those renders (20× the step; docs/figures.md).
    "matting_step_tol": 1e-4,
}

#: name -> DefocusParams. ``"paper"`` is the literal reproduction and equals ``DefocusParams()``.
PRESETS.update({
    "paper": Entry(DefocusParams(), "the paper's method and defaults (Bae & Durand 2007)"),
    "robust": Entry(DefocusParams(**ROBUST_CHANGES), "beyond the paper: checked fit in linear light, disk PSF"),
    "zhuo_sim": Entry(DefocusParams(**ZHUO_SIM_CHANGES), "Zhuo & Sim 2011 as their public code measures"),
})
