"""Fig. 4: blur estimation at edges — zero crossing (Elder–Zucker) vs model fit (the paper's, Sec. 3.2).

Every estimator registered in :data:`method.BLUR_ESTIMATORS` that the config names is compared
(default: ``model_fit``, ``zero_crossing``, ``gradient_ratio``) on

* **rendered scenes** — Mitsuba renders (:func:`scenes.render_scene`), σ_gt from the render's CoC,
  at detected edge pixels, occlusion boundaries excluded; for both input encodings
  (``"srgb"`` as a camera stores it, ``"linear"`` radiance) and both CoC → σ conventions
  (``"line_spread"`` c/4, ``"erf_fit"`` 0.273·c; each ⊕ the box filter's 1/√12 px).
  The method's model is a *Gaussian*-blurred step in the *pixel values*; the renderer blurs with a
  *disk* in *linear light* and the camera stores sRGB: the mean signed error per case measures the
  bias each mismatch causes;
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
4. Bias decomposition: encoding effect = bias(srgb) − bias(linear) (same convention); convention
   effect = bias(line_spread) − bias(erf_fit) (same encoding and pixels) = mean(σ_erf − σ_ls).
5. Method presets (``config.presets``, the first ``"paper"`` = ``DefocusParams()``): steps 1–4 with
   each preset's parameters (edge detector and estimators) and its own model fit in place of
   ``model_fit`` (:func:`fit_estimator`: the robust preset's ``model_fit_checked``); further presets
   under ``metrics["presets"][name]``.
6. Scene sets: the rendered comparison (steps 1, 2, 4) on the default set ``scene_set`` (flat keys)
   and on each of ``other_scene_sets`` (``metrics["scene_sets"][name]``, with its own ``"presets"``);
   the analytic images (step 3) have no scene set and are computed once per preset.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig4Config", "compute", "fit_estimator", "preset_estimators"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig4Config:
    """Every parameter of Fig. 4."""

    estimators: tuple[str, ...] = ("model_fit", "zero_crossing", "gradient_ratio")
    # keys of method.BLUR_ESTIMATORS compared (the first two are the paper's Fig. 4); "model_fit"
    # stands for each preset's fit (its ``estimator`` when that is a model-fit variant, e.g. the
    # robust preset's "model_fit_checked").
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS); the first is "paper" (= DefocusParams(), the
    # top-level metrics), the others go to metrics["presets"][name] (edge detection and every
    # estimator run with that preset's parameters). Not to be confused with the render `preset`.
    scenes: tuple[str, ...] = ("planes", "tilted_plane", "portrait", "clutter", "shadow_gloss")
    # keys of scenes.SCENES rendered (all in ``scene_set``).
    scene_set: str = "tabletop_stress"
    # name of the scenes.SCENE_SETS entry ``scenes`` is drawn from (the flat metrics describe it).
    other_scene_sets: tuple = (("paper_cameras", (("scenes", ("portrait_garden", "street_figures", "patio_table",
                                                              "heron_at_the_lake")),
                                                  ("showcase_scene", "portrait_garden"))),)
    # further scene sets of the rendered comparison: (set name, ((config field, value), ...)) overrides;
    # their metrics go to metrics["scene_sets"][name] (with their own "presets"), arrays to
    # "<name>__<key>" (experiments.scene_sets). The analytic images do not depend on the scene set
    # and are computed once per preset (flat / "presets" only).
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
    showcase_scene: str = "planes"
    # scene whose maps are drawn (input, σ_gt, estimates).
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
QUICK = Fig4Config(scenes=("planes", "shadow_gloss"), preset="small",
                   other_scene_sets=(("paper_cameras", (("scenes", ("patio_table", "portrait_garden")),
                                                        ("showcase_scene", "portrait_garden"))),),
                   analytic_sigmas=(0.5, 1.0, 2.0, 4.0, 8.0), analytic_angles_deg=(7.0, 97.0, 232.0),
                   bar_sigmas=(1.0, 2.0), bar_spacings=(2.0, 3.0, 4.0, 6.0), bar_angles_deg=(0.0, 30.0))

#: Analytic conditions: name → (noise_std multiplier, quantize_bits).
_CONDITIONS = ("clean", "noisy")


def _metrics(err_est, err_gt, outlier_px):
    from .metrics import sparse_metrics

    if err_est:
        est, gt = np.concatenate(err_est), np.concatenate(err_gt)
    else:
        est = gt = np.zeros(0)
    m = sparse_metrics(est, gt, outlier_px=outlier_px)
    return {k: m[k] for k in ("n", "mae", "median_ae", "median_rel_error", "outlier_fraction", "bias", "rmse")}


# --- analytic images ---------------------------------------------------------------------------
def _analytic_case(sc, estimators, params, config, border):
    """Estimates at the scored edge pixels of one analytic image: {est: values}, and σ."""
    from .evaluation import sparse_estimates

    edges, sig = sparse_estimates(sc.image, estimators, params=params)
    inner = np.zeros(sc.image.shape, dtype=bool)
    inner[border:-border, border:-border] = True
    sel = edges & inner & (np.abs(sc.edge_distance) < config.edge_tolerance_px)
    return {name: s[sel] for name, s in sig.items()}


def _degradation(config, cond, seed):
    if cond == "clean":
        return {}
    return {"noise_std": config.noise_std, "quantize_bits": 8, "rng": int(seed)}


def _analytic(config: Fig4Config, params, ests) -> tuple[dict, dict]:
    from scenes.analytic import blurred_disk, parallel_edges, step_edge

    sigmas = np.asarray(config.analytic_sigmas, dtype=np.float64)
    arrays = {}
    metrics: dict = {}
    seed = config.noise_seed
    for family in ("straight", "curved"):
        med = np.full((len(_CONDITIONS), len(ests), sigmas.size), np.nan)
        fail = np.full_like(med, np.nan)
        metrics[family] = {}
        for ci, cond in enumerate(_CONDITIONS):
            pooled = {e: ([], []) for e in ests}
            for si, s in enumerate(sigmas):
                per = {e: [] for e in ests}
                if family == "straight":
                    images = []
                    for a in config.analytic_angles_deg:
                        seed += 1
                        images.append((step_edge(config.analytic_shape, sigma=float(s), angle=math.radians(a),
                                                 offset=0.37, **_degradation(config, cond, seed)),
                                       config.analytic_border_px))
                else:
                    r = config.disk_radius_factor * s + config.disk_radius_offset_px
                    n = int(2 * r + 2 * config.analytic_border_px + 8 * s) | 1
                    seed += 1
                    images = [(blurred_disk((n, n), sigma=float(s), radius=r, center=(n / 2 - 0.3, n / 2 + 0.2),
                                            **_degradation(config, cond, seed)), 2)]
                for sc, border in images:
                    for e, v in _analytic_case(sc, ests, params, config, border).items():
                        per[e].append(v)
                for ei, e in enumerate(ests):
                    v = np.concatenate(per[e]) if per[e] else np.zeros(0)
                    fail[ci, ei, si] = float(np.mean(~np.isfinite(v))) if v.size else np.nan
                    ok = v[np.isfinite(v)]
                    med[ci, ei, si] = float(np.median(np.abs(ok - s))) if ok.size else np.nan
                    pooled[e][0].append(v)
                    pooled[e][1].append(np.full(v.shape, s))
            metrics[family][cond] = {e: _metrics(*pooled[e], config.outlier_px) for e in ests}
        arrays[f"analytic_{family}_median_ae"] = med
        arrays[f"analytic_{family}_failure_rate"] = fail
    # neighbouring edges
    ks = np.asarray(config.bar_spacings, dtype=np.float64)
    rel = np.full((len(config.bar_kinds), len(_CONDITIONS), len(ests), ks.size), np.nan)
    metrics["neighbouring"] = {}
    for gi, kind in enumerate(config.bar_kinds):
        metrics["neighbouring"][kind] = {}
        for ci, cond in enumerate(_CONDITIONS):
            metrics["neighbouring"][kind][cond] = {}
            for ki, k in enumerate(ks):
                pooled = {e: ([], []) for e in ests}
                for s in config.bar_sigmas:
                    for a in config.bar_angles_deg:
                        seed += 1
                        sc = parallel_edges(config.bar_shape, sigma=float(s), spacing=float(k * s),
                                            angle=math.radians(a), kind=kind, offset=0.3,
                                            **_degradation(config, cond, seed))
                        border = max(config.analytic_border_px, 16)
                        for e, v in _analytic_case(sc, ests, params, config, border).items():
                            pooled[e][0].append(v)
                            pooled[e][1].append(np.full(v.shape, s))
                m = {e: _metrics(*pooled[e], config.outlier_px) for e in ests}
                for ei, e in enumerate(ests):
                    rel[gi, ci, ei, ki] = m[e]["median_rel_error"]
                metrics["neighbouring"][kind][cond][f"D={k:g}sigma"] = m
    arrays["bar_median_rel_error"] = rel
    return arrays, metrics


# --- rendered scenes ---------------------------------------------------------------------------
def _rendered(config: Fig4Config, by_preset: dict) -> dict:
    """The rendered comparison of one scene set for every preset: ``{preset: (arrays, metrics)}``.

    ``by_preset``: ``{name: (DefocusParams, estimator names)}``. Every render and input image is made
    once and given to every preset (its own edge map and estimates)."""
    from scenes import render_scene

    from .evaluation import binned_abs_error, ground_truth_sigma, input_image, sparse_estimates
    from .metrics import sparse_metrics

    bins = np.asarray(config.error_bins_px, dtype=np.float64)
    state = {}
    for pname, (_, ests) in by_preset.items():
        # pooled[(enc, conv, est)] = ([est values], [gt values])
        state[pname] = {
            "pooled": {(enc, conv, e): ([], []) for enc in config.encodings for conv in config.conventions
                       for e in ests},
            "pooled_coc": {(enc, e): [] for enc in config.encodings for e in ests},
            "by_scene": {}, "arrays": {}}
    for scene in config.scenes:
        for st in state.values():
            st["by_scene"][scene] = {}
        for n in config.f_numbers:
            render = render_scene(scene, preset=config.preset, f_number=n, progress=False)
            keep = ~np.asarray(render.occlusion_boundary, dtype=bool)
            gts = {conv: ground_truth_sigma(render, convention=conv) for conv in config.conventions}
            coc = np.asarray(render.coc_px, dtype=np.float64)
            for st in state.values():
                st["by_scene"][scene][f"f/{n:g}"] = {}
            for enc in config.encodings:
                image = input_image(render, encoding=enc, quantize_bits=config.quantize_bits)
                for pname, (params, ests) in by_preset.items():
                    st = state[pname]
                    edges, sig = sparse_estimates(image, ests, params=params)
                    sel = edges & keep
                    row = st["by_scene"][scene][f"f/{n:g}"][enc] = {}
                    for e in ests:
                        st["pooled_coc"][(enc, e)].append(coc[sel])
                        for conv in config.conventions:
                            st["pooled"][(enc, conv, e)][0].append(sig[e][sel])
                            st["pooled"][(enc, conv, e)][1].append(gts[conv][sel])
                        m = sparse_metrics(sig[e], gts[config.conventions[0]], mask=sel, outlier_px=config.outlier_px)
                        row[e] = {k: m[k] for k in ("n", "mae", "median_ae", "median_rel_error", "outlier_fraction",
                                                    "bias")}
                    if scene == config.showcase_scene and n == config.showcase_f_number and enc == config.encodings[0]:
                        st["arrays"]["showcase_image"] = image.astype(np.float32)
                        st["arrays"]["showcase_sigma_gt"] = gts[config.conventions[0]].astype(np.float32)
                        st["arrays"]["showcase_estimates"] = np.stack([sig[e] for e in ests]).astype(np.float32)
                        st["arrays"]["showcase_occlusion"] = ~keep
    out = {}
    for pname, (_, ests) in by_preset.items():
        st = state[pname]
        pooled, pooled_coc, arrays = st["pooled"], st["pooled_coc"], st["arrays"]
        metrics: dict = {}
        curves = np.full((len(config.encodings), len(config.conventions), len(ests), bins.size - 1), np.nan)
        counts = np.zeros(curves.shape, dtype=np.int64)
        for a, enc in enumerate(config.encodings):
            metrics[enc] = {}
            for b, conv in enumerate(config.conventions):
                metrics[enc][conv] = {}
                for c, e in enumerate(ests):
                    est_v, gt_v = pooled[(enc, conv, e)]
                    m = _metrics(est_v, gt_v, config.outlier_px)
                    ev = np.concatenate(est_v) if est_v else np.zeros(0)
                    gv = np.concatenate(gt_v) if gt_v else np.zeros(0)
                    cv = np.concatenate(pooled_coc[(enc, e)]) if pooled_coc[(enc, e)] else np.zeros(0)
                    # the same pixels under every convention: selected by the CoC, not by σ_gt
                    big = (cv >= config.blurred_coc_px) & np.isfinite(ev) & np.isfinite(gv)
                    m["n_blurred"] = int(big.sum())
                    m["bias_blurred"] = float(np.mean(ev[big] - gv[big])) if big.any() else float("nan")
                    m["mae_blurred"] = float(np.mean(np.abs(ev[big] - gv[big]))) if big.any() else float("nan")
                    m["failure_rate"] = float(np.mean(~np.isfinite(ev))) if ev.size else float("nan")
                    metrics[enc][conv][e] = m
                    curves[a, b, c], counts[a, b, c] = binned_abs_error(ev, gv, bins)
        arrays["curve_bin_edges"] = bins
        arrays["curve_rendered_median_ae"] = curves
        arrays["curve_rendered_count"] = counts
        out[pname] = (arrays, {"pooled": metrics, "by_scene": st["by_scene"]})
    return out


def _bias_effects(config, pooled, ests) -> dict:
    """Encoding effect bias(srgb) − bias(linear) and convention effect bias(line_spread) − bias(erf_fit),
    over all scored edge pixels (``all``) and over the blurred subset CoC ≥ ``blurred_coc_px`` (``blurred``)."""
    out = {"encoding_effect": {}, "convention_effect": {}}
    encs, convs = config.encodings, config.conventions
    for e in ests:
        for subset, key in (("all", "bias"), ("blurred", "bias_blurred")):
            if "srgb" in encs and "linear" in encs:
                out["encoding_effect"].setdefault(e, {})[subset] = {
                    conv: pooled["srgb"][conv][e][key] - pooled["linear"][conv][e][key] for conv in convs}
            if "line_spread" in convs and "erf_fit" in convs:
                out["convention_effect"].setdefault(e, {})[subset] = {
                    enc: pooled[enc]["line_spread"][e][key] - pooled[enc]["erf_fit"][e][key] for enc in encs}
    return out


def _claims(ests, fit, analytic_metrics) -> dict:
    """Paper claim "model fit beats zero crossing near neighbouring edges", per case (median relative error).

    ``fit`` is the preset's model fit (a key of ``ests``); the entries keep the role names
    ``model_fit`` and ``zero_crossing``."""
    out = {}
    if fit not in ests or "zero_crossing" not in ests:
        return out
    for kind, conds in analytic_metrics["neighbouring"].items():
        for cond, cases in conds.items():
            for case, m in cases.items():
                mf, zc = m[fit]["median_rel_error"], m["zero_crossing"]["median_rel_error"]
                out[f"{kind}.{cond}.{case}"] = {"model_fit": mf, "zero_crossing": zc,
                                                "model_fit_better": bool(mf < zc)}
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


def compute(config: Fig4Config) -> dict:
    """Estimates, error curves and metrics of Fig. 4, for every preset and scene set.

    Parameters
    ----------
    config : Fig4Config

    Returns
    -------
    dict
        ``estimators`` (E,) str; ``encodings`` (A,), ``conventions`` (B,);
        ``showcase_image`` HxWx3, ``showcase_sigma_gt`` HxW px, ``showcase_estimates`` (E, H, W) px
        (NaN off edges), ``showcase_occlusion`` HxW bool;
        ``curve_bin_edges`` (k + 1,) px, ``curve_rendered_median_ae`` (A, B, E, k) px,
        ``curve_rendered_count`` (A, B, E, k);
        ``analytic_sigmas`` (S,) px, ``analytic_straight_median_ae`` / ``analytic_curved_median_ae``
        (2 conditions clean/noisy, E, S) px, ``..._failure_rate`` (same);
        ``bar_spacings`` (K,) (multiples of σ), ``bar_median_rel_error`` (kinds, 2, E, K) — all of the
        paper preset on the default scene set; the same keys prefixed ``<set>__`` for each further
        scene set (analytic arrays repeated: they do not depend on the set) and ``<P>__`` /
        ``<set>__<P>__`` for each further preset P;
        ``metrics``: ``rendered`` (pooled[encoding][convention][estimator], by_scene),
        ``analytic`` (straight/curved[condition][estimator], neighbouring[kind][condition][D]),
        ``bias_effects``, ``claims``, ``fit_estimator``, ``timings``, ``scene_set`` — the paper preset
        on the default set; ``presets.<P>`` the same for preset P; ``scene_sets.<set>`` = {``rendered``,
        ``bias_effects``, ``fit_estimator``, ``scene_set``, ``presets.<P>``} for each further set.

    Notes
    -----
    1. Presets (:func:`experiments.fig6_alpha_sweep.method_presets`): each preset's parameters and its
       own fit (:func:`preset_estimators`) for edge detection and every estimate.
    2. Analytic images once per preset (they have no scene set).
    3. Rendered scenes once per scene set; each render and input image is estimated by every preset.
    """
    from .evaluation import validate_estimators
    from .fig6_alpha_sweep import method_presets
    from .scene_sets import scene_set_configs

    validate_estimators(config.estimators)
    presets = method_presets(config.presets)
    by_preset = {p: (params, preset_estimators(config.estimators, params)) for p, params in presets.items()}
    for _, ests in by_preset.values():
        validate_estimators(ests)
    sets = scene_set_configs(config)
    t0 = time.perf_counter()
    rendered = {name: _rendered(cfg, by_preset) for name, cfg in sets}
    t1 = time.perf_counter()
    analytic = {p: _analytic(config, params, ests) for p, (params, ests) in by_preset.items()}
    t2 = time.perf_counter()

    def node(pname, set_name, with_analytic):
        params, ests = by_preset[pname]
        r_arrays, r_metrics = rendered[set_name][pname]
        m = {"rendered": r_metrics, "bias_effects": _bias_effects(config, r_metrics["pooled"], ests),
             "fit_estimator": fit_estimator(params), "estimators": list(ests)}
        arrays = {"estimators": np.asarray(ests), "encodings": np.asarray(config.encodings),
                  "conventions": np.asarray(config.conventions),
                  "analytic_sigmas": np.asarray(config.analytic_sigmas, dtype=np.float64),
                  "bar_spacings": np.asarray(config.bar_spacings, dtype=np.float64),
                  "bar_kinds": np.asarray(config.bar_kinds), **r_arrays, **analytic[pname][0]}
        if with_analytic:
            a_metrics = analytic[pname][1]
            m["analytic"] = a_metrics
            m["claims"] = {"neighbouring_edges": _claims(ests, fit_estimator(params), a_metrics)}
        return arrays, m

    names = list(presets)
    default = config.scene_set
    data, metrics = node(names[0], default, True)
    metrics.update({
        "scene_set": default,
        "timings": {"rendered_s": t1 - t0, "analytic_s": t2 - t1},
        "outlier_threshold_px": config.outlier_px,
        "edge_selection": "rendered: detected edge pixels not on occlusion boundaries with finite σ_gt; analytic: "
                          f"detected edge pixels within {config.edge_tolerance_px} px of a true edge",
        "relative_error": "median over edge pixels of |σ_est − σ_gt| / σ_gt",
        "analytic_note": "analytic images have no scene set: computed once per preset, stored under the default "
                         "scene set's keys only",
    })
    metrics["presets"] = {}
    for pname in names[1:]:
        arrays, m = node(pname, default, True)
        metrics["presets"][pname] = m
        data.update({f"{pname}__{k}": v for k, v in arrays.items()})
    metrics["scene_sets"] = {}
    for set_name, _ in sets[1:]:
        arrays, m = node(names[0], set_name, False)
        m["scene_set"] = set_name
        m["presets"] = {}
        data.update({f"{set_name}__{k}": v for k, v in arrays.items()})
        for pname in names[1:]:
            arrays, pm = node(pname, set_name, False)
            m["presets"][pname] = pm
            data.update({f"{set_name}__{pname}__{k}": v for k, v in arrays.items()})
        metrics["scene_sets"][set_name] = m
    data["metrics"] = metrics
    return data


FIGURE = Figure(
    name="fig4",
    title="Blur at edges: zero crossing vs model fit (and gradient ratio), rendered + analytic, sRGB/linear",
    compute=compute,
    plot="experiments.plotting.fig4:plot",
    configs={"quick": QUICK, "full": FULL},
    version=2,  # 2: every preset of ``presets`` and every scene set
    sigma_convention="both reported: line_spread sigma = sqrt((c/4)^2 + 1/12) and erf_fit "
                     "sigma = sqrt((0.273c)^2 + 1/12), px; analytic images: exact Gaussian sigma",
)
