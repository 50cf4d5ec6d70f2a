"""The engine of an experiment sweep: its cases on the case runner, the output tables, the Dask client.

:func:`run_sweep` runs (or resumes) a :class:`repro._sweep_grid.Grid` on the case runner
(:func:`repro._runner.run_figures`: a Dask LocalCluster, an existing scheduler or this process): one case
per distinct render, one case per cell needing it (:mod:`experiments.sweep_cells`); each finished case is
stored at once in the one case store (:func:`experiments.cases.run_case`), so the same command again
reads it back. Then the long results table ``results.parquet`` + ``results.csv``
(:mod:`experiments.results_table`, the format of every evaluation), its wide view
``results_wide.parquet`` and ``timings.parquet`` (:mod:`experiments.sweep_table`) and the metric's plot
(:mod:`experiments.plotting.sweep`).
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

from experiments.sweep_table import write_table

from ._sweep_grid import Grid

__all__ = ["SweepRun", "long_rows", "run_sweep", "sweep_cases"]


def sweep_cases(grid: Grid) -> list:
    """The case of every cell of ``grid`` (:func:`experiments.sweep_cells.cell_case`), in grid order; cells of
    one render need the same render case."""
    from experiments.sweep_cells import cell_case, render_case

    renders = {r: render_case(r.scene, f_number=r.f_number, scene_preset=r.scene_preset, camera=r.camera,
                              seed=r.seed) for r in grid.renders}
    return [cell_case(renders[c.render], method_preset=c.method_preset, estimator=c.estimator,
                      param_changes=c.params, encoding=c.encoding) for c in grid.cells]


def long_rows(grid: Grid, cases: list, outputs: dict, evaluation_id: str) -> list[dict]:
    """The sweep's rows of the long results table (:mod:`experiments.results_table`), cells in grid order.

    ``variant`` is the method variant label (preset/estimator and the swept values), with `` seed=N`` for a
    render sampler seed other than 0; ``camera`` the camera preset (empty: the scene's own).
    """
    from experiments.cases import scene_ids
    from experiments.results_table import metric_rows

    from ._sweep_grid import SCENE_CAMERA

    rows = []
    for c, case in zip(grid.cells, cases):
        r = c.render
        ids = {"evaluation_id": evaluation_id, "source": "sweep", "figure": "sweep", **scene_ids(r.scene),
               "scene": r.scene, "scene_size": r.scene_preset, "aperture": float(r.f_number),
               "preset": c.method_preset, "estimator": c.estimator, "encoding": c.encoding, "noise": "none",
               "variant": c.variant_label + (f" seed={r.seed}" if r.seed else "")}
        if (r.camera or SCENE_CAMERA) != SCENE_CAMERA:
            ids["camera"] = r.camera
        rows += metric_rows(ids, outputs[case].metrics)
    return rows


@dataclasses.dataclass
class SweepRun:
    """What :func:`run_sweep` did."""

    rows: list
    timings: list
    n_cells: int
    n_resumed: int
    n_render_tasks: int
    wall_s: float          # whole run, engine start-up included
    compute_wall_s: float  # first submission to last cell back
    paths: list
    dashboard: str | None


def run_sweep(grid: Grid, out, *, workers: int | None = None, scheduler: str | None = None,
              progress: bool = True, force: bool = False, log=None) -> SweepRun:
    """Run (or resume) a sweep and write its outputs.

    Parameters
    ----------
    grid : Grid
        From :func:`build_grid`.
    out : path
        Output folder (created): ``results.parquet`` + ``results.csv`` (the long table),
        ``results_wide.parquet`` (one row per cell), ``timings.parquet``, ``<metric>.png``.
    workers : int, optional, keyword-only
        LocalCluster size (single-threaded worker processes); default one per core; 1: in this process.
    scheduler : str, optional, keyword-only
        Address of an existing Dask scheduler (``tcp://HOST:PORT``) instead of a LocalCluster.
    progress : bool, keyword-only
        tqdm bar of cases done / total with ETA.
    force : bool, keyword-only
        Compute every case again (the stored ones are replaced), none read back.
    log : callable, optional, keyword-only
        Where one-line messages go (default: print to stderr).

    Returns
    -------
    SweepRun

    Notes
    -----
    1. One case per cell and per distinct render (:func:`sweep_cases`); cells the one case store holds
       (:func:`experiments.cases.stored_case`) are read back here.
    2. If any remain: the case runner (:func:`repro._runner.run_figures`) runs them and the renders they
       need (one task per distinct render, each cell waiting for its render's task only); each case is
       stored as it finishes.
    3. The long table and, as a view under its own name, the wide table; the timings; the plot.
    """
    from defocus_cache import hash_key
    from experiments.cases import run_case, stored_case
    from experiments.cache_keys import code_fingerprint
    from experiments.registry import library_versions
    from experiments.results_table import write_results
    from experiments.sweep_cells import UNIT, SweepConfig

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    out = Path(out)
    t_start = time.perf_counter()
    config = SweepConfig(variant=grid.variant)
    cases = sweep_cases(grid)
    outputs = {} if force else {c: run_case(UNIT, config, c, {}) for c in dict.fromkeys(cases)
                                if stored_case(UNIT, config, c)}
    resumed = set(outputs)
    todo = [c for c in dict.fromkeys(cases) if c not in outputs]
    n_total = len(grid.cells)
    n_render_tasks, compute_wall = 0, 0.0
    if resumed:
        log(f"resuming: {len(resumed)} of {n_total} cells read back from the case store")
    if todo:
        from ._runner import FigureJob, run_figures

        t0 = time.perf_counter()
        computed = []

        def keep(_job, output):
            outputs[output.case] = output
            computed.append(output)

        (run,) = run_figures([FigureJob(UNIT, config, "sweep", cases=tuple(todo))], workers=workers,
                             scheduler=scheduler, force=force, progress=progress, on_case=keep, log=log,
                             desc="sweep")
        if run.error is not None:
            raise RuntimeError(f"a sweep case failed: {run.error}\n{run.traceback}")
        compute_wall = time.perf_counter() - t0
        n_render_tasks = sum(1 for o in computed if not o.cached and json.loads(o.case.variant)["render"])
    rows, timings = [], []
    for c, case in zip(grid.cells, cases):
        res = outputs[case].info
        cid = hash_key(case.key())
        rows.append({**c.inputs(), "method_variant": c.variant_label, "mitsuba_variant": res["variant"],
                     **_metric_columns(outputs[case].metrics)})
        timings.append({"cell_id": cid, "render_id": c.render.render_id, "method_variant": c.variant_label,
                        "scene": c.render.scene, "f_number": c.render.f_number, "seed": c.render.seed,
                        "host": res.get("host"), "pid": res.get("pid"), "seconds": res.get("seconds"),
                        "seconds_pipeline": res.get("seconds_pipeline"),
                        "render_task_seconds": res.get("render_task_seconds"), "resumed": case in resumed})
    meta = {"grid": {"n_cells": n_total, "param_names": list(grid.param_names), "metric": grid.metric,
                     "variant_requested": grid.variant},
            "code": code_fingerprint(), "versions": library_versions(),
            "mitsuba_variants": sorted({r["mitsuba_variant"] for r in rows})}
    evaluation_id = f"sweep-{hash_key([case.key() for case in cases])[:12]}"
    paths = write_results(out, long_rows(grid, cases, outputs, evaluation_id), {"evaluation_id": evaluation_id, **meta})
    paths += [write_table(out / "results_wide.parquet", rows, meta),
              write_table(out / "timings.parquet", timings, meta)]
    from experiments.plotting.sweep import plot_metric

    paths.append(plot_metric(rows, grid.metric, out / f"{grid.metric}.png"))
    return SweepRun(rows=rows, timings=timings, n_cells=n_total, n_resumed=len(resumed),
                    n_render_tasks=n_render_tasks, wall_s=time.perf_counter() - t_start,
                    compute_wall_s=compute_wall, paths=paths, dashboard=None)


def _metric_columns(flat: dict) -> dict:
    """Metric columns: :data:`experiments.evaluation_columns.METRIC_COLUMNS` first (without timings), then the rest sorted."""
    from experiments.evaluation_columns import METRIC_COLUMNS

    first = [c for c in METRIC_COLUMNS if c != "seconds_total"]
    rest = sorted(k for k in flat if k not in first and not k.startswith("timings"))
    return {k: flat.get(k) for k in [*first, *rest]}
