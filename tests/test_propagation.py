"""Propagation, Eq. (4): normal equations, oracle agreement, invariants, colour-edge steps."""

import numpy as np
import pytest
import scipy.sparse as sp

from method.propagation.defocus import (
    PROPAGATION_REFINEMENTS,
    PROPAGATION_SOLVERS,
    colorization_matrix,
    colorization_weights,
    normal_equations,
    propagate_defocus,
)
from tests.tolerances import (
    PROPAGATION_COARSE_RMS_RTOL,
    PROPAGATION_DEFAULT_VS_EXACT_P99_PX,
    PROPAGATION_DEFAULT_VS_EXACT_RMS_PX,
    PROPAGATION_DIRECT_RTOL,
    PROPAGATION_RESIDUAL_RTOL,
    PROPAGATION_ROW_SUM_ATOL,
)


def _photo(rng, h, w):
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    ref = np.stack([0.5 + 0.4 * np.sin(6 * xx + 2 * yy), 0.5 + 0.3 * np.cos(5 * yy), 0.3 + 0.4 * (xx > 0.5)], -1)
    return np.clip(ref + 0.03 * rng.standard_normal((h, w, 3)), 0, 1)


def _sparse(rng, ref, density=0.05):
    h, w = ref.shape[:2]
    mask = rng.random((h, w)) < density
    truth = 1.0 + 3.0 * ref[..., 2] + np.linspace(0, 1, w)[None, :]
    return np.where(mask, truth, np.nan)


def test_solvers_registered():
    assert set(PROPAGATION_SOLVERS) == {"amg_pcg", "direct"}
    assert set(PROPAGATION_REFINEMENTS) == {"galerkin"}


@pytest.mark.parametrize("neighborhood", [3, 5, 7])
def test_rows_of_w_sum_to_one(rng, neighborhood):
    ref = _photo(rng, 23, 17)
    L = colorization_matrix(ref, window=7, neighborhood=neighborhood)
    assert isinstance(L, sp.csr_matrix) and L.shape == (23 * 17, 23 * 17)
    np.testing.assert_allclose(L.diagonal(), 1.0)
    np.testing.assert_allclose(np.asarray(L.sum(axis=1)).ravel(), 0.0, atol=PROPAGATION_ROW_SUM_ATOL)
    off = L - sp.diags(L.diagonal())
    assert off.max() <= 0  # w_pq >= 0
    assert L.getnnz(axis=1).max() == neighborhood**2
    w, offs = colorization_weights(ref, window=7, neighborhood=neighborhood)
    np.testing.assert_allclose(w.sum(axis=0), 1.0, atol=PROPAGATION_ROW_SUM_ATOL)


def test_weights_follow_eq4c_by_hand():
    """One interior pixel's affinities recomputed directly from Eq. (4c)."""
    rng = np.random.default_rng(3)
    ref = rng.random((9, 9, 3))
    w, offs = colorization_weights(ref, window=7, neighborhood=3)
    p = (4, 4)
    win = ref[1:8, 1:8].reshape(-1, 3)
    var = np.maximum(win.var(axis=0), 1e-6)
    raw = []
    for dy, dx in offs:
        q = ref[p[0] + dy, p[1] + dx]
        raw.append(np.sum(np.exp(-((ref[p] - q) ** 2) / (2 * var))))
    raw = np.array(raw)
    np.testing.assert_allclose(w[:, 4, 4], raw / raw.sum(), rtol=1e-12)


def test_exact_solve_satisfies_normal_equations(rng):
    ref = _photo(rng, 48, 64)
    bm = _sparse(rng, ref)
    B = propagate_defocus(bm, ref, downsample=1, tol=1e-7)
    A, rhs = normal_equations(bm, ref)
    res = np.linalg.norm(A @ B.ravel() - rhs) / np.linalg.norm(rhs)
    assert res <= PROPAGATION_RESIDUAL_RTOL


@pytest.mark.parametrize("neighborhood", [3, 7])
def test_amg_pcg_matches_direct(rng, neighborhood):
    ref = _photo(rng, 40, 50)
    bm = _sparse(rng, ref)
    kw = dict(neighborhood=neighborhood, downsample=1)
    amg = propagate_defocus(bm, ref, solver="amg_pcg", tol=1e-8, **kw)
    direct = propagate_defocus(bm, ref, solver="direct", **kw)
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.max(np.abs(amg - direct)) <= PROPAGATION_DIRECT_RTOL * span


def test_constant_bm_gives_constant_map(rng):
    ref = _photo(rng, 30, 40)
    bm = np.where(rng.random((30, 40)) < 0.05, 2.5, np.nan)
    for solver in ("amg_pcg", "direct"):
        np.testing.assert_allclose(propagate_defocus(bm, ref, solver=solver), 2.5, rtol=0, atol=1e-12)


def test_constant_bm_through_the_solver_stays_constant(rng):
    """Same check without the constant shortcut: nearly constant data gives a nearly constant map."""
    ref = _photo(rng, 30, 40)
    bm = np.where(rng.random((30, 40)) < 0.05, 2.5, np.nan)
    bm[np.nonzero(np.isfinite(bm))[0][0], np.nonzero(np.isfinite(bm))[1][0]] = 2.5 + 1e-9
    B = propagate_defocus(bm, ref, downsample=1, tol=1e-10)
    np.testing.assert_allclose(B, 2.5, atol=1e-6)


@pytest.mark.parametrize("downsample", [1, 2])
def test_step_kept_at_colour_edge(rng, downsample):
    """Two regions of different colour and BM: the map keeps the step at the colour edge."""
    h, w = 40, 60
    ref = np.zeros((h, w, 3)) + 0.2
    ref[:, 30:] = [0.8, 0.6, 0.3]
    ref = np.clip(ref + 0.01 * rng.standard_normal(ref.shape), 0, 1)
    bm = np.full((h, w), np.nan)
    mask = rng.random((h, w)) < 0.05
    bm[:, :30][mask[:, :30]] = 1.0
    bm[:, 30:][mask[:, 30:]] = 4.0
    B = propagate_defocus(bm, ref, downsample=downsample, refine_iterations=200)
    # Away from the edge each side takes its own measure ...
    assert np.all(np.abs(B[:, :22] - 1.0) < 0.15)
    assert np.all(np.abs(B[:, 38:] - 4.0) < 0.15)
    # ... and in every row the largest jump sits exactly at the colour edge and carries a large part
    # of the step (Eq. 4c sums affinities over channels and σ_ip grows in windows straddling the
    # edge, so some smoothing across it is inherent to the formula — measured jump ≈ 1.2–1.8).
    jumps = np.diff(B, axis=1)
    assert np.all(np.argmax(jumps, axis=1) == 29)
    assert np.min(jumps[:, 29]) > 0.9


@pytest.mark.parametrize("solver", ["amg_pcg", "direct"])
def test_coarse_mode_close_to_exact(rng, solver):
    ref = _photo(rng, 128, 128)
    bm = _sparse(rng, ref)
    exact = propagate_defocus(bm, ref, downsample=1, tol=1e-8)
    approx = propagate_defocus(bm, ref, downsample=2, refinement="galerkin", solver=solver, refine_iterations=60)
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.sqrt(np.mean((approx - exact) ** 2)) <= PROPAGATION_COARSE_RMS_RTOL * span


def _textured(rng, h, w):
    """Smooth colour gradients, a colour step and a disc, plus noise (a mid-size photo stand-in)."""
    yy, xx = np.mgrid[0:h, 0:w] / 64.0
    img = np.stack([0.5 + 0.3 * np.sin(3 * xx + np.cos(2 * yy)),
                    0.5 + 0.3 * np.cos(2.5 * yy) * (xx > 2.2),
                    0.3 + 0.4 * ((xx - 2.5) ** 2 + (yy - 2.3) ** 2 < 1.2)], axis=-1)
    return np.clip(img + 0.01 * rng.standard_normal(img.shape), 0.0, 1.0)


@pytest.fixture(scope="module")
def mid_size_case():
    """320² textured image, 1 % of the pixels measured, and its exact Eq. (4) solution."""
    rng = np.random.default_rng(20070101)
    ref = _textured(rng, 320, 320)
    bm = _sparse(rng, ref, density=0.01)
    return ref, bm, propagate_defocus(bm, ref, downsample=1, tol=1e-10)


@pytest.mark.parametrize("downsample", ["auto", 2])
def test_default_refinement_close_to_exact_mid_size(mid_size_case, downsample):
    """The default (coarse solve + two-level PCG refinement) is within named bounds of the exact solve.

    320² > 2¹⁵ px, so ``"auto"`` takes the coarse path (4×, :data:`AUTO_MIN_COARSENING`: its 80²
    coarse grid is under 2¹³ px); 2× was the auto factor at 512² earlier.
    """
    ref, bm, exact = mid_size_case
    approx = propagate_defocus(bm, ref, downsample=downsample)
    err = np.abs(approx - exact)
    assert np.sqrt(np.mean(err**2)) <= PROPAGATION_DEFAULT_VS_EXACT_RMS_PX
    assert np.percentile(err, 99) <= PROPAGATION_DEFAULT_VS_EXACT_P99_PX


def test_auto_downsample_factors():
    from method.propagation.defocus import AUTO_MAX_COARSE_PIXELS, AUTO_MAX_EXACT_PIXELS, _auto_downsample

    assert AUTO_MAX_EXACT_PIXELS >= 160 * 120  # the small renders (CI goldens) are solved exactly
    assert _auto_downsample(181, 181, AUTO_MAX_COARSE_PIXELS) == 1  # up to 2^15 px: exact
    assert _auto_downsample(182, 181, AUTO_MAX_COARSE_PIXELS) == 4  # never 2×: at least 4× coarser
    assert _auto_downsample(256, 256, AUTO_MAX_COARSE_PIXELS) == 4
    assert _auto_downsample(360, 360, AUTO_MAX_COARSE_PIXELS) == 4  # 90² = 8100 ≤ 2^13: still 4×
    assert _auto_downsample(362, 362, AUTO_MAX_COARSE_PIXELS) == 8  # 91² = 8281 > 2^13: 8×
    assert _auto_downsample(512, 512, AUTO_MAX_COARSE_PIXELS) == 8  # 4× would be 128² > 2^13
    assert _auto_downsample(724, 724, AUTO_MAX_COARSE_PIXELS) == 8
    assert _auto_downsample(1024, 1024, AUTO_MAX_COARSE_PIXELS) == 8
    assert _auto_downsample(1448, 1448, AUTO_MAX_COARSE_PIXELS) == 8  # 181² ≤ 2^15
    assert _auto_downsample(2048, 2048, AUTO_MAX_COARSE_PIXELS) == 16
    assert _auto_downsample(6, 20000, AUTO_MAX_COARSE_PIXELS) == 2  # the coarse grid keeps >= 2 px a side


def test_coarse_tol_default_and_validation(rng):
    ref = _photo(rng, 160, 160)  # coarse grid 40² > pyamg's max_coarse (500): an iterative coarse solve
    bm = _sparse(rng, ref)
    default = propagate_defocus(bm, ref, downsample=4)
    np.testing.assert_array_equal(default, propagate_defocus(bm, ref, downsample=4, coarse_tol=1e-3))
    tight = propagate_defocus(bm, ref, downsample=4, coarse_tol=1e-9, refine_iterations=0)
    loose = propagate_defocus(bm, ref, downsample=4, refine_iterations=0)
    assert not np.array_equal(tight, loose)  # the option reaches the coarse solve
    for bad in (0.0, 1.0, -1e-3, "x"):
        with pytest.raises(ValueError, match="coarse_tol"):
            propagate_defocus(bm, ref, downsample=4, coarse_tol=bad)


def test_auto_downsample_small_image_is_exact(rng):
    ref = _photo(rng, 32, 32)
    bm = _sparse(rng, ref)
    # same path, and the solve is deterministic (no random numbers in the AMG setup): same bytes
    np.testing.assert_array_equal(propagate_defocus(bm, ref), propagate_defocus(bm, ref, downsample=1))


def test_region_without_edges_is_finite(rng):
    """A region cut off by a strong edge with no measures: the guard term keeps the system SPD."""
    h, w = 30, 30
    ref = np.zeros((h, w, 3))
    ref[10:20, 10:20] = 1.0
    bm = np.full((h, w), np.nan)
    bm[::5, ::5] = np.where(np.arange(0, w, 5)[None, :] < 15, 1.0, 3.0)
    bm[10:20, 10:20] = np.nan
    B = propagate_defocus(bm, ref, downsample=1)
    assert np.all(np.isfinite(B))
    assert 0.5 < B[15, 15] < 3.5


def test_no_edges_gives_zeros(rng):
    ref = _photo(rng, 16, 16)
    np.testing.assert_array_equal(propagate_defocus(np.full((16, 16), np.nan), ref), 0.0)


@pytest.mark.parametrize("bad", [
    dict(solver="cholesky"), dict(alpha=0), dict(window=4), dict(neighborhood=1), dict(tol=2.0),
    dict(downsample=0), dict(downsample="half"), dict(refine_iterations=-1), dict(eps=0),
    dict(refinement="gauss_seidel"), dict(refinement=None)])
def test_bad_options_raise(rng, bad):
    ref = _photo(rng, 16, 16)
    with pytest.raises(ValueError):
        propagate_defocus(_sparse(rng, ref), ref, **bad)


def test_bad_inputs_raise(rng):
    ref = _photo(rng, 16, 16)
    bm = _sparse(rng, ref)
    with pytest.raises(ValueError, match="shape"):
        propagate_defocus(bm[:8], ref)
    with pytest.raises(ValueError, match="Inf"):
        propagate_defocus(np.where(np.isfinite(bm), np.inf, np.nan), ref)
    with pytest.raises(ValueError, match=">= 0"):
        propagate_defocus(np.where(np.isfinite(bm), -1.0, np.nan), ref)
