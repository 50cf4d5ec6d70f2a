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
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from .scene_sets import scene_set_figure

__all__ = ["FIGURE", "FULL", "QUICK", "SWEEP_CURVES", "Fig5Config", "bias_sweep", "compute", "compute_set", "scale_label"]

#: Stages compared, in plot order.
STAGES = ("before", "after_bias", "after_no_bias")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig5Config:
    """Every parameter of Fig. 5."""

    scenes: tuple[str, ...] = ("patio_table", "portrait_garden")
    # keys of scenes.SCENES: the outlier scene (soft shadow + glossy highlight) and a control.
    outlier_scenes: tuple[str, ...] = ("patio_table",)
    # which of ``scenes`` have the paper's outliers (written to metrics["outlier_scenes"] for the claims).
    scene_set: str = "paper_cameras"
    # name of the scenes.SCENE_SETS entry ``scenes`` is drawn from (the flat metrics describe it).
    other_scene_sets: tuple = (("tabletop_stress", (("scenes", ("shadow_gloss", "planes")),
                                                    ("outlier_scenes", ("shadow_gloss",)))),)
    # further scene sets computed the same way: (set name, ((config field, value), ...)) overrides;
    # their metrics go to metrics["scene_sets"][name], arrays to "<name>__<key>" (experiments.scene_sets).
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
QUICK = Fig5Config(preset="small")


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


def compute_set(config: Fig5Config) -> dict:
    """Sparse maps before/after Eq. (3) with and without the bias, and their metrics (one scene set).

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
        Bias-scale sweep (:func:`bias_sweep`): ``bias_scales`` (S,) px (inf = no bias);
        ``<c>_sweep_refined`` (S, H, W) px (NaN off edges), ``<c>_sweep_dense`` (S, H, W) px;
        ``sweep_<name>`` (n_cases, S) for each name of :data:`SWEEP_CURVES` (px, or a fraction for
        ``in_focus_outliers``; NaN where the pixel set is empty); ``metrics["bias_sweep"][case][label]``
        the full metrics (``label`` = :func:`scale_label`).
    """
    from method import DefocusParams, biased_cross_bilateral
    from scenes import render_scene

    from .evaluation import ground_truth_sigma, input_image, sparse_estimates, validate_estimators
    from .metrics import in_focus_outlier_fraction, sparse_metrics

    validate_estimators([config.estimator])
    scales = _validate_scales(config.bias_scales)
    params = DefocusParams(estimator=config.estimator)
    out: dict = {}
    metrics: dict = {}
    sweep: dict = {}
    cases = []
    t_sweep = 0.0
    t0 = time.perf_counter()
    for scene in config.scenes:
        for n in config.f_numbers:
            case = f"{scene}_f{n:g}"
            cases.append(case)
            render = render_scene(scene, preset=config.preset, f_number=n, progress=False)
            image = input_image(render, encoding=config.encoding, quantize_bits=config.quantize_bits)
            gt = ground_truth_sigma(render, convention=config.convention)
            keep = ~np.asarray(render.occlusion_boundary, dtype=bool)
            edges, sig = sparse_estimates(image, [config.estimator], params=params)
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
            ts = time.perf_counter()
            refined, dense, sweep[case] = bias_sweep(
                before, image, gt, keep, edges, scales, params=params, in_focus_px=config.in_focus_px,
                blurry_px=config.blurry_px, blurry_edge_px=config.blurry_edge_px,
                texture_threshold=config.texture_threshold)
            t_sweep += time.perf_counter() - ts
            out[f"{case}_sweep_refined"] = refined.astype(np.float32)
            out[f"{case}_sweep_dense"] = dense.astype(np.float32)
            out[f"{case}_image"] = image.astype(np.float32)
            out[f"{case}_sigma_gt"] = gt.astype(np.float32)
            out[f"{case}_occlusion"] = ~keep
    metrics["summary"] = {
        case: {f"{stage}.{k}": (metrics[case][stage]["mae"] if k == "mae"
                                else metrics[case][stage]["in_focus_outliers"]["fraction"])
               for stage in STAGES for k in ("mae", "in_focus_outlier_fraction")}
        for case in cases
    }
    for name, path in SWEEP_CURVES.items():
        rows = []
        for case in cases:
            row = []
            for sc in scales:
                v = sweep[case][scale_label(sc)]
                for k in path:
                    v = v[k]
                row.append(v)
            rows.append(row)
        out[f"sweep_{name}"] = np.asarray(rows, dtype=np.float64)
    out["bias_scales"] = np.asarray(scales, dtype=np.float64)
    metrics["bias_sweep"] = sweep
    metrics["outlier_scenes"] = [s for s in config.outlier_scenes if s in config.scenes]
    metrics["timings"] = {"total_s": time.perf_counter() - t0, "bias_sweep_s": t_sweep}
    metrics["definitions"] = {
        "mae": "mean |σ_est − σ_gt| at edge pixels off occlusion boundaries, px",
        "in_focus_outlier_fraction": f"fraction of those with σ_gt ≤ {config.in_focus_px} px estimated "
                                     f"> {config.blurry_px} px",
        "bias_sweep": f"per bias scale s (px; inf = no bias) of b(BM) = exp(−BM/s): refined measures at "
                      f"edges off occlusion boundaries (in_focus_edges: σ_gt ≤ {config.in_focus_px} px, "
                      f"blurry_edges: σ_gt ≥ {config.blurry_edge_px} px), in-focus outlier fraction, and the "
                      f"dense map of Eq. (4) (DefocusParams defaults) over all / textured / edges pixels "
                      f"off occlusion boundaries; mae and bias (mean signed error) in px",
    }
    return {"cases": np.asarray(cases), **out, "metrics": metrics}


FIGURE = scene_set_figure(
    compute_set, name="fig5", quick=QUICK, full=FULL, version=3,
    title="Blur measure before/after the biased cross-bilateral filter (Eq. 3), no-bias ablation and bias-scale sweep",
)
#: :func:`compute_set` on the default scene set and on each of ``config.other_scene_sets``
#: (:func:`experiments.scene_sets.compute_scene_sets`).
compute = FIGURE.compute
