"""The scatter renderer (method.magnify.scatter): kernels, energy, occlusion, linear light, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from method.magnify.magnification import magnify_defocus
from method.magnify.scatter import (APERTURES, HEXAGON_RADIUS_RATIO, aperture_kernel, layer_index, radius_for_sigma,
                                    scatter_blur)
from method.magnify.upsampling import magnify_defocus_tiled

#: Relative error allowed on a kernel's per-axis variance (σ ≥ 0.5 px): radii are quantised to 1/64 px;
#: measured for σ = 0.5, 0.7, 1, 1.5, 2.5, 6, 10 px: at most 1.0 % (hexagon, σ = 0.5), 0.75 % (disk).
VARIANCE_RTOL = 0.02


def _moments(out, cy, cx):
    y, x = np.mgrid[:out.shape[0], :out.shape[1]]
    total = out.sum()
    return total, float((out * (y - cy) ** 2).sum() / total), float((out * (x - cx) ** 2).sum() / total)


@pytest.mark.parametrize("aperture", list(APERTURES))
@pytest.mark.parametrize("b_px", [0.4, 1.5, 3.0])
def test_point_of_light_becomes_the_aperture_with_its_energy(aperture, b_px):
    """magnify_defocus(×2) of one bright pixel: its energy is kept (sum 1), the second moment is the
    extra blur σ_e = √3·B, and the support is the aperture of radius R ≈ 2σ_e (disk) or the hexagon of
    the same variance (wider than tall: flat top)."""
    n = 81
    img = np.zeros((n, n))
    img[40, 40] = 1.0
    out = magnify_defocus(img, np.full((n, n), b_px), factor=2.0, renderer="scatter", aperture=aperture,
                          encoding="linear", preprocess=False)
    sigma_e = math.sqrt(3.0) * b_px
    total, vy, vx = _moments(out, 40, 40)
    assert abs(total - 1.0) < 1e-12
    assert abs(0.5 * (vy + vx) - sigma_e**2) <= VARIANCE_RTOL * sigma_e**2
    r = float(radius_for_sigma(np.array([sigma_e]), aperture=aperture)[0])
    assert abs(r - 2.0 * sigma_e) < 0.1 * sigma_e + 0.3  # R ≈ 2σ (diameter 4σ), pixel grid aside
    y, x = np.mgrid[:n, :n] - 40
    support = out > 1e-12
    if aperture == "disk":
        assert np.all(np.hypot(y, x)[support] <= r + 1.0)
        assert np.all(support[np.hypot(y, x) <= r - 1.0])
    else:
        a = HEXAGON_RADIUS_RATIO * r
        inside = (np.abs(y) <= a * math.sqrt(3) / 2) & (np.abs(x) + np.abs(y) / math.sqrt(3) <= a)
        grown = (np.abs(y) <= a * math.sqrt(3) / 2 + 1) & (np.abs(x) + np.abs(y) / math.sqrt(3) <= a + 1.2)
        assert np.all(grown[support]) and np.all(support[ndimage.binary_erosion(inside, iterations=1)])
        if b_px >= 1.5:  # flat top and bottom: the hexagon is wider than tall
            assert np.any(support, axis=0).sum() > np.any(support, axis=1).sum()


@pytest.mark.parametrize("aperture", list(APERTURES))
def test_constant_map_equals_convolution_with_the_kernel(aperture):
    """With one σ everywhere the scatter is the convolution with aperture_kernel(σ), normalised by the
    kernel's sum inside the image at the borders."""
    rng = np.random.default_rng(0)
    img = rng.random((40, 52, 3))
    sigma = 2.3
    k = aperture_kernel(sigma, aperture=aperture)
    assert abs(k.sum() - 1.0) < 1e-12
    out = scatter_blur(img, np.full((40, 52), sigma), aperture=aperture)
    norm = ndimage.convolve(np.ones((40, 52)), k, mode="constant")
    ref = np.stack([ndimage.convolve(img[..., c], k, mode="constant") for c in range(3)], axis=-1) / norm[..., None]
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("sigma", [0.5, 0.7, 1.0, 2.5, 6.0])
def test_kernel_variance_is_sigma_squared(sigma):
    for aperture in APERTURES:
        k = aperture_kernel(sigma, aperture=aperture)
        cy, cx = k.shape[0] // 2, k.shape[1] // 2
        _, vy, vx = _moments(k, cy, cx)
        assert abs(0.5 * (vy + vx) - sigma**2) <= VARIANCE_RTOL * sigma**2, aperture


def _square_scene(square_sigma, background_sigma, n=64, lo=20, hi=44):
    """Background: texture in the red channel only; square: green only. Returns (image, σ map, square mask)."""
    rng = np.random.default_rng(1)
    img = np.zeros((n, n, 3))
    img[..., 0] = 0.2 + 0.6 * rng.random((n, n))
    square = np.zeros((n, n), bool)
    square[lo:hi, lo:hi] = True
    img[square] = (0.0, 0.8, 0.0)
    return img, np.where(square, square_sigma, background_sigma), square


def test_sharp_square_before_blurry_background_gets_no_background_radiance():
    """A sharp square (σ = 0) before a blurry background (σ_e ≈ 5 px): its interior and the 3-px band
    along its border receive no background (red) radiance and keep their values exactly, and the
    square leaks no green into the background (measured: 0). The gather keeps the square too but
    spreads it over the background (measured halo: green up to 0.36 outside, mean > 0.05 in the
    background's 3-px band)."""
    img, sigma, square = _square_scene(0.0, 3.0)
    band = square & ~ndimage.binary_erosion(square, iterations=3)
    outside_band = ndimage.binary_dilation(square, iterations=3) & ~square
    out = magnify_defocus(img, sigma, factor=2.0, renderer="scatter", encoding="linear", preprocess=False)
    assert float(out[..., 0][square].max()) == 0.0 and float(out[..., 0][band].max()) == 0.0
    np.testing.assert_array_equal(out[square], img[square])  # sharp and in front: kept bit for bit
    assert float(out[..., 1][~square].max()) == 0.0  # no halo of the subject
    gather = magnify_defocus(img, sigma, factor=2.0, encoding="linear", light="linear", preprocess=False)
    assert float(gather[..., 1][outside_band].mean()) > 0.05


def test_blurry_square_spreads_only_when_marked_in_front():
    """A blurry square before a sharp background is in front of the focus plane: marked ``in_front`` it
    spreads over the background (green within ~R outside the square), unmarked the rule "sharper is
    nearer" keeps it behind the sharp background, cut at its silhouette (the stated limit)."""
    img, sigma, square = _square_scene(3.0, 0.0)
    distance = ndimage.distance_transform_edt(~square)
    ring = (distance > 0) & (distance <= 3)
    far = distance > 12
    front = magnify_defocus(img, sigma, factor=2.0, renderer="scatter", encoding="linear", preprocess=False,
                            in_front=square)
    behind = magnify_defocus(img, sigma, factor=2.0, renderer="scatter", encoding="linear", preprocess=False)
    assert float(front[..., 1][ring].mean()) > 0.15  # spreads over what is behind it
    assert float(front[..., 1][far].max()) == 0.0  # not farther than its disk (R ≈ 10.4 px + the rim)
    assert float(behind[..., 1][~square].max()) == 0.0
    np.testing.assert_array_equal(behind[~square], img[~square])


def test_linear_light_keeps_a_highlight_brighter_than_srgb_blending():
    """A bright pixel on a dark ground blurred in linear light (the scatter's default, sRGB decoded)
    spreads into a brighter disk than blending the sRGB values as given (measured ring mean, sRGB:
    scatter 0.159 vs 0.111, gather 0.180 vs 0.116); far from it both are the ground."""
    n = 41
    img = np.full((n, n, 3), 0.1)
    img[20, 20] = 1.0
    sigma = np.full((n, n), 1.5)
    for renderer in ("scatter", "gather"):
        lin = magnify_defocus(img, sigma, factor=2.0, renderer=renderer, light="linear", preprocess=False)
        disp = magnify_defocus(img, sigma, factor=2.0, renderer=renderer, light="display", preprocess=False)
        ring = (np.hypot(*np.mgrid[-20:21, -20:21]) >= 1) & (np.hypot(*np.mgrid[-20:21, -20:21]) <= 3)
        assert float(lin[..., 0][ring].mean()) > float(disp[..., 0][ring].mean()) + 0.02, renderer
        np.testing.assert_allclose(lin[:5, :5], 0.1, atol=1e-9)
        np.testing.assert_allclose(disp[:5, :5], 0.1, atol=1e-9)


def test_highlights_are_not_clipped_in_linear():
    img = np.full((31, 31, 3), 0.05)
    img[15, 15] = 40.0  # a specular highlight, far above white
    out = magnify_defocus(img, np.full((31, 31), 1.0), factor=2.0, renderer="scatter", encoding="linear",
                          preprocess=False)
    assert float(out.max()) > 1.0
    # energy conserved: the ground stays 0.05 everywhere, so the highlight's excess is all still there
    np.testing.assert_allclose(float((out - 0.05).sum()), (40.0 - 0.05) * 3, rtol=1e-9)


@pytest.mark.parametrize("top_px", [4.0, 24.0])
def test_tiled_scatter_equals_whole_image(top_px):
    """Tiles (with their halo, aligned to the coarsest blocks) give the whole-image result; σ up to 24 px
    spreads through every block level."""
    from method.magnify.scatter import COARSE_RADIUS, MAX_LEVEL
    from method.magnify.upsampling import _halo

    rng = np.random.default_rng(2)
    h, w = (300, 280) if top_px < 10 else (560, 600)
    img = rng.random((h, w, 3))
    m = top_px * np.linspace(0.0, 1.0, w)[None, :] * np.ones((h, 1)) / math.sqrt(3.0)  # σ_e = √3·B up to top_px
    whole = magnify_defocus(img, m, factor=2.0, renderer="scatter", preprocess=False)
    tiled = magnify_defocus_tiled(img, m, factor=2.0, renderer="scatter", preprocess=False, tile_pixels=256 * 256)
    # the occlusion's hidden fraction is a float32 FFT whose round-off depends on the FFT size (measured
    # ≤ 1.4e-7 here); everything else agrees to float64 round-off
    np.testing.assert_allclose(tiled, whole, rtol=0, atol=1e-6)
    if top_px > 10:
        assert 2 * top_px >= 2 * COARSE_RADIUS  # the coarse levels were used
        assert _halo(top_px, "scatter") % 2**MAX_LEVEL == 0


def test_layers_order_sharper_nearer_and_in_front_first():
    sigma = np.array([[0.0, 0.6, 3.0], [3.0, 0.2, 1.2]])
    layers = layer_index(sigma)
    # bins [0, 0.5), [0.5, 0.71), [0.71, 1), [1, 1.41), [1.41, 2), [2, 2.83), [2.83, 4) px
    ids = layers.ids
    assert [int(ids[0, 0]), int(ids[0, 1]), int(ids[0, 2]), int(ids[1, 2])] == [0, 1, 6, 3]
    assert list(layers.order) == [0, 1, 3, 6]
    assert np.all(np.diff(layers.sigma) > 0) and np.all(layers.sigma < layers.upper)
    for layer, top in zip(layers.order, layers.upper):
        assert float(sigma[ids == layer].max()) < top
    front = np.zeros_like(sigma, bool)
    front[1, 0] = front[0, 1] = True
    layers = layer_index(sigma, in_front=front)
    first = [int(layers.ids[1, 0]), int(layers.ids[0, 1])]
    assert list(layers.order[:2]) == first and layers.sigma[0] > layers.sigma[1]  # in front: blurrier first


@pytest.mark.parametrize("kwargs,needle", [
    ({"renderer": "splat"}, "renderer='splat' is invalid"),
    ({"renderer": "scatter", "aperture": "octagon"}, "aperture='octagon' is invalid"),
    ({"renderer": "scatter", "kernel": "disk"}, "kernel applies to the 'gather' renderer"),
    ({"aperture": "disk"}, "aperture applies to the 'scatter' renderer"),
    ({"in_front": np.ones((10, 10), bool)}, "in_front applies to the 'scatter' renderer"),
    ({"renderer": "scatter", "in_front": np.ones((9, 10), bool)}, "in_front must be a bool array"),
    ({"renderer": "scatter", "encoding": "log"}, "encoding='log' is invalid"),
    ({"encoding": "display"}, "encoding='display' is invalid .*allowed: .*'linear', 'srgb'"),
    ({"renderer": "scatter", "light": "srgb"}, "light='srgb' is invalid .*allowed: 'display', 'linear'"),
])
def test_bad_renderer_options(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        magnify_defocus(np.random.default_rng(0).random((10, 10, 3)), np.ones((10, 10)), **kwargs)


def test_bad_sigma_and_linear_image():
    img = np.random.default_rng(0).random((10, 10, 3))
    for bad in (np.full((10, 10), np.nan), -np.ones((10, 10))):
        with pytest.raises(ValueError, match="sigma must be finite and >= 0"):
            scatter_blur(img, bad)
    with pytest.raises(ValueError, match="sigma has shape"):
        scatter_blur(img, np.ones((9, 10)))
    with pytest.raises(ValueError, match=">= 0"):
        magnify_defocus(img - 1.0, np.ones((10, 10)), renderer="scatter", encoding="linear")
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        magnify_defocus(img * 3.0, np.ones((10, 10)), renderer="scatter")  # sRGB values above 1


@pytest.mark.parametrize("sigma", [7.0, 14.0, 25.0])
def test_coarse_levels_agree_with_the_full_resolution_scatter(sigma, monkeypatch):
    """Blurs wider than COARSE_RADIUS are spread as blocks at lower resolution: on a photo the result
    stays within 50 dB PSNR of spreading every pixel at full resolution (measured 53.4–60.4 dB)."""
    import method.magnify.scatter as scatter
    from skimage import data

    img = data.coffee() / 255.0
    m = np.full(img.shape[:2], sigma)
    coarse = scatter_blur(img, m)
    monkeypatch.setattr(scatter, "COARSE_RADIUS", np.inf)
    fine = scatter_blur(img, m)
    inner = (slice(60, -60), slice(60, -60))
    psnr = 10 * np.log10(1.0 / np.mean((coarse[inner] - fine[inner]) ** 2))
    assert psnr >= 50.0, psnr
