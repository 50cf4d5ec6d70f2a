"""Defocus magnification: map preprocessing and spatially varying blur (Sec. 5).

The paper renders with Photoshop's lens blur; this module does its own spatially varying blur so
that every pixel's total blur becomes ``factor × B(p)``. For Gaussian blur, σ's add in quadrature,
so the extra blur is σ_e(p) = √(factor² − 1)·B(p).

Renderers (:data:`MAGNIFICATION_RENDERERS`), both adding the extra blur σ_e(p):

* ``"gather"`` (default; the paper preset's path): every output pixel interpolates, per pixel, a
  stack of uniformly blurred copies of the image (no occlusion: a blurry background bleeds over a
  sharp subject and the subject leaks into it). Kernel shape: ``kernel``.
* ``"scatter"``: every pixel spreads its linear radiance over its own disk (or hexagon) of σ_e,
  composited in occlusion layers (sharper = nearer), normalised by the accumulated weight
  (:mod:`method.magnify.scatter`). Aperture shape: ``aperture``.

Light (the vocabulary of :mod:`method.luma`): ``encoding`` (:data:`method.luma.ENCODINGS`) says what
the image's values are — ``"srgb"`` (display values in [0, 1], default) or ``"linear"`` (linear
radiance ≥ 0 that may exceed 1, e.g. a render's highlights; returned unclipped) — and ``light``
(:data:`method.luma.LIGHTS`) the light the renderer blends in: ``"display"`` (the sRGB-encoded values,
the paper's path and the gather's default) or ``"linear"`` (linear light, the scatter's default: a
lens adds light, not sRGB values). When they differ the image goes through the sRGB transfer
function of colour-science once each way (a linear image blended in display light loses values
above 1).

Kernels of the gather (:data:`MAGNIFICATION_KERNELS`):

* ``"gaussian"`` (default): sampled, normalised Gaussian of std σ_e.
* ``"disk"``: uniform disk (anti-aliased, normalised) of radius R = 2σ_e — a disk of radius R has
  per-axis variance R²/4, so R = 2σ matches the second moment of the Gaussian σ_e (equivalently a
  circle of confusion of diameter c has σ = c/4).

Map floor (:data:`MAP_FLOOR_MODES`, :mod:`method.magnify.map_floor`): how Sec. 5's "clamping its
minimum value to 0" is read — ``"clamp"`` (the literal max(B, 0), default here and in the paper preset),
``"subtract"``, ``"shift"`` or ``"auto"`` (the in-focus floor estimated per photo, no blur added within
its uncertainty; the robust preset's). ``focus_point`` and ``keep_sharp`` name the subject.

``factor < 1`` would need deblurring and is rejected.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from scipy import fft as sfft

from ..luma import LIGHTS, decode, encode, light_of
from ..validation import validate_image, validate_map
from ..registry import Entry, Registry
from .map_floor import (MAP_FLOOR_MODES, floor_at_point, keep_sharp_weight, preprocess_defocus_map,
                        soft_floor)
from .scatter import APERTURES, scatter_blur

__all__ = ["MAGNIFICATION_KERNELS", "MAGNIFICATION_RENDERERS", "MAP_FLOOR_MODES",
           "check_extra_blur", "magnify_defocus", "preprocess_defocus_map"]

#: Ratio between the σ of consecutive blur-stack levels (levels 0, 0.5 px, 0.5·√2 px, ...).
LEVEL_RATIO = 2.0**0.5
#: σ of the first non-zero blur-stack level, px.
FIRST_LEVEL_SIGMA = 0.5


def _gaussian_kernel_1d(sigma):
    r = max(1, int(np.ceil(4.0 * sigma)))
    x = np.arange(-r, r + 1, dtype=np.float64)
    k = np.exp(-x * x / (2.0 * sigma * sigma))
    return k / k.sum()


def _gaussian_kernel(sigma):
    """Separable sampled Gaussian of std σ px; returns (2-D kernel, per-axis variance px²)."""
    k = _gaussian_kernel_1d(sigma)
    r = len(k) // 2
    x = np.arange(-r, r + 1)
    return np.outer(k, k), float(np.sum(k * x * x))


def _disk_kernel(sigma, supersample=8):
    """Anti-aliased uniform disk of radius R = 2σ px (area coverage by supersampling)."""
    radius = 2.0 * sigma
    r = int(np.ceil(radius))
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    x = np.arange(-r, r + 1, dtype=np.float64)
    fine = (x[:, None] + sub[None, :]).ravel()
    inside = (fine[:, None] ** 2 + fine[None, :] ** 2) <= radius * radius
    k = inside.reshape(2 * r + 1, supersample, 2 * r + 1, supersample).mean(axis=(1, 3))
    if k.sum() == 0:
        k[r, r] = 1.0
    k /= k.sum()
    return k, float(np.sum(k * (x[:, None] ** 2)))


#: Kernel families for the extra blur, by name: σ px → (normalised 2-D kernel, per-axis variance px²).
MAGNIFICATION_KERNELS = Registry("magnification kernel", {
    "gaussian": Entry(_gaussian_kernel, "Gaussian of σ (Sec. 5)"),
    "disk": Entry(_disk_kernel, "uniform disk of radius 2σ, a thin lens's defocus"),
})


def _check_map(defocus_map, shape=None, *, name="defocus_map"):
    # may be negative here: Sec. 5's preprocessing clamps it
    return validate_map(defocus_map, shape, name=name, allow_negative=True)


def _levels(max_sigma):
    levels = [0.0]
    s = FIRST_LEVEL_SIGMA
    while True:
        levels.append(s)
        if s >= max_sigma:
            break
        s *= LEVEL_RATIO
    return levels


def blur_stack_apply(image, sigma_extra, kernel, *, spectral_filter=None):
    """Per-pixel filtering by interpolating, in variance, between the two nearest blur-stack levels.

    ``image`` is HxWxC float64, ``sigma_extra`` HxW ≥ 0 (px). By default level ℓ is the image blurred
    with ``MAGNIFICATION_KERNELS[kernel](σ_ℓ)``. ``spectral_filter(khat, (fh, fw))``, if given, maps
    the kernel's rfft2 spectrum (fh x fw//2+1, complex) to the filter spectrum applied instead (e.g. a
    Wiener inverse, :mod:`method.magnify.refocusing`); level 0 is always the image itself.
    """
    h, w, c = image.shape
    make = MAGNIFICATION_KERNELS[kernel]
    levels = _levels(float(sigma_extra.max()))
    kernels = [make(s) for s in levels[1:]]
    variances = np.array([0.0] + [v for _, v in kernels])
    pad = max(k.shape[0] // 2 for k, _ in kernels)
    padded = np.pad(image, ((pad, pad), (pad, pad), (0, 0)), mode="symmetric")
    ph, pw = padded.shape[:2]
    fh, fw = sfft.next_fast_len(ph, real=True), sfft.next_fast_len(pw, real=True)
    spectrum = sfft.rfft2(padded, s=(fh, fw), axes=(0, 1))
    target = sigma_extra * sigma_extra
    # level index j such that variances[j] <= target < variances[j+1]; weight linear in variance
    j = np.clip(np.searchsorted(variances, target, side="right") - 1, 0, len(variances) - 2)
    t = (target - variances[j]) / (variances[j + 1] - variances[j])
    t = np.clip(t, 0.0, 1.0)
    out = np.zeros_like(image)
    w_lo = (1.0 - t)
    # level 0 (the image itself)
    sel0 = j == 0
    out += np.where(sel0, w_lo, 0.0)[..., None] * image
    for lvl in range(1, len(levels)):
        weight = np.where(j == lvl, 1.0 - t, 0.0) + np.where(j == lvl - 1, t, 0.0)
        if not np.any(weight > 0):
            continue
        k, _ = kernels[lvl - 1]
        r = k.shape[0] // 2
        kpad = np.zeros((fh, fw))
        kpad[:k.shape[0], :k.shape[1]] = k
        kpad = np.roll(kpad, (-r, -r), axis=(0, 1))
        khat = sfft.rfft2(kpad)
        if spectral_filter is not None:
            khat = spectral_filter(khat, (fh, fw))
        blurred = sfft.irfft2(spectrum * khat[..., None], s=(fh, fw), axes=(0, 1))
        out += weight[..., None] * blurred[pad:pad + h, pad:pad + w]
    return out


#: Smallest bound on the extra blur σ_e, px, whatever the image size (:func:`check_extra_blur`): tiny
#: images may be blurred past their size (cheap), large ones up to their longer side.
MIN_EXTRA_SIGMA_LIMIT = 64.0


def check_extra_blur(factor: float, defocus_map: np.ndarray, shape, *, name: str = "factor") -> float:
    """Largest extra blur σ_e = √(factor² − 1)·max B, px; ValueError when it exceeds the image's longer side
    (or :data:`MIN_EXTRA_SIGMA_LIMIT`, whichever is larger).

    A Gaussian (or disk) wider than the image already averages the whole image, so a larger σ_e
    changes nothing visible while the blur stack's memory grows with it (its padding is ≈ 6 σ_e on
    each side: ``--factor 1e9`` asked for σ_e ≈ 10⁹ px and was killed for memory).

    Parameters
    ----------
    factor : float
        Magnification factor, ≥ 1.
    defocus_map : ndarray, HxW
        The (preprocessed) blur map B, px, ≥ 0.
    shape : tuple
        Shape of the whole image (H, W, ...).
    name : str, keyword-only
        What to call the factor in the message (a CLI passes its flag).

    Returns
    -------
    float
        max σ_e, px.

    Raises
    ------
    ValueError
        max σ_e > max(H, W, MIN_EXTRA_SIGMA_LIMIT); the message gives the largest factor this map allows.
    """
    top_b = float(np.max(defocus_map, initial=0.0))
    extra = float(np.sqrt(factor * factor - 1.0)) * top_b
    limit = max(float(max(shape[:2])), MIN_EXTRA_SIGMA_LIMIT)
    if extra > limit:
        k_max = float(np.sqrt(1.0 + (limit / top_b) ** 2))
        raise ValueError(f"{name} {factor:g} is too large for this image: the extra blur would reach σ = {extra:.3g} px, "
                         f"more than {limit:g} px (the image's longer side, at least {MIN_EXTRA_SIGMA_LIMIT:g}); "
                         f"allowed: factor <= {k_max:.4g} for this defocus map (max σ {top_b:.3g} px)")
    return extra


#: Code values of the sRGB decoding table (16 bits: 8-bit samples k/255 are the codes 257·k).
SRGB_TABLE_CODES = 65535
_SRGB_TABLE: list = []


def _srgb_decode(x):
    """colour-science's sRGB decoding; looked up in a table of its values when every sample is a 16-bit code."""
    import colour

    x = np.clip(x, 0.0, 1.0)
    codes = np.rint(x * SRGB_TABLE_CODES)
    if np.array_equal(codes / SRGB_TABLE_CODES, x):  # 8/16-bit photos: same numbers, ~5× faster
        if not _SRGB_TABLE:
            _SRGB_TABLE.append(colour.cctf_decoding(np.arange(SRGB_TABLE_CODES + 1) / SRGB_TABLE_CODES, function="sRGB"))
        return _SRGB_TABLE[0][codes.astype(np.int32)]
    return colour.cctf_decoding(x, function="sRGB")


def _srgb_encode(x):
    import colour

    return np.clip(colour.cctf_encoding(np.clip(x, 0.0, 1.0), function="sRGB"), 0.0, 1.0)


def _transfer(encoding: str, light: str):
    """(to the blending light, back) for an image of ``encoding`` blended in ``light``; None when they agree."""
    source = light_of(encoding)
    if source == light:
        return None
    if light == "linear" and encoding != "srgb":  # another tone curve: its own (method.luma.ENCODINGS)
        return (lambda x: decode(x, encoding)), (lambda x: encode(x, encoding))
    return (_srgb_decode, _srgb_encode) if light == "linear" else (_srgb_encode, _srgb_decode)


@dataclasses.dataclass(frozen=True)
class Renderer:
    """A magnification renderer: ``render(image HxWxC, sigma_extra HxW px, **options) -> HxWxC``.

    Attributes
    ----------
    render : callable
        Keyword options: ``kernel``, ``aperture``, ``in_front``, ``progress`` (each renderer reads
        the ones its entry's capabilities name).
    default_light : str
        Key of :data:`method.luma.LIGHTS` it blends in when ``light=None``.
    """

    render: Callable
    default_light: str


def _render_gather(image, sigma_extra, *, kernel, aperture, in_front, progress):
    out = blur_stack_apply(image, sigma_extra, kernel)
    return np.where((sigma_extra == 0)[..., None], image, out)


def _render_scatter(image, sigma_extra, *, kernel, aperture, in_front, progress):
    return scatter_blur(image, sigma_extra, aperture=aperture, in_front=in_front, progress=progress)


#: Magnification renderers, by name (module docstring). Capabilities: the options each one reads.
MAGNIFICATION_RENDERERS = Registry("magnification renderer", {
    "gather": Entry(Renderer(_render_gather, "display"),
                    "per-pixel interpolation of a blur stack, no occlusion (the paper preset's path)",
                    capabilities={"kernel"}),
    "scatter": Entry(Renderer(_render_scatter, "linear"),
                     "each pixel spreads its linear radiance over its disk/hexagon, occlusion by σ layers",
                     capabilities={"aperture", "occlusion"}),
})


def _check_renderer_options(renderer, kernel, aperture, in_front, light, shape):
    """(kernel, aperture, in_front, light) validated, defaults filled in; ValueError otherwise."""
    MAGNIFICATION_RENDERERS.check(renderer, what="renderer")
    caps = MAGNIFICATION_RENDERERS.entry(renderer).capabilities
    for name, value, cap in (("kernel", kernel, "kernel"), ("aperture", aperture, "aperture"),
                             ("in_front", in_front, "occlusion")):
        if value is not None and cap not in caps:
            users = ", ".join(repr(n) for n in sorted(MAGNIFICATION_RENDERERS.having(cap)))
            raise ValueError(f"{name} applies to the {users} renderer, not to renderer={renderer!r}")
    kernel = MAGNIFICATION_KERNELS.check(kernel or "gaussian", what="kernel")
    aperture = APERTURES.check(aperture or "disk", what="aperture")
    light = LIGHTS.check(light or MAGNIFICATION_RENDERERS[renderer].default_light, what="light")
    if in_front is not None:
        in_front = np.asarray(in_front)
        if in_front.shape != tuple(shape[:2]) or in_front.dtype != bool:
            raise ValueError(f"in_front must be a bool array of shape {tuple(shape[:2])}, got {in_front.dtype} "
                             f"{in_front.shape}")
    return kernel, aperture, in_front, light


def magnify_defocus(image, defocus_map, *, factor=2.0, kernel=None, clip_percent=5.0, smoothing=0.005,
                    floor="clamp", preprocess=True, renderer="gather", aperture=None, encoding="srgb", light=None,
                    in_front=None, focus_point=None, keep_sharp=None,
                    progress: Callable[[str], None] | None = None) -> np.ndarray:
    """Magnify the defocus of a photo: blur each pixel so its total blur is factor·B(p) (Sec. 5).

    Parameters
    ----------
    image : ndarray, HxW or HxWx3, float
        The photo: sRGB-encoded values in [0, 1] (``encoding="srgb"``) or linear radiance ≥ 0
        (``"linear"``).
    defocus_map : ndarray, HxW, float
        Dense blur σ B(p), px (the propagated map). With ``preprocess=False`` it must be ≥ 0.
    factor : float, keyword-only
        Magnification k ≥ 1 (2 doubles the aperture diameter). k < 1 would need deblurring and is
        rejected; k = 1 returns the image unchanged.
    kernel : str or None, keyword-only
        Gather only: key of :data:`MAGNIFICATION_KERNELS`, ``"gaussian"`` (None: the default) or
        ``"disk"`` (radius 2σ_e).
    clip_percent, smoothing : float, keyword-only
        Map preprocessing, see :func:`preprocess_defocus_map` (paper: 5 %, 0.5 %).
    floor : str, keyword-only
        Key of :data:`MAP_FLOOR_MODES` (Sec. 5 "clamp its minimum value to 0"): ``"clamp"``
        (default, literal: max(B, 0); an in-focus floor of σ_f px gets √(factor² − 1)·σ_f px of extra
        blur), ``"subtract"`` (the lower-percentile value p_lo px removed in quadrature), ``"shift"``
        (B − p_lo) or ``"auto"`` (the floor estimated from the smoothed map, no extra blur at or below
        it plus its uncertainty, smoothly growing above: :func:`method.magnify.map_floor.soft_floor`).
        Checked even when ``preprocess=False``, where it is not used.
    preprocess : bool, keyword-only
        Apply :func:`preprocess_defocus_map` first (paper: yes).
    renderer : str, keyword-only
        Key of :data:`MAGNIFICATION_RENDERERS`: ``"gather"`` (default, the paper preset's path) or
        ``"scatter"`` (:mod:`method.magnify.scatter`).
    aperture : str or None, keyword-only
        Scatter only: key of :data:`method.magnify.scatter.APERTURES`, ``"disk"`` (None: the
        default) or ``"hexagon"``.
    encoding : str, keyword-only
        What the image's values are, key of :data:`method.luma.ENCODINGS`: ``"srgb"`` (default) or
        ``"linear"``.
    light : str or None, keyword-only
        The light the renderer blends in, key of :data:`method.luma.LIGHTS` (None: the renderer's
        default, ``"display"`` for the gather, ``"linear"`` for the scatter).
    in_front : ndarray of bool, HxW, optional, keyword-only
        Scatter only: pixels in front of the focus plane (:func:`method.magnify.scatter.layer_index`).
    focus_point : (float, float), optional, keyword-only
        (x, y) px (column, row) of a pixel of the subject: the floor is read at the map around it
        and no blur is added to pixels as sharp as it, growing smoothly above
        (:func:`method.magnify.map_floor.floor_at_point`; with ``preprocess=False`` applied to the
        given map as it is).
    keep_sharp : ndarray, HxW, bool or float in [0, 1], optional, keyword-only
        Where no blur is added (1 = none), feathered outside the mask
        (:func:`method.magnify.map_floor.keep_sharp_weight`).
    progress : callable, optional, keyword-only
        Scatter: called with ``"scatter layer i/n"`` before each occlusion layer.

    Returns
    -------
    ndarray, same shape as ``image``, float64
        In [0, 1], except with ``encoding="linear"`` (≥ 0, not clipped).

    Raises
    ------
    ValueError
        Bad image, map shape mismatch, NaN/Inf, negative map without preprocessing, factor < 1,
        unknown renderer, kernel, aperture, encoding, light or floor, an option the renderer does not take,
        an extra blur σ_e above the image size (:func:`check_extra_blur`), a focus point outside the
        image, a keep_sharp mask not of the image's HxW.

    Notes
    -----
    1. Optionally preprocess the map (clip percentiles, remove the floor as ``floor`` says,
       Gaussian blur).
    2. Extra blur per pixel σ_e = √(factor² − 1)·B (Gaussians add in quadrature; for the scatter's
       disks, the per-axis variances add the same way).
    3. Convert the image from ``encoding`` into ``light`` when they differ (sRGB decoding, or
       encoding for a linear image blended in display light).
    4. Gather: blur stack, level 0 = the image, levels ℓ ≥ 1 = image ⊛ kernel(σ_ℓ), σ_ℓ = 0.5·√2^(ℓ−1)
       px, up to max σ_e, computed by FFT with symmetric padding; per pixel, linear interpolation
       between the two levels whose kernel variances v_ℓ bracket σ_e² (the second moment of the
       effective kernel is exactly σ_e²; v_ℓ are the measured variances of the discrete kernels).
       Level 0 enters with weight exactly 1 where σ_e = 0, so factor = 1 and a zero map return the
       input bit for bit. Scatter: :func:`method.magnify.scatter.scatter_blur` of σ_e.
    5. Convert back to ``encoding`` (a pixel the blur left unchanged is returned as given, bit for
       bit); clip to [0, 1] (``encoding="srgb"``: kernels are non-negative, so only round-off is
       clipped) or to ≥ 0 (``"linear"``).
    """
    light_of(encoding)
    kernel, aperture, in_front, light = _check_renderer_options(renderer, kernel, aperture, in_front, light,
                                                                np.shape(image))
    image = validate_image(image, min_side=1, check_range=encoding != "linear")
    if encoding == "linear" and image.size and float(image.min()) < 0:
        raise ValueError(f"image (linear radiance) must be >= 0, got min {float(image.min()):.6g}")
    m = _check_map(defocus_map, image.shape)
    try:
        factor = float(factor)
    except (TypeError, ValueError):
        raise ValueError(f"factor={factor!r} is invalid; allowed: finite number >= 1") from None
    if not (np.isfinite(factor) and factor >= 1.0):
        raise ValueError(f"factor={factor!r} is invalid; allowed: finite and >= 1 "
                         "(factor < 1 would need deblurring, which this module does not do)")
    floor = MAP_FLOOR_MODES.check(floor, what="floor")
    if preprocess:
        m = preprocess_defocus_map(m, clip_percent=clip_percent, smoothing=smoothing, floor=floor,
                                   focus_point=focus_point, keep_sharp=keep_sharp)
    elif m.size and float(m.min()) < 0:
        raise ValueError(f"defocus_map must be >= 0 (blur σ, px) when preprocess=False, got min {float(m.min()):.6g}")
    else:  # the subject named on a map given as it is
        m = m if focus_point is None else soft_floor(m, floor_at_point(m, focus_point))
        m = m if keep_sharp is None else m * keep_sharp_weight(keep_sharp, m.shape, 2.0)
    check_extra_blur(factor, m, image.shape)
    image64 = image.astype(np.float64, copy=False)
    sigma_extra = np.sqrt(factor * factor - 1.0) * m
    if factor == 1.0 or not np.any(sigma_extra > 0):
        return image64.copy()
    img3 = image64 if image64.ndim == 3 else image64[..., None]
    transfer = _transfer(encoding, light)
    work = transfer[0](img3) if transfer else img3
    out = MAGNIFICATION_RENDERERS[renderer].render(work, sigma_extra, kernel=kernel, aperture=aperture,
                                                   in_front=in_front, progress=progress)
    if transfer:  # pixels the blur left unchanged are returned as given, without the round trip's rounding
        out = np.where(np.all(out == work, axis=-1, keepdims=True), img3, transfer[1](out))
    out = np.maximum(out, 0.0) if encoding == "linear" else np.clip(out, 0.0, 1.0)
    return out if image.ndim == 3 else out[..., 0]
