"""python -m repro.estimate: outputs, bad input (one stderr line, exit 2), working resolution, cache.

Most cases call the CLI in-process (same code path as ``python -m``, much faster); a few run it
as a real subprocess to prove there is no traceback and to exercise two processes at once.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from repro.estimate import PROG, main
from repro.photo_io import write_photo
from tests.photo_cli import cache_dir, cli_runner, photo, textured_photo  # noqa: F401 (fixtures)

ROOT = Path(__file__).resolve().parents[1]


run, assert_one_line_error = cli_runner(main, PROG)


# ------------------------------------------------------------------------------------------------
# outputs
# ------------------------------------------------------------------------------------------------


def test_exr_npy_png_outputs(tmp_path, photo, cache_dir, capsys):
    import OpenEXR
    from PIL import Image

    status, out, err = run([photo, "-o", tmp_path / "m.exr"], capsys)
    assert status == 0, err
    assert out.strip() == str(tmp_path / "m.exr")
    sigma = OpenEXR.File(str(tmp_path / "m.exr")).channels()["sigma"].pixels
    assert sigma.shape == (96, 128) and sigma.dtype == np.float32
    assert np.all(np.isfinite(sigma)) and sigma.min() >= 0
    # the blurred right half must read blurrier than the sharp left half
    assert np.median(sigma[:, 80:]) > np.median(sigma[:, :48])

    status, _, err = run([photo, "-o", tmp_path / "m.npy"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)
    raw = np.load(tmp_path / "m.npy")
    assert raw.dtype == np.float64
    np.testing.assert_array_equal(raw.astype(np.float32), sigma)

    status, _, _ = run([photo, "-o", tmp_path / "m.png"], capsys)
    assert status == 0
    with Image.open(tmp_path / "m.png") as im:
        assert im.format == "PNG" and im.size[0] > 200


def test_default_output_next_to_photo(photo, cache_dir, capsys):
    status, out, _ = run([photo], capsys)
    assert status == 0
    assert Path(out.strip()) == photo.with_name("photo.defocus.exr")
    assert photo.with_name("photo.defocus.exr").is_file()


def test_help_mentions_default_output(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "<stem>.defocus.exr" in text and "--max-working-pixels" in text


def test_constant_image_zero_map_warning(tmp_path, cache_dir, capsys):
    path = write_photo(tmp_path / "flat.png", np.full((40, 50, 3), 0.4))
    status, _, err = run([path, "-o", tmp_path / "m.npy"], capsys)
    assert status == 0
    assert any("warning: no edges" in line for line in err)
    m = np.load(tmp_path / "m.npy")
    assert m.shape == (40, 50) and not np.any(m)
    # the warning survives a cache hit
    status, _, err = run([path, "-o", tmp_path / "m2.npy"], capsys)
    assert status == 0 and any("warning: no edges" in line for line in err)


def test_rgba_input_note(tmp_path, cache_dir, capsys):
    from PIL import Image

    rgba = np.concatenate([textured_photo(32, 40), np.ones((32, 40, 1))], axis=-1)
    Image.fromarray((rgba * 255).astype(np.uint8), "RGBA").save(tmp_path / "a.png")
    status, _, err = run([tmp_path / "a.png", "-o", tmp_path / "m.npy"], capsys)
    assert status == 0
    assert any("alpha channel ignored" in line for line in err)


def test_exr_input_nonfinite_refused_then_repaired(tmp_path, cache_dir, capsys):
    import OpenEXR

    from scenes.display import srgb_to_linear

    lin = srgb_to_linear(textured_photo(32, 40)).astype(np.float32)
    lin[5, 5, 0] = np.nan
    lin[6, 6, 1] = np.inf
    path = tmp_path / "bad.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": lin}).write(str(path))
    status, _, err = run([path, "-o", tmp_path / "m.npy"], capsys)
    assert_one_line_error(status, err, "NaN/Inf", "--repair-nonfinite")
    assert not (tmp_path / "m.npy").exists()
    status, _, err = run([path, "-o", tmp_path / "m.npy", "--repair-nonfinite"], capsys)
    assert status == 0 and any("repaired 2" in line for line in err)
    assert np.all(np.isfinite(np.load(tmp_path / "m.npy")))


def test_working_resolution_is_announced_and_map_is_full_size(tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "m.npy", "--max-working-pixels", "3000"], capsys)
    assert status == 0
    line = next(line for line in err if "max-working-pixels" in line)
    assert "estimating at" in line and "guided filter" in line
    m = np.load(tmp_path / "m.npy")
    assert m.shape == (96, 128) and np.all(np.isfinite(m)) and m.min() >= 0
    # a cached working-resolution map is upsampled as a fresh one is: the same bytes
    status, _, err = run([photo, "-o", tmp_path / "again.npy", "--max-working-pixels", "3000"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)
    np.testing.assert_array_equal(np.load(tmp_path / "again.npy"), m)


def test_estimator_and_alpha_change_the_map(tmp_path, photo, cache_dir, capsys):
    assert run([photo, "-o", tmp_path / "a.npy"], capsys)[0] == 0
    assert run([photo, "-o", tmp_path / "b.npy", "--estimator", "zero_crossing"], capsys)[0] == 0
    assert run([photo, "-o", tmp_path / "c.npy", "--alpha", "0.1"], capsys)[0] == 0
    a, b, c = (np.load(tmp_path / f"{n}.npy") for n in "abc")
    assert not np.array_equal(a, b) and not np.array_equal(a, c)
    assert len([p for p in (cache_dir / "maps").iterdir() if p.is_dir()]) == 3


# ------------------------------------------------------------------------------------------------
# --preset (registry method.PRESETS; default robust)
# ------------------------------------------------------------------------------------------------


def test_default_preset_is_robust_and_says_so(tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "d.npy"], capsys)
    assert status == 0, err
    assert [line for line in err if "preset:" in line] == [
        f"{PROG}: preset: robust (beyond the paper; --preset paper for the literal reproduction)"]
    status, _, err = run([photo, "-o", tmp_path / "r.npy", "--preset", "robust"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)  # same parameters
    np.testing.assert_array_equal(np.load(tmp_path / "d.npy"), np.load(tmp_path / "r.npy"))
    status, _, err = run([photo, "-o", tmp_path / "q.npy", "-q"], capsys)
    assert status == 0 and err == []  # -q: not even the preset line


def test_presets_paper_and_robust_round_trip(tmp_path, photo, cache_dir, capsys):
    from method import DefocusParams
    from method.pipeline import estimate_defocus_map
    from method.magnify.upsampling import DEFAULT_MAX_WORKING_PIXELS
    from repro.photo_io import read_photo

    maps = {}
    for name in ("paper", "robust"):
        out = tmp_path / f"{name}.npy"
        status, stdout, err = run([photo, "-o", out, "--preset", name], capsys)
        assert status == 0, err
        assert stdout.strip() == str(out)
        assert any(line.startswith(f"{PROG}: preset: {name} (") for line in err), err
        maps[name] = np.load(out)
        assert maps[name].shape == (96, 128) and np.all(np.isfinite(maps[name])) and maps[name].min() >= 0
    assert not np.array_equal(maps["paper"], maps["robust"])
    # 96x128 is below the working-resolution budget: the tool estimates the decoded photo as is
    image = read_photo(photo).image
    assert image.shape[0] * image.shape[1] <= DEFAULT_MAX_WORKING_PIXELS
    np.testing.assert_array_equal(maps["paper"], estimate_defocus_map(image, DefocusParams()).defocus_map)
    # the cache is keyed by the full parameter set: one entry per preset, the name recorded
    entries = [p for p in (cache_dir / "maps").iterdir() if p.is_dir() and not p.name.startswith(".")]
    assert sorted(json.loads((e / "meta.json").read_text())["preset"] for e in entries) == ["paper", "robust"]


def test_preset_zhuo_sim_runs(tmp_path, cache_dir, capsys):
    small = write_photo(tmp_path / "small.png", textured_photo(48, 64))  # matting propagation: keep it small
    status, stdout, err = run([small, "-o", tmp_path / "z.npy", "--preset", "zhuo_sim"], capsys)
    assert status == 0, err
    assert stdout.strip() == str(tmp_path / "z.npy")
    assert any(line.startswith(f"{PROG}: preset: zhuo_sim (Zhuo & Sim 2011") for line in err), err
    z = np.load(tmp_path / "z.npy")
    assert z.shape == (48, 64) and np.all(np.isfinite(z)) and z.min() >= 0


def test_preset_with_override_is_its_own_cache_entry(tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "a.npy", "--preset", "paper", "--alpha", "0.1"], capsys)
    assert status == 0
    assert f"{PROG}: preset: paper (the literal reproduction of Bae & Durand 2007), with --alpha 0.1" in err
    assert run([photo, "-o", tmp_path / "b.npy", "--preset", "paper"], capsys)[0] == 0
    assert not np.array_equal(np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy"))
    assert len([p for p in (cache_dir / "maps").iterdir() if p.is_dir()]) == 2


def test_unknown_preset_is_one_line_exit_2(tmp_path, photo, cache_dir, capsys):
    from method import PRESETS

    status, stdout, err = run([photo, "-o", tmp_path / "m.npy", "--preset", "magic"], capsys)
    assert_one_line_error(status, err, "--preset", "magic", *PRESETS)
    assert stdout == "" and not (tmp_path / "m.npy").exists() and not (cache_dir / "maps").exists()


def test_presets_come_from_the_registry(monkeypatch, tmp_path, photo, capsys):
    from method import PRESETS, DefocusParams

    monkeypatch.setitem(PRESETS, "test_only", DefocusParams(alpha=0.25))
    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert all(name in text for name in PRESETS)
    assert "test_only (changes alpha from the paper)" in text
    status, _, err = run([photo, "-o", tmp_path / "m.npy", "--preset", "nope"], capsys)
    assert_one_line_error(status, err, "test_only", "paper", "robust", "zhuo_sim")


# ------------------------------------------------------------------------------------------------
# bad input: one line on stderr, exit status 2, nothing written
# ------------------------------------------------------------------------------------------------


def _make_bad(kind, tmp_path):
    from tests.test_photo_io import png_with_header

    if kind == "missing":
        return tmp_path / "nope.jpg", ["no such file"]
    if kind == "directory":
        (tmp_path / "dir.png").mkdir()
        return tmp_path / "dir.png", ["directory"]
    if kind == "empty":
        (tmp_path / "e.jpg").write_bytes(b"")
        return tmp_path / "e.jpg", ["empty"]
    if kind == "truncated_jpeg":
        good = write_photo(tmp_path / "g.jpg", textured_photo())
        (tmp_path / "t.jpg").write_bytes(good.read_bytes()[: good.stat().st_size // 2])
        return tmp_path / "t.jpg", ["truncated"]
    if kind == "text_png":
        (tmp_path / "x.png").write_text("hello\n" * 20)
        return tmp_path / "x.png", ["not a recognised image"]
    if kind == "1x1":
        return write_photo(tmp_path / "one.png", np.full((1, 1, 3), 0.5)), ["1x1", "smallest supported side is 8"]
    if kind == "5x5":
        return write_photo(tmp_path / "five.png", np.full((5, 5), 0.5)), ["5x5", "smallest supported side is 8"]
    if kind == "100MP":
        return png_with_header(tmp_path / "huge.png", 10_000, 10_000), ["100.0 MP", "pixel budget"]
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["missing", "directory", "empty", "truncated_jpeg", "text_png", "1x1", "5x5", "100MP"])
def test_bad_photo(kind, tmp_path, cache_dir, capsys):
    path, needles = _make_bad(kind, tmp_path)
    out = tmp_path / "out.npy"
    status, stdout, err = run([path, "-o", out], capsys)
    assert_one_line_error(status, err, *needles)
    assert stdout == "" and not out.exists()


def test_pixel_budget_is_configurable(tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "m.npy", "--max-pixels", "10000"], capsys)
    assert_one_line_error(status, err, "pixel budget")


def test_pillow_bomb_guard_is_one_line(tmp_path, cache_dir, capsys):
    from tests.test_photo_io import png_with_header

    path = png_with_header(tmp_path / "bomb.png", 20_000, 20_000, ctype=3)
    status, _, err = run([path, "-o", tmp_path / "m.npy", "--max-pixels", "1e12"], capsys)
    assert_one_line_error(status, err, "decompression-bomb")


@pytest.mark.parametrize("argv,needles", [
    (["--estimator", "magic"], ["--estimator", "magic", "model_fit"]),
    (["--preset", "magic"], ["--preset", "magic", "paper", "robust", "zhuo_sim"]),
    (["--alpha", "0"], ["--alpha", "> 0"]),
    (["--alpha", "abc"], ["--alpha", "not a number"]),
    (["--alpha", "nan"], ["--alpha"]),
    (["--max-working-pixels", "-5"], ["max-working-pixels"]),
    (["--max-pixels", "lots"], ["max-pixels", "not a pixel count"]),
    (["--no-such-flag"], ["unrecognized"]),
])
def test_bad_options(argv, needles, tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "m.npy", *argv], capsys)
    assert_one_line_error(status, err, *needles)
    assert not (tmp_path / "m.npy").exists()


@pytest.mark.parametrize("where,needles", [
    ("missing_folder", ["does not exist"]),
    ("file_as_folder", ["not a folder"]),
    ("bad_extension", ["extension", ".exr"]),
    ("is_directory", ["directory"]),
])
def test_unwritable_output(where, needles, tmp_path, photo, cache_dir, capsys):
    if where == "missing_folder":
        out = tmp_path / "no" / "m.exr"
    elif where == "file_as_folder":
        (tmp_path / "afile").write_text("x")
        out = tmp_path / "afile" / "m.exr"
    elif where == "bad_extension":
        out = tmp_path / "m.gif"
    else:
        out = tmp_path / "d.exr"
        out.mkdir()
    status, _, err = run([photo, "-o", out], capsys)
    assert_one_line_error(status, err, *needles)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write in a read-only folder")
def test_read_only_folder(tmp_path, photo, cache_dir, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        status, _, err = run([photo, "-o", ro / "m.exr"], capsys)
        assert_one_line_error(status, err, "not writable")
    finally:
        ro.chmod(0o700)


def test_output_equal_to_input_refused_unless_overwrite(tmp_path, cache_dir, capsys):
    path = write_photo(tmp_path / "p.exr", textured_photo(32, 40))
    before = path.read_bytes()
    status, _, err = run([path, "-o", path], capsys)
    assert_one_line_error(status, err, "is the input photo", "--overwrite")
    assert path.read_bytes() == before
    status, _, _ = run([path, "-o", path, "--overwrite"], capsys)
    assert status == 0 and path.read_bytes() != before


def test_no_temp_files_left_after_errors(tmp_path, photo, cache_dir, capsys):
    run([photo, "-o", tmp_path / "m.exr", "--estimator", "x"], capsys)
    run([tmp_path / "nope.png", "-o", tmp_path / "m.exr"], capsys)
    assert not (tmp_path / "m.exr").exists()
    assert not [p for p in tmp_path.iterdir() if ".tmp." in p.name or ".probe." in p.name]


# ------------------------------------------------------------------------------------------------
# real subprocesses: no traceback; cache shared between concurrent processes; corrupt entries
# ------------------------------------------------------------------------------------------------


def _cli(args, cache, **kw):
    env = dict(os.environ, DEFOCUS_CACHE_DIR=str(cache))
    return subprocess.Popen([sys.executable, "-m", "repro.estimate", *map(str, args)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


@pytest.mark.parametrize("kind", ["missing", "text_png", "5x5"])
def test_subprocess_error_is_one_line_without_traceback(kind, tmp_path):
    path, needles = _make_bad(kind, tmp_path)
    proc = _cli([path, "-o", tmp_path / "m.exr"], tmp_path / "cache")
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"{PROG}: error:")


def _entries(cache):
    maps = cache / "maps"
    return [p for p in maps.iterdir() if p.is_dir() and not p.name.startswith(".")] if maps.exists() else []


@pytest.mark.slow  # subprocesses or a benchmark run: in make test, not in make test-fast
def test_two_processes_share_one_cache_entry(tmp_path):
    photo = write_photo(tmp_path / "photo.png", textured_photo())
    cache = tmp_path / "cache"
    procs = [_cli([photo, "-o", tmp_path / f"m{i}.npy", "-q"], cache) for i in range(2)]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], results
    np.testing.assert_array_equal(np.load(tmp_path / "m0.npy"), np.load(tmp_path / "m1.npy"))
    entries = _entries(cache)
    assert len(entries) == 1
    from defocus_cache import Cache

    manifest = json.loads((entries[0] / "manifest.json").read_text())
    assert Cache(cache / "maps").is_valid(manifest["key"])
    assert not [p for p in (cache / "maps").iterdir() if p.name.endswith(".tmp")]


def test_truncated_cache_entry_is_rebuilt(tmp_path, cache_dir, capsys):
    """A map entry cut short (as a killed writer would leave it) is not read back: estimated again, rewritten
    whole, then reused (in process: the entry is on disk, nothing of it is held in memory)."""
    photo = write_photo(tmp_path / "photo.png", textured_photo())
    status, _, _ = run([photo, "-o", tmp_path / "a.npy"], capsys)
    assert status == 0
    (entry,) = _entries(cache_dir)
    data = (entry / "map.npy").read_bytes()
    (entry / "map.npy").write_bytes(data[: len(data) // 2])  # as a killed writer would leave it
    status, _, err = run([photo, "-o", tmp_path / "b.npy"], capsys)
    assert status == 0
    assert not any("reused from the cache" in line for line in err)  # detected as invalid, so estimated again
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy"))
    assert (entry / "map.npy").read_bytes() == data
    status, _, err = run([photo, "-o", tmp_path / "c.npy"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)


def test_force_re_estimates_and_replaces_the_cached_map(tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "a.npy"], capsys)
    assert status == 0 and not any("reused from the cache" in line for line in err)
    entries = sorted(p.name for p in (cache_dir / "maps").iterdir() if p.is_dir())
    status, _, err = run([photo, "-o", tmp_path / "b.npy", "--force"], capsys)
    assert status == 0 and not any("reused from the cache" in line for line in err)  # estimated again
    assert sorted(p.name for p in (cache_dir / "maps").iterdir() if p.is_dir()) == entries  # same key, replaced
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy"))
    status, _, err = run([photo, "-o", tmp_path / "c.npy"], capsys)
    assert status == 0 and any("reused from the cache" in line for line in err)


def _disk_blurred_photo(h=96, w=128, radius=5.0):
    """textured_photo's blocks, right half blurred by a uniform disk (a thin lens's defocus) in linear light."""
    from scipy.signal import fftconvolve

    from method.luma import to_light
    from tests.photo_cli import textured_photo

    img = to_light(textured_photo(h, w, blur_right=1e-3), "linear", encoding="srgb")
    yy, xx = np.mgrid[-8:9, -8:9]
    k = (xx ** 2 + yy ** 2 <= radius ** 2).astype(float)
    k /= k.sum()
    pad = np.pad(img, ((9, 9), (9, 9), (0, 0)), mode="edge")
    blurred = np.stack([fftconvolve(pad[..., c], k, mode="same")[9:-9, 9:-9] for c in range(3)], axis=-1)
    img[:, w // 2:] = blurred[:, w // 2:]
    return to_light(np.clip(img, 0, 1), "display", encoding="linear")


@pytest.mark.parametrize("preset, blur, want", [
    ("robust", "disk", "blur model at the edges: uniform disk (a thin lens's defocus) (chosen for this photo by fit_psf='auto')"),
    ("robust", "gaussian", "blur model at the edges: Gaussian, Eq. (2c) of the paper (chosen for this photo by fit_psf='auto')"),
    ("paper", "disk", "blur model at the edges: Gaussian, Eq. (2c) of the paper (fit_psf='gaussian')"),
])
def test_the_blur_model_is_said(preset, blur, want, tmp_path, cache_dir, capsys):
    """The photo tools say which edge-response model measured the blur (robust chooses per photo)."""
    img = _disk_blurred_photo() if blur == "disk" else textured_photo()
    src = write_photo(tmp_path / f"{blur}.png", img)
    status, _, err = run([src, "-o", tmp_path / "m.npy", "--preset", preset], capsys)
    assert status == 0, err
    assert [line for line in err if "blur model" in line] == [f"{PROG}: {want}"]
    status, _, err = run([src, "-o", tmp_path / "m2.npy", "--preset", preset], capsys)  # from the cache
    assert status == 0 and [line for line in err if "blur model" in line] == [f"{PROG}: {want}"]


def test_no_blur_model_line_without_a_model_fit(tmp_path, photo, cache_dir, capsys):
    status, _, err = run([photo, "-o", tmp_path / "g.npy", "--estimator", "gradient_ratio"], capsys)
    assert status == 0, err
    assert not any("blur model" in line for line in err), err


def test_psf_line_texts():
    """Every branch of the 'blur model' line: none, one model, and the per-edge mix."""
    from method import DefocusParams
    from repro.estimate import psf_line

    robust = DefocusParams.preset("robust")
    assert psf_line({"psf_model": None}, robust) is None
    assert psf_line({}, robust) is None  # a cache entry written before the line existed
    assert psf_line({"psf_model": "disk"}, robust) == (
        "blur model at the edges: uniform disk (a thin lens's defocus) (chosen for this photo by fit_psf='auto')")
    best = robust.replace(fit_psf="best")
    assert psf_line({"psf_model": "mixed", "measures": 200, "psf_disk_measures": 50}, best) == (
        "blur model at the edges: disk at 25% of the measures, Gaussian at the rest (per edge, fit_psf='best')")
