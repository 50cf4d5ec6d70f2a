"""Compare blur estimators on the rendered scenes: one metrics table per estimator × scene × aperture.

``python -m repro.evaluate [--preset paper robust zhuo_sim] [--estimator NAME ...] [--scenes NAME ...]
[--fnumber N ...] [--scene-preset small|full] [--encoding srgb linear] [--noise LEVEL ...] [--stages] [--out DIR]
[--force] [--variant V] [-q]``

``python -m repro.evaluate --procedural N --split dev|test|fresh [--scene-seed-start S] [--preset NAME ...]
[--fnumber N ...] [--scene-preset small|full] [--noise LEVEL ...] [--encoding ...] [--spp N]
[--workers W | --scheduler ADDR] [--out DIR] [--force] [-q]``

``python -m repro.evaluate --photos [NAME ...] [--preset NAME ...] [--out DIR] [--force] [-q]``

``python -m repro.evaluate --maps MAPDIR [--dataset DIR] [--protocol harness rtf syndof detection]
[--detection-threshold PX] [--png-scale S] [--out DIR] [-q]``

For every combination, the scene is rendered (cached), the whole pipeline runs with the estimator
(:func:`experiments.evaluation.evaluate_case`, cached per estimator, scene, f-number, preset and
encoding, keyed also by the code fingerprint), and the errors against the render's σ_gt are
tabulated, per method preset (:data:`method.PRESETS`) and estimator: the sparse blur measure at edge pixels, after the cross-bilateral filter, the dense map
over all / edge / textured pixels, RTF-normalised errors and the in-focus outlier fraction
(occlusion boundaries excluded everywhere). The table is printed and written to
``<out>/evaluate.csv`` and ``<out>/evaluate.json`` (atomically).

``--noise`` adds the sensor noise levels (:data:`scenes.display.NOISE_LEVELS`) as an axis. ``--procedural N``
scores the presets on N seeded scenes of a ``--split`` (tune on dev, report test and fresh), one Dask task
per scene, into the long results table (:mod:`repro._evaluate_procedural`, docs/procedural.md).

``--stages`` adds the stage attribution (:mod:`experiments.stage_attribution`): the error after
each stage (sparse, refined, dense over all / textured / edge pixels) for the estimated measures
and with oracle inputs (σ_gt at the detected edges fed into Eq. 3, or straight into Eq. 4), per
σ_gt bin; printed and written to ``<out>/stages.csv`` and ``<out>/stages.json``.

``--photos`` scores the method presets (default: paper, robust, zhuo_sim) on the real photos that
ship with hand-drawn "in focus" / "defocused" regions (:mod:`experiments.photo_regions`; default:
all of them) instead: the ranking AUC P(σ_defocused > σ_in-focus) and the share of in-focus pixels
above the defocused region's median, per photo × preset. The maps are the ``photos`` figure's
(cached, recomputed with ``--force``); the table is printed and written to ``<out>/photos.json``
and ``<out>/photos.md`` (atomically). An unknown photo or preset, or ``--photos`` with the scene
options: one line on stderr, exit status 2.

``--maps`` scores defocus maps made by any tool (:mod:`experiments.external_maps`): ``MAPDIR/NAME``
``.npy``/``.npz``/float ``.exr``/16-bit ``.png`` (σ × ``--png-scale``), ``NAME`` an image of the
``--dataset`` folder (``repro.dataset export``; needs neither the renderer nor the sweep engine) or,
without it, of the harness's own renders (``<scene>_f<N>_<scene_preset>``: the images of
``--scenes`` × ``--fnumber`` × ``--scene-preset`` when one is given, else every map named like one).
Per image and protocol the metrics are printed with their means and written to ``<out>/maps.json``
and ``<out>/maps.csv``. A missing, misnamed, wrongly sized, NaN-only or unreadable map is one line on
stderr naming it and the others are still scored; exit status 2 when none could be scored. A dataset
of an unknown major layout version is refused.

Estimators are read from :data:`method.BLUR_ESTIMATORS` at run time, so a newly registered
estimator is compared on the same ground truth with no other change. Unknown estimator or scene,
or a bad f-number: one line on stderr, exit status 2.
"""

from __future__ import annotations

import csv
import io
import json
import sys
import time
from pathlib import Path

from repro import _evaluate_procedural as _procedural

PROG = "python -m repro.evaluate"
DEFAULT_OUT = Path("report") / "evaluate"

#: Identifying columns, then metric columns (flattened ``experiments.evaluation.evaluate_result`` keys).
ID_COLUMNS = ("method_preset", "estimator", "scene", "f_number", "scene_preset", "encoding", "noise")
METRIC_COLUMNS = (
    "sparse_n", "sparse_mae", "sparse_median_ae", "sparse_rmse", "sparse_bias", "sparse_median_rel_error",
    "sparse_outlier_fraction",
    "refined_mae", "refined_median_ae", "refined_bias", "refined_outlier_fraction",
    "dense_all_mae", "dense_all_rmse", "dense_all_bias", "dense_all_outlier_fraction",
    "dense_edges_mae", "dense_edges_rmse", "dense_textured_n", "dense_textured_mae", "dense_textured_rmse",
    "rtf_nmse", "rtf_nmae",
    "in_focus_outliers_sparse_fraction", "in_focus_outliers_refined_fraction",
    "seconds_total",
)
#: Columns shown in the terminal table.
SHOWN = ("sparse_n", "sparse_mae", "sparse_median_ae", "sparse_outlier_fraction", "refined_mae",
         "dense_all_mae", "dense_textured_mae", "rtf_nmae", "in_focus_outliers_sparse_fraction")
_SHORT = {"sparse_n": "n_edge", "sparse_mae": "BM_MAE", "sparse_median_ae": "BM_medAE",
          "sparse_outlier_fraction": "BM_out>1", "refined_mae": "bCBF_MAE", "dense_all_mae": "map_MAE",
          "dense_textured_mae": "map_MAE_tex", "rtf_nmae": "RTF_nMAE",
          "in_focus_outliers_sparse_fraction": "infocus_out"}


def _parser():
    from method import BLUR_ESTIMATORS, PRESETS
    from repro._cli import ArgumentParser, add_force_option, add_quiet_option, add_variant_option, float_type
    from scenes import SCENES

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_variant_option(p)
    p.add_argument("--preset", nargs="+", default=None, metavar="NAME",
                   help=f"method presets to compare (registered: {', '.join(PRESETS)}; default: paper). "
                        "The render resolution is --scene-preset")
    p.add_argument("--estimator", nargs="+", default=None, metavar="NAME",
                   help=f"estimators to compare, overriding each preset's own (registered: {', '.join(BLUR_ESTIMATORS)}; "
                        "default: all registered with the paper preset alone, else each preset's own estimator)")
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help=f"scenes (default: all: {', '.join(SCENES)})")
    p.add_argument("--fnumber", nargs="+", type=float_type("--fnumber"), default=None, metavar="N",
                   help="apertures (default: 8 4; with --procedural: 8 4 2)")
    p.add_argument("--scene-preset", default="small", choices=("small", "full"),
                   help="render resolution preset (small 160x120, full 640x480; default small)")
    p.add_argument("--stages", action="store_true",
                   help="also print and write the stage attribution (errors after each stage, with oracle inputs)")
    p.add_argument("--encoding", nargs="+", default=["srgb"], choices=("srgb", "linear"),
                   help="input encoding(s) given to the method (default: srgb, as a camera stores it)")
    _procedural.add_options(p)
    p.add_argument("--photos", nargs="*", default=None, metavar="NAME",
                   help="score the presets on the real photos with hand-drawn regions instead of the renders "
                        f"(photos: {', '.join(_photo_names())}; default: all; presets default: "
                        "paper robust zhuo_sim)")
    p.add_argument("--maps", type=Path, default=None, metavar="MAPDIR",
                   help="score the defocus maps in MAPDIR (NAME.npy|npz|exr|png, σ in px, NAME an image of the "
                        "dataset) instead of running the method (docs/dataset.md)")
    p.add_argument("--dataset", type=Path, default=None, metavar="DIR",
                   help="with --maps: the ground truth of a repro.dataset export folder (default: the harness's "
                        "own renders of --scenes × --fnumber × --scene-preset, matched by name)")
    p.add_argument("--protocol", nargs="+", default=["harness"], metavar="NAME",
                   help="with --maps: harness (MAE, bias, per-σ bins, textured pixels), rtf, syndof, detection "
                        "(default: harness)")
    p.add_argument("--detection-threshold", type=float_type("--detection-threshold"), default=1.0, metavar="PX",
                   help="with --maps: blurred where σ > PX in the detection protocol (default 1)")
    p.add_argument("--png-scale", type=float_type("--png-scale"), default=1000.0, metavar="S",
                   help="with --maps: a 16-bit PNG map holds σ × S (default 1000: 0.001 px steps)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help=f"output folder (default: {DEFAULT_OUT}; with --procedural: {_procedural.DEFAULT_ROOT}, one "
                        "folder per evaluation in it)")
    add_force_option(p)
    add_quiet_option(p, what="no progress display")
    return p


def _photo_names() -> tuple[str, ...]:
    from experiments.photo_regions import available_photos

    return available_photos()


#: Options of the render evaluation that ``--photos`` does not take (flag, argparse default).
_SCENE_ONLY = (("--estimator", "estimator", None), ("--scenes", "scenes", None), ("--stages", "stages", False),
               ("--fnumber", "fnumber", None), ("--scene-preset", "scene_preset", "small"),
               ("--encoding", "encoding", ["srgb"]), ("--variant", "variant", None), ("--noise", "noise", None))


def _validate_photos(args):
    from experiments.photo_regions import SCORE_PRESETS, validate_photo_names
    from method import PRESETS

    used = [flag for flag, attr, default in _SCENE_ONLY if getattr(args, attr, default) != default]
    if used:
        raise ValueError(f"--photos does not take {', '.join(used)}; allowed with --photos: --preset, --out, "
                         "--force, -q")
    names = validate_photo_names(args.photos)
    presets = PRESETS.check_all(dict.fromkeys(args.preset or SCORE_PRESETS), what="preset")
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"--out {str(args.out)!r} is a file; allowed: a folder")
    return names, presets


#: Columns of the photo table (keys of experiments.photo_regions.score_defocus_map, plus seconds).
PHOTO_COLUMNS = ("auc", "in_focus_above_defocused_median", "in_focus_median_px", "defocused_median_px",
                 "n_in_focus", "n_defocused", "meets_targets", "seconds")


def photo_rows(metrics: dict) -> list[dict]:
    """One flat dict per photo × preset from the ``photos`` figure's metrics."""
    rows = []
    for photo, per in metrics["photos"].items():
        for preset in metrics["presets_scored"]:
            rows.append({"photo": photo, "method_preset": preset, **{c: per[preset][c] for c in PHOTO_COLUMNS}})
    return rows


def format_photo_table(rows, *, markdown: bool = False) -> str:
    """Terminal (or Markdown) table of :func:`photo_rows`."""
    head = ["photo", "preset", "AUC", "in-focus > defoc. median", "median σ in focus (px)",
            "median σ defocused (px)", "meets targets"]
    body = [[r["photo"], r["method_preset"], f"{r['auc']:.3f}", f"{100 * r['in_focus_above_defocused_median']:.1f} %",
             f"{r['in_focus_median_px']:.2f}", f"{r['defocused_median_px']:.2f}",
             "yes" if r["meets_targets"] else "no"] for r in rows]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        return "\n".join(lines + ["| " + " | ".join(b) + " |" for b in body])
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths))]
    return "\n".join(lines + ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body])


def main_photos(args) -> int:
    """``--photos``: score the presets on the photos (the ``photos`` figure's cached compute); exit status."""
    import dataclasses

    from defocus_cache import atomic_write_text
    from experiments.photo_regions import TARGET_AUC, TARGET_SHARE
    from experiments.registry import FIGURES, code_fingerprint, compute_cached, library_versions, to_jsonable

    from repro._cli import user_input

    with user_input():
        names, presets = _validate_photos(args)
    fig = FIGURES["photos"]
    config = dataclasses.replace(fig.config("full"), photos=tuple(names), presets=tuple(presets))
    if not args.quiet:
        print(f"scoring {', '.join(presets)} on {', '.join(names)} ...", file=sys.stderr)
    result = compute_cached(fig, config, force=args.force)
    rows = photo_rows(result.metrics)
    info = {"columns": ["photo", "method_preset", *PHOTO_COLUMNS],
            "scores": "auc = P(σ_defocused > σ_in-focus) over pixel pairs, ties half (Mann–Whitney U); "
                      "in_focus_above_defocused_median = share of in-focus pixels with σ above the defocused "
                      "region's median",
            "targets": {"auc_min": TARGET_AUC, "in_focus_above_defocused_median_max": TARGET_SHARE},
            "regions": "experiments/photos/<photo>.json (hand-drawn, conservative)",
            "code": code_fingerprint(), "versions": library_versions(), "cache_hit": result.cached}
    args.out.mkdir(parents=True, exist_ok=True)
    json_path, md_path = args.out / "photos.json", args.out / "photos.md"
    atomic_write_text(json_path, json.dumps(to_jsonable({**info, "rows": rows}), indent=1, sort_keys=True) + "\n")
    atomic_write_text(md_path, "# Defocus maps on real photos with hand-drawn regions\n\n"
                      f"Targets: AUC ≥ {TARGET_AUC:g} and at most {100 * TARGET_SHARE:g} % of in-focus pixels above "
                      "the defocused region's median σ.\n\n" + format_photo_table(rows, markdown=True) + "\n")
    print(format_photo_table(rows))
    for p in (json_path, md_path):
        print(f"  {p}")
    return 0


def _validate(args):
    from experiments.evaluation import validate_estimators
    from method import BLUR_ESTIMATORS, PRESETS
    from repro._cli import scene_grid

    try:
        presets = PRESETS.check_all(dict.fromkeys(args.preset or ["paper"]), what="preset")
    except ValueError as exc:
        hint = " (the render resolution is --scene-preset small|full)" if {"small", "full"} & set(args.preset or ()) else ""
        raise ValueError(f"{exc}{hint}") from None
    if args.estimator:
        estimators = validate_estimators(dict.fromkeys(args.estimator))
    elif args.preset is None:
        estimators = validate_estimators(list(BLUR_ESTIMATORS))
    else:
        estimators = (None,)
    scenes, f_numbers = scene_grid(args.scenes, args.fnumber or [8.0, 4.0], args.scene_preset, out=args.out)
    return presets, estimators, scenes, f_numbers, list(dict.fromkeys(args.encoding)), _procedural.noises(args.noise)


def table_rows(cases) -> list[dict]:
    """One flat dict per :class:`experiments.evaluation.EvaluationCase`: ID_COLUMNS + METRIC_COLUMNS."""
    from experiments.evaluation import flatten_metrics

    rows = []
    for case in cases:
        flat = flatten_metrics(case.metrics)
        row = {c: case.key["preset" if c == "scene_preset" else c] for c in ID_COLUMNS}
        for c in METRIC_COLUMNS:
            if c == "seconds_total":
                row[c] = flat.get("timings_total_s")
            else:
                row[c] = flat.get(c)
        rows.append(row)
    return rows


def _fmt(v) -> str:
    if v is None:
        return "nan"
    if isinstance(v, float):
        return f"{v:.3f}"
    return str(v)


def format_table(rows) -> str:
    """Fixed-width terminal table of the :data:`SHOWN` columns."""
    head = [*ID_COLUMNS[:4], *ID_COLUMNS[5:7], *(_SHORT[c] for c in SHOWN)]
    body = [[str(r["method_preset"]), str(r["estimator"]), str(r["scene"]), f"{r['f_number']:g}", str(r["encoding"]),
             str(r["noise"]), *(_fmt(r[c]) for c in SHOWN)] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body]
    return "\n".join(lines)


def write_csv_json(out_dir: Path, stem: str, rows, fields, doc: dict) -> list[Path]:
    """Write ``<stem>.csv`` (``fields`` of every row; None as empty) and ``<stem>.json`` (``doc``)
    atomically into ``out_dir``; returns the two paths."""
    from experiments.registry import to_jsonable
    from defocus_cache import atomic_write_text

    out_dir.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(fields), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in fields})
    csv_path, json_path = out_dir / f"{stem}.csv", out_dir / f"{stem}.json"
    atomic_write_text(csv_path, buf.getvalue())
    atomic_write_text(json_path, json.dumps(to_jsonable(doc), indent=1, sort_keys=True) + "\n")
    return [csv_path, json_path]


def write_outputs(rows, out_dir: Path, info: dict) -> list[Path]:
    """Write ``evaluate.csv`` and ``evaluate.json`` atomically; returns the paths."""
    return write_csv_json(out_dir, "evaluate", rows, [*ID_COLUMNS, *METRIC_COLUMNS], {**info, "rows": rows})


STAGE_ID_COLUMNS = ("method_preset", "estimator", "scene", "f_number", "scene_preset", "encoding", "noise")


def stage_table_rows(cases) -> list[dict]:
    """Stage-attribution rows (:func:`experiments.stage_attribution.stage_rows`) of every case."""
    from experiments.stage_attribution import stage_rows

    rows = []
    for case in cases:
        ids = {c: case.key["preset" if c == "scene_preset" else c] for c in STAGE_ID_COLUMNS}
        rows += stage_rows(case.metrics["stages"], **ids)
    return rows


def format_stage_table(rows) -> str:
    """Terminal table: MAE (bias) per input × stage, overall and per σ_gt bin with pixels in it."""
    if not rows:
        return "(no stage rows)"
    bins = [k[4:] for k in rows[0] if k.startswith("mae_")]
    used = [b for b in bins if any((r.get(f"n_{b}") or 0) > 0 for r in rows)]
    head = ["preset", "scene", "f", "input", "stage", "n", "all", *(f"σ[{b.replace('_', ',')})" for b in used)]

    def cell(m, b):
        return "-" if m is None else f"{m:.2f}({b:+.2f})"

    body = [[str(r["method_preset"]), str(r["scene"]), f"{r['f_number']:g}", r["input"], r["stage"], str(r["n"]),
             cell(r["mae"], r["bias"]), *(cell(r[f"mae_{b}"], r[f"bias_{b}"]) for b in used)] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    lines = ["MAE (bias), px, per σ_gt bin [lo,hi) px; oracle_refine = σ_gt at the detected edges into Eq. 3; "
             "oracle_propagate = σ_gt at the edges into Eq. 4",
             "  ".join(h.ljust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body]
    return "\n".join(lines)


def write_stage_outputs(rows, out_dir: Path, info: dict) -> list[Path]:
    """Write ``stages.csv`` and ``stages.json`` atomically; returns the paths."""
    meta = {k: v for k, v in info.items() if k != "columns"}
    return write_csv_json(out_dir, "stages", rows, list(rows[0]) if rows else list(STAGE_ID_COLUMNS),
                          {**meta, "rows": rows})


#: Options only ``--maps`` takes (flag, attribute, argparse default).
_MAPS_ONLY = (("--dataset", "dataset", None), ("--protocol", "protocol", ["harness"]),
              ("--detection-threshold", "detection_threshold", 1.0), ("--png-scale", "png_scale", 1000.0))
#: Options ``--maps --dataset`` does not take (the dataset fixes the images).
_NOT_WITH_DATASET = (("--scenes", "scenes", None), ("--fnumber", "fnumber", None),
                     ("--scene-preset", "scene_preset", "small"), ("--variant", "variant", None))
#: Options of the method runs that ``--maps`` does not take.
_METHOD_ONLY = (("--preset", "preset", None), ("--estimator", "estimator", None), ("--stages", "stages", False),
                ("--encoding", "encoding", ["srgb"]), ("--photos", "photos", None), ("--force", "force", False),
                ("--noise", "noise", None))


def _used(args, table) -> list[str]:
    return [flag for flag, attr, default in table if getattr(args, attr, default) != default]


def _validate_maps(args):
    """The ground truth and the protocols of ``--maps`` (ValueError, one line, on a bad combination)."""
    from experiments.external_maps import PROTOCOLS, DatasetTruth, RenderTruth

    used = _used(args, _METHOD_ONLY)
    if used:
        raise ValueError(f"--maps does not take {', '.join(used)}; allowed with --maps: --dataset, --protocol, "
                         "--detection-threshold, --png-scale, --scenes, --fnumber, --scene-preset, --out, -q")
    protocols = PROTOCOLS.check_all(dict.fromkeys(args.protocol), what="protocol")
    if not args.maps.is_dir():
        raise ValueError(f"--maps {str(args.maps)!r} is not a folder; allowed: a folder of NAME.npy|npz|exr|png maps")
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"--out {str(args.out)!r} is a file; allowed: a folder")
    if args.dataset is not None:
        used = _used(args, _NOT_WITH_DATASET)
        if used:
            raise ValueError(f"--maps --dataset does not take {', '.join(used)} (the dataset fixes the images); "
                             "allowed: --protocol, --detection-threshold, --png-scale, --out, -q")
        return DatasetTruth(args.dataset), protocols
    from repro._cli import require_extras, scene_grid

    require_extras("render", command="repro.evaluate --maps without --dataset")
    if not _used(args, _NOT_WITH_DATASET[:3]):  # the maps say which images: files named like a render
        truth = RenderTruth.named_by([args.maps], variant=args.variant)
    else:
        scenes, f_numbers = scene_grid(args.scenes, args.fnumber or [8.0, 4.0], args.scene_preset)
        truth = RenderTruth(RenderTruth.grid(scenes, f_numbers, args.scene_preset), variant=args.variant)
    if args.variant:
        from scenes.backend import select_variant

        select_variant(args.variant)
    return truth, protocols


#: Identifying columns of the ``--maps`` table.
MAP_ID_COLUMNS = ("image", "scene", "protocol", "map")


def format_map_table(rows, summary) -> str:
    """Per image and protocol the headline metrics (:data:`experiments.external_maps.HEADLINE`), then the means."""
    from experiments.external_maps import HEADLINE

    lines = []
    for protocol in dict.fromkeys(r["protocol"] for r in summary):
        cols = HEADLINE[protocol]
        head = ["image", *(label for _, label in cols)]
        body = [[r["image"], *(_fmt(r.get(k)) for k, _ in cols)] for r in rows if r["protocol"] == protocol]
        body += [[f"mean of {m['n_images']}", *(_fmt(m.get(k)) for k, _ in cols)]
                 for m in summary if m["protocol"] == protocol]
        widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
        lines += [f"protocol {protocol}:", "  ".join(h.ljust(w) for h, w in zip(head, widths))]
        lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body] + [""]
    return "\n".join(lines).rstrip()


def main_maps(args) -> int:
    """``--maps``: score external maps; exit status 0 when at least one map was scored, else 2."""
    from experiments.external_maps import MAP_SUFFIXES, score_folder, summarize

    from repro._cli import user_input

    with user_input():
        truth, protocols = _validate_maps(args)
    result = score_folder(args.maps, truth, protocols=protocols, threshold_px=args.detection_threshold,
                          png_scale=args.png_scale)
    for line in result.problems:
        print(f"{PROG}: skipped {line}", file=sys.stderr)
    if not result.scored:
        print(f"{PROG}: error: no map in {args.maps} could be scored (expected NAME{'|'.join(MAP_SUFFIXES)} "
              f"for the {len(truth.names)} image(s) of {truth.source})", file=sys.stderr)
        return 2
    summary = summarize(result.rows)
    info = {"maps": str(args.maps), "ground_truth": truth.source, "protocols": protocols,
            "detection_threshold_px": args.detection_threshold, "png_scale": args.png_scale,
            "occlusion_bands": "excluded in every protocol", "skipped": result.problems}
    if isinstance(getattr(truth, "manifest", None), dict):
        info["layout_version"] = truth.manifest.get("layout_version")
    fields = list(MAP_ID_COLUMNS) + sorted({k for r in result.rows for k in r} - set(MAP_ID_COLUMNS))
    csv_path, json_path = write_csv_json(args.out, "maps", result.rows, fields,
                                         {**info, "summary": summary, "rows": result.rows})
    if not args.quiet:
        print(format_map_table(result.rows, summary))
    for p in (json_path, csv_path):
        print(f"  {p}")
    return 0


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    if args.procedural is not None:
        from repro._cli import require_extras

        require_extras("render", command="repro.evaluate --procedural")
        return _procedural.main_procedural(args)
    from repro._cli import user_input

    used = _used(args, _procedural.PROCEDURAL_ONLY)
    if used:
        with user_input():
            raise ValueError(f"{', '.join(used)} is invalid without --procedural; allowed: with --procedural N")
    if args.out is None:
        args.out = DEFAULT_OUT
    if args.maps is not None:
        return main_maps(args)
    used = _used(args, _MAPS_ONLY)
    if used:
        with user_input():
            raise ValueError(f"{', '.join(used)} is invalid without --maps; allowed: with --maps MAPDIR")
    from repro._cli import require_extras

    require_extras("render", command="repro.evaluate")
    if args.photos is not None:
        return main_photos(args)
    with user_input():
        presets, estimators, scenes, f_numbers, encodings, noises = _validate(args)
    if args.variant:
        from scenes.backend import select_variant

        select_variant(args.variant)
    from tqdm import tqdm

    from experiments.evaluation import EVAL_VERSION, evaluate_case
    from experiments.registry import code_fingerprint, library_versions

    combos = [(pr, e, s, n, enc, nz) for s in scenes for n in f_numbers for enc in encodings for nz in noises
              for pr in presets for e in estimators]
    cases = []
    t0 = time.perf_counter()
    with tqdm(combos, desc="evaluate", unit="case", file=sys.stderr, disable=args.quiet) as bar:
        for pr, e, s, n, enc, nz in bar:
            bar.set_postfix_str(f"{pr} {e or ''} {s} f/{n:g} {enc} {nz}")
            cases.append(evaluate_case(e, s, f_number=n, preset=args.scene_preset, encoding=enc, noise=nz,
                                       method_preset=pr, variant=args.variant, force=args.force))
    rows = table_rows(cases)
    info = {
        "columns": [*ID_COLUMNS, *METRIC_COLUMNS],
        "sigma_convention": "line_spread: sigma_gt = sqrt((c/4)^2 + 1/12) px (box pixel filter)",
        "regions": "sparse/refined: edge pixels; dense: all / edges / textured (local std > 0.02); "
                   "occlusion boundaries excluded everywhere",
        "eval_version": EVAL_VERSION,
        "code": code_fingerprint(),
        "versions": library_versions(),
        "cache_hits": sum(c.cached for c in cases),
        "seconds": time.perf_counter() - t0,
    }
    paths = write_outputs(rows, args.out, info)
    print(format_table(rows))
    if args.stages:
        srows = stage_table_rows(cases)
        paths += write_stage_outputs(srows, args.out, info)
        print()
        print(format_stage_table(srows))
    for p in paths:
        print(f"  {p}")
    return 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
