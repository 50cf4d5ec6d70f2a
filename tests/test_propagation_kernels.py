"""The matrix-free numba kernels (method.propagation.matrix_free) agree with the assembled Eq. (4) system."""

import numpy as np
import pytest
import scipy.sparse as sp

import method.propagation.matrix_free as MF
import method.propagation.normal_operator as NO
import method.propagation.solvers as S
import method.propagation.system as E


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
    A, _ = E.normal_equations(bm, ref, neighborhood=neighborhood)
    a, _, lam, _ = E.data_term(bm, 0.5, 1e-6)
    weights, offs = E.padded_weights(ref, 7, neighborhood, 1e-6, dtype=np.float64)
    r = neighborhood // 2
    x = rng.standard_normal((h, w))
    xp = np.zeros((h + 2 * r, w + 2 * r))
    xp[r:r + h, r:r + w] = x
    q = np.zeros_like(xp)
    rowdot = np.zeros(h)
    NO.apply_normal(xp, weights, offs, (a + lam).reshape(h, w), q, rowdot)
    expected = (A @ x.ravel()).reshape(h, w)
    np.testing.assert_allclose(q[r:r + h, r:r + w], expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rowdot, np.sum(x * expected, axis=1), rtol=1e-10, atol=1e-12)
    # the padding stays zero
    assert not q[:r].any() and not q[-r:].any() and not q[:, :r].any() and not q[:, -r:].any()
    diag = np.zeros_like(xp)
    NO.normal_diagonal(weights, offs, (a + lam).reshape(h, w), r, diag)
    np.testing.assert_allclose(diag[r:r + h, r:r + w].ravel(), A.diagonal(), rtol=1e-12)


def test_float32_weights_close_to_float64():
    """The refinement stores the affinities in float32 (half the memory traffic); they round to 6e-8."""
    rng = np.random.default_rng(2)
    ref, _ = _case(rng, 50, 60)
    w32, _ = E.padded_weights(ref, 7, 3, 1e-6)
    w64, _ = E.padded_weights(ref, 7, 3, 1e-6, dtype=np.float64)
    assert w32.dtype == np.float32
    np.testing.assert_allclose(w32, w64, rtol=1e-7, atol=1e-8)


# --- two-level refinement kernels ---------------------------------------------------------------
def _csr(t, shape):
    indptr, indices, data = t
    return sp.csr_matrix((data, indices, indptr), shape=shape)


@pytest.mark.parametrize("n, s", [(37, 4), (64, 2), (33, 3), (5, 2)])
def test_bilinear_is_the_start_map_interpolation_and_its_transpose(n, s):
    rng = np.random.default_rng(1)
    nc = -(-n // s)
    fwd, tr = MF.bilinear_1d(n, nc, s)
    P1, T1 = _csr(fwd, (n, nc)), _csr(tr, (nc, n))
    assert abs(T1 - P1.T).max() == 0
    np.testing.assert_allclose(np.asarray(P1.sum(axis=1)).ravel(), 1.0, rtol=1e-15)  # partition of unity
    c = rng.random((nc, nc))  # P₁ ⊗ P₁ makes the start map: bilinear at block-centred coordinates
    from scipy import ndimage

    from method.propagation.galerkin import prolong

    pos = (np.arange(n) + 0.5) / s - 0.5  # fine pixel centres in coarse sample units
    oracle = ndimage.map_coordinates(c, np.meshgrid(pos, pos, indexing="ij"), order=1, mode="nearest")
    np.testing.assert_allclose(P1 @ c @ P1.T, oracle, atol=1e-14)
    np.testing.assert_allclose(prolong(c, s=s, shape=(n, n)), oracle, atol=1e-14)


@pytest.mark.parametrize("neighborhood", [3, 5])
@pytest.mark.parametrize("shape", [(7, 5), (37, 70), (70, 33)])
def test_fused_direction_and_apply_bit_identical(neighborhood, shape):
    rng = np.random.default_rng(4)
    h, w = shape
    ref, bm = _case(rng, h, w)
    a, _, lam, _ = E.data_term(bm, 0.5, 1e-6)
    a_diag = (a + lam).reshape(h, w)
    weights, offs = E.padded_weights(ref, 7, neighborhood, 1e-6)
    r = neighborhood // 2
    pad = lambda v: np.pad(v, r)
    z, p_old = pad(rng.standard_normal((h, w))), pad(rng.standard_normal((h, w)))
    beta = 0.37
    p_new, q, rowdot = np.zeros_like(z), np.zeros_like(z), np.zeros(h)
    NO.direction_and_apply(z, p_old, beta, weights, offs, a_diag, p_new, q, rowdot)
    p_ref, q_ref, rowdot_ref = z + beta * p_old, np.zeros_like(z), np.zeros(h)  # padding stays 0
    NO.apply_normal(p_ref, weights, offs, a_diag, q_ref, rowdot_ref)
    np.testing.assert_array_equal(p_new, p_ref)
    np.testing.assert_array_equal(q, q_ref)
    np.testing.assert_array_equal(rowdot, rowdot_ref)


@pytest.mark.parametrize("shape", [(3, 4), (7, 5), (37, 70), (70, 33), (65, 64)])
def test_unrolled_3x3_kernels_bit_identical_to_generic(shape):
    """The unrolled 3×3 kernels (the default neighbourhood's fast path) give the generic kernels' bits."""
    rng = np.random.default_rng(8)
    h, w = shape
    ref, bm = _case(rng, h, w)
    a, _, lam, _ = E.data_term(bm, 0.5, 1e-6)
    a_diag = (a + lam).reshape(h, w)
    weights, offs = E.padded_weights(ref, 7, 3, 1e-6)
    assert NO.operator_kernels(offs) == (NO._apply_normal_3x3, NO._direction_and_apply_3x3)
    assert NO.operator_kernels(E._offsets(5)) == (NO.apply_normal, NO.direction_and_apply)
    z, p_old = np.pad(rng.standard_normal((h, w)), 1), np.pad(rng.standard_normal((h, w)), 1)
    outs = []
    for apply_normal, direction_and_apply in [(NO.apply_normal, NO.direction_and_apply),
                                              (NO._apply_normal_3x3, NO._direction_and_apply_3x3)]:
        q1, rd1 = np.zeros_like(z), np.zeros(h)
        apply_normal(z, weights, offs, a_diag, q1, rd1)
        p_new, q2, rd2 = np.zeros_like(z), np.zeros_like(z), np.zeros(h)
        direction_and_apply(z, p_old, -0.61, weights, offs, a_diag, p_new, q2, rd2)
        outs.append((q1, rd1, p_new, q2, rd2))
    for generic, unrolled in zip(*outs):
        np.testing.assert_array_equal(unrolled, generic)
    assert np.any(outs[0][0] != 0)  # a real product, not zeros on both sides


@pytest.mark.parametrize("shape, s", [((37, 70), 4), ((70, 33), 2), ((9, 12), 3)])
def test_step_restrict_and_precondition_match_sparse_algebra(shape, s):
    from tests.tolerances import PROPAGATION_TRANSPOSE_RTOL

    rng = np.random.default_rng(9)
    h, w = shape
    r = 1
    hc, wc = -(-h // s), -(-w // s)
    fy, ty = MF.bilinear_1d(h, hc, s)
    fx, tx = MF.bilinear_1d(w, wc, s)
    Pfull = sp.kron(_csr(fy, (h, hc)), _csr(fx, (w, wc))).tocsr()
    pad = lambda v: np.pad(v, r)
    x, res, p, q = (pad(rng.standard_normal((h, w))) for _ in range(4))
    x0, res0 = x.copy(), res.copy()
    res_new, tmp, r_c, rowsq = np.zeros_like(res), np.zeros((hc, w)), np.zeros((hc, wc)), np.zeros(h)
    step = 0.3
    MF._step_and_restrict(x, res, res_new, p, q, step, r, s, *ty, *tx, tmp, r_c, rowsq)
    inner = (slice(r, r + h), slice(r, r + w))
    np.testing.assert_array_equal(x[inner], x0[inner] + step * p[inner])
    np.testing.assert_array_equal(res, res0)  # the old buffer is left alone
    np.testing.assert_array_equal(res_new[inner], res0[inner] - step * q[inner])
    np.testing.assert_allclose(rowsq, np.sum(res_new[inner] ** 2, axis=1), rtol=1e-12)
    np.testing.assert_allclose(r_c.ravel(), Pfull.T @ res_new[inner].ravel(), rtol=1e-12, atol=1e-12)
    # prolongation + Jacobi
    dinv = pad(rng.random((h, w)) + 0.5)
    e_c = rng.standard_normal((hc, wc))
    e_x = np.zeros((hc, w))
    MF._interpolate_x(e_c, *fx, e_x)
    z, rowdot = np.zeros_like(res), np.zeros(h)
    MF._precondition(res_new, dinv, e_x, r, *fy, z, rowdot)
    expected = dinv[inner] * res_new[inner] + (Pfull @ e_c.ravel()).reshape(h, w)
    np.testing.assert_allclose(z[inner], expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rowdot, np.sum(res_new[inner] * expected, axis=1), rtol=1e-10, atol=1e-12)
    assert not z[:r].any() and not z[-r:].any() and not z[:, :r].any() and not z[:, -r:].any()
    # restriction = transpose of prolongation, through the kernels
    u = res_new[inner]
    lhs = float(np.sum(r_c * e_c))
    rhs = float(np.sum(u * (Pfull @ e_c.ravel()).reshape(h, w)))
    assert abs(lhs - rhs) <= PROPAGATION_TRANSPOSE_RTOL * (abs(lhs) + abs(rhs))


@pytest.mark.parametrize("setup", ["amg_pcg", "direct"])
def test_two_level_cg_solves_the_system(setup):
    rng = np.random.default_rng(5)
    h, w, s = 60, 75, 4
    ref, bm = _case(rng, h, w)
    A, rhs = E.normal_equations(bm, ref)
    a, _, lam, _ = E.data_term(bm, 0.5, 1e-6)
    weights, offs = E.padded_weights(ref, 7, 3, 1e-6, dtype=np.float64)
    from method.propagation.galerkin import galerkin_coarse_operator

    coarse_shape = (-(-h // s), -(-w // s))
    A_c = galerkin_coarse_operator(weights, offs, (a + lam).reshape(h, w), s=s, coarse_shape=coarse_shape)
    coarse = S.COARSE_SETUPS[setup](A_c)
    x, res = MF.two_level_pcg(weights, offs, (a + lam).reshape(h, w), rhs.reshape(h, w),
                              np.zeros((h, w)), coarse=coarse, s=s, coarse_shape=coarse_shape,
                              maxiter=2000, tol=1e-10)
    assert res <= 1e-10
    assert np.linalg.norm(A @ x.ravel() - rhs) <= 2e-10 * np.linalg.norm(rhs)


@pytest.mark.parametrize("env, expected", [(None, "PASSIVE"), ("ACTIVE", "ACTIVE")])
def test_openmp_wait_policy_set_by_the_entry_points_not_by_method(env, expected):
    """numba's OpenMP workers must not busy-wait between the refinement's parallel regions when the
    tools run (unless asked); the pure-numerics ``method`` package leaves the environment alone."""
    import os
    import subprocess
    import sys

    child_env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if env is not None:
        child_env["OMP_WAIT_POLICY"] = env
    code = ("import os, method; before = os.environ.get('OMP_WAIT_POLICY', 'unset'); import repro.estimate; "
            "print(before, os.environ['OMP_WAIT_POLICY'])")
    out = subprocess.run([sys.executable, "-c", code], env=child_env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == [env or "unset", expected]


def test_unrolled_rgb_weights_kernel_bit_identical_to_the_generic_one():
    """The 3×3 / RGB affinity kernel (fixed sizes) gives the same bytes as the generic one."""
    rng = np.random.default_rng(4)
    ref = np.ascontiguousarray(np.clip(rng.random((37, 53, 3)) * 0.5 + np.linspace(0, 0.4, 53)[None, :, None], 0, 1))
    inv = np.ascontiguousarray(0.5 / np.maximum(E._local_variance(ref, 7), 1e-6))
    offs = E._offsets(3)
    generic, unrolled = np.zeros((8, 37, 53)), np.zeros((8, 37, 53))
    E._weights_kernel(ref, inv, offs, generic)
    E._weights_kernel_3x3_rgb(ref, inv, offs, unrolled)
    assert np.array_equal(generic, unrolled)
    np.testing.assert_allclose(generic.sum(axis=0), 1.0, rtol=1e-12)


@pytest.mark.parametrize("shape,window", [((5, 4), 7), ((70, 41), 7), ((33, 90), 5), ((40, 3), 3)])
def test_box_variance_equals_the_clipped_window_variance(shape, window):
    """σ_ip² of Eq. (4c) against a slow loop over each pixel's clipped window (population variance);
    more rows than one parallel block, windows wider than the image, and any thread count give the
    same bytes."""
    import numba

    rng = np.random.default_rng(5)
    ref = rng.random(shape + (3,))
    r = window // 2
    h, w = shape
    want = np.empty(ref.shape)
    for y in range(h):
        for x in range(w):
            patch = ref[max(0, y - r):y + r + 1, max(0, x - r):x + r + 1].reshape(-1, 3)
            want[y, x] = patch.var(axis=0)
    got = E._local_variance(ref, window)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-13)
    n = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = E._local_variance(ref, window)
    finally:
        numba.set_num_threads(n)
    assert one.tobytes() == got.tobytes()
