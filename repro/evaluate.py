"""Compare blur estimators on the rendered scenes: one metrics table per estimator × scene × aperture.

``python -m repro.evaluate [--preset paper robust zhuo_sim] [--estimator NAME ...] [--scenes NAME ...]
[--fnumber N ...] [--scene-size small|full] [--encoding srgb linear] [--noise LEVEL ...] [--stages] [--out DIR]
[--force] [--variant V] [-q]``

``python -m repro.evaluate --procedural N --split dev|test|fresh [--scene-seed-start S] [--preset NAME ...]
[--estimator NAME ...] [--fnumber N ...] [--scene-size small|full] [--noise LEVEL ...] [--encoding ...] [--spp N]
[--workers W | --scheduler ADDR] [--out DIR] [--force] [-q]``

``python -m repro.evaluate --photos [NAME ...] [--preset NAME ...] [--out DIR] [--force] [-q]``

``python -m repro.evaluate --maps MAPDIR [--dataset DIR] [--protocol harness rtf syndof detection]
[--detection-threshold PX] [--png-scale S] [--out DIR] [-q]``

For every combination, the scene is rendered (cached), the whole pipeline runs with the estimator
(:func:`experiments.units.evaluate_case`, scored by :func:`experiments.scoring.score_render` and kept in
the one case store per estimator, scene, f-number, preset, encoding and noise, keyed also by the code
fingerprint), and the errors against the render's σ_gt are
tabulated, per method preset (:data:`method.PRESETS`) and estimator: the sparse blur measure at edge pixels, after the cross-bilateral filter, the dense map
over all / edge / textured pixels, RTF-normalised errors and the in-focus outlier fraction
(occlusion boundaries excluded everywhere). The trivial baselines (:mod:`experiments.baselines`:
constant maps at the scene's median σ_gt and at the pixel filter's floor; their dense metrics only) are
rows of the same table. The table is printed and written to
``<out>/evaluate.csv`` and ``<out>/evaluate.json`` (atomically). Every mode writes under the git-ignored
``report/quick/`` unless ``--out`` says otherwise (named scenes, ``--photos``, ``--maps``:
``report/quick/evaluate``; ``--procedural``: ``report/quick/evaluations``): an evaluation never changes
the committed report by default. The report's generalisation section reads the procedural evaluations
of ``report/evaluations``, written there only on purpose (``--procedural N --split dev|test --out
report/evaluations``).

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
without it, of the harness's own renders (``<scene>_f<N>_<scene_size>``: the images of
``--scenes`` × ``--fnumber`` × ``--scene-size`` when one is given, else every map named like one).
Per image and protocol the metrics are printed with their means and written to ``<out>/maps.json``
and ``<out>/maps.csv``. A missing, misnamed, wrongly sized, NaN-only or unreadable map is one line on
stderr naming it and the others are still scored; exit status 2 when none could be scored. A dataset
of an unknown major layout version is refused.

Estimators are read from :data:`method.BLUR_ESTIMATORS` at run time, so a newly registered
estimator is compared on the same ground truth with no other change; one of another package is
registered by ``--estimator-module pkg.module:function`` or its entry point (:mod:`repro._plugins`), here
and on every Dask worker. Unknown estimator or scene, or a bad f-number: one line on stderr, exit status 2.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from experiments.evaluation_columns import METRIC_COLUMNS
from repro import _evaluate_procedural as _procedural
from repro._report_paths import EVALUATIONS, QUICK_EVALUATE

from ._evaluate_inputs import MAPS_ONLY, MAP_ID_COLUMNS, PHOTO_COLUMNS, main_maps, main_photos, photo_names, photo_rows, used
from ._evaluate_table import (ID_COLUMNS, SHOWN, STAGE_ID_COLUMNS, format_stage_table, format_table,
                              stage_table_rows, table_rows, write_csv_json, write_outputs, write_stage_outputs)

PROG = "python -m repro.evaluate"
#: Default ``--out`` of the named-scene, ``--photos`` and ``--maps`` evaluations (git-ignored: exploratory).
DEFAULT_OUT = QUICK_EVALUATE
__all__ = ["DEFAULT_OUT", "ID_COLUMNS", "MAP_ID_COLUMNS", "PHOTO_COLUMNS", "PROG", "SHOWN",
           "STAGE_ID_COLUMNS", "evaluate_named", "format_stage_table", "format_table", "main", "main_maps", "main_photos", "photo_rows",
           "stage_table_rows", "table_rows", "write_csv_json", "write_outputs", "write_stage_outputs"]


def _parser():
    from method import BLUR_ESTIMATORS, PRESETS
    from method.luma import ENCODINGS
    from repro._cli import (ArgumentParser, add_force_option, add_plugin_options, add_quiet_option,
                            add_scene_size_option, add_variant_option, float_type)
    from scenes import SCENES

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_variant_option(p)
    p.add_argument("--preset", nargs="+", default=None, metavar="NAME",
                   help=f"method parameter sets (method.PRESETS): {', '.join(PRESETS)}. Default: paper "
                        "(with --procedural: all registered, with --estimator paper; with --photos: paper robust "
                        "zhuo_sim). The render size is --scene-size")
    p.add_argument("--estimator", nargs="+", default=None, metavar="NAME",
                   help=f"estimators to compare, overriding each preset's own (registered: {', '.join(BLUR_ESTIMATORS)}, "
                        "plus --estimator-module and installed entry points; default: all registered with the paper "
                        "preset alone, else each preset's own estimator; with --procedural: each preset, default "
                        "paper, runs once with each)")
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help=f"scenes (default: all: {', '.join(SCENES)})")
    p.add_argument("--fnumber", nargs="+", type=float_type("--fnumber"), default=None, metavar="N",
                   help="apertures (default: 8 4; with --procedural: 8 4 2)")
    add_scene_size_option(p)
    p.add_argument("--stages", action="store_true",
                   help="also print and write the stage attribution (errors after each stage, with oracle inputs)")
    p.add_argument("--encoding", nargs="+", default=["srgb"], choices=tuple(ENCODINGS),
                   help="input encoding(s) of the render given to the method and declared to it (default: "
                        "srgb, as a camera stores it; linear: the radiance)")
    _procedural.add_options(p)
    p.add_argument("--photos", nargs="*", default=None, metavar="NAME",
                   help="score the presets on the real photos with hand-drawn regions instead of the renders "
                        f"(photos: {', '.join(photo_names())}; default: all; presets default: "
                        "paper robust zhuo_sim)")
    p.add_argument("--maps", type=Path, default=None, metavar="MAPDIR",
                   help="score the defocus maps in MAPDIR (NAME.npy|npz|exr|png, σ in px, NAME an image of the "
                        "dataset) instead of running the method (docs/dataset.md)")
    p.add_argument("--dataset", type=Path, default=None, metavar="DIR",
                   help="with --maps: the ground truth of a repro.dataset export folder (default: the harness's "
                        "own renders of --scenes × --fnumber × --scene-size, matched by name)")
    p.add_argument("--protocol", nargs="+", default=["harness"], metavar="NAME",
                   help="with --maps: harness (MAE, bias, per-σ bins, textured pixels), rtf, syndof, detection "
                        "(default: harness)")
    p.add_argument("--detection-threshold", type=float_type("--detection-threshold"), default=1.0, metavar="PX",
                   help="with --maps: blurred where σ > PX in the detection protocol (default 1)")
    p.add_argument("--png-scale", type=float_type("--png-scale"), default=1000.0, metavar="S",
                   help="with --maps: a 16-bit PNG map holds σ × S (default 1000: 0.001 px steps)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help=f"output folder (default: {DEFAULT_OUT}; with --procedural: {_procedural.DEFAULT_ROOT}, one "
                        "folder per evaluation in it; both git-ignored. The committed report shows the procedural "
                        f"evaluations of {EVALUATIONS}: write there only on purpose, with --out {EVALUATIONS})")
    add_force_option(p)
    add_quiet_option(p, what="no progress display")
    add_plugin_options(p)
    return p


def _validate(args):
    from experiments.evaluation import validate_estimators
    from method import BLUR_ESTIMATORS, PRESETS
    from repro._cli import scene_grid

    try:
        presets = PRESETS.check_all(dict.fromkeys(args.preset or ["paper"]), what="preset")
    except ValueError as exc:
        hint = " (the render size is --scene-size small|full)" if {"small", "full"} & set(args.preset or ()) else ""
        raise ValueError(f"{exc}{hint}") from None
    if args.estimator:
        estimators = validate_estimators(dict.fromkeys(args.estimator))
    elif args.preset is None:
        estimators = validate_estimators(list(BLUR_ESTIMATORS))
    else:
        estimators = (None,)
    scenes, f_numbers = scene_grid(args.scenes, args.fnumber or [8.0, 4.0], args.scene_size, out=args.out)
    return presets, estimators, scenes, f_numbers, list(dict.fromkeys(args.encoding)), _procedural.noises(args.noise)


def _evaluate_cases(args, presets, estimators, scenes, f_numbers, encodings, noises):
    """Every case of the named-scene evaluation through the case runner; returns the
    :class:`experiments.units.EvaluationCase`-like records (key, metrics, cached) in grid order."""
    import types

    from experiments.units import EvaluateConfig

    from ._runner import engine_choice

    config = EvaluateConfig(presets=tuple(presets), estimators=tuple(estimators), scenes=tuple(scenes),
                            f_numbers=tuple(float(n) for n in f_numbers), scene_size=args.scene_size,
                            encodings=tuple(encodings), noises=tuple(noises), variant=args.variant)
    workers, scheduler = engine_choice(args.workers, args.scheduler, command=PROG)
    data = evaluate_named(config, workers=workers, scheduler=scheduler, force=args.force, progress=not args.quiet)
    return [types.SimpleNamespace(key=o.info["key"], metrics=o.info["metrics"], cached=o.cached)
            for o in data.outputs.values()], data


def evaluate_named(config, *, workers=None, scheduler=None, force=False, progress=True):
    """Every case of an :class:`experiments.units.EvaluateConfig` (presets and baselines on named scenes)
    through the case runner (``workers`` None: one per core); returns the run's figure data (``outputs`` in
    grid order, ``rows()`` the long results rows)."""
    from experiments.units import EVALUATE

    from ._runner import FigureJob, run_figures

    (run,) = run_figures([FigureJob(EVALUATE, config, "evaluate")], workers=workers, scheduler=scheduler,
                         force=force, progress=progress, desc="evaluate")
    if run.error is not None:
        raise RuntimeError(f"an evaluation case failed: {run.error}\n{run.traceback}")
    return run.data


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    if args.procedural is not None:
        from repro._cli import require_extras

        require_extras("render", command="repro.evaluate --procedural")
        return _procedural.main_procedural(args)
    from repro._cli import CLIError, user_input

    bad = used(args, _procedural.PROCEDURAL_ONLY)
    if bad:
        raise CLIError(f"{', '.join(bad)} is invalid without --procedural; allowed: with --procedural N")
    if args.out is None:
        args.out = DEFAULT_OUT
    if args.maps is not None:
        return main_maps(args)
    bad = used(args, MAPS_ONLY)
    if bad:
        raise CLIError(f"{', '.join(bad)} is invalid without --maps; allowed: with --maps MAPDIR")
    from repro._cli import require_extras

    require_extras("render", command="repro.evaluate")
    if args.photos is not None:
        return main_photos(args)
    with user_input():
        presets, estimators, scenes, f_numbers, encodings, noises = _validate(args)
    if args.variant:
        from scenes.backend import select_variant

        select_variant(args.variant)
    from experiments.cache_keys import code_fingerprint
    from experiments.registry import library_versions
    from experiments.units import EVAL_VERSION
    from experiments.results_table import write_results

    t0 = time.perf_counter()
    cases, data = _evaluate_cases(args, presets, estimators, scenes, f_numbers, encodings, noises)
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
    long_rows = [{**r, "source": "scenes"} for r in data.rows()]
    paths += write_results(args.out, long_rows, {k: v for k, v in info.items() if k != "columns"})
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
