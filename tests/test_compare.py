"""``repro.compare``: the paired bootstrap, the verdicts, the scene counts, the trivial baselines, bad input."""

from __future__ import annotations

import json
import math
import types

import numpy as np
import pytest

from experiments.baselines import BASELINES, baseline_metrics, baseline_rows
from experiments.compare import (check_pair, compare_rows, direction, scenes_for_half_width, scenes_for_power,
                                 verdict)
from experiments.judgements import append_judgement, read_judgements
from experiments.results_table import difference, paired_difference
from tests.cli_run import run_in_process

# --- the paired bootstrap ------------------------------------------------------------------------------


def _paired(shift, *, n=24, spread=1.0, noise=0.05, seed=1):
    """Per-scene values of A (a wide scene-to-scene spread) and B = A + shift + small noise."""
    rng = np.random.default_rng(seed)
    a = 1.0 + spread * rng.random(n)
    return a, a + shift + noise * rng.standard_normal(n)


def test_paired_interval_covers_a_known_shift_and_excludes_zero():
    a, b = _paired(0.2)
    d = paired_difference(a, b, n_resamples=2000)
    assert d["ci_low"] <= 0.2 <= d["ci_high"]
    assert d["ci_low"] > 0.0  # the effect is far larger than the noise: 0 is excluded
    assert d["value"] == pytest.approx(np.mean(b - a))
    assert d["sd"] == pytest.approx(np.std(b - a, ddof=1))
    assert d["n_pairs"] == a.size


def test_paired_interval_includes_zero_without_an_effect():
    a, b = _paired(0.0)
    d = paired_difference(a, b, n_resamples=2000)
    assert d["ci_low"] < 0.0 < d["ci_high"]


def test_pairing_removes_the_scene_spread_the_unpaired_interval_keeps():
    a, b = _paired(0.2, spread=2.0)
    paired = paired_difference(a, b, n_resamples=2000)
    unpaired = difference(a, b, n_resamples=2000)
    assert paired["ci_high"] - paired["ci_low"] < 0.2 * (unpaired["ci_high"] - unpaired["ci_low"])
    assert unpaired["ci_low"] < 0.0 < unpaired["ci_high"]  # unpaired: the shift is lost in the scene spread


def test_paired_interval_is_seeded_and_refuses_unpaired_lengths():
    a, b = _paired(0.1)
    assert paired_difference(a, b, seed=3, n_resamples=500) == paired_difference(a, b, seed=3, n_resamples=500)
    with pytest.raises(ValueError, match="same scenes"):
        paired_difference(a, b[:-1])


# --- verdicts and scene counts -------------------------------------------------------------------------


@pytest.mark.parametrize(("low", "high", "way", "expected"), [
    (0.1, 0.3, "lower", "worse"), (-0.3, -0.1, "lower", "better"), (-0.1, 0.2, "lower", "no difference detected"),
    (0.1, 0.3, None, "higher"), (-0.3, -0.1, None, "lower"), (None, None, "lower", "too few scenes")])
def test_verdict_both_sides(low, high, way, expected):
    assert verdict(low, high, way) == expected


def test_directions():
    assert direction("dense_textured_mae") == "lower"
    assert direction("rtf_nmae") == "lower"
    assert direction("pipeline_failed") == "lower"
    assert direction("dense_all_bias") == "closer to 0"
    assert direction("sparse_n") is None and direction("n_edges") is None


def test_power_formula_against_a_hand_computed_case():
    # z_0.975 + z_0.8 = 1.959964 + 0.841621 = 2.801585; (2.801585 · 0.2 / 0.1)² = 31.40 → 32 scenes
    assert scenes_for_power(0.1, 0.2) == 32
    assert scenes_for_power(-0.1, 0.2) == 32  # the sign of the difference does not matter
    assert scenes_for_power(0.0, 0.2) is None
    # ±0.3 on 8 scenes → ±0.15 needs 8 · (0.3 / 0.15)² = 32 scenes
    assert scenes_for_half_width(8, 0.3) == 32
    assert scenes_for_half_width(8, None) is None


def _rows(values_a, values_b, *, metric="dense_textured_mae", a="paper", b="robust", aperture=8.0):
    rows = []
    for i, (va, vb) in enumerate(zip(values_a, values_b)):
        for name, v in ((a, va), (b, vb)):
            rows.append({"scene": f"s{i}", "preset": name, "aperture": aperture, "encoding": "srgb", "noise": "none",
                         "metric": metric, "value": v})
    return rows


def test_compare_rows_verdicts_both_ways():
    a, b = _paired(0.3)
    worse = compare_rows(_rows(a, b), "paper", "robust", n_resamples=2000)
    (rec,) = worse
    assert rec["verdict"] == "worse" and rec["mean_diff"] == pytest.approx(0.3, abs=0.05)
    assert rec["half_width"] == pytest.approx((rec["ci_high"] - rec["ci_low"]) / 2)
    assert rec["n_for_power"] == scenes_for_power(rec["mean_diff"], rec["sd_diff"])
    assert rec["n_for_half_width"] == scenes_for_half_width(a.size, rec["half_width"])
    (nmae,) = compare_rows(_rows(a, b, metric="rtf_nmae"), "paper", "robust", n_resamples=200)
    assert nmae["n_for_half_width"] is None  # the ±0.15 px target is for metrics in px
    (better,) = compare_rows(_rows(b, a), "paper", "robust", n_resamples=2000)
    assert better["verdict"] == "better"
    a0, b0 = _paired(0.0)
    (none,) = compare_rows(_rows(a0, b0), "paper", "robust", n_resamples=2000)
    assert none["verdict"] == "no difference detected"


def test_compare_rows_pairs_scenes_and_compares_bias_by_its_size():
    rows = _rows([0.5, -0.4, 0.6], [0.1, 0.1, -0.1], metric="dense_all_bias")
    rows.append({"scene": "s9", "preset": "paper", "aperture": 8.0, "encoding": "srgb", "noise": "none",
                 "metric": "dense_all_bias", "value": 0.3})  # B failed on s9: not paired
    rows += [r for r in _rows([1.0, 2.0], [1.0, 2.0], metric="sparse_mae") if r["preset"] == "paper"]  # A's only
    (rec,) = compare_rows(rows, "paper", "robust", n_resamples=500)
    assert rec["metric"] == "|dense_all_bias|" and rec["n_scenes"] == 3
    assert rec["mean_a"] == pytest.approx(0.5) and rec["mean_b"] == pytest.approx(0.1)


def test_check_pair_refuses_a_equal_b_and_unknown_names():
    assert check_pair("paper", "const_floor", presets=["paper"], baselines=BASELINES) == ("paper", "const_floor")
    with pytest.raises(ValueError, match="A = B"):
        check_pair("paper", "paper", presets=["paper"], baselines=BASELINES)
    with pytest.raises(ValueError, match="allowed: paper, const_median_gt, const_floor"):
        check_pair("paper", "nope", presets=["paper"], baselines=BASELINES)


# --- trivial baselines ---------------------------------------------------------------------------------


def _render():
    """A fake render: 3/4 of the pixels with CoC 4 px (σ_gt √(1 + 1/12)), 1/4 in focus (σ_gt 1/√12)."""
    coc = np.full((16, 16), 4.0)
    coc[:4] = 0.0
    return types.SimpleNamespace(coc_px=coc, occlusion_boundary=np.zeros((16, 16), dtype=bool))


def test_baselines_score_their_analytic_mae():
    render = _render()
    image = np.random.default_rng(0).random((16, 16, 3))
    floor, blurred = 1.0 / math.sqrt(12.0), math.sqrt(1.0 + 1.0 / 12.0)
    m = baseline_metrics("const_floor", render, image=image)
    assert m["baseline_sigma_px"] == pytest.approx(floor)
    assert m["dense"]["all"]["mae"] == pytest.approx(0.75 * (blurred - floor))
    med = baseline_metrics("const_median_gt", render, image=image)
    assert med["baseline_sigma_px"] == pytest.approx(blurred)
    assert med["dense"]["all"]["mae"] == pytest.approx(0.25 * (blurred - floor))
    assert "sparse" not in m and "edges" not in m["dense"]  # no edges: no sparse metrics (not a score)


def test_baseline_rows_carry_the_baseline_name_as_preset():
    rows = baseline_rows(_render(), {"scene": "x", "aperture": 8.0}, image=np.random.default_rng(0).random((16, 16, 3)))
    assert {r["preset"] for r in rows} == set(BASELINES)
    assert any(r["metric"] == "dense_all_mae" and r["value"] is not None for r in rows)
    with pytest.raises(ValueError, match="allowed: 'const_floor', 'const_median_gt'"):
        baseline_rows(_render(), {}, image=np.zeros((16, 16, 3)), names=["const_mean"])


# --- the judgement log ---------------------------------------------------------------------------------


def test_judgement_log_counts_runs(tmp_path):
    rec = {"a": "paper", "b": "robust", "command": "python -m repro.compare paper robust --procedural 2 --split fresh",
           "commit": "abc", "date_utc": "2026-12-06T07:00:00+00:00", "scene_size": "small", "seeds": [5, 6],
           "n_scenes": 2, "verdicts": [{"aperture": 8.0, "metric": "dense_textured_mae", "mean_a": 0.2, "mean_b": 0.6,
                                        "mean_diff": 0.4, "ci_low": 0.1, "ci_high": 0.7, "verdict": "worse"}],
           "baselines": {"const_floor": {"8": 0.18}}}
    log = tmp_path / "judgements.jsonl"
    assert append_judgement(rec, log) == 1
    assert append_judgement({**rec, "seeds": [9, 10]}, log) == 2
    assert [r["seeds"] for r in read_judgements(log)] == [[5, 6], [9, 10]]
    md = log.with_suffix(".md").read_text()
    assert "judgements so far: 2" in md and "| 8 | dense_textured_mae | 0.200 | 0.600 | +0.400" in md


# --- the command line ----------------------------------------------------------------------------------


@pytest.mark.parametrize(("args", "message"), [
    (["paper", "paper", "--procedural", "4", "--split", "dev"], "A = B = 'paper' is invalid"),
    (["paper", "nope", "--procedural", "4", "--split", "dev"], "'nope' is invalid (unknown preset or baseline); allowed"),
    (["paper", "robust", "--procedural", "1", "--split", "dev"], "--procedural 1 is invalid"),
    (["paper", "robust", "--procedural", "4"], "--procedural needs --split"),
    (["paper", "robust", "--procedural", "4", "--split", "train"], "--split 'train' is invalid"),
    (["paper", "robust"], "give one scene source"),
    (["paper", "robust", "--scenes", "planes"], "a paired interval needs two scenes"),
    (["paper", "robust", "--scenes", "planes", "nowhere"], "unknown scene(s) 'nowhere'"),
    (["paper", "robust", "--scenes", "planes", "portrait", "--metric", "mae"], "--metric 'mae' is invalid; allowed"),
])
def test_bad_input_is_one_line_and_exit_2(args, message, tmp_path):
    res = run_in_process("repro.compare", [*args, "--out", str(tmp_path / "out")])
    assert res.returncode == 2
    assert message in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.render
def test_compare_two_dev_scenes_end_to_end(tmp_path):
    out = tmp_path / "out"
    res = run_in_process("repro.compare", ["paper", "const_floor", "--procedural", "2", "--split", "dev",
                                           "--scene-size", "small", "--fnumber", "8", "--workers", "1", "-q",
                                           "--out", str(out)])
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "compare.json").read_text())
    assert doc["seeds"] == [0, 1] and doc["a"] == "paper" and doc["b"] == "const_floor"
    (rec,) = [r for r in doc["records"] if r["metric"] == "dense_textured_mae"]
    assert rec["n_scenes"] == 2 and rec["aperture"] == 8.0
    assert rec["mean_diff"] == pytest.approx(rec["mean_b"] - rec["mean_a"])
    assert (out / "compare.png").is_file() and (out / "rows.csv").is_file()
    assert "dense_textured_mae" in res.stdout and "scenes for ±0.15 px" in res.stdout
    assert not any(r["metric"].startswith("sparse") for r in doc["records"])  # a constant has no sparse values


@pytest.mark.slow
@pytest.mark.render
def test_compare_two_named_scenes_against_a_baseline(tmp_path):
    out = tmp_path / "out"
    res = run_in_process("repro.compare", ["paper", "const_floor", "--scenes", "planes", "portrait_garden",
                                           "--fnumber", "8", "--scene-size", "small", "--workers", "1", "-q",
                                           "--out", str(out)])
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "compare.json").read_text())
    assert doc["scenes"] == ["planes", "portrait_garden"]
    by = {r["metric"]: r for r in doc["records"]}
    assert by["dense_textured_mae"]["n_scenes"] == 2  # the runner's dense/textured/mae, named as in the tables
    assert "sparse_mae" not in by


def test_the_ablation_bench_shows_dev_only():
    from experiments.bench.ablation import ABLATION_CONFIG, ablation_markdown

    assert set(ABLATION_CONFIG["procedural"]) == {"dev", "scene_preset"}  # no held-out seeds beside every variant
    row = {"label": "robust", "lens": {"mean_mae": 1.0, "fails": 1, "cells": 2}, "renders": {"heron f/8": 0.5},
           "photos": {"coffee": {"auc": 0.8, "share": 0.1}}, "procedural": {"dev": 0.865}}
    md = ablation_markdown({"rows": [row], "config": ABLATION_CONFIG, "date": "d", "runtime_s": 60.0})
    assert "procedural dev: mean MAE" in md and "| 0.865 |" in md and "dev / test" not in md
