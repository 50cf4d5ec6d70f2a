"""Supplementary figure S1: which stage loses accuracy — stage attribution with oracle inputs.

Not a figure of the paper. For every method preset (``paper``, ``robust``, ``zhuo_sim``) on analytic
texture mosaics (:func:`scenes.analytic.texture_mosaic`: tiles of one known Gaussian σ each,
8-bit + noise) and on the rendered scenes, the error after each stage (sparse at edges, refined at
edges, dense over textured pixels) for the estimated measures and with oracle inputs (σ_gt at the
detected edges fed into Eq. 3, or straight into Eq. 4; :mod:`experiments.stage_attribution`).
Also the robust preset's ablation (each beyond-the-paper switch turned off alone) on the mosaics,
and the dense-map accuracy targets for the robust preset (docs/presets.md), checked per σ bin.

Notes
-----
1. Mosaics: ``texture_mosaic(texture=t, sigmas=config.mosaic_sigmas, tile=config.mosaic_tile,
   noise_std=config.noise_std, quantize_bits=8, rng=config.seed)``, seam bands excluded.
2. Renders: ``render_scene(scene, preset=config.preset, f_number=N)``; input 8-bit sRGB; σ_gt the
   line-spread convention; occlusion boundaries excluded.
3. :func:`experiments.stage_attribution.stage_errors` per case × preset (and per ablation row on
   the mosaics).
4. Targets (robust, mosaics): dense textured MAE ≤ 0.3 px in every bin with σ ≤ 4 px and ≤ 10 % of σ
   for 4 < σ ≤ 6 px; |bias| ≤ 0.3 px in every bin up to 6 px; rendered: textured dense MAE ≤ ½ of
   the paper's. Recorded as booleans with the numbers (no verdict is hard-coded).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "StagesConfig", "compute"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class StagesConfig:
    """Every parameter of figure S1."""

    presets: tuple[str, ...] = ("paper", "robust", "zhuo_sim")
    # method presets (method.PRESETS) compared.
    mosaic_textures: tuple[str, ...] = ("dead_leaves", "skimage")
    # scenes.analytic.TEXTURES used for the mosaics.
    mosaic_sigmas: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
    # Gaussian σ of the tiles, px.
    mosaic_tile: int = 96
    # tile side, px.
    noise_std: float = 1.0 / 255.0
    # additive Gaussian noise before 8-bit quantisation, image units.
    seed: int = 0
    # mosaic texture and noise seed.
    scenes: tuple[str, ...] = ("portrait", "planes", "clutter", "shadow_gloss")
    # rendered scenes (scenes.SCENES).
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_numbers: tuple[float, ...] = (8.0, 4.0)
    # apertures N of the renders.
    ablation: bool = True
    # also run the robust preset with each of its switches off alone, on the mosaics.


QUICK = StagesConfig(mosaic_tile=64, mosaic_sigmas=(0.5, 1.0, 2.0, 4.0, 6.0), mosaic_textures=("dead_leaves",),
                     scenes=("portrait", "planes"), preset="small")
FULL = StagesConfig()

_STAGES = (("estimated", "sparse"), ("estimated", "refined"), ("estimated", "dense_textured"),
           ("oracle_refine", "dense_textured"), ("oracle_propagate", "dense_textured"))


def _targets(errs: dict) -> dict:
    """The robust preset's per-bin accuracy targets on a mosaic's dense textured map."""
    rows = []
    ok_mae = ok_bias = True
    for b in errs["bins"]:
        if not b["n"] or b["lo"] >= 6.0:
            continue
        mid = b["hi"] if np.isfinite(b["hi"]) else b["lo"]
        limit = 0.3 if b["hi"] <= 4.0 + 1e-9 else 0.1 * b["lo"]
        r = {"bin": [b["lo"], b["hi"]], "n": b["n"], "mae": b["mae"], "bias": b["bias"], "mae_limit": limit,
             "mae_ok": bool(b["mae"] <= limit), "bias_ok": bool(abs(b["bias"]) <= 0.3), "sigma_ref": mid}
        ok_mae &= r["mae_ok"]
        ok_bias &= r["bias_ok"]
        rows.append(r)
    return {"bins": rows, "mae_ok": bool(ok_mae), "bias_ok": bool(ok_bias)}


def compute(config: StagesConfig) -> dict:
    """Stage attribution for every preset on mosaics and renders; see the module Notes."""
    from method import DefocusParams, NoEdgesWarning
    from method.presets import ROBUST_CHANGES
    from scenes import render_scene
    from scenes.analytic import texture_mosaic

    from .evaluation import ground_truth_sigma, input_image
    from .stage_attribution import ablation_params, stage_errors

    t0 = time.perf_counter()
    cases = []
    for tex in config.mosaic_textures:
        m = texture_mosaic(texture=tex, sigmas=config.mosaic_sigmas, tile=config.mosaic_tile,
                           noise_std=config.noise_std, quantize_bits=8, rng=config.seed)
        cases.append((f"mosaic:{tex}", "mosaic", m.image, m.sigma, ~m.boundary))
    for scene in config.scenes:
        for n in config.f_numbers:
            r = render_scene(scene, preset=config.preset, f_number=n, progress=False)
            cases.append((f"{scene} f/{n:g}", "render", input_image(r), ground_truth_sigma(r),
                          ~np.asarray(r.occlusion_boundary, dtype=bool)))
    presets = {name: DefocusParams.preset(name) for name in config.presets}
    per_case: dict = {}
    mae = np.full((len(cases), len(presets), len(_STAGES)), np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoEdgesWarning)
        for i, (label, kind, img, gt, valid) in enumerate(cases):
            per_case[label] = {"kind": kind}
            for j, (pname, params) in enumerate(presets.items()):
                errs = stage_errors(img, gt, params=params, valid=valid)
                per_case[label][pname] = errs
                for k, (inp, st) in enumerate(_STAGES):
                    v = errs.get(inp, {}).get(st, {}).get("mae")
                    mae[i, j, k] = np.nan if v is None else v
            if kind == "mosaic" and "robust" in presets:
                per_case[label]["targets_robust"] = _targets(per_case[label]["robust"]["estimated"]["dense_textured"])
    ablation = {}
    if config.ablation and "robust" in presets:
        rows = ablation_params(presets["robust"], ROBUST_CHANGES)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NoEdgesWarning)
            for label, kind, img, gt, valid in cases:
                if kind != "mosaic":
                    continue
                for row, params in rows.items():
                    e = stage_errors(img, gt, params=params, valid=valid)["estimated"]
                    ablation.setdefault(row, {})[label] = {
                        "sparse_mae": e["sparse"]["mae"], "sparse_coverage": e["sparse"]["coverage"],
                        "dense_textured_mae": e["dense_textured"]["mae"],
                        "dense_textured_bias": e["dense_textured"]["bias"]}
    render_cases = [c[0] for c in cases if c[1] == "render"]
    ratio = {}
    if "paper" in presets and "robust" in presets and render_cases:
        for label in render_cases:
            p = per_case[label]["paper"]["estimated"]["dense_textured"]["mae"]
            r = per_case[label]["robust"]["estimated"]["dense_textured"]["mae"]
            ratio[label] = None if (p is None or r is None or p == 0) else r / p
    vals = [v for v in ratio.values() if v is not None]
    metrics = {
        "cases": per_case,
        "ablation": ablation,
        "robust_over_paper_textured_mae": ratio,
        "robust_over_paper_textured_mae_mean": float(np.mean(vals)) if vals else None,
        "robust_render_target_ok": bool(vals and all(v <= 0.5 for v in vals)),
        "stages": [f"{a}:{b}" for a, b in _STAGES],
        "presets": list(presets),
        "compute_seconds": time.perf_counter() - t0,
    }
    bins_lo = [b["lo"] for b in per_case[cases[0][0]][next(iter(presets))]["estimated"]["dense_textured"]["bins"]]
    return {"case_labels": np.array([c[0] for c in cases]), "mae": mae, "bins_lo": np.array(bins_lo),
            "metrics": metrics}


FIGURE = Figure(
    name="stages",
    title="Supplementary S1: stage attribution (sparse / refined / dense, with oracle inputs) per preset",
    compute=compute,
    plot="experiments.plotting.stages:plot",
    configs={"quick": QUICK, "full": FULL},
    version=1,
    sigma_convention="Gaussian σ in px: mosaics exactly the applied σ (dead leaves) or √(σ² + σ0²) (photos); "
                     "renders σ_gt = √((c/4)² + 1/12) px",
)
