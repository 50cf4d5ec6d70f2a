"""Elder–Zucker multiscale edges with minimum reliable scale (Sec. 3.1) on analytic images."""

import math

import numpy as np
import pytest
import scipy.ndimage as ndi

from method.edges.elder_zucker import EdgeMap, detect_edges
from scenes.analytic import blurred_disk, step_edge
from tests import tolerances as tol

_SHAPE = (80, 80)
_BORDER = 12


def _inner(shape, border=_BORDER):
    m = np.zeros(shape, dtype=bool)
    m[border:-border, border:-border] = True
    return m


@pytest.mark.parametrize("sigma", [1.0, 4.0])
def test_straight_edges_found_thin_and_oriented(sigma):
    for deg in range(0, 360, 30):
        th = math.radians(deg + 7)
        sc = step_edge(_SHAPE, sigma=sigma, angle=th, offset=0.3)
        em = detect_edges(sc.image)
        inner = _inner(_SHAPE)
        truth = sc.edge_mask & inner
        found = em.edges & inner
        recall = (found & truth).sum() / truth.sum()
        assert recall >= tol.EDGE_RECALL_MIN, (deg, recall)
        assert np.abs(sc.edge_distance[found]).max() <= tol.EDGE_LOCALISATION_PX, deg
        dth = np.angle(np.exp(1j * (em.theta[found] - th)))
        assert np.median(np.abs(dth)) <= tol.EDGE_THETA_MEDIAN_RAD, deg
        assert np.all(np.isfinite(em.sigma1[found])) and np.all(np.isfinite(em.sigma2[found]))
        assert np.all(em.gradient_magnitude[found] > 0)


def test_minimum_reliable_scale_grows_with_blur():
    s2 = []
    for sigma in (0.5, 2.0, 8.0):
        sc = step_edge(_SHAPE, sigma=sigma, angle=0.0, offset=0.3)
        em = detect_edges(sc.image)
        s2.append(np.median(em.sigma2[em.edges & _inner(_SHAPE)]))
    assert s2[0] <= s2[1] <= s2[2] and s2[0] < s2[2]


def test_disk_edges_follow_the_circle():
    sc = blurred_disk((96, 96), sigma=2.0, radius=30.0, center=(47.3, 48.6))
    em = detect_edges(sc.image)
    inner = _inner(sc.image.shape, 4)
    found = em.edges & inner
    truth = sc.edge_mask & inner
    # on a curve the pixel chosen along the sampling axis can differ by one from the pixel nearest
    # along the normal: count a true pixel as found if an edge lies in its 3x3 neighbourhood
    near_found = ndi.binary_dilation(found, structure=np.ones((3, 3), bool))
    assert (near_found & truth).sum() / truth.sum() >= tol.EDGE_RECALL_MIN
    near = np.abs(sc.edge_distance[found]) <= tol.EDGE_LOCALISATION_PX
    assert near.mean() >= 0.98


def test_edge_map_types_and_shapes():
    sc = step_edge((40, 50), sigma=1.0, angle=0.4)
    em = detect_edges(sc.image)
    assert isinstance(em, EdgeMap)
    for name in ("edges", "theta", "gradient_magnitude", "sigma1", "sigma2"):
        assert getattr(em, name).shape == (40, 50)
    assert em.edges.dtype == bool
    for name in ("theta", "gradient_magnitude", "sigma1", "sigma2"):
        assert getattr(em, name).dtype == np.float64
    unreliable = np.isnan(em.sigma1)
    assert np.all(em.gradient_magnitude[unreliable] == 0)
    assert np.all(np.isnan(em.sigma2[unreliable]))


def test_no_edges_in_constant_or_low_noise_images(rng):
    em = detect_edges(np.full((48, 48), 0.4))
    assert not em.edges.any() and np.isnan(em.sigma1).all()
    noisy = np.clip(0.5 + rng.normal(0, 0.5 / 255, (64, 64)), 0, 1)
    em = detect_edges(noisy)
    assert not em.edges.any()


def test_noise_at_the_assumed_level_gives_almost_no_edges(rng):
    noisy = np.clip(0.5 + rng.normal(0, 2.5 / 255, (96, 96)), 0, 1)
    em = detect_edges(noisy)
    assert em.edges.sum() <= 2  # α_I = 1e-6 per test; allow a couple from scale correlations


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((8, 8, 3)), "shape HxW,"),
        (np.zeros((2, 8)), "smallest supported side is 3 px"),
        (np.zeros((8, 8), dtype=np.uint8), "float array"),
        (np.array([[0.0, np.nan, 0.0]] * 3), "NaN"),
    ],
)
def test_bad_input_raises(bad, match):
    with pytest.raises(ValueError, match=match):
        detect_edges(bad)


def test_bad_options_raise():
    img = np.zeros((8, 8))
    with pytest.raises(ValueError, match="sigma1_scales"):
        detect_edges(img, sigma1_scales=())
    with pytest.raises(ValueError, match="sigma2_scales"):
        detect_edges(img, sigma2_scales=(1.0, -2.0))
    with pytest.raises(ValueError, match="noise_std"):
        detect_edges(img, noise_std=0.0)
    with pytest.raises(ValueError, match="false_positive_rate"):
        detect_edges(img, false_positive_rate=2.0)


def test_edges_do_not_depend_on_the_thread_count(rng, monkeypatch):
    """One thread (the runner's cases) and several (responses computed ahead on a pool) give the same bytes."""
    import numba

    img = blurred_disk(_SHAPE, sigma=2.0, radius=22.0, noise_std=0.02, rng=rng).image
    maps = []
    for n in (1, 3):  # the pool's path whatever the machine's core count
        monkeypatch.setattr(numba, "get_num_threads", lambda n=n: n)
        maps.append(detect_edges(img, keep_hessians=True))
    assert maps[0].edges.any() and len(maps[0].hessians) > 1
    for name in ("edges", "theta", "gradient_magnitude", "sigma1", "sigma2"):
        assert getattr(maps[1], name).tobytes() == getattr(maps[0], name).tobytes(), name
    assert sorted(maps[1].hessians) == sorted(maps[0].hessians)
    for s in maps[0].hessians:
        assert [h.tobytes() for h in maps[1].hessians[s]] == [h.tobytes() for h in maps[0].hessians[s]]
