"""The two kinds of task of an experiment sweep (``python -m repro.sweep``): one render, one cell.

A *render* is one distinct (scene, camera, f-number, scene preset, seed) image with its ground truth,
made through the render cache (:func:`scenes.render_scene`: content-addressed, file-locked, atomic);
a *cell* is one render × method preset × estimator × parameter values × input encoding: the image
the method sees, the whole pipeline, and every metric of :func:`experiments.evaluation.evaluate_result`
against σ_gt. Many cells share one render; the sweep engine runs each render once and makes its
cells depend on it.

Both functions are plain, picklable-by-reference module functions taking and returning small JSON-able
values (paths, numbers, dicts), so a Dask worker on another machine can run them: it needs the project
installed and, to reuse renders instead of redoing them, the same cache folder
(``$DEFOCUS_CACHE_DIR``, :func:`scenes.backend.cache_root`).

Main entry points
-----------------
render_task(scene, *, f_number, scene_preset, camera, seed, variant) -> dict (path, variant, times).
cell_task(render_info, *, scene, ..., method_preset, estimator, param_changes, encoding) -> dict.
cell_params(method_preset, estimator, param_changes) -> DefocusParams.
"""

from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

__all__ = ["SWEEP_CELL_VERSION", "cell_params", "cell_task", "render_camera", "render_task"]

#: Version of :func:`cell_task`'s output layout; part of every sweep cell's resume key.
SWEEP_CELL_VERSION = 1


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


def _single_threaded():
    """Context: BLAS and numba kernels on one thread (cells are the parallelism; numbers then do not
    depend on how many cores a worker has)."""
    import contextlib

    from threadpoolctl import threadpool_limits

    stack = contextlib.ExitStack()
    stack.enter_context(threadpool_limits(1))
    try:
        import numba

        old = numba.get_num_threads()
        numba.set_num_threads(1)
        stack.callback(numba.set_num_threads, old)
    except ImportError:  # pragma: no cover - numba is a dependency
        pass
    return stack


def cell_task(render_info: dict, *, scene: str, f_number: float, scene_preset: str = "small",
              camera: str | None = None, seed: int = 0, method_preset: str = "paper", estimator: str | None = None,
              param_changes: dict | None = None, encoding: str = "srgb", quantize_bits: int | None = 8,
              convention: str = "line_spread") -> dict:
    """One sweep cell: the image the method sees, the whole pipeline, every metric against σ_gt.

    Parameters
    ----------
    render_info : dict
        :func:`render_task`'s result for this cell's render (the engine passes the render's future,
        so the cell waits for that one task).
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
        ``metrics`` (flat dict of :func:`experiments.evaluation.evaluate_result`'s numbers, px or
        fractions; NaN as None), ``variant`` (Mitsuba variant of the render), ``seconds`` (this task's
        wall time, s), ``seconds_pipeline`` (the method alone, s), ``host``, ``pid``,
        ``render_task_seconds`` (wall time of the render task this cell waited for, s).

    Notes
    -----
    The pipeline runs with BLAS and numba on one thread, so a cell's numbers are the same on any
    worker whatever its core count, and serial and parallel sweeps give identical tables.
    """
    import numpy as np

    from method import NoEdgesWarning, estimate_defocus_map
    from scenes import load_render

    from .evaluation import evaluate_result, flatten_metrics, input_image

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
    t1 = time.perf_counter()
    with _single_threaded(), warnings.catch_warnings():
        warnings.simplefilter("ignore", NoEdgesWarning)
        result = estimate_defocus_map(image, params, encoding=encoding)
    t_pipe = time.perf_counter() - t1
    metrics = evaluate_result(result, render, image=image, convention=convention)
    flat = {}
    for k, v in flatten_metrics(metrics).items():
        v = v.item() if isinstance(v, np.generic) else v
        flat[k] = None if isinstance(v, float) and np.isnan(v) else v  # NaN -> None (missing); inf kept
    return {"metrics": flat, "variant": str(render.metadata.get("variant")), "seconds": time.perf_counter() - t0,
            "seconds_pipeline": t_pipe, "host": os.uname().nodename, "pid": os.getpid(),
            "render_task_seconds": render_info.get("seconds")}
