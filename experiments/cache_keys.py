"""The figure cache's keys: JSON-able values, the source fingerprint of the project's numerics, a case's key.

A leaf module (it imports no other module of ``experiments``), so the figure registry, the case runner,
the evaluations and the command-line tools share one definition of each without import cycles.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from collections.abc import Mapping

import numpy as np

__all__ = ["CACHE_SUBDIR", "cache_key", "check_config", "code_fingerprint", "plugin_fingerprints", "to_jsonable"]

#: Folder under the project cache holding figure compute results.
CACHE_SUBDIR = "figures"

#: Packages whose source determines every figure's numbers.
_FINGERPRINT_PACKAGES = ("method", "scenes", "experiments")
#: Modules that only read computed results (plots, the claim verdicts of the report, the table's queries,
#: the finished figure's views, the leaderboard's tables): editing them must not invalidate cached figure data.
FINGERPRINT_EXCLUDED = ("experiments/plotting", "experiments/claims", "experiments/results_query.py",
                        "experiments/figure_data.py", "experiments/leaderboard.py")


def check_config(config) -> None:
    """ValueError unless ``config`` is a frozen dataclass instance."""
    if not dataclasses.is_dataclass(config) or isinstance(config, type) or not type(config).__dataclass_params__.frozen:
        raise ValueError(f"config {config!r} is invalid; allowed: a frozen dataclass instance")


def to_jsonable(obj):
    """Recursively convert numpy scalars/arrays, tuples and dataclasses to JSON types."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable(dataclasses.asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None if np.isnan(obj) else ("inf" if obj > 0 else "-inf")
    return obj


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """:func:`defocus_cache.source_fingerprint` (16 hex digits) of ``method``, ``scenes`` and ``experiments``.

    Part of every figure's cache key, so an edit of the estimator, the scenes or an experiment
    invalidates cached figure data without anyone remembering to bump a version number
    (renders keep their own, finer cache keyed by each scene's content).
    """
    from defocus_cache import source_fingerprint

    return source_fingerprint(*(importlib.import_module(p) for p in _FINGERPRINT_PACKAGES),
                              exclude=FINGERPRINT_EXCLUDED)


def plugin_fingerprints() -> dict:
    """Registry kind -> name -> what identifies each variant registered from another package
    (:meth:`method.registry.Registry.plugin_names`; code outside :func:`code_fingerprint`): an estimator's
    :func:`defocus_cache.source_fingerprint`, a preset's fields. Empty when there is none."""
    from defocus_cache import source_fingerprint
    from method import BLUR_ESTIMATORS, PRESETS

    out = {}
    for reg in (BLUR_ESTIMATORS, PRESETS):
        names = reg.plugin_names()
        if names:
            out[reg.kind] = {n: (source_fingerprint(reg[n]) if callable(reg[n]) else to_jsonable(reg[n]))
                             for n in names}
    return out


def cache_key(figure, config) -> dict:
    """JSON-able key of a compute result: figure name, code version and source fingerprint, config type and
    fields, the versions of the numerical and rendering libraries (:data:`defocus_cache.KEY_LIBRARIES`)
    and, for figures that render, the Mitsuba variant.

    Parameters
    ----------
    figure : experiments.registry.Figure or experiments.units.CaseUnit
        Read for ``name``, ``version`` and ``renders``.
    config : frozen dataclass
    """
    from defocus_cache import library_versions

    key = {
        "figure": figure.name,
        "version": figure.version,
        "code": code_fingerprint(),
        "config_type": type(config).__qualname__,
        "config": to_jsonable(config),
        "libraries": library_versions(),
    }
    plugins = plugin_fingerprints()
    if plugins:  # only then: the keys of a run without other packages' variants stay as they were
        key["plugins"] = plugins
    if figure.renders:
        from scenes.backend import select_variant

        key["mitsuba"] = {"variant": select_variant()}
    return key
