"""The harness's results table: one row per measured value, the same columns for every evaluation.

A *long* table: each row is one number (``value``, in ``unit``) of one ``metric`` measured on one
image (``scene`` at ``aperture`` and ``scene_size``, given to the method as ``encoding`` with sensor
``noise``) by one method ``preset``, in one evaluation (``evaluation_id``). Ground-truth facts of an
image (its σ_gt range) are rows too, with no preset. Long tables concatenate across evaluations and
pivot into any wide view; :data:`COLUMNS` is the schema, documented in docs/results-schema.md, and
:func:`write_results` / :func:`read_results` the one way to store it (Parquet with the evaluation's
metadata in the schema, plus the same rows as CSV).

:func:`summarise` gives, per group (preset, aperture, …), the mean of a metric over scenes with a
95 % bootstrap interval (resampling scenes; :func:`scipy.stats.bootstrap`, percentile method, seeded);
:func:`difference` the same for the difference of two groups' means (test − dev), resampling each
group's scenes independently.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import MappingProxyType

import numpy as np

__all__ = ["COLUMNS", "GROUP_COLUMNS", "RESULTS_META_KEY", "SCHEMA_VERSION", "SUMMARY_METRICS", "Column",
           "column_names", "difference", "mean_interval", "metric_rows", "metric_unit", "paired_difference", "read_results",
           "read_results_csv", "summarise", "write_results"]

#: Version of the table's columns; in every table's metadata.
SCHEMA_VERSION = 2
#: Key of the JSON metadata in the Parquet schema.
RESULTS_META_KEY = b"defocus_results"


@dataclasses.dataclass(frozen=True)
class Column:
    """One column: name, Arrow type (``string``, ``int64``, ``float64``), whether it may be empty, meaning."""

    name: str
    type: str
    nullable: bool
    description: str


#: The columns, in order.
COLUMNS: tuple[Column, ...] = (
    Column("evaluation_id", "string", False, "the evaluation (run) that measured the value: an evaluation's folder name, "
                                             "or <figure>-<mode>-<config hash> for a figure"),
    Column("source", "string", False, "what produced the row: 'procedural' (repro.evaluate --procedural), 'scenes' "
                                      "(repro.evaluate on named scenes), 'figures' (repro.figures), 'sweep' "
                                      "(repro.sweep), 'accuracy' (repro.bench --accuracy)"),
    Column("figure", "string", True, "the figure (or benchmark) whose case measured the value; empty for evaluations"),
    Column("scene_set", "string", True, "scene set of the case (paper_cameras, tabletop_stress, procedural_test, …); "
                                        "empty for a case without one (analytic images, optics)"),
    Column("scene", "string", True, "scene (or image) name (procedural_<seed> for the procedural family); empty for "
                                    "a case pooled over scenes or without one"),
    Column("seed", "int64", True, "scene seed of a procedural scene (empty for named scenes)"),
    Column("split", "string", True, "seed split: dev (tune here), test or fresh (report these); empty if none"),
    Column("scene_size", "string", True, "render resolution preset: small (160x120) or full (640x480); empty without "
                                         "a render"),
    Column("camera", "string", True, "camera preset of the render (scenes.CAMERA_PRESETS)"),
    Column("lighting", "string", True, "emission (textures emitted, no lighting) or lit (area light, path traced)"),
    Column("aperture", "float64", True, "f-number N of the render; empty without one"),
    Column("preset", "string", True, "method preset (method.PRESETS); empty for ground-truth facts and "
                                     "preset-independent rows"),
    Column("estimator", "string", True, "blur estimator of the row; empty when the preset's own"),
    Column("encoding", "string", True, "input encoding given to the method: srgb or linear"),
    Column("noise", "string", True, "sensor noise level of the input (scenes.display.NOISE_LEVELS)"),
    Column("variant", "string", True, "the case's own axis within its figure (e.g. s=2 for a bias scale, nsr=0.01, "
                                      "stage, pooled); empty if none"),
    Column("metric", "string", False, "what was measured (docs/results-schema.md lists the metrics)"),
    Column("value", "float64", True, "the number; empty when undefined (e.g. an MAE over no pixels)"),
    Column("unit", "string", False, "unit of value: 'px (σ)', 'pixels', 'fraction of pixels', 'dimensionless', "
                                    "'relative', 'm', 'cm', 'µm', 'dB', 's', 'px²', 'flag' (1 = yes)"),
)
#: Columns that identify a summary group (everything but the scene, its seed and the value).
GROUP_COLUMNS = ("evaluation_id", "source", "split", "scene_size", "aperture", "preset", "encoding", "noise", "metric")
#: Metrics of the summaries and the report (flattened :func:`experiments.evaluation.evaluate_result` keys).
SUMMARY_METRICS = ("dense_textured_mae", "dense_all_mae", "sparse_mae", "refined_mae", "rtf_nmae",
                   "in_focus_outliers_sparse_fraction", "pipeline_failed")
_TYPES = MappingProxyType({c.name: c.type for c in COLUMNS})


def column_names() -> tuple[str, ...]:
    """The column names, in order."""
    return tuple(c.name for c in COLUMNS)


#: Names (last part of a metric path) that are yes/no facts.
_FLAG_NAMES = ("model_fit_better", "alpha_applies", "trade_off", "visible", "meets_targets", "mae_ok", "bias_ok",
               "outlier_scene", "sharp_kept", "blur_gained", "target_ok")


def metric_unit(metric: str) -> str:
    """Unit of a metric (the ``unit`` column), from the last part of its path (``a/b/psnr_db`` → dB)."""
    name = metric.rsplit("/", 1)[-1]
    if name.endswith("_failed") or name in _FLAG_NAMES or name.endswith("_ok"):
        return "flag"
    if name == "n" or name.endswith("_n") or name.startswith("n_") or name.endswith("_n_in_focus") \
            or name.endswith("_n_blurry_estimates") or name.endswith("_pixels"):
        return "pixels"
    if "psnr" in name or name.endswith("_db"):
        return "dB"
    if "ssim" in name or name.startswith("rtf_") or "ratio" in name or name in ("auc", "factor", "nsr"):
        return "dimensionless"
    if name.endswith("_term"):
        return "px²"
    if name.endswith("_s") or name.endswith("seconds") or name.startswith("seconds"):
        return "s"
    if "fraction" in name or name.endswith("_rate") or "above" in name:
        return "fraction of pixels"
    if name.endswith("_m"):
        return "m"
    if name.endswith("_cm"):
        return "cm"
    if name.endswith("_um"):
        return "µm"
    if name.endswith("_rel_error") or name.endswith("rel_err") or name.startswith("rel_"):
        return "relative"
    return "px (σ)"


def _value(v):
    """A number as float; None and NaN as None (empty); ±inf kept (e.g. the PSNR of equal images)."""
    if v is None or isinstance(v, bool):
        return None if v is None else float(v)
    v = float(v)
    return None if math.isnan(v) else v


def metric_rows(ids: Mapping, metrics: Mapping) -> list[dict]:
    """One row per metric: the identifying fields ``ids`` plus ``metric``, ``value``, ``unit``.

    Parameters
    ----------
    ids : mapping
        Values of every column but ``metric``, ``value`` and ``unit`` (missing ones are empty).
    metrics : mapping of str to number or None
        Flat metric name → value (NaN and None are stored as empty; a bool as 1/0 with unit ``flag``).

    Raises
    ------
    ValueError
        A key of ``ids`` that is not a column.
    """
    bad = sorted(set(ids) - set(_TYPES))
    if bad:
        raise ValueError(f"unknown results column(s) {bad}; allowed: {', '.join(_TYPES)}")
    base = {c: ids.get(c) for c in column_names() if c not in ("metric", "value", "unit")}
    return [{**base, "metric": str(k), "value": _value(v),
             "unit": "flag" if isinstance(v, (bool, np.bool_)) else metric_unit(str(k))} for k, v in metrics.items()]


def _arrow_table(rows: list[dict], meta: dict):
    import pyarrow as pa

    types = {"string": pa.string(), "int64": pa.int64(), "float64": pa.float64()}
    schema = pa.schema([pa.field(c.name, types[c.type], nullable=c.nullable) for c in COLUMNS],
                       metadata={RESULTS_META_KEY: json.dumps({"schema_version": SCHEMA_VERSION, **meta},
                                                              sort_keys=True, default=str).encode()})
    return pa.Table.from_pylist([{c: r.get(c) for c in _TYPES} for r in rows], schema=schema)


def write_results(folder, rows: list[dict], meta: dict, *, stem: str = "results") -> list[Path]:
    """Write ``<stem>.parquet`` (metadata in the schema; when pyarrow is installed) and ``<stem>.csv``
    atomically; return the paths (the Parquet file first).

    Raises
    ------
    ValueError
        A row with a column outside :data:`COLUMNS`.
    """
    from defocus_cache import atomic_write, atomic_write_text

    for r in rows:
        extra = set(r) - set(_TYPES)
        if extra:
            raise ValueError(f"unknown results column(s) {sorted(extra)}; allowed: {', '.join(_TYPES)}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    parquet, csv_path = folder / f"{stem}.parquet", folder / f"{stem}.csv"
    paths = [csv_path]
    try:
        import pyarrow.parquet as pq
    except ImportError:  # the sweep extra is not installed: the CSV alone (it holds the same rows)
        pq = None
    if pq is not None:
        table = _arrow_table(rows, meta)
        with atomic_write(parquet) as tmp:
            pq.write_table(table, tmp)
        paths.insert(0, parquet)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(_TYPES), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in _TYPES})
    atomic_write_text(csv_path, buf.getvalue())
    return paths


def _upgrade(names, rows: list[dict], path) -> list[dict]:
    """Rows of a table with an older column set (a subsequence of :data:`COLUMNS`), with the new columns empty."""
    names = tuple(names)
    it = iter(column_names())
    if not names or not all(any(n == c for c in it) for n in names):
        raise ValueError(f"{path} is not a results table (columns {list(names)}); allowed: a results table written by "
                         "experiments.results_table.write_results")
    if names == column_names():
        return rows
    return [{c: r.get(c) for c in column_names()} for r in rows]


def read_results(path) -> tuple[list[dict], dict]:
    """(rows, metadata) of a ``results.parquet`` (one of an older schema version gets the new columns empty).

    Raises
    ------
    ValueError
        A file that is not a results table (no metadata, other columns).
    """
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    raw = (table.schema.metadata or {}).get(RESULTS_META_KEY)
    if raw is None:
        raise ValueError(f"{path} is not a results table (no {RESULTS_META_KEY.decode()} metadata); allowed: a "
                         "results.parquet written by experiments.results_table.write_results")
    return _upgrade(table.column_names, table.to_pylist(), path), json.loads(raw)


def read_results_csv(path) -> list[dict]:
    """The rows of a ``results.csv``, typed as :data:`COLUMNS` say (empty cells → None); needs no pyarrow.

    Raises
    ------
    ValueError
        A file whose header is not :data:`COLUMNS` (or an older schema's subsequence of it).
    """
    conv = {"string": str, "int64": int, "float64": float}
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        names = tuple(reader.fieldnames or ())
        rows = [{k: (None if v == "" else conv[_TYPES[k]](v)) for k, v in row.items() if k in _TYPES} for row in reader]
    return _upgrade(names, rows, path)


def _interval(samples: tuple, statistic, *, confidence: float, n_resamples: int, seed: int, paired: bool = False):
    """(low, high) percentile-bootstrap interval of ``statistic`` (None, None with too few scenes); ``paired``
    resamples the same scene indices in every sample."""
    from scipy.stats import bootstrap

    if min(len(s) for s in samples) < 2:
        return None, None
    res = bootstrap(samples, statistic, confidence_level=confidence, n_resamples=n_resamples, method="percentile",
                    vectorized=True, paired=paired, random_state=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def _mean(x, axis=-1):
    return np.mean(x, axis=axis)


def _groups(rows: Iterable[dict], by: tuple, metrics: tuple) -> dict:
    out: dict[tuple, dict] = {}
    for r in rows:
        if r["metric"] not in metrics or r.get("value") is None:
            continue
        key = tuple(r.get(c) for c in by)
        out.setdefault(key, {})[r["scene"]] = float(r["value"])
    return out


def summarise(rows: Iterable[dict], *, by: tuple = GROUP_COLUMNS, metrics: tuple = SUMMARY_METRICS,
              confidence: float = 0.95, n_resamples: int = 9999, seed: int = 0) -> list[dict]:
    """Mean over scenes of each metric per group, with a bootstrap interval over scenes.

    Parameters
    ----------
    rows : iterable of dict
        Results rows (:func:`metric_rows`).
    by : tuple of str, keyword-only
        Grouping columns (must include ``metric``).
    metrics : tuple of str, keyword-only
        Metrics summarised (others are skipped).
    confidence : float, keyword-only
        Interval level (0.95: a 95 % interval).
    n_resamples : int, keyword-only
        Bootstrap resamples.
    seed : int, keyword-only
        Seed of the resampling (the same rows give the same interval).

    Returns
    -------
    list of dict
        Per group, in first-seen order: the ``by`` columns, ``n_scenes``, ``mean``, ``ci_low``,
        ``ci_high`` (None with fewer than two scenes), ``unit``. Empty values are not counted.

    Notes
    -----
    Each scene contributes one value per group; the interval resamples scenes with replacement
    (percentile bootstrap: the 2.5th and 97.5th percentiles of the resampled means).
    """
    out = []
    for key, per_scene in _groups(rows, by, metrics).items():
        row = dict(zip(by, key))
        out.append({**row, **mean_interval(per_scene.values(), confidence=confidence, n_resamples=n_resamples,
                                           seed=seed), "unit": metric_unit(row["metric"])})
    return out


def mean_interval(values: Iterable[float], *, confidence: float = 0.95, n_resamples: int = 9999,
                  seed: int = 0) -> dict:
    """Mean of per-scene values with a percentile-bootstrap interval.

    Returns
    -------
    dict
        ``n_scenes``, ``mean`` (None without values), ``ci_low``, ``ci_high`` (None with fewer than two).
    """
    v = np.asarray([float(x) for x in values], dtype=np.float64)
    if v.size == 0:
        return {"n_scenes": 0, "mean": None, "ci_low": None, "ci_high": None}
    lo, hi = _interval((v,), _mean, confidence=confidence, n_resamples=n_resamples, seed=seed)
    return {"n_scenes": int(v.size), "mean": float(v.mean()), "ci_low": lo, "ci_high": hi}


def _difference_of_means(x, y, axis=-1):
    return np.mean(y, axis=axis) - np.mean(x, axis=axis)


def difference(first: Iterable[float], second: Iterable[float], *, confidence: float = 0.95,
               n_resamples: int = 9999, seed: int = 0) -> dict:
    """mean(second) − mean(first) with a bootstrap interval resampling each sample independently.

    Parameters
    ----------
    first, second : iterable of float
        Per-scene values of two groups (e.g. dev and test scenes), finite.

    Returns
    -------
    dict
        ``value``, ``ci_low``, ``ci_high`` (None when a group has fewer than two values), ``n_first``,
        ``n_second``.
    """
    a = np.asarray([float(v) for v in first], dtype=np.float64)
    b = np.asarray([float(v) for v in second], dtype=np.float64)
    if a.size == 0 or b.size == 0:
        return {"value": None, "ci_low": None, "ci_high": None, "n_first": int(a.size), "n_second": int(b.size)}
    lo, hi = _interval((a, b), _difference_of_means, confidence=confidence, n_resamples=n_resamples, seed=seed)
    return {"value": float(b.mean() - a.mean()), "ci_low": lo, "ci_high": hi, "n_first": int(a.size),
            "n_second": int(b.size)}


def paired_difference(first: Iterable[float], second: Iterable[float], *, confidence: float = 0.95,
                      n_resamples: int = 9999, seed: int = 0) -> dict:
    """mean(second − first) over paired values (the same scenes) with a paired bootstrap interval.

    Parameters
    ----------
    first, second : iterable of float, (n,)
        Per-scene values of two variants on the same scenes, in the same order, finite.
    confidence, n_resamples, seed : keyword-only
        As :func:`summarise`.

    Returns
    -------
    dict
        ``value`` (mean of the differences), ``sd`` (their sample standard deviation, ddof 1; None below
        two pairs), ``ci_low``, ``ci_high`` (None below two pairs), ``n_pairs``.

    Raises
    ------
    ValueError
        ``first`` and ``second`` of different lengths.

    Notes
    -----
    Each resample draws n scene indices with replacement and takes both variants' values of those scenes
    (:func:`scipy.stats.bootstrap` with ``paired=True``, percentile interval): the scene-to-scene
    spread that both variants share cancels, unlike :func:`difference`.
    """
    a = np.asarray([float(v) for v in first], dtype=np.float64)
    b = np.asarray([float(v) for v in second], dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"paired values of lengths {a.size} and {b.size} are invalid; allowed: the same scenes in both")
    if a.size == 0:
        return {"value": None, "sd": None, "ci_low": None, "ci_high": None, "n_pairs": 0}
    d = b - a
    if d.size > 1 and np.all(d == d[0]):  # every resample gives the same mean: the interval is that point
        lo = hi = float(d[0])
    else:
        lo, hi = _interval((a, b), _difference_of_means, confidence=confidence, n_resamples=n_resamples, seed=seed,
                           paired=True)
    return {"value": float(d.mean()), "sd": float(d.std(ddof=1)) if d.size > 1 else None, "ci_low": lo, "ci_high": hi,
            "n_pairs": int(a.size)}
