"""Zhuo & Sim (2011) propagation with the matting Laplacian: direct-solve oracle, known answer,
trivial inputs, bad inputs."""

import numpy as np
import pymatting
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from method.propagation.matting import (
    DEFAULT_EPSILON,
    DEFAULT_LAMBDA,
    MATTING_SOLVERS,
    _reads_step_tol,
    matting_system,
    propagate_defocus_matting,
)

# Tolerances of this file (named here rather than in tests/tolerances.py only because this change
# may not touch that file; move them there when it is convenient).
#: CG (tol 1e-6) vs an independent sparse LU of (L + λD) d = λDd̂ on a 40×50 image, max |Δ| px.
#: Measured ≤ 1e-5 px with both preconditioners; the direct solver agrees to round-off.
MATTING_VS_DIRECT_ATOL_PX = 1e-4
#: Two-colour image, σ = 1 / 3 px on a 6-px grid (70 samples), colour noise 0.005: max |d − truth|
#: at pixels ≥ 2 px from the colour edge. Measured 0.04 px with the defaults (the weak data term
#: λ = 0.005 lets the smoothness term pull both sides slightly toward each other; it is 0.01 px
#: without noise and grows with it, because the colour-line model treats noise as misfit).
MATTING_TWO_COLOUR_ATOL_PX = 0.1
#: The default solver against the earlier default (``"cg_vcycle"``, tol 1e-6) on Zhuo & Sim's
#: stage cases and in the test above, max |Δσ| px: the budget of the solver change.
MATTING_SOLVER_CHANGE_ATOL_PX = 0.01
#: A constant sparse map must come back as exactly that constant (returned without solving).
MATTING_CONSTANT_ATOL = 0.0


def _photo(rng, h, w):
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    ref = np.stack([0.5 + 0.4 * np.sin(6 * xx + 2 * yy), 0.5 + 0.3 * np.cos(5 * yy), 0.3 + 0.4 * (xx > 0.5)], -1)
    return np.clip(ref + 0.03 * rng.standard_normal((h, w, 3)), 0, 1)


def _sparse(rng, ref, density=0.05):
    h, w = ref.shape[:2]
    mask = rng.random((h, w)) < density
    truth = 1.0 + 3.0 * ref[..., 2] + np.linspace(0, 1, w)[None, :]
    return np.where(mask, truth, np.nan)


def _oracle(sparse_sigma, ref, lam, epsilon, radius):
    """Independent build of the same system with pymatting + SciPy, solved by sparse LU."""
    known = np.isfinite(sparse_sigma).ravel()
    L = pymatting.cf_laplacian(np.ascontiguousarray(ref, dtype=np.float64), epsilon=epsilon, radius=radius)
    D = sp.diags(known.astype(float))
    rhs = lam * np.where(known, sparse_sigma.ravel(), 0.0)
    return spla.spsolve((L + lam * D).tocsc(), rhs).reshape(sparse_sigma.shape)


def test_solver_registry():
    assert set(MATTING_SOLVERS) == {"cg_amg", "cg_vcycle", "cg_ichol", "direct"}
    assert {name for name in MATTING_SOLVERS if _reads_step_tol(name)} == {"cg_amg"}


# --- 1. equal to a direct sparse solve of the same system ------------------------------------
@pytest.mark.parametrize("solver", sorted(MATTING_SOLVERS))
def test_matches_direct_solve(rng, solver):
    ref = _photo(rng, 40, 50)
    bm = _sparse(rng, ref)
    expected = _oracle(bm, ref, DEFAULT_LAMBDA, DEFAULT_EPSILON, 1)
    got = propagate_defocus_matting(bm, ref, solver=solver)
    assert got.shape == (40, 50) and got.dtype == np.float64
    np.testing.assert_allclose(got, expected, rtol=0, atol=MATTING_VS_DIRECT_ATOL_PX)


@pytest.mark.parametrize("lam, epsilon, radius", [(0.05, 1e-6, 1), (0.001, 9e-7, 1), (0.005, 1e-4, 2)])
def test_options_reach_the_system(rng, lam, epsilon, radius):
    ref = _photo(rng, 31, 37)
    bm = _sparse(rng, ref, density=0.08)
    expected = _oracle(bm, ref, lam, epsilon, radius)
    for solver in ("cg_vcycle", "direct"):
        got = propagate_defocus_matting(bm, ref, lam=lam, epsilon=epsilon, radius=radius, solver=solver)
        np.testing.assert_allclose(got, expected, rtol=0, atol=MATTING_VS_DIRECT_ATOL_PX)
    A, b = matting_system(bm, ref, lam=lam, epsilon=epsilon, radius=radius)
    assert abs(A - A.T).max() < 1e-12
    assert np.all(b[~np.isfinite(bm).ravel()] == 0)


def test_grey_reference_is_repeated_to_three_channels(rng):
    grey = _photo(rng, 24, 30)[..., 0]
    bm = _sparse(rng, grey[..., None].repeat(3, axis=2))
    a = propagate_defocus_matting(bm, grey, solver="direct")
    b = propagate_defocus_matting(bm, np.repeat(grey[..., None], 3, axis=2), solver="direct")
    np.testing.assert_array_equal(a, b)


# --- 2. known answer: a two-colour image ------------------------------------------------------
def test_two_colour_image_keeps_each_side_value():
    rng = np.random.default_rng(20110321)
    h, w = 40, 60
    ref = np.empty((h, w, 3))
    ref[:, : w // 2] = (0.8, 0.3, 0.2)
    ref[:, w // 2:] = (0.2, 0.4, 0.9)
    ref = np.clip(ref + 0.005 * rng.standard_normal(ref.shape), 0, 1)
    grid = np.zeros((h, w), bool)
    grid[3::6, 3::6] = True
    left = np.zeros((h, w), bool)
    left[:, : w // 2] = True
    bm = np.full((h, w), np.nan)
    bm[grid & left] = 1.0
    bm[grid & ~left] = 3.0
    for solver in ("cg_vcycle", "cg_ichol"):
        d = propagate_defocus_matting(bm, ref, solver=solver)
        np.testing.assert_allclose(d[:, : w // 2 - 2], 1.0, atol=MATTING_TWO_COLOUR_ATOL_PX)
        np.testing.assert_allclose(d[:, w // 2 + 2:], 3.0, atol=MATTING_TWO_COLOUR_ATOL_PX)


# --- 3. trivial inputs -------------------------------------------------------------------------
def test_constant_input_gives_constant_output(rng):
    ref = _photo(rng, 20, 25)
    bm = np.where(rng.random((20, 25)) < 0.1, 1.75, np.nan)
    for solver in MATTING_SOLVERS:
        d = propagate_defocus_matting(bm, ref, solver=solver)
        np.testing.assert_allclose(d, 1.75, rtol=0, atol=MATTING_CONSTANT_ATOL)
        assert d.dtype == np.float64


def test_no_finite_value_gives_zeros(rng):
    ref = _photo(rng, 20, 25)
    d = propagate_defocus_matting(np.full((20, 25), np.nan), ref)
    assert d.shape == (20, 25) and d.dtype == np.float64 and not d.any()


@pytest.mark.parametrize("solver", ["cg_amg", "cg_vcycle", "cg_ichol"])
def test_non_convergence_is_reported(rng, solver):
    ref = _photo(rng, 40, 50)
    with pytest.raises(RuntimeError, match="max_iterations=1"):
        propagate_defocus_matting(_sparse(rng, ref), ref, tol=1e-12, max_iterations=1, solver=solver)


def test_default_solver_agrees_with_the_vcycle_oracle(rng):
    """The default ``"cg_amg"`` against the earlier default ``"cg_vcycle"`` at tol 1e-6, with Zhuo & Sim's
    preset options (λ = 0.001, ε = 9e-7, D = d̂): within MATTING_SOLVER_CHANGE_ATOL_PX, and not equal
    (so the default really is the other solver)."""
    ref = _photo(rng, 64, 80)
    bm = _sparse(rng, ref, density=0.08)
    opts = {"lam": 0.001, "epsilon": 9e-7, "data_weight": "sigma"}
    old = propagate_defocus_matting(bm, ref, solver="cg_vcycle", tol=1e-6, **opts)
    new = propagate_defocus_matting(bm, ref, **opts)
    assert np.max(np.abs(new - old)) <= MATTING_SOLVER_CHANGE_ATOL_PX
    assert not np.array_equal(new, old)


def test_zhuo_sim_tolerance_stays_within_the_budget(rng):
    """The ``zhuo_sim`` preset's own stopping tolerance (``matting_tol``, looser than Eq. 4's
    ``propagation_tol``) through the propagation registry: within MATTING_SOLVER_CHANGE_ATOL_PX of the
    ``"cg_vcycle"`` tol-1e-6 solve, and not the tol-1e-6 ``"cg_amg"`` solve (so the field reaches the solver).
    The stop on the iterate's change (``matting_step_tol``) is switched off here: it has its own test."""
    from method import DefocusParams
    from method.propagation.methods import propagate_blur_measures

    ref = _photo(rng, 64, 80)
    bm = _sparse(rng, ref, density=0.08)
    params = DefocusParams.preset("zhuo_sim", matting_step_tol=None)
    assert params.matting_tol > params.propagation_tol
    opts = {"lam": params.matting_lambda, "epsilon": params.matting_epsilon, "data_weight": params.matting_data_weight}
    oracle = propagate_defocus_matting(bm, ref, solver="cg_vcycle", tol=1e-6, **opts)
    loose = propagate_blur_measures(bm, ref, params=params)
    tight = propagate_blur_measures(bm, ref, params=params.replace(matting_tol=1e-6))
    assert np.max(np.abs(loose - oracle)) <= MATTING_SOLVER_CHANGE_ATOL_PX
    assert not np.array_equal(loose, tight)
    # the budget is not met trivially: a far looser stop leaves the solve visibly short of it
    rough = propagate_blur_measures(bm, ref, params=params.replace(matting_tol=0.5))
    assert np.max(np.abs(rough - oracle)) > MATTING_SOLVER_CHANGE_ATOL_PX


def test_zhuo_sim_step_tolerance_stays_within_the_budget(rng):
    """The ``zhuo_sim`` preset's stop on the iterate's change (``matting_step_tol``) through the propagation
    registry: within MATTING_SOLVER_CHANGE_ATOL_PX of the ``"cg_vcycle"`` tol-1e-6 solve and not the solve
    without it (so the field reaches the solver); a far looser step leaves the solve visibly short."""
    from method import DefocusParams
    from method.propagation.methods import propagate_blur_measures

    ref = _photo(rng, 64, 80)
    bm = _sparse(rng, ref, density=0.08)
    params = DefocusParams.preset("zhuo_sim")
    assert params.matting_step_tol is not None
    opts = {"lam": params.matting_lambda, "epsilon": params.matting_epsilon, "data_weight": params.matting_data_weight}
    oracle = propagate_defocus_matting(bm, ref, solver="cg_vcycle", tol=1e-6, **opts)
    stepped = propagate_blur_measures(bm, ref, params=params)
    residual_only = propagate_blur_measures(bm, ref, params=params.replace(matting_step_tol=None))
    assert np.max(np.abs(stepped - oracle)) <= MATTING_SOLVER_CHANGE_ATOL_PX
    assert not np.array_equal(stepped, residual_only)
    rough = propagate_blur_measures(bm, ref, params=params.replace(matting_step_tol=0.5))
    assert np.max(np.abs(rough - oracle)) > MATTING_SOLVER_CHANGE_ATOL_PX


# --- 4. bad inputs -----------------------------------------------------------------------------
def _ok(rng):
    ref = _photo(rng, 12, 14)
    return _sparse(rng, ref, density=0.2), ref


def test_shape_mismatch(rng):
    bm, ref = _ok(rng)
    with pytest.raises(ValueError, match="shape"):
        propagate_defocus_matting(bm[:-1], ref)
    with pytest.raises(ValueError, match="HxW or HxWx3"):
        propagate_defocus_matting(bm, np.ones((12, 14, 2)))


def test_inf_and_negative_sigma(rng):
    bm, ref = _ok(rng)
    bad = bm.copy()
    bad[0, 0] = np.inf
    with pytest.raises(ValueError, match="Inf"):
        propagate_defocus_matting(bad, ref)
    bad[0, 0] = -0.5
    with pytest.raises(ValueError, match=">= 0"):
        propagate_defocus_matting(bad, ref)


def test_non_float_and_non_finite_reference(rng):
    bm, ref = _ok(rng)
    with pytest.raises(ValueError, match="float"):
        propagate_defocus_matting(np.zeros((12, 14), dtype=int), ref)
    with pytest.raises(ValueError, match="float"):
        propagate_defocus_matting(bm, (ref * 255).astype(np.uint8))
    bad = ref.copy()
    bad[1, 1, 1] = np.nan
    with pytest.raises(ValueError, match="NaN or Inf"):
        propagate_defocus_matting(bm, bad)


def test_unknown_solver_names_the_allowed_ones(rng):
    bm, ref = _ok(rng)
    with pytest.raises(ValueError, match=r"solver='amg' is invalid \(unknown .*\); allowed: 'cg_amg', 'cg_ichol', 'cg_vcycle', 'direct'$"):
        propagate_defocus_matting(bm, ref, solver="amg")


@pytest.mark.parametrize("name, value", [
    ("lam", 0.0), ("lam", -1.0), ("lam", np.nan), ("lam", "big"),
    ("epsilon", 0.0), ("radius", 0), ("radius", 1.5), ("radius", True),
    ("tol", 0.0), ("tol", 1.0), ("max_iterations", 0), ("step_tol", 0.0), ("step_tol", -1e-4), ("step_tol", np.nan),
])
def test_bad_options(rng, name, value):
    bm, ref = _ok(rng)
    with pytest.raises(ValueError, match=name):
        propagate_defocus_matting(bm, ref, **{name: value})


@pytest.mark.parametrize("solver", ["cg_vcycle", "cg_ichol", "direct"])
def test_step_tol_only_with_a_solver_that_reads_it(rng, solver):
    bm, ref = _ok(rng)
    with pytest.raises(ValueError, match=rf"step_tol=0.0001 with solver='{solver}' is invalid; allowed: step_tol=None"):
        propagate_defocus_matting(bm, ref, solver=solver, step_tol=1e-4)


def test_image_smaller_than_window(rng):
    with pytest.raises(ValueError, match="2\\*radius\\+1"):
        propagate_defocus_matting(np.full((4, 9), 1.0), np.zeros((4, 9, 3)), radius=2)


def test_direct_solver_refuses_large_images():
    h, w = 513, 512  # one row over DIRECT_MAX_PIXELS = 512²; rejected before the Laplacian is built
    with pytest.raises(ValueError, match="solver='direct'"):
        propagate_defocus_matting(np.full((h, w), np.nan), np.zeros((h, w)), solver="direct")
