"""Shared evaluation core: the input image, σ_gt, the metrics of one pipeline run, sparse estimates.

Used by the one scorer (:mod:`experiments.scoring`, behind :mod:`repro.evaluate`), by Fig. 4 (estimators
compared at edge pixels) and Fig. 5 (cross-bilateral before/after), and usable by any other figure.

Any estimator registered in :data:`method.BLUR_ESTIMATORS` can be evaluated by name: nothing here
lists the estimators. Ground truth comes from the render (:func:`scenes.render_scene`):
``render.coc_px`` converted to a Gaussian σ with :func:`scenes.thin_lens.coc_to_sigma` in the
requested convention (``"line_spread"`` c/4 — the render's own ``sigma_px`` — or ``"erf_fit"``
0.273·c), in quadrature with the box pixel filter's σ = 1/√12 px. Occlusion boundaries
(``render.occlusion_boundary``, where one pixel mixes two blurs and σ_gt is ill-defined) are
excluded from every region.

Main entry points
-----------------
input_image(render, *, encoding, quantize_bits) -> HxWx3 image the method sees.
ground_truth_sigma(render, *, convention) -> HxW σ_gt (px).
sparse_estimates(image, estimators, *, params, encoding) -> edges + one sparse σ map per estimator (shared edges).
evaluate_result(result, render, *, image, convention) -> metrics dict of one pipeline run.

The pipeline is run and scored in one place, :func:`experiments.scoring.score_render`; the named-scene
evaluation's cases are :func:`experiments.units.evaluate_case`.
"""

from __future__ import annotations

import numpy as np

from method.luma import ENCODINGS

from .metrics import (
    dense_metrics,
    in_focus_outlier_fraction,
    region_masks,
    rtf_normalized_errors,
    sparse_metrics,
)

__all__ = [
    "ENCODINGS",
    "binned_abs_error",
    "estimator_fingerprint",
    "evaluate_result",
    "flatten_metrics",
    "ground_truth_sigma",
    "input_image",
    "sparse_estimates",
    "validate_estimators",
]

# ENCODINGS (re-exported): the input encodings, method.luma's registry ("srgb" as a camera stores
# it, "linear" the renderer's radiance); scenes.display.ENCODINGS names the same (a test checks).


def validate_estimators(names) -> tuple[str, ...]:
    """Check estimator names against :data:`method.BLUR_ESTIMATORS` (read at call time).

    Raises
    ------
    ValueError
        Naming the unknown estimator(s) and the registered ones.
    """
    from method import BLUR_ESTIMATORS

    return tuple(BLUR_ESTIMATORS.check_all(names, what="estimator"))


def estimator_fingerprint(name: str) -> str:
    """:func:`defocus_cache.source_fingerprint` of a registered estimator function (its module,
    qualified name and source).

    Part of the cache key, so an estimator registered at run time from outside ``method/`` (not
    covered by :func:`experiments.cache_keys.code_fingerprint`) still invalidates stale entries.
    """
    from method import BLUR_ESTIMATORS
    from defocus_cache import source_fingerprint

    return source_fingerprint(BLUR_ESTIMATORS[name])


def input_image(render, *, encoding: str = "srgb", quantize_bits: int | None = 8, noise="none",
                rng=None) -> np.ndarray:
    """The image the method is given.

    Parameters
    ----------
    render : scenes.Render
    encoding : {"srgb", "linear"}, keyword-only
        ``"srgb"``: sRGB-encoded as a camera delivers it; ``"linear"``: linear radiance (clipped).
    quantize_bits : int or None, keyword-only
        Bits per channel (8: a JPEG-like file); None keeps float values.
    noise : str or (float, float), keyword-only
        Sensor noise added to the linear radiance before the tone curve: a name of
        :data:`scenes.display.NOISE_LEVELS` or variances (a, b) (:func:`scenes.display.sensor_noise`).
    rng : numpy.random.Generator or int or None, keyword-only
        The noise's generator or seed (None: seed 0).

    Returns
    -------
    ndarray, HxWx3, float64 in [0, 1]
    """
    ENCODINGS.check(encoding, what="encoding")
    return render.image(encoding=encoding, quantize_bits=quantize_bits, noise=noise, rng=rng)


def ground_truth_sigma(render, *, convention: str = "line_spread") -> np.ndarray:
    """σ_gt (px) from the render's CoC diameter in a given convention (NaN where the CoC is undefined).

    Parameters
    ----------
    render : scenes.Render
    convention : {"line_spread", "erf_fit"}, keyword-only
        See :func:`scenes.thin_lens.coc_to_sigma`; combined in quadrature with the box filter σ.

    Returns
    -------
    ndarray, HxW, float64, px
    """
    from scenes.render import FILTER_SIGMA_PX
    from scenes.thin_lens import coc_to_sigma

    coc = np.asarray(render.coc_px, dtype=np.float64)
    coc = np.where(np.isfinite(coc), coc, np.nan)
    return coc_to_sigma(coc, convention=convention, filter_sigma_px=FILTER_SIGMA_PX)


def sparse_estimates(image, estimators, *, params=None, encoding: str = "srgb") -> tuple[np.ndarray, dict]:
    """Edge pixels (Sec. 3.1) and each estimator's σ there (Sec. 3.2), the edges shared by all.

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float in [0, 1]
        The input, its values in ``encoding``.
    estimators : sequence of str
        Keys of :data:`method.BLUR_ESTIMATORS`.
    params : DefocusParams, optional, keyword-only
        Detector/estimator parameters (paper defaults): ``measure_light``, ``edge_detector`` and
        every detector and estimator option apply as in :func:`method.estimate_defocus_map`.
    encoding : str, keyword-only
        What the image's values are, key of :data:`method.luma.ENCODINGS` ("srgb" or "linear").

    Returns
    -------
    edges : ndarray of bool, HxW
    sigma : dict of str to ndarray, HxW float64
        σ in px at edge pixels, NaN elsewhere and where the estimator failed; for each estimator
        equal to ``estimate_defocus_map(image, params.replace(estimator=name), encoding=encoding)
        .sparse_sigma``.

    Notes
    -----
    The pipeline's own stages, on the same input: :func:`method.luma.measure_input` (the luminance
    in ``params.measure_light``) → :func:`method.pipeline.edges_stage` (once, keeping the detector's
    2nd-derivative responses when an estimator samples them again) →
    :func:`method.pipeline.blur_stage` with ``params.replace(estimator=name)`` per estimator.
    """
    from method import BLUR_ESTIMATORS, DefocusParams
    from method.luma import measure_input
    from method.pipeline import blur_stage, edges_stage

    params = DefocusParams() if params is None else params
    names = validate_estimators(estimators)
    seen = measure_input(image, params, encoding=encoding).seen
    reuse = [n for n in names if "detector_hessians" in BLUR_ESTIMATORS.entry(n).capabilities]
    em = edges_stage(seen, params=params.replace(estimator=reuse[0]) if reuse else params, encoding=encoding)
    out = {}
    for name in names:
        sparse, _, _, _ = blur_stage(seen, em, params=params.replace(estimator=name))
        out[name] = sparse
    return em.edges.copy(), out


def binned_abs_error(estimate, truth, bin_edges, *, mask=None) -> tuple[np.ndarray, np.ndarray]:
    """Median |estimate − truth| per σ_gt bin (the error-vs-σ curves of Fig. 4).

    Parameters
    ----------
    estimate, truth : ndarray, any shape (same), σ in px (NaN = none)
    bin_edges : sequence of float, (k + 1,), px
        Bins [e_i, e_{i+1}) of σ_gt.
    mask : ndarray of bool, optional, keyword-only

    Returns
    -------
    median_ae : ndarray, (k,), px (NaN for an empty bin)
    count : ndarray, (k,), int
    """
    est = np.asarray(estimate, dtype=np.float64).ravel()
    gt = np.asarray(truth, dtype=np.float64).ravel()
    ok = np.isfinite(est) & np.isfinite(gt)
    if mask is not None:
        ok &= np.asarray(mask, dtype=bool).ravel()
    est, gt = est[ok], gt[ok]
    edges = np.asarray(bin_edges, dtype=np.float64)
    idx = np.digitize(gt, edges) - 1
    k = edges.size - 1
    med = np.full(k, np.nan)
    cnt = np.zeros(k, dtype=np.int64)
    for i in range(k):
        sel = idx == i
        cnt[i] = int(sel.sum())
        if cnt[i]:
            med[i] = float(np.median(np.abs(est[sel] - gt[sel])))
    return med, cnt


def evaluate_result(result, render, *, image, convention: str = "line_spread",
                    texture_threshold: float = 0.02) -> dict:
    """Every metric of one :class:`method.DefocusResult` against a render's ground truth.

    Parameters
    ----------
    result : method.DefocusResult
    render : scenes.Render
    image : ndarray, HxWx3, float in [0, 1], keyword-only
        The input the method saw (for the texture mask).
    convention : str, keyword-only
        σ_gt convention (:func:`ground_truth_sigma`).
    texture_threshold : float, keyword-only
        Local luminance std above which a pixel counts as textured (:func:`~experiments.metrics.textured_mask`).

    Returns
    -------
    dict
        ``sparse`` (BM at edge pixels vs σ_gt), ``refined`` (after Eq. 3), ``dense`` (``all``,
        ``edges``, ``textured`` regions), ``rtf`` (normalised errors of the dense map over ``all``),
        ``in_focus_outliers`` (before/after), each a dict of numbers; occlusion boundaries excluded.
    """
    gt = ground_truth_sigma(render, convention=convention)
    keep = ~np.asarray(render.occlusion_boundary, dtype=bool)
    regions = region_masks(image, gt, edges=result.edges, exclude=~keep, texture_threshold=texture_threshold)
    return {
        "sparse": sparse_metrics(result.sparse_sigma, gt, mask=keep),
        "refined": sparse_metrics(result.refined_sigma, gt, mask=keep),
        "dense": dense_metrics(result.defocus_map, gt, regions=regions),
        "rtf": rtf_normalized_errors(result.defocus_map, gt, mask=regions["all"]),
        "in_focus_outliers": {
            "sparse": in_focus_outlier_fraction(result.sparse_sigma, gt, mask=keep),
            "refined": in_focus_outlier_fraction(result.refined_sigma, gt, mask=keep),
        },
        "n_edges": int(np.count_nonzero(result.edges)),
        "n_occlusion_excluded": int(np.count_nonzero(~keep)),
    }


def flatten_metrics(d: dict, prefix: str = "", sep: str = "_") -> dict:
    """Nested metric dict → flat ``{"a_b_c": number}`` (the columns of the CSV table)."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten_metrics(v, key + sep, sep))
        else:
            out[key] = v
    return out
