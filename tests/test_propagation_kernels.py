"""The matrix-free numba kernels of method.propagation agree with the assembled Eq. (4) system."""

import numpy as np
import pytest

from method import propagation as P


def _case(rng, h, w):
    ref = np.clip(rng.random((h, w, 3)) * 0.3 + np.linspace(0, 0.6, w)[None, :, None], 0, 1)
    bm = np.where(rng.random((h, w)) < 0.1, 1.0 + 2.0 * rng.random((h, w)), np.nan)
    return ref, bm


@pytest.mark.parametrize("neighborhood", [3, 5, 7])
@pytest.mark.parametrize("shape", [(7, 5), (37, 70), (70, 33)])  # fewer and more rows than a row block
def test_matrix_free_operator_matches_assembled(neighborhood, shape):
    rng = np.random.default_rng(11)
    h, w = shape
    ref, bm = _case(rng, h, w)
    A, _ = P.normal_equations(bm, ref, neighborhood=neighborhood)
    a, _, lam, _ = P._data_term(bm, 0.5, 1e-6)
    weights, offs = P._padded_weights(ref, 7, neighborhood, 1e-6, dtype=np.float64)
    r = neighborhood // 2
    x = rng.standard_normal((h, w))
    xp = np.zeros((h + 2 * r, w + 2 * r))
    xp[r:r + h, r:r + w] = x
    q = np.zeros_like(xp)
    rowdot = np.zeros(h)
    P._apply_normal(xp, weights, offs, (a + lam).reshape(h, w), q, rowdot)
    expected = (A @ x.ravel()).reshape(h, w)
    np.testing.assert_allclose(q[r:r + h, r:r + w], expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rowdot, np.sum(x * expected, axis=1), rtol=1e-10, atol=1e-12)
    # the padding stays zero
    assert not q[:r].any() and not q[-r:].any() and not q[:, :r].any() and not q[:, -r:].any()
    diag = np.zeros_like(xp)
    P._normal_diagonal(weights, offs, (a + lam).reshape(h, w), r, diag)
    np.testing.assert_allclose(diag[r:r + h, r:r + w].ravel(), A.diagonal(), rtol=1e-12)


def test_matrix_free_cg_solves_the_system():
    rng = np.random.default_rng(5)
    h, w = 40, 45
    ref, bm = _case(rng, h, w)
    A, rhs = P.normal_equations(bm, ref)
    a, _, lam, _ = P._data_term(bm, 0.5, 1e-6)
    weights, offs = P._padded_weights(ref, 7, 3, 1e-6, dtype=np.float64)
    x, res = P._jacobi_pcg_matrix_free(weights, offs, (a + lam).reshape(h, w), rhs.reshape(h, w),
                                       np.zeros((h, w)), maxiter=5000, tol=1e-9)
    assert res <= 1e-9
    assert np.linalg.norm(A @ x.ravel() - rhs) <= 2e-9 * np.linalg.norm(rhs)


def test_float32_weights_close_to_float64():
    """The refinement stores the affinities in float32 (half the memory traffic); they round to 6e-8."""
    rng = np.random.default_rng(2)
    ref, _ = _case(rng, 50, 60)
    w32, _ = P._padded_weights(ref, 7, 3, 1e-6)
    w64, _ = P._padded_weights(ref, 7, 3, 1e-6, dtype=np.float64)
    assert w32.dtype == np.float32
    np.testing.assert_allclose(w32, w64, rtol=1e-7, atol=1e-8)
