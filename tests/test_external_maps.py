"""External defocus maps scored against the ground truth (experiments.external_maps, repro.evaluate --maps)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from experiments import dataset as ds
from experiments import external_maps as em


def _gt(sigma, coc=None, occ=None, textured=None):
    sigma = np.asarray(sigma, float)
    return {"sigma": sigma, "coc": sigma * 4 if coc is None else np.asarray(coc, float),
            "occlusion": np.zeros(sigma.shape, bool) if occ is None else np.asarray(occ, bool),
            "textured": np.ones(sigma.shape, bool) if textured is None else np.asarray(textured, bool),
            "depth": np.ones(sigma.shape)}


def make_dataset(root, images: dict, *, version=ds.LAYOUT_VERSION):
    """A hand-made dataset folder: per name the ground-truth dict of :func:`_gt` (and a grey PNG)."""
    import imageio.v3 as iio

    (root / "gt").mkdir(parents=True)
    (root / "images").mkdir()
    entries = []
    for name, gt in images.items():
        for field in ds.GT_FIELDS:
            np.save(root / "gt" / f"{name}_{field}.npy", gt[field])
        h, w = gt["sigma"].shape
        iio.imwrite(root / "images" / f"{name}.png", np.full((h, w, 3), 128, np.uint8))
        entries.append({"name": name, "scene": ds.parse_image_name(name)[0], "shape": [h, w]})
    ds.write_manifest(root, entries, render_settings={}, harness={})
    if version != ds.LAYOUT_VERSION:
        m = json.loads((root / "manifest.json").read_text())
        (root / "manifest.json").write_text(json.dumps({**m, "layout_version": version}))
    return root


# ------------------------------------------------------------------------------------------------
# the protocols on hand-made cases
# ------------------------------------------------------------------------------------------------


def test_constant_map_gives_the_analytic_mae_and_bias():
    sigma = np.array([[0.5, 1.5], [2.5, 3.5]])
    m = em.score_map(np.full((2, 2), 2.0), _gt(sigma))
    assert m["all"]["mae"] == pytest.approx(1.0, abs=1e-12)  # |2 - σ| = 1.5, .5, .5, 1.5
    assert m["all"]["bias"] == pytest.approx(0.0, abs=1e-12)
    assert m["bin_0_1"] == {"n": 1, "mae": pytest.approx(1.5), "bias": pytest.approx(1.5)}
    assert m["bin_2_4"]["n"] == 2 and m["bin_2_4"]["mae"] == pytest.approx(1.0)


def test_occlusion_bands_and_untextured_pixels_are_left_out():
    occ = [[True, False], [False, False]]
    tex = [[True, True], [False, False]]
    m = em.score_map(np.array([[100.0, 1.0], [2.0, 2.0]]), _gt(np.ones((2, 2)), occ=occ, textured=tex))
    assert m["all"]["n"] == 3 and m["all"]["mae"] == pytest.approx(2 / 3)
    assert m["textured"]["n"] == 1 and m["textured"]["mae"] == 0.0
    for protocol in ("rtf", "syndof", "detection"):
        assert em.score_map(np.array([[100.0, 1.0], [2.0, 2.0]]), _gt(np.ones((2, 2)), occ=occ),
                            protocol=protocol)["n"] == 3


def test_rtf_clips_at_3275_and_normalises():
    m = em.score_map(np.array([[10.0, 3.275 / 2]]), _gt([[5.0, 0.0]]), protocol="rtf")
    assert m["nmae"] == pytest.approx(0.25, abs=1e-12)  # 10 and 5 both clip to 3.275: (0 + 0.5) / 2
    assert m["nmse"] == pytest.approx(0.125, abs=1e-12)  # (0 + 0.25) / 2
    below = em.score_map(np.array([[1.0]]), _gt([[3.0]]), protocol="rtf")
    assert below["nmae"] == pytest.approx(2.0 / 3.275, abs=1e-12)


def test_syndof_reference_is_zero_where_coc_below_one():
    gt = _gt([[1.0, 1.0]], coc=[[0.5, 5.0]])  # references 0 and (5 - 1)/4 = 1
    assert em.score_map(np.array([[0.0, 1.0]]), gt, protocol="syndof")["mae"] == pytest.approx(0.0, abs=1e-12)
    m = em.score_map(np.array([[0.25, 1.0]]), gt, protocol="syndof")
    assert m["mae"] == pytest.approx(0.125, abs=1e-12) and m["mse"] == pytest.approx(0.03125, abs=1e-12)
    assert np.array_equal(em.syndof_sigma([0.999, 1.0, 9.0]), [0.0, 0.0, 2.0])


def test_detection_threshold_both_sides():
    gt = _gt([[0.9, 1.1]])
    good = em.score_map(np.array([[0.95, 1.05]]), gt, protocol="detection")
    assert good["accuracy"] == 1.0 and good["f_measure"] == 1.0
    bad = em.score_map(np.array([[1.05, 0.95]]), gt, protocol="detection")
    assert bad["accuracy"] == 0.0 and bad["f_measure"] == 0.0
    # a stated threshold moves the boundary: at 2 px both pixels are sharp in truth and estimate
    assert em.score_map(np.array([[1.05, 0.95]]), gt, protocol="detection", threshold_px=2.0)["accuracy"] == 1.0
    half = em.score_map(np.array([[1.05, 1.05]]), gt, protocol="detection")  # one false positive
    assert half["accuracy"] == 0.5 and half["precision"] == 0.5 and half["recall"] == 1.0
    assert half["f_measure"] == pytest.approx(2 / 3)


def test_unknown_protocol_is_the_registry_message():
    with pytest.raises(ValueError, match=r"protocol='cuhk' is invalid \(unknown protocol\); allowed: 'detection'"):
        em.score_map(np.ones((1, 1)), _gt([[1.0]]), protocol="cuhk")


# ------------------------------------------------------------------------------------------------
# map files
# ------------------------------------------------------------------------------------------------


def test_every_map_format_reads_the_same_sigma(tmp_path):
    import imageio.v3 as iio

    from scenes.exr import write_exr

    sigma = np.array([[0.0, 0.5], [1.25, 3.0]])
    np.save(tmp_path / "a.npy", sigma)
    np.savez(tmp_path / "b.npz", first=sigma, second=sigma * 0)
    write_exr(tmp_path / "c.exr", {"Y": sigma.astype(np.float32)})
    iio.imwrite(tmp_path / "d.png", np.rint(sigma * 1000).astype(np.uint16))
    iio.imwrite(tmp_path / "e.png", np.rint(sigma * 100).astype(np.uint16))
    for name in "abcd":
        assert np.allclose(em.load_map(tmp_path, name), sigma, atol=1e-6), name
    assert np.allclose(em.load_map(tmp_path, "e", png_scale=100), sigma)
    iio.imwrite(tmp_path / "f.png", np.zeros((2, 2), np.uint8))
    with pytest.raises(ValueError, match="f.png: an 8-bit PNG holds no σ values.*preview.*allowed: a 16-bit PNG"):
        em.load_map(tmp_path, "f")


def test_unknown_major_layout_refused(tmp_path):
    make_dataset(tmp_path, {"planes_f8_small": _gt(np.ones((4, 4)))}, version="9.0")
    with pytest.raises(ValueError, match="layout version '9.0' is unknown"):
        em.DatasetTruth(tmp_path)
    make_dataset(tmp_path / "minor", {"planes_f8_small": _gt(np.ones((4, 4)))}, version="1.7")
    assert em.DatasetTruth(tmp_path / "minor").names == ["planes_f8_small"]


NAMES = ("planes_f8_small", "planes_f4_small", "portrait_f8_small", "clutter_f5p6_small", "tilted_plane_f8_small")


def _bad_folder(tmp_path):
    """Two good maps and one bad map per way of being bad."""
    sigma = np.arange(12, dtype=float).reshape(3, 4) / 4
    data = make_dataset(tmp_path / "data", {n: _gt(sigma) for n in NAMES})
    maps = tmp_path / "maps"
    maps.mkdir()
    np.save(maps / "planes_f8_small.npy", sigma)                 # good
    np.save(maps / "portrait_f8_small.npy", sigma + 1.0)         # good, MAE 1
    np.save(maps / "planes_f4_small.npy", np.ones((4, 3)))       # wrong size
    np.save(maps / "clutter_f5p6_small.npy", np.full((3, 4), np.nan))  # NaN-only
    (maps / "tilted_plane_f8_small.exr").write_bytes(b"not an exr")     # unreadable
    np.save(maps / "planes_f2_small.npy", sigma)                 # misnamed: no such image
    return data, maps


def test_bad_maps_each_named_in_one_line_the_others_scored(tmp_path):
    data, maps = _bad_folder(tmp_path)
    result = em.score_folder(maps, em.DatasetTruth(data), protocols=["harness", "rtf"])
    assert set(result.scored) == {"planes_f8_small", "portrait_f8_small"}
    assert len(result.problems) == 4
    for fragment in ("planes_f4_small.npy: shape", "clutter_f5p6_small.npy: no finite value",
                     "tilted_plane_f8_small.exr: unreadable", "planes_f2_small.npy: unknown name"):
        assert sum(fragment in p for p in result.problems) == 1, (fragment, result.problems)
    by = {(r["image"], r["protocol"]): r for r in result.rows}
    assert by[("planes_f8_small", "harness")]["all_mae"] == 0.0
    assert by[("portrait_f8_small", "harness")]["all_mae"] == pytest.approx(1.0)
    (mean,) = [m for m in em.summarize(result.rows) if m["protocol"] == "harness"]
    assert mean["n_images"] == 2 and mean["all_mae"] == pytest.approx(0.5)


def test_missing_map_is_named(tmp_path):
    data = make_dataset(tmp_path / "data", {n: _gt(np.ones((2, 2))) for n in NAMES[:2]})
    maps = tmp_path / "maps"
    maps.mkdir()
    np.save(maps / f"{NAMES[0]}.npy", np.ones((2, 2)))
    result = em.score_folder(maps, em.DatasetTruth(data))
    assert result.scored == [NAMES[0]]
    assert len(result.problems) == 1 and f"{NAMES[1]}: no map" in result.problems[0]


# ------------------------------------------------------------------------------------------------
# the CLI
# ------------------------------------------------------------------------------------------------


def _run(argv, capsys):
    from repro._cli import run_cli
    from repro.evaluate import PROG, main

    status = run_cli(main, [str(a) for a in argv], prog=PROG)
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_maps_scores_the_good_ones_and_names_the_bad(tmp_path, capsys):
    data, maps = _bad_folder(tmp_path)
    out = tmp_path / "out"
    status, stdout, err = _run(["--maps", maps, "--dataset", data, "--protocol", "harness", "syndof", "detection",
                                "--out", out], capsys)
    assert status == 0, err
    lines = err.splitlines()
    assert len(lines) == 4 and all(line.startswith("python -m repro.evaluate: skipped ") for line in lines)
    doc = json.loads((out / "maps.json").read_text())
    assert {r["image"] for r in doc["rows"]} == {"planes_f8_small", "portrait_f8_small"}
    assert {r["protocol"] for r in doc["rows"]} == {"harness", "syndof", "detection"}
    assert len(doc["skipped"]) == 4 and (out / "maps.csv").is_file()
    assert "protocol detection:" in stdout and "mean of 2" in stdout


def test_cli_exit_2_when_no_map_scored(tmp_path, capsys):
    data = make_dataset(tmp_path / "data", {NAMES[0]: _gt(np.ones((2, 2)))})
    maps = tmp_path / "maps"
    maps.mkdir()
    np.save(maps / f"{NAMES[0]}.npy", np.full((2, 2), np.nan))
    status, _, err = _run(["--maps", maps, "--dataset", data, "--out", tmp_path / "out"], capsys)
    assert status == 2
    lines = err.splitlines()
    assert len(lines) == 2 and "NaN-only" in lines[0] and "error: no map" in lines[1]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv, fragment", [
    (["--protocol", "cuhk"], "unknown protocol(s) 'cuhk'; allowed: 'detection', 'harness', 'rtf', 'syndof'"),
    (["--preset", "paper"], "--maps does not take --preset"),
    (["--scenes", "planes"], "--maps --dataset does not take --scenes"),
])
def test_cli_maps_bad_options_one_line(tmp_path, capsys, argv, fragment):
    data = make_dataset(tmp_path / "data", {NAMES[0]: _gt(np.ones((2, 2)))})
    (tmp_path / "maps").mkdir()
    status, _, err = _run(["--maps", tmp_path / "maps", "--dataset", data, *argv], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and fragment in err, err


def test_cli_unknown_layout_one_line(tmp_path, capsys):
    data = make_dataset(tmp_path / "data", {NAMES[0]: _gt(np.ones((2, 2)))}, version="2.0")
    (tmp_path / "maps").mkdir()
    status, _, err = _run(["--maps", tmp_path / "maps", "--dataset", data], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and "layout version '2.0' is unknown" in err


def test_maps_only_flags_need_maps(capsys):
    status, _, err = _run(["--protocol", "rtf"], capsys)
    assert status == 2 and "--protocol is invalid without --maps" in err


# ------------------------------------------------------------------------------------------------
# round trip on an exported render (the smallest scene preset)
# ------------------------------------------------------------------------------------------------


@pytest.mark.render
def test_round_trip_ground_truth_and_estimate_maps_match_the_harness(tmp_path, capsys):
    """σ_gt scored as a map has zero error; ``repro.estimate``'s maps of the exported 8-bit PNGs score
    what ``repro.evaluate --preset`` gives on the same renders (sRGB, 8 bit) to 1e-9 px."""
    import shutil

    from repro import dataset as dataset_cli
    from repro import estimate
    from repro._cli import run_cli
    from repro.evaluate import main as evaluate_main

    data, name = tmp_path / "data", ds.image_name("planes", 8.0, "small")
    assert run_cli(dataset_cli.main, ["export", "--scenes", "planes", "--fnumber", "8", "--out", str(data), "-q"],
                   prog="repro.dataset") == 0
    manifest = json.loads((data / "manifest.json").read_text())
    assert manifest["images"][name]["render"]["spp"] > 0 and "git_commit" in manifest["harness"]

    truth_maps = tmp_path / "truth_maps"
    truth_maps.mkdir()
    shutil.copy(data / "gt" / f"{name}_sigma.npy", truth_maps / f"{name}.npy")
    result = em.score_folder(truth_maps, em.DatasetTruth(data), protocols=list(em.PROTOCOLS))
    assert result.problems == [] and result.scored == [name]
    by = {r["protocol"]: r for r in result.rows}
    assert by["harness"]["all_mae"] == 0.0 and by["harness"]["textured_mae"] == 0.0
    assert by["harness"]["all_n"] > 0 and by["rtf"]["nmae"] == 0.0 and by["detection"]["accuracy"] == 1.0

    maps = tmp_path / "maps"
    maps.mkdir()
    assert run_cli(estimate.main, [str(data / "images" / f"{name}.png"), "-o", str(maps / f"{name}.npy"),
                                   "--preset", "paper", "-q"], prog="repro.estimate") == 0
    assert run_cli(evaluate_main, ["--maps", str(maps), "--dataset", str(data), "--protocol", "harness", "rtf",
                                   "--out", str(tmp_path / "ext"), "-q"], prog="repro.evaluate") == 0
    assert run_cli(evaluate_main, ["--preset", "paper", "--scenes", "planes", "--fnumber", "8", "--encoding", "srgb",
                                   "--workers", "1", "--out", str(tmp_path / "own"), "-q"], prog="repro.evaluate") == 0
    capsys.readouterr()
    ext = {r["protocol"]: r for r in json.loads((tmp_path / "ext" / "maps.json").read_text())["rows"]}
    own, *baselines = json.loads((tmp_path / "own" / "evaluate.json").read_text())["rows"]
    assert [r["method_preset"] for r in baselines] == ["const_median_gt", "const_floor"]
    for ours, theirs in (("dense_all_mae", ext["harness"]["all_mae"]), ("dense_all_bias", ext["harness"]["all_bias"]),
                         ("dense_all_rmse", ext["harness"]["all_rmse"]),
                         ("dense_textured_mae", ext["harness"]["textured_mae"]),
                         ("dense_textured_n", ext["harness"]["textured_n"]),
                         ("rtf_nmae", ext["rtf"]["nmae"]), ("rtf_nmse", ext["rtf"]["nmse"])):
        assert abs(own[ours] - theirs) <= 1e-9, (ours, own[ours], theirs)


@pytest.mark.render
def test_without_a_dataset_maps_match_the_harness_renders_by_name(tmp_path, capsys):
    from experiments.evaluation import ground_truth_sigma
    from scenes import render_scene

    name = ds.image_name("planes", 8.0, "small")
    sigma = ground_truth_sigma(render_scene("planes", preset="small", f_number=8.0, progress=False))
    maps = tmp_path / "maps"
    maps.mkdir()
    np.save(maps / f"{name}.npy", sigma)
    np.save(maps / "planes_f0_small.npy", sigma)  # no such render: named, not fatal
    status, _, err = _run(["--maps", maps, "--protocol", "harness", "detection", "--out", tmp_path / "out"], capsys)
    assert status == 0, err
    assert len(err.splitlines()) == 1 and "planes_f0_small.npy: unknown name" in err
    rows = {r["protocol"]: r for r in json.loads((tmp_path / "out" / "maps.json").read_text())["rows"]}
    assert rows["harness"]["all_mae"] == 0.0 and rows["detection"]["accuracy"] == 1.0
    # with the grid options, the images are the grid's: the missing f/4 map is one line
    status, _, err = _run(["--maps", maps, "--scenes", "planes", "--out", tmp_path / "out2"], capsys)
    assert status == 0 and sum("planes_f4_small: no map" in line for line in err.splitlines()) == 1, err
