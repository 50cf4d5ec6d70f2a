"""python -m repro.magnify: --renderer / --aperture / --kernel, and --map (a defocus map made elsewhere)."""

from __future__ import annotations

import numpy as np
import pytest

from repro import estimate as estimate_cli
from repro.magnify import PROG, main
from repro.photo_io import read_photo, write_photo
from tests.photo_cli import cli_runner, textured_photo

run, assert_one_line_error = cli_runner(main, PROG)
run_estimate, _ = cli_runner(estimate_cli.main, estimate_cli.PROG)


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(tmp_path / "cache"))


@pytest.fixture
def photo(tmp_path):
    return write_photo(tmp_path / "photo.png", textured_photo(48, 64))


@pytest.fixture
def saved_map(tmp_path, photo, capsys):
    """The photo's map written by repro.estimate as .npy and .exr (default preset)."""
    for suffix in (".npy", ".exr"):
        status, _, err = run_estimate([photo, "-o", tmp_path / f"map{suffix}", "-q"], capsys)
        assert status == 0, err
    return tmp_path / "map.npy", tmp_path / "map.exr"


def _summary(err):
    return [line for line in err if line.startswith(f"{PROG}: defocus map σ")]


def test_default_renderer_scatter_but_gather_for_the_paper_preset(tmp_path, photo, capsys):
    status, _, err = run([photo, "-o", tmp_path / "a.png"], capsys)
    assert status == 0 and "scatter renderer, disk aperture" in _summary(err)[0]
    status, _, err = run([photo, "-o", tmp_path / "b.png", "--preset", "paper"], capsys)
    assert status == 0 and "gather renderer, gaussian kernel" in _summary(err)[0]
    status, _, err = run([photo, "-o", tmp_path / "c.png", "--renderer", "gather"], capsys)
    assert status == 0 and "gather renderer" in _summary(err)[0]
    a, c = read_photo(tmp_path / "a.png").image, read_photo(tmp_path / "c.png").image
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("argv,needles", [
    (["--renderer", "splat"], ["--renderer", "splat", "gather", "scatter"]),
    (["--aperture", "octagon"], ["--aperture", "octagon", "disk", "hexagon"]),
    (["--kernel", "disk"], ["--kernel applies to the gather renderer"]),
    (["--renderer", "gather", "--aperture", "hexagon"], ["--aperture applies to the scatter renderer"]),
    (["--png-scale", "100"], ["--png-scale applies to a .png --map"]),
])
def test_bad_renderer_flags_one_line_no_output(argv, needles, tmp_path, photo, capsys):
    status, out, err = run([photo, "-o", tmp_path / "o.png", *argv], capsys)
    assert_one_line_error(status, err, *needles)
    assert out == "" and not (tmp_path / "o.png").exists()


def test_map_round_trip_npy_exact_and_exr_within_float32(tmp_path, photo, saved_map, capsys):
    """Magnifying with the map repro.estimate wrote equals magnifying with estimation at the same
    settings: exactly for .npy; for .exr the map is the float32-rounded one (and nothing else)."""
    npy, exr = saved_map
    status, _, err = run([photo, "-o", tmp_path / "est.png"], capsys)
    assert status == 0, err
    status, _, err = run([photo, "-o", tmp_path / "npy.png", "--map", npy], capsys)
    assert status == 0 and "(--map)" in _summary(err)[0]
    np.testing.assert_array_equal(read_photo(tmp_path / "npy.png").image, read_photo(tmp_path / "est.png").image)
    from repro.magnify import read_given_map

    sigma = np.load(npy)
    from_exr, _ = read_given_map(exr, sigma.shape)
    np.testing.assert_array_equal(from_exr, sigma.astype(np.float32).astype(np.float64))
    assert np.max(np.abs(from_exr - sigma)) <= np.finfo(np.float32).eps * max(1.0, float(sigma.max()))
    np.save(tmp_path / "f32.npy", sigma.astype(np.float32).astype(np.float64))
    for name, path in (("exr", exr), ("f32", tmp_path / "f32.npy")):
        status, _, err = run([photo, "-o", tmp_path / f"{name}.png", "--map", path], capsys)
        assert status == 0, err
    np.testing.assert_array_equal(read_photo(tmp_path / "exr.png").image, read_photo(tmp_path / "f32.png").image)


def test_map_png16_with_scale_and_the_8bit_preview_refused(tmp_path, photo, saved_map, capsys):
    import imageio.v3 as iio

    sigma = np.load(saved_map[0])
    iio.imwrite(tmp_path / "m16.png", np.rint(sigma * 100).astype(np.uint16))
    status, _, err = run([photo, "-o", tmp_path / "p.png", "--map", tmp_path / "m16.png", "--png-scale", "100"], capsys)
    assert status == 0, err
    from repro.magnify import read_given_map

    got, _ = read_given_map(tmp_path / "m16.png", sigma.shape, png_scale=100)
    assert np.max(np.abs(got - sigma)) <= 0.005 + 1e-12  # half a PNG step of 0.01 px
    status, _, err = run([photo, "-o", tmp_path / "q.png", "--save-map", tmp_path / "preview.png"], capsys)
    assert status == 0, err
    status, out, err = run([photo, "-o", tmp_path / "r.png", "--map", tmp_path / "preview.png"], capsys)
    assert_one_line_error(status, err, "--map", "preview.png", "8-bit PNG holds no σ", "preview", "16-bit")
    assert out == "" and not (tmp_path / "r.png").exists()


def test_map_of_the_photos_aspect_is_resized_and_sigma_scaled(tmp_path, photo, capsys):
    """A 24×32 map of σ = 1 px (half the photo's size) is σ = 2 px of the photo: the same result as a
    full-size map of 2 px."""
    np.save(tmp_path / "half.npy", np.full((24, 32), 1.0))
    np.save(tmp_path / "full.npy", np.full((48, 64), 2.0))
    status, _, err = run([photo, "-o", tmp_path / "h.png", "--map", tmp_path / "half.npy", "--renderer", "gather"],
                         capsys)
    assert status == 0 and any("resized to the photo's 64x48 px, σ × 2" in line for line in err), err
    status, _, _ = run([photo, "-o", tmp_path / "f.png", "--map", tmp_path / "full.npy", "--renderer", "gather"], capsys)
    assert status == 0
    np.testing.assert_array_equal(read_photo(tmp_path / "h.png").image, read_photo(tmp_path / "f.png").image)


def _bad_map(kind, tmp_path):
    path = tmp_path / "bad.npy"
    if kind == "other_size":
        np.save(path, np.ones((30, 30)))
        return path, ["30x30 px does not fit", "64x48"]
    if kind == "transposed":
        np.save(path, np.ones((64, 48)))
        return path, ["48x64 px does not fit", "transpose"]
    if kind == "nan":
        m = np.ones((48, 64))
        m[3, 4] = np.nan
        np.save(path, m)
        return path, ["1 non-finite σ"]
    if kind == "inf":
        np.save(path, np.full((48, 64), np.inf))
        return path, ["non-finite σ"]
    if kind == "negative":
        np.save(path, np.full((48, 64), -0.5))
        return path, ["negative σ", ">= 0"]
    if kind == "garbage":
        path.write_bytes(b"this is not a numpy file")
        return path, ["bad.npy: unreadable"]
    if kind == "missing":
        return tmp_path / "nope.npy", ["nope.npy: no such file"]
    if kind == "suffix":
        p = tmp_path / "bad.txt"
        p.write_text("1 2 3")
        return p, ["unreadable", ".npy"]
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["other_size", "transposed", "nan", "inf", "negative", "garbage", "missing",
                                  "suffix"])
def test_bad_map_one_line_exit_2_nothing_written(kind, tmp_path, photo, capsys):
    path, needles = _bad_map(kind, tmp_path)
    argv = [photo, "-o", tmp_path / "o.png", "--save-map", tmp_path / "m.exr", "--map", path]
    status, out, err = run(argv, capsys)
    assert_one_line_error(status, err, "--map", *needles)
    assert out == "" and not (tmp_path / "o.png").exists() and not (tmp_path / "m.exr").exists()


def test_map_refuses_estimation_options(tmp_path, photo, capsys):
    np.save(tmp_path / "m.npy", np.ones((48, 64)))
    status, out, err = run([photo, "-o", tmp_path / "o.png", "--map", tmp_path / "m.npy", "--estimator",
                            "zero_crossing"], capsys)
    assert_one_line_error(status, err, "--map replaces the estimation", "--estimator")
    assert not (tmp_path / "o.png").exists()
