"""python -m repro.magnify: the subject (--focus-point, --keep-sharp), front and back (--depth) and their bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from repro.magnify import PROG, main
from repro.photo_io import read_photo, write_photo
from tests.photo_cli import cache_dir, cli_runner, photo, textured_photo  # noqa: F401 (fixtures)

H, W = 96, 128


@pytest.fixture
def sigma_map(tmp_path):
    """σ 0 px on the left half, 3 px on the right (the textured photo's blurred half)."""
    m = np.zeros((H, W))
    m[:, W // 2:] = 3.0
    np.save(tmp_path / "map.npy", m)
    return tmp_path / "map.npy"


pytestmark = pytest.mark.usefixtures("cache_dir")

run, assert_one_line_error = cli_runner(main, PROG)


class Recorder:
    """Stands in for a magnifier function; records the keyword arguments it is given and calls the real one."""

    def __init__(self, real):
        self.real, self.calls = real, []

    def __call__(self, *args, **kwargs):
        self.calls.append({"focus_point": kwargs.get("focus_point"), "keep_sharp": kwargs.get("keep_sharp"),
                           "in_front": kwargs.get("in_front"), "shape": np.shape(args[0])})
        return self.real(*args, **kwargs)


@pytest.fixture
def recorder(monkeypatch):
    import method.magnify.magnification as magnification

    rec = Recorder(magnification.magnify_defocus)
    monkeypatch.setattr(magnification, "magnify_defocus", rec)
    return rec


@pytest.fixture
def prep_recorder(monkeypatch):
    """Records the Sec. 5 preprocessing's calls, which take the subject (focus point, mask)."""
    import method.magnify.magnification as magnification

    rec = Recorder(magnification.preprocess_defocus_map)
    monkeypatch.setattr(magnification, "preprocess_defocus_map", rec)
    return rec


def _outputs(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("out"))


# ------------------------------------------------------------------------------------------------
# --focus-point, --keep-sharp
# ------------------------------------------------------------------------------------------------


def test_focus_point_and_mask_reach_the_preprocessing_under_their_names(tmp_path, photo, sigma_map, prep_recorder,
                                                                        capsys):
    mask = np.zeros((H, W), np.uint8)
    mask[10:40, 10:50] = 255
    write_photo(tmp_path / "mask.png", mask / 255.0)
    status, _, err = run([photo, "--map", sigma_map, "--focus-point", "20,30", "--keep-sharp", tmp_path / "mask.png",
                          "-o", tmp_path / "out.png"], capsys)
    assert status == 0, err
    (call,) = prep_recorder.calls
    assert call["focus_point"] == (20, 30)
    assert call["keep_sharp"].shape == (H, W)
    np.testing.assert_array_equal(call["keep_sharp"] > 0.5, mask > 0)


def test_the_mask_keeps_its_pixels_unchanged(tmp_path, photo, capsys):
    """No blur is added under the mask, even where the map is blurry."""
    m = np.full((H, W), 3.0)  # everything blurry
    np.save(tmp_path / "flat.npy", m)
    mask = np.zeros((H, W))
    mask[20:70, 20:100] = 1.0
    write_photo(tmp_path / "mask.png", mask)
    status, _, err = run([photo, "--map", tmp_path / "flat.npy", "--floor", "clamp", "--keep-sharp",
                          tmp_path / "mask.png", "-o", tmp_path / "out.png"], capsys)
    assert status == 0, err
    src, res = read_photo(photo).image, read_photo(tmp_path / "out.png").image
    inside = np.abs(res - src)[30:60, 30:90]
    outside = np.abs(res - src)[:, :10]
    assert inside.max() <= 1.5 / 255  # unchanged up to 8-bit rounding
    assert outside.mean() > 0.02      # the rest is blurred


def test_mask_of_the_photos_aspect_ratio_is_resized(tmp_path, photo, sigma_map, prep_recorder, capsys):
    small = np.zeros((H // 2, W // 2))
    small[5:20, 5:25] = 1.0
    write_photo(tmp_path / "mask.png", small)
    status, _, err = run([photo, "--map", sigma_map, "--keep-sharp", tmp_path / "mask.png", "-o", tmp_path / "out.png"],
                         capsys)
    assert status == 0, err
    assert prep_recorder.calls[0]["keep_sharp"].shape == (H, W)


@pytest.mark.parametrize("args,needles", [
    (["--focus-point", "500,10"], ["--focus-point 500,10", "outside", "0 <= X <= 127", "0 <= Y <= 95"]),
    (["--focus-point", "10,-1"], ["outside", "0 <= Y <= 95"]),
    (["--focus-point", "ten"], ["not two numbers", "allowed"]),
    (["--focus-point", "1,2,3"], ["not two numbers"]),
    (["--keep-sharp", "MASK_OTHER"], ["--keep-sharp", "50x50 px does not fit the photo's 128x96", "allowed"]),
    (["--keep-sharp", "MASK_BLACK"], ["no pixel is set", "allowed"]),
    (["--keep-sharp", "MASK_EXR"], ["holds light, not a mask", "allowed"]),
    (["--keep-sharp", "missing.png"], ["--keep-sharp", "no such file"]),
    (["--depth", "DEPTH_NAN"], ["--depth", "3 non-finite values (NaN)", "allowed: a finite depth"]),
    (["--depth", "DEPTH_OTHER"], ["--depth", "100x40 px does not fit", "aspect ratio"]),
    (["--depth", "depth.txt"], ["--depth", "allowed: .npy, .npz, .exr"]),
    (["--depth", "DEPTH_OK", "--renderer", "gather"], ["--depth applies to the scatter renderer", "allowed"]),
    (["--html", "page.txt"], ["--html", "allowed: a file name ending in .html"]),
])
def test_bad_subject_input_is_one_line_and_nothing_is_written(tmp_path, photo, sigma_map, args, needles, capsys):
    write_photo(tmp_path / "mask_other.png", np.ones((50, 50)))
    write_photo(tmp_path / "mask_black.png", np.zeros((H, W)))
    write_photo(tmp_path / "mask.exr", np.ones((H, W)))
    nan = np.ones((H, W))
    nan[1, 1:4] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    np.save(tmp_path / "other.npy", np.ones((40, 100)))
    np.save(tmp_path / "ok.npy", np.ones((H, W)))
    (tmp_path / "depth.txt").write_text("1 2 3")
    names = {"MASK_OTHER": "mask_other.png", "MASK_BLACK": "mask_black.png", "MASK_EXR": "mask.exr",
             "DEPTH_NAN": "nan.npy", "DEPTH_OTHER": "other.npy", "DEPTH_OK": "ok.npy"}
    args = [str(tmp_path / names[a]) if a in names else (str(tmp_path / a) if "." in a and a[0].isalpha() else a)
            for a in args]
    status, _, err = run([photo, "--map", sigma_map, "-o", tmp_path / "out.png", "--save-map", tmp_path / "out.npy",
                          "--html", tmp_path / "out.html", *args], capsys)
    assert_one_line_error(status, err, *needles)
    assert _outputs(tmp_path) == []


# ------------------------------------------------------------------------------------------------
# front and back
# ------------------------------------------------------------------------------------------------


def test_default_assumption_is_said(tmp_path, photo, sigma_map, recorder, capsys):
    status, _, err = run([photo, "--map", sigma_map, "-o", tmp_path / "out.png"], capsys)
    assert status == 0
    assert any("a blurrier pixel is taken to lie behind the subject" in line for line in err), err
    assert recorder.calls[0]["in_front"] is None
    status, _, err = run([photo, "--map", sigma_map, "-o", tmp_path / "out2.png", "--renderer", "gather"], capsys)
    assert status == 0 and not any("front and back" in line for line in err)  # the gather has no occlusion


def test_depth_marks_what_is_nearer_than_the_focus_depth(tmp_path, photo, sigma_map, recorder, capsys):
    depth = np.full((H, W), 3.0)  # metres: the subject at 3 m, a foreground strip at 1 m, a far wall at 9 m
    depth[:, :20] = 1.0
    depth[:, 100:] = 9.0
    np.save(tmp_path / "depth.npy", depth)
    status, _, err = run([photo, "--map", sigma_map, "--depth", tmp_path / "depth.npy", "--focus-point", "60,40",
                          "-o", tmp_path / "out.png"], capsys)
    assert status == 0, err
    np.testing.assert_array_equal(recorder.calls[0]["in_front"], depth < 3.0)
    assert any("front and back from --depth: 15.6% of the pixels in front of the focus depth 3" in line
               and "--focus-point 60,40" in line for line in err), err
    # focused on the far wall instead: the subject plane is in front too
    run([photo, "--map", sigma_map, "--depth", tmp_path / "depth.npy", "--focus-point", "120,40",
         "-o", tmp_path / "out2.png"], capsys)
    np.testing.assert_array_equal(recorder.calls[1]["in_front"], depth < 9.0)


def test_depth_of_half_size_is_resized_and_read_where_the_map_is_sharpest(tmp_path, photo, recorder, capsys):
    sigma = np.full((H, W), 3.0)
    sigma[:, 40:80] = 0.2  # the sharp subject
    np.save(tmp_path / "map.npy", sigma)
    signed = np.full((H // 2, W // 2), 2.0)  # signed defocus: negative in front, 0 at the subject, positive behind
    signed[:, 20:40] = 0.0
    signed[:, :10] = -2.0
    np.save(tmp_path / "signed.npy", signed)
    status, _, err = run([photo, "--map", tmp_path / "map.npy", "--depth", tmp_path / "signed.npy",
                          "-o", tmp_path / "out.png"], capsys)
    assert status == 0, err
    assert any("--depth" in line and "resized to the photo's 128x96" in line for line in err), err
    assert any("sharpest" in line for line in err), err
    in_front = recorder.calls[0]["in_front"]
    assert in_front[:, :18].all() and not in_front[:, 22:].any()


def test_front_back_tolerance_both_sides():
    from repro._magnify_inputs import front_back

    rng = np.random.default_rng(0)
    depth = 5.0 + 0.01 * rng.standard_normal((60, 80))  # a rough subject plane at 5 m
    depth[:, :10] = 4.5                                    # a foreground well in front
    fb = front_back(depth, focus_point=(50, 30))
    assert fb.focus_depth == pytest.approx(5.0, abs=0.01)
    assert fb.in_front[:, :10].all()                       # in front: beyond the tolerance
    assert fb.in_front[:, 10:].mean() < 0.01               # the subject's own roughness is not a foreground
    assert 0.02 < fb.tolerance < 0.1
    with pytest.raises(ValueError, match="focus_point or sigma"):
        front_back(depth)
