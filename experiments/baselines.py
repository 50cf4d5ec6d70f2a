"""Trivial baselines: constant defocus maps a method must beat, scored by the same metric function.

A baseline is a map made without looking at the image: a constant σ over the whole frame. It is
scored exactly as a method's map is (:func:`experiments.scoring.score_render`, the same regions
of the same input image), so its dense metrics (``dense_all_*``, ``dense_textured_*``, ``rtf_*``) sit
beside the presets' in every table and comparison. A baseline finds no edges and makes no sparse
estimate: its ``sparse_*``, ``refined_*``, ``dense_edges_*`` and ``in_focus_outliers_*`` metrics are
empty (a constant has no edge pixels to be scored at); only the dense metrics are meaningful.

Registered baselines (:data:`BASELINES`, a :class:`method.registry.Registry`; a new one is one function
``sigma(truth, occlusion) -> float`` plus one entry):

* ``const_median_gt``: the scene's median σ_gt over the scored pixels (occlusion boundaries excluded),
  an *oracle* constant: it knows the ground truth's median, which no method sees.
* ``const_floor``: the pixel filter's floor, :data:`scenes.render.FILTER_SIGMA_PX` = 1/√12 ≈ 0.289 px
  (the σ_gt of a pixel in perfect focus): the map of "everything is sharp".
"""

from __future__ import annotations

import types

import numpy as np

from method.registry import Entry, Registry

__all__ = ["BASELINES", "baseline_case", "baseline_maps", "baseline_metrics", "baseline_result", "baseline_rows",
           "baseline_sigma", "is_baseline"]


def _median_gt(truth, occlusion) -> float:
    """Median σ_gt (px) over the pixels with a finite σ_gt off the occlusion boundaries (an oracle)."""
    keep = np.isfinite(truth) & ~occlusion
    return float(np.median(truth[keep])) if keep.any() else float("nan")


def _floor(truth, occlusion) -> float:
    """σ of the box pixel filter alone (px): the σ_gt of a pixel in perfect focus."""
    from scenes.render import FILTER_SIGMA_PX

    return float(FILTER_SIGMA_PX)


#: Baselines by name: value ``sigma(truth, occlusion) -> float`` (px), the constant of the map, from σ_gt
#: (HxW, px, NaN where undefined) and the occlusion boundaries (HxW bool, excluded).
BASELINES = Registry("baseline", {
    "const_median_gt": Entry(_median_gt, "constant map at the scene's median σ_gt (oracle: it knows the truth's median)"),
    "const_floor": Entry(_floor, "constant map at the pixel filter's floor, 1/√12 ≈ 0.289 px (everything in focus)"),
})


def is_baseline(name) -> bool:
    """Whether ``name`` is a key of :data:`BASELINES`."""
    return isinstance(name, str) and name in BASELINES


def baseline_sigma(name: str, render, *, convention: str = "line_spread") -> float:
    """The constant σ (px) of baseline ``name`` on ``render``.

    Raises
    ------
    ValueError
        An unknown baseline (naming the registered ones).
    """
    from .evaluation import ground_truth_sigma

    return BASELINES.resolve(name, what="baseline")(ground_truth_sigma(render, convention=convention),
                                                    np.asarray(render.occlusion_boundary, dtype=bool))


def baseline_result(name: str, render, *, convention: str = "line_spread"):
    """A :class:`method.DefocusResult`-like record of baseline ``name``: ``defocus_map`` the constant
    (HxW, px), ``sparse_sigma`` and ``refined_sigma`` NaN everywhere, ``edges`` none (HxW bool)."""
    shape = np.asarray(render.coc_px).shape[:2]
    nan = np.full(shape, np.nan)
    return types.SimpleNamespace(defocus_map=np.full(shape, baseline_sigma(name, render, convention=convention)),
                                 sparse_sigma=nan, refined_sigma=nan, edges=np.zeros(shape, dtype=bool))


def baseline_metrics(name: str, render, *, image, encoding: str = "srgb", convention: str = "line_spread") -> dict:
    """Every metric of :func:`experiments.evaluation.evaluate_result` for baseline ``name``.

    Parameters
    ----------
    name : str
        Key of :data:`BASELINES`.
    render : scenes.Render
    image : ndarray, HxWx3, float in [0, 1], keyword-only
        The input the methods it is compared with saw (its texture mask defines ``dense_textured``).
    encoding : {"srgb", "linear"}, keyword-only
        What ``image``'s values are (:data:`method.luma.ENCODINGS`).
    convention : str, keyword-only
        σ_gt convention.

    Returns
    -------
    dict
        The meaningful part of :func:`~experiments.evaluation.evaluate_result`: ``dense`` (``all``,
        ``textured``), ``rtf``, ``n_occlusion_excluded``; and ``baseline_sigma_px`` (the constant). The
        sparse, refined, edge and in-focus-outlier metrics are left out (a constant has no edges: they
        would be empty or zero counts, not a score).
    """
    from .scoring import score_render

    result = baseline_result(name, render, convention=convention)
    metrics = score_render(render, image, encoding=encoding, result=result, convention=convention).metrics
    dense = {k: v for k, v in metrics["dense"].items() if k != "edges"}
    return {"dense": dense, "rtf": metrics["rtf"], "n_occlusion_excluded": metrics["n_occlusion_excluded"],
            "baseline_sigma_px": float(result.defocus_map.flat[0])}


def baseline_rows(render, ids, *, image, names=None) -> list[dict]:
    """Rows of the long results table (:func:`experiments.results_table.metric_rows`) of every baseline
    on one input: ``ids`` plus ``preset`` = the baseline's name, the flattened metrics of
    :func:`baseline_metrics` (``pipeline_failed`` 0: a constant never fails).

    Parameters
    ----------
    render : scenes.Render
    ids : mapping
        The identifying columns of the input (scene, aperture, encoding, noise, …).
    image : ndarray, HxWx3, float in [0, 1], keyword-only
        The input the methods saw.
    names : sequence of str, optional, keyword-only
        Baselines (default: every registered one).
    """
    from .evaluation import flatten_metrics
    from .results_table import metric_rows

    rows = []
    for name in BASELINES.check_all(names if names is not None else list(BASELINES), what="baseline"):
        metrics = flatten_metrics(baseline_metrics(name, render, image=image, encoding=ids.get("encoding", "srgb")))
        rows += metric_rows({**ids, "preset": name}, {"pipeline_failed": 0.0, **metrics})
    return rows


def baseline_case(name: str, scene: str, *, f_number: float, scene_size: str = "small", encoding: str = "srgb",
                  noise: str = "none", noise_seed: int = 0, variant: str | None = None) -> tuple[dict, dict]:
    """Baseline ``name`` on a named scene's render (cached), scored on the input
    :func:`experiments.units.evaluate_case` gives the presets (8 bits, the same noise seed).

    Returns
    -------
    key : dict
        The identifying fields of an :class:`experiments.evaluation.EvaluationCase` key (``method_preset``
        = the baseline, ``estimator`` None).
    metrics : dict
        :func:`baseline_metrics`.
    """
    from scenes import render_scene

    from .evaluation import input_image

    BASELINES.check(name, what="baseline")
    render = render_scene(scene, preset=scene_size, f_number=f_number, variant=variant, progress=False)
    image = input_image(render, encoding=encoding, quantize_bits=8, noise=noise, rng=int(noise_seed))
    key = {"estimator": None, "method_preset": name, "scene": scene, "f_number": float(f_number),
           "preset": scene_size, "encoding": encoding, "noise": noise}
    return key, baseline_metrics(name, render, image=image, encoding=encoding)


def baseline_maps(truth, name: str):
    """``image name -> (constant map, label)`` of baseline ``name`` on the images of ``truth`` (an
    :class:`experiments.external_maps.DatasetTruth` or ``RenderTruth``), for
    :func:`experiments.external_maps.score_maps` (the leaderboard)."""
    fn = BASELINES.resolve(name, what="baseline")

    def get(image):
        gt = truth.ground_truth(image)
        sigma = np.asarray(gt["sigma"], dtype=np.float64)
        return np.full(sigma.shape, fn(sigma, np.asarray(gt["occlusion"], dtype=bool))), f"baseline {name}: {image}"

    return get
