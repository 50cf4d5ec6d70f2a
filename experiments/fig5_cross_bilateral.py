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
4. Bias-scale sweep (an ablation of the trade-off the bias makes): for every s in
   ``config.bias_scales`` the same sparse map (one edge detection + blur estimation per case) is
   filtered with b(BM) = exp(−BM/s) (s = inf: no bias, the same call as ``after_no_bias``), then
   propagated to a dense map with :func:`method.propagate_defocus` and the
   :class:`~method.DefocusParams` defaults, clipped to [0, ``max_sigma``] as
   :func:`method.estimate_defocus_map` does. Scored: the refined measures at in-focus edges
   (σ_gt ≤ ``in_focus_px``) and blurry edges (σ_gt ≥ ``blurry_edge_px``) — MAE and bias; the
   in-focus outlier fraction; the dense map over ``all`` / ``textured`` / ``edges`` pixels
   (:func:`~experiments.metrics.region_masks`, occlusion boundaries excluded) — MAE and bias.
   A smaller s trusts sharp measures more: fewer in-focus outliers, but blurry edges pulled
   towards their sharp neighbours. For each edge pixel the refined value is a weighted mean of
   BM under weights w_pq·exp(−BM_q/s) — an exponential tilt, so it is non-decreasing in s.
5. Cases (:func:`cases`): per scene set × scene × aperture a ``stages`` case (steps 1–3) and, needing
   its sparse measure, one case per bias scale s (step 4, ``variant = scale_label(s)``).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "SWEEP_CURVES", "Fig5Config", "bias_sweep", "cases", "compute_case", "scale_label"]

#: Stages compared, in plot order.
STAGES = ("before", "after_bias", "after_no_bias")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig5Config:
    """Every parameter of Fig. 5."""

    scene_sets: tuple = (("paper_cameras", ("patio_table", "portrait_garden")),
                         ("tabletop_stress", ("shadow_gloss", "planes")))
    # (scene set, scenes) pairs (experiments.scene_sets), the first the default: the outlier scene of
    # each set (soft shadow + glossy highlight) and a control.
    outlier_scenes: tuple[str, ...] = ("patio_table", "shadow_gloss")
    # which scenes have the paper's outliers (the metric outlier_scene of their stage cases, for the claims).
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
    bias_scales: tuple[float, ...] = (1.0, 2.0, 4.0, 8.0, math.inf)
    # sweep of the sharpness-bias scale s in b(BM) = exp(−BM/s), px; 2 = the paper (Eq. 3),
    # inf = no bias (plain cross-bilateral filter). Ascending, each > 0.
    blurry_edge_px: float = 3.0
    # in the sweep, edges with σ_gt at or above this count as blurry edges, px.
    texture_threshold: float = 0.02
    # local luminance std above which a pixel is "textured" (experiments.metrics.region_masks), image units.


FULL = Fig5Config()
#: Quick: small renders and three bias scales: s = 1, the paper's s = 2 and no bias (the sweep's two
#: steps, each a change; the stage cases, which the claims and the golden read, do not depend on the scales).
QUICK = Fig5Config(preset="small", bias_scales=(1.0, 2.0, math.inf))


def scale_label(s: float) -> str:
    """Metrics key of a bias scale: ``"s=2"``, ``"s=inf"`` (s in px)."""
    return f"s={s:g}"


def _validate_scales(scales) -> tuple[float, ...]:
    out = tuple(float(s) for s in scales)
    if not out or any(not s > 0 for s in out) or any(b <= a for a, b in zip(out, out[1:])):
        raise ValueError(f"bias_scales={scales!r} is invalid; allowed: non-empty, strictly ascending, "
                         f"each > 0 px (inf = no bias)")
    return out


def bias_sweep(before, image, truth, keep, edges, scales, *, params, in_focus_px=1.0, blurry_px=2.0,
               blurry_edge_px=3.0, texture_threshold=0.02) -> tuple[np.ndarray, np.ndarray, dict]:
    """Eq. (3) with the bias b(BM) = exp(−BM/s) for each s, then Eq. (4); metrics per s.

    Parameters
    ----------
    before : ndarray, HxW, float
        Sparse blur measure BM, px, at edge pixels; NaN elsewhere.
    image : ndarray, HxWx3, float in [0, 1]
        The input (guide of both filters).
    truth : ndarray, HxW, float
        σ_gt, px (NaN/inf where undefined).
    keep : ndarray of bool, HxW
        Pixels scored (False on occlusion boundaries).
    edges : ndarray of bool, HxW
        Edge pixels of the detector (for the ``edges`` region of the dense metrics).
    scales : sequence of float
        Bias scales s, px, ascending; ``inf`` = no bias.
    params : DefocusParams, keyword-only
        Every other filter / propagation parameter (paper defaults).
    in_focus_px, blurry_px, blurry_edge_px : float, keyword-only
        σ_gt ≤ ``in_focus_px`` is in focus; an estimate > ``blurry_px`` is blurry (outlier test);
        σ_gt ≥ ``blurry_edge_px`` is a blurry edge. All px.
    texture_threshold : float, keyword-only
        Local-std threshold of the ``textured`` region, image units.

    Returns
    -------
    refined : ndarray, (S, H, W), float64
        Refined sparse σ per scale, px (NaN off edges).
    dense : ndarray, (S, H, W), float64
        Dense σ per scale, px, clipped to [0, ``params.max_sigma``].
    metrics : dict
        ``{scale_label(s): {"refined": {"all_edges"|"in_focus_edges"|"blurry_edges": sparse_metrics},
        "in_focus_outliers": {...}, "dense": {"all"|"textured"|"edges": sparse_metrics}}}``.

    Notes
    -----
    1. Per s: :func:`method.biased_cross_bilateral` (``sharpness_bias=False`` for s = inf).
    2. :func:`method.propagate_defocus` with ``params``' α, windows, solver, downsampling and
       refinement; clip to [0, ``params.max_sigma``] (as :func:`method.estimate_defocus_map`).
    3. Score the refined measures at edges off occlusion boundaries split by σ_gt, and the dense map
       over :func:`~experiments.metrics.region_masks` with ``~keep`` excluded.
    """
    from method import biased_cross_bilateral, propagate_defocus

    from .metrics import dense_metrics, in_focus_outlier_fraction, region_masks, sparse_metrics

    scales = _validate_scales(scales)
    gt = np.asarray(truth, dtype=np.float64)
    regions = region_masks(image, gt, edges=edges, exclude=~keep, texture_threshold=texture_threshold)
    edge_sets = {"all_edges": keep, "in_focus_edges": keep & (gt <= in_focus_px),
                 "blurry_edges": keep & (gt >= blurry_edge_px)}
    refined_all, dense_all, metrics = [], [], {}
    for s in scales:
        finite = math.isfinite(s)
        refined = biased_cross_bilateral(
            before, image, sigma_spatial=params.bilateral_sigma_spatial,
            sigma_range=params.bilateral_sigma_range, sharpness_bias=finite,
            bias_scale=s if finite else params.bias_scale, method=params.bilateral_method)
        dense = propagate_defocus(
            refined, image, alpha=params.alpha, window=params.propagation_window,
            neighborhood=params.propagation_neighborhood, tol=params.propagation_tol,
            solver=params.propagation_solver, downsample=params.propagation_downsample,
            refinement=params.propagation_refinement)
        dense = np.clip(np.asarray(dense, dtype=np.float64), 0.0, params.max_sigma)
        metrics[scale_label(s)] = {
            "refined": {name: sparse_metrics(refined, gt, mask=m) for name, m in edge_sets.items()},
            "in_focus_outliers": in_focus_outlier_fraction(refined, gt, mask=keep, in_focus_px=in_focus_px,
                                                           blurry_px=blurry_px),
            "dense": dense_metrics(dense, gt, regions=regions),
        }
        refined_all.append(refined)
        dense_all.append(dense)
    return np.stack(refined_all), np.stack(dense_all), metrics


#: Per-case sweep curves stored as (n_cases, n_scales) arrays ``sweep_<name>``: name → metrics path.
SWEEP_CURVES = {
    "dense_mae_all": ("dense", "all", "mae"),
    "dense_bias_all": ("dense", "all", "bias"),
    "dense_mae_textured": ("dense", "textured", "mae"),
    "dense_bias_textured": ("dense", "textured", "bias"),
    "refined_mae_in_focus": ("refined", "in_focus_edges", "mae"),
    "refined_bias_in_focus": ("refined", "in_focus_edges", "bias"),
    "refined_mae_blurry": ("refined", "blurry_edges", "mae"),
    "refined_bias_blurry": ("refined", "blurry_edges", "bias"),
    "in_focus_outliers": ("in_focus_outliers", "fraction"),
}


def cases(config: Fig5Config) -> tuple:
    """Per scene set × scene × aperture: a ``stages`` case (render, sparse measure, Eq. 3 with and without
    the bias) and, needing it, one case per bias scale (``variant = scale_label(s)``)."""
    from .cases import Case
    from .scene_sets import set_scene_pairs

    scales = _validate_scales(config.bias_scales)
    out = []
    for set_name, scene in set_scene_pairs(config):
        for n in config.f_numbers:
            stage = Case("fig5", scene_set=set_name, scene=scene, aperture=float(n), variant="stages",
                         scene_size=config.preset)
            out.append(stage)
            out += [Case("fig5", scene_set=set_name, scene=scene, aperture=float(n), variant=scale_label(sc),
                         scene_size=config.preset, needs=(stage,)) for sc in scales]
    return tuple(out)


def compute_case(config: Fig5Config, case, inputs) -> dict:
    """One case of :func:`cases` (see the module Notes).

    Returns
    -------
    dict
        ``stages``: arrays ``image`` HxWx3, ``sigma_gt`` HxW px, ``occlusion`` and ``edges`` HxW bool,
        ``before`` / ``after_bias`` / ``after_no_bias`` HxW px (NaN off edges); metrics per stage
        (sparse metrics + ``in_focus_outliers``) and ``outlier_scene`` (the scene has the paper's
        outliers: ``config.outlier_scenes``). A bias scale s: arrays ``refined`` and ``dense`` HxW px;
        metrics :func:`bias_sweep`'s for s (``refined``, ``in_focus_outliers``, ``dense``).
    """
    from method import DefocusParams, biased_cross_bilateral
    from method.luma import to_light

    from .evaluation import ground_truth_sigma, input_image, sparse_estimates, validate_estimators
    from .metrics import in_focus_outlier_fraction, sparse_metrics

    validate_estimators([config.estimator])
    params = DefocusParams(estimator=config.estimator)
    if case.variant != "stages":
        (stage,) = case.needs
        a = inputs[stage].arrays()
        scale = next(sc for sc in _validate_scales(config.bias_scales) if scale_label(sc) == case.variant)
        refined, dense, m = bias_sweep(
            a["before"], a["image"], a["sigma_gt"], ~a["occlusion"], a["edges"], [scale], params=params,
            in_focus_px=config.in_focus_px, blurry_px=config.blurry_px, blurry_edge_px=config.blurry_edge_px,
            texture_threshold=config.texture_threshold)
        return {"arrays": {"refined": refined[0].astype(np.float32), "dense": dense[0].astype(np.float32)},
                "metrics": m[case.variant]}
    from scenes import render_scene

    render = render_scene(case.scene, preset=config.preset, f_number=case.aperture, progress=False)
    image = input_image(render, encoding=config.encoding, quantize_bits=config.quantize_bits)
    gt = ground_truth_sigma(render, convention=config.convention)
    keep = ~np.asarray(render.occlusion_boundary, dtype=bool)
    edges, sig = sparse_estimates(image, [config.estimator], params=params, encoding=config.encoding)
    image = to_light(image, "display", encoding=config.encoding)  # Eq. (3)'s guide, as the pipeline's
    maps = {"before": sig[config.estimator]}
    for stage, bias in (("after_bias", True), ("after_no_bias", False)):
        maps[stage] = biased_cross_bilateral(
            maps["before"], image, sigma_spatial=params.bilateral_sigma_spatial,
            sigma_range=params.bilateral_sigma_range, sharpness_bias=bias,
            bias_scale=params.bias_scale, method=params.bilateral_method)
    metrics = {"outlier_scene": case.scene in config.outlier_scenes}
    for stage, m in maps.items():
        sm = sparse_metrics(m, gt, mask=keep)
        sm["in_focus_outliers"] = in_focus_outlier_fraction(m, gt, mask=keep, in_focus_px=config.in_focus_px,
                                                            blurry_px=config.blurry_px)
        metrics[stage] = sm
    arrays = {k: v for k, v in maps.items()}  # float64: the scale cases filter this very measure
    arrays.update(image=image, sigma_gt=gt, occlusion=~keep, edges=edges)
    return {"arrays": arrays, "metrics": metrics, "info": {"definitions": _definitions(config)}}


def _definitions(config) -> dict:
    return {
        "mae": "mean |σ_est − σ_gt| at edge pixels off occlusion boundaries, px",
        "in_focus_outlier_fraction": f"fraction of those with σ_gt ≤ {config.in_focus_px} px estimated "
                                     f"> {config.blurry_px} px",
        "bias_sweep": f"per bias scale s (px; inf = no bias) of b(BM) = exp(−BM/s): refined measures at "
                      f"edges off occlusion boundaries (in_focus_edges: σ_gt ≤ {config.in_focus_px} px, "
                      f"blurry_edges: σ_gt ≥ {config.blurry_edge_px} px), in-focus outlier fraction, and the "
                      f"dense map of Eq. (4) (DefocusParams defaults) over all / textured / edges pixels "
                      f"off occlusion boundaries; mae and bias (mean signed error) in px",
    }


FIGURE = Figure(
    name="fig5", plot="experiments.plotting.fig5:plot", configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=4,
    title="Blur measure before/after the biased cross-bilateral filter (Eq. 3), no-bias ablation and bias-scale sweep",
)
