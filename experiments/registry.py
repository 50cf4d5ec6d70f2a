"""Figure registry (showyourwork style).

Every reproduced figure is a :class:`Figure`: a name (``"fig10"``), a title, its cases
(``cases(config)``: the independent units it is made of, :class:`experiments.cases.Case`) and
``compute_case(config, case, inputs)`` returning one case's arrays and metrics, a ``plot`` function
(in :mod:`experiments.plotting`, imported lazily so compute workers never load matplotlib) that
draws from the finished cases (:class:`experiments.figure_data.FigureData`), and one frozen config
dataclass per mode (``"quick"`` and ``"full"``). Every parameter of an experiment is a field of that
one dataclass, with a comment giving its meaning and unit. A figure that is one unit of work gives
``compute(config)`` instead (arrays plus a ``"metrics"`` dict); it is then one case.

Each case is cached in ``<cache>/figures`` through :class:`defocus_cache.Cache`
(:func:`experiments.cases.run_case`), keyed by :func:`experiments.cache_keys.cache_key` and the case, as ``arrays.npz`` +
``metrics.json``. ``python -m repro.figures`` runs the cases (on Dask workers, :mod:`repro._runner`).

Adding a figure: write ``experiments/figN_topic.py`` defining ``FIGURE = Figure(...)`` and
``experiments/plotting/figN.py`` defining ``plot(data, config, out_stem)``, then add the module
name to :data:`FIGURE_MODULES`.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Iterator, Mapping

__all__ = ["FIGURES", "FIGURE_MODULES", "Figure", "library_versions"]

#: Modules (under ``experiments``) that each define ``FIGURE``; order = listing order.
FIGURE_MODULES = ("fig2_sensor_size", "fig4_estimators", "fig5_cross_bilateral", "fig6_alpha_sweep",
                  "fig7_doubled_defocus", "fig8_refocus", "fig10_coc_vs_distance", "fig11_gallery",
                  "figS1_stages", "figS2_photos")

@dataclasses.dataclass(frozen=True)
class Figure:
    """One reproduced paper figure.

    Attributes
    ----------
    name : str
        CLI name, e.g. ``"fig10"``; output files are ``<name>.png/.pdf/.metrics.json``.
    title : str
        One-line description (shown by ``repro.figures --list``).
    plot : str
        ``"module:function"`` of the plot function ``plot(data, config, out_stem) -> list[Path]``
        (resolved lazily; ``data`` is an :class:`experiments.figure_data.FigureData`; it writes
        ``out_stem.png`` and ``out_stem.pdf`` atomically).
    configs : Mapping[str, object]
        Frozen dataclass instances for the modes ``"quick"`` and ``"full"``.
    cases_fn : callable, optional
        ``cases_fn(config) -> tuple[Case, ...]``: the figure's independent cases.
    case_fn : callable, optional
        ``case_fn(config, case, inputs) -> dict`` with ``"arrays"`` (name → ndarray), ``"metrics"``
        (nested dict of numbers), optionally ``"groups"`` (``[(ids, metrics)]``: rows with further
        columns) and ``"info"`` (JSON-able facts that are not numbers); ``inputs`` maps each case of
        ``case.needs`` to its :class:`~experiments.cases.CaseOutput`.
    compute : callable, optional
        For a figure that is one unit of work (no ``cases_fn``): ``compute(config) -> dict`` of numpy
        arrays plus a ``"metrics"`` dict (its numbers become the case's metrics, the whole dict its info).
    version : int
        Code version of the computation; part of the cache key.
    sigma_convention : str
        How the figure's blur quantities relate to Gaussian σ (written to the metrics file).
    renders : bool
        Whether it renders with Mitsuba; if so the Mitsuba variant is part of the cache key
        (variants draw different sample streams).
    key_config : callable, optional
        ``key_config(config, case) -> dict``: the fields of ``config`` one case reads (plus anything else
        that shapes its numbers), put in the case's cache key instead of the whole config, so a case is the
        same stored case in every config that gives it (e.g. one photo of the quick and of the full config).
        Default: the whole config.
    """

    name: str
    title: str
    plot: str
    configs: Mapping[str, object]
    cases_fn: Callable | None = None
    case_fn: Callable | None = None
    compute: Callable[[object], dict] | None = None
    version: int = 1
    sigma_convention: str = "line_spread: sigma = sqrt((c/4)^2 + sigma_filter^2), px"
    renders: bool = True
    key_config: Callable | None = None

    def __post_init__(self):
        for mode in ("quick", "full"):
            cfg = self.configs.get(mode)
            if cfg is None or not dataclasses.is_dataclass(cfg):
                raise ValueError(f"figure {self.name!r}: configs[{mode!r}] must be a dataclass instance")
            if not getattr(type(cfg), "__dataclass_params__").frozen:
                raise ValueError(f"figure {self.name!r}: config {type(cfg).__name__} must be frozen")
        if (self.cases_fn is None) != (self.case_fn is None) or (self.case_fn is None) == (self.compute is None):
            raise ValueError(f"figure {self.name!r}: give cases_fn and case_fn, or compute alone")

    def config(self, mode: str = "full"):
        """The config of ``mode`` (``"quick"`` or ``"full"``)."""
        try:
            return self.configs[mode]
        except KeyError:
            raise ValueError(f"mode={mode!r} is invalid; allowed: {sorted(self.configs)}") from None

    def plot_function(self) -> Callable:
        """Import and return the plot function."""
        module, _, func = self.plot.partition(":")
        return getattr(importlib.import_module(module), func)

    @property
    def single_unit(self) -> bool:
        """Whether the figure is one unit of work (``compute``) rather than declared cases."""
        return self.case_fn is None

    def cases(self, config) -> tuple:
        """The cases of ``config`` (:class:`experiments.cases.Case`); a one-unit figure has one."""
        if self.cases_fn is None:
            from .cases import Case

            return (Case(figure=self.name),)
        out = tuple(self.cases_fn(config))
        bad = [c.label for c in out if c.figure != self.name]
        if bad:
            raise ValueError(f"figure {self.name!r}: cases of another figure {bad}")
        return out

    def compute_case(self, config, case, inputs) -> dict:
        """One case's ``{"arrays", "metrics", "groups", "info"}`` (see ``case_fn``)."""
        if self.case_fn is not None:
            return self.case_fn(config, case, inputs)
        data = self.compute(config)
        if not isinstance(data, Mapping) or not isinstance(data.get("metrics"), Mapping):
            raise TypeError(f"{self.name}.compute must return a dict with a 'metrics' dict")
        return {"arrays": {k: v for k, v in data.items() if k != "metrics"}, "metrics": data["metrics"],
                "info": data["metrics"]}


class _LazyFigures(Mapping):
    """``name → Figure``, importing the figure modules on first use (avoids import cycles)."""

    def __init__(self):
        self._figures: dict[str, Figure] | None = None

    def _load(self) -> dict[str, Figure]:
        if self._figures is None:
            figures = {}
            for mod in FIGURE_MODULES:
                fig = importlib.import_module(f"{__package__}.{mod}").FIGURE
                if fig.name in figures:
                    raise ValueError(f"duplicate figure name {fig.name!r}")
                figures[fig.name] = fig
            self._figures = figures
        return self._figures

    def __getitem__(self, name: str) -> Figure:
        return self._load()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._load())

    def __len__(self) -> int:
        return len(self._load())


#: Registered figures by name.
FIGURES: Mapping[str, Figure] = _LazyFigures()


def library_versions() -> dict:
    """Versions of Python and the libraries a figure depends on (for the metrics files): those of the
    cache keys (:data:`defocus_cache.KEY_LIBRARIES`) plus matplotlib."""
    from defocus_cache import KEY_LIBRARIES
    from defocus_cache import library_versions as versions

    return dict(versions((*KEY_LIBRARIES, "matplotlib")))
