"""Fig. 5: the sparse blur measure before and after the biased cross-bilateral filter (Sec. 3.3, Eq. 3).

The paper's outliers are edges that look blurry although they are in focus — soft shadows and
glossy highlights. The ``shadow_gloss`` scene has both (a box's soft shadow and a glossy sphere's
highlight at the focus distance); a second scene without them is the control. Each is filtered
with the sharpness bias b(BM) = exp(−BM/2) (the paper) and without it (plain cross-bilateral
ablation, ``DefocusParams(sharpness_bias=False)``).

Notes
-----
1. Render (cached), sRGB 8-bit input; luminance → edges → σ at edges by ``estimator``
   (:func:`experiments.evaluation.sparse_estimates`, the same calls as
   :func:`method.estimate_defocus_map`'s first two stages).
2. :func:`method.biased_cross_bilateral` on the sparse map with the RGB input as guide, with and
   without the bias, every other parameter the paper's (σs = 10 % of the size, σr = 10 % of the range).
3. Metrics at edge pixels not on occlusion boundaries: MAE etc. (:func:`~experiments.metrics.sparse_metrics`)
   and the in-focus outlier fraction (σ_gt ≤ 1 px estimated > 2 px,
   :func:`~experiments.metrics.in_focus_outlier_fraction`), before / after / after without bias.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig5Config", "compute"]

#: Stages compared, in plot order.
STAGES = ("before", "after_bias", "after_no_bias")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig5Config:
    """Every parameter of Fig. 5."""

    scenes: tuple[str, ...] = ("shadow_gloss", "planes")
    # keys of scenes.SCENES: the outlier scene (soft shadow + glossy highlight) and a control.
    f_numbers: tuple[float, ...] = (8.0, 4.0)
    # apertures N, dimensionless.
    preset: str = "full"
    # render resolution preset ("small" 160×120, "full" 640×480 px).
    estimator: str = "model_fit"
    # key of method.BLUR_ESTIMATORS producing the sparse blur measure (the paper's).
    encoding: str = "srgb"
    # input encoding (as a camera stores it).
    quantize_bits: int | None = 8
    # bits per channel of the input.
    convention: str = "line_spread"
    # σ_gt convention (scenes.thin_lens.SIGMA_CONVENTIONS).
    in_focus_px: float = 1.0
    # σ_gt at or below this counts as in focus, px.
    blurry_px: float = 2.0
    # an estimate above this counts as blurry, px.


FULL = Fig5Config()
QUICK = Fig5Config(preset="small")


def compute(config: Fig5Config) -> dict:
    """Sparse maps before/after Eq. (3) with and without the bias, and their metrics.

    Parameters
    ----------
    config : Fig5Config

    Returns
    -------
    dict
        Per case ``c`` = ``<scene>_f<N>``: ``<c>_image`` HxWx3, ``<c>_sigma_gt`` HxW px,
        ``<c>_occlusion`` HxW bool, ``<c>_before`` / ``<c>_after_bias`` / ``<c>_after_no_bias``
        HxW px (NaN off edges); ``cases`` (str); ``metrics[case][stage]`` = sparse metrics +
        ``in_focus_outliers``; ``metrics["summary"]`` the headline numbers.
    """
    from method import DefocusParams, biased_cross_bilateral
    from scenes import render_scene

    from .evaluation import ground_truth_sigma, input_image, sparse_estimates, validate_estimators
    from .metrics import in_focus_outlier_fraction, sparse_metrics

    validate_estimators([config.estimator])
    params = DefocusParams(estimator=config.estimator)
    out: dict = {}
    metrics: dict = {}
    cases = []
    t0 = time.perf_counter()
    for scene in config.scenes:
        for n in config.f_numbers:
            case = f"{scene}_f{n:g}"
            cases.append(case)
            render = render_scene(scene, preset=config.preset, f_number=n, progress=False)
            image = input_image(render, encoding=config.encoding, quantize_bits=config.quantize_bits)
            gt = ground_truth_sigma(render, convention=config.convention)
            keep = ~np.asarray(render.occlusion_boundary, dtype=bool)
            _, sig = sparse_estimates(image, [config.estimator], params=params)
            before = sig[config.estimator]
            maps = {"before": before}
            for stage, bias in (("after_bias", True), ("after_no_bias", False)):
                maps[stage] = biased_cross_bilateral(
                    before, image, sigma_spatial=params.bilateral_sigma_spatial,
                    sigma_range=params.bilateral_sigma_range, sharpness_bias=bias,
                    bias_scale=params.bias_scale, method=params.bilateral_method)
            metrics[case] = {}
            for stage, m in maps.items():
                sm = sparse_metrics(m, gt, mask=keep)
                sm["in_focus_outliers"] = in_focus_outlier_fraction(
                    m, gt, mask=keep, in_focus_px=config.in_focus_px, blurry_px=config.blurry_px)
                metrics[case][stage] = sm
                out[f"{case}_{stage}"] = m.astype(np.float32)
            out[f"{case}_image"] = image.astype(np.float32)
            out[f"{case}_sigma_gt"] = gt.astype(np.float32)
            out[f"{case}_occlusion"] = ~keep
    metrics["summary"] = {
        case: {f"{stage}.{k}": (metrics[case][stage]["mae"] if k == "mae"
                                else metrics[case][stage]["in_focus_outliers"]["fraction"])
               for stage in STAGES for k in ("mae", "in_focus_outlier_fraction")}
        for case in cases
    }
    metrics["timings"] = {"total_s": time.perf_counter() - t0}
    metrics["definitions"] = {
        "mae": "mean |σ_est − σ_gt| at edge pixels off occlusion boundaries, px",
        "in_focus_outlier_fraction": f"fraction of those with σ_gt ≤ {config.in_focus_px} px estimated "
                                     f"> {config.blurry_px} px",
    }
    return {"cases": np.asarray(cases), **out, "metrics": metrics}


FIGURE = Figure(
    name="fig5",
    title="Blur measure before/after the biased cross-bilateral filter (Eq. 3), with a no-bias ablation",
    compute=compute,
    plot="experiments.plotting.fig5:plot",
    configs={"quick": QUICK, "full": FULL},
    version=1,
)
