"""The engine of an experiment sweep: resume keys, per-cell files, Dask execution, the output tables.

:func:`run_sweep` runs (or resumes) a :class:`repro._sweep_grid.Grid` on a Dask LocalCluster or an
existing scheduler: one render task per distinct render, one cell task per cell depending on it
(:mod:`experiments.sweep_cells`); each finished cell is stored at once (:func:`write_cell`) under its
resume key (:func:`cell_keys`), so the same command again reads it back. Then ``results.parquet``,
``timings.parquet`` (:mod:`experiments.sweep_table`) and the metric's plot
(:mod:`experiments.plotting.sweep`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from pathlib import Path

from experiments.sweep_table import write_table

from ._sweep_grid import Grid

__all__ = ["SweepRun", "cell_keys", "read_cell", "run_sweep", "write_cell"]


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    from experiments.registry import library_versions

    out = dict(library_versions())
    for pkg in ("numba", "pyamg", "pymatting", "colour-science"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def cell_keys(grid: Grid) -> list[dict]:
    """The resume key of every cell: inputs, full parameters, code and library versions, variant asked."""
    from experiments.evaluation import estimator_fingerprint
    from experiments.registry import code_fingerprint, to_jsonable
    from experiments.sweep_cells import SWEEP_CELL_VERSION, cell_params
    from scenes.backend import VARIANT_ENV

    code, versions = code_fingerprint(), _versions()
    asked = grid.variant or os.environ.get(VARIANT_ENV) or "auto"
    est_code = {}
    keys = []
    for c in grid.cells:
        if c.estimator not in est_code:
            est_code[c.estimator] = estimator_fingerprint(c.estimator)
        params = cell_params(c.method_preset, c.estimator, dict(c.params))
        keys.append({"kind": "sweep_cell", "cell_version": SWEEP_CELL_VERSION, "inputs": to_jsonable(c.inputs()),
                     "params": to_jsonable(params), "quantize_bits": 8, "convention": "line_spread",
                     "code": code, "estimator_code": est_code[c.estimator], "versions": versions,
                     "variant_requested": asked})
    return keys


def _cell_path(out: Path, cell_id: str) -> Path:
    return out / "cells" / f"{cell_id}.json"


def read_cell(out: Path, cell_id: str, key: dict) -> dict | None:
    """A finished cell's stored record, or None (missing, unreadable, or written for another key)."""
    try:
        rec = json.loads(_cell_path(out, cell_id).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(rec, dict) or rec.get("key") != json.loads(json.dumps(key)) or "result" not in rec:
        return None
    return rec


def write_cell(out: Path, cell_id: str, key: dict, result: dict) -> None:
    """Store one finished cell atomically (temporary file + rename)."""
    from defocus_cache import atomic_write_text

    (out / "cells").mkdir(parents=True, exist_ok=True)
    atomic_write_text(_cell_path(out, cell_id), json.dumps({"key": key, "result": result}, sort_keys=True))



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


def _start_client(*, workers: int | None, scheduler: str | None):
    """A Dask client on a new LocalCluster (``workers`` single-threaded processes) or an existing scheduler,
    whose workers register the same plugins as this process (:mod:`repro._plugins`)."""
    import logging

    from dask.distributed import Client, LocalCluster

    from repro._cli_errors import CLIError

    if scheduler:
        client = Client(scheduler, timeout="20s")
        try:
            client.wait_for_workers(1, timeout=60)
        except (TimeoutError, OSError):
            client.close()
            raise CLIError(f"--scheduler {scheduler}: no worker connected within 60 s; "
                             "allowed: a scheduler with workers (dask worker ADDRESS)") from None
        return _with_plugins(client, None)
    n = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
    import dask

    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers to hand freed memory back at once; setting it
    # switches off glibc's adaptive mmap threshold, so every large numpy array is mapped and faulted in
    # afresh (measured: a third of the workers' CPU time spent in the kernel). The workers keep glibc's
    # defaults; the single-thread BLAS/OpenMP settings stay.
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    dask.config.set({"distributed.nanny.pre-spawn-environ": environ})
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    return _with_plugins(Client(cluster), cluster)


def _with_plugins(client, cluster):
    """``(client, cluster)`` once every worker (also any that joins later) has this process's plugins
    (:func:`repro._plugin_worker.install_on_workers`); both closed if that fails."""
    from repro._plugin_worker import install_on_workers

    try:
        install_on_workers(client)
    except BaseException:
        client.close()
        if cluster is not None:
            cluster.close()
        raise
    return client, cluster


def run_sweep(grid: Grid, out, *, workers: int | None = None, scheduler: str | None = None,
              progress: bool = True, log=None) -> SweepRun:
    """Run (or resume) a sweep and write its outputs.

    Parameters
    ----------
    grid : Grid
        From :func:`build_grid`.
    out : path
        Output folder (created): ``cells/``, ``results.parquet``, ``timings.parquet``, ``<metric>.png``.
    workers : int, optional, keyword-only
        LocalCluster size (single-threaded worker processes); default one per core.
    scheduler : str, optional, keyword-only
        Address of an existing Dask scheduler (``tcp://HOST:PORT``) instead of a LocalCluster.
    progress : bool, keyword-only
        tqdm bar of cells done / total with ETA.
    log : callable, optional, keyword-only
        Where one-line messages go (default: print to stderr).

    Returns
    -------
    SweepRun

    Notes
    -----
    1. Resume keys (:func:`cell_keys`); cells whose file in ``out/cells`` matches are read back.
    2. If any remain: start the engine; submit one render task per distinct render they need
       (``key="render-<id>"``) and one cell task per cell (``key="cell-<id>"``) taking the render's
       future, so it waits for that task only; as each cell comes back its file is written.
    3. Rows in grid order from the cell files; ``results.parquet`` and ``timings.parquet`` written
       atomically; the plot.
    """
    from defocus_cache import hash_key

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    out = Path(out)
    t_start = time.perf_counter()
    keys = cell_keys(grid)
    ids = [hash_key(k) for k in keys]
    records: dict[str, dict] = {}
    for cid, key in zip(ids, keys):
        rec = read_cell(out, cid, key)
        if rec is not None:
            records[cid] = rec
    resumed = set(records)
    todo = [(c, cid, key) for c, cid, key in zip(grid.cells, ids, keys) if cid not in records]
    n_total = len(grid.cells)
    dashboard, n_render_tasks, compute_wall = None, 0, 0.0
    if resumed:
        log(f"resuming: {len(resumed)} of {n_total} cells read back from {out / 'cells'}")
    if todo:
        from dask.distributed import as_completed
        from tqdm import tqdm

        from experiments.sweep_cells import cell_task, render_task

        client, cluster = _start_client(workers=workers, scheduler=scheduler)
        try:
            dashboard = client.dashboard_link
            n_workers = len(client.scheduler_info()["workers"]) if scheduler else len(cluster.workers)
            where = scheduler or "LocalCluster"
            log(f"engine: {where} with {n_workers} worker(s); dashboard: {dashboard}")
            t0 = time.perf_counter()
            render_futs = {}
            for c, _, _ in todo:
                r = c.render
                if r not in render_futs:
                    render_futs[r] = client.submit(render_task, r.scene, f_number=r.f_number,
                                                   scene_preset=r.scene_preset, camera=r.camera, seed=r.seed,
                                                   variant=grid.variant, key=f"render-{r.render_id}")
            n_render_tasks = len(render_futs)
            futs = {}
            for c, cid, key in todo:
                r = c.render
                fut = client.submit(cell_task, render_futs[r], scene=r.scene, f_number=r.f_number,
                                    scene_preset=r.scene_preset, camera=r.camera, seed=r.seed,
                                    method_preset=c.method_preset, estimator=c.estimator,
                                    param_changes=dict(c.params), encoding=c.encoding, key=f"cell-{cid}")
                futs[fut.key] = (fut, cid, key)
            with tqdm(total=n_total, initial=len(resumed), desc="sweep", unit="cell", file=sys.stderr,
                      disable=not progress, dynamic_ncols=True) as bar:
                for fut, result in as_completed([f for f, _, _ in futs.values()], with_results=True):
                    _, cid, key = futs[fut.key]
                    write_cell(out, cid, key, result)
                    records[cid] = {"key": key, "result": result}
                    bar.update(1)
            compute_wall = time.perf_counter() - t0
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    rows, timings = [], []
    for c, cid in zip(grid.cells, ids):
        res = records[cid]["result"]
        rows.append({**c.inputs(), "method_variant": c.variant_label, "mitsuba_variant": res["variant"],
                     **_metric_columns(res["metrics"])})
        timings.append({"cell_id": cid, "render_id": c.render.render_id, "method_variant": c.variant_label,
                        "scene": c.render.scene, "f_number": c.render.f_number, "seed": c.render.seed,
                        "host": res.get("host"), "pid": res.get("pid"), "seconds": res.get("seconds"),
                        "seconds_pipeline": res.get("seconds_pipeline"),
                        "render_task_seconds": res.get("render_task_seconds"), "resumed": cid in resumed})
    meta = {"grid": {"n_cells": n_total, "param_names": list(grid.param_names), "metric": grid.metric,
                     "variant_requested": grid.variant},
            "code": keys[0]["code"] if keys else None, "versions": keys[0]["versions"] if keys else None}
    out.mkdir(parents=True, exist_ok=True)
    paths = [write_table(out / "results.parquet", rows, meta), write_table(out / "timings.parquet", timings, meta)]
    from experiments.plotting.sweep import plot_metric

    paths.append(plot_metric(rows, grid.metric, out / f"{grid.metric}.png"))
    return SweepRun(rows=rows, timings=timings, n_cells=n_total, n_resumed=len(resumed),
                    n_render_tasks=n_render_tasks, wall_s=time.perf_counter() - t_start,
                    compute_wall_s=compute_wall, paths=paths, dashboard=dashboard)


def _metric_columns(flat: dict) -> dict:
    """Metric columns: :data:`repro.evaluate.METRIC_COLUMNS` first (without timings), then the rest sorted."""
    from repro.evaluate import METRIC_COLUMNS

    first = [c for c in METRIC_COLUMNS if c != "seconds_total"]
    rest = sorted(k for k in flat if k not in first and not k.startswith("timings"))
    return {k: flat.get(k) for k in [*first, *rest]}
