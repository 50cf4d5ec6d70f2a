"""The refinement's CG kernels (method.propagation.matrix_free, normal_operator) against slow oracles,
bit for bit, with the float32 vectors the driver uses: the same products rounded the same way, and
every per-row sum added from 0 in ascending column order, for any thread count."""

import numba
import numpy as np
import pytest

import method.propagation.matrix_free as MF
import method.propagation.normal_operator as NO
import method.propagation.system as E

F32, F64 = np.float32, np.float64


def _seq_sum(values) -> float:
    """Σ values added one at a time from 0.0 in order (the kernels' per-row order)."""
    acc = 0.0
    for v in np.asarray(values).ravel():
        acc += float(v)
    return acc


def _one_thread(fn):
    n = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        return fn()
    finally:
        numba.set_num_threads(n)


@pytest.mark.parametrize("n", [1, 3, 4, 7, 9])
@pytest.mark.parametrize("dtype", [F32, F64])
def test_row_dots_are_each_rows_sequential_sum(n, dtype):
    rng = np.random.default_rng(n)
    a, b = rng.standard_normal((n + 2, 13)).astype(dtype), rng.standard_normal((n + 1, 13)).astype(dtype)
    out = np.full(n + 3, -1.0)

    @numba.njit
    def call(a, b, out):
        NO.row_dots(a, 2, b, 1, n, 3, 9, out, 1)

    call(a, b, out)
    want = [_seq_sum(a[2 + i, 3:12] * b[1 + i, 3:12]) for i in range(n)]  # float32 products stay float32
    assert out[1:n + 1].tolist() == want
    assert out[0] == -1.0 and out[n + 1] == -1.0  # nothing else written


@pytest.mark.parametrize("shape, s", [((37, 70), 4), ((70, 33), 2), ((9, 12), 3), ((6, 5), 2)])
def test_step_and_restrict_equals_its_oracle_bit_for_bit(shape, s):
    rng = np.random.default_rng(9)
    h, w = shape
    r = 1
    hc, wc = -(-h // s), -(-w // s)
    (_, _, _), ty = MF.bilinear_1d(h, hc, s)
    (_, _, _), tx = MF.bilinear_1d(w, wc, s)
    x, res, p, q = (np.pad(rng.standard_normal((h, w)), r).astype(F32) for _ in range(4))
    step = 0.3137
    inner = (slice(r, r + h), slice(r, r + w))
    # oracle: float64 arithmetic on the float32 values, rounded when stored
    x_want = (x[inner].astype(F64) + step * p[inner].astype(F64)).astype(F32)
    rv = res[inner].astype(F64) - step * q[inner].astype(F64)
    rowsq_want = [_seq_sum(row * row) for row in rv]
    tmp_want = np.zeros((hc, w))
    for i in range(hc):
        for kk in range(ty[0][i], ty[0][i + 1]):
            tmp_want[i] += ty[2][kk] * rv[ty[1][kk]]
    rc_want = np.array([[_seq_sum(tx[2][tx[0][j]:tx[0][j + 1]] * tmp_want[i, tx[1][tx[0][j]:tx[0][j + 1]]])
                         for j in range(wc)] for i in range(hc)])
    outs = []
    for run in (lambda f: f(), _one_thread):
        xx, res_new = x.copy(), np.zeros_like(res)
        tmp, r_c, rowsq = np.zeros((hc, w)), np.zeros((hc, wc)), np.zeros(h)
        run(lambda: MF._step_and_restrict(xx, res, res_new, p, q, step, r, s, *ty, *tx, tmp, r_c, rowsq))
        outs.append((xx, res_new, tmp, r_c, rowsq))
    for xx, res_new, tmp, r_c, rowsq in outs:
        np.testing.assert_array_equal(xx[inner], x_want)
        np.testing.assert_array_equal(res_new[inner], rv.astype(F32))
        assert rowsq.tolist() == rowsq_want
        np.testing.assert_array_equal(tmp, tmp_want)
        np.testing.assert_array_equal(r_c, rc_want)
        assert not res_new[0].any() and not res_new[:, 0].any()  # padding untouched


@pytest.mark.parametrize("shape, s", [((37, 70), 4), ((70, 33), 2), ((9, 12), 3), ((6, 5), 2)])
def test_precondition_equals_its_oracle_bit_for_bit(shape, s):
    rng = np.random.default_rng(3)
    h, w = shape
    r = 1
    hc = -(-h // s)
    fy, _ = MF.bilinear_1d(h, hc, s)
    res = np.pad(rng.standard_normal((h, w)), r).astype(F32)
    dinv = np.pad(rng.random((h, w)) + 0.5, r).astype(F32)
    e_x = rng.standard_normal((hc, w))
    inner = (slice(r, r + h), slice(r, r + w))
    z_want = dinv[inner] * res[inner]  # float32 product
    for y in range(h):
        for kk in range(fy[0][y], fy[0][y + 1]):
            z_want[y] = (z_want[y].astype(F64) + fy[2][kk] * e_x[fy[1][kk]]).astype(F32)
    rowdot_want = [_seq_sum(res[inner][y] * z_want[y]) for y in range(h)]  # float32 products
    for run in (lambda f: f(), _one_thread):
        z, rowdot = np.zeros_like(res), np.zeros(h)
        run(lambda: MF._precondition(res, dinv, e_x, r, *fy, z, rowdot))
        np.testing.assert_array_equal(z[inner], z_want)
        assert rowdot.tolist() == rowdot_want
        assert not z[0].any() and not z[-1].any() and not z[:, 0].any() and not z[:, -1].any()


def _shift(a, dy, dx):
    """The interior (rows/columns 1 … n−2) of padded ``a`` (…, H+2, W+2) moved by (dy, dx)."""
    hp, wp = a.shape[-2:]
    return a[..., 1 + dy:hp - 1 + dy, 1 + dx:wp - 1 + dx]


def _normal_3x3_oracle(p, weights, a_diag):
    """q = (LᵀL + diag a) p and Σ_x p·q per row, written out with numpy in the kernels' operation
    order and operand types (numpy and numba promote alike: float32·float32 stays float32)."""
    W = lambda j, dy=0, dx=0: _shift(weights[j], dy, dx)
    P = lambda dy, dx: _shift(p, dy, dx)
    t = np.zeros(p.shape)
    t[1:-1, 1:-1] = (P(0, 0) - W(0) * P(-1, -1) - W(1) * P(-1, 0) - W(2) * P(-1, 1) - W(3) * P(0, -1)
                     - W(4) * P(0, 1) - W(5) * P(1, -1) - W(6) * P(1, 0) - W(7) * P(1, 1))
    T = lambda dy, dx: _shift(t, dy, dx)
    v = (T(0, 0) + a_diag * P(0, 0) - W(0, 1, 1) * T(1, 1) - W(1, 1, 0) * T(1, 0) - W(2, 1, -1) * T(1, -1)
         - W(3, 0, 1) * T(0, 1) - W(4, 0, -1) * T(0, -1) - W(5, -1, 1) * T(-1, 1) - W(6, -1, 0) * T(-1, 0)
         - W(7, -1, -1) * T(-1, -1))
    return v, [_seq_sum(P(0, 0)[y] * v[y]) for y in range(v.shape[0])]


@pytest.mark.parametrize("shape", [(3, 4), (7, 5), (37, 70), (65, 64), (97, 41)])
def test_unrolled_3x3_kernels_equal_their_oracle_with_float32_vectors(shape):
    """The driver's path (float32 vectors, affinities and data term): the unrolled 3×3 kernels, whose
    L and Lᵀ rows interleave and whose row sums run side by side, against the numpy oracle, bit for
    bit, on one thread and on all."""
    rng = np.random.default_rng(12)
    h, w = shape
    ref = np.clip(rng.random((h, w, 3)) * 0.3 + np.linspace(0, 0.6, w)[None, :, None], 0, 1)
    weights, offs = E.padded_weights(ref, 7, 3, 1e-6)
    assert weights.dtype == F32
    a_diag = np.where(rng.random((h, w)) < 0.2, 0.5, 0.0).astype(F32) + F32(5e-7)
    z, p_old = (np.pad(rng.standard_normal((h, w)), 1).astype(F32) for _ in range(2))
    beta = -0.61
    q_want, rd_want = _normal_3x3_oracle(z, weights, a_diag)
    pb = z.astype(F64) + p_old.astype(F64) * beta  # p ← z + β·p, unrounded in the operator
    q2_want, rd2_want = _normal_3x3_oracle(pb, weights, a_diag)
    inner = (slice(1, h + 1), slice(1, w + 1))
    for run in (lambda f: f(), _one_thread):
        q1, rd1 = np.zeros_like(z), np.zeros(h)
        run(lambda: NO._apply_normal_3x3(z, weights, offs, a_diag, q1, rd1))
        np.testing.assert_array_equal(q1[inner], q_want.astype(F32))
        assert rd1.tolist() == rd_want
        p_new, q2, rd2 = np.zeros_like(z), np.zeros_like(z), np.zeros(h)
        run(lambda: NO._direction_and_apply_3x3(z, p_old, beta, weights, offs, a_diag, p_new, q2, rd2))
        np.testing.assert_array_equal(p_new[inner], pb[inner].astype(F32))
        np.testing.assert_array_equal(q2[inner], q2_want.astype(F32))
        assert rd2.tolist() == rd2_want
        assert not q2[0].any() and not q2[-1].any() and not p_new[:, 0].any() and not p_new[:, -1].any()
    assert np.any(q_want != 0)


@pytest.mark.parametrize("neighborhood", [3, 5])
def test_normal_diagonal_equals_its_oracle_bit_for_bit(neighborhood):
    """Jacobi's diagonal 1 + a_p + Σ_j w[j, p − o_j]², added in offset order (float32 affinities)."""
    rng = np.random.default_rng(6)
    h, w = 29, 41
    r = neighborhood // 2
    ref = rng.random((h, w, 3))
    weights, offs = E.padded_weights(ref, 7, neighborhood, 1e-6)
    a_diag = np.where(rng.random((h, w)) < 0.3, 0.5, 0.0) + 5e-7
    want = 1.0 + a_diag
    for j, (dy, dx) in enumerate(offs):
        g = weights[j, r - dy:r - dy + h, r - dx:r - dx + w].astype(F64)
        want = want + g * g
    for run in (lambda f: f(), _one_thread):
        out = np.zeros((h + 2 * r, w + 2 * r))
        run(lambda: NO.normal_diagonal(weights, offs, a_diag, r, out))
        np.testing.assert_array_equal(out[r:r + h, r:r + w], want)
        assert not out[:r].any() and not out[:, -r:].any()


def test_affinity_kernels_equal_a_per_pixel_loop_with_libm_exp_bit_for_bit():
    """Eq. (4c)'s normalised affinities against a slow per-pixel loop (math.exp for every term, the
    per-pixel maximum subtracted): the same bytes, with flat patches whose identical neighbours give
    exponents of exactly 0, and image borders."""
    import math

    rng = np.random.default_rng(21)
    h, w = 23, 31
    ref = rng.random((h, w, 3))
    ref[3:12, 4:15] = 0.25  # flat: d = 0 for every channel
    ref[15:20, 20:28, 1] = 0.7  # flat in one channel only
    ref = np.ascontiguousarray(ref)
    inv = np.ascontiguousarray(0.5 / np.maximum(E._local_variance(ref, 7), 1e-6))
    offs = E._offsets(3)
    want = np.zeros((8, h, w))
    zeros = 0
    for y in range(h):
        for x in range(w):
            e = {}
            for j, (dy, dx) in enumerate(offs):
                if 0 <= y + dy < h and 0 <= x + dx < w:
                    e[j] = [-(float(ref[y, x, i]) - float(ref[y + dy, x + dx, i])) ** 2 * float(inv[y, x, i])
                            for i in range(3)]
            m = max(max(v) for v in e.values())
            raw = {}
            for j, v in e.items():
                acc = 0.0
                for vi in v:
                    zeros += (vi - m) == 0.0
                    acc += math.exp(vi - m)
                raw[j] = acc
            total = 0.0
            for j in range(8):
                total += raw.get(j, 0.0)
            for j, r in raw.items():
                want[j, y, x] = r / total
    assert zeros > 100
    for kernel in (E._weights_kernel, E._weights_kernel_3x3_rgb):
        got = np.zeros((8, h, w))
        kernel(ref, inv, offs, got)
        np.testing.assert_array_equal(got, want)
