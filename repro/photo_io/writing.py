"""Encoding photo files and defocus maps (of :mod:`repro.photo_io`), atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from defocus_cache import atomic_write

from .formats import JPEG_QUALITY, JPEG_SUBSAMPLING, OUTPUT_SUFFIXES, PhotoError

__all__ = ["output_bit_depth", "write_defocus_map", "write_photo"]


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


def write_photo(path, image, *, bit_depth=None, exif=None, icc_profile=None, encoding="srgb") -> Path:
    """Write a float image in [0, 1] to a file whose format follows the extension, atomically.

    Parameters
    ----------
    path : str or Path
        Destination: ``.jpg``/``.jpeg`` (8-bit), ``.png`` or ``.tif``/``.tiff`` (8 or 16-bit),
        ``.exr`` (float32, linear light). Its folder must exist.
    image : ndarray, HxWx3 or HxW, float in [0, 1] (≥ 0 for ``encoding="linear"``)
        Values in ``encoding``; grey images are written as grey.
    bit_depth : int, optional, keyword-only
        8 or 16 for PNG/TIFF (default 8); ignored for JPEG (always 8) and EXR (float).
    exif, icc_profile : bytes, optional, keyword-only
        Metadata passed through to JPEG, 8-bit PNG and TIFF (16-bit PNG carries none).
    encoding : str, keyword-only
        What the values are (:data:`method.luma.ENCODINGS`): "srgb" (default; sRGB-decoded for an
        EXR) or "linear" (written as given to an EXR, sRGB-encoded for the other formats).

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

    from method.luma import ENCODINGS

    if encoding not in ENCODINGS:
        raise PhotoError(f"encoding={encoding!r} is invalid; allowed: {ENCODINGS.allowed()}")
    if suffix == ".exr":
        from scenes.display import decode

        linear = (np.maximum(image, 0.0) if encoding == "linear" else decode(image, encoding)).astype(np.float32)
        return _write_exr_channels(path, {"RGB" if image.ndim == 3 else "Y": linear})
    if encoding == "linear":
        from scenes.display import linear_to_srgb

        image = linear_to_srgb(image)

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
