"""``python -m repro.bench`` and :mod:`experiments.bench`: the accuracy benchmark (``--accuracy``) on a
tiny configuration, its verdict rule on both sides of every target, and the plain speed bench."""

import copy
import json

import numpy as np
import pytest

import repro.bench as bench
from experiments.bench import accuracy, markdown, mosaics, speed, targets

#: One small dead-leaves mosaic and one small step-edge mosaic (σ = 1, 5, 8 px: an absolute-MAE bin,
#: a relative-MAE bin, a bin without target), the robust preset only, no renders, no speed.
TINY = dict(accuracy.ACCURACY_CONFIG, datasets=("dead_leaves", "step_edges"), sigmas=(1.0, 5.0, 8.0), tile=48,
            mosaic_cols=3, noise_stds=(1.0 / 255,), seeds=(0,), presets=("robust",), scene_sets={}, f_numbers=(),
            estimators=(), speed_presets=(), speed_sizes=(), speed_single={},
            lens=dict(accuracy.LENS_CONFIG, psfs=("disk",), families=("step_edges", "checker"), noises=("iso100",),
                      sigmas=(1.0, 5.0), tile=48, cols=2, variants={"robust": ("robust", {})}))
_TARGETS = ("TARGET_DENSE_MAE_PX", "TARGET_DENSE_REL_MAE", "TARGET_BIAS_PX", "TARGET_BIAS_REL", "TARGET_ABS_MAE_MAX_SIGMA",
            "TARGET_REL_MAE_MAX_SIGMA", "TARGET_BIAS_MAX_SIGMA", "TARGET_RENDER_DENSE_RATIO", "TARGET_SPEED_RATIO")


def _strict_json(path):
    def bad(token):
        raise ValueError(f"non-standard JSON constant {token}")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=bad)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """``main(["--accuracy"])`` with accuracy.ACCURACY_CONFIG replaced by TINY: (out folder, report, stdout rc)."""
    out = tmp_path_factory.mktemp("bench")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(accuracy, "ACCURACY_CONFIG", TINY)
        rc = bench.main(["--accuracy", "--out", str(out)])
    return out, _strict_json(out / "accuracy.json"), rc


@pytest.mark.slow  # subprocesses or a benchmark run: in make test, not in make test-fast
def test_accuracy_report_structure(tiny):
    out, report, rc = tiny
    assert rc == 0
    assert set(report) >= {"config", "analytic", "rendered", "speed", "verdict", "targets", "notes", "machine",
                           "date", "runtime_s"}
    assert report["rendered"] == {"cases": []} and report["speed"] == {"rows": []}
    runs, pooled = report["analytic"]["runs"], report["analytic"]["pooled"]
    assert [(r["dataset"], r["preset"], r["seed"]) for r in runs] == [("dead_leaves", "robust", 0),
                                                                      ("step_edges", "robust", 0)]
    assert len(pooled) == 2
    for g in pooled:
        d = g["dense_textured"]
        # one bin per tile σ, each holding pixels of that σ only
        assert [b["sigma"] for b in d["bins"]] == [1.0, 5.0, 8.0]
        assert all(b["lo"] < b["sigma_gt"] < (b["hi"] if b["hi"] is not None else np.inf) for b in d["bins"])
        assert d["bins"][-1]["hi"] is None  # inf is written as null (strict JSON)
        assert all(b["n"] > 0 and b["mae"] >= abs(b["bias"]) for b in d["bins"])
        assert sum(b["n"] for b in d["bins"]) == d["n"]
        assert g["sparse"]["n"] > 0 and g["sparse"]["mae"] >= 0
        assert g["oracle_propagate_dense_textured"]["mae"] >= 0
    v = report["verdict"]
    assert [(a["dataset"], [b["sigma"] for b in a["bins"]]) for a in v["analytic"]] == [
        ("dead_leaves", [1.0, 5.0, 8.0]), ("step_edges", [1.0, 5.0, 8.0])]
    for a, g in zip(v["analytic"], pooled):
        b1, b5, b8 = a["bins"]
        assert b1["mae_limit"] == targets.TARGET_DENSE_MAE_PX
        assert b5["mae_limit"] == pytest.approx(targets.TARGET_DENSE_REL_MAE * 5.0)
        # σ 8 = TARGET_REL_MAE_MAX_SIGMA = TARGET_BIAS_MAX_SIGMA: relative MAE and bias limits
        assert b8["mae_limit"] == pytest.approx(targets.TARGET_DENSE_REL_MAE * 8.0)
        assert b8["bias_limit"] == pytest.approx(max(targets.TARGET_BIAS_PX, targets.TARGET_BIAS_REL * 8.0))
        # the stored verdicts are the numbers against the limits
        for vb, mb in zip(a["bins"], g["dense_textured"]["bins"]):
            assert vb["mae_ok"] == (mb["mae"] <= vb["mae_limit"])
            assert vb["bias_ok"] == (abs(mb["bias"]) <= vb["bias_limit"])
            assert vb["pass"] == (vb["mae_ok"] and vb["bias_ok"])
        assert a["pass"] == all(b["pass"] for b in (b1, b5, b8) if b["pass"] is not None)
    assert v["rendered"]["pass"] is None and v["speed"]["pass"] is None
    assert v["overall"] == v["analytic_pass"] == all(a["pass"] for a in v["analytic"])
    md = (out / "accuracy.md").read_text(encoding="utf-8")
    assert "Dead-leaves texture mosaic" in md and "Step-edge mosaic" in md and "robust verdict" in md
    assert f"**Overall: {'pass' if v['overall'] else 'FAIL'}**" in md
    assert "✅" not in md and "❌" not in md


def _judge_with(monkeypatch, measured, **limits):
    for name, value in limits.items():
        monkeypatch.setattr(targets, name, value)
    return targets.judge_accuracy(measured)


@pytest.mark.slow  # subprocesses or a benchmark run: in make test, not in make test-fast
def test_analytic_verdict_flips_with_the_targets(tiny, monkeypatch):
    _, report, _ = tiny
    measured = {k: report[k] for k in ("analytic", "rendered", "speed")}
    # trivially satisfied
    v = _judge_with(monkeypatch, measured, TARGET_DENSE_MAE_PX=1e9, TARGET_DENSE_REL_MAE=1e9, TARGET_BIAS_PX=1e9)
    assert v["analytic_pass"] is True and v["overall"] is True
    assert all(b["pass"] in (True, None) for a in v["analytic"] for b in a["bins"])
    # the lens section's targets made trivial too (its cues held to no coverage, any error allowed)
    from experiments.bench import lens

    for key, value in (("edge_min_coverage", 0.0), ("edge_max_rel_bias", 1e9), ("region_max_rel_error", 1e9),
                       ("region_min_coverage", 0.0), ("dense_min_coverage", 0.0), ("dense_mae_px", 1e9),
                       ("dense_rel_mae", 1e9)):
        monkeypatch.setitem(lens.LENS_TARGETS, key, value)
    md = markdown.accuracy_markdown({**report, "verdict": v, "lens_verdict": lens.judge_lens(report["lens"])})
    assert "**Overall: pass**" in md and "FAIL" not in md
    # impossible MAE target (bias target still trivial): every targeted bin fails on its MAE
    v = _judge_with(monkeypatch, measured, TARGET_DENSE_MAE_PX=-1.0, TARGET_DENSE_REL_MAE=-1.0)
    assert v["analytic_pass"] is False and v["overall"] is False
    assert all(b["mae_ok"] is False and b["bias_ok"] is True for a in v["analytic"] for b in a["bins"][:2])
    assert "FAIL (MAE)" in markdown.accuracy_markdown({**report, "verdict": v})
    # impossible bias target alone
    v = _judge_with(monkeypatch, measured, TARGET_DENSE_MAE_PX=1e9, TARGET_DENSE_REL_MAE=1e9, TARGET_BIAS_PX=-1.0,
                    TARGET_BIAS_REL=-1.0)
    assert v["analytic_pass"] is False
    assert "FAIL (bias)" in markdown.accuracy_markdown({**report, "verdict": v})
    # the relative-MAE bin alone decides when only it is impossible
    v = _judge_with(monkeypatch, measured, TARGET_DENSE_MAE_PX=1e9, TARGET_DENSE_REL_MAE=-1.0, TARGET_BIAS_PX=1e9)
    assert [[b["pass"] for b in a["bins"]] for a in v["analytic"]] == [[True, False, False]] * 2  # σ 5, 8: relative
    # and with the relative targets stopping at σ 6, the σ 8 bin has none
    v = _judge_with(monkeypatch, measured, TARGET_DENSE_MAE_PX=1e9, TARGET_DENSE_REL_MAE=-1.0, TARGET_BIAS_PX=1e9,
                    TARGET_REL_MAE_MAX_SIGMA=6.0, TARGET_BIAS_MAX_SIGMA=6.0)
    assert [[b["pass"] for b in a["bins"]] for a in v["analytic"]] == [[True, False, None]] * 2
    # no bin under any target → nothing to judge
    v = _judge_with(monkeypatch, measured, TARGET_ABS_MAE_MAX_SIGMA=0.0, TARGET_REL_MAE_MAX_SIGMA=0.0,
                    TARGET_BIAS_MAX_SIGMA=0.0)
    assert v["analytic_pass"] is None and v["overall"] is None


def test_bias_limit_is_the_larger_of_the_absolute_and_the_relative_one(monkeypatch):
    monkeypatch.setattr(targets, "TARGET_BIAS_PX", 0.3)
    monkeypatch.setattr(targets, "TARGET_BIAS_REL", 0.05)
    monkeypatch.setattr(targets, "TARGET_BIAS_MAX_SIGMA", 8.0)

    def verdict(sigma, bias):
        return targets.bin_verdict({"sigma": sigma, "sigma_gt": sigma, "n": 10, "mae": 0.0, "bias": bias})

    assert verdict(8.0, 0.35)["bias_limit"] == pytest.approx(0.4) and verdict(8.0, -0.35)["bias_ok"] is True
    assert verdict(8.0, 0.45)["bias_ok"] is False
    assert verdict(2.0, 0.35)["bias_limit"] == pytest.approx(0.3) and verdict(2.0, 0.35)["bias_ok"] is False
    assert verdict(2.0, 0.25)["bias_ok"] is True


@pytest.mark.slow  # subprocesses or a benchmark run: in make test, not in make test-fast
def test_targeted_bin_without_pixels_fails(tiny, monkeypatch):
    _, report, _ = tiny
    measured = copy.deepcopy({k: report[k] for k in ("analytic", "rendered", "speed")})
    b = measured["analytic"]["pooled"][0]["dense_textured"]["bins"][0]
    b.update(n=0, mae=None, bias=None)
    v = _judge_with(monkeypatch, measured, TARGET_DENSE_MAE_PX=1e9, TARGET_DENSE_REL_MAE=1e9, TARGET_BIAS_PX=1e9)
    assert v["analytic"][0]["bins"][0]["pass"] is False and v["analytic_pass"] is False


def _err(mae):
    return {"n": 100, "mae": mae, "bias": 0.0, "coverage": 1.0}


def _case(scene, f_number, paper, robust, robust_sparse, zc, gr, scene_set="tabletop_stress"):
    return {"scene_set": scene_set, "scene": scene, "f_number": f_number, "shape": [120, 160],
            "presets": {"paper": {"dense_textured": _err(paper), "sparse": _err(1.0)},
                        "robust": {"dense_textured": _err(robust), "sparse": _err(robust_sparse)}},
            "estimators": {"zero_crossing": {"dense_textured": _err(9.0), "sparse": _err(zc)},
                           "gradient_ratio": {"dense_textured": _err(9.0), "sparse": _err(gr)}}}


def test_rendered_and_speed_verdicts_both_sides(monkeypatch):
    monkeypatch.setattr(targets, "TARGET_RENDER_DENSE_RATIO", 0.5)
    monkeypatch.setattr(targets, "TARGET_SPEED_RATIO", 1.3)
    speed = {"rows": [{"preset": "paper", "size": targets.TARGET_SPEED_SIZE, "median_s": 2.0},
                      {"preset": "robust", "size": targets.TARGET_SPEED_SIZE, "median_s": 2.5}]}
    good = {"rendered": {"cases": [_case("portrait", 8.0, 1.0, 0.4, 0.3, 0.5, 0.6),
                                   _case("planes", 4.0, 2.0, 0.9, 1.0, 0.5, 0.5)]}, "speed": speed}
    v = targets.judge_accuracy(good)
    assert v["rendered"]["pass"] is True and v["speed"]["pass"] is True and v["overall"] is True
    assert v["rendered"]["sets"]["tabletop_stress"]["mean"]["ratio"] == pytest.approx(1.3 / 3.0)
    assert v["rendered"]["sparse"]["best_estimator"] == "zero_crossing"
    assert v["speed"]["ratio"] == pytest.approx(1.25)
    # one case above the ratio (1.05 / 2 > 0.5) while the mean still meets it (0.725 / 1.5 ≤ 0.5):
    # that case, hence the whole part, fails
    bad = copy.deepcopy(good)
    bad["rendered"]["cases"][1]["presets"]["robust"]["dense_textured"]["mae"] = 1.05
    v = targets.judge_accuracy(bad)
    assert [c["pass"] for c in v["rendered"]["cases"]] == [True, False]
    assert v["rendered"]["sets"]["tabletop_stress"]["mean"]["pass"] is True and v["rendered"]["pass"] is False
    # and the mean alone
    bad["rendered"]["cases"][0]["presets"]["robust"]["dense_textured"]["mae"] = 0.5
    bad["rendered"]["cases"][1]["presets"]["robust"]["dense_textured"]["mae"] = 0.9
    bad["rendered"]["cases"][0]["presets"]["paper"]["dense_textured"]["mae"] = 1.0
    bad["rendered"]["cases"][1]["presets"]["paper"]["dense_textured"]["mae"] = 1.8
    v = targets.judge_accuracy(bad)
    assert [c["pass"] for c in v["rendered"]["cases"]] == [True, True]
    assert v["rendered"]["sets"]["tabletop_stress"]["mean"]["pass"] is True  # 0.7 ≤ 0.5 · 1.4
    bad["rendered"]["cases"][1]["presets"]["paper"]["dense_textured"]["mae"] = 1.7
    v = targets.judge_accuracy(bad)
    assert v["rendered"]["cases"][1]["pass"] is False and v["rendered"]["sets"]["tabletop_stress"]["mean"]["pass"] is False
    # robust sparse worse than the best estimator on the target case
    bad = copy.deepcopy(good)
    bad["rendered"]["cases"][0]["presets"]["robust"]["sparse"]["mae"] = 0.55
    v = targets.judge_accuracy(bad)
    assert v["rendered"]["sparse"]["pass"] is False and v["rendered"]["pass"] is False
    assert v["overall"] is False
    # speed ratio above the target; then the target made trivially satisfied again
    slow = copy.deepcopy(good)
    slow["speed"]["rows"][1]["median_s"] = 2.7
    assert targets.judge_accuracy(slow)["speed"]["pass"] is False
    monkeypatch.setattr(targets, "TARGET_SPEED_RATIO", 10.0)
    assert targets.judge_accuracy(slow)["speed"]["pass"] is True


def test_rendered_verdicts_cannot_pass_by_abstaining(monkeypatch):
    monkeypatch.setattr(targets, "TARGET_RENDER_DENSE_RATIO", 0.5)
    assert targets.TARGET_MIN_COVERAGE == 0.5 and targets.targets()["min_coverage"] == 0.5
    good = {"rendered": {"cases": [_case("portrait", 8.0, 1.0, 0.4, 0.3, 0.5, 0.6)]}}
    v = targets.judge_accuracy(good)
    assert v["rendered"]["sparse"]["pass"] is True and v["rendered"]["sparse"]["coverage_ok"] is True
    # the robust edge measures on fewer than the target share of edge pixels: fails, though more accurate
    sparse = good["rendered"]["cases"][0]["presets"]["robust"]["sparse"]
    for cov, ok in ((0.5, True), (0.49, False), (0.0, False)):
        low = copy.deepcopy(good)
        low["rendered"]["cases"][0]["presets"]["robust"]["sparse"].update(coverage=cov)
        v = targets.judge_accuracy(low)
        assert v["rendered"]["sparse"]["pass"] is ok and v["rendered"]["pass"] is ok, cov
    # enough coverage but worse than the best estimator still fails
    worse = copy.deepcopy(good)
    worse["rendered"]["cases"][0]["presets"]["robust"]["sparse"].update(mae=0.6, coverage=sparse["coverage"])
    assert targets.judge_accuracy(worse)["rendered"]["sparse"]["pass"] is False
    # no robust edge measure at all, or no robust dense map where the paper has one: fail, not "n/a"
    none = copy.deepcopy(good)
    none["rendered"]["cases"][0]["presets"]["robust"]["sparse"].update(n=0, mae=None, coverage=0.0)
    assert targets.judge_accuracy(none)["rendered"]["sparse"]["pass"] is False
    none = copy.deepcopy(good)
    none["rendered"]["cases"][0]["presets"]["robust"]["dense_textured"].update(n=0, mae=None)
    v = targets.judge_accuracy(none)
    assert v["rendered"]["cases"][0]["pass"] is False and v["rendered"]["cases"][0]["ratio"] is None
    assert v["rendered"]["sets"]["tabletop_stress"]["mean"] is None and v["rendered"]["pass"] is False


def test_step_mosaic_geometry():
    sigmas, tile = (0.5, 2.0, 8.0), 32
    image, gt, valid = mosaics.step_mosaic(sigmas, tile, 0.0, 0)
    assert image.shape == gt.shape == valid.shape == (2 * tile, 3 * tile)
    np.testing.assert_array_equal(gt[:, ::tile][0], sigmas)
    # mirror-image tiles: with one σ everywhere, continuous across the seams (up to 8-bit rounding);
    # with different σ only the edge's profile changes at a seam
    same, _, _ = mosaics.step_mosaic((2.0,) * 3, tile, 0.0, 0)
    for k in (1, 2):
        assert np.abs(same[:, k * tile] - same[:, k * tile - 1]).max() <= 1.0 / 255 + 1e-12
    assert np.abs(same[tile] - same[tile - 1]).max() <= 1.0 / 255 + 1e-12
    assert np.abs(np.diff(same, axis=1)).max() > 0.1  # there are edges
    # the masked band: STEP_SEAM_BAND_PX px on each side of interior seams only
    band = mosaics.STEP_SEAM_BAND_PX
    cols = ~valid[tile // 2]  # a row farther than the band from the horizontal seam
    assert cols.sum() == 2 * 2 * band and not cols[:tile - band].any() and cols[tile - band:tile + band].all()
    assert (~valid[:, 1]).sum() == 2 * band  # the horizontal seam only; no band at the canvas border


def test_sigma_bins_put_each_value_alone():
    bins = mosaics.sigma_bins([4.0, 0.5, 1.0, 1.0])
    assert bins == (0.0, 0.75, 2.5, np.inf)


#: A made-up row of experiments.bench.speed.time_magnification.
MAGNIFY_ROW = {"renderer": "scatter", "shape": [2828, 4243], "pixels": 11_999_204,
               "sigma_px": {"median": 4.9, "p99": 15.3, "max": 20.6}, "magnify_s": 12.0, "peak_rss_gib": 2.0,
               "load1": [1.0, 1.5]}


def test_magnify_rows_judged_on_both_sides_and_tabled(tmp_path, monkeypatch):
    s = speed.speed_summary([], [MAGNIFY_ROW, dict(MAGNIFY_ROW, renderer="gather", magnify_s=40.0)])
    assert s["magnify scatter: seconds_12mp"] == 12.0 and s["magnify scatter: meets_time_target_12mp"]
    assert "magnify gather: meets_time_target_12mp" not in s  # the target is the scatter's
    monkeypatch.setattr(speed, "TARGET_MAGNIFY_SECONDS_12MP", 10.0)
    assert not speed.speed_summary([], [MAGNIFY_ROW])["magnify scatter: meets_time_target_12mp"]
    table = speed.magnify_table([MAGNIFY_ROW])
    assert "| scatter | 4243×2828 | 4.90 / 15.30 / 20.60 | 12.0 | 2.00 | 1.0 → 1.5 |" in table
    row = {"size": 16, "pixels": 256, "edge_pixels": 3, "timings_s": {"total": 0.5}, "peak_rss_gib": 0.1}
    monkeypatch.setattr(bench, "_run_size", lambda size, repeat, preset="paper": dict(row, size=size, preset=preset))
    calls = []
    monkeypatch.setattr(bench, "_run_magnify", lambda renderer: calls.append(renderer) or dict(MAGNIFY_ROW,
                                                                                                 renderer=renderer))
    assert bench.main(["--sizes", "16", "--repeat", "1", "--out", str(tmp_path), "--magnify-renderers", "none"]) == 0
    assert calls == [] and _strict_json(tmp_path / "bench.json")["magnify_rows"] == []
    assert bench.main(["--sizes", "16", "--repeat", "1", "--out", str(tmp_path), "--magnify-renderers", "gather",
                       "scatter"]) == 0
    assert calls == ["gather", "scatter"]
    assert "Magnification step alone" in (tmp_path / "bench.md").read_text(encoding="utf-8")
    from repro._cli import run_cli

    assert run_cli(bench.main, ["--sizes", "16", "--out", str(tmp_path), "--magnify-renderers", "splat"],
                   prog=bench.PROG) == 2


def test_plain_bench_unchanged_without_the_flag(tmp_path, monkeypatch):
    row = {"size": 16, "pixels": 256, "edge_pixels": 3, "timings_s": {"total": 0.5}, "peak_rss_gib": 0.1}
    monkeypatch.setattr(bench, "_run_size", lambda size, repeat, preset="paper": dict(row, size=size, preset=preset))
    monkeypatch.setattr(bench, "run_accuracy", lambda *a, **k: pytest.fail("--accuracy path taken"))
    monkeypatch.setattr(bench, "_run_magnify", lambda renderer: dict(MAGNIFY_ROW, renderer=renderer))
    assert bench.main(["--sizes", "16", "--repeat", "1", "--out", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.json", "bench.md"]
    first = _strict_json(tmp_path / "bench.json")
    assert first["rows"][0]["size"] == 16
    assert [r["preset"] for r in first["rows"]] == list(speed.BENCH_PRESETS) and first["before"] is None
    # a second run keeps the first as "before", in the JSON and the Markdown
    assert bench.main(["--sizes", "16", "--repeat", "1", "--preset", "robust", "--out", str(tmp_path)]) == 0
    second = _strict_json(tmp_path / "bench.json")
    assert second["before"]["rows"] == first["rows"] and [r["preset"] for r in second["rows"]] == ["robust"]
    assert "## Before" in (tmp_path / "bench.md").read_text(encoding="utf-8")


def test_speed_summary_judges_each_preset_on_both_sides():
    def row(preset, size, total, peak=0.5):
        return {"preset": preset, "size": size, "timings_s": {"total": total}, "peak_rss_gib": peak}

    rows = [row("paper", 512, 0.4), row("paper", 1024, 0.95), row("robust", 512, 1.1),
            row("robust", 1024, 1.05, peak=1.6)]
    s = speed.speed_summary(rows)
    assert s["paper: meets_time_target_512"] and s["paper: meets_time_target_1mp"]
    assert s["paper: meets_memory_target"]
    assert not s["robust: meets_time_target_512"] and not s["robust: meets_time_target_1mp"]
    assert not s["robust: meets_memory_target"]
    assert s["paper: growth_512_to_1024"] == pytest.approx(0.95 / 0.4)
    # one 1-MP target (1.0 s) for every preset: the boundary passes, just over it fails, either preset
    assert speed.TARGET_SECONDS_1MP == 1.0
    s = speed.speed_summary([row("paper", 1024, 1.0), row("robust", 1024, 1.0)])
    assert s["paper: meets_time_target_1mp"] and s["robust: meets_time_target_1mp"]
    s = speed.speed_summary([row("paper", 1024, 1.01), row("robust", 1024, 1.01)])
    assert not s["paper: meets_time_target_1mp"] and not s["robust: meets_time_target_1mp"]


def test_an_unknown_preset_in_the_accuracy_config_is_a_bug_not_a_user_error(tmp_path, monkeypatch):
    """The benchmark's config is code, not the user's input: a bad preset there raises (a traceback),
    before anything is computed or written."""
    monkeypatch.setattr(accuracy, "ACCURACY_CONFIG", dict(TINY, presets=("nope",)))
    from repro._cli import CLIError, run_cli

    with pytest.raises(ValueError, match="nope") as e:
        run_cli(bench.main, ["--accuracy", "--out", str(tmp_path)], prog=bench.PROG)
    assert not isinstance(e.value, CLIError)
    assert not (tmp_path / "accuracy.json").exists()


def test_rendered_verdict_per_scene_set_and_one_table_each(monkeypatch):
    """Each scene set is judged on its own cases and its own mean; one failing set fails the part."""
    monkeypatch.setattr(targets, "TARGET_RENDER_DENSE_RATIO", 0.5)
    cases = [_case("portrait", 8.0, 1.0, 0.4, 0.3, 0.5, 0.6),
             _case("portrait_garden", 8.0, 1.0, 0.45, 0.3, 0.5, 0.6, scene_set="paper_cameras")]
    v = targets.judge_accuracy({"rendered": {"cases": cases}})
    assert set(v["rendered"]["sets"]) == {"tabletop_stress", "paper_cameras"}
    assert v["rendered"]["sets"]["paper_cameras"]["mean"]["ratio"] == pytest.approx(0.45)
    assert v["rendered"]["pass"] is True
    worse = copy.deepcopy(cases)
    worse[1]["presets"]["robust"]["dense_textured"]["mae"] = 0.6  # 0.6 > 0.5 x 1.0 on paper_cameras only
    v = targets.judge_accuracy({"rendered": {"cases": worse}})
    assert v["rendered"]["sets"]["tabletop_stress"]["pass"] is True
    assert v["rendered"]["sets"]["paper_cameras"]["pass"] is False and v["rendered"]["pass"] is False
    report = {"config": dict(accuracy.ACCURACY_CONFIG), "analytic": {"runs": [], "pooled": []},
              "rendered": {"cases": worse}, "speed": {"rows": []}, "verdict": v, "notes": [],
              "date": "2026-12-01 00:00:00", "machine": {"cpus": 2}, "runtime_s": 60.0}
    md = markdown.accuracy_markdown(report)
    assert md.count("### Scene set `tabletop_stress`") == 1 and md.count("### Scene set `paper_cameras`") == 1
    assert "| portrait_garden | 8 |" in md


def test_doubling_runs_each_preset_and_refuses_an_unknown_one(tmp_path, monkeypatch, capsys):
    """``--doubling`` judges every ``--preset`` (one section each); an unknown name is one line, exit 2."""
    import experiments.doubling_sizes as ds
    from repro._cli import run_cli

    seen = []

    def fake_report(cfg, *, progress=True):
        seen.append(cfg["preset"])
        return {"config": dict(cfg), "cases": [], "sizes": {}}

    monkeypatch.setattr(ds, "doubling_report", fake_report)
    assert bench.main(["--doubling", "--preset", "paper", "robust", "--out", str(tmp_path), "-q"]) == 0
    assert seen == ["paper", "robust"]
    md = (tmp_path / "doubling.md").read_text(encoding="utf-8")
    assert "(paper preset)" in md and "(robust preset)" in md
    assert set(json.loads((tmp_path / "doubling.json").read_text(encoding="utf-8"))) == {"paper", "robust"}
    assert run_cli(bench.main, ["--doubling", "--preset", "nope", "--out", str(tmp_path)], prog=bench.PROG) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'nope'" in err[0] and seen == ["paper", "robust"]
