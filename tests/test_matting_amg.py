"""The ``"cg_amg"`` matting solver's parts (method.propagation.matting_amg): its V-cycle against pyamg's own
cycle on the same hierarchy, its CG against a sparse LU solve, both stopping rules on both sides."""

import numpy as np
import pyamg
import pytest
import scipy.sparse.linalg as spla

from method.propagation.matting import matting_system
from method.propagation.matting_amg import amg_hierarchy, pcg, vcycle_preconditioner

#: float32 V-cycle driven here vs pyamg's ``aspreconditioner`` on the same float32 hierarchy: the same
#: operations in the same order, so equal to float32 rounding (relative to the largest entry).
VCYCLE_VS_PYAMG_RTOL = 1e-5
#: CG to relative residual 1e-10 vs sparse LU on a 64×80 matting system, max |Δ| px.
PCG_VS_DIRECT_ATOL_PX = 1e-7


def _system(rng, h=64, w=80):
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    ref = np.stack([0.5 + 0.4 * np.sin(6 * xx + 2 * yy), 0.5 + 0.3 * np.cos(5 * yy), 0.3 + 0.4 * (xx > 0.5)], -1)
    ref = np.clip(ref + 0.03 * rng.standard_normal((h, w, 3)), 0, 1)
    truth = 1.0 + 3.0 * ref[..., 2] + np.linspace(0, 1, w)[None, :]
    sparse = np.where(rng.random((h, w)) < 0.08, truth, np.nan)
    A, b = matting_system(sparse, ref, lam=0.001, epsilon=9e-7, data_weight="sigma")
    return A, b, ref, np.full(h * w, np.nanmean(sparse))


def test_vcycle_equals_pyamg_cycle(rng):
    A, b, ref, _ = _system(rng)
    ml = amg_hierarchy(A, ref)
    assert len(ml.levels) >= 2 and ml.levels[0].A.dtype == np.float32
    r = rng.standard_normal(A.shape[0])
    got = vcycle_preconditioner(ml)(r)
    expected = ml.aspreconditioner(cycle="V") @ r.astype(np.float32)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, expected, rtol=0, atol=VCYCLE_VS_PYAMG_RTOL * np.abs(expected).max())


def test_pcg_matches_direct_solve(rng):
    A, b, ref, x0 = _system(rng)
    expected = spla.spsolve(A.tocsc(), b)
    x, k = pcg(A, b, x0, vcycle_preconditioner(amg_hierarchy(A, ref)), tol=1e-10, max_iterations=500)
    assert 0 < k < 500
    np.testing.assert_allclose(x, expected, rtol=0, atol=PCG_VS_DIRECT_ATOL_PX)
    # the same CG without a preconditioner (identity) reaches the same solution, with more iterations
    x1, k1 = pcg(A, b, x0, lambda r: r.copy(), tol=1e-10, max_iterations=20000)
    np.testing.assert_allclose(x1, expected, rtol=0, atol=PCG_VS_DIRECT_ATOL_PX)
    assert k1 > k


def test_step_rule_stops_at_the_first_small_step(rng):
    """``step_tol``: CG stops at the first iteration whose step moved no entry by more than it, before the
    residual rule would; the iterate is the textbook PCG's after as many iterations."""
    A, b, ref, x0 = _system(rng)
    M = vcycle_preconditioner(amg_hierarchy(A, ref))
    _, k_res = pcg(A, b, x0, M, tol=1e-10, max_iterations=500)
    x, k = pcg(A, b, x0, M, tol=1e-10, max_iterations=500, step_tol=1e-3)
    assert 1 < k < k_res
    iterates = [_pcg_k(A, b, x0.copy(), M, j) for j in (k - 2, k - 1, k)]
    np.testing.assert_allclose(x, iterates[2], rtol=0, atol=1e-12)
    assert np.max(np.abs(iterates[1] - iterates[0])) > 1e-3 >= np.max(np.abs(iterates[2] - iterates[1]))


def _pcg_k(A, b, x, M, k):
    """k iterations of the textbook PCG (the oracle of pcg's iterates)."""
    r = b - A @ x
    z = M(r)
    p = z.copy()
    rz = r @ z
    for _ in range(k):
        Ap = A @ p
        alpha = rz / (p @ Ap)
        x = x + alpha * p
        r = r - alpha * Ap
        z = M(r)
        rz, rz_old = r @ z, rz
        p = z + (rz / rz_old) * p
    return x


def test_residual_rule_and_non_convergence(rng):
    A, b, ref, x0 = _system(rng)
    M = vcycle_preconditioner(amg_hierarchy(A, ref))
    x, k = pcg(A, b, x0, M, tol=1e-6, max_iterations=500)
    assert np.linalg.norm(b - A @ x) <= 1e-6 * np.linalg.norm(b)
    # one iteration fewer did not meet it
    assert np.linalg.norm(b - A @ _pcg_k(A, b, x0.copy(), M, k - 1)) > 1e-6 * np.linalg.norm(b)
    with pytest.raises(RuntimeError, match="max_iterations=2"):
        pcg(A, b, x0, M, tol=1e-12, max_iterations=2)
    # a start that already solves the system returns it without iterating
    exact = spla.spsolve(A.tocsc(), b)
    same, k0 = pcg(A, b, exact, M, tol=1e-6, max_iterations=5)
    assert k0 == 0 and np.array_equal(same, exact)
