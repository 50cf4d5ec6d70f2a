"""Fig. 6: the data weight α of Eq. (4) — dense defocus maps for α ∈ {0.1, 0.2, 0.5, 1}.

The paper shows the propagated map of one photo for four α and remarks that a small α lets the
smoothness term dominate (the map drifts away from the edge measures) while a large α follows the
(noisy) sparse measures closely. Here each map is compared with the rendered ground truth σ_gt.

Beyond the paper, every scene is evaluated for two input encodings: ``"srgb"`` (8-bit sRGB, as a
camera delivers it — the method's documented input) and ``"linear"`` (8-bit linear radiance), each
declared to the method (``encoding=``, so both are measured in the preset's light and differ by where
the 8-bit quantisation falls), and the bias (mean signed error, px) of every map is reported next to
its MAE.

Notes
-----
1. Render each scene (``render_scene``, cached); the input is ``render.image(encoding=e,
   quantize_bits=config.quantize_bits)`` for each encoding e.
2. Run the α-independent stages once per input (:func:`sweep_alpha`): Elder–Zucker edges (Sec. 3.1),
   blur at edges (Sec. 3.2), biased cross-bilateral refinement (Eq. 3). Then solve Eq. (4) once per
   α and clip to [0, max_sigma] exactly as :func:`method.estimate_defocus_map` does (a test checks
   the α = 0.5 map against the pipeline's).
3. Regions (:func:`experiments.metrics.region_masks`): ``all`` = every pixel with a finite σ_gt,
   ``textured`` = local luminance std > ``texture_threshold``, ``edges`` = the method's edge
   pixels. **Occlusion-boundary pixels (``render.occlusion_boundary``: within a CoC radius + 1 px
   of a depth discontinuity, where σ_gt is ill-defined because two blurs mix) are excluded from
   every region.**
4. Metrics per scene, encoding and α: MAE / bias / RMSE per region (px); RTF-style normalised
   MSE/MAE (σ clipped at 3.275 px, divided by it) over ``all``; and the data fidelity of Eq. (4) at
   edge pixels — RMS and mean |B − BM| with BM the refined measures the data term sees (and the raw
   sparse measures). The RMS deviation from BM is non-increasing in α for the exact minimiser of
   Eq. (4) (a quadratic penalty's classic monotonicity); it is what "larger α keeps the map closer
   to the sparse measures" means quantitatively.
5. Ablation (``ablation_from_sparse``): the same sweep propagating the raw sparse measures instead
   of the Eq. (3) output. The biased cross-bilateral filter (σs = 10 % of the image size) already
   makes BM smooth, so with refinement the α values give nearly the same map; without it α decides
   how much of the sparse outliers leak into the map.
6. Cases (:func:`cases`): one per scene set × scene × method preset of ``config.presets`` × encoding;
   a preset's sweep runs its own stages 2–3, then Eq. (4) with ``preset.replace(alpha=a)``, scored the
   same way (the ablation of step 5 for the ``paper`` preset only). A preset whose propagation has no α
   (``"matting_laplacian"``: Zhuo & Sim's λ) is propagated once and that map repeated for every α
   (``alpha_applies`` = false).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig6Config", "StageOutputs", "alpha_summary", "cases", "compute_case",
           "evaluate_input", "sweep_alpha"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig6Config:
    """Every parameter of Fig. 6."""

    scene_sets: tuple = (("paper_cameras", ("portrait_garden", "street_figures", "heron_at_the_lake")),
                         ("tabletop_stress", ("portrait", "planes", "clutter")),
                         ("procedural_test", ("procedural_100000", "procedural_100001", "procedural_100002",
                                              "procedural_100003")))
    # (scene set, scenes) pairs (experiments.scene_sets), the first the default; in each set the first
    # scene is plotted, all enter the metrics.
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_number: float = 4.0
    # N of the render, dimensionless (f/4 spans σ_gt ≈ 0.29–3.5 px at the small preset).
    alphas: tuple[float, ...] = (0.1, 0.2, 0.5, 1.0)
    # α_p of Eq. (4) at edge pixels, dimensionless (paper's Fig. 6 values).
    encodings: tuple[str, ...] = ("srgb", "linear")
    # input encodings evaluated ("srgb": as a camera delivers; "linear": linear radiance).
    plot_encoding: str = "srgb"
    # encoding whose maps are drawn.
    quantize_bits: int = 8
    # bits per channel of the input image (8 = JPEG-like).
    texture_threshold: float = 0.02
    # local luminance std above which a pixel is "textured", image units ([0, 1]).
    rtf_clip_px: float = 3.275
    # σ clip of the RTF-style normalised errors, px.
    ablation_from_sparse: bool = True
    # also sweep α propagating the raw sparse measures (no Eq. 3 refinement), to show where α matters.
    render_seed: int = 0
    # Mitsuba sampler seed.
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS) swept, one case each (not to be confused with the render
    # `preset`); the α ablation without Eq. (3) runs for "paper" only.


FULL = Fig6Config()
#: Quick: small renders, one scene per hand-built set, and three of the paper's four α (the smallest, the
#: method's default and the largest: the trade-off of Eq. (4) and the map change α_min → α_max as in FULL;
#: each α's map is its own solve of Eq. (4), so dropping an α moves no other α's numbers).
QUICK = Fig6Config(scene_sets=(("paper_cameras", ("portrait_garden",)), ("tabletop_stress", ("portrait",)),
                               ("procedural_test", ("procedural_100000", "procedural_100001"))), preset="small",
                   alphas=(0.1, 0.5, 1.0))


@dataclasses.dataclass(frozen=True)
class StageOutputs:
    """The α-independent pipeline stages and the per-α dense maps of one input image."""

    edges: np.ndarray          # bool HxW: edge pixels (Sec. 3.1)
    sparse_sigma: np.ndarray   # float64 HxW: blur at edges, px, NaN elsewhere (Sec. 3.2)
    refined_sigma: np.ndarray  # float64 HxW: after Eq. (3), px, NaN off edges — the BM of Eq. (4)
    maps: np.ndarray           # float64 (n_alpha, H, W): dense σ per α, px, clipped to [0, max_sigma]
    maps_from_sparse: np.ndarray | None  # same, propagated from the raw sparse σ (no Eq. 3); None if not asked
    timings: dict              # seconds: "shared" (edges + blur + Eq. 3) and one entry per α


def sweep_alpha(image, alphas, params=None, *, also_from_sparse=False, encoding="srgb") -> StageOutputs:
    """Dense defocus maps for several α of Eq. (4), sharing the edge and blur stages.

    Parameters
    ----------
    image : ndarray, HxWx3, float in [0, 1]
        Input photo, its values in ``encoding`` (the method's reference image and, via luminance,
        the edge detector's input).
    alphas : sequence of float
        Data weights α > 0 of Eq. (4).
    params : DefocusParams, optional
        Every other pipeline parameter (``params.alpha`` is ignored); default the paper's
        (``DefocusParams()``), or a preset such as ``DefocusParams.preset("robust")``.
    also_from_sparse : bool, keyword-only
        Also propagate the raw sparse measures (skipping Eq. 3) for every α (an ablation).
    encoding : str, keyword-only
        What the image's values are, key of :data:`method.luma.ENCODINGS` ("srgb" or "linear").

    Returns
    -------
    StageOutputs

    Notes
    -----
    Runs the stages of :func:`method.estimate_defocus_map` (the same functions of :mod:`method.pipeline`):
    :func:`method.luma.measure_input` (the input in each stage's light) → :func:`~method.pipeline.edges_stage` → :func:`~method.pipeline.blur_stage` (the blur and,
    for presets that weight their measures — ``relaxed_fit_weight`` — the per-measure confidence used by
    both later stages; the edge-isolation weights and the region cue of Eq. (4) when ``params`` use
    them) → the refinement (:func:`method.pipeline.refine_stage`; Eq. 3 as ``params``
    configure it) once, then the propagation (:func:`method.pipeline.propagate_stage` with
    ``params.replace(alpha=a)``, clipped to [0, ``params.max_sigma``]) per α. When
    ``params.propagation`` has no α (anything but ``"colorization"``, Eq. 4), it runs once and the
    map is repeated for every α (``timings`` then has one ``"propagation"`` entry).
    """
    from method import DefocusParams
    from method.luma import measure_input
    from method.pipeline import (blur_stage, edge_psf_family, edges_stage, isolation_stage, propagate_stage,
                                 refine_stage, region_stage, straddle_edges)

    params = DefocusParams() if params is None else params
    alphas = [float(a) for a in alphas]
    if not alphas or any(not (a > 0) for a in alphas):
        raise ValueError(f"alphas={alphas!r} is invalid; allowed: non-empty sequence of values > 0")
    measured = measure_input(image, params, encoding=encoding)  # what each stage reads, as the pipeline
    rgb, gray, seen = measured.rgb, measured.gray, measured.seen
    timings = {}
    t0 = time.perf_counter()
    sparse, confidence, edge_map, psf_disk = blur_stage(seen, edges_stage(seen, params=params, encoding=encoding),
                                                      params=params)
    if not np.any(np.isfinite(sparse)):
        raise ValueError("no edge pixel found in the image; the α sweep needs edge measures")
    if params.edge_isolation is not None:
        confidence = isolation_stage(seen, edge_map, sparse, params=params, confidence=confidence)
    region = {}
    if params.region_estimator is not None:  # the second cue of Eq. (4), as estimate_defocus_map fuses it
        region_sigma, region_information = region_stage(gray, params=params,
                                                        edge_psf=edge_psf_family(sparse, psf_disk))
        has_region = bool(np.any(np.isfinite(region_sigma)))
        region = dict(region_sigma=region_sigma, region_information=region_information, gray=gray,
                      isolated_edges=straddle_edges(seen, edge_map, sparse, params=params) if has_region else None)
    refined = refine_stage(sparse, rgb, params=params, confidence=confidence)
    timings["shared"] = time.perf_counter() - t0

    def propagate(bm, a):
        dense = propagate_stage(bm, rgb, params=params.replace(alpha=a), sparse_sigma=sparse,
                                confidence=confidence, **region)
        return np.asarray(dense, dtype=np.float64)

    maps, from_sparse = [], []
    if not alpha_applies(params):
        t0 = time.perf_counter()
        dense = propagate(refined, alphas[0])
        timings["propagation"] = time.perf_counter() - t0
        maps = [dense] * len(alphas)
        if also_from_sparse:
            from_sparse = [propagate(sparse, alphas[0])] * len(alphas)
    for a in alphas if alpha_applies(params) else ():
        t0 = time.perf_counter()
        maps.append(propagate(refined, a))
        timings[f"alpha={a:g}"] = time.perf_counter() - t0
        if also_from_sparse:
            from_sparse.append(propagate(sparse, a))
    return StageOutputs(edges=edge_map.edges.copy(), sparse_sigma=sparse, refined_sigma=refined,
                        maps=np.stack(maps), maps_from_sparse=np.stack(from_sparse) if also_from_sparse else None,
                        timings=timings)


def alpha_applies(params) -> bool:
    """Whether ``params.propagation`` uses the data weight α (only Eq. 4's ``"colorization"`` does)."""
    return params.propagation == "colorization"


def _fidelity(dense, measures, edges):
    """RMS and mean |dense − measures| at edge pixels with a finite measure, px."""
    ok = edges & np.isfinite(measures)
    d = dense[ok] - measures[ok]
    return {"rms": float(np.sqrt(np.mean(d**2))), "mae": float(np.mean(np.abs(d))), "n": int(ok.sum())}


def _score_map(m, gt, regions, bm, sparse, edges, rtf_clip_px):
    from .metrics import dense_metrics, rtf_normalized_errors

    dm = dense_metrics(m, gt, regions=regions)
    return {
        **{f"{region}_{k}": dm[region][k] for region in dm for k in ("mae", "bias", "rmse")},
        **{f"rtf_{k}": v for k, v in rtf_normalized_errors(m, gt, mask=regions["all"],
                                                            clip_px=rtf_clip_px).items() if k != "n"},
        "edge_rms_to_bm": _fidelity(m, bm, edges)["rms"],
        "edge_mae_to_bm": _fidelity(m, bm, edges)["mae"],
        "edge_mae_to_sparse": _fidelity(m, sparse, edges)["mae"],
    }


def _alpha_tradeoff(image, stages, alphas, regions, params):
    """What α changes: Eq. (4)'s two terms per α and the map change between the smallest and largest α.

    Returns ``{"energy_terms": {"alpha=<a>": {"data_term", "smoothness_term"}}, "map_change_px": {...}}``:
    data term = mean over edge pixels with a measure of (B − BM)², px²; smoothness term = mean over
    all pixels of (B_p − Σ_q w_pq B_q)² (Eq. 4a with the Eq. 4c affinities of ``params``), px²;
    ``map_change_px`` = mean / 95th percentile of |B(α_max) − B(α_min)| over the textured and all
    pixels. ``energy_terms`` is omitted when ``params.propagation`` has no α (not Eq. 4).
    """
    from method import DefocusParams
    from method.propagation.defocus import colorization_matrix

    params = DefocusParams() if params is None else params
    lo, hi = int(np.argmin(alphas)), int(np.argmax(alphas))
    diff = np.abs(stages.maps[hi] - stages.maps[lo])
    change = {}
    for region in ("textured", "all"):
        d = diff[regions[region]]
        change[f"{region}_mean"] = float(np.mean(d)) if d.size else float("nan")
        change[f"{region}_p95"] = float(np.percentile(d, 95)) if d.size else float("nan")
    change["alphas"] = [float(alphas[lo]), float(alphas[hi])]
    out = {"map_change_px": change}
    if alpha_applies(params):
        L = colorization_matrix(np.asarray(image, dtype=np.float64), window=params.propagation_window,
                                neighborhood=params.propagation_neighborhood)
        ok = stages.edges & np.isfinite(stages.refined_sigma)
        out["energy_terms"] = {
            f"alpha={float(a):g}": {"data_term": float(np.mean((m[ok] - stages.refined_sigma[ok]) ** 2)),
                                    "smoothness_term": float(np.mean((L @ m.ravel()) ** 2))}
            for a, m in zip(alphas, stages.maps)}
    return out


def evaluate_input(image, render, alphas, *, texture_threshold, rtf_clip_px, also_from_sparse=False, params=None,
                   encoding="srgb"):
    """Sweep α on one input and score every map against the render's ground truth.

    Parameters
    ----------
    image : ndarray, HxWx3, float in [0, 1]
    render : scenes.Render
        Supplies ``sigma_px`` (σ_gt, px) and ``occlusion_boundary`` (excluded from every region).
    alphas : sequence of float
    texture_threshold, rtf_clip_px : float, keyword-only
        See :class:`Fig6Config`.
    also_from_sparse : bool, keyword-only
        Also score the ablation that propagates the raw sparse measures (no Eq. 3).
    params : DefocusParams, optional, keyword-only
        Pipeline parameters (default: the paper's); see :func:`sweep_alpha`.
    encoding : str, keyword-only
        What the image's values are (:func:`sweep_alpha`).

    Returns
    -------
    (StageOutputs, dict)
        The maps and ``{f"alpha={a:g}": metrics}`` (ablation: ``{"from_sparse": {...}}``) plus
        ``"regions"`` (pixel counts), the errors of the sparse/refined measures at edges, ``"timings"``,
        ``"energy_terms"`` and ``"map_change_px"`` (see :func:`_alpha_tradeoff`).
    """
    from method.luma import to_light

    from .metrics import dense_metrics, region_masks

    stages = sweep_alpha(image, alphas, params, also_from_sparse=also_from_sparse, encoding=encoding)
    gt = np.asarray(render.sigma_px, dtype=np.float64)
    regions = region_masks(image, gt, edges=stages.edges, exclude=render.occlusion_boundary,
                           texture_threshold=texture_threshold)
    out = {"regions": {k: int(v.sum()) for k, v in regions.items()},
           "occlusion_pixels_excluded": int(np.sum(render.occlusion_boundary & np.isfinite(gt))),
           "sparse_at_edges": dense_metrics(stages.sparse_sigma, gt, regions={"edges": regions["edges"]})["edges"],
           "refined_at_edges": dense_metrics(stages.refined_sigma, gt, regions={"edges": regions["edges"]})["edges"],
           "timings": stages.timings}
    args = (gt, regions, stages.refined_sigma, stages.sparse_sigma, stages.edges, rtf_clip_px)
    for a, m in zip(alphas, stages.maps):
        out[f"alpha={float(a):g}"] = _score_map(m, *args)
    guide = to_light(image, "display", encoding=encoding)  # the propagation's affinities read display values
    out.update(_alpha_tradeoff(guide, stages, alphas, regions, params))
    if also_from_sparse:
        # ablation: the data term sees the raw sparse measures, so fidelity is measured against them
        args = (gt, regions, stages.sparse_sigma, stages.sparse_sigma, stages.edges, rtf_clip_px)
        out["from_sparse"] = {f"alpha={float(a):g}": _score_map(m, *args)
                              for a, m in zip(alphas, stages.maps_from_sparse)}
    return stages, out


def cases(config: Fig6Config) -> tuple:
    """One case per scene set × scene × preset × encoding (aperture ``config.f_number``)."""
    from .cases import Case, method_presets
    from .scene_sets import set_scene_pairs

    if config.plot_encoding not in config.encodings:
        raise ValueError(f"plot_encoding={config.plot_encoding!r} is invalid; allowed: one of {config.encodings}")
    presets = method_presets(config.presets)
    return tuple(Case("fig6", scene_set=s, scene=n, preset=p, aperture=float(config.f_number), encoding=enc,
                      scene_size=config.preset)
                 for s, n in set_scene_pairs(config) for p in presets for enc in config.encodings)


def compute_case(config: Fig6Config, case, inputs) -> dict:
    """α sweep of Eq. (4) of one preset on one input, scored against σ_gt (see the module Notes).

    Returns
    -------
    dict
        Arrays ``maps`` (k, H, W) px, ``refined`` (H, W) px (Eq. 3 output, NaN off edges), the input
        ``image`` (H, W, 3), ``sigma_gt`` (H, W) px, ``occlusion`` and ``edges`` (H, W) bool, and for the
        paper preset with ``ablation_from_sparse`` ``maps_from_sparse`` (k, H, W) px; metrics of
        :func:`evaluate_input` (``alpha=<a>/…``, ``energy_terms``, ``map_change_px``, ``regions``, the
        edge errors, ``from_sparse``), ``sigma_gt_range_px`` and ``alpha_applies``.
    """
    from method import DefocusParams
    from scenes import render_scene

    params = DefocusParams.preset(case.preset)
    ablation = config.ablation_from_sparse and case.preset == "paper"
    render = render_scene(case.scene, preset=config.preset, f_number=config.f_number, seed=config.render_seed,
                          progress=False)
    image = render.image(encoding=case.encoding, quantize_bits=config.quantize_bits)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        stages, metrics = evaluate_input(image, render, config.alphas, texture_threshold=config.texture_threshold,
                                         rtf_clip_px=config.rtf_clip_px, also_from_sparse=ablation, params=params,
                                         encoding=case.encoding)
    timings = metrics.pop("timings")
    metrics["sigma_gt_range_px"] = {"min": float(np.nanmin(render.sigma_px)), "max": float(np.nanmax(render.sigma_px))}
    metrics["alpha_applies"] = alpha_applies(params)
    arrays = {"maps": stages.maps.astype(np.float32), "refined": stages.refined_sigma.astype(np.float32),
              "image": image.astype(np.float32), "sigma_gt": render.sigma_px.astype(np.float32),
              "occlusion": render.occlusion_boundary.astype(bool), "edges": stages.edges}
    if ablation:
        arrays["maps_from_sparse"] = stages.maps_from_sparse.astype(np.float32)
    return {"arrays": arrays, "metrics": metrics,
            "info": {"timings": timings,
                     "regions_note": "occlusion-boundary pixels (within a CoC radius + 1 px of a depth discontinuity) "
                                     "are excluded from every region; 'all' = finite sigma_gt, 'textured' = local std "
                                     f"> {config.texture_threshold}, 'edges' = the method's edge pixels"}}


def alpha_summary(per_scene: dict, encodings, alphas, *, from_sparse: bool) -> dict:
    """``{encoding: {"alpha=<a>": mean over scenes of each metric}}`` (and the ablation's, if asked).

    Parameters
    ----------
    per_scene : dict
        ``{scene: {encoding: case metrics (nested)}}``.
    """
    summary = {}
    for enc in encodings:
        summary[enc] = {}
        for a in alphas:
            key = f"alpha={float(a):g}"
            rows = [per_scene[s][enc][key] for s in per_scene]
            summary[enc][key] = {k: float(np.mean([np.nan if r[k] is None else r[k] for r in rows])) for k in rows[0]}
            if from_sparse:
                rows = [per_scene[s][enc]["from_sparse"][key] for s in per_scene]
                summary[enc].setdefault("from_sparse", {})[key] = {
                    k: float(np.mean([np.nan if r[k] is None else r[k] for r in rows])) for k in rows[0]}
    return summary


FIGURE = Figure(
    name="fig6", plot="experiments.plotting.fig6:plot", configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=4,
    title="Eq. (4) data weight alpha in {0.1, 0.2, 0.5, 1}: dense maps vs ground truth (sRGB and linear input)",
)
