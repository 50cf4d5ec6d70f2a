"""The tables of an experiment sweep: Parquet I/O and the per-variant summary of one metric.

Rows are dicts with the same keys (one per cell: inputs, method variant, metrics);
:func:`write_table` writes them atomically with JSON metadata in the schema, :func:`read_table` reads
them back, :func:`summary` gives per method variant the count, mean, median, min and max of a metric.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["metric_unit", "read_table", "summary", "write_table"]


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
