"""Benchmark of the sweep engine (``python -m repro.bench --sweep``): cells per minute, overhead per cell."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from ._sweep_engine import run_sweep
from ._sweep_grid import build_grid

__all__ = ["run_sweep_bench"]


def _noop(x):
    return x


def run_sweep_bench(out, *, scenes=("planes", "portrait"), f_numbers=(8.0, 4.0),
                    estimators=("model_fit", "zero_crossing", "gradient_ratio"), worker_counts=(1, 2),
                    n_noop: int = 200, progress: bool = True) -> dict:
    """Cells per minute for 1 and 2 workers on the small preset, and the engine's overhead per cell.

    Parameters
    ----------
    out : path
        Folder for ``sweep.json`` and ``sweep.md`` (e.g. ``report/bench``).
    scenes, f_numbers, estimators : sequences, keyword-only
        The benchmark grid (small scene preset, paper preset).
    worker_counts : sequence of int, keyword-only
    n_noop : int, keyword-only
        Trivial tasks timed on each cluster for the per-task round trip.
    progress : bool, keyword-only

    Returns
    -------
    dict
        Written to ``sweep.json``.

    Notes
    -----
    Renders are made first (cached), so the render tasks only read them back (their time still counts in
    the wall time). Each run computes every cell again (``force``), so no cell is read back from the case
store. Engine overhead per cell =
    (workers × wall time − Σ render and cell task seconds) / cells: scheduling, transfer, result
    handling and idle workers at the end; the no-op tasks give the scheduler's own cost per task.
    """
    import logging
    import platform
    import tempfile

    from dask.distributed import Client, LocalCluster

    from experiments.sweep_cells import render_task
    from defocus_cache import atomic_write_text

    out = Path(out)
    grid = build_grid(scenes=scenes, f_numbers=f_numbers, estimators=estimators, presets=("paper",))
    for r in grid.renders:
        render_task(r.scene, f_number=r.f_number, scene_preset=r.scene_preset, camera=r.camera, seed=r.seed)
    load0 = os.getloadavg()
    runs = []
    tables = []
    for n in worker_counts:
        with tempfile.TemporaryDirectory(prefix="sweep-bench-") as tmp:
            run = run_sweep(grid, Path(tmp), workers=n, progress=progress, force=True)
            tables.append([{k: v for k, v in r.items()} for r in run.rows])
        busy_cells = sum(t["seconds"] for t in run.timings)
        busy_renders = sum({t["render_id"]: t["render_task_seconds"] or 0.0 for t in run.timings}.values())
        busy = busy_cells + busy_renders
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None, silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
            client.gather(client.map(_noop, range(20), key=[f"warm-{i}" for i in range(20)]))
            t0 = time.perf_counter()
            client.gather(client.map(_noop, range(n_noop), key=[f"noop-{i}" for i in range(n_noop)]))
            noop_s = (time.perf_counter() - t0) / n_noop
        runs.append({"workers": n, "cells": run.n_cells, "render_tasks": run.n_render_tasks,
                     "wall_s": run.wall_s, "compute_wall_s": run.compute_wall_s,
                     "cells_per_minute": 60.0 * run.n_cells / run.compute_wall_s,
                     "sum_task_s": busy, "sum_render_task_s": busy_renders, "mean_cell_task_s": busy_cells / run.n_cells,
                     "engine_overhead_per_cell_s": (n * run.compute_wall_s - busy) / run.n_cells,
                     "startup_s": run.wall_s - run.compute_wall_s,
                     "noop_task_roundtrip_s": noop_s})
    report = {"grid": {"scenes": list(scenes), "f_numbers": list(f_numbers), "estimators": list(estimators),
                       "preset": "paper", "scene_preset": "small", "cells": len(grid.cells),
                       "renders": len(grid.renders)},
              "runs": runs, "tables_identical": all(t == tables[0] for t in tables),
              "speedup": runs[-1]["cells_per_minute"] / runs[0]["cells_per_minute"] if len(runs) > 1 else None,
              "load_avg_start": load0, "load_avg_end": os.getloadavg(),
              "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
              "date": time.strftime("%Y-%m-%d %H:%M:%S")}
    lines = [f"# Sweep engine benchmark ({report['date']}, {os.cpu_count()} CPUs)", "",
             f"Grid: {len(grid.cells)} cells ({', '.join(scenes)} × f/{', f/'.join(f'{n:g}' for n in f_numbers)} × "
             f"{', '.join(estimators)}; paper preset, small scene preset 160×120), {len(grid.renders)} renders made "
             "beforehand (cached). Load average 1/5/15 min at start: "
             f"{' / '.join(f'{x:.2f}' for x in load0)}; at end: {' / '.join(f'{x:.2f}' for x in report['load_avg_end'])}.",
             "", "| workers | cells/minute | mean cell task (s) | engine overhead per cell (s) | no-op task, wall / tasks (ms) "
             "| engine start-up (s) |", "|---|---|---|---|---|---|"]
    for r in runs:
        lines.append(f"| {r['workers']} | {r['cells_per_minute']:.1f} | {r['mean_cell_task_s']:.2f} | "
                     f"{r['engine_overhead_per_cell_s']:.2f} | {1000 * r['noop_task_roundtrip_s']:.1f} | {r['startup_s']:.1f} |")
    lines += ["", "Engine overhead per cell = (workers × wall time from first submission to last result − Σ render "
              "and cell task seconds) / cells: scheduling, transfers, result handling and workers idle at the end of the grid; a "
              "cell task's time includes each worker's first imports (numba kernels, SciPy). "
              f"Tables of all runs identical: {report['tables_identical']}."]
    if report["speedup"] is not None:
        lines.append(f"Speed-up {worker_counts[-1]} vs {worker_counts[0]} worker(s): {report['speedup']:.2f}×.")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "sweep.json", json.dumps(report, indent=1))
    atomic_write_text(out / "sweep.md", "\n".join(lines) + "\n")
    return report
