"""The cases of an experiment sweep (``python -m repro.sweep``): one per distinct render, one per cell.

A *render* is one distinct (scene, camera, f-number, scene preset, seed) image with its ground truth,
made through the render cache (:func:`scenes.render_scene`: content-addressed, file-locked, atomic);
a *cell* is one render × method preset × estimator × parameter values × input encoding: the image
the method sees, scored by the one scorer (:func:`experiments.scoring.score_render`: the whole pipeline
and every metric of :func:`experiments.evaluation.evaluate_result` against σ_gt). Both are cases of
:data:`UNIT`, run by the case runner (:mod:`repro._runner`) and kept in the one case store
(:func:`experiments.cases.run_case`), each cell keyed by its own inputs and full parameters (never by the
rest of its grid), so an interrupted sweep resumes cell by cell and a cell shared by two grids is
computed once. A cell needs its render's case, so many cells share one render task.

The task functions are plain module functions taking and returning small JSON-able values (paths,
numbers, dicts), so a Dask worker on another machine can run them: it needs the project installed and,
to reuse renders instead of redoing them, the same cache folder (``$DEFOCUS_CACHE_DIR``,
:func:`scenes.backend.cache_root`).

Main entry points
-----------------
render_case(scene, *, f_number, scene_preset, camera, seed) -> Case; cell_case(render, ...) -> Case.
render_task(scene, *, f_number, scene_preset, camera, seed, variant) -> dict (path, variant, times).
cell_task(render_info, *, scene, ..., method_preset, estimator, param_changes, encoding) -> dict.
cell_params(method_preset, estimator, param_changes) -> DefocusParams.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from pathlib import Path

__all__ = ["SWEEP_CELL_VERSION", "UNIT", "SweepConfig", "cell_case", "cell_params", "cell_task", "render_camera",
           "render_case", "render_task"]

#: Version of a sweep case's output layout; part of every sweep case's key.
SWEEP_CELL_VERSION = 2  # 2: cases of the one case store


def render_camera(scene: str, *, scene_preset: str, f_number: float, camera: str | None):
    """The camera of a sweep render: the scene's own (``camera=None``) or a :data:`scenes.CAMERA_PRESETS` name.

    Parameters
    ----------
    scene : str
        Key of :data:`scenes.SCENES`.
    scene_preset : {"small", "full"}, keyword-only
        Render resolution preset.
    f_number : float, keyword-only
        Aperture N (> 0).
    camera : str or None, keyword-only
        Camera preset name (same field of view for all), None for the scene's default.

    Returns
    -------
    scenes.ThinLensCamera or None
        None means "let :func:`scenes.render_scene` choose", which keys the render exactly as the
        other tools (``repro.evaluate``, the figures) do, so their cached renders are reused.
    """
    if camera is None:
        return None
    from scenes import get_scene

    return get_scene(scene).camera(scene_preset, f_number=f_number, camera_name=camera)


def render_task(scene: str, *, f_number: float, scene_preset: str = "small", camera: str | None = None,
                seed: int = 0, variant: str | None = None) -> dict:
    """Render (or read from the render cache) one scene; return where it is, not the pixels.

    Parameters
    ----------
    scene : str
    f_number : float, keyword-only
    scene_preset : {"small", "full"}, keyword-only
    camera : str or None, keyword-only
        See :func:`render_camera`.
    seed : int, keyword-only
        Sampler seed of the render, in [0, 2**32).
    variant : str or None, keyword-only
        Mitsuba variant requested (None: ``$DEFOCUS_MITSUBA_VARIANT`` or the fastest that works on
        *this* worker: ``cuda_ad_rgb`` where a GPU works, see :mod:`scenes.backend`).

    Returns
    -------
    dict
        ``path`` (str, the cached EXR), ``variant`` (str, the one that rendered it), ``seconds``
        (float, wall time of this task, s), ``host`` and ``pid``.
    """
    from scenes import render_scene

    t0 = time.perf_counter()
    cam = render_camera(scene, scene_preset=scene_preset, f_number=f_number, camera=camera)
    render = render_scene(scene, cam, preset=scene_preset, f_number=f_number, seed=seed, variant=variant,
                          progress=False)
    return {"path": str(render.path), "variant": str(render.metadata["variant"]),
            "seconds": time.perf_counter() - t0, "host": os.uname().nodename, "pid": os.getpid()}


def cell_params(method_preset: str, estimator: str | None, param_changes: dict):
    """``DefocusParams`` of one cell: the preset, its estimator replaced (None keeps it), fields changed.

    Raises
    ------
    ValueError
        Unknown preset or estimator, unknown field, or a value the field rejects.
    """
    import dataclasses

    from method import DefocusParams

    from .evaluation import validate_estimators

    params = DefocusParams.preset(method_preset)
    names = {f.name for f in dataclasses.fields(params)}
    bad = [k for k in param_changes if k not in names]
    if bad:
        raise ValueError(f"unknown parameter(s) {', '.join(map(repr, bad))}; allowed: DefocusParams fields {sorted(names)}")
    changes = dict(param_changes)
    if estimator is not None:
        validate_estimators([estimator])
        changes["estimator"] = estimator
    return params.replace(**changes) if changes else params


@dataclasses.dataclass(frozen=True)
class SweepConfig:
    """What shapes every case of a sweep beyond the case's own fields: the Mitsuba variant asked for."""

    variant: str | None = None
    # Mitsuba variant requested (None: $DEFOCUS_MITSUBA_VARIANT or the fastest that works on the worker).


def _spec(case) -> dict:
    return json.loads(case.variant)


def render_case(scene: str, *, f_number: float, scene_preset: str, camera: str | None, seed: int):
    """The case of one distinct render of a sweep (its output's ``info`` is :func:`render_task`'s dict)."""
    from .cases import Case

    spec = json.dumps({"render": True, "camera": camera, "seed": int(seed)}, sort_keys=True)
    return Case("sweep", scene=scene, aperture=float(f_number), scene_size=scene_preset, variant=spec)


def cell_case(render, *, method_preset: str, estimator: str | None, param_changes, encoding: str):
    """The case of one sweep cell; it needs its render's case (:func:`render_case`).

    ``param_changes`` are ``(field, value)`` pairs; the values keep their JSON types (int, float, bool, None,
    str), so the case's key names them exactly.
    """
    from .cases import Case

    spec = {**_spec(render), "render": False, "params": [[k, v] for k, v in param_changes]}
    return Case("sweep", scene=render.scene, aperture=render.aperture, scene_size=render.scene_size,
                preset=method_preset, estimator=estimator, encoding=encoding,
                variant=json.dumps(spec, sort_keys=True), needs=(render,))


def _case_key(config: SweepConfig, case) -> dict:
    """Per case: the variant asked for; for a cell also its full parameters and the estimator's own source
    (an estimator registered at run time from outside ``method/``), the input's bits and the σ_gt convention."""
    from .evaluation import estimator_fingerprint
    from .cache_keys import to_jsonable

    key = {"variant_requested": config.variant, "version": SWEEP_CELL_VERSION}
    if not _spec(case)["render"]:
        params = cell_params(case.preset, case.estimator, dict(_spec(case)["params"]))
        key.update(params=to_jsonable(params), estimator_code=estimator_fingerprint(params.estimator),
                   quantize_bits=8, convention="line_spread")
    return key


def _compute_case(config: SweepConfig, case, inputs) -> dict:
    spec = _spec(case)
    if spec["render"]:
        return {"info": render_task(case.scene, f_number=case.aperture, scene_preset=case.scene_size,
                                    camera=spec["camera"], seed=spec["seed"], variant=config.variant)}
    (render,) = case.needs
    out = cell_task(inputs[render].info, scene=case.scene, f_number=case.aperture, scene_preset=case.scene_size,
                    camera=spec["camera"], seed=spec["seed"], method_preset=case.preset, estimator=case.estimator,
                    param_changes=dict(spec["params"]), encoding=case.encoding)
    return {"metrics": out.pop("metrics"), "info": out}


def cell_task(render_info: dict, *, scene: str, f_number: float, scene_preset: str = "small",
              camera: str | None = None, seed: int = 0, method_preset: str = "paper", estimator: str | None = None,
              param_changes: dict | None = None, encoding: str = "srgb", quantize_bits: int | None = 8,
              convention: str = "line_spread") -> dict:
    """One sweep cell: the image the method sees, scored by :func:`experiments.scoring.score_render`.

    Parameters
    ----------
    render_info : dict
        :func:`render_task`'s result for this cell's render.
    scene, f_number, scene_preset, camera, seed : keyword-only
        The render's inputs (used only when ``render_info["path"]`` is not visible on this worker:
        the render is then made or read through this worker's own render cache).
    method_preset : str, keyword-only
        Key of :data:`method.PRESETS`.
    estimator : str or None, keyword-only
        Key of :data:`method.BLUR_ESTIMATORS`; None keeps the preset's.
    param_changes : dict, optional, keyword-only
        ``DefocusParams`` fields changed from the preset.
    encoding : {"srgb", "linear"}, keyword-only
        Input encoding (:func:`experiments.evaluation.input_image`).
    quantize_bits : int or None, keyword-only
        Bits per channel of the input (8: a JPEG-like file).
    convention : {"line_spread", "erf_fit"}, keyword-only
        σ_gt convention (:func:`experiments.evaluation.ground_truth_sigma`).

    Returns
    -------
    dict
        ``metrics`` (:meth:`experiments.scoring.Score.flat`: every metric of
        :func:`experiments.evaluation.evaluate_result`, px or fractions, and ``pipeline_failed``; NaN as None),
        ``variant``
        (Mitsuba variant of the render), ``seconds`` (this task's wall time, s), ``seconds_pipeline`` (the
        method alone, s), ``host``, ``pid``, ``render_task_seconds`` (wall time of the render task, s).

    Raises
    ------
    Exception
        Whatever the pipeline raised (a cell of a sweep that fails is a bug to see, with its traceback).
    """
    from scenes import load_render

    from .evaluation import input_image
    from .scoring import score_render

    t0 = time.perf_counter()
    params = cell_params(method_preset, estimator, param_changes or {})
    path = Path(render_info["path"])
    if path.is_file():
        render = load_render(path)
    else:  # this worker does not see the cache the render was written to: use its own
        info = render_task(scene, f_number=f_number, scene_preset=scene_preset, camera=camera, seed=seed,
                           variant=render_info["variant"])
        render = load_render(info["path"])
    image = input_image(render, encoding=encoding, quantize_bits=quantize_bits)
    score = score_render(render, image, encoding=encoding, params=params, convention=convention).raise_failure()
    metrics = {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in score.flat().items()}
    return {"metrics": metrics, "variant": str(render.metadata.get("variant")),
            "seconds": time.perf_counter() - t0, "seconds_pipeline": score.seconds, "host": os.uname().nodename,
            "pid": os.getpid(), "render_task_seconds": render_info.get("seconds")}


def _unit():
    from .units import CaseUnit

    return CaseUnit("sweep", lambda config: (), _compute_case, version=SWEEP_CELL_VERSION, cached=True,
                    key_config=_case_key)


#: The sweep's case unit (:func:`experiments.units.unit` finds it by name on a Dask worker).
UNIT = _unit()
