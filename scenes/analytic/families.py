"""Texture families: the surfaces a lens blurs in real scenes, beyond the 1/f² statistics of dead leaves.

Natural textures are roughly 1/f² on average, but single windows of real walls are often periodic
(checks, stripes, fabric, brick), text, flat patches with sharp borders, or smooth shading with no
texture at all (../shared/research/LENS-AND-CAMERA.md). A blur estimator built on one family's
statistics must be judged on the others, and say "no measure" where a texture carries no blur
information. Every family of :data:`TEXTURE_FAMILIES` draws a sharp texture on a window of a lattice
``s`` times finer than the output pixels:

``fn(size, *, s, seed, key, origin) -> ndarray (ny, nx, 3)`` of display (sRGB-encoded) values in [0, 1]

where fine sample (i, j) is the plane point (y, x) = ((origin[0] + i)/s, (origin[1] + j)/s) in
output px. Each texture is a *plane* drawn from ``(seed, key)``: its parameters (period, angle,
colours, …) come from ``SeedSequence(seed, spawn_key=key)`` and do not depend on the window, so the
same plane shows the same pattern in any window (a tile of a mosaic and its blur support agree).

Every family is sharp on the fine lattice (intrinsic blur 0) except ``photo``, whose photographs
carry their own blur (:data:`PHOTO_INTRINSIC_SIGMA_PX`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from types import MappingProxyType

import numpy as np

from .leaves import leaves_labels
from .mosaics import SKIMAGE_IMAGES, SKIMAGE_NATIVE_SIGMA_PX

__all__ = ["PHOTO_INTRINSIC_SIGMA_PX", "PHOTO_SUPERSAMPLE", "TEXTURE_FAMILIES", "TextureFamily", "check_family",
           "family_texture", "texture_bitmap"]

#: The ``photo`` family shows the scikit-image photographs at native resolution on the fine lattice
#: when s = PHOTO_SUPERSAMPLE (one native pixel per fine sample; the s×s box average of the mosaics is
#: then the area downsampling of :func:`scenes.analytic.texture_mosaic`'s "skimage" tiles).
PHOTO_SUPERSAMPLE = 4
#: Assumed intrinsic blur σ₀ (output px) of the ``photo`` family at s = PHOTO_SUPERSAMPLE: the native
#: photographs' own blur (optics, demosaicing, JPEG; assumed 1 native px) shrunk by the factor. The
#: pixel box is part of every lens mosaic's σ, so it is not counted here. An estimate, not a measurement.
PHOTO_INTRINSIC_SIGMA_PX = SKIMAGE_NATIVE_SIGMA_PX / PHOTO_SUPERSAMPLE


@dataclasses.dataclass(frozen=True)
class TextureFamily:
    """One texture family.

    Attributes
    ----------
    fn : callable
        ``fn(size, *, s, seed, key, origin) -> (ny, nx, 3)`` display values (see the module docstring).
    summary : str
        What it draws.
    model_breaking : bool
        True where the texture departs from the 1/f² statistics a spectral blur model assumes
        (periodic, text, flat, shading); False for dead leaves and photographs.
    intrinsic_sigma : float
        Blur σ₀ (output px) the sharp texture already has at s = 4; σ_gt = √(σ² + σ₀²).
    """

    fn: Callable
    summary: str
    model_breaking: bool
    intrinsic_sigma: float = 0.0


def _params_rng(seed, key):
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=tuple(int(k) for k in key)))


def _plane(size, s, origin):
    """Plane coordinates (y, x) in output px of the fine samples of a window."""
    ny, nx = size
    y = (origin[0] + np.arange(ny)) / s
    x = (origin[1] + np.arange(nx)) / s
    return y[:, None], x[None, :]


def _two_colours(gen, min_contrast=0.3):
    """Two display colours whose channel means differ by at least ``min_contrast`` (visible in grey)."""
    while True:
        c = gen.uniform(0.05, 0.95, size=(2, 3))
        if abs(float(np.mean(c[0] - c[1]))) >= min_contrast:
            return c


def _rotated(y, x, angle):
    c, s_ = math.cos(angle), math.sin(angle)
    return x * c + y * s_, -x * s_ + y * c


def _dead_leaves(size, *, s, seed, key, origin):
    labels, colours = leaves_labels(int(seed), tuple(key), origin, size, s, (2.0, 32.0), 3, None, (0.1, 0.9))
    return colours[labels]


def _checker(size, *, s, seed, key, origin):
    gen = _params_rng(seed, key)
    period = float(gen.choice([6.0, 8.0, 12.0, 16.0, 24.0]))  # px per pair of squares
    angle = float(gen.uniform(0.0, math.pi / 2))
    c = _two_colours(gen)
    y, x = _plane(size, s, origin)
    u, v = _rotated(y, x, angle)
    parity = (np.floor(u / (period / 2)) + np.floor(v / (period / 2))).astype(np.int64) % 2
    return c[parity]


def _stripes(size, *, s, seed, key, origin):
    gen = _params_rng(seed, key)
    period = float(gen.choice([4.0, 6.0, 8.0, 12.0, 16.0, 24.0]))  # px per pair of stripes
    angle = float(gen.uniform(0.0, math.pi))
    c = _two_colours(gen)
    y, x = _plane(size, s, origin)
    u, _ = _rotated(y, x, angle)
    u = np.broadcast_to(u, (size[0], size[1]))
    return c[np.floor(u / (period / 2)).astype(np.int64) % 2]


_WORDS = ("defocus", "magnification", "lens", "aperture", "focus", "blur", "circle", "confusion", "thin",
          "sensor", "depth", "field", "edge", "scale", "image", "light", "photo", "camera", "bokeh", "map",
          "Bae", "Durand", "2007", "f/8", "f/4", "85mm", "ISO", "RAW", "JPEG", "sRGB")


@functools.lru_cache(maxsize=16)
def _font(px):
    from PIL import ImageFont

    return ImageFont.load_default(size=int(px))


def _text(size, *, s, seed, key, origin):
    """Lines of words on a page rotated about the plane's origin, looked up at the fine samples."""
    from PIL import Image, ImageDraw

    gen = _params_rng(seed, key)
    font_px = float(gen.choice([8.0, 10.0, 12.0, 16.0]))  # output px
    angle = math.radians(float(gen.uniform(-15.0, 15.0)))
    ink, paper = (0.08, 0.92) if gen.random() < 0.7 else (0.92, 0.15)
    line = 1.4 * font_px * s  # fine px between baselines
    y, x = _plane(size, s, origin)
    u, v = _rotated(y * s, x * s, angle)  # page coordinates, fine px
    u, v = np.broadcast_to(u, (size[0], size[1])), np.broadcast_to(v, (size[0], size[1]))
    u0, v0 = int(math.floor(u.min())) - 1, int(math.floor(v.min())) - 1
    w, h = int(math.ceil(u.max())) - u0 + 2, int(math.ceil(v.max())) - v0 + 2
    page = Image.new("L", (w, h), int(round(paper * 255)))
    draw = ImageDraw.Draw(page)
    font = _font(font_px * s)
    for k in range(int(math.floor(v0 / line)) - 1, int(math.ceil((v0 + h) / line)) + 1):
        # each line repeats its own phrase from its own stream: the page does not depend on the window
        lg = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=tuple(key) + (k + 2 ** 31,)))
        phrase = " ".join(str(word) for word in lg.choice(_WORDS, size=12)) + " "
        width = max(font.getlength(phrase), 1.0)
        shift = float(lg.uniform(0.0, width))
        for m in range(int(math.floor((u0 - shift) / width)) - 1, int(math.ceil((u0 + w - shift) / width)) + 1):
            draw.text((shift + m * width - u0, k * line - v0), phrase, font=font, fill=int(round(ink * 255)))
    a = np.asarray(page, dtype=np.float64) / 255.0
    a = a[np.clip(np.rint(v - v0).astype(np.int64), 0, h - 1), np.clip(np.rint(u - u0).astype(np.int64), 0, w - 1)]
    return np.repeat(a[..., None], 3, axis=2)


def _brick(size, *, s, seed, key, origin):
    gen = _params_rng(seed, key)
    length = float(gen.uniform(12.0, 32.0))  # px
    height = length / 2.5
    mortar = float(gen.choice([1.0, 1.5, 2.0]))
    angle = float(gen.uniform(-0.3, 0.3))
    base = np.array([gen.uniform(0.45, 0.75), gen.uniform(0.2, 0.4), gen.uniform(0.12, 0.3)])
    mortar_c = np.full(3, gen.uniform(0.6, 0.85))
    y, x = _plane(size, s, origin)
    u, v = _rotated(y, x, angle)
    row = np.floor(v / height)
    uu = u + 0.5 * length * (row % 2)
    col = np.floor(uu / length)
    in_mortar = ((v - row * height) < mortar) | ((uu - col * length) < mortar)
    # per-brick colour jitter from a hash of (row, col): window-independent
    h = (np.sin(row * 12.9898 + col * 78.233 + (seed % 1000) * 0.1) * 43758.5453) % 1.0
    bricks = np.clip(base[None, None, :] * (0.8 + 0.4 * h[..., None]), 0.0, 1.0)
    return np.where(in_mortar[..., None], mortar_c[None, None, :], bricks)


def _flat_patches(size, *, s, seed, key, origin):
    """Voronoi cells of jittered points on a 64-px grid, each one flat colour (sharp straight borders)."""
    cell = 64.0
    y, x = _plane(size, s, origin)
    iy = np.floor(y / cell).astype(np.int64)
    ix = np.floor(x / cell).astype(np.int64)
    best = np.full((size[0], size[1]), np.inf)
    colour = np.zeros((size[0], size[1], 3))
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            cy, cx = iy + dy, ix + dx  # (ny, 1), (1, nx)
            for yy in np.unique(cy):
                for xx in np.unique(cx):
                    g = _params_rng(seed, tuple(key) + (int(yy) + 2 ** 31, int(xx) + 2 ** 31))
                    py, px = (yy + g.uniform(0.1, 0.9)) * cell, (xx + g.uniform(0.1, 0.9)) * cell
                    col = g.uniform(0.1, 0.9, size=3)
                    sel_y = (cy[:, 0] == yy)[:, None]
                    sel_x = (cx[0] == xx)[None, :]
                    d = np.where(sel_y & sel_x, (y - py) ** 2 + (x - px) ** 2, np.inf)
                    nearer = d < best
                    best = np.where(nearer, d, best)
                    colour = np.where(nearer[..., None], col[None, None, :], colour)
    return colour


def _shading(size, *, s, seed, key, origin):
    """Smooth shading: three random cosines of wavelength 150–400 px, no edges."""
    gen = _params_rng(seed, key)
    y, x = _plane(size, s, origin)
    field = np.zeros((size[0], size[1]))
    for _ in range(3):
        lam = gen.uniform(150.0, 400.0)
        th = gen.uniform(0.0, 2 * math.pi)
        field = field + np.cos(2 * math.pi * (x * math.cos(th) + y * math.sin(th)) / lam + gen.uniform(0, 2 * math.pi))
    tint = gen.uniform(0.7, 1.0, size=3)
    return np.clip((0.5 + 0.1 * field)[..., None] * tint[None, None, :], 0.0, 1.0)


@functools.lru_cache(maxsize=1)
def _photos():
    import skimage.data

    return tuple(np.asarray(getattr(skimage.data, n)(), dtype=np.float64)[..., :3] / 255.0 for n in SKIMAGE_IMAGES)


def _photo(size, *, s, seed, key, origin):
    """A crop of a scikit-image photograph at native resolution (zoomed by s/4 when s ≠ 4), mirror-extended."""
    gen = _params_rng(seed, key)
    src = _photos()[int(gen.integers(len(SKIMAGE_IMAGES)))]
    # plane origin (0, 0) inside the photograph with 400 native px (100 output px at s = 4) to spare
    oy = int(gen.integers(max(src.shape[0] - 400, 1)))
    ox = int(gen.integers(max(src.shape[1] - 400, 1)))
    zoom = PHOTO_SUPERSAMPLE / s
    iy = np.floor((origin[0] + np.arange(size[0])) * zoom).astype(np.int64) + oy
    ix = np.floor((origin[1] + np.arange(size[1])) * zoom).astype(np.int64) + ox

    def reflect(k, n):
        k = np.mod(k, 2 * n)
        return np.where(k < n, k, 2 * n - 1 - k)

    return src[reflect(iy, src.shape[0])[:, None], reflect(ix, src.shape[1])[None, :]]


#: name -> :class:`TextureFamily`.
TEXTURE_FAMILIES = MappingProxyType({
    "dead_leaves": TextureFamily(_dead_leaves, "occluding discs, radii 2–32 px ∝ r⁻³ (1/f² statistics)", False),
    "photo": TextureFamily(_photo, "crops of scikit-image photographs at native resolution", False,
                           PHOTO_INTRINSIC_SIGMA_PX),
    "checker": TextureFamily(_checker, "checkerboard, period 6–24 px, any angle (periodic)", True),
    "stripes": TextureFamily(_stripes, "hard-edged stripes, period 4–24 px, any angle (periodic)", True),
    "text": TextureFamily(_text, "lines of text, 8–16 px type, ±15° (sparse sharp strokes)", True),
    "brick": TextureFamily(_brick, "running-bond brick, 12–32 px bricks, 1–2 px mortar (periodic)", True),
    "flat_patches": TextureFamily(_flat_patches, "flat Voronoi patches ~64 px with sharp borders (flat)", True),
    "shading": TextureFamily(_shading, "smooth shading, wavelengths 150–400 px (no texture)", True),
})


def check_family(name) -> str:
    """``name`` if it is a key of :data:`TEXTURE_FAMILIES`, else ValueError listing them."""
    if not isinstance(name, str) or name not in TEXTURE_FAMILIES:
        raise ValueError(f"family={name!r} is invalid (unknown texture family); allowed: {', '.join(TEXTURE_FAMILIES)}")
    return name


def family_texture(name, size, *, s=4, seed=0, key=(), origin=(0, 0)) -> np.ndarray:
    """A window of texture plane ``(seed, key)`` of family ``name`` on the fine lattice.

    Parameters
    ----------
    name : str
        Key of :data:`TEXTURE_FAMILIES`.
    size : (int, int)
        Window (ny, nx) in fine samples.
    s : int, keyword-only
        Fine samples per output px.
    seed : int, keyword-only
        Seed >= 0 of the plane.
    key : tuple of int, keyword-only
        Which plane of that seed (e.g. the tile index).
    origin : (int, int), keyword-only
        Fine-lattice coordinates of sample (0, 0).

    Returns
    -------
    ndarray, (ny, nx, 3), float64
        Display (sRGB-encoded) values in [0, 1].
    """
    fam = TEXTURE_FAMILIES[check_family(name)]
    out = np.asarray(fam.fn((int(size[0]), int(size[1])), s=int(s), seed=int(seed), key=tuple(key),
                            origin=(int(origin[0]), int(origin[1]))), dtype=np.float64)
    return np.clip(np.broadcast_to(out, (int(size[0]), int(size[1]), 3)), 0.0, 1.0)


def texture_bitmap(name, size_px, *, seed=0, key=()) -> np.ndarray:
    """A square sharp texture image of family ``name`` (one texel per px), e.g. for a rendered surface.

    Parameters
    ----------
    name : str
        Key of :data:`TEXTURE_FAMILIES`.
    size_px : int
        Side, texels.
    seed : int, keyword-only
    key : tuple of int, keyword-only

    Returns
    -------
    ndarray, (size_px, size_px, 3), float32, display (sRGB-encoded) values in [0, 1]
    """
    n = int(size_px)
    return family_texture(name, (n, n), s=1, seed=seed, key=key).astype(np.float32)
