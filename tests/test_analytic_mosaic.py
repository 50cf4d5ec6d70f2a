"""Texture mosaics and dead leaves (scenes.analytic): determinism, ground-truth maps, and that the
blur in the images is the σ that is claimed.

Tolerances are named constants below (measured values in the comments).
"""

import numpy as np
import pytest
from scipy.ndimage import correlate1d, gaussian_filter
from scipy.optimize import minimize_scalar

from scenes.analytic import _lattice as L
from scenes.analytic import leaves
from scenes.analytic import (SKIMAGE_INTRINSIC_SIGMA_PX, TEXTURES, TextureMosaic, blurred_disk,
                             dead_leaves, step_edge, texture_mosaic)

#: Fitted σ of a supersampled-and-point-sampled disc / straight edge vs the σ applied, px.
#: Measured |error| <= 0.0016 px (s = 4, σ = 0.5–4, 3 discs, 4 edge angles); 0.05 px is the
#: accuracy the ground truth is meant to have (an order of magnitude below estimator errors).
BLUR_FIT_TOL_PX = 0.05
#: Implied σ of a dead-leaves image re-blurred from its σ = 1 version, px (measured <= 1e-6).
RELATIVE_BLUR_TOL_PX = 0.05
#: One-stage decimating blur vs scipy.ndimage.gaussian_filter then point sampling (round-off).
ONE_STAGE_ATOL = 1e-12
#: Cascade (σ >= 2 px) vs the one-stage result on binary white noise (measured <= 1e-5).
CASCADE_ATOL = 3e-5
#: Photograph tile interior vs the discrete Gaussian applied to the sharp mosaic (round-off).
LAYER_ATOL = 1e-12
#: Relative variance deficit of the truncated discrete Gaussian (measured <= 5e-6 for σ = 0.5–8).
DISCRETE_VAR_RTOL = 1e-5
#: Seed-averaged (6 seeds) column mean in the seam band vs E[dead leaves] = 0.5 (measured 0.035;
#: the unnormalised layer sum would give ~0.16).
SEAM_MEAN_TOL = 0.08


def _fit_sigma(model, target, lo=0.05, hi=12.0):
    """σ minimising ||model(σ) − target||² (bounded scalar search)."""
    res = minimize_scalar(lambda s: float(np.sum((model(s) - target) ** 2)), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-5})
    return res.x


def _render_fine_disc(shape, s, center, radius):
    """Indicator of one disc on the fine lattice of :func:`dead_leaves` (padded by ``pad`` px)."""
    h, w = shape
    n_y, n_x = (h - 1) * s + 1, (w - 1) * s + 1
    cy, cx = center[0] * s, center[1] * s
    hit, _ = leaves._first_cover(np.arange(n_y * n_x), n_y * n_x, n_x, np.array([cy]), np.array([cx]),
                            np.array([radius * s]))
    fine = np.zeros(n_y * n_x)
    fine[hit] = 1.0
    return fine.reshape(n_y, n_x)


# --- the blur is what is claimed -------------------------------------------------------------

@pytest.mark.parametrize("sigma", [1.0, 2.0, 4.0])
def test_supersampled_disc_matches_analytic_blur(sigma):
    s, pad, shape = 4, 20, (64, 64)
    big = (shape[0] + 2 * pad, shape[1] + 2 * pad)
    center = (pad + 31.3, pad + 32.6)  # sub-pixel, fine-lattice-incommensurate
    fine = _render_fine_disc(big, s, center, 18.7)
    stages = L.blur_stages(sigma, s)
    img = L.apply_stages_2d(fine, stages, (pad * s, pad * s), shape)
    c = (center[0] - pad, center[1] - pad)
    fit = _fit_sigma(lambda v: blurred_disk(shape, sigma=v, radius=18.7, center=c, inside=1.0,
                                            outside=0.0).image, img)
    assert abs(fit - sigma) < BLUR_FIT_TOL_PX, (sigma, fit)


@pytest.mark.parametrize("sigma", [1.0, 2.0, 4.0])
def test_supersampled_straight_edge_matches_step_edge(sigma):
    """A disc of radius 1e5 px is a straight edge; fit the edge-spread function of step_edge."""
    s, pad, shape = 4, 20, (48, 48)
    big = (shape[0] + 2 * pad, shape[1] + 2 * pad)
    angle, offset, radius = 0.3, 0.37, 1e5
    mid = (pad + 23.5, pad + 23.5)
    # centre of the huge disc on the dark side, so the edge passes `offset` px from the image centre
    center = (mid[0] - (radius - offset) * np.sin(angle), mid[1] - (radius - offset) * np.cos(angle))
    fine = _render_fine_disc(big, s, center, radius)  # inside = the side the normal points away from
    img = L.apply_stages_2d(fine, L.blur_stages(sigma, s), (pad * s, pad * s), shape)
    fit = _fit_sigma(lambda v: 1.0 - step_edge(shape, sigma=v, angle=angle, offset=offset,
                                               low=0.0, high=1.0).image, img)
    assert abs(fit - sigma) < BLUR_FIT_TOL_PX, (sigma, fit)


@pytest.mark.parametrize("sigma", [0.5, 1.0, 1.5, 2.0, 3.0, 8.0])
def test_decimating_blur_is_gaussian_filter_point_sampled(sigma):
    s = 4
    f = (np.random.default_rng(3).random((420, 410)) > 0.5).astype(np.float64)
    stages = L.blur_stages(sigma, s)
    rad = L.stages_support(stages)
    n = ((f.shape[0] - 1 - 2 * rad) // s, (f.shape[1] - 1 - 2 * rad) // s)
    out = L.apply_stages_2d(f, stages, (rad, rad), n)
    ref = gaussian_filter(f, sigma * s, mode="reflect")[rad:rad + s * n[0]:s, rad:rad + s * n[1]:s]
    tol = ONE_STAGE_ATOL if len(stages) == 1 else CASCADE_ATOL
    assert np.abs(out - ref).max() < tol


@pytest.mark.parametrize("sigma", [2.0, 4.0])
def test_dead_leaves_reblurred_from_sigma_1(sigma):
    """Same seed, same discs: G_σ' ∗ DL(σ = 1) ≈ DL(σ) with √(1 + σ'²) = σ (output-grid filter)."""
    kw = dict(rng=11, radius_range=(2.0, 24.0))
    base = dead_leaves((96, 96), sigma=1.0, **kw)
    target = dead_leaves((96, 96), sigma=sigma, **kw)
    m = 24  # drop the border, where the output-grid filter has to reflect
    fit = _fit_sigma(lambda v: gaussian_filter(base, v, mode="reflect")[m:-m, m:-m],
                     target[m:-m, m:-m], lo=0.5)
    assert abs(np.hypot(1.0, fit) - sigma) < RELATIVE_BLUR_TOL_PX


def test_mosaic_tiles_reblurred_from_sigma_1():
    kw = dict(tile=64, cols=3, rng=5, color=False, radius_range=(2.0, 24.0))
    base = texture_mosaic(sigmas=(1.0, 1.0, 1.0), **kw)
    mos = texture_mosaic(sigmas=(1.0, 2.0, 4.0), **kw)
    for t, sigma in enumerate(mos.sigmas):
        c0, m = 64 * t, 18  # interior of the tile, far from the seams
        tgt = mos.image[m:-m, c0 + m:c0 + 64 - m]
        if sigma == 1.0:
            np.testing.assert_allclose(tgt, base.image[m:-m, c0 + m:c0 + 64 - m], atol=1e-12)
            continue
        fit = _fit_sigma(lambda v: gaussian_filter(base.image, v, mode="reflect")[m:-m, c0 + m:c0 + 64 - m],
                         tgt, lo=0.5)
        assert abs(np.hypot(1.0, fit) - sigma) < RELATIVE_BLUR_TOL_PX, (sigma, fit)


def test_skimage_tile_interior_is_the_discrete_gaussian_of_the_sharp_tile():
    kw = dict(tile=48, cols=2, rng=2, texture="skimage", color=False)
    sharp = texture_mosaic(sigmas=(0.0, 0.0), **kw)
    mos = texture_mosaic(sigmas=(0.0, 2.0), **kw)
    k = L.discrete_gaussian(2.0)
    ref = correlate1d(correlate1d(sharp.image, k, axis=0, mode="reflect"), k, axis=1, mode="reflect")
    m = 16  # > kernel radius 12 from the seam and from the (mirrored) canvas border
    assert np.abs(mos.image[m:-m, 48 + m:-m] - ref[m:-m, 48 + m:-m]).max() < LAYER_ATOL
    np.testing.assert_array_equal(mos.image[:, :20], sharp.image[:, :20])  # the σ = 0 tile is untouched


@pytest.mark.parametrize("sigma", [0.5, 1.0, 2.0, 8.0])
def test_discrete_gaussian_has_the_claimed_variance(sigma):
    k = L.discrete_gaussian(sigma)
    n = np.arange(k.size) - (k.size - 1) // 2
    assert abs(k.sum() - 1) < 1e-12
    assert abs(np.sum(k * n * n) / sigma ** 2 - 1) < DISCRETE_VAR_RTOL


# --- determinism ---------------------------------------------------------------------------

def test_dead_leaves_deterministic():
    a = dead_leaves((40, 50), sigma=1.5, rng=7, color=True)
    b = dead_leaves((40, 50), sigma=1.5, rng=7, color=True)
    c = dead_leaves((40, 50), sigma=1.5, rng=8, color=True)
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()
    g1 = dead_leaves((40, 50), rng=np.random.default_rng(3))
    g2 = dead_leaves((40, 50), rng=np.random.default_rng(3))
    assert g1.tobytes() == g2.tobytes()


def test_dead_leaves_shape_range_levels():
    g = dead_leaves((30, 41), sigma=0.0, rng=1, n_levels=3, value_range=(0.2, 0.8))
    assert g.shape == (30, 41) and g.dtype == np.float64
    assert set(np.round(np.unique(g), 12)) <= {0.2, 0.5, 0.8}
    c = dead_leaves((30, 41), sigma=2.0, rng=1, color=True)
    assert c.shape == (30, 41, 3) and 0.1 <= c.min() and c.max() <= 0.9
    # the plane does not depend on the window: supersample 1 vs 4 agree where they sample the same points
    s1, s4 = dead_leaves((30, 41), rng=1, supersample=1), dead_leaves((30, 41), rng=1, supersample=4)
    np.testing.assert_array_equal(s1, s4)  # the same plane points (output centres), same discs


@pytest.mark.parametrize("texture", TEXTURES)
def test_mosaic_deterministic(texture):
    kw = dict(sigmas=(0.5, 2.0, 3.0), tile=32, cols=2, texture=texture, noise_std=0.01)
    a, b, c = texture_mosaic(rng=4, **kw), texture_mosaic(rng=4, **kw), texture_mosaic(rng=5, **kw)
    assert isinstance(a, TextureMosaic) and a.texture == texture
    assert a.image.tobytes() == b.image.tobytes() and np.array_equal(a.boundary, b.boundary)
    assert a.image.tobytes() != c.image.tobytes()


# --- ground-truth maps ---------------------------------------------------------------------

def test_mosaic_layout_sigma_map_and_boundary():
    sig = (0.5, 1.0, 2.0, 4.0, 8.0)
    m = texture_mosaic(sigmas=sig, tile=32, cols=4, color=True)
    assert m.image.shape == (64, 128, 3) and m.sigma.shape == (64, 128)
    assert m.sigmas == sig and m.intrinsic_sigma == 0.0
    assert m.tile_index[0, 0] == 0 and m.tile_index[0, 127] == 3
    assert np.all(m.tile_index[32:] == 4)  # the incomplete last row is one widened tile
    for t, s in enumerate(sig):
        assert np.all(m.sigma[m.tile_index == t] == s)
    # every pixel with a 4-neighbour in another tile is flagged
    ti = m.tile_index
    seam = np.zeros_like(m.boundary)
    seam[:, 1:] |= ti[:, 1:] != ti[:, :-1]
    seam[:, :-1] |= ti[:, 1:] != ti[:, :-1]
    seam[1:] |= ti[1:] != ti[:-1]
    seam[:-1] |= ti[1:] != ti[:-1]
    assert np.all(m.boundary[seam])
    assert not m.boundary.all()


def test_boundary_band_width():
    m = texture_mosaic(sigmas=(1.0, 4.0), tile=48, cols=2, color=False)
    band = int(np.ceil(3 * 4.0)) + 2  # 14 px each side of the seam at x = 47.5
    cols = np.flatnonzero(m.boundary.any(axis=0))
    assert cols.min() == 48 - band and cols.max() == 47 + band
    assert np.all(m.boundary[:, cols.min():cols.max() + 1])
    fixed = texture_mosaic(sigmas=(1.0, 4.0), tile=48, cols=2, color=False, boundary_band=3)
    assert np.array_equal(np.flatnonzero(fixed.boundary.any(axis=0)), np.arange(45, 51))
    assert not texture_mosaic(sigmas=(1.0, 4.0), tile=48, cols=2, boundary_band=0).boundary.any()


def test_skimage_sigma_map_includes_intrinsic_blur():
    m = texture_mosaic(sigmas=(0.0, 1.0, 3.0), tile=32, cols=3, texture="skimage")
    assert m.intrinsic_sigma == SKIMAGE_INTRINSIC_SIGMA_PX
    for t, s in enumerate(m.sigmas):
        np.testing.assert_allclose(m.sigma[m.tile_index == t], np.hypot(s, SKIMAGE_INTRINSIC_SIGMA_PX))
    assert m.image.shape == (32, 96, 3) and 0.0 <= m.image.min() and m.image.max() <= 1.0


def test_seams_are_not_darkened():
    """E[dead leaves] = 0.5 everywhere, so the seed-averaged column profile across a σ = 0.5 | 8
    seam must stay flat; without the normalisation it would swing to ≈ 0.66 / 0.34 at the seam."""
    prof = np.mean([texture_mosaic(sigmas=(0.5, 8.0), tile=64, cols=2, rng=k).image.mean(axis=(0, 2))
                    for k in range(6)], axis=0)
    band = texture_mosaic(sigmas=(0.5, 8.0), tile=64, cols=2).boundary.any(axis=0)
    assert np.abs(prof[band] - 0.5).max() < SEAM_MEAN_TOL


# --- degradation and validation ------------------------------------------------------------

def test_quantisation_on_the_8_bit_grid():
    m = texture_mosaic(sigmas=(1.0, 2.0), tile=32, cols=2, noise_std=2 / 255, quantize_bits=8)
    q = m.image * 255
    assert np.abs(q - np.round(q)).max() < 1e-9
    clean = texture_mosaic(sigmas=(1.0, 2.0), tile=32, cols=2)
    assert 0 < np.abs(m.image - clean.image).mean() < 4 / 255


@pytest.mark.parametrize("kwargs", [
    dict(sigmas=()), dict(sigmas=(1.0, -0.5)), dict(sigmas=(1.0, np.nan)), dict(sigmas=(np.inf,)),
    dict(sigmas=3.0), dict(sigmas=("a",)), dict(tile=15), dict(tile=32.5), dict(cols=0),
    dict(texture="brodatz"), dict(color="yes"), dict(noise_std=-1.0), dict(quantize_bits=0),
    dict(boundary_band=-1), dict(boundary_band=np.inf), dict(rng=-1), dict(rng="seed"),
    dict(supersample=0), dict(radius_range=(0.1, 4.0)), dict(radius_range=(4.0, 2.0)),
])
def test_mosaic_bad_arguments(kwargs):
    base = dict(sigmas=(1.0,), tile=16)
    base.update(kwargs)
    with pytest.raises(ValueError):
        texture_mosaic(**base)


def test_unknown_texture_lists_allowed_names():
    with pytest.raises(ValueError, match="dead_leaves.*skimage"):
        texture_mosaic(texture="noise")


@pytest.mark.parametrize("kwargs", [
    dict(shape=(2, 10)), dict(shape=(10,)), dict(sigma=-1.0), dict(sigma=np.nan),
    dict(radius_range=(0.0, 5.0)), dict(radius_range=(1.0, 1e4)), dict(radius_range=3.0),
    dict(supersample=17), dict(supersample=2.0), dict(n_levels=1), dict(color=1),
    dict(value_range=(0.5, 0.5)), dict(value_range=(-0.1, 0.5)), dict(rng=-3),
])
def test_dead_leaves_bad_arguments(kwargs):
    base = dict(shape=(16, 16))
    base.update(kwargs)
    shape = base.pop("shape")
    with pytest.raises(ValueError):
        dead_leaves(shape, **base)
