"""Blur at edge pixels (Sec. 3.2) on analytic images with known σ.

Run with ``pytest -s`` to see the per-σ error tables.
"""

import math

import numpy as np
import pytest

from method.blur.estimators import BLUR_ESTIMATORS, estimate_blur
from method.blur.model_fit import blur_from_extrema_distance, response_model
from method.edges.elder_zucker import detect_edges
from method.params import DefocusParams
from scenes.analytic import blurred_disk, parallel_edges, step_edge
from tests import tolerances as tol

PARAMS = DefocusParams()
SIGMAS = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
METHODS = ("model_fit", "zero_crossing", "gradient_ratio")
_SHAPE = (80, 80)
_BORDER = 12
_NOISE = 2.0 / 255


def _edge_errors(sc, em, border=_BORDER):
    """|estimate − σ| per method at detected edge pixels within 1.5 px of a true edge."""
    inner = np.zeros(sc.image.shape, dtype=bool)
    inner[border:-border, border:-border] = True
    sel = em.edges & inner & (np.abs(sc.edge_distance) < 1.5)
    out = {}
    for m in METHODS:
        est = estimate_blur(sc.image, em, params=PARAMS, method=m)
        out[m] = np.abs(est[sel] - sc.sigma)
    return out


def _collect(make_scenes):
    table = {}
    for sigma in SIGMAS:
        errs = {m: [] for m in METHODS}
        for sc in make_scenes(sigma):
            em = detect_edges(sc.image)
            for m, e in _edge_errors(sc, em).items():
                errs[m].append(e)
        table[sigma] = {m: np.concatenate(v) for m, v in errs.items()}
    return table


def _median(e):
    """Median |error| counting failures (NaN) as infinitely wrong; NaN fraction reported separately."""
    return float(np.median(np.where(np.isnan(e), np.inf, e))) if e.size else math.nan


def _print_table(title, table):
    print(f"\n{title}: median |σ_est − σ| (px) [failure %], n edge pixels")
    print(f"{'σ':>5} " + " ".join(f"{m:>22}" for m in METHODS) + "      n")
    for sigma, errs in table.items():
        cells = [f"{_median(errs[m]):10.3f} [{100 * np.isnan(errs[m]).mean():4.1f}%]    " for m in METHODS]
        print(f"{sigma:5.1f} " + " ".join(f"{c:>22}" for c in cells) + f" {errs['model_fit'].size:6d}")


@pytest.fixture(scope="module")
def straight_clean():
    angles = [math.radians(a) for a in range(7, 360, 45)]  # 8 orientations, none axis-aligned
    return _collect(lambda s: [step_edge(_SHAPE, sigma=s, angle=a, offset=0.37) for a in angles])


@pytest.fixture(scope="module")
def straight_noisy():
    angles = [math.radians(a) for a in (0, 33, 71, 128)]
    return _collect(lambda s: [step_edge(_SHAPE, sigma=s, angle=a, offset=0.21, noise_std=_NOISE,
                                         quantize_bits=8, rng=int(10 * s) + i)
                               for i, a in enumerate(angles)])


@pytest.fixture(scope="module")
def disks_clean():
    def make(s):
        r = 8 * s + 16
        n = int(2 * r + 2 * _BORDER + 8 * s) | 1
        return [blurred_disk((n, n), sigma=s, radius=r, center=(n / 2 - 0.3, n / 2 + 0.2))]
    table = {}
    for s in (1.0, 2.0, 4.0, 6.0):
        sc = make(s)[0]
        em = detect_edges(sc.image)
        table[s] = _edge_errors(sc, em, border=2)
    return table


def test_table_straight_clean(straight_clean):
    _print_table("straight step edges, 8 orientations, no noise", straight_clean)
    for sigma, errs in straight_clean.items():
        if 1.0 <= sigma <= 6.0:
            bound = max(tol.MODEL_FIT_CLEAN_ATOL_PX, tol.MODEL_FIT_CLEAN_RTOL * sigma)
            assert _median(errs["model_fit"]) <= bound, sigma


def test_table_straight_noisy(straight_noisy):
    _print_table(f"straight step edges, noise {_NOISE * 255:.0f}/255 + 8-bit", straight_noisy)
    for sigma, errs in straight_noisy.items():
        if 1.0 <= sigma <= 6.0:
            bound = max(tol.MODEL_FIT_NOISY_ATOL_PX, tol.MODEL_FIT_NOISY_RTOL * sigma)
            assert _median(errs["model_fit"]) <= bound, sigma


def test_table_disks(disks_clean):
    _print_table("disks (curved edges, radius 8σ + 16 px), no noise", disks_clean)
    for sigma, errs in disks_clean.items():
        bound = max(tol.MODEL_FIT_DISK_ATOL_PX, tol.MODEL_FIT_DISK_RTOL * sigma)
        assert _median(errs["model_fit"]) <= bound, sigma


def test_model_fit_beats_zero_crossing_on_noisy_edges(straight_noisy):
    # The paper's Sec. 3.2 claim: the 3rd-derivative zero crossings are not robust on real
    # (noisy) images. Summed over σ ∈ [1, 6] the fit's median error is smaller.
    mf = np.concatenate([e["model_fit"] for s, e in straight_noisy.items() if 1 <= s <= 6])
    zc = np.concatenate([e["zero_crossing"] for s, e in straight_noisy.items() if 1 <= s <= 6])
    assert _median(mf) < _median(zc)


def test_neighbouring_edges_fig4():
    """Two parallel edges (a bright bar of width D = kσ), Fig. 4's situation.

    Prints the whole comparison. Measured (noise-free and with noise): where the two edges'
    2nd-derivative lobes overlap and shift the extrema (D = 3σ–4σ) the zero-crossing estimate
    degrades by 15–45 % and the model fit (with its window stopped where the neighbour's response
    takes over) is better; at D = 2σ and 6σ and for same-polarity "staircases" the two are
    comparable and zero_crossing is sometimes better — a single-edge model cannot fully explain
    a neighbour's lobe. The assertion covers the overlapping-lobe bar cases.
    """
    rows = []
    for kind in ("bar", "staircase"):
        for sigma in (1.0, 2.0, 3.0):
            for k in (2, 3, 4, 6):
                errs = {m: [] for m in METHODS}
                for i, a in enumerate((0.0, math.radians(30))):
                    sc = parallel_edges((112, 112), sigma=sigma, spacing=k * sigma, angle=a, kind=kind, offset=0.3)
                    em = detect_edges(sc.image)
                    for m, e in _edge_errors(sc, em, border=16).items():
                        errs[m].append(e / sigma)
                errs = {m: np.concatenate(v) for m, v in errs.items()}
                rows.append((kind, sigma, k, errs))
    print("\nparallel edges (no noise): median relative error |σ_est − σ|/σ, n")
    for kind, sigma, k, errs in rows:
        cells = " ".join(f"{m}={_median(errs[m]):6.3f}" for m in METHODS)
        print(f"  {kind:9s} σ={sigma:3.1f} D={k}σ  {cells}  n={errs['model_fit'].size}")
    overlap = [r for r in rows if r[0] == "bar" and r[2] in (3, 4)]
    mf = np.concatenate([r[3]["model_fit"] for r in overlap])
    zc = np.concatenate([r[3]["zero_crossing"] for r in overlap])
    assert _median(mf) < _median(zc)
    # zero_crossing visibly degrades there compared with an isolated edge (≈ 0.01–0.07 relative)
    assert _median(zc) > 0.15


def test_registry_and_unknown_name():
    assert set(METHODS) <= set(BLUR_ESTIMATORS)
    sc = step_edge((32, 32), sigma=2.0)
    em = detect_edges(sc.image)
    with pytest.raises(ValueError, match="model_fit"):
        estimate_blur(sc.image, em, params=PARAMS, method="nope")
    est = estimate_blur(sc.image, em, params=PARAMS)  # params.estimator
    assert est.shape == sc.image.shape and est.dtype == np.float64
    assert np.all(np.isnan(est[~em.edges]))
    assert np.isfinite(est[em.edges]).mean() > 0.9


def test_no_edges_gives_all_nan():
    img = np.full((40, 40), 0.3)
    em = detect_edges(img)
    for m in METHODS:
        est = estimate_blur(img, em, params=PARAMS, method=m)
        assert np.all(np.isnan(est))


def test_estimators_reject_mismatched_inputs():
    sc = step_edge((32, 32), sigma=2.0)
    em = detect_edges(sc.image)
    with pytest.raises(ValueError, match="shape"):
        estimate_blur(sc.image[:30], em, params=PARAMS)
    with pytest.raises(ValueError, match="EdgeMap"):
        estimate_blur(sc.image, {"edges": em.edges}, params=PARAMS)


def test_eq2_helpers():
    s = 2.5
    t = np.linspace(-10, 10, 20001)
    r = response_model(t, s=s, amplitude=0.7)
    d = t[np.argmin(r)] - t[np.argmax(r)]
    assert abs(d - 2 * s) < 2e-3
    assert math.isclose(float(blur_from_extrema_distance(2 * s, 1.5)), 2.0, rel_tol=1e-12)
    assert float(blur_from_extrema_distance(1.0, 2.0)) == 0.0
