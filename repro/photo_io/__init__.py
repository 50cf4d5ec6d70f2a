"""Reading and writing photographers' image files: JPEG, PNG, TIFF (8/16-bit) and OpenEXR.

The method wants a float image, HxW or HxWx3, and its encoding (sRGB display values in [0, 1], or
linear light ≥ 0, whose highlights above 1 an OpenEXR file keeps). This module turns a file into that (:func:`read_photo`, ``Photo.encoding``) and back
(:func:`write_photo`), keeping what a photographer
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
* EXR: the ``OpenEXR`` 3.x API. EXR holds *linear* light: it is read as such (``encoding``
  "linear"); on writing, an image in another encoding is sRGB-decoded (:func:`scenes.display.srgb_to_linear`).

The pixel budget (``max_pixels``) is checked from the file header, before any pixel is decoded,
so a 100-megapixel header costs nothing; Pillow's own ``DecompressionBombError`` is caught too.

The package: :mod:`.formats` (limits, format constants, :class:`PhotoError`, :class:`PhotoHeader`,
:class:`Photo`), :mod:`.reading` (:func:`probe_photo`, :func:`read_photo`, :func:`apply_orientation`)
and :mod:`.writing` (:func:`write_photo`, :func:`write_defocus_map`, :func:`output_bit_depth`); import
the names from ``repro.photo_io``.
"""

from .formats import DEFAULT_MAX_PIXELS, OUTPUT_SUFFIXES, Photo, PhotoError, PhotoHeader
from .reading import apply_orientation, probe_photo, read_photo
from .writing import output_bit_depth, write_defocus_map, write_photo

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
