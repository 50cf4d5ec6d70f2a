"""Highlights that bloom: an EXR's linear light unclipped end to end, and --highlights on display-encoded photos.

The synthetic point: a black photo with one white pixel, blurred with a constant defocus map σ = 3 px
at ×2 (extra blur σ_e = √3 · 3 px): the scatter spreads the point's linear light over a disk whose
per-axis variance is σ_e² and whose radius is :func:`method.magnify.scatter.radius_for_sigma` (σ_e),
keeping its energy.
"""

from __future__ import annotations

import numpy as np
import pytest

from method.luma import ENCODINGS
from repro.magnify import PROG, main
from repro.photo_io import read_photo, write_photo
from repro.photo_io.highlights import DEFAULT_HIGHLIGHT_GAIN, HIGHLIGHT_KNEE, compress_highlights, expand_highlights
from tests.photo_cli import cli_runner, textured_photo
from tests.tolerances import HIGHLIGHT_ENERGY_RTOL, HIGHLIGHT_ROUNDTRIP_ATOL, HIGHLIGHT_VARIANCE_RTOL

N = 65                     # the point photo's side, px
SIGMA = 3.0                # its defocus map, px
SIGMA_E = np.sqrt(3.0) * SIGMA

run, assert_one_line_error = cli_runner(main, PROG)


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(tmp_path / "cache"))


@pytest.fixture
def flat_map(tmp_path):
    np.save(tmp_path / "flat.npy", np.full((N, N), SIGMA))
    return tmp_path / "flat.npy"


def _point(value=1.0, background=0.0):
    img = np.full((N, N, 3), background)
    img[N // 2, N // 2] = value
    return img


def _moments(lin):
    """(energy, per-axis variance px², farthest lit pixel's distance px) of an HxWx3 linear image's green channel."""
    g = lin[..., 1]
    y, x = np.mgrid[:N, :N] - N // 2
    e = g.sum()
    return e, float((g * x * x).sum() / e), float(np.hypot(x, y)[g > 1e-6 * g.max()].max())


def test_curve_is_srgb_below_the_knee_smooth_and_inverted():
    import colour

    v = np.linspace(0.0, 1.0, 2001)
    L = expand_highlights(v)
    below = v <= HIGHLIGHT_KNEE
    np.testing.assert_allclose(L[below], colour.cctf_decoding(v[below], function="sRGB"), atol=1e-7)
    assert L[-1] == pytest.approx(DEFAULT_HIGHLIGHT_GAIN)
    assert np.all(np.diff(L) > 0)                                     # invertible
    # no kink at the knee (no visible seam): the slopes 3 codes below and above it agree to < 1, where a boost
    # rising linearly from the knee would jump by (gain − 1) · L(knee) / (1 − knee) ≈ 55
    h = 3 / 65535
    below, above = (np.diff(expand_highlights(np.array([c - h / 2, c + h / 2])))[0] / h
                    for c in (HIGHLIGHT_KNEE - h, HIGHLIGHT_KNEE + h))
    assert abs(above - below) < 1.0
    np.testing.assert_allclose(compress_highlights(L), v, atol=1e-6)
    assert compress_highlights(np.array([2 * DEFAULT_HIGHLIGHT_GAIN]))[0] == 1.0
    np.testing.assert_allclose(expand_highlights(v, gain=1.0), colour.cctf_decoding(v, function="sRGB"), atol=1e-7)
    for bad in (0.5, np.nan, np.inf):
        with pytest.raises(ValueError, match="gain=.* is invalid; allowed: a finite number >= 1"):
            expand_highlights(v, gain=bad)


@pytest.mark.parametrize("aperture", ["disk", "hexagon"])
def test_a_specular_point_blooms_with_its_energy_and_size(tmp_path, flat_map, aperture, capsys):
    from method.magnify.scatter import radius_for_sigma

    src = write_photo(tmp_path / "point.png", _point())
    energies = {}
    for name, extra in (("plain", []), ("recovered", ["--highlights"])):
        status, _, err = run([src, "--map", flat_map, "--floor", "clamp", "--aperture", aperture, *extra,
                              "-o", tmp_path / f"{name}.exr"], capsys)
        assert status == 0, err
        energy, variance, reach = _moments(read_photo(tmp_path / f"{name}.exr").image)
        energies[name] = energy
        assert variance == pytest.approx(SIGMA_E**2, rel=0.03)         # the disk's size matches σ_e
        R = float(radius_for_sigma(np.array([SIGMA_E]), aperture=aperture)[0])
        bound = R * (np.sqrt(6 / 5) if aperture == "hexagon" else 1.0)
        assert bound - 2.0 < reach <= bound + 1.0
    assert energies["plain"] == pytest.approx(1.0, rel=0.01)           # energy conserved in linear light
    assert energies["recovered"] == pytest.approx(DEFAULT_HIGHLIGHT_GAIN, rel=0.01)


def test_recovered_highlight_is_brighter_in_an_8bit_output(tmp_path, flat_map, capsys):
    src = write_photo(tmp_path / "point.png", _point(background=0.2))
    peaks = {}
    for name, extra in (("plain", []), ("recovered", ["--highlights", "32"])):
        status, _, err = run([src, "--map", flat_map, "--floor", "clamp", *extra, "-o", tmp_path / f"{name}.png"],
                             capsys)
        assert status == 0, err
        out = read_photo(tmp_path / f"{name}.png").image[..., 1]
        peaks[name] = out[N // 2, N // 2]
        assert out[2, 2] == pytest.approx(0.2, abs=1.5 / 255)          # the background keeps its value
    assert peaks["plain"] < 0.25 < 0.35 < peaks["recovered"]


def test_exr_highlights_are_kept_unclipped_end_to_end(tmp_path, flat_map, capsys):
    src = write_photo(tmp_path / "point.exr", _point(value=50.0, background=0.1), encoding="linear")
    photo = read_photo(src)
    assert photo.image.max() == 50.0 and any("above 1.0 kept" in n for n in photo.notes)
    status, _, err = run([src, "--map", flat_map, "--floor", "clamp", "-o", tmp_path / "out.exr"], capsys)
    assert status == 0, err
    out = read_photo(tmp_path / "out.exr").image
    energy = (out - 0.1)[..., 1].sum()
    assert energy == pytest.approx(50.0 - 0.1, rel=0.01)
    assert out.max() > 1.0 / 0.9 * 50.0 / (np.pi * (2 * SIGMA_E) ** 2)  # a disk of the point's light, not of 1


def test_exr_negative_samples_are_raised_to_zero_with_a_note(tmp_path):
    import OpenEXR

    img = np.full((8, 10, 3), 0.5, dtype=np.float32)
    img[0, 0] = -0.25
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": img}).write(str(tmp_path / "n.exr"))
    photo = read_photo(tmp_path / "n.exr")
    assert photo.image.min() == 0.0 and any("below 0 raised to 0" in n for n in photo.notes)


@pytest.mark.parametrize("args,needles", [
    (["--highlights"], ["--highlights applies to display-encoded photos", "point.exr", "allowed: drop --highlights"]),
    (["--highlights", "0.5"], ["--highlights 0.5 is invalid", "allowed: a finite gain >= 1"]),
    (["--highlights", "bright"], ["--highlights 'bright' is not a number"]),
])
def test_highlights_bad_input(tmp_path, flat_map, args, needles, capsys):
    src = write_photo(tmp_path / "point.exr", _point())
    status, _, err = run([src, "--map", flat_map, "-o", tmp_path / "out.exr", *args], capsys)
    assert_one_line_error(status, err, *needles)
    assert not (tmp_path / "out.exr").exists()


def test_highlights_need_the_scatter(tmp_path, capsys):
    src = write_photo(tmp_path / "p.png", textured_photo(48, 64))
    status, _, err = run([src, "--renderer", "gather", "--highlights", "-o", tmp_path / "out.png"], capsys)
    assert_one_line_error(status, err, "--highlights applies to the scatter renderer", "allowed")
    assert not (tmp_path / "out.png").exists()


def test_estimation_sees_linear_highlights_as_white(tmp_path, capsys):
    """The map of an EXR whose highlights exceed 1 is the map of the same EXR clipped at 1."""
    from repro.estimate import PROG as ESTIMATE, main as estimate

    run_estimate, _ = cli_runner(estimate, ESTIMATE)
    base = textured_photo(48, 64) ** 2.2
    hot = base.copy()
    hot[10:14, 10:14] = 40.0       # a specular patch far above white
    hot[30:33, 50:53] = 5.0
    for name, img in (("hot", hot), ("clipped", np.minimum(hot, 1.0))):
        write_photo(tmp_path / f"{name}.exr", img, encoding="linear")
        status, _, err = run_estimate([tmp_path / f"{name}.exr", "-o", tmp_path / f"{name}.npy"], capsys)
        assert status == 0, err
    assert read_photo(tmp_path / "hot.exr").image.max() == 40.0
    np.testing.assert_array_equal(np.load(tmp_path / "hot.npy"), np.load(tmp_path / "clipped.npy"))


# --- the photo's own tone curve (method.luma.ENCODINGS) ------------------------------------------------------------

#: The display curves --highlights takes on the command line (a linear photo is refused: its highlights are kept).
CLI_CURVES = [name for name in ENCODINGS if name != "linear"]


def _wrong_curve(curve):
    """A registered curve other than ``curve`` (sRGB's nearest neighbour is gamma 2.2)."""
    return "gamma2.2" if curve == "srgb" else "srgb"


@pytest.mark.parametrize("curve", list(ENCODINGS))
def test_each_curve_is_decoded_below_the_knee_and_inverted_exactly(curve):
    from method.luma import decode

    v = np.concatenate([np.linspace(0.0, 1.0, 200_001), np.arange(65536) / 65535])
    below = v <= HIGHLIGHT_KNEE
    worst = 0.0
    for gain in (1.0, DEFAULT_HIGHLIGHT_GAIN, 32.0, 1000.0):
        L = expand_highlights(v, gain=gain, encoding=curve)
        np.testing.assert_allclose(L[below], decode(v[below], curve), rtol=1e-12, atol=0)
        assert L.max() == pytest.approx(gain) and L.min() == 0.0
        assert np.all(np.diff(expand_highlights(np.linspace(0, 1, 100_001), gain=gain, encoding=curve)) > 0)
        worst = max(worst, float(np.abs(compress_highlights(L, gain=gain, encoding=curve) - v).max()))
        lin = np.linspace(0.0, gain, 100_001)      # and the other way: display values → the same light
        np.testing.assert_allclose(expand_highlights(compress_highlights(lin, gain=gain, encoding=curve), gain=gain,
                                                     encoding=curve), lin, rtol=0, atol=HIGHLIGHT_ROUNDTRIP_ATOL * gain)
    assert worst <= HIGHLIGHT_ROUNDTRIP_ATOL
    np.testing.assert_allclose(expand_highlights(v, gain=1.0, encoding=curve), decode(v, curve), rtol=1e-12, atol=0)
    assert compress_highlights(np.array([-1.0, 2 * DEFAULT_HIGHLIGHT_GAIN]), encoding=curve).tolist() == [0.0, 1.0]


def test_the_curve_is_really_used_and_bad_curves_are_refused():
    from method.luma import decode

    v = np.array([0.2, 0.5, 0.95])
    for curve in ENCODINGS:     # each curve's expansion differs from its neighbour's by > 5 % where the photo is dim
        other = expand_highlights(v, encoding=_wrong_curve(curve))
        assert np.abs(expand_highlights(v, encoding=curve)[0] / other[0] - 1) > 0.05, curve
    # a gamma-2.2 photo decoded as sRGB: the light at display 0.2 is off by 14 %, and re-encoding with sRGB what
    # was expanded with gamma 2.2 moves the display value
    assert expand_highlights(v, encoding="srgb")[0] == pytest.approx(1.14 * decode(0.2, "gamma2.2"), rel=0.01)
    assert abs(compress_highlights(expand_highlights(v, encoding="gamma2.2"), encoding="srgb")[0] - 0.2) > 0.01
    for fn in (expand_highlights, compress_highlights):
        for bad in ("gamma9", "auto", "sRGB"):
            with pytest.raises(ValueError, match=rf"encoding='{bad}' is invalid.*allowed: .*'gamma2.2'"):
                fn(v, encoding=bad)
        with pytest.raises(ValueError, match="gain=0.5 is invalid; allowed: a finite number >= 1"):
            fn(v, gain=0.5, encoding="gamma2.2")


def _point16(tmp_path, value=1.0):
    """The point photo as a 16-bit PNG (display values, so the output is 16-bit too)."""
    return write_photo(tmp_path / "point.png", _point(value), bit_depth=16)


@pytest.mark.parametrize("curve", CLI_CURVES)
def test_a_specular_point_blooms_with_its_energy_under_each_curve(tmp_path, flat_map, curve, capsys):
    """--encoding CURVE --highlights: the point's light is GAIN × white in linear light (EXR output), and the
    16-bit output, expanded again with the same curve, holds that light: it was re-encoded with CURVE."""
    src = _point16(tmp_path)
    for out in ("out.exr", "out.png"):
        status, _, err = run([src, "--map", flat_map, "--floor", "clamp", "--encoding", curve, "--highlights",
                              "-o", tmp_path / out], capsys)
        assert status == 0, err
        assert any(f"highlights x{DEFAULT_HIGHLIGHT_GAIN:g} ({curve} curve)" in line for line in err), err
    exr = read_photo(tmp_path / "out.exr").image
    png = read_photo(tmp_path / "out.png")
    assert png.bit_depth == 16
    for lin in (exr, expand_highlights(png.image, encoding=curve)):
        energy, variance, _ = _moments(lin)
        assert energy == pytest.approx(DEFAULT_HIGHLIGHT_GAIN, rel=HIGHLIGHT_ENERGY_RTOL)
        assert variance == pytest.approx(SIGMA_E**2, rel=HIGHLIGHT_VARIANCE_RTOL)
    wrong, _, _ = _moments(expand_highlights(png.image, encoding=_wrong_curve(curve)))
    assert abs(wrong / DEFAULT_HIGHLIGHT_GAIN - 1) > 5 * HIGHLIGHT_ENERGY_RTOL


def _dim_point_run(tmp_path, flat_map, capsys, encoding, name):
    """Energy of the magnified linear light (EXR) of a gamma-2.2 photo of a dim point (linear 0.005)."""
    from method.luma import encode

    src = write_photo(tmp_path / "dim.png", _point(float(encode(0.005, "gamma2.2"))), bit_depth=16)
    status, _, err = run([src, "--map", flat_map, "--floor", "clamp", "--encoding", encoding, "--highlights",
                          "-o", tmp_path / f"{name}.exr"], capsys)
    assert status == 0, err
    return _moments(read_photo(tmp_path / f"{name}.exr").image)[0], err


def test_a_gamma22_photo_decoded_as_srgb_gives_another_light(tmp_path, flat_map, capsys):
    right, _ = _dim_point_run(tmp_path, flat_map, capsys, "gamma2.2", "right")
    wrong, _ = _dim_point_run(tmp_path, flat_map, capsys, "srgb", "wrong")
    assert right == pytest.approx(0.005, rel=HIGHLIGHT_ENERGY_RTOL)
    assert wrong / 0.005 - 1 > 0.5      # sRGB decodes display 0.0898 to 0.0085: 70 % more light


def test_auto_takes_the_curve_the_estimate_chose(tmp_path, flat_map, capsys, monkeypatch):
    """--encoding auto: the highlights use the curve resolved for the photo (here made to be gamma 2.2)."""
    import method.edges.tone_curve as tone_curve

    monkeypatch.setattr(tone_curve, "resolve_encoding", lambda image, encoding: "gamma2.2")
    energy, err = _dim_point_run(tmp_path, flat_map, capsys, "auto", "auto")
    assert energy == pytest.approx(0.005, rel=HIGHLIGHT_ENERGY_RTOL)
    assert any("(gamma2.2 curve)" in line for line in err), err


@pytest.mark.parametrize("args,needles", [
    (["--encoding", "gamma9", "--highlights"], ["--encoding", "gamma9", "gamma2.2"]),
    (["--encoding", "linear", "--highlights"], ["--highlights applies to display-encoded photos", "point.png", "linear light",
                                "allowed: drop --highlights, or --encoding with a tone curve"]),
    (["--encoding", "gamma2.2", "--highlights", "0.9"], ["--highlights 0.9 is invalid", "allowed: a finite gain >= 1"]),
])
def test_highlights_bad_curve_or_gain(tmp_path, flat_map, args, needles, capsys):
    src = _point16(tmp_path)
    status, _, err = run([src, "--map", flat_map, *args, "-o", tmp_path / "out.png"], capsys)
    assert_one_line_error(status, err, *needles)
    assert not (tmp_path / "out.png").exists()
