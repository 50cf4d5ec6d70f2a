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

Map floor (:data:`MAP_FLOOR_MODES`). Sec. 5 prepares the map by "cropping the upper and lower 5 %
of the defocus map and clamping its minimum value to 0". Two readings:

* ``"clamp"`` (default, the literal reading): B ← max(B, 0). It only removes negative overshoots,
  so an estimated map keeps its in-focus floor (σ ≈ 0.3–0.7 px of pixel-filter / sensor blur that
  does not scale with the aperture) and magnification adds √(k² − 1)·floor of blur to sharp regions.
* ``"subtract"``: make the map's minimum (the lower-percentile value p_lo after cropping) zero, as
  in a lens-blur depth map whose black is the focal plane — in quadrature, B ← √(max(B² − p_lo², 0)),
  because a Gaussian floor adds to the defocus blur in quadrature (B² = σ_d² + p_lo²).
* ``"shift"``: the same with a linear shift, B ← max(B − p_lo, 0) (over-corrects: removes more than
  the floor wherever B > p_lo, offered for comparison).

``factor < 1`` would need deblurring and is rejected.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from scipy import fft as sfft
from scipy import ndimage

from ..luma import LIGHTS, decode, encode, light_of
from ..validation import validate_image, validate_map
from ..registry import Entry, Registry
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


def _floor_clamp(m, floor):
    """Literal Sec. 5 reading: max(m, 0) px (``floor`` is not used)."""
    return np.maximum(m, 0.0)


def _floor_subtract(m, floor):
    """Remove a Gaussian floor of σ ``floor`` px in quadrature: √(max(m² − floor², 0))."""
    m = np.maximum(m, 0.0)
    return np.sqrt(np.maximum(m * m - floor * floor, 0.0))


def _floor_shift(m, floor):
    """Shift the map so that ``floor`` px becomes 0: max(m − floor, 0)."""
    return np.maximum(m - floor, 0.0)


#: How the map's floor is removed before the Sec. 5 smoothing, by name:
#: (clipped map px, floor p_lo px ≥ 0) → map px ≥ 0. See the module docstring.
MAP_FLOOR_MODES = Registry("map floor", {
    "clamp": Entry(_floor_clamp, "max(σ, 0), the literal Sec. 5 reading"),
    "subtract": Entry(_floor_subtract, "remove the floor in quadrature"),
    "shift": Entry(_floor_shift, "max(σ − floor, 0)"),
})


def _check_floor(floor):
    return MAP_FLOOR_MODES.check(floor, what="floor")


def preprocess_defocus_map(defocus_map, *, clip_percent=5.0, smoothing=0.005, floor="clamp") -> np.ndarray:
    """Prepare a defocus map for magnification as the paper does before lens blur (Sec. 5).

    Parameters
    ----------
    defocus_map : ndarray, HxW, float
        Dense blur σ, px (may hold small negative overshoots).
    clip_percent : float, keyword-only
        Clip values below the ``clip_percent`` and above the ``100 − clip_percent`` percentile, %
        (paper: 5). In [0, 50).
    smoothing : float, keyword-only
        σ of the Gaussian blur of the map as a fraction of max(H, W) (paper: 0.5 % → 0.005). ≥ 0.
    floor : str, keyword-only
        Key of :data:`MAP_FLOOR_MODES`, how "clamp its minimum value to 0" (Sec. 5) is read:
        ``"clamp"`` (default; max(B, 0), the literal reading), ``"subtract"`` (remove the floor
        p_lo = max(P_clip, 0) px in quadrature, √(max(B² − p_lo², 0))) or ``"shift"``
        (max(B − p_lo, 0)).

    Returns
    -------
    ndarray, HxW, float64, ≥ 0
        Processed σ map, px.

    Raises
    ------
    ValueError
        Bad map (not HxW, NaN/Inf), clip_percent outside [0, 50), smoothing < 0, unknown floor.

    Notes
    -----
    1. Clip to [P_clip, P_(100−clip)] (percentiles of the map's values, px).
    2. Floor (Sec. 5 "clamp its minimum value to 0"): with p_lo = max(P_clip, 0) px,
       ``"clamp"`` → max(B, 0); ``"subtract"`` → √(max(B² − p_lo², 0)); ``"shift"`` →
       max(B − p_lo, 0). Quadrature is the physically consistent one: an estimated in-focus σ
       is the defocus σ_d combined with a pixel-filter / sensor blur σ_f that does not change with
       the aperture, B = √(σ_d² + σ_f²), so √(B² − σ_f²) recovers σ_d everywhere, whereas a linear
       shift also shrinks every defocused value by up to p_lo (B − p_lo < σ_d for B > p_lo).
       This assumes p_lo is the in-focus floor σ_f (at least ``clip_percent`` % of the pixels are
       in focus and estimated no lower); in-focus pixels estimated above p_lo keep some extra blur.
       A zero map stays zero in every mode.
    3. Gaussian blur with σ = smoothing·max(H, W) px (reflecting borders).
    """
    m = _check_map(defocus_map)
    clip_percent = float(clip_percent)
    if not 0.0 <= clip_percent < 50.0:
        raise ValueError(f"clip_percent={clip_percent!r} is invalid; allowed: 0 <= p < 50")
    smoothing = float(smoothing)
    if not (np.isfinite(smoothing) and smoothing >= 0):
        raise ValueError(f"smoothing={smoothing!r} is invalid; allowed: finite and >= 0")
    floor = _check_floor(floor)
    lo, hi = np.percentile(m, [clip_percent, 100.0 - clip_percent])
    m = MAP_FLOOR_MODES[floor](np.clip(m, lo, hi), max(float(lo), 0.0))
    sigma = smoothing * max(m.shape)
    if sigma > 0:
        m = ndimage.gaussian_filter(m, sigma, mode="reflect")
    return np.maximum(m, 0.0)


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
                    in_front=None, progress: Callable[[str], None] | None = None) -> np.ndarray:
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
        blur), ``"subtract"`` (the lower-percentile value p_lo px is removed in quadrature, so
        pixels at the floor get no extra blur and the others √(factor² − 1)·√(B² − p_lo²) px) or
        ``"shift"`` (B − p_lo). Checked even when ``preprocess=False``, where it is not used.
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
        an extra blur σ_e above the image size (:func:`check_extra_blur`).

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
    floor = _check_floor(floor)
    if preprocess:
        m = preprocess_defocus_map(m, clip_percent=clip_percent, smoothing=smoothing, floor=floor)
    elif m.size and float(m.min()) < 0:
        raise ValueError(f"defocus_map must be >= 0 (blur σ, px) when preprocess=False, got min {float(m.min()):.6g}")
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
