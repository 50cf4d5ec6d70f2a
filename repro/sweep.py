"""Experiment sweeps on Dask distributed: one machine by default, a cluster when pointed at one.

``python -m repro.sweep [--scenes NAME ...] [--camera PRESET ...] [--fnumber 8 4] [--estimator NAME ...]
[--preset NAME ...] [--param FIELD=V1,V2 ...] [--seeds 0 1] [--scene-preset small|full]
[--encoding srgb linear] [--workers N | --scheduler tcp://HOST:PORT] [--metric COLUMN] [--variant V]
--out DIR``

The grid is the product scenes × cameras × f-numbers × seeds (one *render* each) × method presets ×
estimators × parameter values × encodings (one *cell* each). Every cell renders through the render
cache, runs the whole pipeline and is scored against σ_gt with the metrics of
:mod:`repro.evaluate` (:func:`experiments.sweep_cells.cell_task`). Renders are deduplicated: one Dask
task per distinct render, its cells depend on it.

Engine: a :class:`dask.distributed.LocalCluster` of ``--workers`` single-threaded processes (default:
one per core) whose dashboard address is printed, or an existing cluster (``--scheduler``, started
with ``dask scheduler`` / ``dask worker``; its workers must see the same ``$DEFOCUS_CACHE_DIR``).
Progress: cells done / total with an ETA (tqdm). Each finished cell is written at once, atomically,
to ``DIR/cells/<cell id>.json``, keyed by its inputs, the code fingerprint of method/scenes/experiments,
the estimator's source and the library versions; the same command again (after Ctrl-C, a crash or a
killed worker) reads finished cells back instead of recomputing them. A worker that dies mid-task has
its tasks rerun elsewhere by the scheduler.

Outputs (atomic): ``DIR/results.parquet`` (one row per cell: every input, the method variant label,
the Mitsuba variant, every metric; the same rows serial or parallel), ``DIR/timings.parquet``
(per cell, in the same order: its id = the name of its file in ``cells/``, worker, seconds,
resumed or not), ``DIR/<metric>.png`` (the chosen metric per method
variant) and a summary printed on the terminal.

Bad grid (unknown scene, camera, estimator, preset, parameter name or value, f-number, metric): one
line on stderr and exit status 2 before any cluster is started or task submitted.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import sys
import time
from pathlib import Path

PROG = "python -m repro.sweep"

#: Input columns of ``results.parquet`` before the swept parameter columns.
INPUT_COLUMNS = ("scene", "camera", "f_number", "scene_preset", "seed", "encoding", "method_preset", "estimator")
#: Columns after the inputs and parameters: identity and backend.
INFO_COLUMNS = ("method_variant", "mitsuba_variant")
#: Default metric of the plot and the summary.
DEFAULT_METRIC = "dense_textured_mae"
#: Column value for the scene's own camera (``--camera`` not given).
SCENE_CAMERA = "scene_default"


# --------------------------------------------------------------------------------------------------
# grid


@dataclasses.dataclass(frozen=True)
class Render:
    """One distinct render of the grid."""

    scene: str
    camera: str | None
    f_number: float
    scene_preset: str
    seed: int

    @property
    def render_id(self) -> str:
        from defocus_cache import hash_key

        return hash_key(dataclasses.asdict(self))


@dataclasses.dataclass(frozen=True)
class Cell:
    """One cell: a render × method preset × estimator × parameter values × encoding."""

    render: Render
    method_preset: str
    estimator: str
    params: tuple  # ((field, value), ...) in --param order
    encoding: str

    def inputs(self) -> dict:
        """Every input, named as the results columns."""
        r = self.render
        return {"scene": r.scene, "camera": r.camera or SCENE_CAMERA, "f_number": r.f_number,
                "scene_preset": r.scene_preset, "seed": r.seed, "encoding": self.encoding,
                "method_preset": self.method_preset, "estimator": self.estimator, **dict(self.params)}

    @property
    def variant_label(self) -> str:
        """The method variant: preset/estimator plus the swept parameter values."""
        extra = "".join(f" {k}={_fmt_value(v)}" for k, v in self.params)
        return f"{self.method_preset}/{self.estimator}{extra}"


@dataclasses.dataclass(frozen=True)
class Grid:
    """A validated sweep grid (:func:`build_grid`)."""

    cells: tuple
    param_names: tuple
    metric: str
    variant: str | None

    @property
    def renders(self) -> tuple:
        return tuple(dict.fromkeys(c.render for c in self.cells))


def _fmt_value(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _parse_bool(text: str) -> bool:
    t = text.strip().lower()
    if t in ("true", "1", "yes", "on"):
        return True
    if t in ("false", "0", "no", "off"):
        return False
    raise ValueError


def parse_param_value(field: str, type_text: str, text: str):
    """One ``--param`` value parsed as the ``DefocusParams`` field's annotated type.

    Parameters
    ----------
    field : str
        Field name (for the message).
    type_text : str
        The field's annotation, e.g. ``"float"``, ``"float | None"``, ``"int | str"``, ``"bool"``.
    text : str
        The value as written on the command line.

    Raises
    ------
    ValueError
        Naming the field, the value and the allowed type; tuple fields are not sweepable.
    """
    types = [t.strip() for t in type_text.split("|")]
    if any(t.startswith("tuple") for t in types):
        raise ValueError(f"--param {field}: tuple fields cannot be swept; allowed: scalar DefocusParams fields")
    t = text.strip()
    if "None" in types and t.lower() in ("none", "null"):
        return None
    if "bool" in types:
        try:
            return _parse_bool(t)
        except ValueError:
            raise ValueError(f"--param {field}={text!r} is invalid; allowed: true or false") from None
    if "int" in types:
        try:
            return int(t)
        except ValueError:
            pass
    if "float" in types:
        try:
            return float(t)
        except ValueError:
            pass
    if "str" in types and t:
        return t
    allowed = " or ".join({"int": "integer", "float": "number", "None": "none", "str": "text"}.get(x, x) for x in types)
    raise ValueError(f"--param {field}={text!r} is invalid; allowed: {allowed}")


def parse_params(specs) -> list[tuple[str, list]]:
    """``["alpha=0.1,0.5", ...]`` → ``[("alpha", [0.1, 0.5]), ...]`` (types from ``DefocusParams``).

    Raises
    ------
    ValueError
        Bad syntax, unknown or repeated field, ``estimator`` (use ``--estimator``), bad value.
    """
    from method import DefocusParams

    fields = {f.name: f.type for f in dataclasses.fields(DefocusParams)}
    out: dict[str, list] = {}
    for spec in specs or []:
        name, sep, values = str(spec).partition("=")
        name = name.strip()
        if not sep or not name or not values.strip():
            raise ValueError(f"--param {spec!r} is invalid; allowed: FIELD=V1,V2,... (e.g. alpha=0.1,0.5,1)")
        if name == "estimator":
            raise ValueError("--param estimator=... is invalid; allowed: use --estimator NAME ...")
        if name not in fields:
            raise ValueError(f"--param {name!r} is not a DefocusParams field; allowed: "
                             f"{sorted(n for n, t in fields.items() if not str(t).startswith('tuple') and n != 'estimator')}")
        if name in out:
            raise ValueError(f"--param {name} is given twice; allowed: each field once, values comma-separated")
        parsed = [parse_param_value(name, str(fields[name]), v) for v in values.split(",")]
        out[name] = list(dict.fromkeys(parsed))
    return list(out.items())


def build_grid(*, scenes, cameras=None, f_numbers=(8.0, 4.0), estimators=None, presets=("paper",), params=(),
               seeds=(0,), scene_preset="small", encodings=("srgb",), metric=DEFAULT_METRIC,
               variant=None) -> Grid:
    """Validate every axis of a sweep and enumerate its cells (nothing is rendered or submitted).

    Parameters
    ----------
    scenes : sequence of str, keyword-only
        Keys of :data:`scenes.SCENES`.
    cameras : sequence of str or None, keyword-only
        :data:`scenes.CAMERA_PRESETS` names; None: each scene's own camera.
    f_numbers : sequence of float, keyword-only
        Apertures N (> 0).
    estimators : sequence of str or None, keyword-only
        Keys of :data:`method.BLUR_ESTIMATORS`; None: each preset's own estimator.
    presets : sequence of str, keyword-only
        Keys of :data:`method.PRESETS`.
    params : sequence of (str, list), keyword-only
        Swept ``DefocusParams`` fields and their values (:func:`parse_params`).
    seeds : sequence of int, keyword-only
        Render sampler seeds, in [0, 2**32).
    scene_preset : {"small", "full"}, keyword-only
    encodings : sequence of {"srgb", "linear"}, keyword-only
    metric : str, keyword-only
        Metric column of the plot and summary (:data:`repro.evaluate.METRIC_COLUMNS`).
    variant : str or None, keyword-only
        Mitsuba variant requested (None: each worker's fastest).

    Returns
    -------
    Grid

    Raises
    ------
    ValueError
        Naming the bad value and what is allowed; every parameter combination is validated by
        building its ``DefocusParams`` (so cross-field rules are checked too).
    """
    from experiments.evaluation import ENCODINGS, validate_estimators
    from experiments.sweep_cells import cell_params, render_camera
    from method import PRESETS
    from scenes import CAMERA_PRESETS, SCENES
    from scenes.render import validate_render_options

    from .evaluate import METRIC_COLUMNS

    def uniq(xs):
        return list(dict.fromkeys(xs))

    scenes = uniq(scenes)
    if not scenes:
        raise ValueError(f"no scene given; allowed: {sorted(SCENES)}")
    bad = [s for s in scenes if s not in SCENES]
    if bad:
        raise ValueError(f"unknown scene(s) {', '.join(map(repr, bad))}; allowed: {sorted(SCENES)}")
    cams = [None] if not cameras else uniq(cameras)
    bad = [c for c in cams if c is not None and c not in CAMERA_PRESETS]
    if bad:
        raise ValueError(f"unknown camera(s) {', '.join(map(repr, bad))}; allowed: {sorted(CAMERA_PRESETS)}")
    presets = uniq(presets)
    bad = [p for p in presets if p not in PRESETS]
    if bad:
        hint = " (the render resolution is --scene-preset small|full)" if set(bad) & {"small", "full"} else ""
        raise ValueError(f"unknown preset(s) {', '.join(map(repr, bad))}; allowed: {sorted(PRESETS)}{hint}")
    ests = [None] if not estimators else list(validate_estimators(uniq(estimators)))
    encodings = uniq(encodings)
    bad = [e for e in encodings if e not in ENCODINGS]
    if bad:
        raise ValueError(f"unknown encoding(s) {', '.join(map(repr, bad))}; allowed: {list(ENCODINGS)}")
    f_numbers = uniq(float(n) for n in f_numbers)
    seeds = uniq(seeds)
    shown = [c for c in METRIC_COLUMNS if c != "seconds_total"]
    if metric not in shown:
        raise ValueError(f"--metric {metric!r} is invalid; allowed: {shown}")
    renders = []
    for s, c, n, sd in itertools.product(scenes, cams, f_numbers, seeds):
        validate_render_options(s, render_camera(s, scene_preset=scene_preset, f_number=n, camera=c),
                                preset=scene_preset, f_number=n, seed=sd)  # ValueError on a bad N, seed, preset
        renders.append(Render(scene=s, camera=c, f_number=n, scene_preset=scene_preset, seed=int(sd)))
    names = tuple(name for name, _ in params)
    combos = list(itertools.product(*(vals for _, vals in params))) or [()]
    methods = []
    for p, e, combo in itertools.product(presets, ests, combos):
        changes = dict(zip(names, combo))
        try:
            full = cell_params(p, e, changes)
        except (ValueError, TypeError) as exc:
            shown_changes = ", ".join(f"{k}={v!r}" for k, v in changes.items()) or "no change"
            raise ValueError(f"preset {p!r} with {shown_changes}: {exc}") from None
        methods.append((p, full.estimator, tuple(zip(names, combo))))
    cells = tuple(Cell(render=r, method_preset=p, estimator=e, params=pc, encoding=enc)
                  for r in renders for p, e, pc in methods for enc in encodings)
    if variant is not None:
        from scenes.backend import VARIANT_CANDIDATES

        if variant not in VARIANT_CANDIDATES:
            raise ValueError(f"--variant {variant!r} is invalid; allowed: {list(VARIANT_CANDIDATES)}")
    return Grid(cells=cells, param_names=names, metric=metric, variant=variant)


# --------------------------------------------------------------------------------------------------
# resume keys and per-cell files


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


# --------------------------------------------------------------------------------------------------
# engine


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
    """A Dask client on a new LocalCluster (``workers`` single-threaded processes) or an existing scheduler."""
    import logging

    from dask.distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler, timeout="20s")
        try:
            client.wait_for_workers(1, timeout=60)
        except (TimeoutError, OSError):
            client.close()
            raise ValueError(f"--scheduler {scheduler}: no worker connected within 60 s; "
                             "allowed: a scheduler with workers (dask worker ADDRESS)") from None
        return client, None
    n = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


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
    paths.append(plot_metric(rows, grid.metric, out / f"{grid.metric}.png"))
    return SweepRun(rows=rows, timings=timings, n_cells=n_total, n_resumed=len(resumed),
                    n_render_tasks=n_render_tasks, wall_s=time.perf_counter() - t_start,
                    compute_wall_s=compute_wall, paths=paths, dashboard=dashboard)


# --------------------------------------------------------------------------------------------------
# outputs


def _metric_columns(flat: dict) -> dict:
    """Metric columns: :data:`repro.evaluate.METRIC_COLUMNS` first (without timings), then the rest sorted."""
    from .evaluate import METRIC_COLUMNS

    first = [c for c in METRIC_COLUMNS if c != "seconds_total"]
    rest = sorted(k for k in flat if k not in first and not k.startswith("timings"))
    return {k: flat.get(k) for k in [*first, *rest]}


def _column(values):
    import pyarrow as pa

    kinds = {type(v) for v in values if v is not None}
    if kinds <= {bool}:
        return pa.array(values, type=pa.bool_())
    if kinds <= {int}:
        return pa.array(values, type=pa.int64())
    if kinds <= {int, float}:
        return pa.array([None if v is None else float(v) for v in values], type=pa.float64())
    if kinds <= {str}:
        return pa.array(values, type=pa.string())
    return pa.array([None if v is None else str(v) for v in values], type=pa.string())  # mixed: as text


def write_table(path: Path, rows: list[dict], meta: dict) -> Path:
    """Write rows (dicts with the same keys) as a Parquet file, atomically; JSON ``meta`` in the schema."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from defocus_cache import atomic_write

    names = list(rows[0]) if rows else []
    table = pa.table({n: _column([r.get(n) for r in rows]) for n in names})
    table = table.replace_schema_metadata({b"defocus_sweep": json.dumps(meta, sort_keys=True).encode()})
    with atomic_write(path) as tmp:
        pq.write_table(table, tmp)
    return path


def read_table(path) -> list[dict]:
    """``results.parquet`` / ``timings.parquet`` back as a list of row dicts."""
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


def metric_unit(metric: str) -> str:
    """Unit of a metric column, for labels."""
    if metric.endswith("_n"):
        return "pixels"
    if "fraction" in metric:
        return "fraction of pixels"
    if metric.startswith("rtf_"):
        return "dimensionless"
    if metric.endswith("_rel_error"):
        return "relative"
    return "px (σ)"


def summary(rows: list[dict], metric: str) -> list[dict]:
    """Per method variant: cells, mean, median, min and max of ``metric`` (None values skipped)."""
    import statistics

    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(r["method_variant"], []).append(r.get(metric))
    out = []
    for label, vals in groups.items():
        v = [float(x) for x in vals if x is not None and math.isfinite(float(x))]
        out.append({"method_variant": label, "cells": len(vals), "n": len(v),
                    "mean": statistics.fmean(v) if v else None, "median": statistics.median(v) if v else None,
                    "min": min(v) if v else None, "max": max(v) if v else None})
    return out


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


def plot_metric(rows: list[dict], metric: str, path: Path) -> Path:
    """Each cell's ``metric`` per method variant (dots coloured by scene, bar = mean); PNG, atomic."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from defocus_cache import atomic_write

    labels = list(dict.fromkeys(r["method_variant"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(labels) + 2.5), 4.2), constrained_layout=True)
    cmap = plt.get_cmap("tab10")
    for j, scene in enumerate(scenes):
        xs, ys = [], []
        for r in rows:
            v = r.get(metric)
            if r["scene"] == scene and v is not None and np.isfinite(v):
                i = labels.index(r["method_variant"])
                xs.append(i + (j - (len(scenes) - 1) / 2) * 0.08)
                ys.append(v)
        ax.scatter(xs, ys, s=22, color=cmap(j % 10), label=scene, zorder=3)
    for s in summary(rows, metric):
        if s["mean"] is not None:
            i = labels.index(s["method_variant"])
            ax.hlines(s["mean"], i - 0.35, i + 0.35, color="k", lw=2, zorder=4)
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=20, ha="right", fontsize=8)
    ax.set_xlabel("method variant (preset/estimator and swept parameters)")
    ax.set_ylabel(f"{metric} [{metric_unit(metric)}]")
    ax.set_title(f"Sweep: {metric} per cell (dots, by scene) and mean (bar); {len(rows)} cells")
    ax.grid(axis="y", alpha=0.3)
    if scenes:
        ax.legend(title="scene", fontsize=8)
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path


# --------------------------------------------------------------------------------------------------
# benchmark (python -m repro.bench --sweep)


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
    the wall time). Each run uses a fresh output folder, so no cell is resumed. Engine overhead per cell =
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
            run = run_sweep(grid, Path(tmp), workers=n, progress=progress)
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


# --------------------------------------------------------------------------------------------------
# CLI


def _parser():
    from method import BLUR_ESTIMATORS, PRESETS
    from scenes import CAMERA_PRESETS, SCENES

    from ._cli import ArgumentParser, add_variant_option, float_type, int_type

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_variant_option(p)
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help=f"scenes (default: all: {', '.join(SCENES)})")
    p.add_argument("--camera", nargs="+", default=None, metavar="PRESET",
                   help=f"camera presets, same field of view ({', '.join(CAMERA_PRESETS)}; default: each scene's own)")
    p.add_argument("--fnumber", nargs="+", type=float_type("--fnumber"), default=[8.0, 4.0], metavar="N",
                   help="apertures (default: 8 4)")
    p.add_argument("--estimator", nargs="+", default=None, metavar="NAME",
                   help=f"blur estimators (registered: {', '.join(BLUR_ESTIMATORS)}; default: each preset's own)")
    p.add_argument("--preset", nargs="+", default=["paper"], metavar="NAME",
                   help=f"method presets ({', '.join(PRESETS)}; default: paper)")
    p.add_argument("--param", action="append", default=[], metavar="FIELD=V1,V2",
                   help="sweep a DefocusParams field over values (repeatable), e.g. --param alpha=0.1,0.5,1")
    p.add_argument("--seeds", nargs="+", type=int_type("--seeds", minimum=0), default=[0], metavar="S",
                   help="render sampler seeds (default: 0)")
    p.add_argument("--scene-preset", default="small", choices=("small", "full"),
                   help="render resolution preset (small 160x120, full 640x480; default small)")
    p.add_argument("--encoding", nargs="+", default=["srgb"], choices=("srgb", "linear"),
                   help="input encodings given to the method (default: srgb)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int_type("--workers"), default=None, metavar="N",
                   help="LocalCluster worker processes, one thread each (default: one per core)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="submit to an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (workers must see "
                        "the same $DEFOCUS_CACHE_DIR)")
    p.add_argument("--metric", default=DEFAULT_METRIC, metavar="COLUMN",
                   help=f"metric of the plot and summary (default {DEFAULT_METRIC})")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    from scenes import SCENES

    args = _parser().parse_args(argv)
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"--out {str(args.out)!r} is a file; allowed: a folder")
    if args.scheduler is not None and "://" not in args.scheduler:
        raise ValueError(f"--scheduler {args.scheduler!r} is invalid; allowed: an address like tcp://HOST:PORT")
    grid = build_grid(scenes=args.scenes or list(SCENES), cameras=args.camera, f_numbers=args.fnumber,
                      estimators=args.estimator, presets=args.preset, params=parse_params(args.param),
                      seeds=args.seeds, scene_preset=args.scene_preset, encodings=args.encoding,
                      metric=args.metric, variant=args.variant)
    print(f"sweep: {len(grid.cells)} cells, {len(grid.renders)} distinct renders -> {args.out}", file=sys.stderr)
    run = run_sweep(grid, args.out, workers=args.workers, scheduler=args.scheduler, progress=not args.no_progress)
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
