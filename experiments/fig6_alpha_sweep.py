"""Fig. 6: the data weight α of Eq. (4) — dense defocus maps for α ∈ {0.1, 0.2, 0.5, 1}.

The paper shows the propagated map of one photo for four α and remarks that a small α lets the
smoothness term dominate (the map drifts away from the edge measures) while a large α follows the
(noisy) sparse measures closely. Here each map is compared with the rendered ground truth σ_gt.

Beyond the paper, every scene is evaluated for two input encodings: ``"srgb"`` (8-bit sRGB, as a
camera delivers it — the method's documented input) and ``"linear"`` (8-bit linear radiance), and
the bias (mean signed error, px) of every map is reported next to its MAE.

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
6. Method presets (``config.presets``; the first is always ``"paper"`` = ``DefocusParams()``, the
   reproduction, whose metrics are the top-level ones): every further preset of
   :data:`method.PRESETS` (e.g. ``"robust"``, beyond the paper) runs the same sweep — its own
   stages 2–3, then Eq. (4) with ``preset.replace(alpha=a)`` — on the same inputs, scored the same
   way (no ablation), under ``metrics["presets"][name]`` with the paper's structure (``scenes``,
   ``summary``). A preset whose propagation has no α (``"matting_laplacian"``: Zhuo & Sim's λ) is
   propagated once and that map repeated for every α (``alpha_applies`` = false).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .scene_sets import scene_set_figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig6Config", "StageOutputs", "compute", "compute_set", "method_presets", "sweep_alpha"]


def method_presets(names) -> dict:
    """``name → DefocusParams`` for a figure's ``presets`` field, checked (shared by Fig. 6, 7 and 11).

    Parameters
    ----------
    names : sequence of str
        Keys of :data:`method.PRESETS`, unique; the first must be ``"paper"`` (the reproduction,
        whose results keep the figure's top-level metric keys).

    Returns
    -------
    dict
        ``{name: DefocusParams.preset(name)}`` in the given order.

    Raises
    ------
    ValueError
        Empty, not starting with ``"paper"``, duplicated or unknown names.
    """
    from method import PRESETS, DefocusParams

    names = tuple(names)
    allowed = f"unique names of method.PRESETS ({', '.join(PRESETS)}), the first 'paper'"
    if not names or names[0] != "paper" or len(set(names)) != len(names):
        raise ValueError(f"presets={names!r} is invalid; allowed: {allowed}")
    PRESETS.check_all(names, what="preset")
    return {n: DefocusParams.preset(n) for n in names}


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig6Config:
    """Every parameter of Fig. 6."""

    scenes: tuple[str, ...] = ("portrait_garden", "street_figures", "heron_at_the_lake")
    # scene names (scenes.SCENES); the first is plotted, all enter the metrics.
    scene_set: str = "paper_cameras"
    # name of the scenes.SCENE_SETS entry ``scenes`` is drawn from (the flat metrics describe it).
    other_scene_sets: tuple = (("tabletop_stress", (("scenes", ("portrait", "planes", "clutter")),)),)
    # further scene sets computed the same way: (set name, ((config field, value), ...)) overrides;
    # their metrics go to metrics["scene_sets"][name], arrays to "<name>__<key>" (experiments.scene_sets).
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
    # method parameter presets (method.PRESETS) swept; the first is "paper" (the reproduction, top-level
    # metrics), the others go to metrics["presets"][name] (not to be confused with the render `preset`).


FULL = Fig6Config()
QUICK = Fig6Config(scenes=("portrait_garden",), preset="small",
                   other_scene_sets=(("tabletop_stress", (("scenes", ("portrait",)),)),))


@dataclasses.dataclass(frozen=True)
class StageOutputs:
    """The α-independent pipeline stages and the per-α dense maps of one input image."""

    edges: np.ndarray          # bool HxW: edge pixels (Sec. 3.1)
    sparse_sigma: np.ndarray   # float64 HxW: blur at edges, px, NaN elsewhere (Sec. 3.2)
    refined_sigma: np.ndarray  # float64 HxW: after Eq. (3), px, NaN off edges — the BM of Eq. (4)
    maps: np.ndarray           # float64 (n_alpha, H, W): dense σ per α, px, clipped to [0, max_sigma]
    maps_from_sparse: np.ndarray | None  # same, propagated from the raw sparse σ (no Eq. 3); None if not asked
    timings: dict              # seconds: "shared" (edges + blur + Eq. 3) and one entry per α


def sweep_alpha(image, alphas, params=None, *, also_from_sparse=False) -> StageOutputs:
    """Dense defocus maps for several α of Eq. (4), sharing the edge and blur stages.

    Parameters
    ----------
    image : ndarray, HxWx3, float in [0, 1]
        Input photo (the method's reference image and, via luminance, the edge detector's input).
    alphas : sequence of float
        Data weights α > 0 of Eq. (4).
    params : DefocusParams, optional
        Every other pipeline parameter (``params.alpha`` is ignored); default the paper's
        (``DefocusParams()``), or a preset such as ``DefocusParams.preset("robust")``.
    also_from_sparse : bool, keyword-only
        Also propagate the raw sparse measures (skipping Eq. 3) for every α (an ablation).

    Returns
    -------
    StageOutputs

    Notes
    -----
    Runs the stages of :func:`method.estimate_defocus_map` (the same functions of :mod:`method.pipeline`):
    luminance → :func:`~method.pipeline.edges_stage` → :func:`~method.pipeline.blur_stage` (the blur and,
    for presets that weight their measures — ``relaxed_fit_weight`` — the per-measure confidence used by
    both later stages; the edge-isolation weights and the region cue of Eq. (4) when ``params`` use
    them) → the refinement (:func:`method.pipeline.refine_stage`; Eq. 3 as ``params``
    configure it) once, then the propagation (:func:`method.pipeline.propagate_stage` with
    ``params.replace(alpha=a)``, clipped to [0, ``params.max_sigma``]) per α. When
    ``params.propagation`` has no α (anything but ``"colorization"``, Eq. 4), it runs once and the
    map is repeated for every α (``timings`` then has one ``"propagation"`` entry).
    """
    from method import DefocusParams, luminance
    from method.luma import measure_luminance
    from method.pipeline import (blur_stage, edge_psf_family, edges_stage, isolation_stage, propagate_stage,
                                 refine_stage, region_stage, straddle_edges)

    params = DefocusParams() if params is None else params
    alphas = [float(a) for a in alphas]
    if not alphas or any(not (a > 0) for a in alphas):
        raise ValueError(f"alphas={alphas!r} is invalid; allowed: non-empty sequence of values > 0")
    rgb = np.asarray(image, dtype=np.float64)
    gray = luminance(rgb)
    seen = measure_luminance(rgb, params.measure_light)  # what the edge and blur stages read
    timings = {}
    t0 = time.perf_counter()
    sparse, confidence, edge_map, psf_disk = blur_stage(seen, edges_stage(seen, params=params), params=params)
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


def evaluate_input(image, render, alphas, *, texture_threshold, rtf_clip_px, also_from_sparse=False, params=None):
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

    Returns
    -------
    (StageOutputs, dict)
        The maps and ``{f"alpha={a:g}": metrics}`` (ablation: ``{"from_sparse": {...}}``) plus
        ``"regions"`` (pixel counts), the errors of the sparse/refined measures at edges, ``"timings"``,
        ``"energy_terms"`` and ``"map_change_px"`` (see :func:`_alpha_tradeoff`).
    """
    from .metrics import dense_metrics, region_masks

    stages = sweep_alpha(image, alphas, params, also_from_sparse=also_from_sparse)
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
    out.update(_alpha_tradeoff(image, stages, alphas, regions, params))
    if also_from_sparse:
        # ablation: the data term sees the raw sparse measures, so fidelity is measured against them
        args = (gt, regions, stages.sparse_sigma, stages.sparse_sigma, stages.edges, rtf_clip_px)
        out["from_sparse"] = {f"alpha={float(a):g}": _score_map(m, *args)
                              for a, m in zip(alphas, stages.maps_from_sparse)}
    return stages, out


def compute_set(config: Fig6Config) -> dict:
    """α sweep of Eq. (4) on rendered scenes, both encodings, with errors against σ_gt.

    Parameters
    ----------
    config : Fig6Config

    Returns
    -------
    dict
        ``alphas`` (k,); for the plotted (first) scene: ``image`` (H, W, 3) — the ``plot_encoding``
        input, ``sigma_gt`` (H, W) px, ``occlusion`` (H, W) bool, ``edges`` (H, W) bool, ``maps``
        (k, H, W) px; ``maps_<scene>_<encoding>`` (k, H, W) px for every scene and encoding;
        ``metrics``: ``scenes.<scene>.<encoding>.alpha=<a>.{all,textured,edges}_{mae,bias,rmse}``,
        ``rtf_nmse``, ``rtf_nmae``, ``edge_rms_to_bm``, … (see the module Notes), plus
        ``summary.<encoding>.alpha=<a>`` means over scenes, and timings — all for the ``"paper"``
        preset. Every further preset P of ``config.presets``: ``preset_<P>__maps`` (k, H, W) px and
        ``preset_<P>__refined`` (H, W) px (its Eq. 3 output, NaN off edges) for the plotted scene and
        encoding, ``preset_<P>__maps_<scene>_<encoding>`` (k, H, W) px, and
        ``metrics.presets.<P>`` = {``scenes``, ``summary`` (same keys as the paper's, no
        ``from_sparse``), ``alpha_applies``, ``compute_seconds``}.
    """
    from scenes import render_scene

    if config.plot_encoding not in config.encodings:
        raise ValueError(f"plot_encoding={config.plot_encoding!r} is invalid; allowed: one of {config.encodings}")
    others = dict(list(method_presets(config.presets).items())[1:])  # "paper" is the top level
    t_start = time.perf_counter()
    data = {"alphas": np.asarray(config.alphas, dtype=np.float64)}
    per_scene = {}
    extra = {p: {"scenes": {}, "summary": {}, "alpha_applies": alpha_applies(params), "compute_seconds": 0.0}
             for p, params in others.items()}
    for si, name in enumerate(config.scenes):
        render = render_scene(name, preset=config.preset, f_number=config.f_number, seed=config.render_seed,
                              progress=False)
        per_scene[name] = {"sigma_gt_range_px": [float(np.nanmin(render.sigma_px)),
                                                 float(np.nanmax(render.sigma_px))]}
        for enc in config.encodings:
            image = render.image(encoding=enc, quantize_bits=config.quantize_bits)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                stages, metrics = evaluate_input(image, render, config.alphas,
                                                 texture_threshold=config.texture_threshold,
                                                 rtf_clip_px=config.rtf_clip_px,
                                                 also_from_sparse=config.ablation_from_sparse)
            per_scene[name][enc] = metrics
            data[f"maps_{name}_{enc}"] = stages.maps.astype(np.float32)
            if config.ablation_from_sparse:
                data[f"maps_from_sparse_{name}_{enc}"] = stages.maps_from_sparse.astype(np.float32)
            if si == 0 and enc == config.plot_encoding:
                data.update(image=image.astype(np.float32), sigma_gt=render.sigma_px.astype(np.float32),
                            occlusion=render.occlusion_boundary.astype(bool), edges=stages.edges,
                            maps=stages.maps.astype(np.float32))
            for pname, params in others.items():
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    st, mm = evaluate_input(image, render, config.alphas, texture_threshold=config.texture_threshold,
                                            rtf_clip_px=config.rtf_clip_px, params=params)
                extra[pname]["scenes"].setdefault(name, {"sigma_gt_range_px": per_scene[name]["sigma_gt_range_px"]})
                extra[pname]["scenes"][name][enc] = mm
                data[f"preset_{pname}__maps_{name}_{enc}"] = st.maps.astype(np.float32)
                if si == 0 and enc == config.plot_encoding:
                    data[f"preset_{pname}__maps"] = st.maps.astype(np.float32)
                    data[f"preset_{pname}__refined"] = st.refined_sigma.astype(np.float32)
                extra[pname]["compute_seconds"] += time.perf_counter() - t0
    summary = _summary(per_scene, config, from_sparse=config.ablation_from_sparse)
    for pname in others:
        extra[pname]["summary"] = _summary(extra[pname]["scenes"], config, from_sparse=False)
    data["metrics"] = {
        "scenes": per_scene,
        "summary": summary,
        "presets": extra,
        "regions_note": "occlusion-boundary pixels (within a CoC radius + 1 px of a depth discontinuity) "
                        "are excluded from every region; 'all' = finite sigma_gt, 'textured' = local std > "
                        f"{config.texture_threshold}, 'edges' = the method's edge pixels",
        "compute_seconds": time.perf_counter() - t_start,
    }
    return data


def _summary(per_scene, config, *, from_sparse):
    """``{encoding: {"alpha=<a>": mean over scenes of each metric}}`` (and the ablation's, if asked)."""
    summary = {}
    for enc in config.encodings:
        summary[enc] = {}
        for a in config.alphas:
            key = f"alpha={float(a):g}"
            rows = [per_scene[s][enc][key] for s in config.scenes]
            summary[enc][key] = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
            if from_sparse:
                rows = [per_scene[s][enc]["from_sparse"][key] for s in config.scenes]
                summary[enc].setdefault("from_sparse", {})[key] = {
                    k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
    return summary


FIGURE = scene_set_figure(
    compute_set, name="fig6", quick=QUICK, full=FULL, version=3,
    title="Eq. (4) data weight alpha in {0.1, 0.2, 0.5, 1}: dense maps vs ground truth (sRGB and linear input)",
)
#: :func:`compute_set` on the default scene set and on each of ``config.other_scene_sets``
#: (:func:`experiments.scene_sets.compute_scene_sets`).
compute = FIGURE.compute
