"""Blur estimation (Sec. 3.2): σ at edge pixels (the paper's model fit of Eq. 2c and baselines) and σ
over textured regions from the local spectrum (the second cue), each family in one registry.

Edge estimators (:data:`BLUR_ESTIMATORS`, :mod:`.estimators`): :mod:`.model_fit` (Eq. 2c; its template
search in :mod:`.fit_templates`, the PSF-model choice in :mod:`.psf_selection`),
:mod:`.model_fit_checked`, :mod:`.zero_crossing` (Elder & Zucker), :mod:`.gradient_ratio` (Zhuo & Sim);
:mod:`.disk_edge_response` (the disk PSF's step response); :mod:`.step_plateau` (the checked fit's
plateau gate, :data:`STEP_GATES`). Region estimators
(:data:`REGION_ESTIMATORS`, :mod:`.region_estimators`): :mod:`.local_spectrum` (its model spectra in
:mod:`.spectrum_model`, the noise estimate in :mod:`.image_noise`), :mod:`.gsm`. The sensor noise of Eq. (9)
and the fit's residual test: :mod:`.noise_model` (a·x + b per intensity level), :mod:`.noise_spectrum` (its
spread over frequency). The stages' parameters: :class:`.params.BlurParams`, :class:`.params.RegionParams`.
"""

from .estimators import BLUR_ESTIMATORS, estimate_blur, estimate_blur_measures, estimate_blur_with_confidence
from .region_estimators import REGION_ESTIMATORS, estimate_region_blur
from .params import BELOW_SCALE_RULES, BlurParams, RegionParams
from .step_plateau import STEP_GATES

__all__ = ["BELOW_SCALE_RULES", "BLUR_ESTIMATORS", "REGION_ESTIMATORS", "STEP_GATES", "BlurParams", "RegionParams", "estimate_blur", "estimate_blur_measures",
           "estimate_blur_with_confidence", "estimate_region_blur"]
