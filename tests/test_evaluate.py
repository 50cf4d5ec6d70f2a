"""``python -m repro.evaluate`` and the shared core :mod:`experiments.evaluation`."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests import tolerances as tol

ROOT = Path(__file__).resolve().parents[1]
PROG = "python -m repro.evaluate"


def _run(argv):
    from repro._cli import run_cli
    from repro.evaluate import main

    return run_cli(main, argv, prog=PROG)


def _read(out):
    with open(out / "evaluate.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return rows, json.loads((out / "evaluate.json").read_text())


@pytest.mark.render
def test_evaluate_one_scene_writes_csv_and_json(tmp_path, capsys, goldens):
    from experiments.evaluation_columns import METRIC_COLUMNS
    from repro.evaluate import ID_COLUMNS

    out = tmp_path / "ev"
    assert _run(["--estimator", "model_fit", "zero_crossing", "gradient_ratio", "--scenes", "planes",
                 "--fnumber", "8", "--scene-size", "small", "--workers", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "model_fit" in printed and "gradient_ratio" in printed and "evaluate.csv" in printed
    rows, js = _read(out)
    assert list(rows[0]) == [*ID_COLUMNS, *METRIC_COLUMNS]
    from experiments.baselines import BASELINES

    # the trivial baselines are rows of the table too, after the estimators: dense metrics only
    assert [r["method_preset"] for r in rows[3:]] == list(BASELINES)
    for r in js["rows"][3:]:
        assert np.isfinite(r["dense_textured_mae"]) and r["sparse_mae"] is None and r["estimator"] is None
    rows, js["rows"] = rows[:3], js["rows"][:3]
    assert [r["estimator"] for r in rows] == ["model_fit", "zero_crossing", "gradient_ratio"]
    assert js["columns"] == [*ID_COLUMNS, *METRIC_COLUMNS] and len(js["rows"]) == 3
    for r in js["rows"]:
        assert r["scene"] == "planes" and r["f_number"] == 8.0 and r["encoding"] == "srgb"
        for c in ("sparse_mae", "dense_all_mae", "dense_edges_mae", "dense_textured_mae", "rtf_nmae",
                  "in_focus_outliers_sparse_fraction"):
            assert np.isfinite(r[c]), c
        assert 0 <= r["rtf_nmae"] <= 1
    from tests.golden import evaluate_values

    goldens.check("evaluate_quick", evaluate_values(js["rows"]))


def _dummy_constant_sigma(gray, edge_map, *, params):
    out = np.full(gray.shape, np.nan)
    out[edge_map.edges] = 1.0
    return out


@pytest.mark.render
def test_registered_dummy_estimator_shows_up(tmp_path, monkeypatch):
    from method import BLUR_ESTIMATORS

    monkeypatch.setitem(BLUR_ESTIMATORS, "dummy_constant", _dummy_constant_sigma)
    out = tmp_path / "ev"
    # registered at run time: seen in this process only (--workers 1), not by fresh Dask workers
    assert _run(["--estimator", "dummy_constant", "--scenes", "planes", "--fnumber", "8", "--workers", "1",
                 "--out", str(out)]) == 0
    rows, _ = _read(out)
    assert [r["estimator"] for r in rows] == ["dummy_constant", "", ""]  # then the two trivial baselines
    # σ = 1 px at every edge pixel: the sparse bias is exactly mean(1 − σ_gt) over the scored edges
    from experiments.units import evaluate_case

    case = evaluate_case("dummy_constant", "planes", f_number=8.0)
    assert case.cached
    sparse = case.arrays["sparse_sigma"]
    np.testing.assert_array_equal(sparse[case.arrays["edges"]], 1.0)
    assert float(rows[0]["sparse_bias"]) == pytest.approx(case.metrics["sparse"]["bias"])
    assert int(rows[0]["sparse_n"]) > 100


@pytest.mark.parametrize("argv, needle", [
    (["--estimator", "nope"], "unknown estimator"),
    (["--scenes", "nowhere"], "unknown scene"),
    (["--fnumber", "0"], "--fnumber"),
    (["--fnumber", "-4"], "--fnumber"),
    (["--fnumber", "inf"], "--fnumber"),
    (["--scene-preset", "huge"], "--scene-preset"),
    (["--preset", "small"], "--scene-size"),
    (["--scene-size", "huge"], "--scene-size"),
    (["--preset", "nope"], "allowed"),
    (["--encoding", "raw"], "--encoding"),
    (["--workers", "0"], "--workers"),
    (["--scenes", "planes", "--fnumber", "8", "--scheduler", "tcp://127.0.0.1:{port}"], "unreachable"),
])
def test_bad_input_one_line_exit_2(argv, needle, capsys, tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    argv = [a.format(port=port) for a in argv]
    assert _run([*argv, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"{PROG}: error:") and needle in err
    assert not (tmp_path / "x").exists()  # nothing written


def test_bad_input_subprocess_exit_2():
    env = {**os.environ}
    p = subprocess.run([sys.executable, "-m", "repro.evaluate", "--estimator", "nope"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "unknown estimator" in p.stderr and "model_fit" in p.stderr


@pytest.mark.render
def test_ground_truth_conventions_match_render():
    from experiments.evaluation import ground_truth_sigma
    from scenes import render_scene

    r = render_scene("planes", preset="small", f_number=8, progress=False)
    ls = ground_truth_sigma(r, convention="line_spread")
    ok = np.isfinite(r.sigma_px)
    np.testing.assert_allclose(ls[ok], r.sigma_px[ok], atol=tol.EVAL_SIGMA_GT_ATOL)
    erf = ground_truth_sigma(r, convention="erf_fit")
    assert np.all(erf[ok] >= ls[ok] - tol.EVAL_SIGMA_GT_ATOL)


def test_binned_abs_error_by_hand():
    from experiments.evaluation import binned_abs_error

    gt = np.array([0.3, 0.4, 1.2, 1.8, 5.0, np.nan])
    est = np.array([0.3, 0.0, 1.0, np.nan, 9.0, 1.0])
    med, cnt = binned_abs_error(est, gt, [0.25, 1.0, 2.0, 4.0])
    np.testing.assert_array_equal(cnt, [2, 1, 0])
    np.testing.assert_allclose(med[:2], [0.2, 0.2])
    assert np.isnan(med[2])


@pytest.mark.render
def test_evaluate_presets_and_stages(tmp_path, capsys):
    """--preset compares presets (each with its own estimator); --stages writes the stage attribution."""
    out = tmp_path / "ev"
    assert _run(["--preset", "paper", "robust", "--scenes", "planes", "--fnumber", "8", "--scene-size", "small",
                 "--stages", "--workers", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "oracle_propagate" in printed and "stages.csv" in printed
    rows, js = _read(out)
    assert [(r["method_preset"], r["estimator"]) for r in rows] == [("paper", "model_fit"),
                                                                    ("robust", "model_fit_checked"),
                                                                    ("const_median_gt", ""), ("const_floor", "")]
    assert rows[0]["dense_textured_mae"] != rows[1]["dense_textured_mae"]
    stages = json.loads((out / "stages.json").read_text())["rows"]
    got = {(r["method_preset"], r["input"], r["stage"]) for r in stages}
    for preset in ("paper", "robust"):
        assert (preset, "estimated", "sparse") in got and (preset, "oracle_refine", "refined") in got
        assert (preset, "oracle_propagate", "dense_textured") in got
    for r in stages:  # per-bin counts add up to the stage's pixel count
        assert sum(v for k, v in r.items() if k.startswith("n_")) == r["n"]
    # with σ_gt fed straight into Eq. (4) the dense map at the edges is the truth there (α-weighted fit)
    op = next(r for r in stages if r["method_preset"] == "paper" and r["input"] == "oracle_propagate"
              and r["stage"] == "dense_edges")
    assert op["mae"] < 0.1


class _EngineChosen(Exception):
    pass


@pytest.mark.parametrize("argv", [["--scenes", "planes", "--fnumber", "8"], ["--photos", "coffee"],
                                  ["--procedural", "2", "--split", "dev"]], ids=["named", "photos", "procedural"])
def test_one_workers_default_on_every_path(argv, tmp_path, monkeypatch):
    """Without --workers every path asks the engine for its default (one per core); --workers N is passed on."""
    from repro import _runner
    from repro.evaluate import main

    asked = []

    def chosen(workers, scheduler, *, command):
        asked.append(workers)
        raise _EngineChosen

    monkeypatch.setattr(_runner, "engine_choice", chosen)
    for extra, want in (([], None), (["--workers", "3"], 3)):
        with pytest.raises(_EngineChosen):
            main([*argv, *extra, "--out", str(tmp_path / "o")])
        assert asked.pop() == want
    assert _runner.default_workers() >= 1
