"""Case units that are not figures: the evaluations and the accuracy benchmark, run by the same case runner.

A :class:`CaseUnit` has what the runner (:mod:`repro._runner`, :func:`experiments.cases.run_case`) needs
of a figure — a name, ``cases(config)``, ``compute_case(config, case, inputs)``, a code version, whether
it renders — and whether it keeps its cases in the one case store, the figure cache
(:func:`experiments.cases.run_case`), optionally keyed by a part of its config (``key_config``).
:func:`unit` finds a figure or a unit by name, and :func:`case_task` (the Dask task of one case) runs one of
its cases by that name.

* ``evaluate`` (``repro.evaluate`` on named scenes): one case per scene × aperture × encoding × noise ×
  preset × estimator of an :class:`EvaluateConfig` (:func:`evaluate_case`, scored by
  :func:`experiments.scoring.score_render`), and one per trivial baseline
  (:func:`experiments.baselines.baseline_case`).
* ``procedural`` (``repro.evaluate --procedural``): one case per scene seed of a
  :class:`experiments.procedural_eval.ProceduralPlan` (:func:`experiments.procedural_eval.score_scene`).
* ``sweep`` (``repro.sweep``): one case per render and per cell of a sweep grid
  (:data:`experiments.sweep_cells.UNIT`).
* ``accuracy`` (``repro.bench --accuracy``): :data:`experiments.bench.accuracy.ACCURACY_UNIT`.
"""

from __future__ import annotations

import dataclasses
import importlib

from .case_unit import CaseUnit

__all__ = ["EVALUATE", "EVAL_VERSION", "PROCEDURAL", "UNIT_MODULES", "CaseUnit", "EvaluateConfig", "EvaluationCase",
           "case_task", "evaluate_case", "unit"]


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
    baselines: tuple[str, ...] = dataclasses.field(default_factory=lambda: _all_baselines())
    # trivial baselines scored beside the presets (experiments.baselines.BASELINES; default: all).


#: Version of the named-scene evaluation's case output; part of its cache key.
EVAL_VERSION = 4  # 4: the trivial baselines as cases (experiments.baselines)


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


def _evaluate_params(case):
    """``DefocusParams`` of an evaluate case: its preset, the estimator replaced when the case names one."""
    from method import DefocusParams

    params = DefocusParams.preset(case.preset or "paper")
    return params.replace(estimator=case.estimator) if case.estimator is not None else params


def _evaluate_key(config: EvaluateConfig, case) -> dict:
    """What shapes one evaluate case's numbers beyond its fields: the parameters, the estimator's own source
    (an estimator registered at run time from outside ``method/``), the variant asked, input and σ_gt choices
    (a baseline: its name; its code is in :func:`experiments.cache_keys.code_fingerprint`)."""
    from .baselines import is_baseline
    from .cache_keys import to_jsonable
    from .evaluation import estimator_fingerprint

    if is_baseline(case.preset):
        return {"variant_requested": config.variant, "baseline": case.preset, "quantize_bits": 8,
                "convention": "line_spread", "noise_seed": 0}

    params = _evaluate_params(case)
    return {"variant_requested": config.variant, "params": to_jsonable(params), "quantize_bits": 8,
            "convention": "line_spread", "noise_seed": 0, "estimator_code": estimator_fingerprint(params.estimator)}


def _evaluate_case(config: EvaluateConfig, case, inputs) -> dict:
    """Render (cached), the input, :func:`experiments.scoring.score_render` and the stage attribution of one
    case. ``metrics``: the scorer's flat metrics; ``arrays``: the maps and σ_gt; ``info``: the case's key
    fields and its nested metrics (stage attribution and timings included)."""
    import time

    import numpy as np

    from scenes import render_scene
    from scenes.backend import select_variant

    from .baselines import baseline_case, is_baseline
    from .evaluation import flatten_metrics, ground_truth_sigma, input_image
    from .scoring import score_render
    from .stage_attribution import stage_errors

    if is_baseline(case.preset):
        key, nested = baseline_case(case.preset, case.scene, f_number=case.aperture, scene_size=case.scene_size,
                                    encoding=case.encoding, noise=case.noise, variant=select_variant(config.variant))
        return {"metrics": {"pipeline_failed": 0.0, **flatten_metrics(nested)}, "info": {"key": key, "metrics": nested}}
    params = _evaluate_params(case)
    t0 = time.perf_counter()
    render = render_scene(case.scene, preset=case.scene_size, f_number=case.aperture,
                          variant=select_variant(config.variant), progress=False)
    t_render = time.perf_counter() - t0
    image = input_image(render, encoding=case.encoding, quantize_bits=8, noise=case.noise, rng=0)
    score = score_render(render, image, encoding=case.encoding, params=params).raise_failure()
    result, gt = score.result, ground_truth_sigma(render)
    nested = {**score.metrics,
              "stages": stage_errors(image, gt, params=params, valid=~np.asarray(render.occlusion_boundary, dtype=bool),
                                     result=result, encoding=case.encoding, store=True),
              "timings": {"render_load_s": t_render, **{f"{k}_s": v for k, v in result.timings.items()}}}
    key = {"estimator": params.estimator, "method_preset": case.preset, "scene": case.scene,
           "f_number": float(case.aperture), "preset": case.scene_size, "encoding": case.encoding, "quantize_bits": 8,
           "convention": "line_spread", "noise": case.noise, "noise_seed": 0}
    arrays = {"sparse_sigma": result.sparse_sigma, "refined_sigma": result.refined_sigma,
              "defocus_map": result.defocus_map, "edges": result.edges, "sigma_gt": gt}
    return {"arrays": arrays, "metrics": score.flat(), "info": {"key": key, "metrics": nested}}


@dataclasses.dataclass(frozen=True)
class EvaluationCase:
    """One evaluated (estimator, scene, f-number, preset, encoding, noise) case (:func:`evaluate_case`).

    Attributes
    ----------
    key : dict
        The identifying fields.
    metrics : dict
        :func:`experiments.evaluation.evaluate_result`'s nested dict plus ``stages`` (stage attribution)
        and ``timings`` (s).
    arrays : dict of ndarray
        ``sparse_sigma``, ``refined_sigma``, ``defocus_map``, ``sigma_gt`` (HxW, px) and ``edges`` (HxW bool).
    cached : bool
        Whether the case was read from the case store.
    """

    key: dict
    metrics: dict
    arrays: dict
    cached: bool

    @classmethod
    def of(cls, output) -> "EvaluationCase":
        """The evaluation case of a finished :class:`experiments.cases.CaseOutput` of :data:`EVALUATE`."""
        return cls(key=output.info["key"], metrics=output.info["metrics"], arrays=output.arrays(),
                   cached=output.cached)


def evaluate_case(estimator: str | None, scene: str, *, f_number: float = 8.0, preset: str = "small",
                  encoding: str = "srgb", noise: str = "none", method_preset: str | None = None,
                  variant: str | None = None, use_cache: bool = True, force: bool = False) -> EvaluationCase:
    """One case of the named-scene evaluation, through the one case store (:func:`experiments.cases.run_case`).

    Parameters
    ----------
    estimator : str or None
        Key of :data:`method.BLUR_ESTIMATORS`; None keeps the preset's.
    scene : str
        Key of :data:`scenes.SCENES`.
    f_number : float, keyword-only
        Aperture N of the render (> 0).
    preset : {"small", "full"}, keyword-only
        Render resolution preset (160×120 / 640×480 px).
    encoding : {"srgb", "linear"}, keyword-only
    noise : str, keyword-only
        Sensor noise level of the input (:data:`scenes.display.NOISE_LEVELS`; noise seed 0).
    method_preset : str, optional, keyword-only
        Name of :data:`method.PRESETS` (default ``"paper"``).
    variant : str, optional, keyword-only
        Mitsuba variant.
    use_cache, force : bool, keyword-only
        Read/write the case store; recompute even if stored.

    Returns
    -------
    EvaluationCase

    Raises
    ------
    ValueError
        An unknown estimator, preset, scene, encoding or noise level, or a bad f-number.
    """
    from method import PRESETS
    from scenes.display import check_noise_level
    from scenes.render import validate_render_options

    from .cases import run_case
    from .evaluation import ENCODINGS, validate_estimators

    method_preset = method_preset or "paper"
    PRESETS.check(method_preset, what="preset")
    if estimator is not None:
        validate_estimators([estimator])
    ENCODINGS.check(encoding, what="encoding")
    check_noise_level(noise)
    validate_render_options(scene, preset=preset, f_number=f_number, sigma_convention="line_spread")
    config = EvaluateConfig(presets=(method_preset,), estimators=(estimator,), scenes=(scene,),
                            f_numbers=(float(f_number),), scene_size=preset, encodings=(encoding,), noises=(noise,),
                            variant=variant, baselines=())
    (case,) = _evaluate_cases(config)
    return EvaluationCase.of(run_case(EVALUATE, config, case, force=force, use_cache=use_cache))


def _procedural_cases(plan) -> tuple:
    from scenes.library.procedural import procedural_name

    from .cases import Case

    return tuple(Case("procedural", scene_set=f"procedural_{plan.split}", scene=procedural_name(s),
                      scene_size=plan.scene_size) for s in plan.seeds)


def _procedural_key(plan, case) -> dict:
    """The plan and the version of :func:`experiments.procedural_eval.score_scene`'s output."""
    from .procedural_eval import PROCEDURAL_EVAL_VERSION

    return {"plan": plan, "version": PROCEDURAL_EVAL_VERSION}


def _procedural_case(plan, case, inputs) -> dict:
    """:func:`experiments.procedural_eval.score_scene` of one seed; its whole result in ``info``."""
    from scenes.library.procedural import seed_of

    from .procedural_eval import score_scene

    return {"info": score_scene(seed_of(case.scene)[0], plan=plan.to_dict(), evaluation_id=plan.evaluation_id)}


#: ``repro.evaluate`` on the named scenes.
EVALUATE = CaseUnit("evaluate", _evaluate_cases, _evaluate_case, version=EVAL_VERSION, cached=True,
                    key_config=_evaluate_key)
#: ``repro.evaluate --procedural``.
PROCEDURAL = CaseUnit("procedural", _procedural_cases, _procedural_case, cached=True, key_config=_procedural_key)
#: Modules defining further units (attribute ``UNIT``), imported on first use.
UNIT_MODULES = {"accuracy": "experiments.bench.accuracy", "sweep": "experiments.sweep_cells"}


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


def case_task(figure_name: str, config, case, *needs, force: bool = False):
    """One case as a Dask task: :func:`experiments.cases.run_case` of the figure or unit called ``figure_name``
    (:func:`unit`) with the outputs of ``case.needs`` (in that order); returns the
    :class:`~experiments.cases.CaseOutput` without in-memory arrays (they are in the cache)."""
    from .cases import run_case

    inputs = dict(zip(case.needs, needs))
    out = run_case(unit(figure_name), config, case, inputs, force=force)
    return dataclasses.replace(out, memory=None)
