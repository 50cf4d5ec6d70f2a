"""Reading and writing photographers' image files: JPEG, PNG, TIFF (8/16-bit) and OpenEXR.

The method wants a float image in [0, 1], display-encoded (sRGB), HxW or HxWx3. This module turns
a file into that (:func:`read_photo`) and back (:func:`write_photo`), keeping what a photographer
expects kept: orientation (EXIF), bit depth (16-bit PNG/TIFF in → 16-bit out), grey stays grey,
EXIF and ICC metadata pass through where the format allows.

Every bad file is refused with :class:`PhotoError` (a ``ValueError``) carrying one line that names
the file and what is wrong; nothing is ever half-written (:func:`defocus_cache.atomic_write`).

Decoders
--------
* JPEG, 8-bit PNG, other Pillow formats: Pillow.
* 16-bit PNG: ``imagecodecs.png_decode`` / ``png_encode`` (Pillow keeps only 8 bits of a 16-bit
  RGB PNG and cannot write one).
* TIFF: ``tifffile`` (8/16-bit, float, RGB or grey, chunky or planar); palette/CMYK TIFFs go
  through Pillow.
* EXR: the ``OpenEXR`` 3.x API. EXR holds *linear* light: it is encoded with the sRGB transfer
  function (:func:`scenes.display.linear_to_srgb`) on reading and decoded on writing.

The pixel budget (``max_pixels``) is checked from the file header, before any pixel is decoded,
so a 100-megapixel header costs nothing; Pillow's own ``DecompressionBombError`` is caught too.
"""

from __future__ import annotations

import dataclasses
import struct
import warnings
from pathlib import Path

import numpy as np

from defocus_cache import atomic_write

__all__ = [
    "DEFAULT_MAX_PIXELS",
    "OUTPUT_SUFFIXES",
    "Photo",
    "PhotoError",
    "PhotoHeader",
    "apply_orientation",
    "output_bit_depth",
    "probe_photo",
    "read_photo",
    "write_defocus_map",
    "write_photo",
]

#: Default pixel budget (width × height) of an input photo: 64 MP covers every current camera
#: sensor (≤ 61 MP) while refusing panoramas/scans: full-resolution magnification holds ≈ 75 B per
#: photo pixel plus one ≈ 1.1 GiB tile (measured 2.9 GiB peak at 24 MP), so ≈ 6 GiB at 64 MP.
DEFAULT_MAX_PIXELS = 64_000_000

#: Extensions :func:`write_photo` writes (format chosen from the extension).
OUTPUT_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".exr")

#: JPEG quality of written photos (Pillow scale 1–95) and chroma subsampling 4:4:4 (0): a
#: magnified photo should not lose colour resolution it had.
JPEG_QUALITY = 95
JPEG_SUBSAMPLING = 0

_EXR_MAGIC = b"\x76\x2f\x31\x01"
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
_JPEG_MAGIC = b"\xff\xd8\xff"
_ORIENTATION_TAG = 0x0112


class PhotoError(ValueError):
    """A photo file that cannot be used (missing, not an image, corrupt, too large, NaN/Inf, …)."""


@dataclasses.dataclass(frozen=True)
class PhotoHeader:
    """What a file's header says, read without decoding pixels."""

    path: Path
    format: str    # "JPEG", "PNG", "TIFF", "EXR" or another Pillow format name
    width: int     # px, as stored (before EXIF orientation)
    height: int    # px, as stored

    @property
    def pixels(self) -> int:
        """width × height."""
        return self.width * self.height


@dataclasses.dataclass(frozen=True)
class Photo:
    """A decoded photo, ready for the method.

    Attributes
    ----------
    image : ndarray, HxWx3 or HxW, float64 in [0, 1]
        Display-encoded (sRGB) values, upright (EXIF orientation applied), alpha dropped.
    bit_depth : int
        Bits per sample of the source: 8, 16, or 32 for floating-point sources (EXR, float TIFF).
    format : str
        Source format ("JPEG", "PNG", "TIFF", "EXR", …).
    path : Path
        The file read.
    notes : tuple of str
        One-line remarks for the user (alpha ignored, NaN repaired, values clipped, …).
    exif : bytes or None
        The source's EXIF block with its orientation reset to 1 (pixels are already upright).
    icc_profile : bytes or None
        The source's embedded ICC profile, passed through on writing.
    """

    image: np.ndarray
    bit_depth: int
    format: str
    path: Path
    notes: tuple[str, ...] = ()
    exif: bytes | None = None
    icc_profile: bytes | None = None

    @property
    def is_grey(self) -> bool:
        """True for a single-channel (HxW) photo."""
        return self.image.ndim == 2


# ------------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------------


def _check_file(path) -> Path:
    path = Path(path)
    if not path.exists():
        raise PhotoError(f"{path}: no such file")
    if path.is_dir():
        raise PhotoError(f"{path}: is a directory, not an image file")
    if not path.is_file():
        raise PhotoError(f"{path}: not a regular file")
    try:
        size = path.stat().st_size
        with open(path, "rb"):
            pass
    except OSError as exc:
        raise PhotoError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if size == 0:
        raise PhotoError(f"{path}: empty file (0 bytes)")
    return path


def _sniff(path: Path) -> str | None:
    with open(path, "rb") as fh:
        head = fh.read(16)
    if head.startswith(_EXR_MAGIC):
        return "EXR"
    if head.startswith(_PNG_MAGIC):
        return "PNG"
    if head.startswith(_JPEG_MAGIC):
        return "JPEG"
    if any(head.startswith(m) for m in _TIFF_MAGICS):
        return "TIFF"
    return None


def _png_ihdr(path: Path) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from a PNG's IHDR chunk."""
    with open(path, "rb") as fh:
        head = fh.read(33)
    if len(head) < 33 or head[12:16] != b"IHDR":
        raise PhotoError(f"{path}: corrupt PNG (no IHDR chunk)")
    width, height, depth, ctype = struct.unpack(">IIBB", head[16:26])
    return width, height, depth, ctype


def _open_pillow(path: Path):
    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            return Image.open(path)
    except Image.DecompressionBombError as exc:
        raise PhotoError(f"{path}: refused by Pillow's decompression-bomb guard ({exc})") from None
    except UnidentifiedImageError:
        raise PhotoError(
            f"{path}: not a recognised image file (expected JPEG, PNG, TIFF or OpenEXR)"
        ) from None
    except (OSError, SyntaxError, ValueError) as exc:
        raise PhotoError(f"{path}: corrupt or unreadable image header ({exc})") from None


def probe_photo(path) -> PhotoHeader:
    """Read an image file's header only: format and stored size.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    PhotoHeader

    Raises
    ------
    PhotoError
        Missing path, a directory, an empty file, not an image, a corrupt header.
    """
    path = _check_file(path)
    kind = _sniff(path)
    if kind == "EXR":
        import OpenEXR

        try:
            header = OpenEXR.File(str(path), header_only=True).header()
            (x0, y0), (x1, y1) = (tuple(int(v) for v in c) for c in header["dataWindow"])
        except Exception as exc:  # OpenEXR raises RuntimeError, KeyError…
            raise PhotoError(f"{path}: corrupt OpenEXR file ({exc})") from None
        return PhotoHeader(path, "EXR", x1 - x0 + 1, y1 - y0 + 1)
    if kind == "PNG":
        w, h, _, _ = _png_ihdr(path)
        return PhotoHeader(path, "PNG", w, h)
    if kind == "TIFF":
        import tifffile

        try:
            with tifffile.TiffFile(path) as tif:
                page = tif.pages.first
                return PhotoHeader(path, "TIFF", int(page.imagewidth), int(page.imagelength))
        except Exception as exc:
            raise PhotoError(f"{path}: corrupt TIFF file ({exc})") from None
    with _open_pillow(path) as im:
        w, h = im.size
        return PhotoHeader(path, im.format or "image", int(w), int(h))


def _check_budget(header: PhotoHeader, max_pixels) -> None:
    if header.width < 1 or header.height < 1:
        raise PhotoError(f"{header.path}: header says {header.width}x{header.height} px; nothing to read")
    if max_pixels is not None and header.pixels > max_pixels:
        raise PhotoError(
            f"{header.path}: {header.width}x{header.height} px ({header.pixels / 1e6:.1f} MP) exceeds the "
            f"pixel budget of {max_pixels / 1e6:.1f} MP (raise it with --max-pixels / max_pixels)"
        )


def apply_orientation(array: np.ndarray, orientation: int) -> np.ndarray:
    """Make a stored image upright according to its EXIF orientation tag.

    Parameters
    ----------
    array : ndarray, HxW or HxWxC
        Pixels as stored.
    orientation : int
        EXIF tag 0x0112, 1–8 (anything else is treated as 1).

    Returns
    -------
    ndarray
        The upright image (a view when possible), same as Pillow's ``ImageOps.exif_transpose``.
    """
    a = array
    if orientation == 2:
        return a[:, ::-1]
    if orientation == 3:
        return a[::-1, ::-1]
    if orientation == 4:
        return a[::-1]
    if orientation == 5:
        return a.swapaxes(0, 1)
    if orientation == 6:
        return np.rot90(a, k=-1)
    if orientation == 7:
        return a[::-1, ::-1].swapaxes(0, 1)
    if orientation == 8:
        return np.rot90(a, k=1)
    return a


def _exif_of(im) -> tuple[int, bytes | None]:
    """(orientation, EXIF bytes with orientation reset to 1) of an open Pillow image."""
    try:
        exif = im.getexif()
    except Exception:  # malformed EXIF must not stop us from reading the pixels
        return 1, None
    orientation = int(exif.get(_ORIENTATION_TAG, 1) or 1)
    if not len(exif):
        return orientation, None
    if _ORIENTATION_TAG in exif:
        exif[_ORIENTATION_TAG] = 1
    try:
        return orientation, exif.tobytes()
    except Exception:
        return orientation, None


def _split_alpha(arr: np.ndarray, path: Path, notes: list[str], *, alpha_last=True) -> np.ndarray:
    """Drop an alpha (or extra) channel from HxWxC; return HxW or HxWx3."""
    if arr.ndim == 2:
        return arr
    c = arr.shape[2]
    if c == 1:
        return arr[..., 0]
    if c == 2:
        notes.append(f"{path.name}: alpha channel ignored (grey + alpha image)")
        return arr[..., 0]
    if c == 3:
        return arr
    notes.append(f"{path.name}: alpha channel ignored ({c} channels; using the first 3 as RGB)")
    return arr[..., :3]


def _to_unit(arr: np.ndarray, path: Path, notes: list[str]) -> tuple[np.ndarray, int]:
    """Integer or float samples → float64 in [0, 1] and the source bit depth."""
    if arr.dtype == np.uint8 or arr.dtype == np.uint16:  # one float64 array, scaled in place
        out = arr.astype(np.float64)
        out /= 255.0 if arr.dtype == np.uint8 else 65535.0
        return out, 8 if arr.dtype == np.uint8 else 16
    if arr.dtype == bool:
        return arr.astype(np.float64), 8
    if np.issubdtype(arr.dtype, np.floating):
        out = arr.astype(np.float64)
        if not np.all(np.isfinite(out)):
            raise PhotoError(f"{path}: floating-point image contains NaN or Inf values")
        lo, hi = float(out.min()), float(out.max())
        if lo < 0 or hi > 1:
            notes.append(f"{path.name}: float values in [{lo:.3g}, {hi:.3g}] clipped to [0, 1]")
        return np.clip(out, 0.0, 1.0), 32
    if np.issubdtype(arr.dtype, np.integer):
        hi = int(arr.max()) if arr.size else 0
        if arr.min() >= 0 and hi <= 65535:
            bits = 8 if hi <= 255 and arr.dtype.itemsize == 1 else 16
            return arr.astype(np.float64) / (255.0 if bits == 8 else 65535.0), bits
    raise PhotoError(f"{path}: unsupported sample format {arr.dtype} (expected 8/16-bit integers or float)")


def _read_exr(path: Path, notes: list[str], repair_nonfinite: bool) -> tuple[np.ndarray, int]:
    import OpenEXR

    from scenes.display import linear_to_srgb

    try:
        channels = {k: np.asarray(v.pixels) for k, v in OpenEXR.File(str(path)).channels().items()}
    except Exception as exc:
        raise PhotoError(f"{path}: corrupt or truncated OpenEXR file ({exc})") from None
    if "RGBA" in channels or "RGB" in channels:
        arr = channels.get("RGB", channels.get("RGBA"))
        if arr.shape[-1] == 4:
            notes.append(f"{path.name}: alpha channel ignored")
            arr = arr[..., :3]
    elif "Y" in channels:
        arr = channels["Y"]
    elif len(channels) == 1:
        arr = next(iter(channels.values()))
        if arr.ndim == 3:
            arr = _split_alpha(arr, path, notes)
    elif all(c in channels for c in ("R", "G", "B")):
        arr = np.stack([channels[c] for c in ("R", "G", "B")], axis=-1)
    else:
        raise PhotoError(f"{path}: no RGB or Y channels in this OpenEXR file (has {sorted(channels)})")
    arr = np.asarray(arr, dtype=np.float64)
    bad = ~np.isfinite(arr)
    n_bad = int(bad.sum())
    if n_bad:
        if not repair_nonfinite:
            raise PhotoError(
                f"{path}: {n_bad} NaN/Inf sample(s) in the EXR; refused "
                "(rerun with --repair-nonfinite to set NaN and -Inf to 0 and +Inf to 1)"
            )
        arr = np.where(np.isnan(arr) | np.isneginf(arr), 0.0, np.where(np.isposinf(arr), 1.0, arr))
        notes.append(f"{path.name}: repaired {n_bad} NaN/Inf sample(s) (NaN, -Inf → 0; +Inf → 1)")
    over = float(np.mean(arr > 1.0))
    if over > 0:
        notes.append(f"{path.name}: {100 * over:.2g}% of linear samples above 1.0 clipped to white")
    return linear_to_srgb(arr), 32


def _read_png16(path: Path, notes: list[str]) -> np.ndarray:
    import imagecodecs

    try:
        arr = imagecodecs.png_decode(path.read_bytes())
    except Exception as exc:
        raise PhotoError(f"{path}: corrupt or truncated PNG ({exc})") from None
    return _split_alpha(np.asarray(arr), path, notes)


def _read_tiff(path: Path, notes: list[str]) -> tuple[np.ndarray, int] | None:
    """Decode a TIFF with tifffile; None when it should go through Pillow (palette, CMYK, …)."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages.first
            photometric = int(page.photometric)
            orientation = int(page.orientation) if hasattr(page, "orientation") else 1
            if photometric not in (0, 1, 2):  # MINISWHITE, MINISBLACK, RGB
                return None
            arr = page.asarray()
            axes = page.axes
    except PhotoError:
        raise
    except Exception as exc:
        raise PhotoError(f"{path}: corrupt or truncated TIFF ({exc})") from None
    arr = np.asarray(arr)
    # tifffile gives planar images as SYX; bring samples last
    if axes.startswith("S") and arr.ndim == 3:
        arr = np.moveaxis(arr, 0, -1)
    arr = np.squeeze(arr) if arr.ndim > 3 else arr
    if arr.ndim not in (2, 3):
        raise PhotoError(f"{path}: unsupported TIFF layout {axes} {arr.shape}")
    arr = _split_alpha(arr, path, notes)
    if photometric == 0:  # MINISWHITE: 0 is white
        if arr.dtype == np.uint8 or arr.dtype == np.uint16:
            arr = np.iinfo(arr.dtype).max - arr
        elif arr.dtype == bool:
            arr = ~arr
        else:
            arr = 1.0 - arr
    image, bits = _to_unit(arr, path, notes)
    return apply_orientation(image, orientation), bits


def _read_pillow(path: Path, notes: list[str]) -> tuple[np.ndarray, int, bytes | None, bytes | None, int]:
    im = _open_pillow(path)
    with im:
        orientation, exif = _exif_of(im)
        icc = im.info.get("icc_profile")
        try:
            im.load()
        except Exception as exc:
            raise PhotoError(f"{path}: corrupt or truncated {im.format or 'image'} file ({exc})") from None
        mode = im.mode
        if mode in ("1", "L", "RGB"):
            arr = np.asarray(im.convert("L") if mode == "1" else im)
        elif mode in ("LA", "RGBA", "La", "RGBa"):
            arr = np.asarray(im.convert(mode[:-1] + "A") if mode.endswith("a") else im)
        elif mode in ("P", "PA"):
            has_alpha = mode == "PA" or "transparency" in im.info
            arr = np.asarray(im.convert("RGBA" if has_alpha else "RGB"))
        elif mode.startswith("I;16") or mode in ("I", "F"):
            arr = np.asarray(im)
            if mode.startswith("I;16"):
                arr = arr.astype(np.uint16)
        else:  # CMYK, YCbCr, LAB, HSV …
            notes.append(f"{path.name}: {mode} image converted to RGB")
            arr = np.asarray(im.convert("RGB"))
    arr = _split_alpha(arr, path, notes)
    image, bits = _to_unit(arr, path, notes)
    return image, bits, exif, icc, orientation


def read_photo(path, *, max_pixels=DEFAULT_MAX_PIXELS, repair_nonfinite=False) -> Photo:
    """Read a photo into a float image in [0, 1], upright, alpha dropped.

    Parameters
    ----------
    path : str or Path
        JPEG, PNG (8/16-bit, grey, RGB, palette, with or without alpha), TIFF (8/16-bit, float,
        grey or RGB), OpenEXR (linear light; encoded to sRGB), or any other format Pillow reads.
    max_pixels : int or None, keyword-only
        Pixel budget (width × height) checked from the header *before* decoding; None disables it
        (Pillow's decompression-bomb guard still applies to Pillow formats).
    repair_nonfinite : bool, keyword-only
        EXR only: replace NaN and -Inf by 0 and +Inf by 1 (linear) instead of refusing the file.

    Returns
    -------
    Photo
        ``image`` is float64, HxWx3 (colour) or HxW (grey), in [0, 1], display-encoded.

    Raises
    ------
    PhotoError (a ValueError)
        Missing path, a directory, an empty, truncated or corrupt file, not an image, a pixel count
        over ``max_pixels``, NaN/Inf samples (unless repaired), an unsupported sample format.

    Notes
    -----
    1. Check the path (exists, a regular readable file, not empty) and identify the format by its
       first bytes (not by its extension).
    2. Read the header only and compare width × height with ``max_pixels``.
    3. Decode with the decoder suited to the format and bit depth (see the module docstring).
    4. Drop alpha (noted), scale integers by 255 or 65535, apply the EXIF orientation.
    """
    header = probe_photo(path)
    _check_budget(header, max_pixels)
    path = header.path
    notes: list[str] = []
    exif = icc = None
    kind = header.format
    if kind == "EXR":
        image, bits = _read_exr(path, notes, repair_nonfinite)
    elif kind == "TIFF" and (decoded := _read_tiff(path, notes)) is not None:
        image, bits = decoded
        exif, icc = _tiff_metadata(path)
    elif kind == "PNG" and _png_ihdr(path)[2] == 16:
        arr = _read_png16(path, notes)
        image, bits = _to_unit(arr, path, notes)
        # EXIF (eXIf chunk) orientation and ICC from Pillow's header parse
        with _open_pillow(path) as im:
            orientation, exif = _exif_of(im)
            icc = im.info.get("icc_profile")
        image = apply_orientation(image, orientation)
    else:
        image, bits, exif, icc, orientation = _read_pillow(path, notes)
        image = apply_orientation(image, orientation)
    image = np.ascontiguousarray(image, dtype=np.float64)
    return Photo(image=image, bit_depth=bits, format=kind, path=path, notes=tuple(notes),
                 exif=exif, icc_profile=icc)


def _tiff_metadata(path: Path) -> tuple[bytes | None, bytes | None]:
    try:
        with _open_pillow(path) as im:
            return _exif_of(im)[1], im.info.get("icc_profile")
    except PhotoError:
        return None, None


# ------------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------------


def _write_exr_channels(path: Path, channels: dict) -> Path:
    """float32 channels → ZIP-compressed (lossless) scanline EXR, atomically."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    prepared = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    with atomic_write(path) as tmp:
        OpenEXR.File(header, prepared).write(str(tmp))
    return path


def output_bit_depth(suffix: str, source_bit_depth: int | None = None) -> int:
    """Bits per sample a photo written with this extension gets.

    Parameters
    ----------
    suffix : str
        Output extension, e.g. ``".png"``.
    source_bit_depth : int, optional
        The input's bit depth (8, 16, 32 = float); None means 8.

    Returns
    -------
    int
        8 for JPEG; for PNG/TIFF 8 when the source had 8 bits, else 16; 32 (float) for EXR.
    """
    suffix = suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise PhotoError(f"output extension {suffix or '(none)'!r} not supported; allowed: {', '.join(OUTPUT_SUFFIXES)}")
    if suffix in (".jpg", ".jpeg"):
        return 8
    if suffix == ".exr":
        return 32
    return 8 if (source_bit_depth or 8) <= 8 else 16


def _quantise(image: np.ndarray, bits: int, *, rows=256) -> np.ndarray:
    """[0, 1] floats → rounded 8/16-bit codes, in strips of rows (no full-size float temporaries)."""
    levels = 255.0 if bits == 8 else 65535.0
    out = np.empty(image.shape, dtype=np.uint8 if bits == 8 else np.uint16)
    for y in range(0, image.shape[0], rows):
        strip = np.clip(image[y:y + rows], 0.0, 1.0) * levels
        out[y:y + rows] = np.round(strip, out=strip)
    return out


def write_photo(path, image, *, bit_depth=None, exif=None, icc_profile=None) -> Path:
    """Write a float image in [0, 1] to a file whose format follows the extension, atomically.

    Parameters
    ----------
    path : str or Path
        Destination: ``.jpg``/``.jpeg`` (8-bit), ``.png`` or ``.tif``/``.tiff`` (8 or 16-bit),
        ``.exr`` (float32, linear: the values are sRGB-decoded). Its folder must exist.
    image : ndarray, HxWx3 or HxW, float in [0, 1]
        Display-encoded (sRGB) values; grey images are written as grey.
    bit_depth : int, optional, keyword-only
        8 or 16 for PNG/TIFF (default 8); ignored for JPEG (always 8) and EXR (float).
    exif, icc_profile : bytes, optional, keyword-only
        Metadata passed through to JPEG, 8-bit PNG and TIFF (16-bit PNG carries none).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    PhotoError
        Unsupported extension, bad image shape, NaN/Inf values, bad bit depth.
    OSError
        The folder does not exist or is not writable.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise PhotoError(f"{path}: output extension {suffix or '(none)'!r} not supported; allowed: {', '.join(OUTPUT_SUFFIXES)}")
    image = np.asarray(image, dtype=np.float64)
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] != 3) or min(image.shape[:2]) < 1:
        raise PhotoError(f"image to write has shape {image.shape}; allowed: HxW or HxWx3")
    if not np.all(np.isfinite(image)):
        raise PhotoError("image to write contains NaN or Inf values")
    if suffix in (".jpg", ".jpeg"):
        bits = 8
    elif suffix == ".exr":
        bits = 32
    else:
        bits = 8 if bit_depth is None else int(bit_depth)
        if bits not in (8, 16):
            raise PhotoError(f"bit_depth={bit_depth!r} invalid for {suffix}; allowed: 8 or 16")

    if suffix == ".exr":
        from scenes.display import srgb_to_linear

        linear = srgb_to_linear(image).astype(np.float32)
        return _write_exr_channels(path, {"RGB" if image.ndim == 3 else "Y": linear})

    data = _quantise(image, bits)
    with atomic_write(path) as tmp:
        if suffix in (".tif", ".tiff"):
            import tifffile

            extratags = []
            if icc_profile:
                extratags.append((34675, 7, len(icc_profile), icc_profile, True))
            tifffile.imwrite(tmp, data, photometric="rgb" if data.ndim == 3 else "minisblack",
                             compression="zlib", extratags=extratags, metadata=None)
        elif suffix == ".png" and bits == 16:
            import imagecodecs

            tmp.write_bytes(imagecodecs.png_encode(data))
        else:
            from PIL import Image

            im = Image.fromarray(data, mode="RGB" if data.ndim == 3 else "L")
            kwargs = {}
            if exif:
                kwargs["exif"] = exif
            if icc_profile:
                kwargs["icc_profile"] = icc_profile
            if suffix in (".jpg", ".jpeg"):
                im.save(tmp, format="JPEG", quality=JPEG_QUALITY, subsampling=JPEG_SUBSAMPLING, **kwargs)
            else:
                im.save(tmp, format="PNG", **kwargs)
    return path


def write_defocus_map(path, sigma) -> Path:
    """Write a dense defocus map (σ in px) as raw data, atomically.

    Parameters
    ----------
    path : str or Path
        ``.exr`` (float32 channel ``"sigma"``, lossless) or ``.npy`` (float64 as given).
        The colour-mapped PNG preview is plotting and lives with the CLI (``repro.estimate``).
    sigma : ndarray, HxW, float
        Blur σ in px of the photo it belongs to; finite.

    Returns
    -------
    Path
    """
    path = Path(path)
    sigma = np.asarray(sigma)
    if sigma.ndim != 2:
        raise PhotoError(f"defocus map has shape {sigma.shape}; allowed: HxW")
    suffix = path.suffix.lower()
    if suffix == ".exr":
        return _write_exr_channels(path, {"sigma": sigma.astype(np.float32)})
    if suffix == ".npy":
        with atomic_write(path) as tmp:
            with open(tmp, "wb") as fh:
                np.save(fh, np.ascontiguousarray(sigma), allow_pickle=False)
        return path
    raise PhotoError(f"{path}: map extension {suffix or '(none)'!r} not supported here; allowed: .exr, .npy")
