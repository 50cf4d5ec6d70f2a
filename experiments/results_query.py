"""Reading the long results table: filter rows by their columns, take one value, group by columns.

The one way the harness reads results (the claims, the report, the plots' metrics and the tests):
:class:`Results` wraps rows of :mod:`experiments.results_table` and answers
``results.where(figure="fig7", preset="robust").value("image_vs_large/unchanged_small/psnr_db", scene=s)``.
A value that is not there raises :class:`MissingData` (a claim then says "not evaluated"); two rows
where one is expected raise ``ValueError`` (the query is wrong, a harness failure).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

__all__ = ["MissingData", "Results", "matches", "read_table"]


class MissingData(LookupError):
    """A value the caller needs is not in the table."""


def matches(row: Mapping, cond: Mapping) -> bool:
    """Whether every field of ``cond`` equals (or, for a tuple/list/set, is in) ``row``'s (missing: None).

    The one selection rule of the table's queries and of :meth:`experiments.cases.Case.matches`.
    """
    for k, want in cond.items():
        got = row.get(k)
        if isinstance(want, (tuple, list, set, frozenset)):
            if got not in want:
                return False
        elif got != want:
            return False
    return True


def _describe(cond: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in cond.items() if v is not None) or "all rows"


class Results:
    """Rows of the long results table (:data:`experiments.results_table.COLUMNS`), queried by column.

    Parameters
    ----------
    rows : iterable of dict
        Results rows; a condition ``column=value`` matches rows whose column equals ``value`` (None =
        empty), ``column=(a, b)`` rows whose column is one of them.
    """

    def __init__(self, rows: Iterable[dict] = (), *, where: str = ""):
        self.rows = list(rows)
        self._where = where

    # --- selection ---------------------------------------------------------------------------------
    def where(self, **cond) -> "Results":
        """The rows matching every condition."""
        sub = [r for r in self.rows if matches(r, cond)]
        label = "; ".join(x for x in (self._where, _describe(cond)) if x)
        return Results(sub, where=label)

    def group(self, *columns: str) -> dict:
        """``{value(s) of columns: Results}`` in order of first appearance (a tuple key for several columns)."""
        out: dict = {}
        for r in self.rows:
            key = tuple(r.get(c) for c in columns)
            out.setdefault(key[0] if len(columns) == 1 else key, []).append(r)
        return {k: Results(v, where=f"{self._where}; {columns}={k}") for k, v in out.items()}

    def distinct(self, column: str) -> list:
        """Distinct values of ``column`` in order of first appearance (None included)."""
        return list(dict.fromkeys(r.get(column) for r in self.rows))

    # --- values ------------------------------------------------------------------------------------
    def value(self, metric: str, **cond):
        """The value of the one row of ``metric`` (and ``cond``): a float, or None when empty.

        Raises
        ------
        MissingData
            No such row.
        ValueError
            Several rows (the query does not name one value).
        """
        got = [r for r in self.rows if r["metric"] == metric and matches(r, cond)]
        if not got:
            where = "; ".join(x for x in (self._where, _describe(cond)) if x)
            raise MissingData(f"no metric {metric} ({where})")
        if len(got) > 1:
            raise ValueError(f"{len(got)} rows of {metric} ({self._where}; {_describe(cond)}); the query must name "
                             "one (add a column: scene, preset, encoding, …)")
        return got[0]["value"]

    def number(self, metric: str, **cond) -> float:
        """:meth:`value` as a float (NaN when empty)."""
        v = self.value(metric, **cond)
        return math.nan if v is None else float(v)

    def get(self, metric: str, default=None, **cond):
        """:meth:`value`, or ``default`` when there is no such row."""
        try:
            return self.value(metric, **cond)
        except MissingData:
            return default

    def metrics(self, prefix: str = "") -> dict:
        """``{metric: value}`` of the rows (each metric once), optionally only those under ``prefix/``,
        with the prefix removed.

        Raises
        ------
        ValueError
            A metric appears in several rows.
        """
        out = {}
        cut = f"{prefix}/" if prefix else ""
        for r in self.rows:
            m = r["metric"]
            if cut and not m.startswith(cut):
                continue
            m = m[len(cut):]
            if m in out:
                raise ValueError(f"metric {r['metric']} appears in several rows ({self._where}); select one case first")
            out[m] = r["value"]
        return out

    def nested(self, prefix: str = "") -> dict:
        """:meth:`metrics` as a nested dict (paths split at ``/``)."""
        from .metric_paths import nest

        return nest(self.metrics(prefix))

    def require(self, what: str = "rows") -> "Results":
        """Self, or :class:`MissingData` naming the selection when it is empty."""
        if not self.rows:
            raise MissingData(f"no {what} ({self._where or 'empty table'})")
        return self

    # --- container ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.rows)

    def __bool__(self) -> bool:
        return bool(self.rows)

    def __iter__(self) -> Iterator[dict]:
        return iter(self.rows)

    def __add__(self, other: "Results") -> "Results":
        return Results([*self.rows, *other.rows])

    def __repr__(self) -> str:
        return f"Results({len(self.rows)} rows; {self._where or 'all'})"


def read_table(path) -> Results:
    """The rows of a ``results.parquet`` / ``results.csv`` (or of the folder holding one) as :class:`Results`.

    Raises
    ------
    ValueError
        No results table there, or a file that is not one.
    """
    from .results_table import read_results, read_results_csv

    path = Path(path)
    if path.is_dir():
        parquet, csv_path = path / "results.parquet", path / "results.csv"
        path = parquet if parquet.is_file() else csv_path
    if not path.is_file():
        raise ValueError(f"no results table at {path}; allowed: a results.parquet or results.csv (python -m "
                         "repro.figures writes one)")
    if path.suffix == ".parquet":
        try:
            return Results(read_results(path)[0])
        except ImportError:
            path = path.with_suffix(".csv")
    return Results(read_results_csv(path))
