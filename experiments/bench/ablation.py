"""The robust preset's ablation, judged on three sets at once: lens blur, the paper's cameras, real photos.

A cue beyond the paper stays in ``robust`` only where it improves all three (docs/presets.md):

* **lens bench** — :mod:`experiments.bench.lens` mosaics of every texture family and straight steps,
  disk PSF in linear light, ISO 100 noise, sRGB, 8 bits: mean dense textured MAE over families and
  tile σ 1–8 px, and the number of (family, σ) cells over the dense-map target;
* **renders** — the ``paper_cameras`` scenes at the full preset, f/8, f/4 and f/2 (the sweep's cells,
  :func:`experiments.sweep_cells.cell_task`): dense textured MAE per scene and aperture;
* **real photos** — the shipped photos with hand-drawn regions (:mod:`experiments.photo_regions`):
  ranking AUC and the in-focus share above the defocused median;
* **procedural scenes** — shown beside them: the first 8 scenes of the ``dev`` split
  (:mod:`scenes.library.procedural`), small renders, f/8, f/4, f/2, mean dense textured MAE. Dev only:
  choices are made here; the held-out ``test`` split is not printed beside every variant, and a change is
  judged once on unseen scenes (``python -m repro.compare robust VARIANT --procedural N --split fresh``).

Each row is ``robust`` with some fields changed (:data:`ABLATION_ROWS`); ``python -m repro.bench
--ablation`` writes ``ablation.json`` and ``ablation.md``.
"""

from __future__ import annotations

import time
import warnings

__all__ = ["ABLATION_CONFIG", "ABLATION_ROWS", "ablation_markdown", "ablation_report"]


def _rows():
    from method.presets import REGION_CUE_CHANGES

    return {
        "robust": {},
        "− linear light (edges in display values)": {"measure_light": "display"},
        "+ region cue as fused before (Gaussian model, no gate)": dict(REGION_CUE_CHANGES),
        "+ region cue, disk model + adequacy gate": {**REGION_CUE_CHANGES, "region_psf": "disk",
                                                     "region_gate": "adequacy"},
        "+ edge isolation weights": {"edge_isolation": "normal"},
        "− plateau gate (shading bands measured as blur)": {"fit_step_gate": "none"},
        "fit_max_scale 3 px (instead of 2)": {"fit_max_scale": 3.0},
        "− noise allowance, Eq. (3) with the sharpness bias, σs 10 %": {
            "fit_residual_noise": 0.0, "relaxed_fit_weight": 1.0, "sharpness_bias": True,
            "bilateral_sigma_spatial": 0.1},
        "− noise allowance, Eq. (3) as the paper": {
            "fit_residual_noise": 0.0, "relaxed_fit_weight": 1.0, "sharpness_bias": True,
            "bilateral_sigma_spatial": 0.1, "bilateral_range_kernel": "sum"},
    }


#: Row label -> changes to the robust preset (the paper preset is always the last row).
ABLATION_ROWS = _rows()

#: What each column runs.
ABLATION_CONFIG = {
    "lens": {"psf": "disk", "noise": "iso100", "seed": 0, "sigma_range": (1.0, 8.0)},
    "scenes": ("portrait_garden", "street_figures", "patio_table", "heron_at_the_lake"),
    "f_numbers": (8.0, 4.0, 2.0),
    "scene_preset": "full",
    "photos": None,  # every shipped photo
    # procedural scenes (scenes.library.procedural): the first seeds of the dev split (tune here; never
    # the held-out test split), small renders, f/8 f/4 f/2
    "procedural": {"dev": tuple(range(8)), "scene_preset": "small"},
}


def _lens_column(changes: dict, cfg: dict, cases: dict) -> dict:
    from experiments.stage_attribution import stage_errors
    from method import DefocusParams

    from .lens import LENS_TARGETS
    from .mosaics import sigma_bins

    params = DefocusParams.preset("robust", **changes) if changes is not None else DefocusParams.preset("paper")
    lo, hi = cfg["lens"]["sigma_range"]
    maes, fails = [], 0
    for fam, case in cases.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            err = stage_errors(case["image"], case["sigma_gt"], params=params, valid=case["valid"],
                               bins=sigma_bins(case["gt"]), oracles=False)["estimated"]
        for s, g, b in zip(case["nominal"], case["gt"], err["dense_textured"]["bins"]):
            if not (lo <= s <= hi) or not b["n"] or fam == "step_edges":
                continue
            maes.append(b["mae"])
            limit = LENS_TARGETS["dense_mae_px"] if s <= 4.0 else LENS_TARGETS["dense_rel_mae"] * g
            fails += b["mae"] > limit
    return {"mean_mae": sum(maes) / len(maes) if maes else None, "cells": len(maes), "fails": int(fails)}


def _render_column(changes, cfg: dict, renders: dict) -> dict:
    from experiments.sweep_cells import cell_task

    out = {}
    for (scene, f_number), info in renders.items():
        preset, ch = ("robust", changes) if changes is not None else ("paper", {})
        cell = cell_task(info, scene=scene, f_number=f_number, scene_preset=cfg["scene_preset"], camera=None,
                         seed=0, method_preset=preset, estimator=None, param_changes=ch, encoding="srgb")
        out[f"{scene} f/{f_number:g}"] = cell["metrics"]["dense_textured_mae"]
    return out


def _procedural_column(changes, renders: dict) -> dict:
    """Mean dense textured MAE, px, over the dev scenes and apertures (``{"dev": value}``)."""
    cfg = ABLATION_CONFIG["procedural"]
    out = {}
    for split in ("dev",):
        cells = _render_column(changes, {"scene_preset": cfg["scene_preset"]},
                               {k: v for k, v in renders.items() if k[0] in {f"procedural_{s}" for s in cfg[split]}})
        vals = [v for v in cells.values() if v is not None]
        out[split] = sum(vals) / len(vals) if vals else None
    return out


def _photo_column(changes, images: dict) -> dict:
    from experiments.photo_regions import score_defocus_map
    from method import DefocusParams, estimate_defocus_map

    params = DefocusParams.preset("robust", **changes) if changes is not None else DefocusParams.preset("paper")
    out = {}
    for name, (image, regions) in images.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sc = score_defocus_map(estimate_defocus_map(image, params).defocus_map, regions)
        out[name] = {"auc": sc["auc"], "share": sc["in_focus_above_defocused_median"]}
    return out


def ablation_report(config: dict | None = None, rows: dict | None = None, *, progress: bool = True) -> dict:
    """Every row of the ablation on the three sets (see the module docstring).

    Parameters
    ----------
    config : dict, optional
        Keys as :data:`ABLATION_CONFIG`.
    rows : dict, optional
        Label -> field changes to robust (:data:`ABLATION_ROWS`); the paper preset is added last.
    progress : bool, keyword-only

    Returns
    -------
    dict
        ``rows``: [{``label``, ``changes``, ``lens``, ``renders``, ``photos``, ``procedural`` (``dev``),
        ``seconds``}], ``config``,
        ``date``, ``runtime_s``.
    """
    from tqdm import tqdm

    from experiments.photo_regions import available_photos, load_photo_image, load_regions
    from experiments.sweep_cells import render_task

    from .lens import LENS_CONFIG, lens_case

    cfg = dict(ABLATION_CONFIG if config is None else config)
    rows = dict(ABLATION_ROWS if rows is None else rows)
    rows["paper"] = None
    t0 = time.perf_counter()
    lens_cfg = {**LENS_CONFIG, "psfs": (cfg["lens"]["psf"],)}
    cases = {fam: lens_case(fam, cfg["lens"]["psf"], cfg["lens"]["noise"], None, cfg["lens"]["seed"], lens_cfg)
             for fam in LENS_CONFIG["families"]}
    renders = {(s, float(f)): render_task(s, f_number=float(f), scene_preset=cfg["scene_preset"])
               for s in cfg["scenes"] for f in cfg["f_numbers"]}
    proc = cfg["procedural"]
    proc_renders = {(f"procedural_{seed}", float(f)): render_task(f"procedural_{seed}", f_number=float(f),
                                                                  scene_preset=proc["scene_preset"])
                    for seed in proc["dev"] for f in cfg["f_numbers"]}
    images = {}
    for name in cfg["photos"] or available_photos():
        regions = load_regions(name)
        images[name] = (load_photo_image(regions.source), regions)
    out = []
    for label, changes in tqdm(rows.items(), desc="ablation", unit="row", disable=not progress):
        t = time.perf_counter()
        out.append({"label": label, "changes": changes, "lens": _lens_column(changes, cfg, cases),
                    "renders": _render_column(changes, cfg, renders), "photos": _photo_column(changes, images),
                    "procedural": _procedural_column(changes, proc_renders), "seconds": time.perf_counter() - t})
    return {"rows": out, "config": cfg, "date": time.strftime("%Y-%m-%d %H:%M:%S"),
            "runtime_s": time.perf_counter() - t0}


def ablation_markdown(report: dict) -> str:
    """The ablation table (markdown), one row per variant, with the command that made it."""
    rows = report["rows"]
    apertures = list(dict.fromkeys(k.split(" ")[-1] for k in rows[0]["renders"]))
    photos = list(rows[0]["photos"])
    head = (["variant", "lens bench: mean dense MAE σ 1–8 (cells over target)"]
            + [f"renders {a}: mean MAE (worst scene)" for a in apertures]
            + [f"{p}: AUC / share" for p in photos] + ["procedural dev: mean MAE"])
    out = [f"# Ablation of the robust preset ({report['date']}, {report['runtime_s'] / 60:.1f} min)", "",
           "`python -m repro.bench --ablation` (experiments/bench/ablation.py). Lens bench: every texture family and "
           f"straight steps, {report['config']['lens']['psf']} PSF in linear light, noise "
           f"{report['config']['lens']['noise']}, sRGB, 8 bits. Renders: "
           + ", ".join(report["config"]["scenes"]) + f" at the {report['config']['scene_preset']} preset, dense "
           "textured MAE (px). Photos: ranking AUC of defocused over in-focus regions / in-focus share above the "
           "defocused median. Procedural: the first 8 scenes of the dev split, small renders, f/8 f/4 f/2, mean dense "
           "textured MAE (px; shown, not part of the three-set rule). Held-out scenes are not shown here: a change "
           "is judged once on fresh scenes (python -m repro.compare robust VARIANT --procedural N --split fresh).", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lens = r["lens"]
        cells = [r["label"], f"{lens['mean_mae']:.3f} ({lens['fails']}/{lens['cells']})"]
        for a in apertures:
            vals = {k: v for k, v in r["renders"].items() if k.endswith(" " + a)}
            worst = max(vals, key=vals.get)
            cells.append(f"{sum(vals.values()) / len(vals):.3f} ({worst.split(' ')[0]} {vals[worst]:.2f})")
        cells += [f"{r['photos'][p]['auc']:.3f} / {r['photos'][p]['share']:.3f}" for p in photos]
        cells.append(f"{r['procedural']['dev']:.3f}")
        out.append("| " + " | ".join(cells) + " |")
    out += ["", "Per scene and aperture (dense textured MAE, px):", "",
            "| variant | " + " | ".join(rows[0]["renders"]) + " |", "|---|" + "---|" * len(rows[0]["renders"])]
    for r in rows:
        out.append(f"| {r['label']} | " + " | ".join(f"{v:.3f}" for v in r["renders"].values()) + " |")
    return "\n".join(out)
