"""Which stage loses accuracy: errors after each stage of the pipeline, with oracle inputs.

For an image with known per-pixel blur σ_gt (an analytic mosaic or a render), the pipeline runs
once as it is and twice with **oracle inputs** fed in place of an earlier stage's output:

* ``estimated`` — the pipeline: sparse BM at edges (Sec. 3.2) → refined (Eq. 3) → dense (Eq. 4);
* ``oracle_refine`` — σ_gt at the detected edge pixels fed into Eq. (3), then Eq. (4): what the
  refinement and the propagation do to perfect measures;
* ``oracle_propagate`` — σ_gt at the detected edge pixels fed straight into Eq. (4): what the
  propagation alone does to perfect measures.

The stage that first departs from the truth is the one that loses the accuracy: e.g. a good
``estimated`` sparse error but a bad ``oracle_refine`` dense error points at Eq. (3).

Every error is reported overall and per σ_gt bin (:data:`SIGMA_BINS`, px), as MAE, mean signed
error (bias) and the number of pixels, over the pixels where σ_gt is valid (``valid``: not an
occlusion boundary / tile seam): at edge pixels for the sparse and refined stages; for the dense
map over ``all``, ``textured`` and ``edges`` pixels (:func:`experiments.metrics.region_masks`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import warnings

import numpy as np

from .case_unit import CaseUnit

__all__ = ["INPUTS", "ORACLE", "SIGMA_BINS", "ablation_params", "oracle_runs", "stage_errors", "stage_rows",
           "stored_oracle_runs"]

#: σ_gt bin edges, px: each bin is [edges[i], edges[i+1]).
SIGMA_BINS = (0.0, 0.75, 1.25, 1.75, 2.5, 3.5, 5.0, 7.0, 10.0, np.inf)

#: The three ways the stages are fed (see the module docstring).
INPUTS = ("estimated", "oracle_refine", "oracle_propagate")


def _errors(estimate, truth, mask, bins) -> dict:
    ok = mask & np.isfinite(estimate) & np.isfinite(truth)
    e = estimate[ok] - truth[ok]
    t = truth[ok]
    out = {"n": int(e.size), "mae": float(np.mean(np.abs(e))) if e.size else None,
           "bias": float(np.mean(e)) if e.size else None,
           "median": float(np.median(e)) if e.size else None,
           "coverage": float(ok.sum() / max(1, (mask & np.isfinite(truth)).sum()))}
    per = []
    region_t = truth[mask & np.isfinite(truth)]
    for lo, hi in zip(bins[:-1], bins[1:]):
        sel = (t >= lo) & (t < hi)
        n = int(sel.sum())
        n_region = int(np.count_nonzero((region_t >= lo) & (region_t < hi)))
        per.append({"lo": float(lo), "hi": float(hi), "n": n,
                    "mae": float(np.mean(np.abs(e[sel]))) if n else None,
                    "bias": float(np.mean(e[sel])) if n else None,
                    "median": float(np.median(e[sel])) if n else None,
                    "coverage": n / n_region if n_region else None})
    out["bins"] = per
    return out


def stage_errors(image, sigma_gt, *, params, valid=None, bins=SIGMA_BINS, texture_threshold=0.02,
                 result=None, oracles=True, encoding="srgb", store=False) -> dict:
    """Errors after every stage for the estimated and the two oracle inputs.

    Parameters
    ----------
    image : ndarray, HxWx3 or HxW, float in [0, 1]
        The input the method sees, its values in ``encoding``.
    sigma_gt : ndarray, HxW, float
        Ground-truth blur σ, px (NaN where undefined).
    params : DefocusParams, keyword-only
        Pipeline parameters (a preset or an ablation).
    valid : ndarray, HxW, bool, optional, keyword-only
        Pixels where σ_gt is trusted (default: finite σ_gt); occlusion boundaries / tile seams off.
    bins : sequence of float, keyword-only
        σ_gt bin edges, px.
    texture_threshold : float, keyword-only
        Local luminance std above which a pixel is textured (image units).
    result : method.DefocusResult, optional, keyword-only
        The pipeline's result for (image, params) if already computed.
    oracles : bool, keyword-only
        Also run the two oracle inputs (False: ``oracle_refine`` and ``oracle_propagate`` are empty).
    encoding : str, keyword-only
        What the image's values are, key of :data:`method.luma.ENCODINGS` ("srgb" or "linear").
    store : bool, keyword-only
        Read the oracle runs from the case store, computing and storing them when missing
        (:func:`stored_oracle_runs`; the same numbers as without it).

    Returns
    -------
    dict
        ``{input: {stage: errors}}`` with inputs :data:`INPUTS`; stages ``sparse`` (estimated
        only), ``refined`` (not for ``oracle_propagate``), ``dense_all``, ``dense_textured``,
        ``dense_edges``. ``errors`` = ``n``, ``mae``, ``bias`` (mean signed error), ``median`` (median
        signed error) (px), ``coverage`` (fraction of the region's valid pixels with a finite value)
        and ``bins`` (per σ_gt bin: ``lo``, ``hi``, ``n``, ``mae``, ``bias``, ``median``, ``coverage``).
        Also ``n_edges``.

    Notes
    -----
    1. Run :func:`method.estimate_defocus_map` with ``encoding`` (unless ``result`` is given); the
       oracle stages are guided by the same display-light RGB (:func:`method.luma.measure_input`).
    2. Oracle sparse map: σ_gt at the detected edge pixels (``result.edges``), NaN elsewhere.
    3. The oracle runs (:func:`oracle_runs`): ``oracle_refine`` is :func:`method.pipeline.refine_stage`
       then :func:`method.pipeline.propagate_stage` on it; ``oracle_propagate`` is ``propagate_stage``
       directly (both with ``params``; when the refinement returns the oracle map unchanged, e.g.
       ``params.refine`` False, both inputs are equal and Eq. (4) is solved once for the two).
    4. Errors per stage and per σ_gt bin, over valid pixels (edges for the sparse/refined stages).
    """
    from method import NoEdgesWarning, estimate_defocus_map
    from method.luma import measure_input

    from .metrics import region_masks

    image = np.asarray(image, dtype=np.float64)
    gt = np.asarray(sigma_gt, dtype=np.float64)
    if gt.shape != image.shape[:2]:
        raise ValueError(f"sigma_gt has shape {gt.shape}; expected {image.shape[:2]}")
    valid = np.isfinite(gt) if valid is None else (np.asarray(valid, dtype=bool) & np.isfinite(gt))
    if result is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NoEdgesWarning)
            result = estimate_defocus_map(image, params, encoding=encoding)
    rgb = measure_input(image, params, encoding=result.encoding).rgb  # "auto": the curve the estimate fitted
    edges = np.asarray(result.edges, dtype=bool)
    regions = region_masks(image, gt, edges=edges, exclude=~valid, texture_threshold=texture_threshold)
    at_edges = edges & valid

    def dense_block(dense):
        return {f"dense_{k}": _errors(dense, gt, regions[k], bins) for k in ("all", "textured", "edges")}

    out = {"estimated": {"sparse": _errors(result.sparse_sigma, gt, at_edges, bins),
                         "refined": _errors(result.refined_sigma, gt, at_edges, bins),
                         **dense_block(result.defocus_map)},
           "n_edges": int(edges.sum())}
    oracle = np.where(edges & np.isfinite(gt), gt, np.nan)
    if oracles and np.isfinite(oracle).any():
        runs = stored_oracle_runs(oracle, rgb, params) if store else oracle_runs(oracle, rgb, params)
        out["oracle_refine"] = {"refined": _errors(runs["refined"], gt, at_edges, bins),
                                **dense_block(runs["dense_refined"])}
        out["oracle_propagate"] = dense_block(runs["dense_oracle"])
    else:
        out["oracle_refine"] = {}
        out["oracle_propagate"] = {}
    return out


def oracle_runs(oracle, rgb, params) -> dict:
    """The two oracle inputs through Eq. (3) and Eq. (4) (:func:`stage_errors`, note 3).

    Parameters
    ----------
    oracle : ndarray, HxW, float
        σ_gt at the detected edge pixels, px; NaN elsewhere.
    rgb : ndarray, HxWx3, float
        The display-light RGB guiding both stages (:func:`method.luma.measure_input`).
    params : DefocusParams

    Returns
    -------
    dict of ndarray, HxW, float (px)
        ``refined`` (Eq. 3 of the oracle), ``dense_refined`` (Eq. 4 of ``refined``) and ``dense_oracle``
        (Eq. 4 of the oracle itself; ``dense_refined`` when Eq. (3) left the oracle unchanged).
    """
    from method.pipeline import propagate_stage, refine_stage

    refined = refine_stage(oracle, rgb, params=params)
    dense_refined = propagate_stage(refined, rgb, params=params, sparse_sigma=oracle)
    # Without Eq. (3) (params.refine False) the two oracle inputs reach Eq. (4) equal: one solve.
    same = np.array_equal(refined, oracle, equal_nan=True)
    return {"refined": refined, "dense_refined": dense_refined,
            "dense_oracle": dense_refined if same else propagate_stage(oracle, rgb, params=params, sparse_sigma=oracle)}


@dataclasses.dataclass(frozen=True, eq=False)
class _OracleInput:
    """What the oracle runs read: the oracle map, the guide and the parameters (:data:`ORACLE`'s config)."""

    oracle: np.ndarray
    rgb: np.ndarray
    params: object


def _digest(*arrays) -> str:
    """SHA-256 (hex) of the arrays' dtypes, shapes and bytes."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _oracle_key(config: _OracleInput, case) -> dict:
    from .cache_keys import to_jsonable

    return {"params": to_jsonable(config.params)}


def _oracle_case(config: _OracleInput, case, inputs) -> dict:
    return {"arrays": oracle_runs(config.oracle, config.rgb, config.params)}


#: The oracle runs as a case unit of the case store: one case per (oracle map, guide), keyed by their content
#: digest (which identifies the render or mosaic, its input choices and the detected edges) and the
#: parameters, besides the code fingerprint and library versions of every stored case.
ORACLE = CaseUnit("oracle", lambda config: (), _oracle_case, renders=False, cached=True, key_config=_oracle_key)


def stored_oracle_runs(oracle, rgb, params, *, cache_dir=None) -> dict:
    """:func:`oracle_runs` through the case store (:func:`experiments.cases.run_case` of :data:`ORACLE`):
    computed once per (oracle map, guide, parameters), read back bit for bit by the stages figure and the
    evaluate cases alike.

    Parameters
    ----------
    oracle, rgb, params
        As :func:`oracle_runs`.
    cache_dir : path, optional, keyword-only
        The case store (default ``<cache>/figures``).

    Returns
    -------
    dict of ndarray
        As :func:`oracle_runs`.
    """
    from .cases import Case, run_case

    oracle = np.asarray(oracle, dtype=np.float64)
    rgb = np.asarray(rgb)
    case = Case("oracle", variant=_digest(oracle, rgb))
    return run_case(ORACLE, _OracleInput(oracle=oracle, rgb=rgb, params=params), case, cache_dir=cache_dir).arrays()


def stage_rows(errors: dict, **ids) -> list[dict]:
    """Flatten :func:`stage_errors` into table rows (one per input × stage, bins as columns).

    Returns
    -------
    list of dict
        ``ids`` + ``input``, ``stage``, ``n``, ``mae``, ``bias``, ``coverage`` and, per bin i,
        ``mae_<lo>_<hi>`` / ``bias_<lo>_<hi>`` / ``n_<lo>_<hi>`` (px).
    """
    rows = []
    for inp in INPUTS:
        for stage, err in errors.get(inp, {}).items():
            row = {**ids, "input": inp, "stage": stage, "n": err["n"], "mae": err["mae"], "bias": err["bias"],
                   "coverage": err["coverage"]}
            for b in err["bins"]:
                tag = f"{float(b['lo']):g}_{float(b['hi']):g}"
                row[f"n_{tag}"] = b["n"]
                row[f"mae_{tag}"] = b["mae"]
                row[f"bias_{tag}"] = b["bias"]
            rows.append(row)
    return rows


def ablation_params(base, changes: dict) -> dict:
    """One-switch-off ablations of a preset: ``{"all": base, "no <field>": base with that field reset}``.

    Parameters
    ----------
    base : DefocusParams
        The preset (e.g. ``DefocusParams.preset("robust")``).
    changes : dict
        Its departures from the paper (:data:`method.presets.ROBUST_CHANGES`): each ablation row
        resets one of them to the paper's value.

    Returns
    -------
    dict of str -> DefocusParams
    """
    from method import DefocusParams

    paper = DefocusParams()
    rows = {"all": base}
    for field in changes:
        rows[f"no {field}"] = base.replace(**{field: getattr(paper, field)})
    return rows
