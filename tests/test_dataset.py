"""Dataset export (experiments.dataset, repro.dataset); the maps and protocols: tests/test_external_maps.py."""

import json

import numpy as np
import pytest

from experiments import dataset as ds


def test_image_names_parse_back():
    for scene, n in (("planes", 8.0), ("tilted_plane", 5.6), ("heron_at_the_lake", 2.8)):
        assert ds.parse_image_name(ds.image_name(scene, n, "small")) == (scene, n, "small")
    assert ds.parse_image_name("planes_small") is None


def test_unknown_major_layout_refused(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"layout_version": "9.0"}))
    with pytest.raises(ValueError, match="layout version"):
        ds.read_dataset(tmp_path)
    with pytest.raises(ValueError, match="no manifest.json"):
        ds.read_dataset(tmp_path / "nothing")


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
    from experiments.external_maps import score_map

    assert score_map(gt["sigma"], gt)["all"]["mae"] == 0.0
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
    status, _, err = run(["export", "--scenes", "planes", "--camera", "pinhole", "--out", out], capsys)
    assert_one_line_error(status, err, "--camera='pinhole' is invalid (unknown camera preset)")
    assert not out.exists()


@pytest.mark.render
def test_export_camera_reaches_the_render_and_the_manifest(tmp_path, monkeypatch, capsys):
    import scenes
    from repro.dataset import PROG, main
    from tests.photo_cli import cli_runner

    real = scenes.render_scene("planes", preset="small", f_number=8.0, progress=False)
    seen = []

    def fake_render(scene, camera=None, **kw):  # the cached render stands in; the camera is what is checked
        assert kw["force"] is (len(seen) == 1)
        seen.append(camera)
        return real

    monkeypatch.setattr(scenes, "render_scene", fake_render)
    run, assert_one_line_error = cli_runner(main, PROG)
    out = tmp_path / "data"
    status, _, err = run(["export", "--scenes", "planes", "--fnumber", "8", "--camera", "aps_c_22", "--out", out, "-q"],
                         capsys)
    assert status == 0, err
    (camera,) = seen
    from scenes.camera import CAMERA_PRESETS

    assert camera.sensor_width_mm == CAMERA_PRESETS["aps_c_22"].sensor_width_mm and camera.f_number == 8.0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["render_settings"]["camera_preset"] == "aps_c_22"
    assert manifest["images"]["planes_f8_small"]["camera_preset"] == "aps_c_22"
    assert manifest["images"]["planes_f8_small"]["render"]["spp"] == real.metadata["spp"]
    status, _, err = run(["export", "--scenes", "planes", "--fnumber", "8", "--out", out, "-q"], capsys)
    assert_one_line_error(status, err, "was exported with --camera aps_c_22")
    # --force: re-rendered and re-exported (the camera then replaces the folder's)
    status, _, err = run(["export", "--scenes", "planes", "--fnumber", "8", "--out", out, "--force", "-q"], capsys)
    assert status == 0, err
    assert len(seen) == 2 and seen[1].sensor_width_mm == real.camera.sensor_width_mm
    assert json.loads((out / "manifest.json").read_text())["images"]["planes_f8_small"]["camera_preset"] is None


@pytest.mark.render
def test_export_applies_the_camera_pipeline(tmp_path, monkeypatch, capsys):
    """--noise / --jpeg: the 8- and 16-bit images carry the camera's noise (seeded by the name), the EXR
    stays the linear render; the manifest records the pipeline; a rerun with another pipeline is refused."""
    import imagecodecs

    import scenes
    from repro.dataset import PROG, main
    from scenes.display import NOISE_LEVELS
    from tests.photo_cli import cli_runner

    real = scenes.render_scene("planes", preset="small", f_number=8.0, progress=False)
    monkeypatch.setattr(scenes, "render_scene", lambda *a, **k: real)
    run, assert_one_line_error = cli_runner(main, PROG)
    out = tmp_path / "data"
    status, _, err = run(["export", "--scenes", "planes", "--fnumber", "8", "--noise", "iso800", "--jpeg", "90",
                          "--out", out, "-q"], capsys)
    assert status == 0, err
    name = "planes_f8_small"
    png = imagecodecs.png_decode((out / "images" / f"{name}.png").read_bytes()) / 255.0
    clean = real.image(encoding="srgb", quantize_bits=8)
    expected = real.image(encoding="srgb", quantize_bits=8, noise="iso800", jpeg_quality=90, rng=ds.noise_seed(name))
    assert np.array_equal(png, expected) and np.abs(png - clean).mean() > 1.0 / 255
    pipe = json.loads((out / "manifest.json").read_text())["images"][name]["camera_pipeline"]
    assert pipe["noise"] == "iso800" and (pipe["a"], pipe["b"]) == NOISE_LEVELS["iso800"] and pipe["jpeg_quality"] == 90
    status, _, err = run(["export", "--scenes", "planes", "--fnumber", "8", "--out", out, "-q"], capsys)
    assert_one_line_error(status, err, "another --noise / --jpeg")
    for bad, text in ((["--noise", "iso5"], "unknown noise level"), (["--jpeg", "101"], "1..100")):
        status, _, err = run(["export", "--scenes", "planes", "--out", tmp_path / "other", *bad], capsys)
        assert_one_line_error(status, err, text)
        assert not (tmp_path / "other").exists()
