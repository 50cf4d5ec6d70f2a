"""The lens benchmark: every cue and preset on mosaics blurred the way a lens blurs.

Analytic truth that does *not* share the method's assumptions: tiles of the texture families of
:mod:`scenes.analytic.families` (dead leaves, photographs, and the periodic, text, flat and shading
families that break a 1/f² spectral model) and straight steps, blurred by a lens PSF of
:mod:`scenes.analytic.psfs` (disk, hexagon, soft disk; or a Gaussian) in **linear light**, then a
camera (Poisson–Gaussian noise at a named ISO level, the sRGB curve, 8 bits, optionally JPEG;
:func:`scenes.display.camera_image`). Per PSF × noise × family × σ bin it records, as rows of one
long table (:func:`measure_lens`):

* ``dense_textured`` — the dense map of each preset over textured valid pixels (MAE, mean and median
  signed error, px);
* ``sparse`` — the edge measures (the same, plus coverage: the share of detected edge pixels that
  measure);
* ``region`` — the region (spectral) cue alone, with the robust preset's region settings: median
  relative error of σ̂ and the share of valid pixels it measures ("no measure" elsewhere).

:func:`judge_lens` gives the verdicts of the targets (:data:`LENS_TARGETS`; every cue also held to a
minimum coverage, :data:`experiments.bench.targets.TARGET_MIN_COVERAGE`, so that it cannot pass by
abstaining) and :func:`lens_markdown`
the report; ``python -m repro.bench --accuracy`` runs it (``--psf`` chooses the PSFs, ``--full`` the
full grid).
"""

from __future__ import annotations

import math
import time
import warnings

from .mosaics import lens_step_mosaic, sigma_bins, tile_contrast_snr
from .targets import TARGET_MIN_COVERAGE

__all__ = ["LENS_CONFIG", "LENS_FULL_CONFIG", "LENS_GRIDS", "LENS_LARGE_CONFIG", "LENS_TARGETS", "LENS_TONES",
           "LENS_TONE_CONFIG", "PERIODIC_FAMILIES", "REGION_NO_INFORMATION", "judge_lens", "lens_case", "lens_config",
           "lens_markdown", "measure_lens", "tone_label"]

#: The tone axis: (the camera's tone curve, a key of scenes.display.ENCODINGS; where the blur acts,
#: scenes.analytic.lens.LIGHTS). ("srgb", "linear") is a lens and a camera JPEG; the other curves
#: replace sRGB; ("srgb", "display") blurs the display values (the Gaussian mosaics' model).
LENS_TONES = (("srgb", "linear"), ("gamma1.8", "linear"), ("gamma2.2", "linear"), ("filmic", "linear"),
              ("srgb", "display"))

#: The default grid (about 6 min on the project's 2-core machine; measured in docs/performance.md).
LENS_CONFIG = {
    "psfs": ("disk", "hexagon"),
    "families": ("step_edges", "dead_leaves", "photo", "checker", "stripes", "text", "brick", "flat_patches",
                 "shading"),
    "noises": ("iso100", "iso800"),
    "jpeg_qualities": (None,),
    "sigmas": (0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0),
    "tile": 96,
    "cols": 3,
    "seeds": (0,),
    "tones": LENS_TONES[:1],  # (curve, blur light) pairs of LENS_TONES; the tone grid runs them all
    # name -> (preset, field changes): the presets and the ablations every target is judged against
    "variants": {"paper": ("paper", {}), "robust": ("robust", {}),
                 "robust, display light": ("robust", {"measure_light": "display"}),
                 "robust + region cue (gated disk)": ("robust", {"region_estimator": "local_spectrum",
                                                                 "region_psf": "disk", "region_gate": "adequacy"})},
    # the region cue measured alone, label -> changes to the robust preset; the first is judged (the disk
    # model of a lens with the adequacy gate; docs/region-blur.md), the others are its ablation
    "regions": {"disk + adequacy gate": {"region_estimator": "local_spectrum", "region_psf": "disk",
                                         "region_gate": "adequacy"},
                "disk, no gate": {"region_estimator": "local_spectrum", "region_psf": "disk"},
                "Gaussian, no gate (as fused before)": {"region_estimator": "local_spectrum"}},
}
#: The full grid: every PSF and noise level, JPEG at quality 85 too, two seeds, every tone curve.
LENS_FULL_CONFIG = {**LENS_CONFIG, "psfs": ("gaussian", "disk", "soft_disk", "hexagon"),
                    "noises": ("none", "iso100", "iso800", "iso3200"), "jpeg_qualities": (None, 85), "seeds": (0, 1),
                    "tones": LENS_TONES}
#: The tone grid (``lens_config(tones=True)``): every tone curve and display-value blur at ISO 100, robust
#: in both lights (the tone rule of :data:`LENS_TARGETS`) and with its curve fitted per image.
LENS_TONE_CONFIG = {**LENS_CONFIG, "noises": ("iso100",), "tones": LENS_TONES,
                    "variants": {"robust": ("robust", {}), "robust, linear light": ("robust", {"measure_light": "linear"}),
                                 "robust, display light": ("robust", {"measure_light": "display"}),
                                 "robust, curve fitted (encoding auto)": ("robust", {}, "auto")},
                    "regions": {"disk + adequacy gate": LENS_CONFIG["regions"]["disk + adequacy gate"]}}
#: The large-blur grid (``python -m repro.bench --accuracy --grid large``): σ 8, 12 and 16 px on tiles of
#: 224 px (a disk of σ 16 is 64 px wide and its edge response spans ±64 px), ISO 100, the robust preset
#: with and without the fit's scale following a coarse estimate (``fit_follow_scale``), unguarded and
#: with its residual guard (``fit_follow_max_residual``), the guarded one also with σ2 16; no region cue.
#: Timed in docs/performance.md ("The large-blur lens grid").
_GUARDED = {"fit_follow_scale": 0.5, "fit_follow_max_residual": 0.02}
LENS_LARGE_CONFIG = {**LENS_CONFIG, "noises": ("iso100",), "sigmas": (8.0, 12.0, 16.0), "tile": 224,
                     "variants": {"paper": ("paper", {}), "robust": ("robust", {}),
                                  "robust + scale following": ("robust", {"fit_follow_scale": 0.5,
                                                                          "fit_follow_max_residual": 1.0}),
                                  "robust + guarded scale following": ("robust", _GUARDED),
                                  "robust + guarded scale following + σ2 16": ("robust", {
                                      **_GUARDED, "sigma2_scales": (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)})},
                     "regions": {}}
#: The lens grids by name (``--grid``).
LENS_GRIDS = {"default": LENS_CONFIG, "full": LENS_FULL_CONFIG, "tones": LENS_TONE_CONFIG, "large": LENS_LARGE_CONFIG}

#: Targets (robust), on every tone curve of the grid: edge fit on lens-blurred steps, the region cue, the
#: dense map at ISO 100 on every family (shading included; the periodic ones only where their blurred
#: contrast stays above ``periodic_min_snr`` × the noise), and the tone rule. Every cue is held to a
#: minimum coverage: a cell where it measures too few of its pixels fails (it cannot pass by abstaining).
LENS_TARGETS = {
    "edge_min_coverage": 0.9,      # share of detected step-edge pixels with a measure, σ 1–16
    "edge_max_rel_bias": 0.05,     # |median signed error| / σ_gt, σ 1–16
    "region_max_rel_error": 0.10,  # |median σ̂ − σ_gt| / σ_gt where the cue measures, σ 1–16
    "region_min_coverage": TARGET_MIN_COVERAGE,  # share of a tile's valid pixels the cue measures, σ 1–16
    "dense_min_coverage": TARGET_MIN_COVERAGE,   # share of textured valid pixels the dense map covers
    "dense_mae_px": 0.3,           # dense textured MAE for σ ≤ 4 px …
    "dense_rel_mae": 0.10,         # … and ≤ 10 % of σ_gt for 4 < σ ≤ 16 (noise iso100)
    "periodic_min_snr": 3.0,       # periodic families judged where blurred contrast (std) > 3 × noise std
    "tone_max_excess": 0.10,       # per tone curve and σ bin: MAE ≤ 1.1 × the better of the two lights'
    "tone_light_variants": ("robust, linear light", "robust, display light"),
    "sigma_range": (1.0, 16.0),
}
#: Periodic texture families: a blur large against their period leaves no contrast to measure, so they
#: are judged only in the σ bins where the noise-free blurred tile's contrast exceeds
#: LENS_TARGETS["periodic_min_snr"] × the camera noise (both in display values; :func:`lens_case`).
PERIODIC_FAMILIES = ("checker", "stripes", "brick")
#: Texture families that carry (almost) no blur information for the region cue: there "no measure" is
#: the right answer (scenes.analytic.families: smooth shading has no texture; flat patches are flat
#: but for their borders, which are the edge cue's). The region cue is not held to the coverage target
#: on them; wherever it does measure there, its error is judged like everywhere else.
REGION_NO_INFORMATION = ("flat_patches", "shading")


def lens_config(*, psfs=None, full=False, tones=False, grid=None) -> dict:
    """The grid to run: :data:`LENS_CONFIG` (``full``: :data:`LENS_FULL_CONFIG`; ``tones``: :data:`LENS_TONE_CONFIG`;
    ``grid``: a key of :data:`LENS_GRIDS`), optionally with other PSFs.

    Raises
    ------
    ValueError
        An unknown PSF or grid (the message lists them).
    """
    from scenes.analytic.psfs import check_psf

    if grid is not None and grid not in LENS_GRIDS:
        raise ValueError(f"grid={grid!r} is invalid; allowed: {', '.join(LENS_GRIDS)}")
    cfg = dict(LENS_GRIDS[grid] if grid is not None else LENS_FULL_CONFIG if full else LENS_TONE_CONFIG if tones
               else LENS_CONFIG)
    if psfs:
        cfg["psfs"] = tuple(dict.fromkeys(check_psf(p) for p in psfs))
    return cfg


def tone_label(encoding: str, light: str) -> str:
    """The tone axis's label of a row: the curve, plus ", display blur" when the blur acts on display values."""
    return encoding if light == "linear" else f"{encoding}, display blur"


def lens_case(family: str, psf: str, noise: str, jpeg, seed: int, cfg: dict, *, encoding: str = "srgb",
              light: str = "linear") -> dict:
    """One image of the grid: ``image``, ``sigma_gt`` (px), ``valid`` (bool), per-tile ``nominal``, ``gt`` and ``snr``.

    ``family`` "step_edges" is :func:`experiments.bench.mosaics.lens_step_mosaic`; any other is a
    :func:`scenes.analytic.lens.lens_mosaic` of that texture family, through the tone curve ``encoding``
    with the blur in ``light``. ``snr`` (texture families): per tile σ, the blurred contrast over the
    noise (:func:`experiments.bench.mosaics.tile_contrast_snr`); None for the steps.
    """
    import numpy as np

    from scenes.analytic.lens import lens_mosaic

    sigmas = tuple(float(s) for s in cfg["sigmas"])
    if family == "step_edges":
        if jpeg is not None:
            raise ValueError("the step-edge mosaic has no JPEG variant")
        image, gt, valid = lens_step_mosaic(sigmas, cfg["tile"], psf=psf, noise=noise, seed=seed, light=light,
                                            encoding=encoding)
        nominal = tuple(sorted(set(sigmas)))
        return {"image": image, "sigma_gt": gt, "valid": valid, "nominal": nominal, "gt": nominal, "snr": None}
    m = lens_mosaic(family=family, psf=psf, sigmas=sigmas, tile=cfg["tile"], cols=cfg["cols"], noise=noise,
                    jpeg_quality=jpeg, rng=seed, encoding=encoding, light=light)
    nominal = tuple(sorted(set(sigmas)))
    gt = tuple(float(np.hypot(s, m.intrinsic_sigma)) for s in nominal)
    return {"image": m.image, "sigma_gt": m.sigma, "valid": ~m.boundary, "nominal": nominal, "gt": gt,
            "snr": tile_contrast_snr(m, encoding)}


def _bin_rows(errors: dict, nominal, gt, snr=None, **ids) -> list[dict]:
    return [{**ids, "sigma": s, "sigma_gt": g, **{k: b[k] for k in ("n", "mae", "bias", "median", "coverage")},
             "snr": None if snr is None else snr.get(s)}
            for s, g, b in zip(nominal, gt, errors["bins"])]


def _region_rows(image, case, params, bins, **ids) -> list[dict]:
    """Per tile σ: the region cue's median relative error and the share of valid pixels it measures."""
    import numpy as np

    from method.blur.region_estimators import estimate_region_blur
    from method.luma import luminance

    sig, _ = estimate_region_blur(luminance(image), params=params)
    gt, valid = case["sigma_gt"], case["valid"]
    rows = []
    for s, g, lo, hi in zip(case["nominal"], case["gt"], bins[:-1], bins[1:]):
        sel = valid & (gt >= lo) & (gt < hi)
        v, t = sig[sel], gt[sel]
        ok = np.isfinite(v)
        rel = (v[ok] - t[ok]) / t[ok]
        rows.append({**ids, "sigma": s, "sigma_gt": g, "n": int(ok.sum()),
                     "mae": float(np.mean(np.abs(v[ok] - t[ok]))) if ok.any() else None,
                     "bias": float(np.mean(v[ok] - t[ok])) if ok.any() else None,
                     "median": float(np.median(rel)) if ok.any() else None,  # relative, for the region cue
                     "coverage": float(ok.mean()) if sel.any() else None})
    return rows


def measure_lens(cfg: dict, *, progress: bool = True) -> list[dict]:
    """Run the grid; one row per (psf, noise, jpeg, family, seed, variant, cue, σ bin).

    Parameters
    ----------
    cfg : dict
        Keys as :data:`LENS_CONFIG`.
    progress : bool, keyword-only

    Returns
    -------
    list of dict
        ``psf``, ``noise``, ``jpeg``, ``family``, ``seed``, ``tone`` (:func:`tone_label`), ``variant`` (a key of ``cfg["variants"]``, or
        "region: " + a key of ``cfg["regions"]`` for the cue alone), ``cue`` ("dense_textured", "sparse",
        "region"), ``sigma`` (tile σ, px), ``sigma_gt`` (px), ``n``, ``mae``, ``bias`` (px), ``median``
        (px; for the region cue the median *relative* error), ``coverage`` (share, see the module
        docstring), ``snr`` (texture families: the tile's blurred contrast / noise, :func:`tile_contrast_snr`;
        else None), ``seconds`` (per variant).

    Notes
    -----
    1. Per (psf, noise, jpeg, family, seed, tone): :func:`lens_case`; one σ bin per tile σ.
    2. Per variant (told the curve "srgb", the camera default, or its own third item, e.g. "auto"):
       :func:`method.estimate_defocus_map` and
       :func:`experiments.stage_attribution.stage_errors` (no oracles) → dense textured and sparse rows.
    3. The region cue alone, per setting of ``cfg["regions"]``
       (:func:`method.blur.region_estimators.estimate_region_blur`; texture families only).
    """
    from tqdm import tqdm

    from experiments.stage_attribution import stage_errors
    from method import DefocusParams

    # name -> (params, the encoding the estimator is told: "srgb", the camera default, unless a third item)
    variants = {name: (DefocusParams.preset(v[0], **v[1]), v[2] if len(v) > 2 else "srgb")
                for name, v in cfg["variants"].items()}
    regions = {f"region: {k}": DefocusParams.preset("robust", **ch) for k, ch in cfg["regions"].items()}
    cases = [(psf, noise, jpeg, fam, seed, tone) for psf in cfg["psfs"] for noise in cfg["noises"]
             for jpeg in cfg["jpeg_qualities"] for fam in cfg["families"] for seed in cfg["seeds"]
             for tone in cfg.get("tones", LENS_TONES[:1]) if not (fam == "step_edges" and jpeg is not None)]
    rows = []
    with tqdm(total=len(cases), desc="accuracy: lens", unit="image", disable=not progress) as bar:
        for psf, noise, jpeg, fam, seed, (encoding, light) in cases:
            bar.set_postfix_str(f"{psf} {noise} {fam} {tone_label(encoding, light)}")
            case = lens_case(fam, psf, noise, jpeg, seed, cfg, encoding=encoding, light=light)
            bins = sigma_bins(case["gt"])
            ids = {"psf": psf, "noise": noise, "jpeg": jpeg, "family": fam, "seed": seed,
                   "tone": tone_label(encoding, light)}
            done = {}  # equal parameters and encoding: measured once (e.g. robust and its own light)
            for name, (params, told) in variants.items():
                t0 = time.perf_counter()
                if (params, told) not in done:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        done[(params, told)] = stage_errors(case["image"], case["sigma_gt"], params=params,
                                                            valid=case["valid"], bins=bins, oracles=False,
                                                            encoding=told)["estimated"]
                err = done[(params, told)]
                dt = time.perf_counter() - t0
                for cue in ("dense_textured", "sparse"):
                    rows += [{**r, "seconds": dt} for r in _bin_rows(err[cue], case["nominal"], case["gt"],
                                                                     case["snr"], **ids, variant=name, cue=cue)]
            if fam != "step_edges":
                for name, params in regions.items():
                    rows += _region_rows(case["image"], case, params, bins, **ids, variant=name, cue="region")
            bar.update(1)
    return rows


def _in_range(s) -> bool:
    lo, hi = LENS_TARGETS["sigma_range"]
    return lo <= s <= hi


def judge_lens(rows: list[dict], *, variant: str = "robust", region: str | None = None) -> dict:
    """Verdicts of :data:`LENS_TARGETS` for ``variant`` (the robust preset) from :func:`measure_lens` rows.

    ``region`` names the region-cue rows judged (default: the first "region: …" variant in ``rows``).

    Returns
    -------
    dict
        ``edges`` / ``region`` / ``dense`` / ``tone``: lists of failing cells (each a dict naming psf,
        noise, family, tone, σ, the numbers and ``reason``: "coverage" — the cue measured on fewer than
        the target share of its pixels — or "error"), ``pass`` per part and overall (None where nothing
        was judged); ``region`` also names the setting ``judged`` and the ``exempt`` families
        (:data:`REGION_NO_INFORMATION`); ``dense`` the periodic cells ``not_judged`` (contrast below
        ``periodic_min_snr`` × noise).

    Notes
    -----
    A cell where a cue measures on fewer than its minimum coverage fails (edges: share of detected
    step-edge pixels; region cue: share of the tile's valid pixels, except on the families of
    :data:`REGION_NO_INFORMATION`; dense map: share of the textured valid pixels), so a cue cannot pass
    by abstaining. A cell whose pixels the bench has none of (no textured pixel in a tile) is not judged,
    nor a periodic family's cell whose ``snr`` is below ``periodic_min_snr`` (rows without ``snr``
    are judged). The tone rule: per (psf, noise, jpeg, seed, tone, σ) the dense MAE of ``variant``
    pooled over the judged families (n-weighted) ≤ (1 + ``tone_max_excess``) × the smaller of the
    two ``tone_light_variants``' (judged where both were run).
    """
    t = LENS_TARGETS
    if region is None:
        region = next((r["variant"] for r in rows if r["cue"] == "region"), None)
    fails = {"edges": [], "region": [], "dense": [], "tone": []}
    seen = dict.fromkeys(fails, False)
    not_judged, pooled = [], {}
    for r in rows:
        if not _in_range(r["sigma"]):
            continue
        key = {k: r.get(k) for k in ("psf", "noise", "jpeg", "family", "seed", "tone", "sigma")}
        if (r["cue"] == "dense_textured" and r["family"] in PERIODIC_FAMILIES and r.get("snr") is not None
                and r["snr"] < t["periodic_min_snr"]):
            if r["variant"] == variant:
                not_judged.append({**key, "snr": r["snr"]})
            continue
        if (r["cue"] == "dense_textured" and r["noise"] == "iso100" and r["family"] != "step_edges" and r["n"]
                and r["mae"] is not None and r["variant"] in (variant, *t["tone_light_variants"])):
            cell = pooled.setdefault(tuple(key[k] for k in ("psf", "noise", "jpeg", "seed", "tone", "sigma")), {})
            n, e = cell.get(r["variant"], (0, 0.0))
            cell[r["variant"]] = (n + r["n"], e + r["n"] * r["mae"])
        cov = r["coverage"] or 0.0
        if r["cue"] == "sparse" and r["variant"] == variant and r["family"] == "step_edges":
            seen["edges"] = True
            med = r["median"]
            if cov < t["edge_min_coverage"]:
                fails["edges"].append({**key, "coverage": cov, "median": med, "reason": "coverage"})
            elif med is None or abs(med) > t["edge_max_rel_bias"] * r["sigma_gt"]:
                fails["edges"].append({**key, "coverage": cov, "median": med, "reason": "error"})
        elif r["cue"] == "region" and r["variant"] == region:
            exempt = r["family"] in REGION_NO_INFORMATION
            if r["coverage"] is None or (exempt and r["median"] is None):
                continue  # no valid pixel in the tile; or nothing measured where nothing is to be measured
            seen["region"] = True
            if not exempt and cov < t["region_min_coverage"]:
                fails["region"].append({**key, "coverage": cov, "median_rel": r["median"], "reason": "coverage"})
            elif r["median"] is not None and abs(r["median"]) > t["region_max_rel_error"]:
                fails["region"].append({**key, "coverage": cov, "median_rel": r["median"], "reason": "error"})
        elif (r["cue"] == "dense_textured" and r["variant"] == variant and r["noise"] == "iso100"
              and r["family"] != "step_edges" and r["coverage"] is not None):
            seen["dense"] = True
            limit = t["dense_mae_px"] if r["sigma"] <= 4.0 else t["dense_rel_mae"] * r["sigma_gt"]
            if cov < t["dense_min_coverage"] or r["mae"] is None:
                fails["dense"].append({**key, "coverage": cov, "mae": r["mae"], "limit": limit, "reason": "coverage"})
            elif r["mae"] > limit:
                fails["dense"].append({**key, "coverage": cov, "mae": r["mae"], "limit": limit, "reason": "error"})
    for cell, by in pooled.items():
        if variant in by and all(v in by for v in t["tone_light_variants"]):
            seen["tone"] = True
            mae = {v: e / n for v, (n, e) in by.items()}
            best = min(mae[v] for v in t["tone_light_variants"])
            if mae[variant] > (1.0 + t["tone_max_excess"]) * best:
                fails["tone"].append({**dict(zip(("psf", "noise", "jpeg", "seed", "tone", "sigma"), cell)),
                                      "mae": mae[variant], "best_light_mae": best, "reason": "error"})
    out = {k: {"pass": (not fails[k]) if seen[k] else None, "fails": fails[k]} for k in fails}
    out["dense"]["not_judged"] = not_judged
    out["region"]["judged"] = region
    out["region"]["exempt"] = list(REGION_NO_INFORMATION)
    parts = [v["pass"] for v in out.values() if isinstance(v, dict) and "pass" in v]
    out["pass"] = all(p for p in parts if p is not None) if any(p is not None for p in parts) else None
    return out


def _pooled(rows, **match):
    """Rows matching ``match`` pooled over seeds: n-weighted mae/bias/median, mean coverage, by σ."""
    out = {}
    for r in rows:
        if all(r.get(k) == v for k, v in match.items()):
            out.setdefault(r["sigma"], []).append(r)
    pooled = {}
    for s, rs in out.items():
        n = sum(r["n"] for r in rs)
        avg = (lambda k: sum(r["n"] * r[k] for r in rs if r[k] is not None) / n if n else None)  # noqa: E731
        covs = [r["coverage"] for r in rs if r["coverage"] is not None]
        pooled[s] = {"n": n, "mae": avg("mae"), "bias": avg("bias"), "median": avg("median"),
                     "coverage": sum(covs) / len(covs) if covs else None, "sigma_gt": rs[0]["sigma_gt"]}
    return pooled


def _fmt(v, spec=".2f", none="—"):
    return none if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def lens_markdown(rows: list[dict], cfg: dict, verdict: dict) -> str:
    """The report section of the lens benchmark (markdown): compact table, edges, region cue, dense map."""
    sig = sorted({r["sigma"] for r in rows})
    head = "| " + " | ".join(f"σ {s:g}" for s in sig) + " |"
    sep = "|" + "---|" * (len(sig))
    out = ["## Lens blur: PSFs in linear light, a camera's noise and tone curve",
           "",
           "`python -m repro.bench --accuracy` (`--psf NAME…`, `--full`). Mosaics of texture families and "
           "straight steps blurred by a lens PSF in linear light (σ = PSF ⊗ pixel box), then Poisson–Gaussian "
           "noise, a tone curve and 8 bits (experiments/bench/lens.py). Tone curves: "
           + ", ".join(tone_label(*tc) for tc in cfg.get("tones", LENS_TONES[:1]))
           + " (the estimator is told sRGB unless a variant says otherwise). Grid: PSFs " + ", ".join(cfg["psfs"])
           + "; noise "
           + ", ".join(cfg["noises"]) + "; JPEG " + ", ".join("none" if q is None else str(q)
                                                               for q in cfg["jpeg_qualities"])
           + "; seeds " + ", ".join(map(str, cfg["seeds"])) + ".",
           "",
           f"**Verdict (robust): {'PASS' if verdict['pass'] else 'FAIL' if verdict['pass'] is False else 'n/a'}** — "
           f"edges {_verdict_word(verdict['edges'])}, region cue {_verdict_word(verdict['region'])}, "
           f"dense map at ISO 100 {_verdict_word(verdict['dense'])}, tone rule "
           f"{_verdict_word(verdict.get('tone', {'pass': None, 'fails': []}))}. Targets: edge measures at ≥ "
           f"{LENS_TARGETS['edge_min_coverage']:.0%} of step-edge pixels with |median error| ≤ "
           f"{LENS_TARGETS['edge_max_rel_bias']:.0%} of σ; region cue measuring ≥ "
           f"{LENS_TARGETS['region_min_coverage']:.0%} of each tile's pixels (not required on "
           f"{', '.join(REGION_NO_INFORMATION)}: no blur information) with |median error| ≤ "
           f"{LENS_TARGETS['region_max_rel_error']:.0%} of σ wherever it measures; dense textured MAE ≤ "
           f"{LENS_TARGETS['dense_mae_px']} px for σ ≤ 4 and ≤ {LENS_TARGETS['dense_rel_mae']:.0%} of σ beyond "
           f"(covering ≥ {LENS_TARGETS['dense_min_coverage']:.0%} of textured pixels; the periodic families "
           f"{', '.join(PERIODIC_FAMILIES)} only where their blurred contrast exceeds "
           f"{LENS_TARGETS['periodic_min_snr']:g}× the noise); on every tone curve no σ bin's dense MAE above "
           f"{1 + LENS_TARGETS['tone_max_excess']:.2f}× the better of {' and '.join(LENS_TARGETS['tone_light_variants'])}"
           f" (where both run); all for σ {LENS_TARGETS['sigma_range'][0]:g}–{LENS_TARGETS['sigma_range'][1]:g}. "
           "A cell where a cue measures less than its coverage target fails: a cue cannot pass by abstaining.", ""]
    skipped = verdict.get("dense", {}).get("not_judged", [])
    groups = {}
    for c in skipped:
        groups.setdefault((c["family"], c["psf"], c["tone"]), []).append(f"{c['sigma']:g} ({c['snr']:.1f}×)")
    out += ["Periodic cells not judged (blurred contrast / noise below the threshold): "
            + ("; ".join(f"{f} ({p}, {t}) σ {', '.join(v)}" for (f, p, t), v in groups.items()) if groups else "none")
            + ".", ""]
    for psf in cfg["psfs"]:
        for noise in cfg["noises"]:
            for jpeg in cfg["jpeg_qualities"]:
                for tone in dict.fromkeys(r.get("tone") for r in rows):
                    sub = [r for r in rows if r["psf"] == psf and r["noise"] == noise and r["jpeg"] == jpeg
                           and r.get("tone") == tone]
                    if sub:
                        out += _section(sub, psf, noise, jpeg, sig, head, sep, list(cfg["variants"]), tone)
    return "\n".join(out)


def _verdict_word(part) -> str:
    if part["pass"] is None:
        return "n/a"
    if part["pass"]:
        return "pass"
    n, low = len(part["fails"]), sum(f["reason"] == "coverage" for f in part["fails"])
    return f"FAIL ({n} cell{'' if n == 1 else 's'}" + (f", {low} below the coverage target)" if low else ")")


def _section(sub, psf, noise, jpeg, sig, head, sep, variants, tone=None) -> list[str]:
    title = (f"### PSF {psf}, noise {noise}" + ("" if jpeg is None else f", JPEG {jpeg}")
             + ("" if tone in (None, "srgb") else f", tone curve {tone}"))
    fams = list(dict.fromkeys(r["family"] for r in sub))
    out = [title, "", "Worst texture family per σ bin (dense textured MAE, px, of each variant):", "",
           "| variant " + head, "|---" + sep]
    for v in variants:
        cells = []
        for s in sig:
            worst = None
            for f in fams:
                if f == "step_edges":
                    continue
                p = _pooled(sub, variant=v, cue="dense_textured", family=f).get(s)
                if p and p["n"] and p["mae"] is not None and (worst is None or p["mae"] > worst[1]):
                    worst = (f, p["mae"])
            cells.append("—" if worst is None else f"{worst[0]} {worst[1]:.2f}")
        out.append(f"| {v} | " + " | ".join(cells) + " |")
    out += ["", "Edge measures on the straight steps: median signed error, px (coverage):", "",
            "| variant " + head, "|---" + sep]
    for v in variants:
        p = _pooled(sub, variant=v, cue="sparse", family="step_edges")
        out.append(f"| {v} | " + " | ".join(f"{_fmt(p[s]['median'], '+.2f')} ({_fmt(p[s]['coverage'], '.0%')})"
                                            if s in p else "—" for s in sig) + " |")
    out += ["", "Region cue alone: median relative error (share of pixels measured), per setting:", "",
            "| family | setting " + head, "|---|---" + sep]
    settings = list(dict.fromkeys(r["variant"] for r in sub if r["cue"] == "region"))
    for f in fams:
        for name in settings:
            p = _pooled(sub, variant=name, cue="region", family=f)
            if p:
                out.append(f"| {f} | {name.removeprefix('region: ')} | " + " | ".join(
                    f"{_fmt(p[s]['median'], '+.0%')} ({_fmt(p[s]['coverage'], '.0%')})" if s in p else "—"
                    for s in sig) + " |")
    out += ["", "Dense map over textured pixels: MAE / mean signed error, px:", "",
            "| family | variant " + head, "|---|---" + sep]
    for f in fams:
        for v in variants:
            p = _pooled(sub, variant=v, cue="dense_textured", family=f)
            out.append(f"| {f} | {v} | " + " | ".join(
                f"{_fmt(p[s]['mae'])} / {_fmt(p[s]['bias'], '+.2f')}" if s in p and p[s]["n"] else "—"
                for s in sig) + " |")
    return out + [""]
