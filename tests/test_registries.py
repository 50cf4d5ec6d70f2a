"""Names of variants come from the registries: a new estimator (or propagation) is one function plus one
registry entry, and DefocusParams, the pipeline, repro.evaluate and the CLI help all pick it up."""

import json

import numpy as np
import pytest

from method import BLUR_ESTIMATORS, PROPAGATION_METHODS, DefocusParams, estimate_defocus_map
from tests.photo_cli import textured_photo


def _my_idea(gray, edge_map, *, params):
    out = np.full(gray.shape, np.nan)
    out[edge_map.edges] = 1.25
    return out


def _flat_propagation(sparse_sigma, reference, *, params, confidence=None):
    return np.full(sparse_sigma.shape, float(np.nanmedian(sparse_sigma)))


def test_unregistered_names_are_rejected_with_the_registry():
    with pytest.raises(ValueError, match="estimator='my_idea' is invalid") as e:
        DefocusParams(estimator="my_idea")
    for name in BLUR_ESTIMATORS:
        assert name in str(e.value)
    with pytest.raises(ValueError, match="propagation='flat'"):
        DefocusParams(propagation="flat")


def test_new_estimator_and_propagation_run_in_the_pipeline(monkeypatch):
    monkeypatch.setitem(BLUR_ESTIMATORS, "my_idea", _my_idea)
    monkeypatch.setitem(PROPAGATION_METHODS, "flat", _flat_propagation)
    img = textured_photo()
    res = estimate_defocus_map(img, DefocusParams(estimator="my_idea"))
    assert res.edges.sum() > 50
    np.testing.assert_array_equal(res.sparse_sigma[res.edges], 1.25)
    assert np.all(np.isnan(res.sparse_sigma[~res.edges]))
    res2 = estimate_defocus_map(img, DefocusParams(estimator="my_idea", propagation="flat"))
    np.testing.assert_allclose(res2.defocus_map, np.nanmedian(res2.refined_sigma))


def test_cli_help_lists_registered_names(monkeypatch, capsys):
    monkeypatch.setitem(BLUR_ESTIMATORS, "my_idea", _my_idea)
    from repro import estimate, evaluate

    for mod in (estimate, evaluate):
        with pytest.raises(SystemExit):
            mod.main(["--help"])
        assert "my_idea" in capsys.readouterr().out, mod.__name__


@pytest.mark.render
def test_new_estimator_through_repro_evaluate(monkeypatch, tmp_path, capsys):
    from repro.evaluate import main

    monkeypatch.setitem(BLUR_ESTIMATORS, "my_idea", _my_idea)
    out = tmp_path / "ev"
    # registered at run time: seen in this process only (--workers 1), not by fresh Dask workers
    assert main(["--estimator", "my_idea", "model_fit", "--scenes", "tilted_plane", "--fnumber", "8", "--workers", "1",
                 "--out", str(out)]) == 0
    rows = json.loads((out / "evaluate.json").read_text())["rows"]
    assert [r["estimator"] for r in rows] == ["my_idea", "model_fit", None, None]  # then the trivial baselines
    mine = rows[0]
    assert mine["sparse_n"] > 50 and mine["dense_all_mae"] is not None
    # a constant 1.25 px at every edge: the sparse measure's median error is |1.25 − σ_gt| there, not 0
    assert mine["sparse_mae"] != rows[1]["sparse_mae"]
    assert "my_idea" in capsys.readouterr().out
