"""The Galerkin coarse operator of the two-level propagation (method.propagation.galerkin).

Oracle: the matrix-free kernel against the explicit sparse product Pᵀ (LᵀL + diag a) P of the
assembled Eq. (4) system; the transfer operators against each other and against the start-map
interpolation; and the reason the operator exists — with the same coarse grid and the same number
of CG iterations, the Galerkin refinement ends closer to the exact solve than the re-discretised one.
"""

import numpy as np
import pytest
import scipy.sparse as sp

import method.propagation.defocus as P
import method.propagation.system as E
from method.propagation.galerkin import galerkin_coarse_operator, prolong, restrict
from method.propagation.matrix_free import bilinear_1d


def _case(rng, h, w, density=0.2):
    ref = np.clip(rng.random((h, w, 3)) * 0.4 + np.linspace(0, 0.5, w)[None, :, None], 0, 1)
    a = np.where(rng.random((h, w)) < density, 0.5, 0.0) + 1e-7
    return ref, a


def _explicit(ref, a, s, neighborhood):
    h, w = a.shape
    hc, wc = -(-h // s), -(-w // s)
    L = E.colorization_matrix(ref, window=7, neighborhood=neighborhood)
    A = (L.T @ L + sp.diags(a.ravel())).tocsr()

    def p1(n, nc):
        (ptr, idx, val), _ = bilinear_1d(n, nc, s)
        return sp.csr_matrix((val, idx, ptr), shape=(n, nc))

    Pm = sp.kron(p1(h, hc), p1(w, wc)).tocsr()
    return (Pm.T @ A @ Pm).toarray(), Pm, (hc, wc)


@pytest.mark.parametrize("shape,s,neighborhood", [
    ((37, 29), 2, 3), ((40, 50), 4, 3), ((33, 41), 8, 3), ((30, 26), 2, 5), ((64, 64), 4, 7), ((9, 70), 4, 3)])
def test_matrix_free_galerkin_operator_equals_explicit_product(shape, s, neighborhood):
    rng = np.random.default_rng(3)
    ref, a = _case(rng, *shape)
    weights, offs = E.padded_weights(ref, 7, neighborhood, 1e-6, dtype=np.float64)
    expected, _, coarse_shape = _explicit(ref, a, s, neighborhood)
    got = galerkin_coarse_operator(weights, offs, a, s=s, coarse_shape=coarse_shape)
    np.testing.assert_allclose(got.toarray(), expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    assert got.has_sorted_indices
    np.testing.assert_allclose(got.toarray(), got.toarray().T, atol=1e-13 * np.abs(expected).max())
    assert np.linalg.eigvalsh(got.toarray()).min() > 0  # SPD: a > 0 everywhere here


def test_galerkin_operator_is_deterministic_and_float32_weights_close():
    rng = np.random.default_rng(5)
    ref, a = _case(rng, 50, 61)
    w64, offs = E.padded_weights(ref, 7, 3, 1e-6, dtype=np.float64)
    w32, _ = E.padded_weights(ref, 7, 3, 1e-6)
    shape = (-(-50 // 4), -(-61 // 4))
    g1 = galerkin_coarse_operator(w32, offs, a, s=4, coarse_shape=shape)
    g2 = galerkin_coarse_operator(w32, offs, a, s=4, coarse_shape=shape)
    assert (g1 != g2).nnz == 0
    g64 = galerkin_coarse_operator(w64, offs, a, s=4, coarse_shape=shape)
    assert abs(g1 - g64).max() < 1e-6 * abs(g64).max()


def test_transfer_operators_are_transposes_and_match_the_explicit_kronecker_product():
    rng = np.random.default_rng(9)
    h, w, s = 45, 38, 4
    hc, wc = -(-h // s), -(-w // s)
    u = rng.standard_normal((hc, wc))
    v = rng.standard_normal((h, w))
    lhs = float(np.sum(prolong(u, s=s, shape=(h, w)) * v))
    rhs = float(np.sum(u * restrict(v, s=s, coarse_shape=(hc, wc))))
    assert abs(lhs - rhs) <= 1e-12 * max(abs(lhs), 1.0)
    (pyp, pyi, pyv), _ = bilinear_1d(h, hc, s)
    (pxp, pxi, pxv), _ = bilinear_1d(w, wc, s)
    Py = sp.csr_matrix((pyv, pyi, pyp), shape=(h, hc)).toarray()
    Px = sp.csr_matrix((pxv, pxi, pxp), shape=(w, wc)).toarray()
    np.testing.assert_allclose(prolong(u, s=s, shape=(h, w)), Py @ u @ Px.T, atol=1e-12)  # rows P_y, columns P_x
    # block-centred: a constant coarse map interpolates to the same constant everywhere
    np.testing.assert_allclose(prolong(np.full((hc, wc), 2.5), s=s, shape=(h, w)), 2.5, atol=1e-12)


def test_galerkin_operator_rejects_mismatched_shapes():
    rng = np.random.default_rng(1)
    ref, a = _case(rng, 20, 24)
    weights, offs = E.padded_weights(ref, 7, 3, 1e-6)
    with pytest.raises(ValueError, match="coarse_shape"):
        galerkin_coarse_operator(weights, offs, a, s=4, coarse_shape=(6, 6))
    with pytest.raises(ValueError, match="weights"):
        galerkin_coarse_operator(weights[:, 1:], offs, a, s=4, coarse_shape=(5, 6))



@pytest.mark.parametrize("shape,s", [((50, 61), 4), ((33, 70), 8), ((40, 29), 2)])
def test_specialised_3x3_kernel_equals_the_generic_one_to_round_off(shape, s):
    import method.propagation.galerkin as G

    rng = np.random.default_rng(21)
    ref, a = _case(rng, *shape)
    weights, offs = E.padded_weights(ref, 7, 3, 1e-6)
    h, w = shape
    hc, wc = -(-h // s), -(-w // s)
    (pyp, pyi, pyv), _ = bilinear_1d(h, hc, s)
    (pxp, pxi, pxv), _ = bilinear_1d(w, wc, s)
    ylo, my = G._coarse_span(pyp, pyi, h, 1)
    xlo, mx = G._coarse_span(pxp, pxi, w, 1)
    assert max(my, mx) == 3
    block_rows = np.minimum(np.arange(hc + 1, dtype=np.int64) * s, h)
    generic = np.zeros((hc, wc, 5, 5))
    special = np.zeros((hc, wc, 5, 5))
    G._galerkin_stencil(weights, offs, a, 1, pyp, pyi, pyv, pxp, pxi, pxv, ylo, xlo, 3, block_rows, 4, generic)
    G._galerkin_stencil_3x3(weights, offs, a, G._window_tables(pyp, pyi, pyv, ylo, h, 1, 3),
                            G._window_tables(pxp, pxi, pxv, xlo, w, 1, 3), ylo, xlo, block_rows, 4, special)
    np.testing.assert_allclose(special, generic, rtol=0, atol=1e-14 * np.abs(generic).max())
