"""repro/photo_io/: decoding, bit depths, orientation, metadata, refusals, atomic writes."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from repro.photo_io import (
    DEFAULT_MAX_PIXELS,
    PhotoError,
    apply_orientation,
    output_bit_depth,
    probe_photo,
    read_photo,
    write_defocus_map,
    write_photo,
)
from tests.tolerances import PHOTO_EXR_ROUNDTRIP_ATOL, PHOTO_JPEG_ROUNDTRIP_ATOL, PHOTO_JPEG_ROUNDTRIP_MEAN_ATOL


def smooth_rgb(h=24, w=32):
    """A smooth colour ramp (JPEG-friendly), float in [0, 1]."""
    y, x = np.mgrid[0:h, 0:w]
    return np.stack([x / (w - 1), y / (h - 1), 0.5 + 0.4 * np.sin(x / 5.0) * np.cos(y / 7.0)], axis=-1)


def noisy_rgb(rng, h=24, w=32):
    return rng.random((h, w, 3))


def png_with_header(path, width, height, *, depth=8, ctype=2):
    """A PNG whose IHDR claims width×height, with a tiny (wrong) IDAT: only the header is valid."""

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, depth, ctype, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64))
                     + chunk(b"IEND", b""))
    return path


def no_temp_files(folder):
    return not [p for p in folder.iterdir() if ".tmp." in p.name]


# ------------------------------------------------------------------------------------------------
# round trips
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix,bits", [(".png", 8), (".png", 16), (".tif", 8), (".tiff", 16)])
@pytest.mark.parametrize("grey", [False, True])
def test_lossless_roundtrip_keeps_bit_depth(tmp_path, rng, suffix, bits, grey):
    img = noisy_rgb(rng)
    if grey:
        img = img[..., 0]
    levels = 2**bits - 1
    img = np.round(img * levels) / levels
    path = write_photo(tmp_path / f"a{suffix}", img, bit_depth=bits)
    photo = read_photo(path)
    assert photo.bit_depth == bits
    assert photo.image.shape == img.shape
    assert photo.image.dtype == np.float64
    np.testing.assert_array_equal(photo.image, img)
    assert photo.notes == ()
    assert no_temp_files(tmp_path)


def test_16bit_rgb_png_keeps_16_bits(tmp_path):
    """Pillow alone would truncate a 16-bit RGB PNG to 8 bits; values 1/65535 apart must survive."""
    img = np.zeros((8, 9, 3))
    img[..., 0] = np.arange(9) / 65535.0
    photo = read_photo(write_photo(tmp_path / "a.png", img, bit_depth=16))
    np.testing.assert_array_equal(np.round(photo.image[0, :, 0] * 65535), np.arange(9))


def test_jpeg_roundtrip(tmp_path):
    img = smooth_rgb()
    photo = read_photo(write_photo(tmp_path / "a.jpg", img))
    assert photo.bit_depth == 8 and photo.format == "JPEG"
    assert np.max(np.abs(photo.image - img)) <= PHOTO_JPEG_ROUNDTRIP_ATOL
    assert np.mean(np.abs(photo.image - img)) <= PHOTO_JPEG_ROUNDTRIP_MEAN_ATOL


def test_exr_is_written_linear_and_read_linear(tmp_path):
    """An sRGB image is decoded to linear light on writing an EXR; reading keeps the linear values
    and declares them ``encoding="linear"`` (other formats "srgb"); a linear image is written as given."""
    from scenes.display import linear_to_srgb

    img = smooth_rgb()
    path = write_photo(tmp_path / "a.exr", img)
    import OpenEXR

    stored = OpenEXR.File(str(path)).channels()["RGB"].pixels
    np.testing.assert_allclose(linear_to_srgb(stored), img, atol=PHOTO_EXR_ROUNDTRIP_ATOL)
    assert float(stored.mean()) < float(img.mean())  # linear values are darker than encoded ones
    photo = read_photo(path)
    assert photo.bit_depth == 32 and photo.format == "EXR" and photo.encoding == "linear"
    np.testing.assert_array_equal(photo.image, stored.astype(np.float64))  # not encoded on reading
    again = read_photo(write_photo(tmp_path / "b.exr", photo.image, encoding="linear"))
    np.testing.assert_array_equal(again.image, photo.image)
    assert read_photo(write_photo(tmp_path / "a.png", img)).encoding == "srgb"
    png = read_photo(write_photo(tmp_path / "l.png", photo.image, encoding="linear", bit_depth=16))
    np.testing.assert_allclose(png.image, img, atol=PHOTO_EXR_ROUNDTRIP_ATOL + 0.5 / 65535)  # encoded: 16-bit codes
    with pytest.raises(ValueError, match="encoding='display' is invalid; allowed: 'filmic', 'gamma1.8', 'gamma2.2', 'linear', 'srgb'"):
        write_photo(tmp_path / "c.exr", img, encoding="display")


def test_grey_exr(tmp_path):
    img = smooth_rgb()[..., 1]
    photo = read_photo(write_photo(tmp_path / "g.exr", img))
    assert photo.image.shape == img.shape


def test_rgba_png_alpha_ignored_with_note(tmp_path, rng):
    from PIL import Image

    rgba = (rng.random((10, 12, 4)) * 255).astype(np.uint8)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "a.png")
    photo = read_photo(tmp_path / "a.png")
    assert photo.image.shape == (10, 12, 3)
    np.testing.assert_array_equal(np.round(photo.image * 255), rgba[..., :3])
    assert any("alpha" in n for n in photo.notes)


def test_grey_alpha_and_palette_png(tmp_path, rng):
    from PIL import Image

    la = (rng.random((10, 12, 2)) * 255).astype(np.uint8)
    Image.fromarray(la, "LA").save(tmp_path / "la.png")
    photo = read_photo(tmp_path / "la.png")
    assert photo.image.shape == (10, 12) and any("alpha" in n for n in photo.notes)
    rgb = (rng.random((10, 12, 3)) * 255).astype(np.uint8)
    Image.fromarray(rgb).convert("P").save(tmp_path / "p.png")
    assert read_photo(tmp_path / "p.png").image.shape == (10, 12, 3)


def test_16bit_rgba_tiff_and_png(tmp_path, rng):
    import imagecodecs
    import tifffile

    a = (rng.random((6, 7, 4)) * 65535).astype(np.uint16)
    tifffile.imwrite(tmp_path / "a.tif", a, photometric="rgb", extrasamples=["unassalpha"])
    (tmp_path / "a.png").write_bytes(imagecodecs.png_encode(a))
    for name in ("a.tif", "a.png"):
        photo = read_photo(tmp_path / name)
        assert photo.bit_depth == 16
        np.testing.assert_array_equal(np.round(photo.image * 65535), a[..., :3])
        assert any("alpha" in n for n in photo.notes)


def test_planar_tiff(tmp_path, rng):
    import tifffile

    a = (rng.random((3, 6, 7)) * 255).astype(np.uint8)
    tifffile.imwrite(tmp_path / "p.tif", a, photometric="rgb", planarconfig="separate")
    photo = read_photo(tmp_path / "p.tif")
    np.testing.assert_array_equal(np.round(photo.image * 255), np.moveaxis(a, 0, -1))


# ------------------------------------------------------------------------------------------------
# orientation and metadata
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("orientation", range(1, 9))
def test_exif_orientation_matches_pillow(tmp_path, rng, orientation):
    from PIL import Image, ImageOps

    a = (rng.random((6, 9, 3)) * 255).astype(np.uint8)
    im = Image.fromarray(a)
    exif = im.getexif()
    exif[0x0112] = orientation
    im.save(tmp_path / "o.png", exif=exif.tobytes())
    expected = np.asarray(ImageOps.exif_transpose(Image.open(tmp_path / "o.png")))
    photo = read_photo(tmp_path / "o.png")
    np.testing.assert_array_equal(np.round(photo.image * 255).astype(np.uint8), expected)
    # orientation is applied to the pixels, so the EXIF we pass on must say "upright"
    if photo.exif is not None:
        out = write_photo(tmp_path / "out.jpg", photo.image, exif=photo.exif)
        assert Image.open(out).getexif().get(0x0112, 1) == 1


def test_exif_orientation_16bit_png(tmp_path):
    """The 16-bit decoder (not Pillow) must honour the orientation too."""
    from PIL import Image

    a = np.arange(6 * 9 * 3, dtype=np.uint16).reshape(6, 9, 3) * 100
    path = write_photo(tmp_path / "o.png", a / 65535.0, bit_depth=16)
    # add an eXIf chunk saying "rotate 90° CW" (6) before IEND
    exif = Image.Exif()
    exif[0x0112] = 6
    data = exif.tobytes()[6:] if exif.tobytes().startswith(b"Exif\0\0") else exif.tobytes()
    raw = path.read_bytes()
    chunk = struct.pack(">I", len(data)) + b"eXIf" + data + struct.pack(">I", zlib.crc32(b"eXIf" + data) & 0xFFFFFFFF)
    path.write_bytes(raw[:-12] + chunk + raw[-12:])
    photo = read_photo(path)
    assert photo.image.shape == (9, 6, 3)
    np.testing.assert_array_equal(np.round(photo.image * 65535).astype(np.uint16), np.rot90(a, k=-1))


def test_apply_orientation_inverts_to_identity():
    a = np.arange(12).reshape(3, 4)
    for o in (1, 2, 3, 4):  # involutions
        np.testing.assert_array_equal(apply_orientation(apply_orientation(a, o), o), a)
    np.testing.assert_array_equal(apply_orientation(apply_orientation(a, 6), 8), a)


def test_icc_profile_passes_through_jpeg(tmp_path):
    from PIL import Image, ImageCms

    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    Image.fromarray((smooth_rgb() * 255).astype(np.uint8)).save(tmp_path / "a.jpg", icc_profile=icc)
    photo = read_photo(tmp_path / "a.jpg")
    assert photo.icc_profile == icc
    out = write_photo(tmp_path / "b.jpg", photo.image, icc_profile=photo.icc_profile, exif=photo.exif)
    assert Image.open(out).info.get("icc_profile") == icc


# ------------------------------------------------------------------------------------------------
# refusals: one PhotoError (a ValueError) with a clear message
# ------------------------------------------------------------------------------------------------


def test_missing_dir_empty(tmp_path):
    with pytest.raises(PhotoError, match="no such file"):
        read_photo(tmp_path / "nope.jpg")
    with pytest.raises(PhotoError, match="directory"):
        read_photo(tmp_path)
    (tmp_path / "e.jpg").write_bytes(b"")
    with pytest.raises(PhotoError, match="empty"):
        read_photo(tmp_path / "e.jpg")


def test_truncated_jpeg_and_png(tmp_path, rng):
    good = write_photo(tmp_path / "g.jpg", noisy_rgb(rng, 64, 64))
    (tmp_path / "t.jpg").write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2])
    with pytest.raises(PhotoError, match="truncated|corrupt"):
        read_photo(tmp_path / "t.jpg")
    for bits in (8, 16):
        g = write_photo(tmp_path / f"g{bits}.png", noisy_rgb(rng, 64, 64), bit_depth=bits)
        (tmp_path / f"t{bits}.png").write_bytes(g.read_bytes()[:200])
        with pytest.raises(PhotoError, match="truncated|corrupt"):
            read_photo(tmp_path / f"t{bits}.png")


def test_text_renamed_png(tmp_path):
    (tmp_path / "x.png").write_text("this is not an image\n" * 10)
    with pytest.raises(PhotoError, match="not a recognised image"):
        read_photo(tmp_path / "x.png")


def test_corrupt_exr(tmp_path):
    good = write_photo(tmp_path / "g.exr", smooth_rgb())
    (tmp_path / "t.exr").write_bytes(good.read_bytes()[:100])
    with pytest.raises(PhotoError, match="OpenEXR"):
        read_photo(tmp_path / "t.exr")


def test_exr_nonfinite_refused_or_repaired(tmp_path):
    import OpenEXR

    lin = np.full((8, 10, 3), 0.25, dtype=np.float32)
    lin[1, 1, 0], lin[2, 2, 1], lin[3, 3, 2] = np.nan, np.inf, -np.inf
    path = tmp_path / "bad.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": lin}).write(str(path))
    with pytest.raises(PhotoError, match="NaN/Inf.*--repair-nonfinite"):
        read_photo(path)
    photo = read_photo(path, repair_nonfinite=True)
    assert np.all(np.isfinite(photo.image))
    assert photo.image[1, 1, 0] == 0.0 and photo.image[3, 3, 2] == 0.0
    assert photo.image[2, 2, 1] == pytest.approx(1.0, abs=PHOTO_EXR_ROUNDTRIP_ATOL)
    assert any("repaired 3" in n for n in photo.notes)


def test_huge_header_refused_before_decoding(tmp_path, monkeypatch):
    path = png_with_header(tmp_path / "huge.png", 10_000, 10_000)  # 100 MP, pixels are garbage
    assert probe_photo(path).pixels == 100_000_000
    from PIL import ImageFile

    def no_decoding(self, *args, **kwargs):
        raise AssertionError("pixels were decoded")

    # Any decoding attempt would surface as a different error than the budget refusal.
    monkeypatch.setattr(ImageFile.ImageFile, "load", no_decoding)
    with pytest.raises(PhotoError, match="100.0 MP.*exceeds the pixel budget"):
        read_photo(path, max_pixels=DEFAULT_MAX_PIXELS)
    monkeypatch.undo()
    with pytest.raises(PhotoError, match="pixel budget of 1.0 MP"):
        read_photo(path, max_pixels=1_000_000)


def test_pillow_decompression_bomb_is_a_photo_error(tmp_path):
    """With our budget disabled, Pillow's own guard (> 2×89 MP) must still give a PhotoError."""
    from PIL import Image

    # an 8-bit palette PNG goes through Pillow; 20000² = 400 MP
    path = png_with_header(tmp_path / "bomb.png", 20_000, 20_000, ctype=3)
    assert Image.MAX_IMAGE_PIXELS is not None
    with pytest.raises(PhotoError, match="decompression-bomb"):
        read_photo(path, max_pixels=None)


# ------------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------------


def test_output_bit_depth_rules():
    assert output_bit_depth(".jpg", 16) == 8
    assert output_bit_depth(".png", 16) == 16
    assert output_bit_depth(".tif", 32) == 16
    assert output_bit_depth(".png", 8) == 8
    assert output_bit_depth(".exr", 8) == 32
    with pytest.raises(PhotoError, match="allowed"):
        output_bit_depth(".gif", 8)


def test_write_refuses_bad_input_and_leaves_nothing(tmp_path):
    with pytest.raises(PhotoError, match="extension"):
        write_photo(tmp_path / "a.gif", smooth_rgb())
    with pytest.raises(PhotoError, match="NaN"):
        write_photo(tmp_path / "a.png", np.full((4, 4), np.nan))
    with pytest.raises(PhotoError, match="bit_depth"):
        write_photo(tmp_path / "a.png", smooth_rgb(), bit_depth=12)
    with pytest.raises(OSError):
        write_photo(tmp_path / "missing" / "a.png", smooth_rgb())
    assert list(tmp_path.iterdir()) == []


def test_write_failure_keeps_old_file(tmp_path, monkeypatch):
    """An exception while encoding leaves the previous file intact and no temp file."""
    import PIL.Image

    target = write_photo(tmp_path / "a.png", smooth_rgb())
    before = target.read_bytes()

    def boom(*a, **k):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(PIL.Image.Image, "save", boom)
    with pytest.raises(RuntimeError):
        write_photo(target, np.zeros((24, 32, 3)))
    assert target.read_bytes() == before
    assert no_temp_files(tmp_path)


def test_defocus_map_writers(tmp_path, rng):
    import OpenEXR

    sigma = rng.random((12, 17)) * 5
    exr = write_defocus_map(tmp_path / "m.exr", sigma)
    ch = OpenEXR.File(str(exr)).channels()
    assert list(ch) == ["sigma"]
    np.testing.assert_array_equal(ch["sigma"].pixels, sigma.astype(np.float32))
    npy = write_defocus_map(tmp_path / "m.npy", sigma)
    np.testing.assert_array_equal(np.load(npy), sigma)
    with pytest.raises(PhotoError, match="allowed"):
        write_defocus_map(tmp_path / "m.txt", sigma)
    with pytest.raises(PhotoError, match="HxW"):
        write_defocus_map(tmp_path / "m.npy", sigma[None])
