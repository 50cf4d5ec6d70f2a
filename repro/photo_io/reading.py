"""Decoding photo files (of :mod:`repro.photo_io`): the header probe, the decoders, the EXIF orientation."""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from .formats import (EXR_MAGIC, JPEG_MAGIC, ORIENTATION_TAG, PNG_MAGIC, TIFF_MAGICS, DEFAULT_MAX_PIXELS, Photo,
                      PhotoError, PhotoHeader)

__all__ = ["apply_orientation", "probe_photo", "read_photo"]


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
    if head.startswith(EXR_MAGIC):
        return "EXR"
    if head.startswith(PNG_MAGIC):
        return "PNG"
    if head.startswith(JPEG_MAGIC):
        return "JPEG"
    if any(head.startswith(m) for m in TIFF_MAGICS):
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
    orientation = int(exif.get(ORIENTATION_TAG, 1) or 1)
    if not len(exif):
        return orientation, None
    if ORIENTATION_TAG in exif:
        exif[ORIENTATION_TAG] = 1
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
    negative = float(np.mean(arr < 0.0))
    if negative > 0:
        notes.append(f"{path.name}: {100 * negative:.2g}% of linear samples below 0 raised to 0")
    over = float(np.mean(arr > 1.0))
    if over > 0:
        notes.append(f"{path.name}: {100 * over:.2g}% of linear samples above 1.0 kept (highlights, up to "
                     f"{float(arr.max()):.4g})")
    return np.maximum(arr, 0.0), 32  # linear light, as stored, highlights unclipped (Photo.encoding "linear")


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
    """Read a photo into a float image (in [0, 1]; an EXR's linear light ≥ 0), upright, alpha dropped.

    Parameters
    ----------
    path : str or Path
        JPEG, PNG (8/16-bit, grey, RGB, palette, with or without alpha), TIFF (8/16-bit, float,
        grey or RGB), OpenEXR (linear light, kept linear and unclipped), or any other format Pillow reads.
    max_pixels : int or None, keyword-only
        Pixel budget (width × height) checked from the header *before* decoding; None disables it
        (Pillow's decompression-bomb guard still applies to Pillow formats).
    repair_nonfinite : bool, keyword-only
        EXR only: replace NaN and -Inf by 0 and +Inf by 1 (linear) instead of refusing the file.

    Returns
    -------
    Photo
        ``image`` is float64, HxWx3 (colour) or HxW (grey), its values as stored: ``encoding``
        "linear" for OpenEXR (linear light ≥ 0, highlights above 1 kept, negative samples raised to
        0), "srgb" for every other format (display values in [0, 1], as a camera delivers them).

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
    5. Declare the encoding from the format (OpenEXR "linear", others "srgb"); the photo tools'
       ``--encoding`` overrides it.
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
                 exif=exif, icc_profile=icc, encoding="linear" if kind == "EXR" else "srgb")


def _tiff_metadata(path: Path) -> tuple[bytes | None, bytes | None]:
    try:
        with _open_pillow(path) as im:
            return _exif_of(im)[1], im.info.get("icc_profile")
    except PhotoError:
        return None, None
