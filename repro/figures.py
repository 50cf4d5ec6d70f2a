"""Reproduce the paper's figures: every case computed (cached, in parallel), plotted, and the results table written.

``python -m repro.figures [NAMES...] [--list] [--quick] [--workers N | --jobs N | --scheduler ADDR] [--out DIR]
[--force] [--preset NAME ...] [-q]``

For each figure (default: all registered in :data:`experiments.registry.FIGURES`) every case — each
scene set × scene × method preset × aperture, or the figure's own unit (:mod:`experiments.cases`) — is
computed through the caches (renders and case results under ``$DEFOCUS_CACHE_DIR``) by the case runner
(:mod:`repro._runner`): on a Dask LocalCluster of ``--workers`` single-threaded processes (default one per
core; ``--jobs`` is the same flag), an existing scheduler (``--scheduler``), or with one worker (or
without the ``sweep`` extra) in this process. As soon as a figure's cases are done it is plotted:
``<out>/<name>.png``, ``<name>.pdf`` (one more pair per further scene set) and ``<name>.metrics.json``
(the config, the σ convention, library versions, the cases). Every case's numbers go to one long
results table, ``<out>/results.parquet`` and ``results.csv`` (:mod:`experiments.results_table`; the
rows of figures not run this time are kept), which ``repro.report`` reads. ``<out>`` is ``report/figures``
(the committed results) for a full run and ``report/quick/figures`` (git-ignored) with ``--quick``, so an
exploratory run never touches the committed report (:mod:`repro._report_paths`); ``--out`` overrides both.

``--preset robust zhuo_sim`` sets the ``presets`` field (method parameter presets of :data:`method.PRESETS`)
of every selected figure whose config has one, to ``("paper", "robust", "zhuo_sim")`` — ``"paper"``,
the reproduction, always first; ``--preset paper`` runs the paper alone; figures without that field
ignore it. Unknown names or bad values (``--workers 0``, an unreachable scheduler): one line on
stderr, exit status 2. A figure whose computation fails is reported (traceback, then one summary
line) and the others still run; the exit status is then 1.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from ._report_paths import FIGURES, QUICK_FIGURES

PROG = "python -m repro.figures"
#: Default ``--out`` of a full run (the committed results) and of a ``--quick`` run (git-ignored).
DEFAULT_OUT = FIGURES
QUICK_OUT = QUICK_FIGURES
#: Stem of the results table in the output folder.
TABLE_STEM = "results"


def _parser():
    from experiments.registry import FIGURES
    from method import PRESETS
    from repro._cli import ArgumentParser, add_force_option, add_plugin_options, add_quiet_option, add_variant_option

    from ._runner import add_engine_options

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_variant_option(p)
    p.add_argument("names", nargs="*", metavar="NAME",
                   help=f"figures to make (default: all registered: {', '.join(FIGURES)})")
    p.add_argument("--list", action="store_true", help="list the registered figures and exit")
    p.add_argument("--quick", action="store_true", help="quick mode: fewer points, fewer samples per pixel")
    add_engine_options(p)
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help=f"output folder (default: {DEFAULT_OUT}, the committed results; with --quick: {QUICK_OUT}, "
                        "git-ignored)")
    add_force_option(p)
    add_quiet_option(p, what="no progress display")
    p.add_argument("--preset", nargs="+", default=None, metavar="NAME",
                   help=f"method parameter presets (method.PRESETS: {', '.join(PRESETS)}) for the figures whose "
                        "config has a 'presets' field; 'paper' is always kept first (--preset paper: the paper "
                        "alone); default: each config's own; figures without the field ignore it")
    add_plugin_options(p)
    return p


def preset_names(names) -> tuple[str, ...]:
    """The ``presets`` tuple of ``--preset NAMES``: ``"paper"`` first, then the others in order, without repeats.

    Raises
    ------
    ValueError
        A name not in :data:`method.PRESETS` (the message lists the allowed names).
    """
    from method import PRESETS

    return tuple(dict.fromkeys(["paper", *PRESETS.check_all(names or ["paper"], what="preset")]))


def figure_config(fig, mode: str, presets=None):
    """``fig``'s config of ``mode``, with its ``presets`` field set to ``presets`` when it has one (else unchanged)."""
    import dataclasses

    config = fig.config(mode)
    if presets is not None and any(f.name == "presets" for f in dataclasses.fields(config)):
        config = dataclasses.replace(config, presets=tuple(presets))
    return config


def write_figure(data, out_dir: Path) -> dict:
    """Plot one finished figure and write its ``<name>.metrics.json``; returns a summary dict.

    Parameters
    ----------
    data : experiments.figure_data.FigureData
    out_dir : Path
    """
    from defocus_cache import atomic_write_text
    from experiments.cache_keys import to_jsonable
    from experiments.registry import library_versions

    t0 = time.perf_counter()
    fig, config = data.figure, data.config
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = out_dir / fig.name
    paths = fig.plot_function()(data, config, stem)
    n_cached = sum(o.cached for o in data.outputs.values())
    info = {
        "figure": fig.name,
        "title": fig.title,
        "mode": data.mode,
        "evaluation_id": data.evaluation_id,
        "config_type": type(config).__qualname__,
        "config": to_jsonable(config),
        "code_version": fig.version,
        "sigma_convention": fig.sigma_convention,
        "versions": library_versions(),
        "cache": {"hit": n_cached == len(data.outputs), "cases": len(data.outputs), "cached_cases": n_cached},
        "cases": [c.label for c in data.outputs],
        "results": f"{TABLE_STEM}.parquet / {TABLE_STEM}.csv (rows with figure = {fig.name})",
        "outputs": [p.name for p in paths],
    }
    metrics_path = out_dir / f"{fig.name}.metrics.json"
    atomic_write_text(metrics_path, json.dumps(to_jsonable(info), indent=1, sort_keys=True) + "\n")
    return {"name": fig.name, "cached": info["cache"]["hit"], "cases": len(data.outputs), "cached_cases": n_cached,
            "plot_seconds": time.perf_counter() - t0, "files": [str(p) for p in [*paths, metrics_path]]}


def write_table(out_dir: Path, datas) -> list[Path]:
    """Merge the rows of the finished figures ``datas`` into ``<out>/results.{parquet,csv}``: rows of other
    figures already there are kept, these figures' old rows replaced (under a lock; atomic writes)."""
    from filelock import FileLock

    from experiments.results_table import write_results

    done = {d.figure.name for d in datas}
    with FileLock(str(out_dir / f".{TABLE_STEM}.lock")):
        old = []
        if (out_dir / f"{TABLE_STEM}.csv").is_file():
            from experiments.results_query import read_table

            try:
                old = [r for r in read_table(out_dir) if r.get("figure") not in done]
            except ValueError:
                old = []
        rows = [*old, *(r for d in datas for r in d.rows())]
        # figures in registry order (not the order they finished in), each in its own case order: the
        # same results give the same file, whatever the workers did
        from experiments.registry import FIGURES

        rank = {name: i for i, name in enumerate(FIGURES)}
        rows.sort(key=lambda r: rank.get(r.get("figure"), len(rank)))
        meta = {"figures": sorted({r["figure"] for r in rows if r.get("figure")}),
                "evaluations": sorted({r["evaluation_id"] for r in rows})}
        return write_results(out_dir, rows, meta, stem=TABLE_STEM)


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    from experiments.registry import FIGURES

    from ._runner import FigureJob, engine_choice, run_figures

    if args.list:
        for name, fig in FIGURES.items():
            print(f"{name:<8} {fig.title}")
        return 0
    from repro._cli import user_input

    with user_input():  # the figure and preset names
        names = list(dict.fromkeys(args.names)) or list(FIGURES)
        unknown = [n for n in names if n not in FIGURES]
        if unknown:
            raise ValueError(f"unknown figure(s) {', '.join(map(repr, unknown))}; choose from {', '.join(FIGURES)}")
        mode = "quick" if args.quick else "full"
        out = args.out if args.out is not None else QUICK_OUT if args.quick else DEFAULT_OUT
        presets = preset_names(args.preset) if args.preset is not None else None
    workers, scheduler = engine_choice(args.workers, args.scheduler, command=PROG)
    if args.variant:
        import os

        from scenes.backend import VARIANT_ENV, select_variant

        select_variant(args.variant)  # fails early (one line, exit 2) if it does not work here
        os.environ[VARIANT_ENV] = args.variant  # inherited by worker processes
    jobs = [FigureJob(FIGURES[n], figure_config(FIGURES[n], mode, presets), mode) for n in names]
    for job in jobs:
        job.case_list()  # a bad config (unknown scene set, preset, …) fails before anything runs
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    summaries, finished = {}, []

    def on_figure(run):
        if run.data is None:
            return
        try:
            summaries[run.job.figure.name] = write_figure(run.data, out)
        except Exception as exc:  # noqa: BLE001 - a failing plot fails its figure; the others go on
            import traceback

            run.error = f"plot: {type(exc).__name__}: {exc}"
            run.traceback = "".join(traceback.format_exception(exc))
            return
        finished.append(run.data)

    runs = run_figures(jobs, workers=workers, scheduler=scheduler, force=args.force, progress=not args.quiet,
                       on_figure=on_figure)
    table = write_table(out, finished) if finished else []
    failed = [r for r in runs if r.error is not None]
    for r in failed:
        print(r.traceback, file=sys.stderr)
    for r in runs:
        s = summaries.get(r.job.figure.name)
        if s is None:
            continue
        how = "cached" if s["cached"] else f"computed ({s['cases'] - s['cached_cases']} of {s['cases']} cases)"
        print(f"{s['name']}: {how}; {s['cases']} cases")
        for f in s["files"]:
            print(f"  {f}")
    for p in table:
        print(f"results table: {p}")
    print(f"{len(runs) - len(failed)} figure(s) in {time.perf_counter() - t0:.1f} s "
          f"({'this process' if workers == 1 else scheduler or f'{workers} workers'})")
    for r in failed:
        print(f"{PROG}: {r.job.figure.name} failed: {r.error}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
