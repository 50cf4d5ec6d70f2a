"""The whole defocus-estimation pipeline of Bae & Durand 2007 (Sec. 2): image → dense blur map.

Stages, each in its own module:

1. :mod:`method.edges.elder_zucker` — multiscale steerable derivatives, Eq. (7)–(9), minimum
   reliable scales and the edge map (Sec. 3.1, Appendix B);
2. :mod:`method.blur.estimators` — blur σ at edge pixels by the registered estimator
   (``"model_fit"``, Eq. (2); ``"zero_crossing"``; ``"gradient_ratio"``) (Sec. 3.2);
3. :mod:`method.refine.cross_bilateral` — biased cross-bilateral refinement, Eq. (3) (Sec. 3.3);
4. :mod:`method.propagation.defocus` — propagation to every pixel, Eq. (4) (Sec. 4).

Beyond the paper, both off in the ``paper`` preset: isolation weights of the edge measures
(:mod:`method.edges.isolation`, ``params.edge_isolation``) and a region (spectral) blur estimator
(``params.region_estimator``, :func:`region_stage`) whose measures are fused with the edge measures
as data terms of Eq. (4) (:mod:`method.propagation.cue_fusion`). Eq. (3) stays edge-only.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable

import numpy as np

from .blur.estimators import BLUR_ESTIMATORS, estimate_blur_measures
from .blur.noise_model import noise_variance_map
from .blur.noise_spectrum import noise_spectrum_of
from .edges.canny import detect_edges_canny
from .refine.cross_bilateral import biased_cross_bilateral
from .refine.params import bias_strength
from .propagation.cue_fusion import fuse_cues
from .propagation.data_weights import edge_confidence, propagation_confidence
from .edges.isolation import isolation_weights
from .edges.elder_zucker import EdgeMap, detect_edges
from .luma import LUMA_WEIGHTS, luminance, measure_input  # noqa: F401 (LUMA_WEIGHTS re-exported)
from .params import DefocusParams
from .propagation.methods import propagate_blur_measures
from .edges.tone_curve import resolve_encoding

__all__ = ["DefocusResult", "NoEdgesWarning", "blur_stage", "edge_confidence", "edge_psf_family", "edges_stage",
           "estimate_defocus_map", "isolation_stage", "luminance", "propagate_stage", "propagation_confidence",
           "refine_stage", "region_stage", "straddle_edges"]

STAGES = ("edges", "blur_at_edges", "region_blur", "cross_bilateral", "propagation")


class NoEdgesWarning(UserWarning):
    """The image has no edge pixel above the noise thresholds; the defocus map is all zeros."""


@dataclasses.dataclass(frozen=True)
class DefocusResult:
    """Everything :func:`estimate_defocus_map` computed (all σ in px of the input image)."""

    edges: np.ndarray          # bool HxW: Elder–Zucker edge pixels (Sec. 3.1)
    sparse_sigma: np.ndarray   # float64 HxW: blur σ at edge pixels by params.estimator, NaN elsewhere (Sec. 3.2)
    refined_sigma: np.ndarray  # float64 HxW: after the biased cross-bilateral filter, NaN off edges (Eq. 3)
    defocus_map: np.ndarray    # float64 HxW: dense σ after propagation, ≥ 0 (Eq. 4)
    edge_map: EdgeMap          # scales, gradient direction and magnitude of the edge detector
    timings: dict              # wall-clock seconds per stage (keys: STAGES) and "total"
    params: DefocusParams      # the parameters used
    cpu_timings: dict = dataclasses.field(default_factory=dict)
    # CPU seconds of the whole process (all threads: numba, FFT workers) per stage and "total"
    # (time.process_time); with ``timings`` it shows the algorithmic cost on a shared machine.
    measure_confidence: np.ndarray | None = None
    # float64 HxW per-measure confidence c_q in (0, 1] (params.relaxed_fit_weight for measures admitted
    # by the fit's noise allowance only, 1 otherwise; with params.measure_weighting="uncertainty" ∝ 1/Var(σb):
    # method.blur.measure_uncertainty; NaN off measures), or None when every c_q = 1.
    psf_disk: np.ndarray | None = None
    # bool HxW: True at the measures whose edge response was fitted with the disk PSF model of a thin
    # lens (params.fit_psf "disk", "best", or "auto" when it chose the disk), False at the other
    # pixels; None when params.estimator fits no PSF model (no "psf_model" hook in method.blur.estimators.BLUR_ESTIMATORS).
    region_sigma: np.ndarray | None = None
    # float64 HxW: blur σ, px, of the region estimator (params.region_estimator; NaN where it has no
    # measure), fused with the edge measures in Eq. (4); None when params.region_estimator is None.
    region_information: np.ndarray | None = None
    # float64 HxW: Fisher information of region_sigma, px⁻² (1 / variance); None with region_sigma.
    encoding: str = "srgb"
    # the tone curve the input was read with (key of method.luma.ENCODINGS): as declared, or for
    # encoding="auto" the curve method.edges.tone_curve.fit_encoding chose for this image.

    @property
    def psf_model(self) -> str | None:
        """Which edge-response model measured the blur: "gaussian" (Eq. 2c), "disk", "mixed" or None.

        "mixed" when some measures used each model (``fit_psf="best"``); "gaussian" also when there
        are no measures; None when the estimator fits no PSF model.
        """
        if self.psf_disk is None:
            return None
        n_disk = int(np.count_nonzero(self.psf_disk))
        n = int(np.count_nonzero(np.isfinite(self.sparse_sigma)))
        return "gaussian" if n_disk == 0 else "disk" if n_disk == n else "mixed"


def estimate_defocus_map(image, params=None, *, encoding: str = "srgb",
                         progress: Callable[[str], None] | None = None) -> DefocusResult:
    """Estimate the spatially varying defocus blur σ of a single photo (Bae & Durand 2007).

    Parameters
    ----------
    image : ndarray, HxWx3 or HxW, float in [0, 1]
        The photo, its values in ``encoding``. Sides ≥ 8 px.
    params : DefocusParams, optional
        Pipeline parameters; the paper's defaults when omitted.
    encoding : str, keyword-only
        What the image's values are, a key of :data:`method.edges.tone_curve.INPUT_ENCODINGS`: ``"srgb"``
        (default; sRGB-encoded display values, as a camera delivers them), ``"linear"`` (linear
        radiance, as a render or an OpenEXR file holds it), another tone curve of
        :data:`method.luma.ENCODINGS`, or ``"auto"`` (display values of unknown curve, fitted per
        image: :func:`method.edges.tone_curve.fit_encoding`; the result's ``encoding`` names it).
    progress : callable, optional, keyword-only
        Called with each stage's name (see ``STAGES``) as it starts, for progress displays.

    Returns
    -------
    DefocusResult
        ``edges``, ``sparse_sigma``, ``refined_sigma``, ``defocus_map`` (σ in px), ``timings``
        (wall s) and ``cpu_timings`` (process CPU s, all threads).

    Raises
    ------
    ValueError
        Bad image (wrong shape, dtype, range, NaN/Inf, too small), unknown encoding or bad parameters.

    Warns
    -----
    NoEdgesWarning
        When no edge pixel survives the noise thresholds; the map is then all zeros.

    Notes
    -----
    1. The input is converted once from ``encoding`` into the light each stage measures in
       (:func:`method.luma.measure_input`): luminance (Rec. 709 weights) in
       ``params.measure_light`` feeds the edge detector and the blur estimator (the paper: the
       display values; beyond the paper: linear light); the RGB image in display values is the
       reference image of the cross-bilateral filter and of the propagation affinities. An sRGB
       input and its linear radiance give the same map (up to the round-off of the sRGB curve).
    2. Multiscale Elder–Zucker edges with the Eq. (9) thresholds (Sec. 3.1; :func:`edges_stage`);
       for the estimators that sample them again (model fit) the detector keeps its 2nd-derivative
       responses at the σ2 that produced edges.
    3. Blur σ at edge pixels with ``params.estimator`` (Sec. 3.2; :func:`blur_stage`), reusing
       those responses; they are dropped from the returned EdgeMap.
    4. Biased cross-bilateral refinement of the sparse measures, Eq. (3) (Sec. 3.3).
    5. Propagation by minimising Eq. (4): (LᵀL + diag α) B = α·BM (Sec. 4).

    Beyond the paper (both off in ``paper``): with ``params.edge_isolation`` the measures'
    confidence is multiplied by their isolation weight (:func:`isolation_stage`) after step 3; with
    ``params.region_estimator`` the region estimator runs on the luminance (stage "region_blur",
    :func:`region_stage`) and its measures join the refined edge measures as data terms of Eq. (4)
    by inverse variance (:func:`method.propagation.cue_fusion.fuse_cues`). Eq. (3) stays edge-only.
    """
    params = DefocusParams() if params is None else params
    if not isinstance(params, DefocusParams):
        raise ValueError(f"params must be a DefocusParams, got {type(params).__name__}")
    encoding = resolve_encoding(image, encoding)
    measured = measure_input(image, params, encoding=encoding)
    rgb, gray, seen = measured.rgb, measured.gray, measured.seen
    timings: dict[str, float] = {}
    cpu: dict[str, float] = {}
    t_start = time.perf_counter()
    c_start = time.process_time()
    c_last = [c_start]

    def stage(name):
        if progress is not None:
            progress(name)
        c_last[0] = time.process_time()
        return time.perf_counter()

    def done(name, t):
        timings[name] = time.perf_counter() - t
        cpu[name] = time.process_time() - c_last[0]

    t = stage("edges")
    edge_map = edges_stage(seen, params=params, encoding=encoding)
    done("edges", t)

    t = stage("blur_at_edges")
    sparse, confidence, edge_map, psf_disk = blur_stage(seen, edge_map, params=params)
    if params.edge_isolation is not None:
        confidence = isolation_stage(seen, edge_map, sparse, params=params, confidence=confidence)
    done("blur_at_edges", t)

    if params.region_estimator is not None:
        t = stage("region_blur")
        region_sigma, region_info = region_stage(gray, params=params, edge_psf=edge_psf_family(sparse, psf_disk))
        done("region_blur", t)
    else:
        region_sigma = region_info = None
        timings["region_blur"] = 0.0
        cpu["region_blur"] = 0.0
    has_region = region_sigma is not None and bool(np.any(np.isfinite(region_sigma)))

    shape = gray.shape
    if not np.any(np.isfinite(sparse)) and not has_region:
        warnings.warn(
            "no edges found above the noise thresholds; returning an all-zero defocus map",
            NoEdgesWarning, stacklevel=2,
        )
        for name in ("cross_bilateral", "propagation"):
            timings[name] = 0.0
            cpu[name] = 0.0
        timings["total"] = time.perf_counter() - t_start
        cpu["total"] = time.process_time() - c_start
        return DefocusResult(
            edges=edge_map.edges.copy(), sparse_sigma=sparse, refined_sigma=np.full(shape, np.nan),
            defocus_map=np.zeros(shape), edge_map=edge_map, timings=timings, params=params,
            cpu_timings=cpu, measure_confidence=confidence, psf_disk=psf_disk,
            region_sigma=region_sigma, region_information=region_info, encoding=encoding,
        )

    t = stage("cross_bilateral")
    if np.any(np.isfinite(sparse)):
        refined = refine_stage(sparse, rgb, params=params, confidence=confidence)
    else:  # region measures only
        refined = np.full(shape, np.nan)
    done("cross_bilateral", t)

    t = stage("propagation")
    isolated = straddle_edges(seen, edge_map, sparse, params=params) if has_region else None
    dense = propagate_stage(refined, rgb, params=params, sparse_sigma=sparse, confidence=confidence,
                            region_sigma=region_sigma, region_information=region_info, gray=gray,
                            isolated_edges=isolated)
    done("propagation", t)
    timings["total"] = time.perf_counter() - t_start
    cpu["total"] = time.process_time() - c_start
    return DefocusResult(
        edges=edge_map.edges.copy(), sparse_sigma=sparse, refined_sigma=refined,
        defocus_map=dense, edge_map=edge_map, timings=timings, params=params, cpu_timings=cpu,
        measure_confidence=confidence, psf_disk=psf_disk, region_sigma=region_sigma,
        region_information=region_info, encoding=encoding,
    )


def edges_stage(gray, *, params, encoding: str = "srgb"):
    """Elder–Zucker edges with minimum reliable scales (Sec. 3.1) as ``params`` configure them.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (:func:`luminance`).
    params : DefocusParams, keyword-only
        ``sigma1_scales``, ``sigma2_scales`` (px), ``noise_std``, ``false_positive_rate``,
        ``estimator`` (the detector keeps its 2nd-derivative responses for the estimators of
        the ``"detector_hessians"`` capability in :data:`method.blur.estimators.BLUR_ESTIMATORS`). With ``edge_detector="canny"``
        (beyond the paper: Zhuo & Sim's edge set) Canny edges instead, from ``canny_sigma`` (px),
        ``canny_low_threshold`` and ``canny_high_threshold``
        (:func:`method.edges.canny.detect_edges_canny`). With ``noise_model="signal_dependent"``
        (beyond the paper) the thresholds of Eq. (9) read the per-pixel noise variance of
        :func:`method.blur.noise_model.noise_variance_map` (from ``noise_a``, ``noise_b`` or
        estimated from ``gray``), kept on the EdgeMap for the checked fit's residual test; with
        ``noise_spectrum="estimated"`` also the noise's spectrum
        (:func:`method.blur.noise_spectrum.noise_spectrum_of`), so each filter scale's threshold
        follows the correlated noise that filter sees.
    encoding : str, keyword-only
        The input's encoding (key of :data:`method.luma.ENCODINGS`): its tone curve carries the noise
        into display light (``noise_model="signal_dependent"`` only).

    Returns
    -------
    EdgeMap
    """
    if params.edge_detector == "canny":
        return detect_edges_canny(gray, sigma=params.canny_sigma, low_threshold=params.canny_low_threshold,
                                  high_threshold=params.canny_high_threshold)
    return detect_edges(gray, sigma1_scales=params.sigma1_scales, sigma2_scales=params.sigma2_scales,
                        noise_std=params.noise_std, false_positive_rate=params.false_positive_rate,
                        noise_variance=lambda: noise_variance_map(gray, params, encoding=encoding),
                        noise_spectrum=lambda: noise_spectrum_of(gray, params),
                        keep_hessians="detector_hessians" in BLUR_ESTIMATORS.entry(params.estimator).capabilities)


def blur_stage(gray, edge_map, *, params):
    """Blur measures at the edges (Sec. 3.2) with the estimator of ``params``, and their confidence.

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        Output of :func:`edges_stage` for ``gray``.
    params : DefocusParams, keyword-only

    Returns
    -------
    sparse_sigma : ndarray, shape (H, W), float64
        σ in px at edge pixels, NaN elsewhere and where the estimator fails.
    confidence : ndarray, shape (H, W), float64, or None
        Per-measure confidence (:func:`method.blur.estimators.estimate_blur_with_confidence`).
    edge_map : EdgeMap
        ``edge_map`` without its 2nd-derivative responses (~12 MB per σ2 at 1 MP, not kept).
    psf_disk : ndarray, shape (H, W), bool, or None
        Measures fitted with the disk PSF model (``params.fit_psf``); None when the estimator fits
        no PSF model (:func:`method.blur.estimators.estimate_blur_measures`).
    """
    sparse, confidence, psf_disk = estimate_blur_measures(gray, edge_map, params=params)
    sparse = np.where(edge_map.edges, np.asarray(sparse, dtype=np.float64), np.nan)
    return sparse, confidence, dataclasses.replace(edge_map, hessians=None), psf_disk


def isolation_stage(gray, edge_map, sparse_sigma, *, params, confidence=None) -> np.ndarray:
    """The measures' confidence times their isolation weight (beyond the paper; ``params.edge_isolation``).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1].
    edge_map : EdgeMap
        The detector's output (edges and gradient direction θ).
    sparse_sigma : ndarray, shape (H, W), float
        Blur measures, px, NaN off edges (:func:`blur_stage`).
    params : EdgeParams or DefocusParams, keyword-only
        ``edge_isolation`` (not None), ``isolation_radius``, ``isolation_floor``.
    confidence : ndarray, shape (H, W), float in (0, 1], or None, keyword-only
        The estimator's confidence (None: 1).

    Returns
    -------
    ndarray, shape (H, W), float64
        c_q · w_q in (0, 1] at the measures, NaN elsewhere
        (:func:`method.edges.isolation.isolation_weights`).
    """
    w = isolation_weights(gray, edge_map.edges, edge_map.theta, sparse_sigma, method=params.edge_isolation,
                          radius=params.isolation_radius, floor=params.isolation_floor)
    return w if confidence is None else np.where(np.isfinite(w), w * confidence, np.nan)


def region_stage(gray, *, params, edge_psf=None):
    """Region (spectral) blur measures and their Fisher information (beyond the paper).

    Parameters
    ----------
    gray : ndarray, shape (H, W), float
        Luminance in [0, 1] (:func:`luminance` of the sRGB input, as the edge fit sees it).
    params : RegionParams or DefocusParams, keyword-only
        ``region_estimator`` (None: no measures) and its options.
    edge_psf : {"gaussian", "disk"} or None, keyword-only
        The PSF family most edge measures were fitted with (``params.region_psf == "edges"``).

    Returns
    -------
    sigma : ndarray, shape (H, W), float64, or None
        σ, px, NaN where the estimator has no measure; None when ``params.region_estimator`` is None.
    information : ndarray, shape (H, W), float64, or None
        Fisher information of σ, px⁻²; None with ``sigma``.
    """
    if params.region_estimator is None:
        return None, None
    from .blur.region_estimators import estimate_region_blur

    sigma, information = estimate_region_blur(gray, params=params, edge_psf=edge_psf)
    return np.asarray(sigma, dtype=np.float64), np.asarray(information, dtype=np.float64)


def refine_stage(sparse_sigma, rgb, *, params, confidence=None) -> np.ndarray:
    """Stage 3: the cross-bilateral refinement of Eq. (3) as ``params`` configure it.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels; NaN elsewhere (the estimator's output, or an oracle's).
    rgb : ndarray, HxWx3, float in [0, 1]
        Guide image.
    params : RefineParams or DefocusParams, keyword-only
        ``refine`` (False: the measures pass unchanged), ``bilateral_*``, ``sharpness_bias``,
        ``bias_scale`` with ``bias_reference`` (px, or a fraction of max(H, W)), ``refinement_robust_*``,
        ``bias_weighting`` (``"uncertainty"``: the bias of each measure raised to 1 − c_q).
    confidence : ndarray, HxW, float in (0, 1], or None, keyword-only
        Beyond the paper: per-measure confidence c_q multiplying its Eq. (3) weight (the
        estimator's ``measure_confidence``); None: all 1 (paper; oracle inputs; with
        ``bias_weighting="uncertainty"`` then no measure is biased).

    Returns
    -------
    ndarray, HxW, float64
        Refined σ, px, at the finite pixels of ``sparse_sigma``; NaN elsewhere.
    """
    if not params.refine:
        return np.array(sparse_sigma, dtype=np.float64)
    scale = params.bias_scale
    if params.bias_reference == "image_fraction":
        scale = params.bias_scale * max(sparse_sigma.shape)
    return biased_cross_bilateral(
        sparse_sigma, rgb,
        sigma_spatial=params.bilateral_sigma_spatial,
        sigma_range=params.bilateral_sigma_range,
        sharpness_bias=params.sharpness_bias,
        bias_scale=scale,
        method=params.bilateral_method,
        range_kernel=params.bilateral_range_kernel,
        robust_iterations=params.refinement_robust_iterations,
        robust_scale=params.refinement_robust_scale,
        weights=confidence,
        bias_strength=bias_strength(sparse_sigma, confidence, params),
    )


def edge_psf_family(sparse_sigma, psf_disk) -> str | None:
    """The PSF family most edge fits chose ("disk" or "gaussian"), for ``region_psf="edges"``.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Edge measures, px (NaN where none).
    psf_disk : ndarray, HxW, bool, or None
        ``DefocusResult.psf_disk`` (None when the estimator fits no PSF model).

    Returns
    -------
    str or None
        "disk" when more than half of the measures used the disk model, else "gaussian"; None
        without a PSF model.
    """
    if psf_disk is None:
        return None
    n = int(np.count_nonzero(np.isfinite(sparse_sigma)))
    return "disk" if n and 2 * int(np.count_nonzero(psf_disk)) > n else "gaussian"


def straddle_edges(gray, edge_map, sparse_sigma, *, params) -> np.ndarray | None:
    """Isolated edge measures for the fusion's straddle test (``params.fusion_straddle_weight`` < 1).

    Parameters
    ----------
    gray : ndarray, HxW, float
        Luminance.
    edge_map : EdgeMap
        The edge detector's output (edges and gradient direction).
    sparse_sigma : ndarray, HxW, float
        Edge measures, px (NaN where none).
    params : DefocusParams, keyword-only
        ``fusion_straddle_weight``, ``isolation_radius``, ``isolation_floor``.

    Returns
    -------
    ndarray, HxW, bool, or None
        True at measures with full isolation weight (:func:`method.edges.isolation.isolation_weights`,
        method "normal"); None when the straddle test is off.
    """
    if not params.fusion_straddle_weight < 1:
        return None
    iso = isolation_weights(gray, edge_map.edges, edge_map.theta, sparse_sigma, method="normal",
                            radius=params.isolation_radius, floor=params.isolation_floor)
    return np.isfinite(iso) & (iso >= 1.0)


def propagate_stage(refined_sigma, rgb, *, params, sparse_sigma=None, confidence=None, region_sigma=None,
                    region_information=None, gray=None, isolated_edges=None) -> np.ndarray:
    """Stage 4: propagation (Eq. 4, or the registered ``params.propagation``), clipped to [0, max_sigma].

    Parameters
    ----------
    refined_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels; NaN elsewhere.
    rgb : ndarray, HxWx3, float in [0, 1]
        Guide image.
    params : DefocusParams, keyword-only
    sparse_sigma : ndarray, HxW, float, or None, keyword-only
        The raw measures, needed by ``alpha_confidence="agreement"`` (None: refined used as raw).
    confidence : ndarray, HxW, float in (0, 1], or None, keyword-only
        Beyond the paper: per-measure confidence c_p (the estimator's ``measure_confidence``), so
        α_p = α·c_p (times the agreement factor when ``alpha_confidence="agreement"``); None: 1.
    region_sigma, region_information : ndarray, HxW, float, or None, keyword-only
        Beyond the paper: region measures σ_r (px, NaN where none) and their Fisher information
        (px⁻²), fused with the edge measures as data terms of Eq. (4) by inverse variance
        (:func:`method.propagation.cue_fusion.fuse_cues`, ``params.fusion_*``); None: edge measures only.
    gray : ndarray, HxW, float, or None, keyword-only
        Luminance for the fusion's island test (None: :func:`luminance` of ``rgb``).
    isolated_edges : ndarray, HxW, bool, or None, keyword-only
        Isolated edge measures for the fusion's straddle test (``params.fusion_straddle_weight``).

    Returns
    -------
    ndarray, HxW, float64
        Dense σ, px, in [0, max_sigma].
    """
    confidence = propagation_confidence(refined_sigma, params=params, sparse_sigma=sparse_sigma,
                                        confidence=confidence)
    if region_sigma is not None:
        if region_information is None:
            raise ValueError("region_information is needed with region_sigma")
        gray = luminance(rgb) if gray is None else gray
        refined_sigma, confidence = fuse_cues(refined_sigma, confidence, region_sigma, region_information,
                                              gray=gray, params=params, isolated_edges=isolated_edges)
        if not np.any(np.isfinite(refined_sigma)):
            return np.zeros(refined_sigma.shape)
        # fused weights may exceed 1 (a region term stands for a window of pixels)
        c_max = max(1.0, float(np.nanmax(confidence)))
        dense = propagate_blur_measures(refined_sigma, rgb, params=params, confidence=confidence,
                                        max_confidence=c_max)
        return np.clip(dense, 0.0, params.max_sigma)
    dense = propagate_blur_measures(refined_sigma, rgb, params=params, confidence=confidence)
    return np.clip(dense, 0.0, params.max_sigma)
