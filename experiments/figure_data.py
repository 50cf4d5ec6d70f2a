"""A figure's finished cases: what its plot draws and the rows it adds to the results table.

:class:`FigureData` holds the :class:`~experiments.cases.CaseOutput` of every case of one figure run
(one config) and gives them by their fields (:meth:`FigureData.find`, :meth:`FigureData.one`), their
arrays and metrics, and the figure's rows of the long results table (:meth:`FigureData.rows`,
:mod:`experiments.results_table`). :func:`run_figure` computes a figure in this process, case after
case through the cache; :mod:`repro._runner` does the same on Dask workers and builds the same object.
"""

from __future__ import annotations

import dataclasses
from .cases import CaseOutput, case_rows, run_cases

__all__ = ["FigureData", "evaluation_id", "evaluation_mode", "run_figure"]


def evaluation_id(figure, config, mode: str | None = None) -> str:
    """``<figure>-<mode>-<8 hex digits of the config>``: the ``evaluation_id`` of a figure run's rows.

    ``mode`` is ``"quick"`` / ``"full"`` when ``config`` is that mode's config, else ``"custom"``
    (found from ``figure.configs`` when not given).
    """
    from defocus_cache import hash_key

    from .cache_keys import to_jsonable

    if mode is None:
        mode = next((m for m, c in figure.configs.items() if c == config), "custom")
    return f"{figure.name}-{mode}-{hash_key(to_jsonable(config))[:8]}"


def evaluation_mode(evaluation_id: str, figure: str) -> str | None:
    """The mode (``quick``, ``full``, ``custom``) that :func:`evaluation_id` wrote into a run of ``figure``
    (a figure name); None for an id of another shape or figure."""
    head, sep, rest = str(evaluation_id).partition(f"{figure}-")
    mode, sep2, digest = rest.rpartition("-")
    return mode if sep and not head and sep2 and mode and "-" not in mode and len(digest) == 8 else None


@dataclasses.dataclass
class FigureData:
    """Every finished case of one figure run.

    Attributes
    ----------
    figure : experiments.registry.Figure
    config : frozen dataclass
    outputs : dict
        ``{Case: CaseOutput}`` of the figure's cases and what they need (needs first).
    mode : str
        ``"quick"``, ``"full"`` or ``"custom"``.
    """

    figure: object
    config: object
    outputs: dict
    mode: str = "custom"

    @property
    def evaluation_id(self) -> str:
        """The ``evaluation_id`` of this run's rows (:func:`evaluation_id`)."""
        return evaluation_id(self.figure, self.config, self.mode)

    def find(self, **fields) -> list[CaseOutput]:
        """Outputs whose case matches ``fields`` (:meth:`experiments.cases.Case.matches`), in case order."""
        return [o for c, o in self.outputs.items() if c.matches(**fields)]

    def one(self, **fields) -> CaseOutput:
        """The one output matching ``fields``.

        Raises
        ------
        LookupError
            None or several match.
        """
        got = self.find(**fields)
        if len(got) != 1:
            raise LookupError(f"{self.figure.name}: {len(got)} cases match {fields} (need exactly one)")
        return got[0]

    def values(self, field: str, **fields) -> list:
        """Distinct values of a case field among the outputs matching ``fields``, in case order."""
        return list(dict.fromkeys(getattr(o.case, field) for o in self.find(**fields)))

    @property
    def cached(self) -> bool:
        """Whether every case came from the cache."""
        return all(o.cached for o in self.outputs.values())

    def rows(self) -> list[dict]:
        """The figure's rows of the long results table (every case, including the ones others need)."""
        out = []
        for o in self.outputs.values():
            out += case_rows(o, evaluation_id=self.evaluation_id)
        return out

    def single(self) -> dict:
        """A one-unit figure's compute dict: its arrays plus ``"metrics"`` (as ``compute`` returned them)."""
        (output,) = self.outputs.values()
        return {**output.arrays(), "metrics": output.info}


def run_figure(figure, config, *, mode: str | None = None, force: bool = False, cases=None,
               progress=None, cache_dir=None, use_cache: bool = True) -> FigureData:
    """Compute every case of ``figure`` (or ``cases``) in this process, through the cache.

    Parameters
    ----------
    figure : experiments.registry.Figure
    config : frozen dataclass
    mode : str, optional, keyword-only
        Label of the run (default: found from ``figure.configs``).
    force : bool, keyword-only
        Recompute every case.
    cases : iterable of Case, optional, keyword-only
        A subset of ``figure.cases(config)``.
    progress : callable, optional, keyword-only
        ``progress(case)`` after each case.
    cache_dir : path, optional, keyword-only
    use_cache : bool, keyword-only
        Read and write the cache (False: every case computed in memory).

    Returns
    -------
    FigureData
    """
    outputs = run_cases(figure, config, cases, force=force, progress=progress, cache_dir=cache_dir,
                        use_cache=use_cache)
    if mode is None:
        mode = next((m for m, c in figure.configs.items() if c == config), "custom")
    return FigureData(figure=figure, config=config, outputs=outputs, mode=mode)


