"""The long results table (experiments.results_table), its bootstrap summaries, the generalisation gap
(experiments.leaderboard) and the report section that shows it (repro.report --evaluations). No renders."""

from __future__ import annotations

import json

import numpy as np
import pytest

from experiments.results_table import (COLUMNS, column_names, difference, mean_interval, metric_rows, metric_unit,
                                       read_results, read_results_csv, summarise, write_results)


def _rows(split, values, *, eid, metric="dense_textured_mae", preset="paper", apertures=(2.0,)):
    rows = []
    for i, v in enumerate(values):
        for n in apertures:
            ids = {"evaluation_id": eid, "source": "procedural", "scene": f"procedural_{i}", "seed": i, "split": split,
                   "scene_size": "small", "camera": "canon_1d_mark_ii_85mm", "lighting": "emission", "aperture": n,
                   "preset": preset, "estimator": "model_fit", "encoding": "srgb", "noise": "none"}
            rows += metric_rows(ids, {metric: v * (1.0 if n == 2.0 else 0.5), "sparse_n": 120, "rtf_nmae": None})
    return rows


def test_schema_has_the_required_columns_once():
    names = column_names()
    assert len(names) == len(set(names)) == len(COLUMNS)
    for c in ("source", "scene", "seed", "split", "scene_size", "aperture", "preset", "encoding", "noise", "metric",
              "value", "unit", "evaluation_id"):
        assert c in names


def test_the_docs_page_lists_exactly_the_columns_in_order():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "results-schema.md").read_text(encoding="utf-8")
    assert re.findall(r"^\| `(\w+)` \|", text, flags=re.MULTILINE) == list(column_names())


def test_units_of_the_metric_families():
    assert metric_unit("dense_textured_mae") == "px (σ)" and metric_unit("sparse_n") == "pixels"
    assert metric_unit("sparse_outlier_fraction") == "fraction of pixels" and metric_unit("rtf_nmae") == "dimensionless"
    assert metric_unit("gt_depth_max_m") == "m" and metric_unit("n_edges") == "pixels"
    # a figure's metric paths: the unit of the last part
    assert metric_unit("image_vs_large/magnified_estimated/psnr_in_focus_db") == "dB"
    assert metric_unit("image_vs_large/unchanged_small/ssim") == "dimensionless"
    assert metric_unit("energy_terms/alpha=0.5/data_term") == "px²"
    assert metric_unit("alpha=0.5/textured_mae") == "px (σ)" and metric_unit("line_spread/n") == "pixels"
    assert metric_unit("k_x_map_small_vs_map_large/median_rel_error") == "relative"
    rows = metric_rows({"evaluation_id": "e", "source": "figures"}, {"a/model_fit_better": True, "b/n": 3})
    assert [(r["value"], r["unit"]) for r in rows] == [(1.0, "flag"), (3.0, "pixels")]


def test_a_table_of_the_first_schema_is_read_with_the_new_columns_empty(tmp_path):
    import csv

    old = [c for c in column_names() if c not in ("figure", "scene_set", "variant")]
    with open(tmp_path / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=old)
        w.writeheader()
        w.writerow({"evaluation_id": "e", "source": "procedural", "scene": "procedural_1", "seed": 1, "split": "dev",
                    "scene_size": "small", "aperture": 2.0, "metric": "sparse_mae", "value": 0.5, "unit": "px (σ)"})
    (row,) = read_results_csv(tmp_path / "results.csv")
    assert list(row) == list(column_names()) and row["figure"] is None and row["variant"] is None
    assert row["seed"] == 1 and row["value"] == 0.5
    with open(tmp_path / "other.csv", "w") as fh:
        fh.write("a,b\n1,2\n")
    with pytest.raises(ValueError, match="not a results table"):
        read_results_csv(tmp_path / "other.csv")


def test_results_query_selects_groups_and_names_a_missing_value():
    from experiments.results_query import MissingData, Results

    t = Results(_rows("dev", [0.5, 1.5], eid="e1", apertures=(2.0, 4.0)))
    assert t.where(scene="procedural_1", aperture=4.0).value("dense_textured_mae") == 0.75
    assert t.where(aperture=(2.0, 4.0)).distinct("scene") == ["procedural_0", "procedural_1"]
    assert list(t.group("scene", "aperture"))[:2] == [("procedural_0", 2.0), ("procedural_0", 4.0)]
    assert t.where(scene="procedural_0", aperture=2.0).metrics() == {"dense_textured_mae": 0.5, "sparse_n": 120.0,
                                                                     "rtf_nmae": None}
    with pytest.raises(MissingData, match="no metric nope"):
        t.value("nope")
    with pytest.raises(ValueError, match="4 rows of sparse_n"):
        t.value("sparse_n")  # the query names no single value: a harness failure, not missing data
    assert t.get("nope", 7) == 7 and len(t.where(preset="robust")) == 0


def test_parquet_and_csv_round_trip_the_same_typed_rows(tmp_path):
    rows = _rows("dev", [0.5, float("nan"), 1.25], eid="e1")
    paths = write_results(tmp_path, rows, {"plan": {"split": "dev"}})
    back, meta = read_results(paths[0])
    assert back == read_results_csv(paths[1])
    assert len(back) == len(rows) and meta["plan"] == {"split": "dev"} and meta["schema_version"] == 2
    assert [r["value"] for r in back if r["metric"] == "dense_textured_mae"] == [0.5, None, 1.25]  # NaN -> empty
    assert back[0]["seed"] == 0 and back[0]["aperture"] == 2.0 and back[0]["unit"] == "px (σ)"
    assert not list(tmp_path.glob("*.tmp*"))
    with pytest.raises(ValueError, match="unknown results column"):
        write_results(tmp_path, [{**rows[0], "bogus": 1}], {})
    with pytest.raises(ValueError, match="unknown results column"):
        metric_rows({"bogus": 1}, {"m": 1.0})


def test_bootstrap_interval_brackets_the_mean_and_shrinks_with_more_scenes():
    rng = np.random.default_rng(1)
    few = mean_interval(rng.normal(1.0, 0.5, 8))
    many = mean_interval(rng.normal(1.0, 0.5, 200))
    for s in (few, many):
        assert s["ci_low"] < s["mean"] < s["ci_high"]
    assert (many["ci_high"] - many["ci_low"]) < (few["ci_high"] - few["ci_low"]) / 3
    assert mean_interval([2.0, 2.0, 2.0]) == {"n_scenes": 3, "mean": 2.0, "ci_low": 2.0, "ci_high": 2.0}
    assert mean_interval([1.0])["ci_low"] is None and mean_interval([])["mean"] is None
    assert mean_interval([1.0, 3.0], seed=5) == mean_interval([1.0, 3.0], seed=5)  # seeded: reproducible


def test_difference_is_second_minus_first_with_an_interval():
    d = difference([1.0, 2.0, 3.0, 4.0], [2.0, 3.0, 4.0, 5.0])
    assert d["value"] == pytest.approx(1.0) and d["ci_low"] < 1.0 < d["ci_high"]
    same = difference([1.0, 1.0], [1.0, 1.0])
    assert same["value"] == 0.0 and same["ci_low"] == same["ci_high"] == 0.0


def test_summary_groups_by_preset_and_aperture_and_skips_empty_values():
    rows = _rows("dev", [1.0, 2.0, 3.0], eid="e", apertures=(2.0, 8.0)) + _rows("dev", [4.0], eid="e", preset="robust")
    rows.append({**rows[0], "scene": "procedural_9", "value": None})
    s = {(r["preset"], r["aperture"]): r for r in summarise(rows, by=("preset", "aperture", "metric"),
                                                            metrics=("dense_textured_mae",))}
    assert set(s) == {("paper", 2.0), ("paper", 8.0), ("robust", 2.0)}
    assert s[("paper", 2.0)]["n_scenes"] == 3 and s[("paper", 2.0)]["mean"] == pytest.approx(2.0)
    assert s[("paper", 8.0)]["mean"] == pytest.approx(1.0) and s[("robust", 2.0)]["ci_low"] is None


def test_generalisation_gap_is_test_minus_dev_per_preset_and_aperture():
    from experiments.leaderboard import generalisation_gap, generalisation_tables

    dev = _rows("dev", [1.0, 2.0, 3.0], eid="d", apertures=(2.0, 8.0))
    test = _rows("test", [1.5, 2.5, 3.5, 4.5], eid="t", apertures=(2.0, 8.0))
    rows = generalisation_gap(dev, test, metrics=("dense_textured_mae",))
    by = {r["aperture"]: r for r in rows}
    assert set(by) == {2.0, 8.0, "all"}
    assert by[2.0]["dev"]["mean"] == pytest.approx(2.0) and by[2.0]["test"]["mean"] == pytest.approx(3.0)
    assert by[2.0]["gap"]["value"] == pytest.approx(1.0) and by[8.0]["gap"]["value"] == pytest.approx(0.5)
    assert by["all"]["gap"]["value"] == pytest.approx(0.75)  # each scene's mean over f/2 and f/8
    assert by[2.0]["test"]["n_scenes"] == 4 and by[2.0]["fresh"] is None
    # a group only one split has is not compared
    assert generalisation_gap(dev, _rows("test", [1.0], eid="t", preset="robust"), metrics=("dense_textured_mae",)) == []
    table = generalisation_tables(rows)[0]
    assert table["header"][-1] == "test − dev [95 % CI]"
    assert table["rows"][0][:3] == ["paper", "2", "3"] and table["rows"][0][6].startswith("+1.000 [")


def _evaluation(root, eid, split, values, finished):
    from experiments.results_table import write_results

    folder = root / eid
    write_results(folder, _rows(split, values, eid=eid), {})
    meta = {"evaluation_id": eid, "plan": {"split": split, "scene_size": "small"}, "finished_utc": finished, "seeds": [0, len(values) - 1],
            "rerun": f"python -m repro.evaluate --procedural {len(values)} --split {split}", "summary": []}
    (folder / "summary.json").write_text(json.dumps(meta))


def test_report_shows_the_newest_dev_and_test_side_by_side(tmp_path):
    from repro._cli import run_cli
    from repro._report_text import GENERALISATION_HEADING
    from repro.report import main
    from tests.claims_tables import fig10

    ev = tmp_path / "ev"
    _evaluation(ev, "dev-old", "dev", [9.0, 9.0], "2026-12-01T00:00:00+00:00")
    _evaluation(ev, "dev-new", "dev", [1.0, 2.0, 3.0], "2026-12-03T00:00:00+00:00")
    _evaluation(ev, "test-a", "test", [2.0, 3.0, 4.0], "2026-12-02T00:00:00+00:00")
    (ev / "unfinished").mkdir()
    (ev / "unfinished" / "run.json").write_text("{}")
    figs = tmp_path / "figures"
    write_results(figs, fig10(0.001), {})
    (figs / "fig10.metrics.json").write_text(json.dumps({"title": "CoC vs distance", "mode": "quick"}))
    out = tmp_path / "rep"
    assert run_cli(main, ["--figures", str(figs), "--out", str(out), "--evaluations", str(ev)]) == 0
    md = (out / "README.md").read_text()
    assert f"## {GENERALISATION_HEADING}" in md
    assert "`dev-new`" in md and "dev-old" not in md and "`test-a`" in md
    line = next(ln for ln in md.splitlines() if ln.startswith("| paper | 2 |"))
    assert "| 3 | 2.000 [" in line and "| 3 | 3.000 [" in line and "+1.000 [" in line
    gen = json.loads((out / "generalisation.json").read_text())
    assert gen["rows"][0]["gap"]["value"] == pytest.approx(1.0)
    assert {s["evaluation_id"] for s in gen["sources"]} == {"dev-new", "test-a"}
    assert GENERALISATION_HEADING in (out / "index.html").read_text()
    # without a test evaluation the section is left out
    for p in (ev / "test-a").iterdir():
        p.unlink()
    out2 = tmp_path / "rep2"
    assert run_cli(main, ["--figures", str(figs), "--out", str(out2), "--evaluations", str(ev)]) == 0
    assert GENERALISATION_HEADING not in (out2 / "README.md").read_text()


def test_a_method_that_raises_on_one_input_is_recorded_and_the_others_go_on(monkeypatch):
    """No renderer: a synthetic render (a blurred step, σ_gt known); the robust preset made to raise."""
    import method
    from experiments.procedural_eval import FAILED_METRIC, plan_evaluation
    from experiments.procedural_eval import _render_rows as score_render
    from scenes.render import Render

    h, w = 48, 64
    x = np.linspace(0, 1, w)[None, :].repeat(h, 0)
    rgb = np.repeat((0.1 + 0.6 * (x > 0.5))[..., None], 3, axis=2).astype(np.float32)
    sigma = np.full((h, w), 0.29, np.float32)
    render = Render(rgb=rgb, depth=np.ones((h, w), np.float32), coc_px=np.zeros((h, w), np.float32),
                    sigma_px=sigma, occlusion_boundary=np.zeros((h, w), bool), metadata={})
    real = method.estimate_defocus_map

    def flaky(image, params, **kw):
        if params.estimator == method.DefocusParams.preset("robust").estimator and params != method.DefocusParams():
            raise RuntimeError("did not converge")
        return real(image, params, **kw)

    monkeypatch.setattr(method, "estimate_defocus_map", flaky)
    plan = plan_evaluation(1, split="dev", presets=["paper", "robust"], f_numbers=[2.0])
    failures = []
    rows, seconds = score_render(render, {"scene": "procedural_0", "aperture": 2.0}, plan, 0, failures, [])
    failed = {r["preset"]: r["value"] for r in rows if r["metric"] == FAILED_METRIC}
    assert failed == {"paper": 0.0, "robust": 1.0, "const_median_gt": 0.0, "const_floor": 0.0}  # baselines never fail
    assert [r["metric"] for r in rows if r["preset"] == "robust"] == [FAILED_METRIC]
    assert any(r["metric"] == "sparse_mae" for r in rows if r["preset"] == "paper")
    assert len(failures) == 1 and "robust on procedural_0 f/2" in failures[0] and "did not converge" in failures[0]
    assert set(seconds) == {"paper", "robust"}


def test_the_figures_table_lists_figures_in_registry_order_whatever_order_they_finished_in(tmp_path):
    """Two workers finish figures in any order; the same results must give the same results.csv."""
    import types

    from repro.figures import write_table

    def data(name, value):
        row = {"evaluation_id": f"{name}-quick-0", "source": "figures", "figure": name, "metric": "m",
               "value": value, "unit": "px (σ)"}
        return types.SimpleNamespace(figure=types.SimpleNamespace(name=name), rows=lambda: [row])

    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    write_table(a, [data("fig7", 2.0), data("fig2", 1.0)])
    write_table(b, [data("fig2", 1.0), data("fig7", 2.0)])
    text = (a / "results.csv").read_text()
    assert text == (b / "results.csv").read_text()
    assert text.index("fig2-quick-0") < text.index("fig7-quick-0")
