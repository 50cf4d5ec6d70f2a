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
   the mosaics, estimated inputs only); the oracle runs are read from the case store
   (:func:`experiments.stage_attribution.stored_oracle_runs`), shared with the evaluate cases.
4. Targets (robust, mosaics): dense textured MAE ≤ 0.3 px in every bin with σ ≤ 4 px and ≤ 10 % of σ
   for 4 < σ ≤ 6 px; |bias| ≤ 0.3 px in every bin up to 6 px; rendered: textured dense MAE ≤ ½ of
   the paper's. Recorded as booleans with the numbers (no verdict is hard-coded).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "STAGES", "StagesConfig", "case_label", "cases", "compute_case"]


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

STAGES = (("estimated", "sparse"), ("estimated", "refined"), ("estimated", "dense_textured"),
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


def cases(config: StagesConfig) -> tuple:
    """One case per image (mosaic texture, scene × aperture) × preset, and per mosaic × ablation row of
    the robust preset (``variant = "ablation:<row>"``)."""
    from method import PRESETS

    from .cases import Case

    presets = PRESETS.check_all(config.presets, what="preset")
    out = [Case("stages", scene=tex, preset=p, variant="mosaic") for tex in config.mosaic_textures for p in presets]
    out += [Case("stages", scene=scene, preset=p, aperture=float(n), variant="render", scene_size=config.preset)
            for scene in config.scenes for n in config.f_numbers for p in presets]
    if config.ablation and "robust" in presets:
        out += [Case("stages", scene=tex, preset="robust", variant=f"ablation:{row}")
                for tex in config.mosaic_textures for row in _ablation_rows()]
    return tuple(out)


def _ablation_rows() -> dict:
    """One-switch-off rows of the robust preset's estimation switches (the magnification's leave the map alone)."""
    import dataclasses

    from method import DefocusParams
    from method.magnify.params import MagnifyParams
    from method.presets import ROBUST_CHANGES

    from .stage_attribution import ablation_params

    magnify = {f.name for f in dataclasses.fields(MagnifyParams)}
    return ablation_params(DefocusParams.preset("robust"), {k: v for k, v in ROBUST_CHANGES.items() if k not in magnify})


def _image(config: StagesConfig, case):
    """(image, σ_gt, valid) of a case's mosaic or render."""
    if case.variant == "render":
        from scenes import render_scene

        from .evaluation import ground_truth_sigma, input_image

        r = render_scene(case.scene, preset=config.preset, f_number=case.aperture, progress=False)
        return input_image(r), ground_truth_sigma(r), ~np.asarray(r.occlusion_boundary, dtype=bool)
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(texture=case.scene, sigmas=config.mosaic_sigmas, tile=config.mosaic_tile,
                       noise_std=config.noise_std, quantize_bits=8, rng=config.seed)
    return m.image, m.sigma, ~m.boundary


def compute_case(config: StagesConfig, case, inputs) -> dict:
    """Stage attribution (:func:`experiments.stage_attribution.stage_errors`) of one preset on one image;
    on a mosaic with the robust preset also its accuracy targets (``targets_robust``); an ablation row:
    ``sparse_mae``, ``sparse_coverage``, ``dense_textured_mae``, ``dense_textured_bias``."""
    from method import DefocusParams, NoEdgesWarning

    from .stage_attribution import stage_errors

    img, gt, valid = _image(config, case)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoEdgesWarning)
        if case.variant.startswith("ablation:"):
            params = _ablation_rows()[case.variant.split(":", 1)[1]]
            e = stage_errors(img, gt, params=params, valid=valid, oracles=False)["estimated"]
            return {"metrics": {"sparse_mae": e["sparse"]["mae"], "sparse_coverage": e["sparse"]["coverage"],
                                "dense_textured_mae": e["dense_textured"]["mae"],
                                "dense_textured_bias": e["dense_textured"]["bias"]}}
        errs = stage_errors(img, gt, params=DefocusParams.preset(case.preset), valid=valid, store=True)
    metrics = dict(errs)
    if case.variant == "mosaic" and case.preset == "robust":
        metrics["targets_robust"] = _targets(errs["estimated"]["dense_textured"])
    return {"metrics": metrics}


def case_label(case) -> str:
    """The plot's and the report's name of an image: ``mosaic:<texture>`` or ``<scene> f/<N>``."""
    return f"mosaic:{case.scene}" if case.variant == "mosaic" else f"{case.scene} f/{case.aperture:g}"


FIGURE = Figure(
    name="stages",
    title="Supplementary S1: stage attribution (sparse / refined / dense, with oracle inputs) per preset",
    plot="experiments.plotting.stages:plot",
    configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=2,
    sigma_convention="Gaussian σ in px: mosaics exactly the applied σ (dead leaves) or √(σ² + σ0²) (photos); "
                     "renders σ_gt = √((c/4)² + 1/12) px",
)
