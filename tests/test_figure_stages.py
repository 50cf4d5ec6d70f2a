"""Figures run the pipeline they name: the stages a figure rebuilds are the pipeline's own.

:func:`experiments.evaluation.sparse_estimates` (Fig. 4, Fig. 5) must give, for every preset and
encoding, exactly the sparse σ of :func:`method.estimate_defocus_map` with that preset: same light
(``measure_light``), same edge detector, same estimator options.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from experiments.evaluation import sparse_estimates
from method import PRESETS, DefocusParams, estimate_defocus_map


@pytest.fixture(scope="module")
def mosaic():
    from scenes.analytic.lens import lens_mosaic

    m = lens_mosaic(family="dead_leaves", sigmas=(0.5, 1.5, 3.0, 5.0), tile=32, cols=2, rng=5)  # 8-bit sRGB
    return {"srgb": m.image, "linear": m.linear}


def _pipeline(image, params, encoding):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return estimate_defocus_map(image, params, encoding=encoding)


@pytest.mark.parametrize("encoding", ["srgb", "linear"])
@pytest.mark.parametrize("preset", list(PRESETS))
def test_sparse_estimates_equal_the_pipelines_sparse_sigma(mosaic, preset, encoding):
    params = DefocusParams.preset(preset)
    image = mosaic[encoding]
    edges, sig = sparse_estimates(image, [params.estimator], params=params, encoding=encoding)
    result = _pipeline(image, params, encoding)
    np.testing.assert_array_equal(edges, result.edges)
    np.testing.assert_array_equal(sig[params.estimator], result.sparse_sigma)
    assert np.isfinite(result.sparse_sigma).sum() > 50


def test_shared_edges_serve_every_estimator(mosaic):
    """Several estimators on one edge map (Fig. 4): each equals the pipeline run with that estimator."""
    params = DefocusParams.preset("robust")
    names = ["gradient_ratio", "model_fit", "zero_crossing", params.estimator]
    edges, sig = sparse_estimates(mosaic["srgb"], names, params=params)
    for name in names:
        result = _pipeline(mosaic["srgb"], params.replace(estimator=name), "srgb")
        np.testing.assert_array_equal(edges, result.edges)
        np.testing.assert_array_equal(sig[name], result.sparse_sigma, err_msg=name)


def test_robust_measures_in_linear_light(mosaic):
    """The robust preset's light is used: measuring its sRGB input as display values (what Fig. 4 did)
    gives other measures."""
    params = DefocusParams.preset("robust")
    assert params.measure_light == "linear"
    _, own = sparse_estimates(mosaic["srgb"], [params.estimator], params=params)
    _, display = sparse_estimates(mosaic["srgb"], [params.estimator], params=params.replace(measure_light="display"))
    a, b = own[params.estimator], display[params.estimator]
    assert not np.array_equal(np.isfinite(a), np.isfinite(b)) or np.nanmax(np.abs(a - b)) > 0.05
