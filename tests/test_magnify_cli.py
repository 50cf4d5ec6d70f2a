"""python -m repro.magnify: formats and bit depths, orientation, factor/kernel checks, cache reuse."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from repro.magnify import PROG, main
from repro.photo_io import read_photo, write_photo
from tests.photo_cli import cache_dir, cli_runner, photo, textured_photo  # noqa: F401 (fixtures)

ROOT = Path(__file__).resolve().parents[1]


pytestmark = pytest.mark.usefixtures("cache_dir")

run, assert_one_line_error = cli_runner(main, PROG)


def test_default_output_png_8bit(tmp_path, photo, capsys):
    from PIL import Image

    status, out, err = run([photo, "--factor", "2"], capsys)
    assert status == 0, err
    path = Path(out.strip())
    assert path == tmp_path / "photo.magnified-x2.png"
    with Image.open(path) as im:
        assert im.mode == "RGB" and im.size == (128, 96)
    src, res = read_photo(photo).image, read_photo(path).image
    # the blurred (right) half gets blurrier: its gradient energy drops more than the sharp half's
    def energy(a):
        return float(np.sum(np.diff(a, axis=1) ** 2))
    assert energy(res[:, 72:]) < energy(src[:, 72:])
    assert energy(res[:, 72:]) / energy(src[:, 72:]) < energy(res[:, :56]) / energy(src[:, :56])


@pytest.mark.parametrize("suffix,bits", [(".png", 16), (".tif", 16), (".tif", 8)])
def test_bit_depth_preserved(tmp_path, suffix, bits, capsys):
    import tifffile

    src = write_photo(tmp_path / f"in{suffix}", textured_photo(48, 64), bit_depth=bits)
    status, out, err = run([src, "-o", tmp_path / f"out{suffix}"], capsys)
    assert status == 0, err
    out = tmp_path / f"out{suffix}"
    if suffix == ".png":
        import imagecodecs

        arr = imagecodecs.png_decode(out.read_bytes())
    else:
        arr = tifffile.imread(out)
    assert arr.dtype == (np.uint16 if bits == 16 else np.uint8)
    assert arr.shape == (48, 64, 3)
    assert read_photo(out).bit_depth == bits


def test_16bit_in_jpeg_out_is_8bit(tmp_path, capsys):
    src = write_photo(tmp_path / "in.png", textured_photo(48, 64), bit_depth=16)
    status, _, _ = run([src, "-o", tmp_path / "out.jpg"], capsys)
    assert status == 0
    assert read_photo(tmp_path / "out.jpg").bit_depth == 8


@pytest.mark.parametrize("shape", [["--renderer", "gather", "--kernel", "disk"], ["--aperture", "hexagon"]])
def test_grey_jpeg_stays_grey_and_same_size(shape, tmp_path, capsys):
    from PIL import Image

    src = write_photo(tmp_path / "g.jpg", textured_photo(48, 64)[..., 1])
    status, out, _ = run([src, "--factor", "3", *shape], capsys)
    assert status == 0
    with Image.open(out.strip()) as im:
        assert im.mode == "L" and im.size == (64, 48) and im.format == "JPEG"


def test_exr_in_exr_out(tmp_path, capsys):
    import OpenEXR

    src = write_photo(tmp_path / "in.exr", textured_photo(48, 64))
    status, out, _ = run([src], capsys)
    assert status == 0
    assert Path(out.strip()).name == "in.magnified-x2.exr"
    rgb = OpenEXR.File(out.strip()).channels()["RGB"].pixels
    assert rgb.shape == (48, 64, 3) and rgb.dtype == np.float32 and np.all(np.isfinite(rgb))


def test_exif_orientation_respected(tmp_path, capsys):
    from PIL import Image

    img = (textured_photo(48, 64) * 255).astype(np.uint8)
    im = Image.fromarray(img)
    exif = im.getexif()
    exif[0x0112] = 6  # stored landscape, displayed portrait
    im.save(tmp_path / "rot.jpg", exif=exif.tobytes(), quality=95)
    status, out, _ = run([tmp_path / "rot.jpg", "--factor", "1.5"], capsys)
    assert status == 0
    with Image.open(out.strip()) as res:
        assert res.size == (48, 64)  # upright: W×H swapped
        assert res.getexif().get(0x0112, 1) == 1


def test_factor_one_is_identity(tmp_path, photo, capsys):
    status, _, _ = run([photo, "--factor", "1", "-o", tmp_path / "same.png"], capsys)
    assert status == 0
    np.testing.assert_array_equal(read_photo(tmp_path / "same.png").image, read_photo(photo).image)


def test_constant_image_unchanged_with_warning(tmp_path, capsys):
    src = write_photo(tmp_path / "flat.png", np.full((40, 50, 3), 0.3))
    status, out, err = run([src, "--factor", "4"], capsys)
    assert status == 0
    assert any("warning: no edges" in line for line in err)
    np.testing.assert_array_equal(read_photo(out.strip()).image, read_photo(src).image)


def test_second_factor_reuses_cached_map_and_save_map(tmp_path, photo, capsys):
    status, _, err = run([photo, "--factor", "2", "--save-map", tmp_path / "m.npy"], capsys)
    assert status == 0 and not any("reused" in line for line in err)
    status, _, err = run([photo, "--factor", "3", "--save-map", tmp_path / "m2.npy"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)
    np.testing.assert_array_equal(np.load(tmp_path / "m.npy"), np.load(tmp_path / "m2.npy"))
    a = read_photo(tmp_path / "photo.magnified-x2.png").image
    b = read_photo(tmp_path / "photo.magnified-x3.png").image
    assert not np.array_equal(a, b)


def test_working_resolution_path(tmp_path, photo, capsys):
    status, _, err = run([photo, "--max-working-pixels", "3000", "-o", tmp_path / "o.png"], capsys)
    assert status == 0
    assert any("estimating at" in line for line in err)
    assert read_photo(tmp_path / "o.png").image.shape == (96, 128, 3)


def test_default_preset_is_robust_and_says_so(tmp_path, photo, capsys):
    status, _, err = run([photo, "-o", tmp_path / "d.png", "--save-map", tmp_path / "d.npy"], capsys)
    assert status == 0, err
    assert [line for line in err if "preset:" in line] == [
        f"{PROG}: preset: robust (beyond the paper; --preset paper for the literal reproduction)"]
    # and which edge-response model measured the blur (this photo is Gaussian-blurred)
    assert [line for line in err if "blur model" in line] == [
        f"{PROG}: blur model at the edges: Gaussian, Eq. (2c) of the paper (chosen for this photo by fit_psf='auto')"]
    status, _, err = run([photo, "-o", tmp_path / "r.png", "--preset", "robust"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)
    np.testing.assert_array_equal(read_photo(tmp_path / "d.png").image, read_photo(tmp_path / "r.png").image)
    status, _, err = run([photo, "-o", tmp_path / "q.png", "-q"], capsys)
    assert status == 0 and err == []


def test_presets_paper_and_robust_round_trip(tmp_path, photo, capsys):
    from method import DefocusParams
    from method.pipeline import estimate_defocus_map

    maps, results = {}, {}
    for name in ("paper", "robust"):
        out, saved = tmp_path / f"{name}.png", tmp_path / f"{name}.npy"
        status, stdout, err = run([photo, "-o", out, "--save-map", saved, "--preset", name], capsys)
        assert status == 0, err
        assert stdout.strip() == str(out)
        assert any(line.startswith(f"{PROG}: preset: {name} (") for line in err), err
        maps[name], results[name] = np.load(saved), read_photo(out).image
        assert results[name].shape == (96, 128, 3)
    assert not np.array_equal(maps["paper"], maps["robust"])
    assert not np.array_equal(results["paper"], results["robust"])
    # the photo is below the working-resolution budget: the map is the pipeline's on the decoded photo
    expected = estimate_defocus_map(read_photo(photo).image, DefocusParams()).defocus_map
    np.testing.assert_array_equal(maps["paper"], expected)


def test_preset_zhuo_sim_runs(tmp_path, capsys):
    small = write_photo(tmp_path / "small.png", textured_photo(48, 64))  # matting propagation: keep it small
    status, stdout, err = run([small, "-o", tmp_path / "z.png", "--preset", "zhuo_sim"], capsys)
    assert status == 0, err
    assert stdout.strip() == str(tmp_path / "z.png")
    assert any(line.startswith(f"{PROG}: preset: zhuo_sim (Zhuo & Sim 2011") for line in err), err
    assert read_photo(tmp_path / "z.png").image.shape == (48, 64, 3)


def test_unknown_preset_is_one_line_exit_2(tmp_path, photo, capsys):
    from method import PRESETS

    argv = [photo, "-o", tmp_path / "o.png", "--save-map", tmp_path / "m.npy", "--preset", "magic"]
    status, out, err = run(argv, capsys)
    assert_one_line_error(status, err, "--preset", "magic", *PRESETS)
    assert out == "" and not (tmp_path / "o.png").exists() and not (tmp_path / "m.npy").exists()


@pytest.mark.parametrize("factor,needles", [
    ("0", ["--factor", ">= 1"]),
    ("-2", ["--factor", ">= 1"]),
    ("abc", ["not a number"]),
    ("nan", ["finite"]),
    ("inf", ["finite"]),
    ("0.5", ["deblurring"]),
])
def test_bad_factor(factor, needles, tmp_path, photo, capsys):
    status, out, err = run([photo, "--factor", factor, "-o", tmp_path / "o.png"], capsys)
    assert_one_line_error(status, err, *needles)
    assert out == "" and not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("argv,needles", [
    (["--kernel", "hexagon"], ["--kernel", "gaussian"]),
    (["--estimator", "magic"], ["--estimator", "model_fit"]),
    (["--bit-depth", "12"], ["bit-depth"]),
    (["--tile-pixels", "x"], ["tile-pixels"]),
])
def test_bad_options(argv, needles, tmp_path, photo, capsys):
    status, _, err = run([photo, "-o", tmp_path / "o.png", *argv], capsys)
    assert_one_line_error(status, err, *needles)


def test_output_equal_to_input(tmp_path, photo, capsys):
    before = photo.read_bytes()
    status, _, err = run([photo, "-o", photo], capsys)
    assert_one_line_error(status, err, "is the input photo", "--overwrite")
    assert photo.read_bytes() == before
    status, _, _ = run([photo, "-o", photo, "--overwrite"], capsys)
    assert status == 0 and photo.read_bytes() != before


def test_bad_outputs(tmp_path, photo, capsys):
    status, _, err = run([photo, "-o", tmp_path / "no" / "o.png"], capsys)
    assert_one_line_error(status, err, "does not exist")
    status, _, err = run([photo, "-o", tmp_path / "o.gif"], capsys)
    assert_one_line_error(status, err, "extension", ".jpg")
    status, _, err = run([photo, "-o", tmp_path / "o.png", "--save-map", tmp_path / "o.png"], capsys)
    assert_one_line_error(status, err, "--save-map")
    status, _, err = run([photo, "-o", tmp_path / "o.png", "--save-map", tmp_path / "m.jpg"], capsys)
    assert_one_line_error(status, err, "--save-map", ".exr")
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("kind", ["missing", "directory", "empty", "truncated_jpeg", "text_png", "1x1", "5x5", "100MP"])
def test_bad_photo(kind, tmp_path, capsys):
    from tests.test_estimate_cli import _make_bad

    path, needles = _make_bad(kind, tmp_path)
    status, out, err = run([path, "-o", tmp_path / "o.png"], capsys)
    assert_one_line_error(status, err, *needles)
    assert not (tmp_path / "o.png").exists()


def test_subprocess_bad_factor_no_traceback(tmp_path, photo):
    env = dict(os.environ, DEFOCUS_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-m", "repro.magnify", str(photo), "--factor", "zero"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(f"{PROG}: error:")


def test_floor_subtract_keeps_the_sharp_half_closer_to_the_photo(tmp_path, photo, capsys):
    """--floor subtract removes the map's in-focus floor (Sec. 5, other reading): the sharp left half
    changes less than with the literal --floor clamp; the blurry right half still gets blurrier."""
    src = read_photo(photo).image
    res = {}
    for mode in ("clamp", "subtract"):
        # the paper's map (its in-focus floor is what Sec. 5's two readings differ on; robust's map
        # reaches 0 in focus, where both readings agree)
        status, _, err = run([photo, "--preset", "paper", "--floor", mode, "-o", tmp_path / f"{mode}.png"], capsys)
        assert status == 0, err
        res[mode] = read_photo(tmp_path / f"{mode}.png").image
    def err_sharp(a):
        return float(np.mean(np.abs(a[:, :56] - src[:, :56])))
    assert err_sharp(res["subtract"]) < err_sharp(res["clamp"])

    def energy(a):
        return float(np.sum(np.diff(a, axis=1) ** 2))
    assert energy(res["subtract"][:, 72:]) < energy(src[:, 72:])


def test_bad_floor_is_one_line_exit_2(tmp_path, photo, capsys):
    status, out, err = run([photo, "--floor", "zero", "-o", tmp_path / "o.png"], capsys)
    assert_one_line_error(status, err, "--floor", "clamp", "subtract")
    assert out == "" and not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("factor", ["1e9", "1e300"])
def test_huge_factor_is_one_line_exit_2(factor, tmp_path, photo, capsys):
    """--factor 1e9 used to be accepted and killed for memory: the extra blur σ is bounded by the image size."""
    status, out, err = run([photo, "--factor", factor, "-q", "-o", tmp_path / "o.png"], capsys)
    assert_one_line_error(status, err, "--factor", "too large", "allowed: factor <=")
    assert out == "" and not (tmp_path / "o.png").exists()


def test_largest_allowed_factor_works_and_just_above_is_refused(tmp_path, photo, capsys):
    import re

    status, _, err = run([photo, "--factor", "1e6", "-q", "-o", tmp_path / "o.png"], capsys)
    k_max = float(re.search(r"factor <= ([0-9.e+]+)", err[-1]).group(1))
    assert 1 < k_max < 1e6
    status, _, _ = run([photo, "--factor", f"{k_max * 0.99:.6g}", "-o", tmp_path / "ok.png"], capsys)
    assert status == 0 and (tmp_path / "ok.png").exists()
    status, _, err = run([photo, "--factor", f"{k_max * 1.01:.6g}", "-q", "-o", tmp_path / "no.png"], capsys)
    assert_one_line_error(status, err, "too large")
    assert not (tmp_path / "no.png").exists()


@pytest.mark.slow  # subprocesses or a benchmark run: in make test, not in make test-fast
def test_huge_factor_subprocess_under_a_memory_limit(tmp_path, photo):
    """In a process limited to 3 GiB of address space the refusal is quick and clean (no MemoryError, no kill)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    env = dict(os.environ, DEFOCUS_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-m", "repro.magnify", str(photo), "--factor", "1e9", "-q",
                           "-o", str(tmp_path / "o.png")], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300, preexec_fn=limit)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "too large" in proc.stderr and "Traceback" not in proc.stderr


def test_magnify_api_bounds_the_extra_blur():
    from method.magnify.magnification import magnify_defocus
    from method.magnify.upsampling import magnify_defocus_tiled

    img = textured_photo(48, 64)
    m = np.full((48, 64), 2.0)
    with pytest.raises(ValueError, match="factor 1e\\+09 is too large"):
        magnify_defocus(img, m, factor=1e9, preprocess=False)
    with pytest.raises(ValueError, match="too large"):
        magnify_defocus_tiled(np.tile(img, (6, 6, 1)), np.full((288, 384), 2.0), factor=1e9, preprocess=False,
                              tile_pixels=256 * 256)
    # σ_e = √(k² − 1)·2 px = 64 px (the longer side): allowed, just above refused
    k = float(np.sqrt(1 + 32.0**2))
    assert magnify_defocus(img, m, factor=k * 0.999, preprocess=False).shape == img.shape
    with pytest.raises(ValueError, match="too large"):
        magnify_defocus(img, m, factor=k * 1.01, preprocess=False)
    # a tiny image may be blurred past its size, up to MIN_EXTRA_SIGMA_LIMIT
    from method.magnify.magnification import MIN_EXTRA_SIGMA_LIMIT

    tiny, mt = img[:8, :8], np.full((8, 8), 2.0)
    k_tiny = float(np.sqrt(1 + (MIN_EXTRA_SIGMA_LIMIT / 2.0) ** 2))
    assert magnify_defocus(tiny, mt, factor=k_tiny * 0.999, preprocess=False).shape == tiny.shape
    with pytest.raises(ValueError, match="too large"):
        magnify_defocus(tiny, mt, factor=k_tiny * 1.01, preprocess=False)
