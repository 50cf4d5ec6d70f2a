"""Photo file limits and formats, and what reading one gives: :class:`PhotoHeader`, :class:`Photo`,
:class:`PhotoError` (of :mod:`repro.photo_io`)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

__all__ = ["DEFAULT_MAX_PIXELS", "JPEG_QUALITY", "JPEG_SUBSAMPLING", "OUTPUT_SUFFIXES", "Photo", "PhotoError",
           "PhotoHeader"]

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

EXR_MAGIC = b"\x76\x2f\x31\x01"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
JPEG_MAGIC = b"\xff\xd8\xff"
ORIENTATION_TAG = 0x0112


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
    image : ndarray, HxWx3 or HxW, float64
        The stored values in ``encoding``, upright (EXIF orientation applied), alpha dropped: in
        [0, 1], except linear light (OpenEXR), ≥ 0 with its highlights above 1 kept.
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
    encoding : str
        What the values are, a key of :data:`method.luma.ENCODINGS`: "srgb" (display values: JPEG,
        PNG, TIFF) or "linear" (linear light: OpenEXR).
    """

    image: np.ndarray
    bit_depth: int
    format: str
    path: Path
    notes: tuple[str, ...] = ()
    exif: bytes | None = None
    icc_profile: bytes | None = None
    encoding: str = "srgb"

    @property
    def is_grey(self) -> bool:
        """True for a single-channel (HxW) photo."""
        return self.image.ndim == 2
