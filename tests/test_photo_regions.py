"""experiments.photo_regions: region files, rasteriser, ranking AUC and in-focus share, both sides."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from experiments import photo_regions as pr

#: Exact scores: AUC and share are ratios of pixel counts, computed in float64 (no tolerance needed
#: beyond round-off).
EXACT = 1e-12


def _write(tmp_path, name="coffee", **changes):
    """A copy of the shipped ``name`` region file in ``tmp_path`` with top-level ``changes``."""
    doc = json.loads((pr.PHOTO_DIR / f"{name}.json").read_text())
    doc.update(changes)
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(doc))
    return path


# --- scores on hand-made maps --------------------------------------------------------------------
def test_auc_and_share_on_separated_samples_both_sides():
    sharp, blurry = np.full(50, 0.5), np.linspace(2.0, 3.0, 40)
    assert pr.ranking_auc(sharp, blurry) == 1.0
    assert pr.in_focus_share_above_median(sharp, blurry) == 0.0
    assert pr.ranking_auc(blurry, sharp) == 0.0  # inverted: in-focus region blurrier
    assert pr.in_focus_share_above_median(blurry, sharp) == 1.0


def test_ties_count_half_and_match_the_pair_count():
    assert pr.ranking_auc(np.ones(7), np.ones(3)) == pytest.approx(0.5, abs=EXACT)
    rng = np.random.default_rng(3)
    a, b = rng.integers(0, 5, 60).astype(float), rng.integers(1, 6, 45).astype(float)  # many ties
    pairs = (b[None, :] > a[:, None]).mean() + 0.5 * (b[None, :] == a[:, None]).mean()
    assert pr.ranking_auc(a, b) == pytest.approx(pairs, abs=EXACT)


def test_share_counts_strictly_above_the_defocused_median():
    defocused = np.array([1.0, 2.0, 3.0])  # median 2
    assert pr.in_focus_share_above_median(np.array([1.0, 2.0, 2.5, 4.0]), defocused) == 0.5


def test_score_defocus_map_on_a_map_drawn_from_the_regions_both_sides():
    regions = pr.load_regions("coffee")
    masks = regions.masks()
    good = np.where(masks["defocused"], 3.0, 0.6)  # ranks correctly
    s = pr.score_defocus_map(good, regions)
    assert s["auc"] == 1.0 and s["in_focus_above_defocused_median"] == 0.0 and s["meets_targets"]
    assert s["in_focus_median_px"] == 0.6 and s["defocused_median_px"] == 3.0
    assert s["n_in_focus"] == masks["in_focus"].sum() and s["n_defocused"] == masks["defocused"].sum()
    bad = np.where(masks["in_focus"], 3.0, 0.6)  # the failure seen on coffee: the cup marked blurry
    s = pr.score_defocus_map(bad, regions)
    assert s["auc"] == 0.0 and s["in_focus_above_defocused_median"] == 1.0 and not s["meets_targets"]
    # a constant map ranks nothing: every pair is a tie
    s = pr.score_defocus_map(np.ones(regions.shape[:2]), regions)
    assert s["auc"] == 0.5 and s["in_focus_above_defocused_median"] == 0.0


def test_targets_are_checked_at_their_thresholds():
    regions = pr.load_regions("chelsea")
    m = regions.masks()
    f_idx = np.flatnonzero(m["in_focus"].ravel())
    base = np.where(m["defocused"], 3.0, 0.5).ravel()
    over = base.copy()
    over[f_idx[: int(np.ceil(0.05 * f_idx.size))]] = 9.0  # 5 % of the in-focus pixels blurrier than all
    s = pr.score_defocus_map(over.reshape(m["in_focus"].shape), regions)
    assert s["in_focus_above_defocused_median"] > pr.TARGET_SHARE and not s["meets_targets"]
    assert s["auc"] == pytest.approx(1 - np.ceil(0.05 * f_idx.size) / f_idx.size, abs=EXACT)


def test_score_photo_refuses_a_map_of_another_size():
    with pytest.raises(ValueError, match=r"does not fit photo 'coffee'; allowed: \(400, 600\)"):
        pr.score_photo("coffee", np.zeros((300, 451)))


def test_nan_in_the_regions_is_refused():
    regions = pr.load_regions("coffee")
    m = np.ones(regions.shape[:2])
    m[regions.masks()["in_focus"]] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        pr.score_defocus_map(m, regions)


# --- rasteriser ----------------------------------------------------------------------------------
def test_rasterise_rectangle_and_triangle():
    mask = pr.rasterise_polygon([[2, 1], [5, 1], [5, 3], [2, 3]], (6, 8))  # x 2..5, y 1..3
    want = np.zeros((6, 8), bool)
    want[1:4, 2:6] = True
    np.testing.assert_array_equal(mask, want)
    tri = pr.rasterise_polygon([[0, 0], [20, 0], [0, 20]], (40, 40))
    yy, xx = np.mgrid[:40, :40]
    inside = (xx + yy < 20) & (xx >= 0) & (yy >= 0)
    assert (tri & ~(xx + yy <= 20)).sum() == 0  # nothing outside the hypotenuse
    assert (inside & ~tri).sum() == 0  # every strictly inside pixel
    assert not tri[:, 21:].any() and not tri[21:, :].any()


def test_rasterise_rejects_a_degenerate_polygon():
    with pytest.raises(ValueError, match="V >= 3"):
        pr.rasterise_polygon([[0, 0], [3, 3]], (5, 5))


# --- region files --------------------------------------------------------------------------------
def test_shipped_region_files_load_with_both_labels_disjoint():
    assert {"coffee", "chelsea", "astronaut"} <= set(pr.available_photos())
    for name in pr.available_photos():
        r = pr.load_regions(name)
        m = r.masks()
        assert m["in_focus"].sum() > 5000 and m["defocused"].sum() > 5000, name
        assert not (m["in_focus"] & m["defocused"]).any()
        assert all(reg.why for reg in r.regions)
        assert pr.load_photo_image(r.source).shape == r.shape


def test_coffee_in_focus_region_holds_the_cup_rim():
    """The region file follows the brief: the cup's rim (top of the cup, ~y 25–40 at x 290) is in focus."""
    m = pr.load_regions("coffee").masks()
    assert m["in_focus"][30, 290] and m["in_focus"][110, 185] and m["in_focus"][110, 400]
    assert m["defocused"][20, 560] and not m["in_focus"][20, 560]


def test_region_file_that_does_not_fit_its_photo_is_refused(tmp_path):
    path = _write(tmp_path, shape=[300, 451, 3])
    with pytest.raises(ValueError) as exc:
        pr.load_regions(path)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and "does not fit its photo" in msg and "[400, 600, 3]" in msg


def test_polygon_outside_the_photo_is_refused(tmp_path):
    doc = json.loads((pr.PHOTO_DIR / "chelsea.json").read_text())
    doc["regions"][0]["polygon"] = [[0, 0], [500, 0], [0, 10]]
    path = tmp_path / "chelsea.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"leaves the photo; allowed: 0 <= x <= 450, 0 <= y <= 299"):
        pr.load_regions(path)


@pytest.mark.parametrize("change, needle", [
    ({"regions": []}, "has no regions"),
    ({"regions": [{"label": "sharp", "polygon": [[0, 0], [5, 0], [0, 5]]}]}, "allowed: ['in_focus', 'defocused']"),
    ({"regions": [{"label": "in_focus", "polygon": [[0, 0], [50, 0], [0, 50]]}]}, "'defocused' regions are empty"),
    ({"regions": [{"label": "in_focus", "polygon": [[0, 0], [50, 0], [0, 50]]},
                  {"label": "defocused", "polygon": [[100.3, 100.3], [100.6, 100.3], [100.3, 100.6]]}]}, "'defocused' regions are empty"),
    ({"regions": [{"label": "in_focus", "polygon": [[0, 0], [50, 0], [0, 50]]},
                  {"label": "defocused", "polygon": [[5, 5], [60, 5], [5, 60]]}]}, "labelled both"),
    ({"source": "skimage.data.nope"}, "allowed: 'skimage.data.<function>'"),
    ({"source": "scipy.datasets.face"}, "allowed: 'skimage.data.<function>'"),
    ({"photo": "other"}, "allowed: 'coffee'"),
    ({"shape": [400, 600]}, "allowed: [H, W, 3]"),
])
def test_bad_region_files_are_refused_with_one_line(tmp_path, change, needle):
    path = _write(tmp_path, **change)
    with pytest.raises(ValueError) as exc:
        pr.load_regions(path)
    assert needle in str(exc.value) and str(path) in str(exc.value) and "\n" not in str(exc.value)


def test_unknown_photo_name_names_the_allowed_ones():
    with pytest.raises(ValueError, match=r"unknown photo\(s\) 'teapot'; allowed: \['astronaut', 'chelsea', 'coffee'"):
        pr.load_regions("teapot")
    with pytest.raises(ValueError, match="unknown photo"):
        pr.score_presets(["teapot"])
    with pytest.raises(ValueError, match=r"unknown preset\(s\) 'fast'; allowed"):
        pr.score_presets(["coffee"], ("fast",))


def test_photo_dir_is_what_load_regions_reads(tmp_path):
    shutil.copy(pr.PHOTO_DIR / "chelsea.json", tmp_path / "chelsea.json")
    assert pr.available_photos(tmp_path) == ("chelsea",)
    assert pr.load_regions("chelsea", photo_dir=tmp_path).path == tmp_path / "chelsea.json"
    with pytest.raises(ValueError, match=r"allowed: \['chelsea'\]"):
        pr.load_regions("coffee", photo_dir=tmp_path)


# --- CLI -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, needle", [
    (["--photos", "teapot"], "unknown photo(s) 'teapot'; allowed: ['astronaut', 'chelsea', 'coffee']"),
    (["--photos", "coffee", "--preset", "fast"], "unknown preset(s) 'fast'; allowed"),
    (["--photos", "--stages"], "--photos does not take --stages"),
])
def test_evaluate_photos_bad_input_is_one_line_exit_2(argv, needle, capsys, tmp_path):
    from repro._cli import run_cli
    from repro.evaluate import PROG, main

    assert run_cli(main, [*argv, "--out", str(tmp_path / "o")], prog=PROG) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not (tmp_path / "o").exists()


def test_evaluate_photos_writes_the_table(tmp_path, monkeypatch, capsys):
    """The CLI's table from the photos figure's metrics (its compute replaced by a hand-made result)."""
    import repro._runner as runner
    import repro.evaluate as ev
    from experiments import figS2_photos
    from experiments.cases import CaseOutput
    from experiments.figure_data import FigureData

    score = {"auc": 0.25, "in_focus_above_defocused_median": 0.5, "in_focus_median_px": 1.0,
             "defocused_median_px": 0.5, "n_in_focus": 10, "n_defocused": 5, "meets_targets": False}
    metrics = {"photos": {"coffee": {"shape": [400, 600], "robust": {**score, "seconds": 0.1}}},
               "presets_scored": ["robust"]}

    def fake_run(jobs, **kwargs):
        (job,) = jobs
        case = job.figure.cases(job.config)[0]
        data = FigureData(job.figure, job.config, {case: CaseOutput(case, score, cached=True)})
        return [runner.FigureRun(job=job, data=data)]

    monkeypatch.setattr(runner, "run_figures", fake_run)
    monkeypatch.setattr(figS2_photos, "photo_view", lambda fd: {"metrics": metrics})
    assert ev.main(["--photos", "coffee", "--preset", "robust", "--out", str(tmp_path), "-q"]) == 0
    doc = json.loads((tmp_path / "photos.json").read_text())
    assert doc["rows"] == [{"photo": "coffee", "method_preset": "robust", **score, "seconds": 0.1}]
    md = (tmp_path / "photos.md").read_text()
    assert "| coffee | robust | 0.250 | 50.0 % | 1.00 | 0.50 | no |" in md
    out = capsys.readouterr().out.splitlines()
    assert out[1].split() == ["coffee", "robust", "0.250", "50.0", "%", "1.00", "0.50", "no"]
