"""Fig. 4: blur estimation at edges — zero crossing (Elder–Zucker) vs model fit (the paper's, Sec. 3.2).

Every estimator registered in :data:`method.BLUR_ESTIMATORS` that the config names is compared
(default: ``model_fit``, ``zero_crossing``, ``gradient_ratio``) on

* **rendered scenes** — Mitsuba renders (:func:`scenes.render_scene`), σ_gt from the render's CoC,
  at detected edge pixels, occlusion boundaries excluded; for both input encodings
  (``"srgb"`` as a camera stores it, ``"linear"`` radiance) and both CoC → σ conventions
  (``"line_spread"`` c/4, ``"erf_fit"`` 0.273·c; each ⊕ the box filter's 1/√12 px).
  The method's model is a *Gaussian*-blurred step in the light the preset measures in (display
  values for the paper, linear light for robust); the renderer blurs with a *disk* in *linear light*
  and the camera stores sRGB: the mean signed error per case measures the bias each mismatch causes.
  Each input's encoding is declared to the method (:func:`method.estimate_defocus_map` ``encoding``),
  so both encodings are measured in the same light and differ by where the 8-bit quantisation falls;
* **analytic images** (:mod:`scenes.analytic`, exact Gaussian σ): straight and curved steps for
  σ ∈ ``analytic_sigmas``, and the neighbouring-edge case — a bright bar (opposite-polarity edges)
  and a staircase (same polarity) with spacing D = k·σ — where the paper claims the model fit beats
  the zero crossings. Each both noise-free and camera-like (noise + 8-bit).

Notes
-----
1. For each scene × f-number × encoding: render (cached), input image (8-bit), edge map once,
   σ at edges by each estimator (:func:`experiments.evaluation.sparse_estimates`).
2. For each σ_gt convention: errors at edge pixels not on occlusion boundaries; pooled metrics
   (MAE, median AE, median relative error, outlier fraction |e| > 1 px, bias = mean signed error),
   per-scene metrics (line_spread), binned median |error| vs σ_gt (the error-vs-σ curves).
3. Analytic families: the detected edge pixels within ``edge_tolerance_px`` of a true edge and
   ``analytic_border_px`` from the image border; errors against the exact σ.
4. Bias decomposition: encoding effect = bias(srgb) − bias(linear) (same convention; the 8-bit
   quantisation in display vs linear values, the measure light being the same); convention
   effect = bias(line_spread) − bias(erf_fit) (same encoding and pixels) = mean(σ_erf − σ_ls).
5. Cases (:func:`cases`): per preset of ``config.presets`` (the paper's, ``robust``'s …) the three
   analytic families (step 3; no scene set), with the preset's parameters (edge detector and
   estimators) and its own model fit in place of ``model_fit`` (:func:`fit_estimator`: the robust
   preset's ``model_fit_checked``); per hand-built scene set × scene × aperture × preset a ``rendered``
   case (steps 1–2) and per set × preset a ``pooled`` case needing them (steps 2 and 4); on the
   procedural test split the straight and curved steps with the σ of its scenes' surfaces
   (:func:`experiments.fig4_analytic.procedural_steps`).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig4Config", "cases", "compute_case", "fit_estimator", "preset_estimators"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig4Config:
    """Every parameter of Fig. 4."""

    estimators: tuple[str, ...] = ("model_fit", "zero_crossing", "gradient_ratio")
    # keys of method.BLUR_ESTIMATORS compared (the first two are the paper's Fig. 4); "model_fit"
    # stands for each preset's fit (its ``estimator`` when that is a model-fit variant, e.g. the
    # robust preset's "model_fit_checked").
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS), each its own cases (edge detection and every estimator
    # run with that preset's parameters). Not to be confused with the render `preset`.
    scene_sets: tuple = (("tabletop_stress", ("planes", "tilted_plane", "portrait", "clutter", "shadow_gloss")),
                         ("paper_cameras", ("portrait_garden", "street_figures", "patio_table", "heron_at_the_lake")),
                         ("procedural_test", ("procedural_100000", "procedural_100001", "procedural_100002",
                                              "procedural_100003")))
    # (scene set, scenes) pairs (experiments.scene_sets), the first the default: the rendered comparison
    # on the hand-built sets; on procedural_test the analytic steps with σ from its scenes
    # (experiments.fig4_analytic.procedural_steps).
    showcase: tuple = (("tabletop_stress", "planes"), ("paper_cameras", "portrait_garden"))
    # (scene set, scene whose maps are drawn) pairs.
    procedural_f_number: float = 4.0
    # N at which the procedural scenes' CoCs give the σ of their analytic steps.
    f_numbers: tuple[float, ...] = (8.0, 4.0)
    # apertures N of the renders, dimensionless.
    preset: str = "full"
    # render resolution preset ("small" 160×120, "full" 640×480 px).
    encodings: tuple[str, ...] = ("srgb", "linear")
    # input encodings given to the method (camera sRGB, linear radiance).
    conventions: tuple[str, ...] = ("line_spread", "erf_fit")
    # CoC → σ_gt conventions (scenes.thin_lens.SIGMA_CONVENTIONS).
    quantize_bits: int | None = 8
    # bits per channel of the rendered input (8 = camera JPEG-like), both encodings.
    showcase_f_number: float = 4.0
    # N of the drawn scene.
    error_bins_px: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0)
    # σ_gt bin edges of the error-vs-σ curves, px.
    analytic_sigmas: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
    # σ of the analytic straight and curved steps, px.
    analytic_angles_deg: tuple[float, ...] = (7.0, 52.0, 97.0, 142.0, 187.0, 232.0)
    # normal directions of the straight steps, degrees (none axis-aligned).
    analytic_shape: tuple[int, int] = (80, 80)
    # straight-step image size (H, W), px.
    disk_radius_factor: float = 8.0
    # curved step: disk radius R = disk_radius_factor·σ + disk_radius_offset_px, px.
    disk_radius_offset_px: float = 16.0
    # see disk_radius_factor.
    bar_sigmas: tuple[float, ...] = (1.0, 2.0, 3.0)
    # σ of the neighbouring-edge images, px.
    bar_spacings: tuple[float, ...] = (2.0, 3.0, 4.0, 5.0, 6.0)
    # edge spacing D as a multiple k of σ (D = k·σ), dimensionless (brief: 2–6σ).
    bar_kinds: tuple[str, ...] = ("bar", "staircase")
    # scenes.analytic.parallel_edges kinds: opposite-polarity bar, same-polarity staircase.
    bar_angles_deg: tuple[float, ...] = (0.0, 30.0)
    # normal directions of the neighbouring-edge images, degrees.
    bar_shape: tuple[int, int] = (112, 112)
    # neighbouring-edge image size, px.
    noise_std: float = 2.0 / 255.0
    # additive Gaussian noise of the "noisy" analytic condition, image units (then 8-bit).
    noise_seed: int = 4
    # base seed of the analytic noise.
    edge_tolerance_px: float = 1.5
    # analytic: a detected edge pixel is scored if it lies within this distance of a true edge, px.
    analytic_border_px: int = 12
    # analytic: pixels this close to the image border are not scored, px.
    outlier_px: float = 1.0
    # |error| above which an estimate is an outlier, px.
    blurred_coc_px: float = 4.0
    # "blurred" subset for bias_blurred / mae_blurred: CoC diameter ≥ this, px (σ_gt ≥ 1.04 px
    # line_spread); selected by the CoC so that both conventions score the same pixels.


FULL = Fig4Config()
QUICK = Fig4Config(scene_sets=(("tabletop_stress", ("planes", "shadow_gloss")),
                               ("paper_cameras", ("patio_table", "portrait_garden")),
                               ("procedural_test", ("procedural_100000", "procedural_100001"))), preset="small",
                   analytic_sigmas=(0.5, 1.0, 2.0, 4.0, 8.0), analytic_angles_deg=(7.0, 97.0, 232.0),
                   bar_sigmas=(1.0, 2.0), bar_spacings=(2.0, 3.0, 4.0, 6.0), bar_angles_deg=(0.0, 30.0))

# --- rendered scenes ---------------------------------------------------------------------------
def _rendered_case(config: Fig4Config, case, params, ests) -> dict:
    """One render × preset: every encoding's estimates at the scored edge pixels (for the pooled case) and
    the per-scene metrics (first convention), per encoding × estimator."""
    from scenes import render_scene

    from .evaluation import ground_truth_sigma, input_image, sparse_estimates
    from .metrics import sparse_metrics

    render = render_scene(case.scene, preset=config.preset, f_number=case.aperture, progress=False)
    keep = ~np.asarray(render.occlusion_boundary, dtype=bool)
    gts = {conv: ground_truth_sigma(render, convention=conv) for conv in config.conventions}
    coc = np.asarray(render.coc_px, dtype=np.float64)
    arrays, groups = {}, []
    for enc in config.encodings:
        image = input_image(render, encoding=enc, quantize_bits=config.quantize_bits)
        edges, sig = sparse_estimates(image, ests, params=params, encoding=enc)
        sel = edges & keep
        arrays[f"{enc}__coc"] = coc[sel]
        for conv in config.conventions:
            arrays[f"{enc}__gt__{conv}"] = gts[conv][sel]
        for e in ests:
            arrays[f"{enc}__est__{e}"] = sig[e][sel]
            m = sparse_metrics(sig[e], gts[config.conventions[0]], mask=sel, outlier_px=config.outlier_px)
            groups.append(({"encoding": enc, "estimator": e},
                           {k: m[k] for k in ("n", "mae", "median_ae", "median_rel_error", "outlier_fraction", "bias")}))
        if (case.scene_set, case.scene) in config.showcase and case.aperture == config.showcase_f_number \
                and enc == config.encodings[0]:
            arrays.update(showcase_image=image.astype(np.float32),
                          showcase_sigma_gt=gts[config.conventions[0]].astype(np.float32),
                          showcase_estimates=np.stack([sig[e] for e in ests]).astype(np.float32),
                          showcase_occlusion=~keep)
    return {"arrays": arrays, "groups": groups}


def _pooled_case(config: Fig4Config, case, ests, inputs) -> dict:
    """Pooled over every render of the set (scene, then aperture order): per encoding × estimator the
    metrics per convention, the blurred subset and the failure rate; the error-vs-σ curves; the bias effects."""
    from .evaluation import binned_abs_error
    from .fig4_analytic import pooled_metrics

    outs = [inputs[c].arrays() for c in case.needs]
    bins = np.asarray(config.error_bins_px, dtype=np.float64)
    curves = np.full((len(config.encodings), len(config.conventions), len(ests), bins.size - 1), np.nan)
    counts = np.zeros(curves.shape, dtype=np.int64)
    pooled: dict = {}
    for a, enc in enumerate(config.encodings):
        cv = np.concatenate([o[f"{enc}__coc"] for o in outs]) if outs else np.zeros(0)
        for b, conv in enumerate(config.conventions):
            gv = np.concatenate([o[f"{enc}__gt__{conv}"] for o in outs]) if outs else np.zeros(0)
            for c, e in enumerate(ests):
                ev = np.concatenate([o[f"{enc}__est__{e}"] for o in outs]) if outs else np.zeros(0)
                m = pooled_metrics([o[f"{enc}__est__{e}"] for o in outs], [o[f"{enc}__gt__{conv}"] for o in outs],
                             config.outlier_px)
                # the same pixels under every convention: selected by the CoC, not by σ_gt
                big = (cv >= config.blurred_coc_px) & np.isfinite(ev) & np.isfinite(gv)
                m["n_blurred"] = int(big.sum())
                m["bias_blurred"] = float(np.mean(ev[big] - gv[big])) if big.any() else float("nan")
                m["mae_blurred"] = float(np.mean(np.abs(ev[big] - gv[big]))) if big.any() else float("nan")
                m["failure_rate"] = float(np.mean(~np.isfinite(ev))) if ev.size else float("nan")
                pooled.setdefault((enc, e), {})[conv] = m
                curves[a, b, c], counts[a, b, c] = binned_abs_error(ev, gv, bins)
    arrays = {"curve_bin_edges": bins, "curve_rendered_median_ae": curves, "curve_rendered_count": counts,
              "estimators": np.asarray(ests), "encodings": np.asarray(config.encodings),
              "conventions": np.asarray(config.conventions)}
    groups = [({"encoding": enc, "estimator": e}, m) for (enc, e), m in pooled.items()]
    groups += [({"estimator": e}, m) for e, m in _bias_effects(config, pooled, ests).items()]
    return {"arrays": arrays, "groups": groups}


def _bias_effects(config, pooled, ests) -> dict:
    """Per estimator: encoding effect bias(srgb) − bias(linear) and convention effect bias(line_spread) −
    bias(erf_fit), over all scored edge pixels (``all``) and the blurred subset CoC ≥ ``blurred_coc_px``."""
    out = {}
    encs, convs = config.encodings, config.conventions
    for e in ests:
        eff = out[e] = {}
        for subset, key in (("all", "bias"), ("blurred", "bias_blurred")):
            if "srgb" in encs and "linear" in encs:
                eff.setdefault("encoding_effect", {})[subset] = {
                    conv: pooled[("srgb", e)][conv][key] - pooled[("linear", e)][conv][key] for conv in convs}
            if "line_spread" in convs and "erf_fit" in convs:
                eff.setdefault("convention_effect", {})[subset] = {
                    enc: pooled[(enc, e)]["line_spread"][key] - pooled[(enc, e)]["erf_fit"][key] for enc in encs}
    return out


def fit_estimator(params) -> str:
    """The model fit a preset uses: its ``estimator`` when that is a model-fit variant, else ``"model_fit"``.

    Parameters
    ----------
    params : DefocusParams

    Returns
    -------
    str
        A key of :data:`method.BLUR_ESTIMATORS` (``"model_fit"`` for the paper preset,
        ``"model_fit_checked"`` for the robust one).
    """
    return params.estimator if params.estimator.startswith("model_fit") else "model_fit"


def preset_estimators(estimators, params) -> tuple[str, ...]:
    """``estimators`` with ``"model_fit"`` replaced by the preset's fit (:func:`fit_estimator`), deduplicated."""
    fit = fit_estimator(params)
    out = []
    for e in estimators:
        e = fit if e == "model_fit" else e
        if e not in out:
            out.append(e)
    return tuple(out)


def cases(config: Fig4Config) -> tuple:
    """Per preset: the analytic families (no scene set) and, on the procedural test split, its steps;
    per hand-built scene set × scene × aperture × preset a ``rendered`` case, and per set × preset a
    ``pooled`` case needing them."""
    from .cases import Case, method_presets
    from .evaluation import validate_estimators
    from .scene_sets import PROCEDURAL_TEST, check_scene_sets

    validate_estimators(config.estimators)
    presets = method_presets(config.presets)
    out = [Case("fig4", preset=p, variant=f"analytic:{fam}") for p in presets for fam in ("straight", "curved",
                                                                                          "neighbouring")]
    for set_name, scenes in check_scene_sets(config.scene_sets):
        if set_name == PROCEDURAL_TEST:
            out += [Case("fig4", scene_set=set_name, preset=p, variant=f"analytic:{fam}") for p in presets
                    for fam in ("straight", "curved")]
            continue
        for p in presets:
            scene_cases = tuple(Case("fig4", scene_set=set_name, scene=sc, preset=p, aperture=float(n),
                                     variant="rendered", scene_size=config.preset)
                                for sc in scenes for n in config.f_numbers)
            out += [*scene_cases, Case("fig4", scene_set=set_name, preset=p, variant="pooled",
                                       scene_size=config.preset, needs=scene_cases)]
    return tuple(out)


def compute_case(config: Fig4Config, case, inputs) -> dict:
    """One case of :func:`cases` with the preset's parameters and its own model fit (:func:`preset_estimators`).

    Returns
    -------
    dict
        Groups per estimator (and encoding): ``analytic:<family>`` (:func:`experiments.fig4_analytic.analytic_case`);
        ``rendered``: ``n``, ``mae``, ``median_ae``, ``median_rel_error``, ``outlier_fraction``, ``bias`` at the
        render's scored edge pixels (first convention), arrays of the estimates and σ_gt there (and the drawn
        maps of the showcase scene); ``pooled``: per convention those metrics plus ``n_blurred``,
        ``bias_blurred``, ``mae_blurred``, ``failure_rate`` over every render of the set, per estimator the
        bias effects (module Notes 4), arrays of the error-vs-σ curves.
    """
    from method import DefocusParams

    from .evaluation import validate_estimators
    from .fig4_analytic import analytic_case

    params = DefocusParams.preset(case.preset)
    ests = validate_estimators(preset_estimators(config.estimators, params))
    if case.variant.startswith("analytic:"):
        return analytic_case(config, case, params, ests)
    if case.variant == "rendered":
        return _rendered_case(config, case, params, ests)
    return _pooled_case(config, case, ests, inputs)


FIGURE = Figure(
    name="fig4",
    title="Blur at edges: zero crossing vs model fit (and gradient ratio), rendered + analytic, sRGB/linear",
    plot="experiments.plotting.fig4:plot",
    configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=3,
    sigma_convention="both reported: line_spread sigma = sqrt((c/4)^2 + 1/12) and erf_fit "
                     "sigma = sqrt((0.273c)^2 + 1/12), px; analytic images: exact Gaussian sigma",
)
