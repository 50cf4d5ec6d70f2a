"""The one scorer of a render: the whole pipeline on the input the method saw, every metric against σ_gt.

Every path that scores a render's maps calls :func:`score_render`: the named-scene evaluation and the
figures' cases built on it (:mod:`experiments.units`), the procedural evaluation
(:func:`experiments.procedural_eval.score_scene`), the sweep's cells (:mod:`experiments.sweep_cells`)
and the benchmarks (:mod:`experiments.bench.ablation`). External maps, which come without a pipeline run,
are scored by :func:`experiments.external_maps.score_map`, whose ``harness`` protocol uses the same
metric functions (:mod:`experiments.metrics`) on the same regions.

Main entry points
-----------------
score_render(render, image, *, encoding, params, result, convention) -> Score.
Score.flat() -> flat ``{metric: number}`` with :data:`FAILED_METRIC` (the long table's metrics).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

__all__ = ["FAILED_METRIC", "Score", "score_render"]

#: Metric of every scored (render, input, parameters): 1 when the method raised on it (its other metrics are
#: then absent), else 0; its mean over scenes is the failure rate.
FAILED_METRIC = "pipeline_failed"


@dataclasses.dataclass(frozen=True)
class Score:
    """What :func:`score_render` measured.

    Attributes
    ----------
    metrics : dict
        :func:`experiments.evaluation.evaluate_result`'s nested dict (px, fractions, counts); empty
        when the pipeline raised.
    result : method.DefocusResult or None
        The pipeline's output (None when it raised).
    error : str or None
        ``"<exception type>: <message>"`` when the pipeline raised, else None.
    exception : BaseException or None
        The exception itself (a caller for whom a failure is a bug re-raises it).
    seconds : float
        Wall time of the pipeline, s (0 when ``result`` was given).
    """

    metrics: dict
    result: object
    error: str | None
    exception: BaseException | None = dataclasses.field(default=None, compare=False, repr=False)
    seconds: float = 0.0

    @property
    def failed(self) -> bool:
        """Whether the pipeline raised."""
        return self.error is not None

    def flat(self) -> dict:
        """``{FAILED_METRIC: 0 or 1, "sparse_mae": …, …}``: the metrics flattened with ``_`` (the metric names
        of the results table), NumPy scalars as Python numbers, NaN kept."""
        from .evaluation import flatten_metrics

        out = {FAILED_METRIC: 1.0 if self.failed else 0.0}
        for k, v in flatten_metrics(self.metrics).items():
            out[k] = v.item() if isinstance(v, np.generic) else v
        return out

    def raise_failure(self) -> "Score":
        """Re-raise the pipeline's exception (for callers to whom a failure is a bug); else return self."""
        if self.exception is not None:
            raise self.exception
        return self


def score_render(render, image, *, encoding: str, params=None, result=None,
                 convention: str = "line_spread") -> Score:
    """Run the whole pipeline on ``image`` (single-threaded) and score its maps against ``render``'s σ_gt.

    Parameters
    ----------
    render : scenes.Render
        The ground truth (σ_gt from its circle of confusion, occlusion boundaries excluded).
    image : ndarray, HxWx3, float in [0, 1]
        The input the method saw (:func:`experiments.evaluation.input_image` of ``render``).
    encoding : {"srgb", "linear"}, keyword-only
        The light ``image`` is encoded in (sRGB-encoded values or linear radiance), as the pipeline is told.
    params : method.DefocusParams, optional, keyword-only
        The pipeline's parameters (default: the paper preset). Ignored when ``result`` is given.
    result : method.DefocusResult, optional, keyword-only
        A pipeline output already computed on ``image`` (then only scored).
    convention : {"line_spread", "erf_fit"}, keyword-only
        σ_gt convention (:func:`experiments.evaluation.ground_truth_sigma`).

    Returns
    -------
    Score
        A pipeline that raises is recorded (``error``, ``exception``; ``metrics`` empty), not raised.

    Notes
    -----
    1. :func:`method.estimate_defocus_map` with BLAS and numba on one thread
       (:func:`experiments.threads.single_threaded`), ``NoEdgesWarning`` silenced (no edges gives NaN
       metrics).
    2. :func:`experiments.evaluation.evaluate_result`: sparse, refined and dense errors, RTF-normalised
       errors, in-focus outliers.
    """
    from method import DefocusParams, NoEdgesWarning, estimate_defocus_map

    from .evaluation import ENCODINGS, evaluate_result
    from .threads import single_threaded

    ENCODINGS.check(encoding, what="encoding")
    seconds = 0.0
    if result is None:
        params = DefocusParams() if params is None else params
        t0 = time.perf_counter()
        try:
            with single_threaded(), warnings.catch_warnings():
                warnings.simplefilter("ignore", NoEdgesWarning)
                result = estimate_defocus_map(image, params, encoding=encoding)
        except Exception as exc:  # the method failing on an input is a result: recorded, not fatal
            return Score(metrics={}, result=None, error=f"{type(exc).__name__}: {exc}", exception=exc,
                         seconds=time.perf_counter() - t0)
        seconds = time.perf_counter() - t0
    metrics = evaluate_result(result, render, image=image, convention=convention)
    return Score(metrics=metrics, result=result, error=None, seconds=seconds)
