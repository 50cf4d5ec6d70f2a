"""Point-spread functions of a lens for the analytic benchmarks, sampled on a supersampled lattice.

A thin lens with a circular aperture blurs a defocused point into a uniform disk of diameter c
(Eq. 5 of the paper, in px), which the pixel then integrates over its 1-px box. The harness reports
blur as σ, the per-axis standard deviation of the whole PSF (kernel ⊗ pixel box): for the disk
σ = √((c/4)² + 1/12) (../shared/research/LENS-AND-CAMERA.md). Every PSF of :data:`PSFS` follows the
same convention, so the same σ_gt is comparable across them:

* ``gaussian`` — a Gaussian of std √(σ² − 1/12) (⊗ the pixel box);
* ``disk`` — a uniform disk of diameter c = 4·√(σ² − 1/12) (the thin lens's defocus);
* ``soft_disk`` — that disk ⊗ a Gaussian of std 0.1·c (aberrations soften the rim), with c chosen so
  that (c/4)² + (0.1·c)² = σ² − 1/12;
* ``hexagon`` — a regular six-blade aperture (flat sides top and bottom) whose per-axis second moment
  5a²/24 (a the circumradius; isotropic, as for every regular polygon) equals the disk's.

:func:`psf_kernel` samples one on a lattice ``supersample`` times finer than the output pixels, as
the lens mosaics use it (:mod:`scenes.analytic.lens`): each fine cell holds the kernel's integral
over the cell (by m×m sub-samples), and the shape parameter is then adjusted so that the *discrete*
kernel's per-axis second moment equals σ² − 1/12 exactly (the cell integration adds (1/s)²/12; the
point sampling of a texture on the lattice and the s×s box average to output pixels add back
exactly 1/12, see :func:`scenes.analytic.lens.lens_mosaic`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from types import MappingProxyType

import numpy as np
from scipy.ndimage import convolve1d
from scipy.special import ndtr

__all__ = ["BOX_VARIANCE", "PSF", "PSFS", "check_psf", "kernel_sigma", "psf_kernel", "psf_shape"]

#: Per-axis variance of the 1-px pixel box, px².
BOX_VARIANCE = 1.0 / 12.0
#: Sub-samples per fine cell and axis for the cell integrals of the disk and the hexagon.
_SUBSAMPLES = 8
#: Soft disk: std of its Gaussian as a fraction of the disk's diameter.
SOFT_DISK_FRACTION = 0.1


@dataclasses.dataclass(frozen=True)
class PSF:
    """One PSF family.

    Attributes
    ----------
    summary : str
        What it models.
    size : callable
        σ_K (px, the kernel's per-axis std without the pixel box) → the shape parameter (px): the
        Gaussian's std, the disk's diameter c, the hexagon's circumradius a.
    size_name : str
        Name of that parameter.
    """

    summary: str
    size: Callable[[float], float]
    size_name: str


#: name -> :class:`PSF`.
PSFS = MappingProxyType({
    "gaussian": PSF("Gaussian (the model of the paper's Eq. 1)", lambda s: s, "std_px"),
    "disk": PSF("uniform disk of diameter c: a thin lens's defocus", lambda s: 4.0 * s, "diameter_px"),
    "soft_disk": PSF("disk of diameter c ⊗ Gaussian of std 0.1·c (aberrations)",
                     lambda s: s / math.sqrt(1.0 / 16.0 + SOFT_DISK_FRACTION ** 2), "diameter_px"),
    "hexagon": PSF("regular six-blade aperture with the disk's second moment", lambda s: s * math.sqrt(24.0 / 5.0),
                   "circumradius_px"),
})


def check_psf(name) -> str:
    """``name`` if it is a key of :data:`PSFS`, else ValueError listing them."""
    if not isinstance(name, str) or name not in PSFS:
        raise ValueError(f"psf={name!r} is invalid (unknown PSF); allowed: {', '.join(PSFS)}")
    return name


def kernel_sigma(sigma: float) -> float:
    """σ_K = √(σ² − 1/12) px: the kernel's per-axis std for a reported σ (which includes the pixel box).

    Raises
    ------
    ValueError
        σ below the box's own 1/√12 ≈ 0.289 px, or not finite.
    """
    s = float(sigma)
    if not (math.isfinite(s) and s >= math.sqrt(BOX_VARIANCE)):
        raise ValueError(f"sigma={sigma!r} is invalid; allowed: finite σ >= 1/√12 ≈ 0.289 px "
                         "(the pixel box alone)")
    return math.sqrt(max(s * s - BOX_VARIANCE, 0.0))


def psf_shape(name: str, sigma: float) -> dict:
    """The continuous shape parameter of PSF ``name`` for reported σ (px), e.g. ``{"diameter_px": c}``."""
    spec = PSFS[check_psf(name)]
    return {spec.size_name: spec.size(kernel_sigma(sigma))}


def _cell_integral_gaussian(std, h, radius):
    """1-D cell integrals of a Gaussian of std ``std`` (px) over cells of width h at i·h, |i| <= radius."""
    x = np.arange(-radius, radius + 1) * h
    w = ndtr((x + h / 2) / std) - ndtr((x - h / 2) / std)
    return w / w.sum()


def _coverage(inside, h, radius):
    """Cell integrals of an indicator ``inside(x, y)`` (px) over h×h cells centred at lattice points."""
    m = _SUBSAMPLES
    sub = (np.arange(m) + 0.5) / m - 0.5
    c = np.arange(-radius, radius + 1) * h
    fine = (c[:, None] + h * sub[None, :]).ravel()  # sub-sample coordinates along one axis
    y, x = np.meshgrid(fine, fine, indexing="ij")
    cover = inside(x, y).astype(np.float64)
    n = 2 * radius + 1
    return cover.reshape(n, m, n, m).mean(axis=(1, 3))


def _hexagon(a):
    """Indicator of a regular hexagon of circumradius ``a`` with flat sides top and bottom."""
    apothem = a * math.sqrt(3.0) / 2.0

    def inside(x, y):
        ay = np.abs(y)
        return (ay <= apothem) & (math.sqrt(3.0) * np.abs(x) + ay <= math.sqrt(3.0) * a)

    return inside


def _kernel_for(name, size, h):
    """The normalised discrete kernel (odd square) of PSF ``name`` with shape parameter ``size`` (px)."""
    if name == "gaussian":
        radius = max(1, int(math.ceil(4.0 * size / h)))
        g = _cell_integral_gaussian(max(size, 1e-9), h, radius)
        k = np.outer(g, g)
    elif name == "hexagon":
        radius = int(math.ceil(size / h)) + 1
        k = _coverage(_hexagon(size), h, radius)
    else:  # disk, soft_disk
        r_disk = size / 2.0
        radius = int(math.ceil(r_disk / h)) + 1
        k = _coverage(lambda x, y: x * x + y * y <= r_disk * r_disk, h, radius)
        if name == "soft_disk":
            std = SOFT_DISK_FRACTION * size
            rg = max(1, int(math.ceil(4.0 * std / h)))
            k = np.pad(k, rg)
            g = _cell_integral_gaussian(std, h, rg)
            k = convolve1d(convolve1d(k, g, axis=0, mode="constant"), g, axis=1, mode="constant")
    return k / k.sum()


def _axis_variance(k, h):
    n = k.shape[0]
    x = (np.arange(n) - n // 2) * h
    return 0.5 * float(np.sum((k.sum(axis=0) + k.sum(axis=1)) * x * x))  # mean of both axes


def psf_kernel(name: str, *, sigma: float, supersample: int = 4) -> np.ndarray:
    """PSF ``name`` for reported σ (px) on a lattice ``supersample`` times finer than the pixels.

    Parameters
    ----------
    name : str
        Key of :data:`PSFS`.
    sigma : float, keyword-only
        Reported blur σ, px (kernel ⊗ the 1-px pixel box), >= 1/√12.
    supersample : int, keyword-only
        s, fine samples per output px (1..16).

    Returns
    -------
    ndarray, (2r + 1, 2r + 1), float64
        Cell integrals of the kernel over the fine cells, sum 1, centred; its per-axis second moment
        (in px², lattice spacing 1/s) is σ² − 1/12 (to round-off). σ = 1/√12 gives the 1×1 identity.

    Raises
    ------
    ValueError
        Unknown PSF, σ < 1/√12 or not finite, or a bad ``supersample``.

    Notes
    -----
    1. σ_K² = σ² − 1/12 (:func:`kernel_sigma`); the shape parameter p = ``PSFS[name].size(σ_K)``.
    2. Cell integrals on the lattice of spacing h = 1/s: the Gaussian by differences of its CDF
       (separable), the disk and the hexagon by 8×8 sub-samples per cell; the soft disk as the
       disk's cells convolved with the Gaussian's.
    3. The cell integration adds ≈ h²/12 to the second moment: p is rescaled, p ← p·√(σ_K²/v(p)) with
       v the discrete kernel's per-axis second moment, then lowered in 0.5 % steps until v <= σ_K²
       (the sub-sampled coverage changes in steps); the rest, σ_K² − v, is added exactly by a separable
       3-tap kernel [ε/2, 1 − ε, ε/2] with taps j cells apart, ε·(j·h)² = σ_K² − v, ε <= 1/2.
    """
    spec = PSFS[check_psf(name)]
    if isinstance(supersample, (bool, np.bool_)) or not isinstance(supersample, (int, np.integer)) \
            or not 1 <= supersample <= 16:
        raise ValueError(f"supersample={supersample!r} is invalid; allowed: an int in 1..16")
    target = kernel_sigma(sigma) ** 2
    if target <= 1e-12:  # the pixel box alone (σ = 1/√12 up to round-off)
        return np.ones((1, 1))
    h = 1.0 / int(supersample)
    size = spec.size(math.sqrt(target))
    k, v = None, 0.0
    for _ in range(8):  # p ← p·√(σ_K²/v): v ≈ c·p² + h²/12, so a few steps
        k = _kernel_for(name, size, h)
        v = _axis_variance(k, h)
        if v <= target and target - v <= 1e-3 * target:
            break
        size *= math.sqrt(target / v) if v > 0 else 2.0
    for _ in range(400):  # end at or just below the target: the sub-sampled coverage changes in steps
        if v <= target:
            break
        size *= 0.995
        k = _kernel_for(name, size, h)
        v = _axis_variance(k, h)
    deficit = target - v  # the rest by a separable 3-tap [ε/2, 1 − ε, ε/2] at ±j cells (variance ε·(j·h)²)
    if deficit > 0:
        j = max(1, int(math.ceil(math.sqrt(deficit / (0.5 * h * h)))))  # so that ε <= 1/2
        eps = deficit / (j * h) ** 2
        tap = np.zeros(2 * j + 1)
        tap[[0, j, 2 * j]] = (eps / 2.0, 1.0 - eps, eps / 2.0)
        k = np.pad(k, j)
        k = convolve1d(convolve1d(k, tap, axis=0, mode="constant"), tap, axis=1, mode="constant")
    return k / k.sum()
