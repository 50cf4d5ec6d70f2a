"""The case unit: a named set of cases the case runner runs like a figure's.

A leaf module (it imports no other module of ``experiments``), so the evaluations
(:mod:`experiments.units`), the sweep's cells and the stage attribution's oracle runs
(:mod:`experiments.stage_attribution`) define their units without import cycles.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

__all__ = ["CaseUnit"]


@dataclasses.dataclass(frozen=True)
class CaseUnit:
    """A named set of cases the runner runs like a figure's (:mod:`experiments.units` lists them).

    ``key_config(config, case)``, when given, is the part of ``config`` (plus anything else that shapes the
    case's numbers) that enters the case's cache key instead of the whole config: a case of a bigger grid
    is then the same stored case as in a smaller one.
    """

    name: str
    cases_fn: Callable
    case_fn: Callable
    version: int = 1
    renders: bool = True
    cached: bool = False
    key_config: Callable | None = None

    def cases(self, config) -> tuple:
        """The cases of ``config``."""
        return tuple(self.cases_fn(config))

    def compute_case(self, config, case, inputs) -> dict:
        """One case's ``{"arrays", "metrics", "groups", "info"}``."""
        return self.case_fn(config, case, inputs)
