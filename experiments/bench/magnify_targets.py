"""Targets of the magnification as a user gets it: the subject untouched, the background blurred.

Measured with a preset's own magnification (its ``magnify_renderer`` and ``map_floor``, no focus point,
no mask), ×2:

* the ``paper_cameras`` full renders (:data:`experiments.fig7_doubled_defocus.FULL`, f/8 magnified ×2
  against the real f/4 render): in-focus PSNR ≥ min(unchanged − :data:`TARGET_IN_FOCUS_DROP_DB`,
  :data:`TARGET_IN_FOCUS_MIN_DB`), defocused-region PSNR ≥ unchanged + :data:`TARGET_DEFOCUSED_GAIN_DB`,
  and the default renderer's overall PSNR ≥ every other renderer's with the same floor;
* the photos of ``experiments/photos`` (their drawn regions): in-focus PSNR against the unchanged photo
  ≥ :data:`TARGET_PHOTO_IN_FOCUS_DB`; in the defocused regions the median σ the preset's estimator reads
  on the output ≥ :data:`TARGET_PHOTO_BLUR_RATIO` × what it reads on the input;
* the 12-MP magnification ≤ :data:`experiments.bench.speed.TARGET_MAGNIFY_SECONDS_12MP` (timed by the
  caller, :func:`experiments.bench.speed.time_magnification`).

Rows beside the default (not judged): the gather with the literal ``"clamp"`` floor and the other
renderers with the preset's floor.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["TARGET_DEFOCUSED_GAIN_DB", "TARGET_IN_FOCUS_DROP_DB", "TARGET_IN_FOCUS_MIN_DB", "TARGET_PHOTO_BLUR_RATIO",
           "TARGET_PHOTO_IN_FOCUS_DB", "magnify_markdown", "magnify_report", "photo_rows", "render_rows"]

TARGET_IN_FOCUS_DROP_DB = 1.0
TARGET_IN_FOCUS_MIN_DB = 40.0
TARGET_DEFOCUSED_GAIN_DB = 1.0
TARGET_PHOTO_IN_FOCUS_DB = 40.0
TARGET_PHOTO_BLUR_RATIO = 1.6
#: The scenes and photos measured.
RENDER_SCENES = ("portrait_garden", "heron_at_the_lake")
PHOTOS = ("astronaut", "chelsea", "coffee")
FACTOR = 2.0


def _variants(params) -> dict:
    """{label: (renderer, floor)}: the preset's default first, then the rows shown beside it."""
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    default = (params.magnify_renderer, params.map_floor)
    out = {"default": default}
    for r in MAGNIFICATION_RENDERERS:
        if (r, params.map_floor) != default:
            out[f"{r}, floor {params.map_floor}"] = (r, params.map_floor)
    if ("gather", "clamp") not in out.values():
        out["gather, floor clamp"] = ("gather", "clamp")
    return out


def _magnify(image, defocus_map, params, renderer, floor):
    from method import magnify_defocus

    return magnify_defocus(image, defocus_map, factor=FACTOR, renderer=renderer, floor=floor,
                           clip_percent=params.map_clip_percent, smoothing=params.map_smoothing)


def render_rows(preset: str = "robust", scenes=RENDER_SCENES) -> list[dict]:
    """Per scene: PSNR (dB) against the real f/4 render overall, in focus and defocused of the unchanged f/8
    render and of each magnification (:func:`_variants`), and the verdicts of the render targets."""
    from method import DefocusParams

    from .. import fig7_doubled_defocus as f7

    params = DefocusParams.preset(preset)
    rows = []
    for scene in scenes:
        pair = f7._render_pair(scene, f7.FULL)
        sigma = f7._estimate(pair.image_small, params, encoding=f7.FULL.encoding).defocus_map
        scores = {"unchanged": f7._score_image(pair.image_small, pair)}
        for label, (renderer, floor) in _variants(params).items():
            scores[label] = f7._score_image(_magnify(pair.image_small, sigma, params, renderer, floor), pair)
        psnr = {k: {"all": v["psnr_db"], "in_focus": v["psnr_in_focus_db"], "defocused": v["psnr_defocused_db"]}
                for k, v in scores.items()}
        base, d = psnr["unchanged"], psnr["default"]
        same_floor = [v["all"] for k, v in psnr.items() if k.endswith(f"floor {params.map_floor}")]
        rows.append({"scene": scene, "psnr_db": psnr, "targets": {
            "in_focus_kept": d["in_focus"] >= min(base["in_focus"] - TARGET_IN_FOCUS_DROP_DB, TARGET_IN_FOCUS_MIN_DB),
            "defocused_gained": d["defocused"] >= base["defocused"] + TARGET_DEFOCUSED_GAIN_DB,
            "default_renderer_best": all(d["all"] >= x for x in same_floor)}})
    return rows


def photo_rows(preset: str = "robust", names=PHOTOS) -> list[dict]:
    """Per photo: in-focus PSNR against the unchanged photo (dB) and the median σ (px) the estimator reads in the
    defocused regions before and after, for each magnification (:func:`_variants`), and the photo targets."""
    from method import DefocusParams, estimate_defocus_map

    from ..photo_regions import compute_photo_maps

    params = DefocusParams.preset(preset)
    rows = []
    for name in names:
        d = compute_photo_maps(name, presets=(preset,))
        image, sigma, masks = d["image"], d["results"][preset].defocus_map, d["regions"].masks()
        inf, de = masks["in_focus"], masks["defocused"]
        before = float(np.median(sigma[de]))
        out = {}
        for label, (renderer, floor) in _variants(params).items():
            mag = _magnify(image, sigma, params, renderer, floor)
            mse = float(np.mean((mag[inf] - image[inf]) ** 2))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                after = float(np.median(estimate_defocus_map(mag, params).defocus_map[de]))
            out[label] = {"in_focus_psnr_db": float("inf") if mse == 0 else float(10 * np.log10(1 / mse)),
                          "defocused_sigma_px": after, "blur_ratio": after / before}
        dflt = out["default"]
        rows.append({"photo": name, "defocused_sigma_px_input": before, "magnified": out, "targets": {
            "in_focus_kept": dflt["in_focus_psnr_db"] >= TARGET_PHOTO_IN_FOCUS_DB,
            "defocused_gained": dflt["blur_ratio"] >= TARGET_PHOTO_BLUR_RATIO}})
    return rows


def magnify_report(preset: str = "robust", *, speed_row: dict | None = None) -> dict:
    """:func:`render_rows`, :func:`photo_rows` and (given) the 12-MP timing with its verdict."""
    from method import DefocusParams

    from .speed import TARGET_MAGNIFY_SECONDS_12MP

    params = DefocusParams.preset(preset)
    report = {"preset": preset, "default": {"renderer": params.magnify_renderer, "floor": params.map_floor},
              "renders": render_rows(preset), "photos": photo_rows(preset)}
    if speed_row is not None:
        report["speed_12mp"] = {**speed_row, "meets_target": speed_row["magnify_s"] <= TARGET_MAGNIFY_SECONDS_12MP}
    return report


def _mark(ok) -> str:
    return "pass" if ok else "FAIL"


def magnify_markdown(report: dict) -> str:
    """Markdown tables of :func:`magnify_report`."""
    d = report["default"]
    lines = [f"# Magnification targets ({report['preset']}: {d['renderer']}, floor {d['floor']}; ×{FACTOR:g})", "",
             "paper_cameras full renders, PSNR (dB) against the real f/4 render, all / in focus / defocused:", "",
             "| scene | row | all | in focus | defocused |", "|---|---|---|---|---|"]
    for r in report["renders"]:
        for label, p in r["psnr_db"].items():
            lines.append(f"| {r['scene']} | {label} | {p['all']:.2f} | {p['in_focus']:.2f} | {p['defocused']:.2f} |")
        t = r["targets"]
        lines.append(f"| {r['scene']} | targets | best renderer: {_mark(t['default_renderer_best'])} | "
                     f"{_mark(t['in_focus_kept'])} | {_mark(t['defocused_gained'])} |")
    lines += ["", f"Photos: in-focus PSNR against the unchanged photo (target ≥ {TARGET_PHOTO_IN_FOCUS_DB:g} dB) and the "
              f"estimated σ in the defocused regions, output / input (target ≥ {TARGET_PHOTO_BLUR_RATIO:g}×):", "",
              "| photo | row | in focus (dB) | defocused σ (px) | ratio |", "|---|---|---|---|---|"]
    for r in report["photos"]:
        for label, m in r["magnified"].items():
            lines.append(f"| {r['photo']} | {label} | {m['in_focus_psnr_db']:.2f} | "
                         f"{r['defocused_sigma_px_input']:.2f} → {m['defocused_sigma_px']:.2f} | {m['blur_ratio']:.2f} |")
        t = r["targets"]
        lines.append(f"| {r['photo']} | targets | {_mark(t['in_focus_kept'])} | | {_mark(t['defocused_gained'])} |")
    s = report.get("speed_12mp")
    if s is not None:
        lines += ["", f"12-MP magnification ({s['renderer']}, {s['shape'][1]}×{s['shape'][0]}): "
                  f"{s['magnify_s']:.1f} s ({_mark(s['meets_target'])}; 1-min load {s['load1'][0]:.1f} → "
                  f"{s['load1'][1]:.1f} on this machine's cores)"]
    return "\n".join(lines)
