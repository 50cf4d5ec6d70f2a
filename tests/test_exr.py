"""Float32 multi-channel EXR round trip (scenes/exr.py)."""

import numpy as np
import pytest

from scenes.exr import read_exr, write_exr


def _bits(a):
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def test_round_trip_bit_exact_with_inf_nan(tmp_path, rng):
    h, w = 7, 11
    rgb = rng.normal(size=(h, w, 3)).astype(np.float32) * 10
    rgb[0, 0] = [np.inf, -np.inf, 1e-42]  # inf and a float32 subnormal
    z = rng.uniform(0.1, 5, size=(h, w)).astype(np.float32)
    z[3, :] = np.inf
    coc = rng.uniform(0, 30, size=(h, w)).astype(np.float32)
    coc[1, 1] = np.nan
    sigma = np.float32(-0.0) * np.ones((h, w), np.float32)
    mask = rng.random((h, w)) > 0.5
    path = tmp_path / "r.exr"
    write_exr(path, {"RGB": rgb, "Z": z, "coc": coc, "sigma": sigma, "occlusion_boundary": mask})
    back = read_exr(path)
    assert set(back) == {"RGB", "Z", "coc", "sigma", "occlusion_boundary"}
    for name, a in (("RGB", rgb), ("Z", z), ("coc", coc), ("sigma", sigma)):
        assert back[name].dtype == np.float32 and back[name].shape == a.shape
        np.testing.assert_array_equal(_bits(back[name]), _bits(a))
    np.testing.assert_array_equal(back["occlusion_boundary"], mask.astype(np.float32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.exr"]  # no temporary left


def test_float64_input_is_stored_as_float32(tmp_path):
    a = np.linspace(0, 1, 12).reshape(3, 4)
    write_exr(tmp_path / "a.exr", {"Z": a})
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr")["Z"], a.astype(np.float32))


def test_overwrite_is_atomic(tmp_path):
    p = tmp_path / "a.exr"
    write_exr(p, {"Z": np.zeros((2, 2))})
    write_exr(p, {"Z": np.ones((2, 2))})
    assert read_exr(p)["Z"].sum() == 4
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.exr"]


@pytest.mark.parametrize(
    "channels",
    [
        {},
        {"Z": np.zeros((2, 2)), "coc": np.zeros((3, 2))},
        {"Z": np.zeros((2, 2, 2))},
        {"Z": np.zeros(5)},
    ],
)
def test_bad_channels_rejected(tmp_path, channels):
    with pytest.raises(ValueError):
        write_exr(tmp_path / "bad.exr", channels)
    assert not (tmp_path / "bad.exr").exists()


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_exr(tmp_path / "none.exr")
    with pytest.raises(FileNotFoundError):
        write_exr(tmp_path / "no" / "a.exr", {"Z": np.zeros((2, 2))})
