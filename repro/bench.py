"""Benchmark suite: per-stage and whole-pipeline wall time and peak memory of the method.

``python -m repro.bench [--sizes 256 512 1024] [--presets paper robust] [--repeat 3] [--out report/bench]``

Each (preset, size) runs in a fresh subprocess (so its peak resident memory, ``ru_maxrss``, is its
own) on a textured photo-like image (``skimage.data.astronaut`` resized, shipped with scikit-image),
with the 1-min load average before and after. Writes ``bench.json`` and ``bench.md`` and prints the
table; the run it replaces (the previous ``bench.json`` in ``--out``) is kept in the output as
"before". Targets (this 2-core machine kind), for every preset: whole pipeline at 1 MP
≤ 2.0 s and ≤ 1.5 GiB, at 512² ≤ 1.0 s; 512² → 1024² cost growth ≤ 4.5×. The machine is shared, so
each row says how loaded it was; the fastest of ``--repeat`` runs counts.

``python -m repro.bench --accuracy [--out report/bench]`` instead records the targets of the
dense-map issue (:func:`run_accuracy`, configuration :data:`ACCURACY_CONFIG`): dense-map and sparse
edge errors per σ bin on analytic truth (dead-leaves / photo mosaics, step-edge mosaics; 8 bits +
noise), on the rendered scenes, and the whole-pipeline speed of the presets, with pass/fail per
target. Writes ``accuracy.json`` and ``accuracy.md`` (``--sizes`` / ``--repeat`` do not apply).

``python -m repro.bench --sweep [--out report/bench]`` benchmarks the sweep engine
(:func:`repro.sweep.run_sweep_bench`): cells per minute for 1 and 2 workers on the small preset and the
engine's overhead per cell. Writes ``sweep.json`` and ``sweep.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

TARGET_SECONDS_1MP = 2.0
#: Per-preset 1-MP time targets, s, where they differ from TARGET_SECONDS_1MP: robust runs the
#: region (spectral) estimator too (its target ≤ 2.5 s and ≤ 1.5 × paper, TARGET_SPEED_RATIO).
TARGET_SECONDS_1MP_BY_PRESET = {"robust": 2.5}
TARGET_SECONDS_512 = 1.0
TARGET_PEAK_GIB_1MP = 1.5
#: Presets timed by default (every one must meet the targets).
BENCH_PRESETS = ("paper", "robust")
TARGET_GROWTH_512_TO_1024 = 4.5


def _test_image(size: int):
    import numpy as np
    from skimage import data, transform

    img = data.astronaut().astype(np.float64) / 255.0
    return np.clip(transform.resize(img, (size, size), order=1, anti_aliasing=True), 0.0, 1.0)


def _worker(size: int, repeat: int, preset: str = "paper") -> dict:
    """Run the pipeline ``repeat`` times at ``size``²; return the best timings, peak RSS and load."""
    import warnings

    from method import DefocusParams, estimate_defocus_map, magnify_defocus

    image = _test_image(size)
    params = DefocusParams.preset(preset)
    load_before = os.getloadavg()[0]
    best = None
    for _ in range(repeat):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = estimate_defocus_map(image, params)
            t = time.perf_counter()
            magnify_defocus(image, result.defocus_map, factor=2.0)
            t_mag = time.perf_counter() - t
        timings = dict(result.timings)
        timings["magnification"] = t_mag
        if best is None or timings["total"] < best["total"]:
            best = timings
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "preset": preset,
        "load1": [load_before, os.getloadavg()[0]],
        "size": size,
        "pixels": size * size,
        "edge_pixels": int(result.edges.sum()),
        "timings_s": best,
        "peak_rss_gib": peak_kib / 2**20,
    }


def _run_size(size: int, repeat: int, preset: str = "paper") -> dict:
    cmd = [sys.executable, "-m", "repro.bench", "--worker", str(size), "--repeat", str(repeat),
           "--worker-preset", preset]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark of {preset} at {size}² failed:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _table(rows: list[dict]) -> str:
    stages = list(rows[0]["timings_s"].keys())
    head = ("| preset | size | edge px | " + " | ".join(f"{s} (s)" for s in stages)
            + " | peak RSS (GiB) | load 1-min (before → after) |")
    sep = "|" + "---|" * (len(stages) + 5)
    lines = [head, sep]
    for r in rows:
        cells = " | ".join(f"{r['timings_s'][s]:.3f}" if s in r["timings_s"] else "" for s in stages)
        load = r.get("load1")
        load = f"{load[0]:.1f} → {load[1]:.1f}" if load else "not recorded"
        lines.append(f"| {r.get('preset', 'paper')} | {r['size']}² | {r['edge_pixels']} | {cells} | "
                     f"{r['peak_rss_gib']:.2f} | {load} |")
    return "\n".join(lines)


def _summary(rows: list[dict]) -> dict:
    """Per preset: 1 MP / 512² totals and peak memory against the targets, and the 512² → 1024² growth."""
    summary = {}
    for preset in dict.fromkeys(r.get("preset", "paper") for r in rows):
        by_size = {r["size"]: r for r in rows if r.get("preset", "paper") == preset}
        if 1024 in by_size:
            r = by_size[1024]
            summary[f"{preset}: total_1mp_s"] = r["timings_s"]["total"]
            summary[f"{preset}: peak_1mp_gib"] = r["peak_rss_gib"]
            limit = TARGET_SECONDS_1MP_BY_PRESET.get(preset, TARGET_SECONDS_1MP)
            summary[f"{preset}: meets_time_target_1mp"] = r["timings_s"]["total"] <= limit
            summary[f"{preset}: meets_memory_target"] = r["peak_rss_gib"] <= TARGET_PEAK_GIB_1MP
        if 512 in by_size:
            summary[f"{preset}: total_512_s"] = by_size[512]["timings_s"]["total"]
            summary[f"{preset}: meets_time_target_512"] = by_size[512]["timings_s"]["total"] <= TARGET_SECONDS_512
        if 512 in by_size and 1024 in by_size:
            g = by_size[1024]["timings_s"]["total"] / by_size[512]["timings_s"]["total"]
            summary[f"{preset}: growth_512_to_1024"] = g
            summary[f"{preset}: meets_growth_target"] = g <= TARGET_GROWTH_512_TO_1024
    return summary


# --- accuracy benchmark (``--accuracy``) ------------------------------------------------------------
#
# The targets of the dense-map issue (robust preset). Module constants, read when the verdicts are
# computed (tests monkeypatch them); every pass/fail is computed from the measured numbers.

#: Dense textured MAE target, px, for bins whose tile σ ≤ TARGET_ABS_MAE_MAX_SIGMA px.
TARGET_DENSE_MAE_PX = 0.3
TARGET_ABS_MAE_MAX_SIGMA = 4.0
#: Dense textured MAE target as a fraction of σ_gt for TARGET_ABS_MAE_MAX_SIGMA < σ ≤ TARGET_REL_MAE_MAX_SIGMA.
TARGET_DENSE_REL_MAE = 0.10
TARGET_REL_MAE_MAX_SIGMA = 8.0
#: |mean signed error| target, max(TARGET_BIAS_PX, TARGET_BIAS_REL · σ_gt) px, in every bin whose
#: tile σ ≤ TARGET_BIAS_MAX_SIGMA px.
TARGET_BIAS_PX = 0.3
TARGET_BIAS_REL = 0.05
TARGET_BIAS_MAX_SIGMA = 8.0
#: Rendered scenes: robust dense textured MAE ≤ this × the paper preset's, per case and on the mean.
TARGET_RENDER_DENSE_RATIO = 0.5
#: Rendered (scene, f-number) whose robust sparse edge MAE must be ≤ the best baseline estimator's.
TARGET_SPARSE_CASE = ("portrait", 8.0)
#: Speed: robust whole-pipeline wall time ≤ this × the paper preset's at TARGET_SPEED_SIZE² px.
TARGET_SPEED_RATIO = 1.5
TARGET_SPEED_SIZE = 1024

#: Half-width (px) of the band masked on each side of the step-edge mosaic's tile seams.
STEP_SEAM_BAND_PX = 6
#: Normal angle θ (rad) of the step-edge mosaic's first tile; the others are its mirror images.
STEP_BASE_ANGLE = math.pi / 6

ANALYTIC_DATASETS = ("dead_leaves", "skimage", "step_edges")

#: What ``--accuracy`` measures (see :func:`run_accuracy`); tests pass a smaller dict.
ACCURACY_CONFIG = {
    "datasets": ANALYTIC_DATASETS,
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
}


def _noise_label(noise_std: float) -> str:
    return f"{noise_std * 255:.3g}/255"


def _sigma_bins(values) -> tuple:
    """Bin edges (px) putting each distinct value in its own half-open bin: 0, midpoints, inf."""
    v = sorted({float(x) for x in values})
    return (0.0, *((a + b) / 2.0 for a, b in zip(v[:-1], v[1:])), math.inf)


def _step_mosaic(sigmas, tile: int, noise_std: float, seed: int):
    """Mosaic of straight blurred step edges: 2 rows x len(sigmas) tiles of ``tile``² px.

    Column c holds :func:`scenes.analytic.step_edge` with σ = sigmas[c] through the tile centre, normal
    angle θ (row 0) / −θ (row 1), θ = :data:`STEP_BASE_ANGLE`, mirrored (π − angle) in odd columns, so
    every tile is the mirror image of its neighbours and the noise-free image is continuous across
    seams (only σ changes there). Then 8-bit + Gaussian noise (:func:`scenes.analytic.degrade`).

    Returns
    -------
    image : ndarray, (2·tile) x (len(sigmas)·tile), float in [0, 1]
    sigma_gt : ndarray, same shape, px (the tile's σ)
    valid : ndarray of bool, same shape; False within STEP_SEAM_BAND_PX of a seam
    """
    import numpy as np

    from scenes.analytic import degrade, step_edge

    rows = []
    for base in (STEP_BASE_ANGLE, -STEP_BASE_ANGLE):
        angles = [base if c % 2 == 0 else math.pi - base for c in range(len(sigmas))]
        rows.append(np.concatenate([step_edge((tile, tile), sigma=float(s), angle=a).image
                                    for s, a in zip(sigmas, angles)], axis=1))
    image = degrade(np.concatenate(rows, axis=0), noise_std=noise_std, quantize_bits=8,
                    rng=np.random.default_rng(seed))
    h, w = image.shape
    sigma_gt = np.broadcast_to(np.repeat(np.asarray(sigmas, dtype=np.float64), tile)[None, :], (h, w)).copy()

    def near_seam(n):  # pixel centres k + ½ within the band of an interior seam at multiples of tile
        k = np.arange(n) + 0.5
        d = np.abs(k - tile * np.round(k / tile))
        inner = (np.round(k / tile) > 0) & (np.round(k / tile) < n // tile)
        return inner & (d < STEP_SEAM_BAND_PX)

    valid = ~(near_seam(h)[:, None] | near_seam(w)[None, :])
    return image, sigma_gt, valid


def _analytic_case(dataset: str, config: dict, noise_std: float, seed: int) -> dict:
    """Image, σ_gt, valid mask and per-tile (nominal σ, σ_gt) of one analytic test image."""
    import numpy as np

    sigmas = tuple(float(s) for s in config["sigmas"])
    if dataset == "step_edges":
        image, gt, valid = _step_mosaic(sigmas, config["tile"], noise_std, seed)
        return {"image": image, "sigma_gt": gt, "valid": valid, "nominal": tuple(sorted(set(sigmas))),
                "gt": tuple(sorted(set(sigmas))), "intrinsic_sigma": 0.0}
    if dataset not in ("dead_leaves", "skimage"):
        raise ValueError(f"dataset={dataset!r} is invalid; allowed: {', '.join(ANALYTIC_DATASETS)}")
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(texture=dataset, sigmas=sigmas, tile=config["tile"], cols=config["mosaic_cols"],
                       noise_std=noise_std, quantize_bits=8, rng=seed)
    nominal = tuple(sorted(set(sigmas)))  # one bin per distinct tile σ, in the bins' order
    gt = tuple(float(np.sqrt(s ** 2 + m.intrinsic_sigma ** 2)) for s in nominal)
    return {"image": m.image, "sigma_gt": m.sigma, "valid": ~m.boundary, "nominal": nominal, "gt": gt,
            "intrinsic_sigma": float(m.intrinsic_sigma)}


def _slim(err, nominal=None, gt=None) -> dict | None:
    """The parts of one :func:`experiments.stage_attribution.stage_errors` entry the report keeps."""
    if not err:
        return None
    out = {k: err[k] for k in ("n", "mae", "bias", "coverage")}
    if nominal is not None:
        out["bins"] = [{"sigma": s, "sigma_gt": g, "lo": b["lo"], "hi": b["hi"], "n": b["n"], "mae": b["mae"],
                        "bias": b["bias"]} for s, g, b in zip(nominal, gt, err["bins"])]
    return out


def _pool(entries) -> dict:
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


def _preset_seeds(config: dict, preset: str) -> tuple:
    return tuple(config.get("preset_seeds", {}).get(preset, config["seeds"]))


def _measure_analytic(config: dict, bar) -> dict:
    import time as _time
    import warnings

    from experiments.stage_attribution import stage_errors
    from method import DefocusParams

    runs = []
    for dataset in config["datasets"]:
        for noise in config["noise_stds"]:
            for seed in config["seeds"]:
                presets = [p for p in config["presets"] if seed in _preset_seeds(config, p)]
                if not presets:
                    continue
                case = _analytic_case(dataset, config, float(noise), int(seed))
                bins = _sigma_bins(case["gt"])
                for preset in presets:
                    bar.set_postfix_str(f"{dataset} {_noise_label(noise)} seed {seed} {preset}")
                    t = _time.perf_counter()
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        err = stage_errors(case["image"], case["sigma_gt"], params=DefocusParams.preset(preset),
                                           valid=case["valid"], bins=bins)
                    est = err["estimated"]
                    runs.append({
                        "dataset": dataset, "noise_std": float(noise), "seed": int(seed), "preset": preset,
                        "shape": list(case["image"].shape[:2]), "intrinsic_sigma": case["intrinsic_sigma"],
                        "dense_textured": _slim(est["dense_textured"], case["nominal"], case["gt"]),
                        "sparse": _slim(est["sparse"], case["nominal"], case["gt"]),
                        "oracle_propagate_dense_textured": _slim(err["oracle_propagate"].get("dense_textured"),
                                                                  case["nominal"], case["gt"]),
                        "n_edges": err["n_edges"], "seconds": _time.perf_counter() - t})
                    bar.update(1)
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
                               **{k: _pool([r[k] for r in sel])
                                  for k in ("dense_textured", "sparse", "oracle_propagate_dense_textured")}})
    return {"runs": runs, "pooled": pooled}


def _measure_rendered(config: dict, bar) -> dict:
    import time as _time
    import warnings

    from experiments.evaluation import ground_truth_sigma, input_image
    from experiments.stage_attribution import stage_errors
    from method import DefocusParams
    from scenes import render_scene

    cases = []
    for scene_set, scene in ((k, v) for k, scenes in config["scene_sets"].items() for v in scenes):
        for f_number in config["f_numbers"]:
            render = render_scene(scene, preset=config["render_preset"], f_number=float(f_number), progress=False)
            image, gt = input_image(render), ground_truth_sigma(render)
            valid = ~render.occlusion_boundary
            runs = [("presets", p, DefocusParams.preset(p)) for p in config["presets"]]
            runs += [("estimators", e, DefocusParams().replace(estimator=e)) for e in config["estimators"]]
            case = {"scene_set": scene_set, "scene": scene, "f_number": float(f_number),
                    "shape": list(image.shape[:2]), "presets": {}, "estimators": {}}
            for kind, name, params in runs:
                bar.set_postfix_str(f"{scene} f/{f_number:g} {name}")
                t = _time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    est = stage_errors(image, gt, params=params, valid=valid)["estimated"]
                case[kind][name] = {"dense_textured": _slim(est["dense_textured"]), "sparse": _slim(est["sparse"]),
                                    "seconds": _time.perf_counter() - t}
                bar.update(1)
            cases.append(case)
    return {"cases": cases}


def _measure_speed(config: dict, bar) -> dict:
    import statistics
    import time as _time
    import warnings

    from method import DefocusParams, estimate_defocus_map

    plan = [(p, s, config["speed_repeat"]) for p in config["speed_presets"] for s in config["speed_sizes"]]
    plan += [(p, s, 1) for p, sizes in config["speed_single"].items() for s in sizes]
    images, rows = {}, []
    for preset, size, repeat in plan:
        if size not in images:
            images[size] = _test_image(size)
        params = DefocusParams.preset(preset)
        load_before, runs, totals = os.getloadavg(), [], []
        for _ in range(repeat):
            bar.set_postfix_str(f"{preset} {size}²")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t = _time.perf_counter()
                result = estimate_defocus_map(images[size], params)
                runs.append(_time.perf_counter() - t)
            totals.append(result.timings["total"])
            bar.update(1)
        rows.append({"preset": preset, "size": size, "runs_s": runs, "median_s": statistics.median(runs),
                     "pipeline_total_s": totals, "load_before": list(load_before),
                     "load_after": list(os.getloadavg())})
    return {"rows": rows}


def _bin_verdict(b: dict) -> dict:
    """Targets of one robust σ bin (chosen by the tile σ) and whether its numbers meet them."""
    s = b["sigma"]
    if s <= TARGET_ABS_MAE_MAX_SIGMA:
        mae_limit = TARGET_DENSE_MAE_PX
    elif s <= TARGET_REL_MAE_MAX_SIGMA:
        mae_limit = TARGET_DENSE_REL_MAE * b["sigma_gt"]
    else:
        mae_limit = None
    bias_limit = max(TARGET_BIAS_PX, TARGET_BIAS_REL * b["sigma_gt"]) if s <= TARGET_BIAS_MAX_SIGMA else None
    out = {"sigma": s, "mae_limit": mae_limit, "bias_limit": bias_limit, "mae_ok": None, "bias_ok": None}
    if mae_limit is None and bias_limit is None:
        out["pass"] = None  # no target in this bin
        return out
    if not b["n"]:
        out["pass"] = False  # a targeted bin without a single estimate fails
        return out
    if mae_limit is not None:
        out["mae_ok"] = bool(b["mae"] <= mae_limit)
    if bias_limit is not None:
        out["bias_ok"] = bool(abs(b["bias"]) <= bias_limit)
    out["pass"] = all(v for v in (out["mae_ok"], out["bias_ok"]) if v is not None)
    return out


def _all_pass(flags) -> bool | None:
    flags = [f for f in flags if f is not None]
    return all(flags) if flags else None


def judge_accuracy(measured: dict) -> dict:
    """Pass/fail of every target from the measured numbers (``measured`` as :func:`measure_accuracy`).

    Returns
    -------
    dict
        ``analytic`` (per dataset x noise: per-bin verdicts of the robust preset, and ``pass``),
        ``rendered`` (per case and on the mean: robust ≤ ratio x paper dense MAE; the sparse case),
        ``speed`` (robust / paper at TARGET_SPEED_SIZE²) and ``overall``; ``pass`` is None where a
        target could not be evaluated (e.g. the robust or paper preset was not run).
    """
    out = {"analytic": [], "rendered": {}, "speed": {}}
    for group in measured.get("analytic", {}).get("pooled", []):
        if group["preset"] != "robust":
            continue
        bins = [_bin_verdict(b) for b in group["dense_textured"].get("bins", [])]
        out["analytic"].append({"dataset": group["dataset"], "noise_std": group["noise_std"], "bins": bins,
                                "pass": _all_pass(b["pass"] for b in bins)})
    cases = measured.get("rendered", {}).get("cases", [])
    per_case = []
    for c in cases:
        p, r = (c["presets"].get(k, {}).get("dense_textured") for k in ("paper", "robust"))
        ok = None
        if p and r and p["mae"] is not None and r["mae"] is not None:
            ok = bool(r["mae"] <= TARGET_RENDER_DENSE_RATIO * p["mae"])
        per_case.append({"scene_set": c.get("scene_set"), "scene": c["scene"], "f_number": c["f_number"],
                         "ratio": r["mae"] / p["mae"] if ok is not None and p["mae"] > 0 else None, "pass": ok})
    sets = {}
    for name in dict.fromkeys(c.get("scene_set") for c in cases):
        mine = [c for c in cases if c.get("scene_set") == name]
        verdicts = [v for v in per_case if v["scene_set"] == name]
        mean = None
        if verdicts and all(v["pass"] is not None for v in verdicts):
            mp = sum(c["presets"]["paper"]["dense_textured"]["mae"] for c in mine) / len(mine)
            mr = sum(c["presets"]["robust"]["dense_textured"]["mae"] for c in mine) / len(mine)
            mean = {"paper_mae": mp, "robust_mae": mr, "ratio": mr / mp if mp > 0 else None,
                    "pass": bool(mr <= TARGET_RENDER_DENSE_RATIO * mp)}
        sets[name] = {"cases": verdicts, "mean": mean,
                      "pass": _all_pass([v["pass"] for v in verdicts] + ([mean["pass"]] if mean else [None]))}
    rendered = {"cases": per_case, "sets": sets, "sparse": None}
    scene, f_number = TARGET_SPARSE_CASE
    for c in cases:
        if (c["scene"], c["f_number"]) == (scene, float(f_number)) and "robust" in c["presets"] and c["estimators"]:
            rob = c["presets"]["robust"]["sparse"]["mae"]
            base = {k: v["sparse"]["mae"] for k, v in c["estimators"].items() if v["sparse"]["mae"] is not None}
            if rob is not None and base:
                best = min(base, key=base.get)
                rendered["sparse"] = {"scene": scene, "f_number": float(f_number), "robust_mae": rob,
                                      "best_estimator": best, "best_mae": base[best], "pass": bool(rob <= base[best])}
    rendered["pass"] = _all_pass([v["pass"] for v in sets.values()]
                                 + ([rendered["sparse"]["pass"]] if rendered["sparse"] else []))
    out["rendered"] = rendered
    rows = {(r["preset"], r["size"]): r for r in measured.get("speed", {}).get("rows", [])}
    paper, robust = rows.get(("paper", TARGET_SPEED_SIZE)), rows.get(("robust", TARGET_SPEED_SIZE))
    if paper and robust:
        ratio = robust["median_s"] / paper["median_s"]
        out["speed"] = {"size": TARGET_SPEED_SIZE, "ratio": ratio, "pass": bool(ratio <= TARGET_SPEED_RATIO)}
    else:
        out["speed"] = {"size": TARGET_SPEED_SIZE, "ratio": None, "pass": None}
    analytic_ok = _all_pass(g["pass"] for g in out["analytic"])
    out["analytic_pass"] = analytic_ok
    out["overall"] = _all_pass([analytic_ok, rendered["pass"], out["speed"]["pass"]])
    return out


def measure_accuracy(config: dict, *, progress: bool = True) -> dict:
    """Run every measurement of ``config`` (keys as :data:`ACCURACY_CONFIG`); no verdicts, no files."""
    from tqdm import tqdm

    n_analytic = len(config["datasets"]) * len(config["noise_stds"]) * sum(
        len(set(_preset_seeds(config, p)) & set(config["seeds"])) for p in config["presets"])
    n_render = sum(len(v) for v in config["scene_sets"].values()) * len(config["f_numbers"]) * (len(config["presets"]) + len(config["estimators"]))
    n_speed = (len(config["speed_presets"]) * len(config["speed_sizes"]) * config["speed_repeat"]
               + sum(len(s) for s in config["speed_single"].values()))
    out = {}
    with tqdm(total=n_analytic, desc="accuracy: analytic", unit="run", disable=not progress or not n_analytic) as bar:
        out["analytic"] = _measure_analytic(config, bar) if n_analytic else {"runs": [], "pooled": []}
    with tqdm(total=n_render, desc="accuracy: renders", unit="run", disable=not progress or not n_render) as bar:
        out["rendered"] = _measure_rendered(config, bar) if n_render else {"cases": []}
    with tqdm(total=n_speed, desc="accuracy: speed", unit="run", disable=not progress or not n_speed) as bar:
        out["speed"] = _measure_speed(config, bar) if n_speed else {"rows": []}
    return out


def _targets() -> dict:
    return {"dense_mae_px": TARGET_DENSE_MAE_PX, "abs_mae_max_sigma_px": TARGET_ABS_MAE_MAX_SIGMA,
            "dense_rel_mae": TARGET_DENSE_REL_MAE, "rel_mae_max_sigma_px": TARGET_REL_MAE_MAX_SIGMA,
            "bias_px": TARGET_BIAS_PX, "bias_rel": TARGET_BIAS_REL, "bias_max_sigma_px": TARGET_BIAS_MAX_SIGMA,
            "render_dense_ratio": TARGET_RENDER_DENSE_RATIO, "sparse_case": list(TARGET_SPARSE_CASE),
            "speed_ratio": TARGET_SPEED_RATIO, "speed_size": TARGET_SPEED_SIZE}


def _json_safe(obj):
    """Non-finite floats → None, tuples → lists, NumPy scalars → Python (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _f(x, fmt=".2f") -> str:
    return "–" if x is None else format(x, fmt)


def _word(ok) -> str:
    return "n/a" if ok is None else ("pass" if ok else "FAIL")


def _bin_cell(v: dict) -> str:
    if v["pass"] is None:
        return "n/a"
    if v["pass"]:
        return "pass"
    why = [k for k, ok in (("MAE", v["mae_ok"]), ("bias", v["bias_ok"])) if ok is False]
    return "FAIL" + (f" ({'+'.join(why)})" if why else " (no pixels)")


def _seeds_text(cfg: dict) -> str:
    text = ", ".join(str(s) for s in cfg["seeds"])
    cut = [f"{p}: {', '.join(str(s) for s in _preset_seeds(cfg, p))} only" for p in cfg["presets"]
           if set(_preset_seeds(cfg, p)) != set(cfg["seeds"])]
    return text + (f" ({'; '.join(cut)}, to bound the run time)" if cut else "")


def accuracy_markdown(report: dict) -> str:
    """The Markdown of ``accuracy.md`` from a :func:`run_accuracy` report."""
    cfg, verdict = report["config"], report["verdict"]
    lines = [f"# Accuracy benchmark ({report['date']}, {report['machine']['cpus']} CPUs, "
             f"{report['runtime_s'] / 60:.1f} min)", "",
             "`python -m repro.bench --accuracy`. Targets of the dense-map issue, for the robust preset; "
             "every pass/fail is computed from the numbers below.", "",
             f"**Overall: {_word(verdict['overall'])}** (analytic truth: {_word(verdict['analytic_pass'])}, "
             f"rendered scenes: {_word(verdict['rendered']['pass'])}, speed: {_word(verdict['speed']['pass'])})", ""]
    for note in report["notes"]:
        lines.append(f"- {note}")
    lines.append("")
    lines += ["## 1. Analytic truth (8 bits + Gaussian noise)", "",
              "Dense map over textured valid pixels (`stage_errors` → estimated → `dense_textured`), one bin "
              "per tile σ: cells are MAE / mean signed error (px), pooled over seeds "
              f"{_seeds_text(cfg)} (pixel-weighted). `all` = every bin; `oracle` = "
              "the dense MAE when σ_gt itself is fed at the detected edges into Eq. (4) (`oracle_propagate`), "
              "the propagation's own floor; `sparse` = MAE of the edge measures (coverage = share of valid edge "
              "pixels with a measure).",
              f"Targets (robust): MAE ≤ {TARGET_DENSE_MAE_PX:g} px for σ ≤ {TARGET_ABS_MAE_MAX_SIGMA:g}; "
              f"≤ {TARGET_DENSE_REL_MAE:.0%} of σ_gt for {TARGET_ABS_MAE_MAX_SIGMA:g} < σ ≤ "
              f"{TARGET_REL_MAE_MAX_SIGMA:g}; |mean signed error| ≤ max({TARGET_BIAS_PX:g} px, {TARGET_BIAS_REL:.0%} of σ_gt) for σ ≤ "
              f"{TARGET_BIAS_MAX_SIGMA:g} px; no target above. Row `target` gives MAE limit / |bias| limit.", ""]
    pooled = report["analytic"]["pooled"]
    verdicts = {(v["dataset"], v["noise_std"]): v for v in verdict["analytic"]}
    for dataset in cfg["datasets"]:
        groups = [g for g in pooled if g["dataset"] == dataset]
        if not groups:
            continue
        title = {"dead_leaves": "Dead-leaves texture mosaic",
                 "skimage": "skimage-photo mosaic (σ_gt = √(σ² + σ₀²), σ₀ assumed)",
                 "step_edges": "Step-edge mosaic"}[dataset]
        shape = next(r["shape"] for r in report["analytic"]["runs"] if r["dataset"] == dataset)
        lines += [f"### {title}, {shape[0]}×{shape[1]} px", ""]
        bins = groups[0]["dense_textured"]["bins"]
        heads = [f"σ {b['sigma']:g}" + (f" ({b['sigma_gt']:.2f})" if abs(b["sigma_gt"] - b["sigma"]) > 1e-9 else "")
                 for b in bins]
        lines += ["| noise | preset | " + " | ".join(heads) + " | all | oracle | sparse (coverage) |",
                  "|---|---|" + "---|" * (len(bins) + 3)]
        shown_target = False
        for g in groups:
            v = verdicts.get((dataset, g["noise_std"])) if g["preset"] == "robust" else None
            if v and not shown_target:
                cells = [("–" if b["mae_limit"] is None else f"≤{b['mae_limit']:.2f}") + " / "
                         + ("–" if b["bias_limit"] is None else f"±{b['bias_limit']:.2f}") for b in v["bins"]]
                lines.append("| | target | " + " | ".join(cells) + " | | | |")
                shown_target = True
            d, sp = g["dense_textured"], g["sparse"]
            cells = [f"{_f(b['mae'])} / {_f(b['bias'], '+.2f')}" for b in d["bins"]]
            cov = [r["sparse"]["coverage"] for r in report["analytic"]["runs"]
                   if (r["dataset"], r["noise_std"], r["preset"]) == (dataset, g["noise_std"], g["preset"])]
            oracle = (g["oracle_propagate_dense_textured"] or {}).get("mae")
            lines.append(f"| {_noise_label(g['noise_std'])} | {g['preset']} | " + " | ".join(cells)
                         + f" | {_f(d['mae'])} / {_f(d['bias'], '+.2f')} | {_f(oracle)} | {_f(sp['mae'])} "
                         f"({_f(sum(cov) / len(cov), '.0%') if cov and None not in cov else '–'}) |")
            if v:
                lines.append(f"| {_noise_label(g['noise_std'])} | **robust verdict** | "
                             + " | ".join(_bin_cell(b) for b in v["bins"]) + f" | **{_word(v['pass'])}** | | |")
        lines.append("")
    cases = report["rendered"]["cases"]
    if cases:
        rv = verdict["rendered"]
        presets = list(cases[0]["presets"])
        ests = list(cases[0]["estimators"])
        lines += [f"## 2. Rendered scenes ({cfg['render_preset']} preset, "
                  f"{cases[0]['shape'][1]}×{cases[0]['shape'][0]} px, 8-bit sRGB), one table per scene set", "",
                  "Dense textured MAE and sparse edge MAE (px) over valid pixels (not occlusion boundaries); "
                  "sparse coverage in brackets; estimators run in the paper pipeline. "
                  f"Targets: robust dense ≤ {TARGET_RENDER_DENSE_RATIO:g} × paper per case and on each set's mean; "
                  f"robust sparse MAE on {TARGET_SPARSE_CASE[0]} f/{TARGET_SPARSE_CASE[1]:g} ≤ min over "
                  f"{', '.join(ests) or 'the estimators'}.", ""]
        by_case = {(v["scene_set"], v["scene"], v["f_number"]): v for v in rv["cases"]}
        for name, sv in rv.get("sets", {}).items():
            mine = [c for c in cases if c.get("scene_set") == name]
            lines += [f"### Scene set `{name}` — **{_word(sv['pass'])}**", "",
                      "| scene | f/N | " + " | ".join(f"dense {p}" for p in presets) + " | robust/paper | verdict | "
                      + " | ".join(f"sparse {p}" for p in presets + ests) + " |",
                      "|---|---|" + "---|" * (2 * len(presets) + len(ests) + 2)]
            for c in mine:
                v = by_case[(name, c["scene"], c["f_number"])]
                runs = [c["presets"][p] for p in presets] + [c["estimators"][e] for e in ests]
                lines.append(f"| {c['scene']} | {c['f_number']:g} | "
                             + " | ".join(_f(c["presets"][p]["dense_textured"]["mae"]) for p in presets)
                             + f" | {_f(v['ratio'])} | {_word(v['pass'])} | "
                             + " | ".join(f"{_f(r['sparse']['mae'])} ({_f(r['sparse']['coverage'], '.0%')})"
                                          for r in runs)
                             + " |")
            means = [sum(c["presets"][p]["dense_textured"]["mae"] or 0.0 for c in mine) / len(mine) for p in presets]
            m = sv["mean"] or {}
            lines += ["| **mean** | | " + " | ".join(_f(x) for x in means)
                      + f" | {_f(m.get('ratio'))} | **{_word(m.get('pass'))}** | "
                      + " | ".join("" for _ in presets + ests) + " |", ""]
        s = rv["sparse"]
        if s:
            lines += [f"Sparse target, {s['scene']} f/{s['f_number']:g}: robust {s['robust_mae']:.3f} px vs "
                      f"best estimator {s['best_estimator']} {s['best_mae']:.3f} px → **{_word(s['pass'])}**."]
        lines.append("")
    rows = report["speed"]["rows"]
    if rows:
        sv = verdict["speed"]
        lines += ["## 3. Speed (whole pipeline, astronaut test image as `python -m repro.bench`)", "",
                  "Wall time of `estimate_defocus_map` (no magnification), median of the runs, in this process "
                  "after the accuracy runs (numba cache warm); load = 1/5/15-min load average before → after.", "",
                  "| preset | size | median (s) | runs (s) | load before | load after |", "|---|---|---|---|---|---|"]
        for r in rows:
            lines.append(f"| {r['preset']} | {r['size']}² | {r['median_s']:.2f} | "
                         + ", ".join(f"{t:.2f}" for t in r["runs_s"])
                         + f" | {' / '.join(f'{x:.2f}' for x in r['load_before'])} | "
                         f"{' / '.join(f'{x:.2f}' for x in r['load_after'])} |")
        lines += ["", f"Target robust ≤ {TARGET_SPEED_RATIO:g} × paper at {sv['size']}²: "
                  f"ratio {_f(sv['ratio'])} → "
                  f"**{_word(sv['pass'])}**.", ""]
    return "\n".join(lines)


def run_accuracy(config: dict | None = None, *, out: Path, progress: bool = True) -> dict:
    """Measure, judge and write ``accuracy.json`` / ``accuracy.md`` to ``out`` (atomically).

    Parameters
    ----------
    config : dict, optional
        Keys as :data:`ACCURACY_CONFIG` (the default); empty ``datasets`` / ``scenes`` /
        ``speed_presets`` and ``speed_single`` skip that part.
    out : Path, keyword-only
        Output folder (created).
    progress : bool, keyword-only
        tqdm progress bars.

    Returns
    -------
    dict
        The report written to ``accuracy.json`` (``config``, ``analytic``, ``rendered``, ``speed``,
        ``verdict``, ``targets``, ``notes``, ``machine``, ``date``, ``runtime_s``).

    Notes
    -----
    1. Analytic truth, per dataset x noise x seed: the image (:func:`_analytic_case`), bins with one
       tile σ_gt each, then :func:`experiments.stage_attribution.stage_errors` for every preset.
    2. Rendered scenes: cached renders, σ_gt in the line-spread convention, occlusion boundaries
       excluded; every preset and every estimator (paper pipeline) through ``stage_errors``.
    3. Speed: :func:`_test_image` at each size, median wall time, load averages around it.
    4. Verdicts (:func:`judge_accuracy`) from the numbers and the TARGET_* constants.
    """
    from scenes.analytic import SKIMAGE_INTRINSIC_SIGMA_PX
    from defocus_cache import atomic_write_text

    from method import PRESETS

    cfg = dict(ACCURACY_CONFIG if config is None else config)
    for p in list(cfg["presets"]) + list(cfg["speed_presets"]) + list(cfg["speed_single"]):
        if p not in PRESETS:
            raise ValueError(f"preset {p!r} is invalid; allowed: {sorted(PRESETS)}")
    t0 = time.perf_counter()
    load0 = os.getloadavg()
    measured = measure_accuracy(cfg, progress=progress)
    verdict = judge_accuracy(measured)
    notes = [f"skimage mosaics: σ_gt = √(σ² + σ₀²) with σ₀ = {SKIMAGE_INTRINSIC_SIGMA_PX:.3f} px, "
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
             f"Noise: {', '.join(_noise_label(n) for n in cfg['noise_stds'])} then 8-bit quantisation; seeds "
             f"{_seeds_text(cfg)}; the noise field of a seed is the same for both levels (scaled).",
             f"Machine load (1/5/15 min) at start: {' / '.join(f'{x:.2f}' for x in load0)}; "
             f"at end: {' / '.join(f'{x:.2f}' for x in os.getloadavg())}."]
    report = {"config": cfg, **measured, "verdict": verdict, "targets": _targets(), "notes": notes,
              "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                          "platform": platform.platform()},
              "date": time.strftime("%Y-%m-%d %H:%M:%S"), "runtime_s": time.perf_counter() - t0}
    report = _json_safe(report)
    md = accuracy_markdown(report)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "accuracy.json", json.dumps(report, indent=1, allow_nan=False))
    atomic_write_text(out / "accuracy.md", md + "\n")
    return report


PROG = "python -m repro.bench"


def main(argv=None) -> int:
    from repro._cli import ArgumentParser, add_quiet_option, int_type, require_extras

    parser = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int_type("--sizes", minimum=16), nargs="+", default=[256, 512, 1024],
                        help="image sides, px (>= 16)")
    parser.add_argument("--repeat", type=int_type("--repeat"), default=3, help="runs per size; the fastest counts")
    add_quiet_option(parser, what="no progress display")
    parser.add_argument("--out", type=Path, default=Path("report") / "bench", help="output folder")
    parser.add_argument("--accuracy", action="store_true",
                        help="record the dense-map accuracy targets (accuracy.md / accuracy.json) instead")
    parser.add_argument("--sweep", action="store_true",
                        help="benchmark the sweep engine instead (cells/minute for 1 and 2 workers, engine overhead "
                             "per cell; sweep.md / sweep.json)")
    parser.add_argument("--presets", nargs="+", default=list(BENCH_PRESETS),
                        help=f"presets to time (default: {' '.join(BENCH_PRESETS)})")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--worker-preset", default="paper", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker is not None:
        print(json.dumps(_worker(args.worker, args.repeat, args.worker_preset)))
        return 0
    if args.accuracy:
        require_extras("render", command="repro.bench --accuracy")
        run_accuracy(out=args.out)  # a ValueError is one line + exit 2 (repro._cli.run_cli)
        print((args.out / "accuracy.md").read_text(encoding="utf-8"))
        return 0
    if args.sweep:
        require_extras("sweep", "render", command="repro.bench --sweep")
        from repro.sweep import run_sweep_bench

        run_sweep_bench(args.out)
        print((args.out / "sweep.md").read_text(encoding="utf-8"))
        return 0
    from tqdm import tqdm

    from defocus_cache import atomic_write_text

    from method import PRESETS

    unknown = [p for p in args.presets if p not in PRESETS]
    if unknown:
        raise ValueError(f"--presets {' '.join(unknown)} is invalid; allowed: {', '.join(PRESETS)}")
    before = None
    try:  # the run this one replaces, kept as "before"
        before = json.loads((args.out / "bench.json").read_text(encoding="utf-8"))
        before = {"date": before["date"], "rows": before["rows"], "summary": before["summary"]}
    except (OSError, ValueError, KeyError, TypeError):
        before = None
    jobs = [(p, s) for p in args.presets for s in args.sizes]
    rows = [_run_size(s, args.repeat, p) for p, s in tqdm(jobs, desc="bench runs", unit="run", disable=args.quiet)]
    summary = _summary(rows)
    report = {
        "rows": rows,
        "summary": summary,
        "before": before,
        "targets": {"total_1mp_s": TARGET_SECONDS_1MP, "total_512_s": TARGET_SECONDS_512,
                    "peak_1mp_gib": TARGET_PEAK_GIB_1MP, "growth_512_to_1024": TARGET_GROWTH_512_TO_1024},
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    table = _table(rows)
    md = (f"# Benchmark ({report['date']}, {os.cpu_count()} CPUs)\n\n"
          "Whole-pipeline `total` excludes magnification (timed separately); fastest of "
          f"{args.repeat} runs; peak RSS of the whole worker process.\n\n{table}\n\n"
          + "\n".join(f"- {k}: {v:.3f}" if isinstance(v, float) else f"- {k}: {v}" for k, v in summary.items())
          + "\n")
    if before:
        md += (f"\n## Before: the previous run ({before['date']})\n\n{_table(before['rows'])}\n\n"
               + "\n".join(f"- {k}: {v:.3f}" if isinstance(v, float) else f"- {k}: {v}"
                            for k, v in before["summary"].items()) + "\n")
    atomic_write_text(args.out / "bench.json", json.dumps(report, indent=1))
    atomic_write_text(args.out / "bench.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
