"""``python -m repro.evaluate --photos`` (the presets on the real photos with hand-drawn regions) and
``--maps`` (defocus maps made by any tool, scored against the dataset's or the renders' ground truth)."""

from __future__ import annotations

import json
import sys

from ._evaluate_procedural import PROG
from ._evaluate_table import fmt_value, write_csv_json

__all__ = ["MAPS_ONLY", "MAP_ID_COLUMNS", "PHOTO_COLUMNS", "format_map_table", "format_photo_table", "main_maps", "main_photos",
           "photo_names", "photo_rows", "used"]


def photo_names() -> tuple[str, ...]:
    from experiments.photo_regions import available_photos

    return available_photos()


#: Options of the render evaluation that ``--photos`` does not take (flag, attribute, argparse default).
_SCENE_ONLY = (("--estimator", "estimator", None), ("--scenes", "scenes", None), ("--stages", "stages", False),
               ("--fnumber", "fnumber", None), ("--scene-size", "scene_size", "small"),
               ("--encoding", "encoding", ["srgb"]), ("--variant", "variant", None), ("--noise", "noise", None))


def _validate_photos(args):
    from experiments.photo_regions import SCORE_PRESETS, validate_photo_names
    from method import PRESETS

    bad = used(args, _SCENE_ONLY)
    if bad:
        raise ValueError(f"--photos does not take {', '.join(bad)}; allowed with --photos: --preset, --out, "
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
    """One flat dict per photo × preset from the ``photos`` figure's metrics
    (:func:`experiments.figS2_photos.photo_view`)."""
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
    """``--photos``: score the presets on the photos (the ``photos`` figure's cases, cached); exit status."""
    import dataclasses

    from defocus_cache import atomic_write_text
    from experiments.figS2_photos import photo_view
    from experiments.photo_regions import TARGET_AUC, TARGET_SHARE
    from experiments.cache_keys import code_fingerprint, to_jsonable
    from experiments.registry import FIGURES, library_versions

    from ._runner import FigureJob, engine_choice, run_figures

    from repro._cli import user_input

    with user_input():
        names, presets = _validate_photos(args)
    fig = FIGURES["photos"]
    config = dataclasses.replace(fig.config("full"), photos=tuple(names), presets=tuple(presets))
    workers, scheduler = engine_choice(args.workers, args.scheduler, command=PROG)
    if not args.quiet:
        print(f"scoring {', '.join(presets)} on {', '.join(names)} ...", file=sys.stderr)
    (run,) = run_figures([FigureJob(fig, config, "photos")], workers=workers, scheduler=scheduler, force=args.force,
                         progress=not args.quiet)
    if run.error is not None:
        raise RuntimeError(f"the photos figure failed: {run.error}\n{run.traceback}")
    rows = photo_rows(photo_view(run.data)["metrics"])
    info = {"columns": ["photo", "method_preset", *PHOTO_COLUMNS],
            "scores": "auc = P(σ_defocused > σ_in-focus) over pixel pairs, ties half (Mann–Whitney U); "
                      "in_focus_above_defocused_median = share of in-focus pixels with σ above the defocused "
                      "region's median",
            "targets": {"auc_min": TARGET_AUC, "in_focus_above_defocused_median_max": TARGET_SHARE},
            "regions": "experiments/photos/<photo>.json (hand-drawn, conservative)",
            "code": code_fingerprint(), "versions": library_versions(), "cache_hit": run.data.cached}
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
#: Options only ``--maps`` takes (flag, attribute, argparse default).
MAPS_ONLY = (("--dataset", "dataset", None), ("--protocol", "protocol", ["harness"]),
              ("--detection-threshold", "detection_threshold", 1.0), ("--png-scale", "png_scale", 1000.0))
#: Options ``--maps --dataset`` does not take (the dataset fixes the images).
_NOT_WITH_DATASET = (("--scenes", "scenes", None), ("--fnumber", "fnumber", None),
                     ("--scene-size", "scene_size", "small"), ("--variant", "variant", None))
#: Options of the method runs that ``--maps`` does not take.
_METHOD_ONLY = (("--preset", "preset", None), ("--estimator", "estimator", None), ("--stages", "stages", False),
                ("--encoding", "encoding", ["srgb"]), ("--photos", "photos", None), ("--force", "force", False),
                ("--noise", "noise", None))


def used(args, table) -> list[str]:
    return [flag for flag, attr, default in table if getattr(args, attr, default) != default]


def _validate_maps(args):
    """The ground truth and the protocols of ``--maps`` (ValueError, one line, on a bad combination)."""
    from experiments.external_maps import PROTOCOLS, DatasetTruth, RenderTruth

    bad = used(args, _METHOD_ONLY)
    if bad:
        raise ValueError(f"--maps does not take {', '.join(bad)}; allowed with --maps: --dataset, --protocol, "
                         "--detection-threshold, --png-scale, --scenes, --fnumber, --scene-size, --out, -q")
    protocols = PROTOCOLS.check_all(dict.fromkeys(args.protocol), what="protocol")
    if not args.maps.is_dir():
        raise ValueError(f"--maps {str(args.maps)!r} is not a folder; allowed: a folder of NAME.npy|npz|exr|png maps")
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"--out {str(args.out)!r} is a file; allowed: a folder")
    if args.dataset is not None:
        bad = used(args, _NOT_WITH_DATASET)
        if bad:
            raise ValueError(f"--maps --dataset does not take {', '.join(bad)} (the dataset fixes the images); "
                             "allowed: --protocol, --detection-threshold, --png-scale, --out, -q")
        return DatasetTruth(args.dataset), protocols
    from repro._cli import require_extras, scene_grid

    require_extras("render", command="repro.evaluate --maps without --dataset")
    if not used(args, _NOT_WITH_DATASET[:3]):  # the maps say which images: files named like a render
        truth = RenderTruth.named_by([args.maps], variant=args.variant)
    else:
        scenes, f_numbers = scene_grid(args.scenes, args.fnumber or [8.0, 4.0], args.scene_size)
        truth = RenderTruth(RenderTruth.grid(scenes, f_numbers, args.scene_size), variant=args.variant)
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
        body = [[r["image"], *(fmt_value(r.get(k)) for k, _ in cols)] for r in rows if r["protocol"] == protocol]
        body += [[f"mean of {m['n_images']}", *(fmt_value(m.get(k)) for k, _ in cols)]
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


