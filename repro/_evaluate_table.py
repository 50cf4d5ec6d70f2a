"""The tables of ``python -m repro.evaluate`` on the named scenes: columns, rows, the terminal table and the
stage attribution, and the atomic CSV + JSON writer every part of the command uses."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from experiments.evaluation_columns import METRIC_COLUMNS

__all__ = ["ID_COLUMNS", "SHOWN", "STAGE_ID_COLUMNS", "fmt_value", "format_stage_table",
           "format_table", "stage_table_rows", "table_rows", "write_csv_json", "write_outputs", "write_stage_outputs"]

#: Identifying columns (the metric columns follow: :data:`experiments.evaluation_columns.METRIC_COLUMNS`).
ID_COLUMNS = ("method_preset", "estimator", "scene", "f_number", "scene_preset", "encoding", "noise")
#: Columns shown in the terminal table.
SHOWN = ("sparse_n", "sparse_mae", "sparse_median_ae", "sparse_outlier_fraction", "refined_mae",
         "dense_all_mae", "dense_textured_mae", "rtf_nmae", "in_focus_outliers_sparse_fraction")
_SHORT = {"sparse_n": "n_edge", "sparse_mae": "BM_MAE", "sparse_median_ae": "BM_medAE",
          "sparse_outlier_fraction": "BM_out>1", "refined_mae": "bCBF_MAE", "dense_all_mae": "map_MAE",
          "dense_textured_mae": "map_MAE_tex", "rtf_nmae": "RTF_nMAE",
          "in_focus_outliers_sparse_fraction": "infocus_out"}


def table_rows(cases) -> list[dict]:
    """One flat dict per :class:`experiments.units.EvaluationCase`: ID_COLUMNS + METRIC_COLUMNS."""
    from experiments.evaluation import flatten_metrics

    rows = []
    for case in cases:
        flat = flatten_metrics(case.metrics)
        row = {c: case.key["preset" if c == "scene_preset" else c] for c in ID_COLUMNS}
        for c in METRIC_COLUMNS:
            if c == "seconds_total":
                row[c] = flat.get("timings_total_s")
            else:
                row[c] = flat.get(c)
        rows.append(row)
    return rows


def fmt_value(v) -> str:
    """A table cell: ``nan`` for None, three decimals for a float."""
    if v is None:
        return "nan"
    if isinstance(v, float):
        return f"{v:.3f}"
    return str(v)


def format_table(rows) -> str:
    """Fixed-width terminal table of the :data:`SHOWN` columns."""
    head = [*ID_COLUMNS[:4], *ID_COLUMNS[5:7], *(_SHORT[c] for c in SHOWN)]
    body = [[str(r["method_preset"]), str(r["estimator"]), str(r["scene"]), f"{r['f_number']:g}", str(r["encoding"]),
             str(r["noise"]), *(fmt_value(r[c]) for c in SHOWN)] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body]
    return "\n".join(lines)


def write_csv_json(out_dir: Path, stem: str, rows, fields, doc: dict) -> list[Path]:
    """Write ``<stem>.csv`` (``fields`` of every row; None as empty) and ``<stem>.json`` (``doc``)
    atomically into ``out_dir``; returns the two paths."""
    from experiments.cache_keys import to_jsonable
    from defocus_cache import atomic_write_text

    out_dir.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(fields), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in fields})
    csv_path, json_path = out_dir / f"{stem}.csv", out_dir / f"{stem}.json"
    atomic_write_text(csv_path, buf.getvalue())
    atomic_write_text(json_path, json.dumps(to_jsonable(doc), indent=1, sort_keys=True) + "\n")
    return [csv_path, json_path]


def write_outputs(rows, out_dir: Path, info: dict) -> list[Path]:
    """Write ``evaluate.csv`` and ``evaluate.json`` atomically; returns the paths."""
    return write_csv_json(out_dir, "evaluate", rows, [*ID_COLUMNS, *METRIC_COLUMNS], {**info, "rows": rows})


STAGE_ID_COLUMNS = ("method_preset", "estimator", "scene", "f_number", "scene_preset", "encoding", "noise")


def stage_table_rows(cases) -> list[dict]:
    """Stage-attribution rows (:func:`experiments.stage_attribution.stage_rows`) of every case."""
    from experiments.stage_attribution import stage_rows

    rows = []
    for case in cases:
        if "stages" not in case.metrics:  # a trivial baseline: no stages
            continue
        ids = {c: case.key["preset" if c == "scene_preset" else c] for c in STAGE_ID_COLUMNS}
        rows += stage_rows(case.metrics["stages"], **ids)
    return rows


def format_stage_table(rows) -> str:
    """Terminal table: MAE (bias) per input × stage, overall and per σ_gt bin with pixels in it."""
    if not rows:
        return "(no stage rows)"
    bins = [k[4:] for k in rows[0] if k.startswith("mae_")]
    used = [b for b in bins if any((r.get(f"n_{b}") or 0) > 0 for r in rows)]
    head = ["preset", "scene", "f", "input", "stage", "n", "all", *(f"σ[{b.replace('_', ',')})" for b in used)]

    def cell(m, b):
        return "-" if m is None else f"{m:.2f}({b:+.2f})"

    body = [[str(r["method_preset"]), str(r["scene"]), f"{r['f_number']:g}", r["input"], r["stage"], str(r["n"]),
             cell(r["mae"], r["bias"]), *(cell(r[f"mae_{b}"], r[f"bias_{b}"]) for b in used)] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    lines = ["MAE (bias), px, per σ_gt bin [lo,hi) px; oracle_refine = σ_gt at the detected edges into Eq. 3; "
             "oracle_propagate = σ_gt at the edges into Eq. 4",
             "  ".join(h.ljust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body]
    return "\n".join(lines)


def write_stage_outputs(rows, out_dir: Path, info: dict) -> list[Path]:
    """Write ``stages.csv`` and ``stages.json`` atomically; returns the paths."""
    meta = {k: v for k, v in info.items() if k != "columns"}
    return write_csv_json(out_dir, "stages", rows, list(rows[0]) if rows else list(STAGE_ID_COLUMNS),
                          {**meta, "rows": rows})


