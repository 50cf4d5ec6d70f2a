"""Analytic test images of the accuracy benchmark: texture and step-edge mosaics with known σ per tile.

:func:`analytic_case` gives one image of a dataset of :data:`ANALYTIC_DATASETS` with its σ_gt map,
the mask of pixels to score and one bin per tile σ (:func:`sigma_bins`); :func:`step_mosaic` is the
step-edge mosaic (straight blurred edges, Eq. (1) of the paper with a Gaussian PSF).
"""

from __future__ import annotations

import math

from method.registry import Registry

__all__ = ["ANALYTIC_DATASETS", "STEP_BASE_ANGLE", "STEP_SEAM_BAND_PX", "analytic_case", "lens_step_mosaic",
           "noise_label", "sigma_bins", "step_mosaic", "tile_contrast_snr"]

#: Half-width (px) of the band masked on each side of the step-edge mosaic's tile seams.
STEP_SEAM_BAND_PX = 6
#: Normal angle θ (rad) of the step-edge mosaic's first tile; the others are its mirror images.
STEP_BASE_ANGLE = math.pi / 6

#: The analytic datasets; each summary is the title of its table in ``accuracy.md``.
ANALYTIC_DATASETS = Registry("analytic dataset", {
    "dead_leaves": "Dead-leaves texture mosaic",
    "skimage": "skimage-photo mosaic (σ_gt = √(σ² + σ₀²), σ₀ assumed)",
    "step_edges": "Step-edge mosaic",
})


def noise_label(noise_std: float) -> str:
    """A noise standard deviation (image units) as ``"k/255"``."""
    return f"{noise_std * 255:.3g}/255"


def sigma_bins(values) -> tuple:
    """Bin edges (px) putting each distinct value in its own half-open bin: 0, midpoints, inf."""
    v = sorted({float(x) for x in values})
    return (0.0, *((a + b) / 2.0 for a, b in zip(v[:-1], v[1:])), math.inf)


def _near_seam(n: int, tile: int):
    """Pixel centres k + ½ within STEP_SEAM_BAND_PX of an interior seam (multiples of ``tile``)."""
    import numpy as np

    k = np.arange(n) + 0.5
    d = np.abs(k - tile * np.round(k / tile))
    inner = (np.round(k / tile) > 0) & (np.round(k / tile) < n // tile)
    return inner & (d < STEP_SEAM_BAND_PX)


def _mirrored_steps(sigmas, tile: int, make):
    """2 rows x len(sigmas) tiles: ``make(sigma, angle)`` (a tile²-px image) at the mirrored normal angles."""
    import numpy as np

    rows = []
    for base in (STEP_BASE_ANGLE, -STEP_BASE_ANGLE):
        angles = [base if c % 2 == 0 else math.pi - base for c in range(len(sigmas))]
        rows.append(np.concatenate([make(float(s), a) for s, a in zip(sigmas, angles)], axis=1))
    image = np.concatenate(rows, axis=0)
    h, w = image.shape[:2]
    sigma_gt = np.broadcast_to(np.repeat(np.asarray(sigmas, dtype=np.float64), tile)[None, :], (h, w)).copy()
    valid = ~(_near_seam(h, tile)[:, None] | _near_seam(w, tile)[None, :])
    return image, sigma_gt, valid


def step_mosaic(sigmas, tile: int, noise_std: float, seed: int):
    """Mosaic of straight blurred step edges: 2 rows x len(sigmas) tiles of ``tile``² px.

    Column c holds :func:`scenes.analytic.step_edge` with σ = sigmas[c] through the tile centre, normal
    angle θ (row 0) / −θ (row 1), θ = :data:`STEP_BASE_ANGLE`, mirrored (π − angle) in odd columns, so
    every tile is the mirror image of its neighbours and the noise-free image is continuous across
    seams (only σ changes there). Then 8-bit + Gaussian noise (:func:`scenes.analytic.degrade`).

    Parameters
    ----------
    sigmas : sequence of float
        Blur σ of each column, px.
    tile : int
        Tile side, px.
    noise_std : float
        Gaussian noise standard deviation, image units.
    seed : int
        Noise seed.

    Returns
    -------
    image : ndarray, (2·tile) x (len(sigmas)·tile), float in [0, 1]
    sigma_gt : ndarray, same shape, px (the tile's σ)
    valid : ndarray of bool, same shape; False within STEP_SEAM_BAND_PX of a seam
    """
    import numpy as np

    from scenes.analytic import degrade, step_edge

    image, sigma_gt, valid = _mirrored_steps(sigmas, tile, lambda s, a: step_edge((tile, tile), sigma=s, angle=a).image)
    image = degrade(image, noise_std=noise_std, quantize_bits=8, rng=np.random.default_rng(seed))
    return image, sigma_gt, valid


def lens_step_mosaic(sigmas, tile: int, *, psf: str, noise: str, seed: int, light: str = "linear",
                     encoding: str = "srgb"):
    """:func:`step_mosaic`'s layout with steps blurred by a lens PSF in linear light, then the camera.

    Each tile is :func:`scenes.analytic.lens.lens_step_edge` (display values 0.2 → 0.8, PSF ``psf`` of
    reported σ = sigmas[c], kernel ⊗ pixel box); then Poisson–Gaussian noise ``noise`` in linear
    units, the tone curve ``encoding`` (a key of :data:`scenes.display.ENCODINGS`, default sRGB) and 8
    bits (:func:`scenes.display.camera_image`).

    Returns
    -------
    image, sigma_gt, valid
        As :func:`step_mosaic`.
    """
    import numpy as np

    from scenes.analytic.lens import lens_step_edge
    from scenes.display import camera_image, decode

    def make(s, a):
        return lens_step_edge((tile, tile), sigma=s, psf=psf, angle=a, light=light, encoding=encoding).image

    image, sigma_gt, valid = _mirrored_steps(sigmas, tile, make)
    image = camera_image(decode(image, encoding), noise=noise, quantize_bits=8, rng=np.random.default_rng(seed),
                         encoding=encoding)
    return image, sigma_gt, valid


def analytic_case(dataset: str, config: dict, noise_std: float, seed: int) -> dict:
    """Image, σ_gt, valid mask and per-tile (nominal σ, σ_gt) of one analytic test image.

    Parameters
    ----------
    dataset : str
        Key of :data:`ANALYTIC_DATASETS`.
    config : dict
        ``sigmas`` (tile σ, px), ``tile`` (px), ``mosaic_cols`` (texture mosaics), as
        :data:`experiments.bench.accuracy.ACCURACY_CONFIG`.
    noise_std : float
        Gaussian noise standard deviation, image units (then 8-bit quantisation).
    seed : int
        Noise (and texture) seed.

    Returns
    -------
    dict
        ``image`` (H x W float), ``sigma_gt`` (H x W, px), ``valid`` (H x W bool), ``nominal`` and
        ``gt`` (one σ per bin, px), ``intrinsic_sigma`` (px, the texture's own blur assumed).
    """
    import numpy as np

    ANALYTIC_DATASETS.check(dataset, what="dataset")
    sigmas = tuple(float(s) for s in config["sigmas"])
    if dataset == "step_edges":
        image, gt, valid = step_mosaic(sigmas, config["tile"], noise_std, seed)
        return {"image": image, "sigma_gt": gt, "valid": valid, "nominal": tuple(sorted(set(sigmas))),
                "gt": tuple(sorted(set(sigmas))), "intrinsic_sigma": 0.0}
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(texture=dataset, sigmas=sigmas, tile=config["tile"], cols=config["mosaic_cols"],
                       noise_std=noise_std, quantize_bits=8, rng=seed)
    nominal = tuple(sorted(set(sigmas)))  # one bin per distinct tile σ, in the bins' order
    gt = tuple(float(np.sqrt(s ** 2 + m.intrinsic_sigma ** 2)) for s in nominal)
    return {"image": m.image, "sigma_gt": m.sigma, "valid": ~m.boundary, "nominal": nominal, "gt": gt,
            "intrinsic_sigma": float(m.intrinsic_sigma)}


def tile_contrast_snr(m, encoding: str) -> dict:
    """Per tile σ of a lens mosaic: the noise-free blurred tile's display-luma std / the camera's noise std.

    The noise std in display values is √(a·x + b) · encode′(x) (x the linear value; encode′ by central
    differences) and the 8-bit step's 1/√12, in quadrature, as an rms over the tile's valid pixels.
    """
    import numpy as np

    from scenes.display import encode

    lin = np.asarray(m.linear, dtype=np.float64).mean(axis=2) if m.linear.ndim == 3 else m.linear
    disp = encode(lin, encoding)
    h = 1e-4
    slope = (encode(np.clip(lin + h, 0, 1), encoding) - encode(np.clip(lin - h, 0, 1), encoding)) / (
        np.clip(lin + h, 0, 1) - np.clip(lin - h, 0, 1))
    var = (m.noise["a"] * lin + m.noise["b"]) * slope ** 2 + 1.0 / (12 * 255.0 ** 2)
    out = {}
    for t, sig in enumerate(m.sigmas):
        sel = (m.tile_index == t) & ~m.boundary
        out[float(sig)] = float(disp[sel].std() / np.sqrt(var[sel].mean())) if sel.any() else 0.0
    return out
