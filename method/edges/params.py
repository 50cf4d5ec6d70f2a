"""Parameters of the edge stage (Sec. 3.1): the multiscale Elder–Zucker detector, the light it sees,
Canny (Zhuo & Sim's edge set) and the isolation weights of the edge measures.

Images are floats in [0, 1]; scales are Gaussian σ in px of the input image. Measurements behind the
values beyond the paper: docs/presets.md ("Per-field measurements").
"""

from __future__ import annotations

import dataclasses

from ..luma import MEASURE_LIGHTS
from ..registry import Registry
from ..validation import check_field_choice, invalid_field, require_field
from .isolation import EDGE_ISOLATION_METHODS
from .noise_thresholds import NOISE_SPECTRA, SENSOR_NOISE_MODELS

__all__ = ["EDGE_DETECTORS", "EdgeParams"]

_INF = float("inf")

#: ``EdgeParams.edge_detector`` (read by :func:`method.pipeline.edges_stage`).
EDGE_DETECTORS = Registry("edge detector", {
    "elder_zucker": "Elder & Zucker 1998 multi-scale detector, Eq. (7)-(9) (the paper)",
    "canny": "Canny edges (Zhuo & Sim's edge set); only with estimator='gradient_ratio'",
})


@dataclasses.dataclass(frozen=True, kw_only=True)
class EdgeParams:
    """Where the blur is measured: edge pixels and their minimum reliable scales (Sec. 3.1, Appendix B).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``); the
    scale tuples are normalised to sorted tuples of float.
    """

    sigma1_scales: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
    # σ1 of the steerable 1st-derivative filters, px (Sec. 3.1, Eq. 7); searched smallest first.
    sigma2_scales: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
    # σ2 of the steerable 2nd-derivative filters, px (Sec. 3.1, Eq. 8); searched smallest first.
    noise_std: float = 2.5 / 255.0
    # sensor noise s_n, image units ([0, 1] scale): 2.5 grey levels of 8 bits (Sec. 3.1, Eq. 9).
    # Also read by the checked fit's noise allowance and the fusion's island test.
    noise_model: str = "constant"
    # beyond the paper: the noise of Eq. (9)'s thresholds and of the checked fit's residual test (key of
    # method.edges.noise_thresholds.SENSOR_NOISE_MODELS): "constant" (noise_std everywhere, paper) or
    # "signal_dependent" (per pixel, variance a·x + b of the linear signal x carried through the tone
    # curve into measure_light; method.blur.noise_model).
    noise_spectrum: str = "white"
    # beyond the paper, read with noise_model "signal_dependent" only: how that noise spreads over frequency (key of
    # method.edges.noise_thresholds.NOISE_SPECTRA): "white" (each filter scale sees the pixel-scale
    # variance) or "estimated" (the spectrum per octave band from the image, method.blur.noise_spectrum:
    # Eq. (9)'s thresholds and the fit's residual test use the variance of each filter's response to
    # the correlated noise that resizing, demosaicking or JPEG leave; docs/noise.md).
    noise_a: float | None = None
    noise_b: float | None = None
    # noise_model "signal_dependent": shot-noise gain a (linear units) and read-noise variance b (linear
    # units²) of the measured luminance's noise, a·x + b; None (both): estimated from the image per
    # intensity level (method.blur.noise_model.estimate_noise_levels).
    measure_light: str = "display"
    # the light edges are detected and their blur measured in (key of method.luma.MEASURE_LIGHTS):
    # "display" (sRGB-encoded values, paper) or "linear" (linear light: a lens blurs linear radiance;
    # noise_std is then in linear units). The input is converted into it from its declared encoding
    # (estimate_defocus_map(encoding=...)). Eq. (3), Eq. (4) and the region cue read display values
    # either way.
    false_positive_rate: float = 1e-6
    # image-wide false-positive tolerance α_I = 0.0001 %, dimensionless (Sec. 3.1, Eq. 9).
    edge_detector: str = "elder_zucker"
    # key of EDGE_DETECTORS: "elder_zucker" (Sec. 3.1, the paper) or "canny" (Canny 1986 via
    # skimage.feature.canny, Zhuo & Sim 2011's edge set; method.edges.canny). "canny" only with
    # estimator "gradient_ratio": the other estimators read the detector's σ2 scales.
    canny_sigma: float = 1.0
    # σ of Canny's Gaussian smoothing, px (edge_detector="canny"; Zhuo & Sim's public code: 1).
    canny_low_threshold: float = 0.1
    canny_high_threshold: float = 0.2
    # Canny hysteresis thresholds on skimage's Sobel magnitude of the smoothed image (≈ 8·|∇I|, image
    # units/px); skimage's defaults for float images, as Zhuo & Sim's public code uses them.
    edge_isolation: str | None = None
    # beyond the paper: how much an edge measure is trusted given its neighbours (key of
    # method.edges.isolation.EDGE_ISOLATION_METHODS; None: every measure weighs fully, paper).
    # "normal": weight 1 when no other edge pixel lies within isolation_radius·max(σ̂, 1 px) along the
    # gradient normal (a bar's two edges widen each other's response); "persistence": weight 1 when the
    # edge is still detected at a scale ≈ its own σ̂ (Karaali & Jung 2018). The weight multiplies the
    # measure's confidence c_q (Eq. 3 and α_p of Eq. 4).
    isolation_radius: float = 3.0
    # distance, in units of the measure's max(σ̂, 1 px), within which another edge down-weights it.
    isolation_floor: float = 0.1
    # weight in (0, 1] of a measure whose neighbour edge touches it; rises as (d / radius)² to 1.

    def __post_init__(self):
        for name in ("sigma1_scales", "sigma2_scales"):  # normalised: sorted tuple of float px
            try:
                scales = tuple(sorted(float(v) for v in getattr(self, name)))
            except (TypeError, ValueError):
                scales = ()
            if not scales or any(not (v > 0) for v in scales):
                raise invalid_field(name, getattr(self, name), "non-empty tuple of positive scales (px)")
            object.__setattr__(self, name, scales)
        require_field(self, "noise_std", self.noise_std > 0, "> 0")
        check_field_choice(self, "measure_light", MEASURE_LIGHTS)
        check_field_choice(self, "noise_model", SENSOR_NOISE_MODELS)
        check_field_choice(self, "noise_spectrum", NOISE_SPECTRA)
        for name in ("noise_a", "noise_b"):
            value = getattr(self, name)
            require_field(self, name, value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)
                                                        and 0 <= value < _INF), "None or finite and >= 0")
        require_field(self, "noise_b", (self.noise_a is None) == (self.noise_b is None),
                      "None together with noise_a, or a value with it")
        require_field(self, "noise_b", self.noise_a is None or self.noise_a + self.noise_b > 0,
                      "noise_a + noise_b > 0 (a noise-free sensor has no Eq. (9) threshold)")
        require_field(self, "false_positive_rate", 0 < self.false_positive_rate < 1, "0 < α_I < 1")
        check_field_choice(self, "edge_detector", EDGE_DETECTORS)
        require_field(self, "canny_sigma", 0 < self.canny_sigma < _INF, "finite and > 0 (px)")
        require_field(self, "canny_low_threshold", 0 <= self.canny_low_threshold <= self.canny_high_threshold < _INF,
                      "finite 0 <= canny_low_threshold <= canny_high_threshold")
        check_field_choice(self, "edge_isolation", EDGE_ISOLATION_METHODS, optional=True)
        require_field(self, "isolation_radius", 0 < self.isolation_radius < _INF, "finite and > 0 (units of σ̂)")
        require_field(self, "isolation_floor", 0 < self.isolation_floor <= 1, "0 < weight <= 1")
