"""The doubling claim (Sec. 5, Fig. 7) at both render sizes of the same scenes, and which stage loses f/4's blur.

The paper claims that doubling the defocus map of an f/8 photo gives a map similar to that of the f/4
photo. Judged on maps that cannot see f/4's blur, the claim fails for a reason that is not the paper's:
the literal reading measures every blur in pixels of the input, and Eq. (3)'s sharpness bias
exp(−BM/2) is written for the paper's (unstated) units, so at a higher resolution the same scene's
blur, larger in pixels, is pulled down harder. Rendering the same scenes at two sizes (``small``
160×120 and ``full`` 640×480: 4× the blur in pixels) separates the two readings:

* the claim holds at the small size and fails at the full size → the literal reading's pixel units
  fail at this resolution, not the paper's claim;
* it fails at both sizes → the claim, as the method reproduces it, fails;
* it holds at both → nothing to separate.

Per scene and size: the doubling claim's numbers (:func:`experiments.claims.rules.doubling_verdict`, the
rule the claims matrix applies to Fig. 7) and, on the f/4 render, the signed error of the dense map over
textured pixels split over the stages with the oracle inputs of :mod:`experiments.stage_attribution`
(:func:`attribute_stage`). ``python -m repro.bench --doubling`` writes ``doubling.json`` / ``doubling.md``
(report/bench/), which ``python -m repro.report`` shows. Measured: docs/presets.md.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

__all__ = ["DOUBLING_SIZES_CONFIG", "LOSS_MIN_PX", "STAGES", "attribute_stage", "doubling_case", "doubling_markdown",
           "doubling_report", "size_verdict"]

#: Scenes, render sizes, preset and apertures of ``python -m repro.bench --doubling``: Fig. 7's
#: paper_cameras scenes (the committed report's doubling claim) at both render sizes.
DOUBLING_SIZES_CONFIG = {"scenes": ("portrait_garden", "heron_at_the_lake"), "sizes": ("small", "full"),
                         "preset": "paper", "f_numbers": (8.0, 4.0)}

#: The stages the f/4 dense map's signed error is split over (:func:`attribute_stage`).
STAGES = ("edge fit (Sec. 3.2)", "Eq. (3) refinement", "Eq. (4) propagation")

#: A stage "loses the blur" only when its share of the dense map's mean signed error is below −this, px.
LOSS_MIN_PX = 0.25


def attribute_stage(errors: dict, *, region: str = "dense_textured") -> dict:
    """Split the dense map's mean signed error over the three stages, with the oracle inputs.

    Parameters
    ----------
    errors : dict
        :func:`experiments.stage_attribution.stage_errors` with ``oracles=True``.
    region : str, keyword-only
        The dense region whose bias is split (``dense_textured``, ``dense_all`` or ``dense_edges``).

    Returns
    -------
    dict
        ``shares``: ``{stage: px}`` for :data:`STAGES` (they sum to the estimated map's bias);
        ``bias``: the estimated dense map's mean signed error, px; ``sparse_bias`` / ``refined_bias``:
        the edge measures' before and after Eq. (3), px; ``stage``: the stage with the most negative share
        if it is below −:data:`LOSS_MIN_PX` (it loses the blur), else None.

    Notes
    -----
    Telescoping over the oracle inputs, on the same textured pixels: Eq. (4) alone on σ_gt at the
    detected edges (``oracle_propagate``) gives Eq. (4)'s share; Eq. (3) then Eq. (4) on σ_gt
    (``oracle_refine``) minus that gives Eq. (3)'s; the pipeline's map minus ``oracle_refine`` gives the
    edge fit's (the real measures instead of perfect ones, through the same Eq. 3 and 4).
    """
    est, o_ref, o_prop = (errors.get(k, {}).get(region, {}).get("bias") for k in
                          ("estimated", "oracle_refine", "oracle_propagate"))
    if est is None or o_ref is None or o_prop is None:
        raise ValueError(f"stage errors without the {region} bias of every input; allowed: stage_errors(..., "
                         "oracles=True) on an image with edges")
    shares = dict(zip(STAGES, (est - o_ref, o_ref - o_prop, o_prop)))
    worst = min(shares, key=shares.get)
    return {"shares": shares, "bias": est, "sparse_bias": errors["estimated"]["sparse"]["bias"],
            "refined_bias": errors["estimated"]["refined"]["bias"],
            "stage": worst if shares[worst] < -LOSS_MIN_PX else None}


_RANK = {"reproduced": 2, "partly reproduced": 1, "not reproduced": 0}


def size_verdict(verdicts: dict) -> dict:
    """Separate "the paper's claim fails" from "the literal reading's pixel units fail at this resolution".

    Parameters
    ----------
    verdicts : dict
        ``{"small": verdict, "full": verdict}``, each "reproduced", "partly reproduced" or "not reproduced"
        (the doubling rule on the same scenes rendered at each size).

    Returns
    -------
    dict
        ``key``: "holds" (reproduced at both sizes), "pixel_units" (better at the small size than at the
        full size: the same scenes with 4× less blur in px pass where the full size fails), "claim_fails"
        (not reproduced at both), "full_only" (better at the full size) or "same" (the same partial
        verdict at both); ``text``: one sentence.

    Raises
    ------
    ValueError
        A missing size or an unknown verdict.
    """
    for size in ("small", "full"):
        if verdicts.get(size) not in _RANK:
            raise ValueError(f"verdict of size {size!r} is {verdicts.get(size)!r}; allowed: {', '.join(_RANK)}")
    s, f = _RANK[verdicts["small"]], _RANK[verdicts["full"]]
    if s == f == 2:
        key, text = "holds", "the claim holds at both sizes"
    elif s > f:
        key, text = "pixel_units", ("the literal reading's pixel units fail at this resolution: the same scenes "
                                    f"with 4× less blur in px are {verdicts['small']} at the small size, "
                                    f"{verdicts['full']} at the full size")
    elif s == f == 0:
        key, text = "claim_fails", ("the paper's claim, as the method reproduces it, fails: not reproduced at "
                                    "either size, so not a matter of the pixel units alone")
    elif f > s:
        key, text = "full_only", (f"{verdicts['full']} at the full size but {verdicts['small']} at the small one: "
                                  "the small renders resolve too little blur")
    else:
        key, text = "same", f"{verdicts['small']} at both sizes"
    return {"key": key, "text": text}


def _render_pair(scene, size, f_numbers):
    from scenes import render_scene

    renders = [render_scene(scene, preset=size, f_number=n, seed=0, progress=False) for n in f_numbers]
    gts = [np.asarray(r.sigma_px, dtype=np.float64) for r in renders]
    mask = np.isfinite(gts[0]) & np.isfinite(gts[1])
    for r in renders:
        mask &= ~np.asarray(r.occlusion_boundary, dtype=bool)
    return [r.image(encoding="srgb", quantize_bits=8) for r in renders], gts, mask


def doubling_case(scene: str, size: str, *, preset: str = "paper", f_numbers=(8.0, 4.0)) -> dict:
    """One scene at one render size: the doubling claim's numbers and the f/4 stage attribution.

    Parameters
    ----------
    scene : str
        A scene of :data:`scenes.SCENES` or a procedural scene name.
    size : {"small", "full"}
        Render preset (160×120 / 640×480 px).
    preset : str, keyword-only
        Method preset.
    f_numbers : (float, float), keyword-only
        (small aperture, large aperture), e.g. (8, 4): the magnification k is their ratio.

    Returns
    -------
    dict
        ``scene``, ``size``, ``preset``; ``doubling``: the rule's numbers
        (``doubled_f8_vs_map_f4_median_rel``, ``doubled_f8_vs_gt_median_rel``, ``map_f4_vs_gt_median_rel``,
        dimensionless; the MAEs, px); ``median_sigma_gt_f4`` (px); ``attribution``
        (:func:`attribute_stage` on the large-aperture render); ``seconds``.
    """
    from method import DefocusParams, estimate_defocus_map

    from .metrics import dense_metrics
    from .stage_attribution import stage_errors

    t0 = time.perf_counter()
    (img_s, img_l), (gt_s, gt_l), mask = _render_pair(scene, size, f_numbers)
    params = DefocusParams.preset(preset)
    k = float(f_numbers[0]) / float(f_numbers[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res_s = estimate_defocus_map(img_s, params)
        res_l = estimate_defocus_map(img_l, params)
        errors = stage_errors(img_l, gt_l, params=params, valid=mask, result=res_l)
    regions = {"all": mask}
    to_gt = {n: dense_metrics(m, gt_l, regions=regions)["all"] for n, m in
             (("k_x_map_small", k * res_s.defocus_map), ("map_large", res_l.defocus_map))}
    apart = dense_metrics(k * res_s.defocus_map, res_l.defocus_map, regions=regions)["all"]
    doubling = {"doubled_f8_vs_map_f4_median_rel": float(apart["median_rel_error"]),
                "doubled_f8_vs_map_f4_mae": float(apart["mae"]),
                "doubled_f8_vs_gt_median_rel": float(to_gt["k_x_map_small"]["median_rel_error"]),
                "map_f4_vs_gt_median_rel": float(to_gt["map_large"]["median_rel_error"]),
                "doubled_f8_vs_gt_mae": float(to_gt["k_x_map_small"]["mae"]),
                "map_f4_vs_gt_mae": float(to_gt["map_large"]["mae"])}
    return {"scene": scene, "size": size, "preset": preset, "doubling": doubling,
            "median_sigma_gt_f4": float(np.median(gt_l[mask])), "attribution": attribute_stage(errors),
            "seconds": time.perf_counter() - t0}


def doubling_report(cfg: dict = DOUBLING_SIZES_CONFIG, *, progress: bool = True) -> dict:
    """Every scene × size of ``cfg`` (:data:`DOUBLING_SIZES_CONFIG`) and the verdicts.

    Returns
    -------
    dict
        ``config``; ``cases`` (:func:`doubling_case` each); ``sizes``: per size the doubling rule's
        ``verdict`` and ``evidence`` over the scenes (:func:`experiments.claims.rules.doubling_verdict`)
        and the ``stage`` that loses the blur most often at f/4 (None when none does); ``verdict``:
        :func:`size_verdict`.
    """
    from tqdm import tqdm

    cases = []
    todo = [(s, z) for z in cfg["sizes"] for s in cfg["scenes"]]
    for scene, size in tqdm(todo, desc="doubling at both sizes", unit="scene", disable=not progress):
        cases.append(doubling_case(scene, size, preset=cfg["preset"], f_numbers=tuple(cfg["f_numbers"])))
    return summarise(cases, cfg)


def summarise(cases: list[dict], cfg: dict) -> dict:
    """:func:`doubling_report`'s verdicts from its cases (no rendering; see there)."""
    from .claims.rules import doubling_verdict

    sizes = {}
    for size in cfg["sizes"]:
        mine = [c for c in cases if c["size"] == size]
        verdict, evidence = doubling_verdict({c["scene"]: c["doubling"] for c in mine})
        stages = [c["attribution"]["stage"] for c in mine if c["attribution"]["stage"] is not None]
        stage = max(set(stages), key=stages.count) if stages else None
        sizes[size] = {"verdict": verdict, "evidence": evidence, "stage": stage}
    out = {"config": dict(cfg), "cases": cases, "sizes": sizes}
    if {"small", "full"} <= set(sizes):
        out["verdict"] = size_verdict({z: sizes[z]["verdict"] for z in ("small", "full")})
    return out


def doubling_markdown(report: dict) -> str:
    """The report's section (Markdown): per size the verdict, then per scene the numbers and the stage shares."""
    cfg = report["config"]
    n_s, n_l = cfg["f_numbers"]
    out = [f"# The doubling claim at both render sizes ({cfg['preset']} preset)", "",
           f"`python -m repro.bench --doubling` (experiments/doubling_sizes.py): the scenes "
           f"{', '.join(cfg['scenes'])} rendered at {' and '.join(cfg['sizes'])} size, f/{n_s:g} and f/{n_l:g}; "
           "the doubling claim judged by the claims matrix's rule at each size, and the f/"
           f"{n_l:g} dense map's mean signed error over textured pixels split over the stages with oracle inputs "
           "(edge fit: the real measures against σ_gt at the same edges; Eq. (3): its change to perfect "
           "measures; Eq. (4): propagation of perfect measures).", ""]
    if "verdict" in report:
        out += [f"**Verdict: {report['verdict']['text']}.**", ""]
    out += ["| size | doubling claim | stage losing the f/4 blur |", "|---|---|---|"]
    for size, s in report["sizes"].items():
        out.append(f"| {size} | {s['verdict']} | {s['stage'] or 'none'} |")
    out += ["", f"| scene | size | median σ_gt f/{n_l:g}, px | 2×map vs map, median | map f/{n_l:g} vs σ_gt | "
            f"2×map f/{n_s:g} vs σ_gt | edges (bias, px) | after Eq. (3) | dense | "
            + " | ".join(f"share: {st}" for st in STAGES) + " |", "|---" * (9 + len(STAGES)) + "|"]
    for c in report["cases"]:
        d, a = c["doubling"], c["attribution"]
        out.append(f"| {c['scene']} | {c['size']} | {c['median_sigma_gt_f4']:.2f} | "
                   f"{100 * d['doubled_f8_vs_map_f4_median_rel']:.0f} % | {100 * d['map_f4_vs_gt_median_rel']:.0f} % | "
                   f"{100 * d['doubled_f8_vs_gt_median_rel']:.0f} % | {_px(a['sparse_bias'])} | "
                   f"{_px(a['refined_bias'])} | {_px(a['bias'])} | "
                   + " | ".join(_px(a["shares"][st]) for st in STAGES) + " |")
    return "\n".join(out) + "\n"


def _px(v) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{v:+.2f}"
