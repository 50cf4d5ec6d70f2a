"""Cases: the independent units of work a figure is made of, each cached on its own, and their table rows.

A figure (:class:`experiments.registry.Figure`) declares its cases — ``Figure.cases(config)`` gives a
tuple of :class:`Case`, one per scene set × scene × method preset × aperture (or whatever the
figure's unit is) — and computes one with ``Figure.compute_case(config, case, inputs)``, which returns
the case's arrays and its metrics (a nested dict of numbers, flattened here into ``/``-separated
metric paths). A case may *need* other cases (:attr:`Case.needs`: a shared stage such as the
renders and the preset-independent rows of Fig. 7, or the scene cases a pooled summary reads); it then
receives their :class:`CaseOutput` in ``inputs``.

:func:`run_case` computes one case through the figure cache (``<cache>/figures``, keyed by the figure,
its code version, the source fingerprint of ``method``/``scenes``/``experiments``, the config, the
case and what it needs, the library versions and, for figures that render, the Mitsuba variant),
with numba and BLAS on one thread (:func:`experiments.threads.single_threaded`): cases are the
parallelism (:mod:`repro._runner` runs them on Dask workers), and one thread per case makes every number
independent of how many cases run at once. It is the one case store: the figures, the evaluations
(:mod:`experiments.units`) and the sweep's cells (:mod:`experiments.sweep_cells`) keep their cases there.
:func:`run_cases` runs cases one after another in this process (needs first).
:func:`case_rows` turns a finished case into rows of the long results table
(:mod:`experiments.results_table`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from .metric_paths import flatten, nest

__all__ = ["Case", "CaseOutput", "case_key", "case_rows", "task_key", "method_presets", "order_cases", "run_case",
           "run_cases", "stored_case"]


@dataclasses.dataclass(frozen=True)
class Case:
    """One unit of a figure's work; its fields are the columns of the rows it gives.

    Attributes
    ----------
    figure : str
        The figure's name (``"fig7"``).
    scene_set : str or None
        Scene set (:func:`experiments.scene_sets.scene_set_scenes`); None for a unit without one.
    scene : str or None
        Scene (or image) name; None for a unit without one (pooled over scenes, analytic images).
    preset : str or None
        Method preset (:data:`method.PRESETS`); None for a preset-independent unit.
    aperture : float or None
        f-number of the render.
    encoding : str or None
        Input encoding given to the method.
    noise : str or None
        Sensor noise level of the input (:data:`scenes.display.NOISE_LEVELS`).
    estimator : str or None
        Blur estimator overriding the preset's (:data:`method.BLUR_ESTIMATORS`).
    variant : str or None
        The figure's own axis (``"s=2"`` bias scale, ``"nsr=0.01"``, ``"stage"``, ``"pooled"`` …).
    scene_size : str or None
        Render size (``"small"`` / ``"full"``).
    needs : tuple of Case
        Cases whose outputs this one reads (computed first, passed as ``inputs``).
    """

    figure: str
    scene_set: str | None = None
    scene: str | None = None
    preset: str | None = None
    aperture: float | None = None
    encoding: str | None = None
    noise: str | None = None
    estimator: str | None = None
    variant: str | None = None
    scene_size: str | None = None
    needs: tuple = ()

    #: Fields that identify a case (and name its columns).
    ID_FIELDS = ("figure", "scene_set", "scene", "preset", "aperture", "encoding", "noise", "estimator", "variant",
                 "scene_size")

    def ids(self) -> dict:
        """The identifying fields (``needs`` excluded), None where unset."""
        return {f: getattr(self, f) for f in self.ID_FIELDS}

    def key(self) -> dict:
        """JSON-able identity: the fields and, recursively, the keys of what the case needs."""
        out = {k: v for k, v in self.ids().items() if v is not None}
        if self.needs:
            out["needs"] = [n.key() for n in self.needs]
        return out

    @property
    def label(self) -> str:
        """Short readable name: the set fields joined by ``/`` (aperture as ``f<N>``)."""
        parts = []
        for f in self.ID_FIELDS[1:-1]:
            v = getattr(self, f)
            if v is not None:
                parts.append(f"f{v:g}" if f == "aperture" else str(v))
        return "/".join([self.figure, *parts])

    def matches(self, **fields) -> bool:
        """Whether every given field equals (or, for a tuple/list/set, is in) the case's
        (:func:`experiments.results_query.matches`; an unknown field is an AttributeError)."""
        from .results_query import matches

        return matches({k: getattr(self, k) for k in fields}, fields)


@dataclasses.dataclass(frozen=True)
class CaseOutput:
    """A finished case: its flat metrics, its grouped rows, where its arrays are, how it was obtained.

    Attributes
    ----------
    case : Case
    metrics : dict
        Metric path → number (bool, int, float) or None.
    groups : tuple
        ``((ids, metrics), ...)``: rows with further columns set (``encoding``, ``estimator``, …).
    info : dict
        JSON-able facts of the case that are not numbers of the table (written with it, not as rows).
    folder : str or None
        Cache entry holding ``arrays.npz`` (None when computed without the cache).
    cached : bool
        Whether the case was read from the cache.
    seconds : float
        Wall time of computing (or reading) it.
    """

    case: Case
    metrics: dict
    groups: tuple = ()
    info: dict = dataclasses.field(default_factory=dict)
    folder: str | None = None
    cached: bool = False
    seconds: float = 0.0
    memory: dict | None = dataclasses.field(default=None, compare=False, repr=False)

    def arrays(self) -> dict:
        """The case's arrays (read from its cache entry)."""
        if self.memory is not None:
            return self.memory
        if self.folder is None:
            return {}
        with np.load(Path(self.folder) / "arrays.npz", allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}

    def nested(self) -> dict:
        """The metrics as a nested dict (the metric paths split at ``/``)."""
        return nest(self.metrics)

    def without_arrays(self) -> "CaseOutput":
        """The same output without in-memory arrays (what a worker sends back)."""
        return dataclasses.replace(self, memory=None) if self.memory is not None and self.folder else self


def method_presets(names) -> dict:
    """``name → DefocusParams`` of a figure's ``presets`` field, checked.

    Parameters
    ----------
    names : sequence of str
        Keys of :data:`method.PRESETS`, unique, non-empty.

    Returns
    -------
    dict
        ``{name: DefocusParams.preset(name)}`` in the given order.

    Raises
    ------
    ValueError
        Empty, duplicated or unknown names.
    """
    from method import PRESETS, DefocusParams

    names = tuple(names)
    if not names or len(set(names)) != len(names):
        raise ValueError(f"presets={names!r} is invalid; allowed: unique names of method.PRESETS ({', '.join(PRESETS)})")
    PRESETS.check_all(names, what="preset")
    return {n: DefocusParams.preset(n) for n in names}


def order_cases(cases: Iterable[Case]) -> list[Case]:
    """Every case and, recursively, what it needs, each once, needs before the cases that read them."""
    out: dict[Case, None] = {}

    def visit(c: Case):
        if c in out:
            return
        for n in c.needs:  # a frozen case can only need cases made before it: no cycles
            visit(n)
        out[c] = None

    for c in cases:
        visit(c)
    return list(out)


def case_key(figure, config, case: Case) -> dict:
    """The cache key of one case (see the module docstring); a unit with a ``key_config(config, case)``
    (:class:`experiments.units.CaseUnit`) puts that in place of the whole config."""
    from .cache_keys import cache_key

    key_config = getattr(figure, "key_config", None)
    return {**cache_key(figure, config if key_config is None else key_config(config, case)), "case": case.key()}


def stored_case(figure, config, case: Case, *, cache_dir=None) -> Path | None:
    """The case store's folder of ``case`` when it holds the finished case (valid for its current key), else
    None: what a run would read back instead of computing."""
    from defocus_cache import Cache

    from .cache_keys import CACHE_SUBDIR

    if not getattr(figure, "cached", True):
        return None
    if cache_dir is None:
        from scenes.backend import cache_root

        cache_dir = cache_root() / CACHE_SUBDIR
    cache, key = Cache(Path(cache_dir)), case_key(figure, config, case)
    return cache.path_for(key) if cache.is_valid(key) else None


def task_key(figure, config, case: Case) -> str:
    """A Dask task key naming the case: ``case-<figure>-<16 hex digits of its cache key>``."""
    from defocus_cache import hash_key

    return f"case-{figure.name}-{hash_key(case_key(figure, config, case))[:16]}"


def _check_output(figure, case: Case, data) -> tuple[dict, dict, tuple, dict]:
    if not isinstance(data, Mapping) or not isinstance(data.get("metrics", {}), Mapping):
        raise TypeError(f"{figure.name}.compute_case({case.label}) must return a dict with a 'metrics' dict")
    arrays = {k: np.asarray(v) for k, v in data.get("arrays", {}).items()}
    for k, v in arrays.items():
        if v.dtype == object:
            raise TypeError(f"{figure.name}.compute_case({case.label}): array {k!r} has dtype object")
    groups = tuple((dict(ids), flatten(m)) for ids, m in data.get("groups", ()))
    from .cache_keys import to_jsonable

    return arrays, flatten(data.get("metrics", {})), groups, to_jsonable(data.get("info", {}))


def run_case(figure, config, case: Case, inputs: Mapping | None = None, *, force: bool = False,
             use_cache: bool = True, cache_dir=None) -> CaseOutput:
    """Compute one case (cached), numba and BLAS on one thread.

    Parameters
    ----------
    figure : experiments.registry.Figure
    config : frozen dataclass
        One of ``figure.configs`` (or any instance of the same dataclass).
    case : Case
        One of ``figure.cases(config)`` (or a case they need).
    inputs : mapping of Case to CaseOutput, optional
        The outputs of ``case.needs`` (computed here when missing).
    force : bool, keyword-only
        Recompute even when cached (this case only).
    use_cache : bool, keyword-only
        Read and write the cache (False: compute in memory; :attr:`CaseOutput.folder` is None).
    cache_dir : path, optional, keyword-only
        Default ``<cache>/figures``.

    Returns
    -------
    CaseOutput
    """
    from defocus_cache import Cache

    from .cache_keys import CACHE_SUBDIR, check_config

    check_config(config)
    use_cache = use_cache and getattr(figure, "cached", True)
    inputs = dict(inputs or {})
    t0 = time.perf_counter()

    def compute():
        for need in case.needs:
            if need not in inputs:
                inputs[need] = run_case(figure, config, need, inputs, use_cache=use_cache, cache_dir=cache_dir)
        from .threads import single_threaded

        with single_threaded():
            return _check_output(figure, case, figure.compute_case(config, case, inputs))

    if not use_cache:
        arrays, metrics, groups, info = compute()
        return CaseOutput(case=case, metrics=metrics, groups=groups, info=info, seconds=time.perf_counter() - t0,
                          memory=arrays)
    from scenes.backend import cache_root

    cache = Cache(Path(cache_dir) if cache_dir is not None else cache_root() / CACHE_SUBDIR)
    key = case_key(figure, config, case)
    if force:
        cache.invalidate(key)
    cached = cache.is_valid(key)

    def build(folder: Path):
        arrays, metrics, groups, info = compute()
        with open(folder / "arrays.npz", "wb") as fh:
            np.savez_compressed(fh, **arrays)
        doc = {"metrics": metrics, "groups": [[ids, m] for ids, m in groups], "info": info}
        (folder / "metrics.json").write_text(json.dumps(_json_numbers(doc), indent=1, sort_keys=True))

    folder = cache.get_or_build(key, build)
    doc = json.loads((folder / "metrics.json").read_text())
    return CaseOutput(case=case, metrics=_from_json(doc["metrics"]),
                      groups=tuple((ids, _from_json(m)) for ids, m in doc["groups"]), info=_infinities(doc["info"]),
                      folder=str(folder), cached=cached, seconds=time.perf_counter() - t0)


def _json_numbers(obj):
    """NaN → None and ±inf → "inf"/"-inf" (JSON has neither)."""
    if isinstance(obj, dict):
        return {k: _json_numbers(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_json_numbers(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    return obj


def _infinities(obj):
    """:func:`_json_numbers`' "inf" / "-inf" back to floats, anywhere in a JSON document."""
    if isinstance(obj, dict):
        return {k: _infinities(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_infinities(v) for v in obj]
    return float(obj) if obj in ("inf", "-inf") else obj


def _from_json(flat: dict) -> dict:
    return {k: (float(v) if isinstance(v, str) else v) for k, v in flat.items()}


def run_cases(figure, config, cases: Iterable[Case] | None = None, *, force: bool = False, progress=None,
              cache_dir=None, use_cache: bool = True) -> dict:
    """Run a figure's cases (default: all of ``figure.cases(config)``) one after another in this process.

    Parameters
    ----------
    figure : experiments.registry.Figure
    config : frozen dataclass
    cases : iterable of Case, optional
    force : bool, keyword-only
        Recompute every case (each once).
    progress : callable, optional, keyword-only
        ``progress(case)`` after each case.
    cache_dir : path, optional, keyword-only
    use_cache : bool, keyword-only
        Read and write the cache (False: every case computed in memory).

    Returns
    -------
    dict
        ``{Case: CaseOutput}`` for every case and what it needs, needs first.
    """
    todo = order_cases(figure.cases(config) if cases is None else cases)
    done: dict = {}
    for c in todo:
        done[c] = run_case(figure, config, c, done, force=force, cache_dir=cache_dir, use_cache=use_cache)
        if progress is not None:
            progress(c)
    return done


def case_rows(output: CaseOutput, *, evaluation_id: str, source: str = "figures") -> list[dict]:
    """Rows of the long results table of one finished case (:func:`experiments.results_table.metric_rows`).

    The case's fields fill the columns ``figure`` … ``scene_size``; a procedural scene's name fills
    ``seed``, ``split``, ``camera`` and ``lighting``; each group's ids add further columns.
    """
    from .results_table import metric_rows

    ids = {"evaluation_id": evaluation_id, "source": source, **scene_ids(output.case.scene)}
    ids.update({k: v for k, v in output.case.ids().items() if v is not None})
    rows = metric_rows(ids, output.metrics)
    for gids, metrics in output.groups:
        rows += metric_rows({**ids, **gids}, metrics)
    return rows


def scene_ids(scene: str | None) -> dict:
    """``seed``, ``split``, ``camera``, ``lighting`` of a procedural scene name (empty for any other)."""
    from scenes.library.procedural import draw_layout, is_procedural_name, seed_of, split_of

    if not is_procedural_name(scene):
        return {}
    seed, camera = seed_of(scene)
    layout = draw_layout(seed, camera=camera)
    return {"seed": seed, "split": split_of(seed), "camera": layout["camera_name"], "lighting": layout["lighting"]}
