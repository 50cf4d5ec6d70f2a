"""Texture mosaics with known Gaussian blur per tile: dense ground truth for the defocus map.

Rectangular tiles of texture, each blurred by one known Gaussian σ (dense ground truth for the
defocus map). Dead-leaves textures are rendered on a supersampled grid, blurred there and
point-sampled at the output pixel centres; scikit-image photographs are area-downsampled and blurred
on the output grid with the discrete Gaussian (exact variance). The blur acts on the stored values;
mosaics blurred the way a lens blurs (disk PSFs in linear light, then a camera) are
:func:`scenes.analytic.lens.lens_mosaic`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._common import (check_band, check_bool, check_degrade, check_int, check_radius_range, check_sigmas,
                      check_supersample, seed_entropy, degrade)
from ._lattice import apply_stages_1d, apply_stages_2d, blur_stages, discrete_gaussian, stages_support
from .leaves import leaves_labels

__all__ = ["SKIMAGE_DOWNSAMPLE", "SKIMAGE_IMAGES", "SKIMAGE_INTRINSIC_SIGMA_PX", "SKIMAGE_NATIVE_SIGMA_PX",
           "TEXTURES", "TextureMosaic", "texture_mosaic"]


#: Texture families accepted by :func:`texture_mosaic` (``texture="..."``).
TEXTURES = ("dead_leaves", "skimage")

#: RGB photographs shipped inside scikit-image (they load from the installed package, no network)
#: used by ``texture="skimage"``; each tile takes a crop of one of them.
SKIMAGE_IMAGES = ("astronaut", "coffee", "rocket", "immunohistochemistry")

#: Integer area-downsampling factor applied to the scikit-image photographs
#: (``skimage.transform.downscale_local_mean``) before they are used as sharp textures.
SKIMAGE_DOWNSAMPLE = 4

#: Assumed Gaussian σ (px of the *native* photograph) of the photographs' own blur (optics,
#: demosaicing, JPEG): an estimate, not a measurement of these particular files.
SKIMAGE_NATIVE_SIGMA_PX = 1.0

#: Estimated intrinsic blur σ₀ (px) of a downsampled photograph: the area average of
#: ``SKIMAGE_DOWNSAMPLE``² native pixels is a 1-px box (variance 1/12 px²) plus the native blur
#: shrunk by the factor, σ₀ = √(1/12 + (SKIMAGE_NATIVE_SIGMA_PX / SKIMAGE_DOWNSAMPLE)²) ≈ 0.38 px.
#: An ESTIMATE (second moments added as if both were Gaussian; the native blur is assumed): the
#: skimage ground truth σ_gt = √(σ² + σ₀²) is uncertain by roughly ±0.15 px at small σ.
#: Sanity check (grey, σ = 0 tiles, 6 seeds): the edge estimators "model_fit" / "zero_crossing",
#: calibrated on dead leaves of known σ, imply σ₀ ≈ 0.41 / 0.33 px — consistent, but those
#: estimators' bias differs between the two textures by up to ~0.1 px, so this is not a measurement.
SKIMAGE_INTRINSIC_SIGMA_PX = float(np.sqrt(1.0 / 12.0 + (SKIMAGE_NATIVE_SIGMA_PX / SKIMAGE_DOWNSAMPLE) ** 2))




@dataclasses.dataclass(frozen=True)
class TextureMosaic:
    """A mosaic of textured tiles, each blurred by one known Gaussian, and its ground truth.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3) if colour else (H, W), float64
        The image in [0, 1] (after optional noise and quantisation).
    sigma : ndarray, shape (H, W), float64
        Ground-truth Gaussian blur σ (px) of the tile each pixel belongs to (for
        ``texture="skimage"`` this includes the photograph's estimated intrinsic blur:
        √(σ_t² + ``intrinsic_sigma``²)). Inside ``boundary`` the pixel is a mixture and this is
        only the nominal value of its tile.
    tile_index : ndarray, shape (H, W), int64
        Index t of the tile (into ``sigmas``) each pixel belongs to.
    boundary : ndarray, shape (H, W), bool
        Pixels within the mixing band of a seam with another tile (exclude them from metrics,
        like occlusion boundaries in rendered scenes).
    sigmas : tuple of float
        Blur σ_t (px) applied to each tile's texture, in tile order (row-major).
    texture : str
        Texture family, one of :data:`TEXTURES`.
    intrinsic_sigma : float
        Blur σ₀ (px) the sharp texture already has and that ``sigma`` includes: 0 for dead
        leaves (the point-sampling residual is not counted, see :func:`dead_leaves`),
        :data:`SKIMAGE_INTRINSIC_SIGMA_PX` (an estimate) for photographs.
    """

    image: np.ndarray
    sigma: np.ndarray
    tile_index: np.ndarray
    boundary: np.ndarray
    sigmas: tuple
    texture: str
    intrinsic_sigma: float


def _reflect_index(k, n):
    """Map integer indices onto [0, n) by mirror reflection with the edge sample repeated
    (scipy.ndimage mode "reflect": ... c b a | a b c ... z | z y x ...)."""
    k = np.mod(k, 2 * n)
    return np.where(k < n, k, 2 * n - 1 - k)


def _skimage_sources(color):
    """The downsampled scikit-image photographs, float64 [0, 1], (h, w, 3) or (h, w)."""
    import skimage.data
    from skimage.color import rgb2gray
    from skimage.transform import downscale_local_mean

    out = []
    for name in SKIMAGE_IMAGES:
        img = np.asarray(getattr(skimage.data, name)(), dtype=np.float64) / 255.0
        img = img[..., :3]
        if not color:
            img = rgb2gray(img)
        f = SKIMAGE_DOWNSAMPLE
        h, w = (img.shape[0] // f) * f, (img.shape[1] // f) * f
        factors = (f, f, 1) if img.ndim == 3 else (f, f)
        out.append(downscale_local_mean(img[:h, :w], factors))
    return out


def tile_layout(n, tile, cols):
    """Tile rectangles (r0, r1, c0, c1) in output px, row-major, and the canvas (H, W)."""
    cols = min(cols, n)
    rows = -(-n // cols)
    h, w = rows * tile, cols * tile
    rects = []
    for r in range(rows):
        k = min(cols, n - r * cols)
        edges = np.round(np.linspace(0, w, k + 1)).astype(int)  # an incomplete last row is widened
        rects += [(r * tile, (r + 1) * tile, int(edges[i]), int(edges[i + 1])) for i in range(k)]
    return rects, (h, w)


def boundary_mask(rects, shape, band_of):
    """Pixels whose centre is closer than band_of(t, u) px (Euclidean) to another tile u's extent."""
    h, w = shape
    out = np.zeros((h, w), dtype=bool)
    for t, (r0, r1, c0, c1) in enumerate(rects):
        yy, xx = np.mgrid[r0:r1, c0:c1].astype(np.float64)
        for u, (q0, q1, d0, d1) in enumerate(rects):
            if u == t:
                continue
            band = band_of(t, u)
            dy = np.maximum(np.maximum(q0 - 0.5 - yy, yy - (q1 - 0.5)), 0.0)
            dx = np.maximum(np.maximum(d0 - 0.5 - xx, xx - (d1 - 0.5)), 0.0)
            out[r0:r1, c0:c1] |= np.hypot(dy, dx) < band
    return out


@dataclasses.dataclass(frozen=True)
class _LayerWindows:
    """Where one tile's blurred layer is computed (see :func:`texture_mosaic`, Notes 1).

    Attributes
    ----------
    out : (int, int, int, int)
        (a0, a1, b0, b1): output rows [a0, a1) x columns [b0, b1), the tile plus its blur support.
    fine : (int, int, int, int)
        (fy0, fy1, fx0, fx1): the sharp window on the fine lattice, one more support beyond.
    mask : (int, int, int, int)
        (ty0, ty1, tx0, tx1): where M_t = 1 inside the fine window, fine-lattice samples.
    """

    out: tuple
    fine: tuple
    mask: tuple


#: "Infinite" extent of tiles touching the canvas border, fine-lattice samples.
_UNBOUNDED = 1 << 40


def _layer_windows(rect, shape, rad, s) -> _LayerWindows:
    """The windows of tile ``rect`` = (r0, r1, c0, c1) on an (H, W) canvas, kernel radius ``rad``
    (fine samples) and supersampling ``s``."""
    r0, r1, c0, c1 = rect
    h, w = shape
    big = _UNBOUNDED
    q = -(-rad // s) + 1  # layer support beyond the tile, output px
    # tile extent on the fine lattice: samples k with (r0 − ½)s <= k < (r1 − ½)s
    ext_y = (-big if r0 == 0 else int(np.ceil((r0 - 0.5) * s)),
             big if r1 == h else int(np.ceil((r1 - 0.5) * s)))
    ext_x = (-big if c0 == 0 else int(np.ceil((c0 - 0.5) * s)),
             big if c1 == w else int(np.ceil((c1 - 0.5) * s)))
    a0, a1, b0, b1 = max(0, r0 - q), min(h, r1 + q), max(0, c0 - q), min(w, c1 + q)
    fy0, fy1 = a0 * s - rad, (a1 - 1) * s + rad + 1  # fine window [fy0, fy1) x [fx0, fx1)
    fx0, fx1 = b0 * s - rad, (b1 - 1) * s + rad + 1
    ty0, ty1 = max(fy0, ext_y[0]), min(fy1, ext_y[1])  # where M_t = 1 inside the window
    tx0, tx1 = max(fx0, ext_x[0]), min(fx1, ext_x[1])
    return _LayerWindows(out=(a0, a1, b0, b1), fine=(fy0, fy1, fx0, fx1), mask=(ty0, ty1, tx0, tx1))


def _photo_tile(src, pick, rect, mask, n_ch):
    """Sharp texture of a photo tile over ``mask`` = (ty0, ty1, tx0, tx1) (output px, s = 1).

    The crop of ``src`` (mirror-extended) is the best of 4 random offsets (drawn from ``pick``) by
    mean |finite difference| over the tile ``rect`` = (r0, r1, c0, c1). Returns (ty1 − ty0, tx1 − tx0, n_ch).
    """
    r0, r1, c0, c1 = rect
    ty0, ty1, tx0, tx1 = mask
    best = None
    for _ in range(4):  # seam-free offsets if the source is big enough, else anywhere
        span_y, span_x = src.shape[0] - (r1 - r0), src.shape[1] - (c1 - c0)
        oy = int(pick.integers(span_y + 1 if span_y >= 0 else 2 * src.shape[0]))
        ox = int(pick.integers(span_x + 1 if span_x >= 0 else 2 * src.shape[1]))
        crop = src[_reflect_index(oy + np.arange(r1 - r0), src.shape[0])[:, None],
                   _reflect_index(ox + np.arange(c1 - c0), src.shape[1])[None, :]]
        g = np.mean(np.abs(np.diff(crop, axis=0))) + np.mean(np.abs(np.diff(crop, axis=1)))
        if best is None or g > best[0]:
            best = (g, oy, ox)
    _, oy, ox = best
    iy = _reflect_index(oy + np.arange(ty0, ty1) - r0, src.shape[0])
    ix = _reflect_index(ox + np.arange(tx0, tx1) - c0, src.shape[1])
    return src[iy[:, None], ix[None, :]].reshape(ty1 - ty0, tx1 - tx0, n_ch)


def _add_layer(num, den, sharp, stages, win: _LayerWindows, s):
    """Add one tile's blurred layer G ∗ (M_t·T_t) to ``num`` (H, W, C) and G ∗ M_t to ``den`` (H, W), in place."""
    a0, a1, b0, b1 = win.out
    fy0, fy1, fx0, fx1 = win.fine
    ty0, ty1, tx0, tx1 = win.mask
    window = np.zeros((fy1 - fy0, fx1 - fx0))
    start, n_out = (a0 * s - fy0, b0 * s - fx0), (a1 - a0, b1 - b0)
    for c in range(num.shape[2]):
        window[ty0 - fy0:ty1 - fy0, tx0 - fx0:tx1 - fx0] = sharp[..., c]
        num[a0:a1, b0:b1, c] += apply_stages_2d(window, stages, start, n_out)
    my = np.zeros(fy1 - fy0)
    my[ty0 - fy0:ty1 - fy0] = 1.0
    mx = np.zeros(fx1 - fx0)
    mx[tx0 - fx0:tx1 - fx0] = 1.0
    den[a0:a1, b0:b1] += np.outer(apply_stages_1d(my, stages, start[0], n_out[0]),
                                  apply_stages_1d(mx, stages, start[1], n_out[1]))


def texture_mosaic(*, sigmas=(0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0), tile=96, cols=4,
                   texture="dead_leaves", color=True, noise_std=0.0, quantize_bits=None, rng=0,
                   boundary_band=None, supersample=4, radius_range=(2.0, 32.0)):
    """Rectangular tiles of texture, tile t blurred by σ_t, as abutting fronto-parallel planes.

    Parameters
    ----------
    sigmas : sequence of float, keyword-only
        Blur σ_t (px) of each tile, finite, >= 0, non-empty; one tile per value, row-major.
    tile : int, keyword-only
        Tile side, px (>= 16). The canvas is rows·tile x cols·tile px, rows = ⌈len(sigmas)/cols⌉;
        the tiles of an incomplete last row are widened to fill it.
    cols : int, keyword-only
        Tiles per row (>= 1; at most len(sigmas) are used).
    texture : {"dead_leaves", "skimage"}, keyword-only
        "dead_leaves": :func:`dead_leaves` (radius_range, values in [0.1, 0.9]), a different
        random plane per tile. "skimage": a crop of one of :data:`SKIMAGE_IMAGES` per tile,
        downsampled by :data:`SKIMAGE_DOWNSAMPLE` (intrinsic blur :data:`SKIMAGE_INTRINSIC_SIGMA_PX`,
        an estimate).
    color : bool, keyword-only
        True: RGB image (H, W, 3); False: grey (H, W) (photographs converted with rgb2gray).
    noise_std, quantize_bits : keyword-only
        See :func:`degrade` (applied last; the noise stream is derived from ``rng``).
    rng : int or numpy.random.Generator or None, keyword-only
        Seed (int >= 0, None = 0) or generator; same seed → identical output.
    boundary_band : float or None, keyword-only
        Half-width (px) of the band flagged in ``boundary`` on each side of a seam. None: for the
        seam between tiles t and u, ⌈3·max(σ_gt,t, σ_gt,u)⌉ + 2 px (σ_gt includes σ₀).
    supersample : int, keyword-only
        Fine-grid factor for dead leaves (1..16; ignored for "skimage").
    radius_range : (float, float), keyword-only
        Dead-leaves disc radii, px (see :func:`dead_leaves`; ignored for "skimage").

    Returns
    -------
    TextureMosaic
        Image, per-pixel ground-truth σ (px), tile index, boundary band, per-tile σ_t.

    Notes
    -----
    Image formation (blurred layers, normalised):
    I = Σ_t G_{σ_t} ∗ (M_t·T_t) / Σ_t G_{σ_t} ∗ M_t, with M_t tile t's indicator (its extent is
    [r0 − ½, r1 − ½) x [c0 − ½, c1 − ½) in pixel-centre coordinates; tiles on the canvas border
    extend beyond it) and T_t its sharp texture.
    1. Each layer is computed over its tile plus its blur support (≈ 4σ_t, clipped to the
       canvas), from a sharp window that reaches one more support beyond, so no boundary mode
       is used: tiles on the canvas border continue past it (dead leaves) or mirror (photos).
    2. dead_leaves: T_t = the dead-leaves plane with key t, drawn on the fine lattice (spacing
       1/s px, output pixel centres are fine samples) only where M_t = 1; G_{σ_t} is the blur of
       :func:`dead_leaves` (scipy.ndimage.gaussian_filter's kernel of std σ_t·s on that lattice,
       or its σ >= 2 px cascade), evaluated at the output pixel centres. σ_gt = σ_t.
    3. skimage: T_t = a crop of source photograph order[t mod n] (a random permutation of
       :data:`SKIMAGE_IMAGES`), downsampled ×4 by area averaging (100–160 px a side); the crop
       is the best of 4 random positions by mean |finite difference|. The source is extended
       by mirror reflection (mode "reflect"): tiles larger than the source (tile > 100 px)
       contain mirror seams. The blur acts on the stored (sRGB-encoded) values. G_{σ_t} =
       Lindeberg's discrete Gaussian e^{−σ²} I_n(σ²) on the output grid (variance σ², unlike the
       sampled kernel, whose std is 0.46 for σ = 0.5); σ_gt = √(σ_t² + σ₀²), σ₀ estimated.
    4. The masks M_t are blurred with the same kernels (separably, as 1-D box indicators).
       Normalising by Σ_t G_{σ_t} ∗ M_t — exactly 1 farther than the supports from every seam,
       so tile interiors are exactly G_{σ_t} ∗ T_t — keeps seams between different σ from
       darkening or brightening (unnormalised, a σ = 0.5 | 8 seam would swing to ~0.7–1.3 × the
       local mean).
    5. boundary: pixels of tile t whose centre is closer (Euclidean) than the band to another
       tile's extent; ``sigma`` and ``tile_index`` are those of the pixel's own tile.
    6. Optional noise, clipping and quantisation (:func:`degrade`) on the final image.
    """
    sig = check_sigmas(sigmas)
    tile = check_int(tile, "tile", 16)
    cols = check_int(cols, "cols", 1)
    if texture not in TEXTURES:
        raise ValueError(f"texture={texture!r} is invalid; allowed: {', '.join(repr(t) for t in TEXTURES)}")
    color = check_bool(color, "color")
    band_val = check_band(boundary_band)
    s = check_supersample(supersample) if texture == "dead_leaves" else 1
    r_range = check_radius_range(radius_range, s) if texture == "dead_leaves" else None
    check_degrade(noise_std, quantize_bits)
    entropy = seed_entropy(rng)
    n_ch = 3 if color else 1
    rects, (h, w) = tile_layout(len(sig), tile, cols)

    if texture == "dead_leaves":
        sigma0, plans = 0.0, [blur_stages(v, s) for v in sig]
    else:
        sigma0, plans = SKIMAGE_INTRINSIC_SIGMA_PX, [[(discrete_gaussian(v), 1)] for v in sig]
        sources = _skimage_sources(color)
        pick = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(1,)))
        order = pick.permutation(len(sources))  # tile t uses source order[t mod n]
    num = np.zeros((h, w, n_ch))
    den = np.zeros((h, w))
    for t, (rect, stages) in enumerate(zip(rects, plans)):
        win = _layer_windows(rect, (h, w), stages_support(stages), s)
        ty0, ty1, tx0, tx1 = win.mask
        if texture == "dead_leaves":
            labels, colours = leaves_labels(entropy, (t,), (ty0, tx0), (ty1 - ty0, tx1 - tx0), s,
                                             r_range, n_ch, None, (0.1, 0.9))
            sharp = colours[labels]
        else:
            sharp = _photo_tile(sources[order[t % len(sources)]], pick, rect, win.mask, n_ch)
        _add_layer(num, den, sharp, stages, win, s)

    image = np.clip(num / den[..., None], 0.0, 1.0)
    image = image if color else image[..., 0]
    image = degrade(image, noise_std=noise_std, quantize_bits=quantize_bits,
                    rng=np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(2,))))
    tile_index = np.zeros((h, w), dtype=np.int64)
    for t, (r0, r1, c0, c1) in enumerate(rects):
        tile_index[r0:r1, c0:c1] = t
    gt = np.sqrt(np.asarray(sig) ** 2 + sigma0 ** 2)
    if boundary_band is None:
        band_of = lambda t, u: np.ceil(3.0 * max(gt[t], gt[u])) + 2.0  # noqa: E731
    else:
        band_of = lambda t, u: band_val  # noqa: E731
    return TextureMosaic(image=image, sigma=gt[tile_index], tile_index=tile_index,
                         boundary=boundary_mask(rects, (h, w), band_of), sigmas=sig,
                         texture=texture, intrinsic_sigma=float(sigma0))
