"""Accuracy benchmark of the method: dense-map and sparse edge errors per σ bin, and relative speed.

:func:`measure_accuracy` runs what :data:`ACCURACY_CONFIG` lists — analytic truth (texture and
step-edge mosaics, 8 bits + noise, :mod:`experiments.bench.mosaics`), the rendered scenes (cached
renders, σ_gt in the line-spread convention) and the presets' whole-pipeline speed — through
:func:`experiments.stage_attribution.stage_errors`; :func:`accuracy_report` adds the verdicts
(:func:`experiments.bench.targets.judge_accuracy`), the notes and the machine. ``python -m repro.bench
--accuracy`` writes the report; measurements are in ``docs/performance.md``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import statistics
import time
import warnings

from .lens import LENS_CONFIG, judge_lens, measure_lens
from .mosaics import ANALYTIC_DATASETS, STEP_BASE_ANGLE, STEP_SEAM_BAND_PX, analytic_case, noise_label, sigma_bins
from .speed import machine_info, bench_image
from .targets import judge_accuracy, targets

__all__ = ["ACCURACY_CONFIG", "UNIT", "AccuracyCases", "accuracy_report", "json_safe", "measure_accuracy", "pool",
           "preset_seeds", "seeds_text"]

#: What ``--accuracy`` measures (see :func:`measure_accuracy`); tests pass a smaller dict.
ACCURACY_CONFIG = {
    "datasets": tuple(ANALYTIC_DATASETS),
    "sigmas": (0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0),  # tile blur σ, px
    "tile": 96,  # px
    "mosaic_cols": 4,  # texture mosaics; the step-edge mosaic is 2 rows x len(sigmas)
    "noise_stds": (1.0 / 255, 2.0 / 255),  # image units, then 8-bit quantisation
    "seeds": (0, 1),
    "presets": ("paper", "robust", "zhuo_sim"),
    # preset -> seeds it runs on, if not all (zhuo_sim's matting-Laplacian propagation, run three times
    # by stage_errors, costs ~15 s per mosaic: one seed keeps --accuracy under ~10 min; no target on it)
    "preset_seeds": {"zhuo_sim": (0,)},
    # scene set -> scenes (every scene of both sets of scenes.SCENE_SETS); one table and one verdict
    # per set (the dense-map target is judged per case and on each set's mean)
    "scene_sets": {"tabletop_stress": ("portrait", "planes", "tilted_plane", "clutter", "shadow_gloss"),
                   "paper_cameras": ("portrait_garden", "street_figures", "patio_table", "heron_at_the_lake")},
    "f_numbers": (8.0, 4.0),
    "render_preset": "small",
    "estimators": ("zero_crossing", "gradient_ratio"),  # run in the paper pipeline
    "speed_presets": ("paper", "robust"),
    "speed_sizes": (512, 1024),  # px (square astronaut, as the speed bench)
    "speed_repeat": 3,  # median of this many runs
    "speed_single": {"zhuo_sim": (512,)},  # preset -> sizes timed once
    # the lens benchmark (experiments.bench.lens): texture families and steps blurred by a lens PSF in
    # linear light, then a camera; None skips it. ``repro.bench --accuracy --psf …`` / ``--full`` change it.
    "lens": LENS_CONFIG,
}


def preset_seeds(config: dict, preset: str) -> tuple:
    """The seeds ``preset`` runs on: ``config["preset_seeds"][preset]`` if given, else every seed."""
    return tuple(config.get("preset_seeds", {}).get(preset, config["seeds"]))


def _slim(err, nominal=None, gt=None) -> dict | None:
    """The parts of one :func:`experiments.stage_attribution.stage_errors` entry the report keeps."""
    if not err:
        return None
    out = {k: err[k] for k in ("n", "mae", "bias", "coverage")}
    if nominal is not None:
        # an open upper edge is None (JSON null), here already: the case runner stores results as JSON
        out["bins"] = [{"sigma": s, "sigma_gt": g, "lo": b["lo"], "hi": None if math.isinf(b["hi"]) else b["hi"],
                        "n": b["n"], "mae": b["mae"], "bias": b["bias"]} for s, g, b in zip(nominal, gt, err["bins"])]
    return out


def pool(entries) -> dict:
    """Pixel-weighted pooling of error dicts (``n``, ``mae``, ``bias``[, ``bins``]) over seeds."""
    entries = [e for e in entries if e]

    def pooled(items):
        n = sum(i["n"] for i in items)
        return {"n": n,
                "mae": sum(i["n"] * i["mae"] for i in items if i["n"]) / n if n else None,
                "bias": sum(i["n"] * i["bias"] for i in items if i["n"]) / n if n else None}

    out = pooled(entries)
    if entries and "bins" in entries[0]:
        out["bins"] = [{**{k: same[0][k] for k in ("sigma", "sigma_gt", "lo", "hi")}, **pooled(same)}
                       for same in map(list, zip(*(e["bins"] for e in entries)))]
    return out


def _analytic_run(dataset, noise, seed, preset, case, bins) -> dict:
    """One preset on one analytic image: slimmed ``stage_errors`` entries and the time taken."""
    from experiments.stage_attribution import stage_errors
    from method import DefocusParams

    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        err = stage_errors(case["image"], case["sigma_gt"], params=DefocusParams.preset(preset),
                           valid=case["valid"], bins=bins)
    est = err["estimated"]
    return {"dataset": dataset, "noise_std": float(noise), "seed": int(seed), "preset": preset,
            "shape": list(case["image"].shape[:2]), "intrinsic_sigma": case["intrinsic_sigma"],
            "dense_textured": _slim(est["dense_textured"], case["nominal"], case["gt"]),
            "sparse": _slim(est["sparse"], case["nominal"], case["gt"]),
            "oracle_propagate_dense_textured": _slim(err["oracle_propagate"].get("dense_textured"),
                                                      case["nominal"], case["gt"]),
            "n_edges": err["n_edges"], "seconds": time.perf_counter() - t}


def _analytic_runs(config: dict, dataset, noise, seed) -> list[dict]:
    """Every preset (that runs on ``seed``) on one analytic image."""
    presets = [p for p in config["presets"] if seed in preset_seeds(config, p)]
    case = analytic_case(dataset, config, float(noise), int(seed))
    bins = sigma_bins(case["gt"])
    return [_analytic_run(dataset, noise, seed, preset, case, bins) for preset in presets]


def _pool_analytic(config: dict, runs: list[dict]) -> dict:
    pooled = []
    for dataset in config["datasets"]:
        for noise in config["noise_stds"]:
            for preset in config["presets"]:
                key = (dataset, float(noise), preset)
                sel = [r for r in runs if (r["dataset"], r["noise_std"], r["preset"]) == key]
                if not sel:
                    continue
                pooled.append({"dataset": dataset, "noise_std": float(noise), "preset": preset,
                               "seeds": [r["seed"] for r in sel], "intrinsic_sigma": sel[0]["intrinsic_sigma"],
                               **{k: pool([r[k] for r in sel])
                                  for k in ("dense_textured", "sparse", "oracle_propagate_dense_textured")}})
    return {"runs": runs, "pooled": pooled}


def _rendered_case(config: dict, scene_set: str, scene: str, f_number: float) -> dict:
    """Every preset and every estimator (paper pipeline) on one render: the pipeline run by the one scorer
    (:func:`experiments.scoring.score_render`), its stages scored by ``stage_errors``."""
    from experiments.evaluation import ground_truth_sigma, input_image
    from experiments.scoring import score_render
    from experiments.stage_attribution import stage_errors
    from method import DefocusParams
    from scenes import render_scene

    render = render_scene(scene, preset=config["render_preset"], f_number=float(f_number), progress=False)
    image, gt = input_image(render), ground_truth_sigma(render)
    valid = ~render.occlusion_boundary
    runs = [("presets", p, DefocusParams.preset(p)) for p in config["presets"]]
    runs += [("estimators", e, DefocusParams().replace(estimator=e)) for e in config["estimators"]]
    case = {"scene_set": scene_set, "scene": scene, "f_number": float(f_number),
            "shape": list(image.shape[:2]), "presets": {}, "estimators": {}}
    for kind, name, params in runs:
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = score_render(render, image, encoding="srgb", params=params).raise_failure().result
            est = stage_errors(image, gt, params=params, valid=valid, result=result)["estimated"]
        case[kind][name] = {"dense_textured": _slim(est["dense_textured"]), "sparse": _slim(est["sparse"]),
                            "seconds": time.perf_counter() - t}
    return case


@dataclasses.dataclass(frozen=True)
class AccuracyCases:
    """The measured part of a config as the runner's frozen config: the config dict as sorted JSON."""

    config_json: str

    @classmethod
    def of(cls, config: dict) -> "AccuracyCases":
        """The config's analytic and rendered part (``lens`` and the speed runs are measured apart)."""
        keep = {k: v for k, v in config.items() if k not in ("lens",)}
        return cls(json.dumps(json_safe(keep), sort_keys=True))

    def config(self) -> dict:
        """The config dict back."""
        return json.loads(self.config_json)


def _cases(cfg: AccuracyCases) -> tuple:
    from experiments.cases import Case

    config = cfg.config()
    out = [Case("accuracy", scene=d, variant=f"noise={float(n)!r}/seed={int(s)}")
           for d in config["datasets"] for n in config["noise_stds"] for s in config["seeds"]
           if any(s in preset_seeds(config, p) for p in config["presets"])]
    out += [Case("accuracy", scene_set=k, scene=v, aperture=float(n), scene_size=config["render_preset"])
            for k, scenes in config["scene_sets"].items() for v in scenes for n in config["f_numbers"]]
    return tuple(out)


def _case(cfg: AccuracyCases, case, inputs) -> dict:
    config = cfg.config()
    if case.scene_set is None:
        noise, seed = (part.split("=", 1)[1] for part in case.variant.split("/"))
        return {"info": {"runs": _analytic_runs(config, case.scene, float(noise), int(seed))}}
    return {"info": {"case": _rendered_case(config, case.scene_set, case.scene, case.aperture)}}


def _run_here(unit, cfg, *, progress: bool) -> dict:
    """The unit's cases one after another in this process (the default of :func:`measure_accuracy`)."""
    from tqdm import tqdm

    from experiments.cases import run_cases

    cases = unit.cases(cfg)
    with tqdm(total=len(cases), desc="accuracy", unit="case", disable=not progress) as bar:
        return run_cases(unit, cfg, cases, progress=lambda c: bar.update(1))


def _measure_speed(config: dict, bar) -> dict:
    from method import DefocusParams, estimate_defocus_map

    plan = [(p, s, config["speed_repeat"]) for p in config["speed_presets"] for s in config["speed_sizes"]]
    plan += [(p, s, 1) for p, sizes in config["speed_single"].items() for s in sizes]
    images, rows = {}, []
    for preset, size, repeat in plan:
        if size not in images:
            images[size] = bench_image(size)
        params = DefocusParams.preset(preset)
        load_before, runs, totals = os.getloadavg(), [], []
        for _ in range(repeat):
            bar.set_postfix_str(f"{preset} {size}²")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t = time.perf_counter()
                result = estimate_defocus_map(images[size], params)
                runs.append(time.perf_counter() - t)
            totals.append(result.timings["total"])
            bar.update(1)
        rows.append({"preset": preset, "size": size, "runs_s": runs, "median_s": statistics.median(runs),
                     "pipeline_total_s": totals, "load_before": list(load_before),
                     "load_after": list(os.getloadavg())})
    return {"rows": rows}


def measure_accuracy(config: dict, *, progress: bool = True, run_cases=None) -> dict:
    """Run every measurement of ``config``; no verdicts, no files.

    Parameters
    ----------
    config : dict
        Keys as :data:`ACCURACY_CONFIG`; empty ``datasets`` / ``scene_sets`` / ``speed_presets`` and
        ``speed_single`` skip that part.
    progress : bool, keyword-only
        tqdm progress bars.
    run_cases : callable, optional, keyword-only
        ``run_cases(unit, config) -> {Case: CaseOutput}``: how the analytic and rendered cases run
        (``repro.bench`` passes the case runner, :mod:`repro._runner`); default one after another here.

    Returns
    -------
    dict
        ``analytic`` (``runs``: one per dataset x noise x seed x preset; ``pooled``: pixel-weighted over
        seeds), ``rendered`` (``cases``: per scene set x scene x f-number, every preset and estimator),
        ``speed`` (``rows``: per preset x size, wall times in s and load averages), ``lens`` (the rows
        of :func:`experiments.bench.lens.measure_lens`; empty without ``config["lens"]``).

    Notes
    -----
    1. Analytic truth, per dataset x noise x seed (one case): the image
       (:func:`experiments.bench.mosaics.analytic_case`), bins with one tile σ_gt each, then
       :func:`experiments.stage_attribution.stage_errors` for every preset.
    2. Rendered scenes, per scene set x scene x f-number (one case): cached renders, σ_gt in the
       line-spread convention, occlusion boundaries excluded; every preset and every estimator (paper
       pipeline) through ``stage_errors``.
    3. Speed, after every case is done (nothing else running): :func:`experiments.bench.speed.bench_image`
       at each size, median wall time, load averages around it.
    4. Lens blur: :func:`experiments.bench.lens.measure_lens` on ``config["lens"]``.
    """
    from tqdm import tqdm

    cfg = AccuracyCases.of(config)
    outputs = (run_cases or (lambda u, c: _run_here(u, c, progress=progress)))(UNIT, cfg)
    by_case = {c: o for c, o in outputs.items()}
    cases = UNIT.cases(cfg)
    runs = [r for c in cases if c.scene_set is None for r in by_case[c].info["runs"]]
    out = {"analytic": _pool_analytic(config, runs),
           "rendered": {"cases": [by_case[c].info["case"] for c in cases if c.scene_set is not None]}}
    n_speed = (len(config["speed_presets"]) * len(config["speed_sizes"]) * config["speed_repeat"]
               + sum(len(s) for s in config["speed_single"].values()))
    with tqdm(total=n_speed, desc="accuracy: speed", unit="run", disable=not progress or not n_speed) as bar:
        out["speed"] = _measure_speed(config, bar) if n_speed else {"rows": []}
    out["lens"] = measure_lens(config["lens"], progress=progress) if config.get("lens") else []
    return out


def json_safe(obj):
    """Non-finite floats → None, tuples → lists, NumPy scalars → Python (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def seeds_text(cfg: dict) -> str:
    """The seeds of ``cfg`` in words, naming the presets run on fewer."""
    text = ", ".join(str(s) for s in cfg["seeds"])
    cut = [f"{p}: {', '.join(str(s) for s in preset_seeds(cfg, p))} only" for p in cfg["presets"]
           if set(preset_seeds(cfg, p)) != set(cfg["seeds"])]
    return text + (f" ({'; '.join(cut)}, to bound the run time)" if cut else "")


def _notes(cfg: dict, load0) -> list[str]:
    """The notes of ``accuracy.md``: assumptions, masks, binning, noise and seeds, machine load."""
    from scenes.analytic import SKIMAGE_INTRINSIC_SIGMA_PX

    return [f"skimage mosaics: σ_gt = √(σ² + σ₀²) with σ₀ = {SKIMAGE_INTRINSIC_SIGMA_PX:.3f} px, "
             "an *assumed* "
             "intrinsic blur of the downsampled photographs (scenes.analytic.SKIMAGE_INTRINSIC_SIGMA_PX, an "
             "estimate, not a measurement): their errors include any error of that assumption.",
             f"Step-edge mosaic: 2 × {len(cfg['sigmas'])} tiles of {cfg['tile']}² px, one σ per column, normals at "
             f"±{math.degrees(STEP_BASE_ANGLE):g}° and 180° ∓ {math.degrees(STEP_BASE_ANGLE):g}° "
             "(mirror-image tiles, "
             f"continuous across seams); a {STEP_SEAM_BAND_PX}-px band each side of every seam is masked. "
             "Texture mosaics: the mosaic's own seam band (⌈3·max σ⌉ + 2 px) is masked.",
             "Verdict bins are chosen by the tile σ (its σ_gt for the 10 % rule); the pooled numbers (pixel-"
             "weighted over seeds) are judged; a targeted bin with no pixel fails.",
             f"Noise: {', '.join(noise_label(n) for n in cfg['noise_stds'])} then 8-bit quantisation; seeds "
             f"{seeds_text(cfg)}; the noise field of a seed is the same for both levels (scaled).",
             f"Machine load (1/5/15 min) at start: {' / '.join(f'{x:.2f}' for x in load0)}; "
             f"at end: {' / '.join(f'{x:.2f}' for x in os.getloadavg())}."]


def accuracy_report(config: dict | None = None, *, progress: bool = True, run_cases=None) -> dict:
    """Measure and judge: the record written to ``accuracy.json`` (strict JSON: no inf/NaN, no tuples).

    Parameters
    ----------
    config : dict, optional
        Keys as :data:`ACCURACY_CONFIG` (the default).
    progress : bool, keyword-only
        tqdm progress bars.
    run_cases : callable, optional, keyword-only
        How the cases run (:func:`measure_accuracy`).

    Returns
    -------
    dict
        ``config``, ``analytic``, ``rendered``, ``speed``, ``lens`` (:func:`measure_accuracy`), ``verdict``
        (:func:`experiments.bench.targets.judge_accuracy`), ``lens_verdict``
        (:func:`experiments.bench.lens.judge_lens`, None without lens rows), ``targets``, ``notes``,
        ``machine``, ``date``, ``runtime_s``.

    Raises
    ------
    ValueError
        A preset of ``config`` that :data:`method.PRESETS` does not have (before anything runs).
    """
    from method import PRESETS

    cfg = dict(ACCURACY_CONFIG if config is None else config)
    names = list(cfg["presets"]) + list(cfg["speed_presets"]) + list(cfg["speed_single"])
    if names:
        PRESETS.check_all(dict.fromkeys(names))
    if cfg["datasets"]:
        ANALYTIC_DATASETS.check_all(cfg["datasets"])
    t0 = time.perf_counter()
    load0 = os.getloadavg()
    measured = measure_accuracy(cfg, progress=progress, run_cases=run_cases)
    report = {"config": cfg, **measured, "verdict": judge_accuracy(measured), "targets": targets(),
              "lens_verdict": judge_lens(measured["lens"]) if measured["lens"] else None,
              "notes": _notes(cfg, load0), "machine": machine_info(),
              "date": time.strftime("%Y-%m-%d %H:%M:%S"), "runtime_s": time.perf_counter() - t0}
    return json_safe(report)


def _unit():
    from experiments.units import CaseUnit

    return CaseUnit("accuracy", _cases, _case)


#: The analytic and rendered measurements as a case unit of the case runner (:mod:`experiments.units`).
UNIT = _unit()
