"""Experiment sweeps on Dask distributed: one machine by default, a cluster when pointed at one.

``python -m repro.sweep [--scenes NAME ...] [--camera PRESET ...] [--fnumber 8 4] [--estimator NAME ...]
[--preset NAME ...] [--param FIELD=V1,V2 ...] [--seeds 0 1] [--scene-size small|full]
[--encoding srgb linear] [--workers N | --scheduler tcp://HOST:PORT] [--metric COLUMN] [--variant V] [--force]
[-q] --out DIR``

The grid is the product scenes × cameras × f-numbers × seeds (one *render* each) × method presets ×
estimators × parameter values × encodings (one *cell* each). Every cell renders through the render
cache, runs the whole pipeline and is scored against σ_gt by the one scorer of every render
(:func:`experiments.scoring.score_render`, the metrics of :mod:`repro.evaluate`). Renders and cells are
cases of the case runner (:mod:`experiments.sweep_cells`, :mod:`repro._runner`): one task per distinct
render, its cells depend on it.

Engine: a :class:`dask.distributed.LocalCluster` of ``--workers`` single-threaded processes (default:
one per core; 1: in this process) whose dashboard address is printed, or an existing cluster
(``--scheduler``, started with ``dask scheduler`` / ``dask worker``; its workers must see the same
``$DEFOCUS_CACHE_DIR``). Progress: cases done / total with an ETA (tqdm). Each finished case is stored at
once, atomically, in the one case store (``$DEFOCUS_CACHE_DIR/figures``), keyed by its inputs and full
parameters, the code fingerprint of method/scenes/experiments, the estimator's source and the library
versions (never by the rest of the grid); the same command again (after Ctrl-C, a crash or a killed
worker) reads finished cells back instead of recomputing them (``--force`` recomputes them). A worker that dies mid-task has its
tasks rerun elsewhere by the scheduler.

Outputs (atomic): ``DIR/results.parquet`` and ``DIR/results.csv``, the long results table of every
evaluation (docs/results-schema.md: one row per cell × metric, ``source`` = sweep, ``variant`` = the
method variant); ``DIR/results_wide.parquet``, its wide view (one row per cell: every input, the method
variant label, the Mitsuba variant, every metric; the same rows serial or parallel); ``DIR/timings.parquet``
(per cell, in the same order: worker, seconds, read back or not); ``DIR/<metric>.png`` (the chosen metric
per method variant) and a summary printed on the terminal.

Bad grid (unknown scene, camera, estimator, preset, parameter name or value, f-number, metric): one
line on stderr and exit status 2 before any cluster is started or task submitted.
"""

from __future__ import annotations

import sys
from pathlib import Path

from experiments.sweep_table import metric_unit, read_table, summary, write_table

from ._sweep_engine import SweepRun, long_rows, run_sweep, sweep_cases
from ._sweep_grid import (DEFAULT_METRIC, INFO_COLUMNS, INPUT_COLUMNS, SCENE_CAMERA, Cell, Grid, Render, build_grid,
                          parse_param_value, parse_params)

__all__ = ["DEFAULT_METRIC", "INFO_COLUMNS", "INPUT_COLUMNS", "PROG", "SCENE_CAMERA", "Cell", "Grid", "Render",
           "SweepRun", "build_grid", "format_summary", "long_rows", "main", "metric_unit", "parse_param_value",
           "parse_params", "plot_metric", "read_table", "run_sweep", "summary", "sweep_cases", "write_table"]

PROG = "python -m repro.sweep"

#: Method presets (keys of ``method.PRESETS``) swept when ``--preset`` is not given: the literal
#: reproduction, the baseline every other variant of a sweep is compared with.
DEFAULT_PRESETS = ("paper",)


def plot_metric(rows: list[dict], metric: str, path: Path) -> Path:
    """:func:`experiments.plotting.sweep.plot_metric` (matplotlib imported only when called)."""
    from experiments.plotting.sweep import plot_metric as plot

    return plot(rows, metric, path)


def format_summary(rows: list[dict], metric: str) -> str:
    """Terminal table of :func:`summary`."""
    s = summary(rows, metric)
    head = ["method variant", "cells", f"mean {metric}", "median", "min", "max"]

    def f(x):
        return "-" if x is None else f"{x:.3f}"

    body = [[r["method_variant"], str(r["cells"]), f(r["mean"]), f(r["median"]), f(r["min"]), f(r["max"])] for r in s]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]
    lines = [f"{metric} ({metric_unit(metric)}) per method variant, over scenes × cameras × f-numbers × seeds × encodings",
             "  ".join(h.ljust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body]
    return "\n".join(lines)


def _parser():
    from method import BLUR_ESTIMATORS
    from method.luma import ENCODINGS
    from scenes import CAMERA_PRESETS, SCENES

    from ._cli import (ArgumentParser, add_force_option, add_plugin_options, add_preset_option, add_quiet_option,
                       add_scene_size_option, add_variant_option, float_type, hidden_alias, int_type)
    from ._runner import add_engine_options

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_variant_option(p)
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help=f"scenes (default: all: {', '.join(SCENES)})")
    p.add_argument("--camera", nargs="+", default=None, metavar="PRESET",
                   help=f"camera presets, same field of view ({', '.join(CAMERA_PRESETS)}; default: each scene's own)")
    p.add_argument("--fnumber", nargs="+", type=float_type("--fnumber"), default=[8.0, 4.0], metavar="N",
                   help="apertures (default: 8 4)")
    p.add_argument("--estimator", nargs="+", default=None, metavar="NAME",
                   help=f"blur estimators ({BLUR_ESTIMATORS.describe()}; default: each preset's own)")
    add_preset_option(p, default=DEFAULT_PRESETS, many=True)
    p.add_argument("--param", action="append", default=[], metavar="FIELD=V1,V2",
                   help="sweep a DefocusParams field over values (repeatable), e.g. --param alpha=0.1,0.5,1")
    p.add_argument("--seeds", nargs="+", type=int_type("--seeds", minimum=0), default=[0], metavar="S",
                   help="render sampler seeds (default: 0)")
    add_scene_size_option(p)
    p.add_argument("--encoding", nargs="+", default=["srgb"], choices=tuple(ENCODINGS),
                   help="input encodings given to the method (default: srgb)")
    add_engine_options(p, what="cells", one_in_process=False)
    p.add_argument("--metric", default=DEFAULT_METRIC, metavar="COLUMN",
                   help=f"metric of the plot and summary (default {DEFAULT_METRIC})")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    add_force_option(p, what="recompute every cell even when the output folder holds it (the new cell replaces it)")
    add_quiet_option(p, what="no progress bar")
    hidden_alias(p, "--no-progress", dest="quiet", action="store_true")
    add_plugin_options(p)
    return p


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    from scenes import SCENES

    from ._cli import CLIError, user_input

    args = _parser().parse_args(argv)
    if args.out.exists() and not args.out.is_dir():
        raise CLIError(f"--out {str(args.out)!r} is a file; allowed: a folder")
    if args.scheduler is not None and "://" not in args.scheduler:
        raise CLIError(f"--scheduler {args.scheduler!r} is invalid; allowed: an address like tcp://HOST:PORT")
    with user_input():
        grid = build_grid(scenes=args.scenes or list(SCENES), cameras=args.camera, f_numbers=args.fnumber,
                          estimators=args.estimator, presets=args.preset, params=parse_params(args.param),
                          seeds=args.seeds, scene_preset=args.scene_size, encodings=args.encoding,
                          metric=args.metric, variant=args.variant)
    if not args.quiet:
        print(f"sweep: {len(grid.cells)} cells, {len(grid.renders)} distinct renders -> {args.out}", file=sys.stderr)
    run = run_sweep(grid, args.out, workers=args.workers, scheduler=args.scheduler, progress=not args.quiet,
                    force=args.force)
    print(format_summary(run.rows, grid.metric))
    variants = sorted({r["mitsuba_variant"] for r in run.rows})
    print(f"cells: {run.n_cells} ({run.n_resumed} read back, {run.n_cells - run.n_resumed} computed; "
          f"{run.n_render_tasks} render tasks); Mitsuba variant(s): {', '.join(variants)}; {run.wall_s:.1f} s")
    for p in run.paths:
        print(f"  {p}")
    return 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
