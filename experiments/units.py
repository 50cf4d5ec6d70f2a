"""Case units that are not figures: the evaluations and the accuracy benchmark, run by the same case runner.

A :class:`CaseUnit` has what the runner (:mod:`repro._runner`, :func:`experiments.cases.run_case`) needs
of a figure — a name, ``cases(config)``, ``compute_case(config, case, inputs)``, a code version, whether
it renders — and says whether its cases go through the figure cache (``cached``; the evaluations keep
their own stores: :func:`experiments.evaluation.evaluate_case`'s cache, the procedural evaluation's
resume files). :func:`unit` finds a figure or a unit by name (what a Dask worker does with a task's name).

* ``evaluate`` (``repro.evaluate`` on named scenes): one case per scene × aperture × encoding × noise ×
  preset × estimator of an :class:`EvaluateConfig` (:func:`experiments.evaluation.evaluate_case`), and
  one per trivial baseline (:func:`experiments.baselines.baseline_case`).
* ``procedural`` (``repro.evaluate --procedural``): one case per scene seed of a
  :class:`experiments.procedural_eval.ProceduralPlan` (:func:`experiments.procedural_eval.score_scene`).
* ``accuracy`` (``repro.bench --accuracy``): :data:`experiments.bench.accuracy.ACCURACY_UNIT`.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable

__all__ = ["EVALUATE", "PROCEDURAL", "UNIT_MODULES", "CaseUnit", "EvaluateConfig", "unit"]


@dataclasses.dataclass(frozen=True)
class CaseUnit:
    """A named set of cases the runner runs like a figure's (see the module docstring)."""

    name: str
    cases_fn: Callable
    case_fn: Callable
    version: int = 1
    renders: bool = True
    cached: bool = False

    def cases(self, config) -> tuple:
        """The cases of ``config``."""
        return tuple(self.cases_fn(config))

    def compute_case(self, config, case, inputs) -> dict:
        """One case's ``{"arrays", "metrics", "groups", "info"}``."""
        return self.case_fn(config, case, inputs)


@dataclasses.dataclass(frozen=True, kw_only=True)
class EvaluateConfig:
    """What ``repro.evaluate`` scores on the named scenes."""

    presets: tuple[str, ...] = ("paper",)
    # method presets (method.PRESETS).
    estimators: tuple = (None,)
    # blur estimators (method.BLUR_ESTIMATORS) overriding each preset's; None: the preset's own.
    scenes: tuple[str, ...] = ("planes",)
    # scene names (scenes.SCENES).
    f_numbers: tuple[float, ...] = (8.0, 4.0)
    # apertures N.
    scene_size: str = "small"
    # render size ("small" 160x120, "full" 640x480 px).
    encodings: tuple[str, ...] = ("srgb",)
    # input encodings.
    noises: tuple[str, ...] = ("none",)
    # sensor noise levels (scenes.display.NOISE_LEVELS).
    variant: str | None = None
    # Mitsuba variant requested.
    force: bool = False
    # recompute even when experiments.evaluation.evaluate_case has the case cached.
    baselines: tuple[str, ...] = dataclasses.field(default_factory=lambda: _all_baselines())
    # trivial baselines scored beside the presets (experiments.baselines.BASELINES; default: all).


def _all_baselines() -> tuple[str, ...]:
    from .baselines import BASELINES

    return tuple(BASELINES)


def _evaluate_cases(config: EvaluateConfig) -> tuple:
    from .cases import Case

    return tuple(Case("evaluate", scene=s, preset=pr, aperture=float(n), encoding=enc, noise=nz, estimator=e,
                      scene_size=config.scene_size)
                 for s in config.scenes for n in config.f_numbers for enc in config.encodings for nz in config.noises
                 for pr in (*config.presets, *config.baselines)
                 for e in ((None,) if pr in config.baselines else config.estimators))


def _evaluate_case(config: EvaluateConfig, case, inputs) -> dict:
    """:func:`experiments.evaluation.evaluate_case` of one case (its own cache); metrics numbers, and in
    ``info`` the case's key, whether it was cached and its nested metrics (stage attribution included)."""
    from .baselines import baseline_case, is_baseline
    from .evaluation import evaluate_case

    if is_baseline(case.preset):
        key, metrics = baseline_case(case.preset, case.scene, f_number=case.aperture, scene_size=config.scene_size,
                                     encoding=case.encoding, noise=case.noise, variant=config.variant)
        return {"metrics": metrics, "info": {"key": key, "cached": False, "metrics": metrics}}
    ev = evaluate_case(case.estimator, case.scene, f_number=case.aperture, preset=config.scene_size,
                       encoding=case.encoding, noise=case.noise, method_preset=case.preset, variant=config.variant,
                       force=config.force)
    metrics = {k: v for k, v in ev.metrics.items() if k not in ("stages", "timings")}
    return {"metrics": metrics, "info": {"key": ev.key, "cached": ev.cached, "metrics": ev.metrics}}


def _procedural_cases(plan) -> tuple:
    from scenes.library.procedural import procedural_name

    from .cases import Case

    return tuple(Case("procedural", scene_set=f"procedural_{plan.split}", scene=procedural_name(s),
                      scene_size=plan.scene_size) for s in plan.seeds)


def _procedural_case(plan, case, inputs) -> dict:
    """:func:`experiments.procedural_eval.score_scene` of one seed; its whole result in ``info``."""
    from scenes.library.procedural import seed_of

    from .procedural_eval import score_scene

    return {"info": score_scene(seed_of(case.scene)[0], plan=plan.to_dict(), evaluation_id=plan.evaluation_id)}


#: ``repro.evaluate`` on the named scenes.
EVALUATE = CaseUnit("evaluate", _evaluate_cases, _evaluate_case)
#: ``repro.evaluate --procedural``.
PROCEDURAL = CaseUnit("procedural", _procedural_cases, _procedural_case)
#: Modules defining further units (attribute ``UNIT``), imported on first use.
UNIT_MODULES = {"accuracy": "experiments.bench.accuracy"}


def unit(name: str):
    """The figure (:data:`experiments.registry.FIGURES`) or case unit called ``name``.

    Raises
    ------
    ValueError
        No figure or unit has that name.
    """
    from .registry import FIGURES

    if name in FIGURES:
        return FIGURES[name]
    if name in UNIT_MODULES:
        return importlib.import_module(UNIT_MODULES[name]).UNIT
    known = {"evaluate": EVALUATE, "procedural": PROCEDURAL}
    if name not in known:
        raise ValueError(f"unknown figure or case unit {name!r}; allowed: {', '.join([*FIGURES, *known, *UNIT_MODULES])}")
    return known[name]
