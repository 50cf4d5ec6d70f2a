"""Float32 multi-channel OpenEXR files for renders and their ground truth.

One file holds everything a render produced: linear ``RGB`` radiance, camera-space depth ``Z``
(metres, ``inf`` where the pixel-centre ray missed), the circle-of-confusion diameter ``coc`` (px)
and the blur ``sigma`` (px), plus boolean masks (stored as float32 0/1). Every channel is float32,
ZIP-compressed (lossless), so a value read back is bit-identical to the one written, ``inf`` and
``nan`` included. Files are written atomically (:func:`defocus_cache.atomic_write`).

Uses the ``OpenEXR`` 3.x Python API: ``OpenEXR.File(header, channels).write(path)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from defocus_cache import atomic_write

__all__ = ["read_exr", "write_exr"]


def _header():
    import OpenEXR

    return {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}


def write_exr(path, channels: Mapping[str, np.ndarray]) -> Path:
    """Write named float32 channels to one EXR file, atomically.

    Parameters
    ----------
    path : str or Path
        Destination (``.exr``); its folder must exist.
    channels : mapping of str to ndarray
        Each value HxW (one channel) or HxWx3 (stored as the three channels ``<name>.R/G/B`` when
        the name is not ``"RGB"``; ``"RGB"`` is stored as R, G, B). Booleans are stored as 0/1.
        Every array must share the same H and W. Values are cast to float32.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        On an empty mapping, a bad shape or mismatched image sizes.
    """
    import OpenEXR

    if not channels:
        raise ValueError("channels is empty; allowed: at least one HxW or HxWx3 array")
    prepared = {}
    size = None
    for name, arr in channels.items():
        a = np.asarray(arr)
        if a.dtype == bool:
            a = a.astype(np.float32)
        a = np.ascontiguousarray(a, dtype=np.float32)
        if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 3)):
            raise ValueError(f"channel {name!r} has shape {a.shape}; allowed: HxW or HxWx3")
        if size is None:
            size = a.shape[:2]
        elif a.shape[:2] != size:
            raise ValueError(f"channel {name!r} is {a.shape[:2]}, the others are {size}; allowed: equal HxW")
        if min(a.shape[:2]) < 1:
            raise ValueError(f"channel {name!r} has shape {a.shape}; allowed: H, W >= 1")
        prepared[str(name)] = a
    path = Path(path)
    with atomic_write(path) as tmp:
        OpenEXR.File(_header(), prepared).write(str(tmp))
    return path


def read_exr(path) -> dict[str, np.ndarray]:
    """Read every channel of an EXR file written by :func:`write_exr`.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    dict of str to ndarray
        float32 arrays, HxW or HxWx3 (``"RGB"``), exactly as written.
    """
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such EXR file: {path}")
    f = OpenEXR.File(str(path))
    return {name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
