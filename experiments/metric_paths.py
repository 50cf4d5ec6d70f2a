"""Metric paths: nested metrics flattened to ``/``-separated names (the long table's ``metric`` column) and back.

A leaf module (it imports no other module of ``experiments``): the case runner writes flat metrics, the
table's queries nest them again.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["PATH_SEP", "flatten", "nest"]

#: Separator of the parts of a metric path (``image_vs_large/unchanged_small/psnr_db``).
PATH_SEP = "/"


def flatten(metrics: Mapping, prefix: str = "") -> dict:
    """Nested metrics → ``{"a/b/c": value}``; lists and tuples by index; strings dropped.

    Raises
    ------
    ValueError
        A key containing ``/`` (it would make the path ambiguous) or a value that is not a number,
        bool, None, string, mapping or sequence.
    """
    out = {}
    for k, v in metrics.items():
        k = str(k)
        if PATH_SEP in k:
            raise ValueError(f"metric key {k!r} is invalid; allowed: names without {PATH_SEP!r}")
        path = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(flatten(v, path + PATH_SEP))
        elif isinstance(v, (list, tuple)):
            out.update(flatten({str(i): x for i, x in enumerate(v)}, path + PATH_SEP))
        elif isinstance(v, str):
            continue
        elif v is None or isinstance(v, (bool, np.bool_)):
            out[path] = None if v is None else bool(v)
        elif isinstance(v, (int, float, np.integer, np.floating)):
            out[path] = v.item() if isinstance(v, np.generic) else v
        else:
            raise ValueError(f"metric {path!r} = {v!r} is invalid; allowed: numbers, bools, None")
    return out


def nest(flat: Mapping) -> dict:
    """:func:`flatten`'s inverse for mappings (list indices stay string keys)."""
    out: dict = {}
    for path, v in flat.items():
        node = out
        parts = path.split(PATH_SEP)
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = v
    return out
