"""Procedural and bundled textures (no downloads), as linear float32 RGB arrays in [0, 1].

Every function is deterministic (seeded) and cached; the returned arrays are read-only. Array row 0
is the *top* of the texture and column 0 its *left* edge; :mod:`scenes.library.base` maps them so
they appear that way in the rendered image.
"""

from __future__ import annotations

import functools

import numpy as np

from ..display import srgb_to_linear

__all__ = ["BUNDLED_PHOTOS", "checker", "dead_leaves", "photo", "stripes"]

#: ``skimage.data`` images that ship inside the scikit-image wheel (no network access needed).
BUNDLED_PHOTOS = ("astronaut", "brick", "camera", "chelsea", "coffee", "grass", "gravel", "rocket", "text")


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float32)
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=64)
def photo(name: str, *, lo: float = 0.03, hi: float = 0.9) -> np.ndarray:
    """A ``skimage.data`` photograph, decoded from sRGB to linear and rescaled to [lo, hi].

    Parameters
    ----------
    name : str
        One of :data:`BUNDLED_PHOTOS`.
    lo, hi : float, keyword-only
        Linear range the image is mapped to (keeps emission below display white; no clipping).

    Returns
    -------
    ndarray, HxWx3 float32, linear, read-only
    """
    if name not in BUNDLED_PHOTOS:
        raise ValueError(f"unknown photo {name!r}; choose one of {list(BUNDLED_PHOTOS)}")
    import skimage.data

    img = np.asarray(getattr(skimage.data, name)())
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    img = img[:, :, :3].astype(np.float64) / 255.0
    lin = srgb_to_linear(img)
    return _readonly(lo + (hi - lo) * lin)


@functools.lru_cache(maxsize=64)
def dead_leaves(
    size: int = 512,
    *,
    seed: int = 0,
    n_discs: int = 3000,
    r_min: float = 2.0,
    r_max: float = 60.0,
    palette: tuple = ((0.03, 0.9),) * 3,
) -> np.ndarray:
    """A "dead leaves" texture: opaque discs of power-law radii painted over each other.

    Sharp edges at every orientation and at all scales between ``r_min`` and ``r_max`` — a good
    target for an edge-based blur estimator. Radii follow the scale-invariant density p(r) ∝ r⁻³.

    Parameters
    ----------
    size : int
        Side length in texels.
    seed : int, keyword-only
        RNG seed.
    n_discs : int, keyword-only
        Number of discs painted.
    r_min, r_max : float, keyword-only
        Radius range in texels.
    palette : tuple of three (lo, hi) pairs, keyword-only
        Uniform linear range of each RGB channel of a disc's colour.

    Returns
    -------
    ndarray, size x size x 3 float32, linear, read-only
    """
    rng = np.random.default_rng(seed)
    lo = np.array([p[0] for p in palette])
    hi = np.array([p[1] for p in palette])
    img = np.empty((size, size, 3), np.float64)
    img[:] = lo + (hi - lo) * rng.random(3)
    # Inverse CDF of p(r) ∝ r^-3 on [r_min, r_max].
    u = rng.random(n_discs)
    a, b = r_min**-2, r_max**-2
    radii = (a - u * (a - b)) ** -0.5
    centres = rng.random((n_discs, 2)) * size
    colours = lo + (hi - lo) * rng.random((n_discs, 3))
    yy, xx = np.mgrid[0:size, 0:size]
    for (cy, cx), r, col in zip(centres, radii, colours):
        y0, y1 = max(int(cy - r), 0), min(int(cy + r) + 2, size)
        x0, x1 = max(int(cx - r), 0), min(int(cx + r) + 2, size)
        if y0 >= y1 or x0 >= x1:
            continue
        m = (yy[y0:y1, x0:x1] - cy) ** 2 + (xx[y0:y1, x0:x1] - cx) ** 2 <= r * r
        img[y0:y1, x0:x1][m] = col
    return _readonly(img)


@functools.lru_cache(maxsize=64)
def checker(size: int = 256, *, cells: int = 8, colours: tuple = ((0.05,) * 3, (0.8,) * 3)) -> np.ndarray:
    """A checkerboard of ``cells`` x ``cells`` squares; the top-left square has ``colours[0]``.

    Returns
    -------
    ndarray, size x size x 3 float32, linear, read-only
    """
    idx = (np.arange(size) * cells // size)
    parity = (idx[:, None] + idx[None, :]) % 2
    c = np.asarray(colours, dtype=np.float64)
    return _readonly(c[parity])


@functools.lru_cache(maxsize=64)
def stripes(
    size: int = 256, *, period: int = 32, colours: tuple = ((0.7, 0.1, 0.1), (0.9, 0.85, 0.7)), vertical: bool = True
) -> np.ndarray:
    """Hard-edged stripes, ``period`` texels per pair; vertical stripes vary along the columns.

    Returns
    -------
    ndarray, size x size x 3 float32, linear, read-only
    """
    idx = (np.arange(size) // (period // 2)) % 2
    c = np.asarray(colours, dtype=np.float64)
    band = c[idx]  # size x 3
    img = np.broadcast_to(band[None, :, :] if vertical else band[:, None, :], (size, size, 3))
    return _readonly(img)
