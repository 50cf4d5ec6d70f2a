"""Dataset export, external-map loading and the field's protocols (experiments.dataset, repro.dataset)."""

import json

import numpy as np
import pytest

from experiments import dataset as ds


def _gt(sigma, coc=None, occ=None):
    sigma = np.asarray(sigma, float)
    return {"sigma": sigma, "coc": sigma * 4 if coc is None else np.asarray(coc, float),
            "occlusion": np.zeros(sigma.shape, bool) if occ is None else occ,
            "textured": np.ones(sigma.shape, bool), "depth": np.ones(sigma.shape)}


def test_constant_map_mae_is_analytic():
    sigma = np.array([[0.5, 1.5], [2.5, 3.5]])
    m = ds.score_map(np.full((2, 2), 2.0), _gt(sigma))["all"]
    assert m["mae"] == pytest.approx(np.mean(np.abs(2.0 - sigma)), abs=1e-12)
    assert m["bias"] == pytest.approx(2.0 - sigma.mean(), abs=1e-12)


def test_rtf_clips_at_3275_and_normalises():
    gt = _gt([[5.0, 0.0]])
    m = ds.score_map(np.array([[10.0, 3.275 / 2]]), gt, protocol="rtf")
    assert m["nmae"] == pytest.approx(0.25, abs=1e-12)  # (0 + 0.5) / 2: 10 and 5 both clip to 3.275


def test_syndof_coc_below_one_is_zero():
    gt = _gt([[1.0, 1.0]], coc=[[0.5, 5.0]])
    m = ds.score_map(np.array([[0.0, 1.0]]), gt, protocol="syndof")
    assert m["mae"] == pytest.approx(0.0, abs=1e-12)
    m = ds.score_map(np.array([[0.25, 1.0]]), gt, protocol="syndof")
    assert m["mae"] == pytest.approx(0.125, abs=1e-12)


def test_detection_threshold_both_sides():
    gt = _gt([[0.9, 1.1]])
    assert ds.score_map(np.array([[0.95, 1.05]]), gt, protocol="detection")["accuracy"] == 1.0
    bad = ds.score_map(np.array([[1.05, 0.95]]), gt, protocol="detection")
    assert bad["accuracy"] == 0.0 and bad["f_measure"] == 0.0


def test_bad_maps_named(tmp_path):
    np.save(tmp_path / "a.npy", np.full((3, 3), np.nan))
    (tmp_path / "b.exr").write_bytes(b"not an exr")
    with pytest.raises(ValueError, match="NaN-only"):
        ds.score_map(ds.load_map(tmp_path, "a"), _gt(np.ones((3, 3))))
    with pytest.raises(ValueError, match="b.exr"):
        ds.load_map(tmp_path, "b")
    with pytest.raises(ValueError, match="no map"):
        ds.load_map(tmp_path, "c")
    np.save(tmp_path / "d.npy", np.ones((2, 2)))
    with pytest.raises(ValueError, match="shape"):
        ds.score_map(ds.load_map(tmp_path, "d"), _gt(np.ones((3, 3))))


def test_unknown_major_layout_refused(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"layout_version": "9.0"}))
    with pytest.raises(ValueError, match="layout version"):
        ds.read_dataset(tmp_path)


@pytest.mark.parametrize("bits", [8, 16])
def test_png_round_trips_exactly(tmp_path, bits):
    from PIL import Image
    import imagecodecs

    img = np.random.default_rng(0).integers(0, 2 ** bits, (4, 5, 3))
    data = ds._png_bytes(img, bits)
    got = imagecodecs.png_decode(data)
    assert got.dtype == (np.uint8 if bits == 8 else np.uint16) and np.array_equal(got, img)
    (tmp_path / "x.png").write_bytes(data)
    if bits == 8:  # a second decoder reads the same pixels
        assert np.array_equal(np.asarray(Image.open(tmp_path / "x.png")), img)


@pytest.mark.render
def test_export_round_trip_and_interruption(tmp_path, monkeypatch):
    from scenes import render_scene

    render = render_scene("planes", preset="small", f_number=8.0, progress=False)
    name = ds.image_name("planes", 8.0, "small")
    calls = {"n": 0}
    real = ds._write_npy

    def flaky(path, arr):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError("simulated interruption")
        real(path, arr)

    monkeypatch.setattr(ds, "_write_npy", flaky)
    with pytest.raises(OSError):
        ds.export_image(tmp_path, name, render)
    assert not ds.is_complete(tmp_path, name)
    monkeypatch.setattr(ds, "_write_npy", real)
    ds.export_image(tmp_path, name, render)
    assert ds.is_complete(tmp_path, name)
    gt = ds.load_ground_truth(tmp_path, name)
    assert ds.score_map(gt["sigma"], gt)["all"]["mae"] == 0.0
    import imageio.v3 as iio

    png = iio.imread(tmp_path / "images" / f"{name}.png") / 255.0
    assert np.array_equal(png, render.image(encoding="srgb", quantize_bits=8))


def test_cli_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    from repro.dataset import PROG, main
    from tests.photo_cli import cli_runner

    run, assert_one_line_error = cli_runner(main, PROG)
    out = tmp_path / "data"
    status, _, err = run(["export", "--scenes", "no_such_scene", "--out", out], capsys)
    assert_one_line_error(status, err, "no_such_scene", "planes")
    assert not out.exists()
    (tmp_path / "file").write_text("x")
    status, _, err = run(["export", "--scenes", "planes", "--out", tmp_path / "file"], capsys)
    assert_one_line_error(status, err, "is a file")
