"""Biased cross-bilateral refinement, Eq. (3): grid vs oracle, bias mechanism, invariants."""

import numpy as np
import pytest

from method.refine.cross_bilateral import BILATERAL_METHODS, biased_cross_bilateral, sharpness_bias
from tests.tolerances import BILATERAL_CONSTANT_ATOL, BILATERAL_GRID_REL_TOL


def _case(rng, h, w, density=0.08, smooth=True):
    ref = rng.random((h, w, 3))
    if smooth:  # photo-like: smooth colour fields plus a sharp region boundary
        yy, xx = np.mgrid[0:h, 0:w]
        ref = 0.5 * ref * 0.2 + 0.4 * (xx > w // 2)[..., None] + 0.3 * np.sin(yy / 7.0)[..., None] ** 2
        ref = np.clip(ref, 0, 1)
    mask = rng.random((h, w)) < density
    mask[0, 0] = True
    bm = np.where(mask, rng.random((h, w)) * 6.0, np.nan)
    return bm, ref


def test_methods_registered():
    assert set(BILATERAL_METHODS) == {"grid", "brute_force"}


@pytest.mark.parametrize("shape", [(24, 31), (64, 64), (90, 120)])
@pytest.mark.parametrize("bias", [True, False])
@pytest.mark.parametrize("sigmas", [(0.10, 0.10), (0.05, 0.05), (0.3, 0.2)])
def test_grid_matches_brute_force(rng, shape, bias, sigmas):
    bm, ref = _case(rng, *shape, smooth=shape[0] != 64)
    kw = dict(sigma_spatial=sigmas[0], sigma_range=sigmas[1], sharpness_bias=bias)
    fast = biased_cross_bilateral(bm, ref, method="grid", **kw)
    slow = biased_cross_bilateral(bm, ref, method="brute_force", **kw)
    edge = np.isfinite(bm)
    assert np.array_equal(np.isfinite(fast), edge) and np.array_equal(np.isfinite(slow), edge)
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.max(np.abs(fast[edge] - slow[edge])) <= BILATERAL_GRID_REL_TOL * span


def test_grey_reference_matches_brute_force(rng):
    bm, ref = _case(rng, 40, 40)
    grey = ref.mean(axis=2)
    fast = biased_cross_bilateral(bm, grey)
    slow = biased_cross_bilateral(bm, grey, method="brute_force")
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.nanmax(np.abs(fast - slow)) <= BILATERAL_GRID_REL_TOL * span


@pytest.mark.parametrize("method", ["grid", "brute_force"])
def test_constant_blur_measure_unchanged(rng, method):
    bm, ref = _case(rng, 50, 40)
    bm = np.where(np.isfinite(bm), 3.25, np.nan)
    out = biased_cross_bilateral(bm, ref, method=method)
    np.testing.assert_allclose(out[np.isfinite(bm)], 3.25, rtol=0, atol=BILATERAL_CONSTANT_ATOL)
    assert np.all(np.isnan(out[~np.isfinite(bm)]))


@pytest.mark.parametrize("method", ["grid", "brute_force"])
def test_bias_pulls_blurry_outlier_down(method):
    """Fig. 5: a blurry outlier among sharp measures of the same colour is pulled towards sharp."""
    h = w = 60
    ref = np.full((h, w, 3), 0.5)
    bm = np.full((h, w), np.nan)
    bm[::4, ::4] = 1.0          # sharp edges
    bm[30, 30] = 8.0            # outlier (e.g. a soft shadow)
    plain = biased_cross_bilateral(bm, ref, sharpness_bias=False, method=method)
    biased = biased_cross_bilateral(bm, ref, sharpness_bias=True, method=method)
    assert biased[30, 30] < plain[30, 30] < 8.0
    assert biased[30, 30] < 1.05   # b(8)/b(1) = e^-3.5: the outlier barely counts
    # and the sharp neighbours are disturbed less with the bias than without
    assert abs(biased[28, 28] - 1.0) < abs(plain[28, 28] - 1.0)


def test_range_weight_respects_colour_edge():
    """Measures across a strong colour edge do not mix (σr = 10 % of range)."""
    h, w = 40, 40
    ref = np.zeros((h, w, 3))
    ref[:, w // 2:] = 1.0
    bm = np.full((h, w), np.nan)
    bm[::3, : w // 2: 3] = 1.0
    bm[::3, w // 2::3] = 5.0
    out = biased_cross_bilateral(bm, ref, sharpness_bias=False)
    np.testing.assert_allclose(out[:, : w // 2][np.isfinite(out[:, : w // 2])], 1.0, atol=1e-6)
    np.testing.assert_allclose(out[:, w // 2:][np.isfinite(out[:, w // 2:])], 5.0, atol=1e-6)


def test_sharpness_bias_values():
    np.testing.assert_allclose(sharpness_bias(np.array([0.0, 2.0, 4.0])), np.exp([0.0, -1.0, -2.0]))
    with pytest.raises(ValueError):
        sharpness_bias(1.0, scale=0)


def test_no_edges_gives_all_nan(rng):
    out = biased_cross_bilateral(np.full((10, 12), np.nan), rng.random((10, 12, 3)))
    assert out.shape == (10, 12) and np.all(np.isnan(out))


@pytest.mark.parametrize("bad", [
    dict(method="nope"), dict(sigma_spatial=0), dict(sigma_range=-1), dict(bias_scale=np.inf)])
def test_bad_options_raise(rng, bad):
    bm, ref = _case(rng, 20, 20)
    with pytest.raises(ValueError):
        biased_cross_bilateral(bm, ref, **bad)


def test_bad_inputs_raise(rng):
    bm, ref = _case(rng, 20, 20)
    with pytest.raises(ValueError, match="shape"):
        biased_cross_bilateral(bm[:10], ref)
    with pytest.raises(ValueError, match=">= 0"):
        biased_cross_bilateral(np.where(np.isfinite(bm), -1.0, np.nan), ref)
    with pytest.raises(ValueError, match="Inf"):
        biased_cross_bilateral(np.where(np.isfinite(bm), np.inf, np.nan), ref)
    bad_ref = ref.copy()
    bad_ref[0, 0, 0] = np.nan
    with pytest.raises(ValueError):
        biased_cross_bilateral(bm, bad_ref)


# --- beyond the paper: joint-colour (product) range kernel, re-weighted (robust) passes -------------
from tests.tolerances import (BILATERAL_PRODUCT_GRID_REL_TOL, BILATERAL_ROBUST_RESIDUAL_FRACTION,  # noqa: E402
                              BILATERAL_SUM_LEAK_MIN_PX)


@pytest.mark.parametrize("shape", [(24, 31), (64, 64), (90, 120)])
@pytest.mark.parametrize("bias", [True, False])
@pytest.mark.parametrize("sigmas", [(0.10, 0.10), (0.3, 0.2), (0.2, 0.3)])
def test_product_grid_matches_brute_force(rng, shape, bias, sigmas):
    # (σs, σr) = (0.05, 0.05) is left out for time: the 5-D grid has (1/(0.75·σ) + 2)^5 cells, 1.7e7 there
    # (~20× the default σ = 0.10).
    bm, ref = _case(rng, *shape, smooth=shape[0] != 64)
    kw = dict(sigma_spatial=sigmas[0], sigma_range=sigmas[1], sharpness_bias=bias, range_kernel="product")
    fast = biased_cross_bilateral(bm, ref, method="grid", **kw)
    slow = biased_cross_bilateral(bm, ref, method="brute_force", **kw)
    edge = np.isfinite(bm)
    assert np.array_equal(np.isfinite(fast), edge) and np.array_equal(np.isfinite(slow), edge)
    span = np.nanmax(bm) - np.nanmin(bm)
    assert np.max(np.abs(fast[edge] - slow[edge])) <= BILATERAL_PRODUCT_GRID_REL_TOL * span
    # the oracle is the product kernel, not the sum one (they differ by more than the tolerance here)
    summed = biased_cross_bilateral(bm, ref, method="brute_force", **{**kw, "range_kernel": "sum"})
    assert np.max(np.abs(summed[edge] - slow[edge])) > np.max(np.abs(fast[edge] - slow[edge]))


def test_product_oracle_is_the_joint_colour_formula(rng):
    """Brute-force product kernel vs Eq. (3) written out with w_pq = g_σs(‖p−q‖)·g_σr(‖C_p − C_q‖)."""
    bm, ref = _case(rng, 16, 18, density=0.2)
    out = biased_cross_bilateral(bm, ref, method="brute_force", range_kernel="product", bias_scale=2.0)
    ys, xs = np.nonzero(np.isfinite(bm))
    v, c = bm[ys, xs], ref[ys, xs]
    ss, sr = 0.10 * 18, 0.10 * (ref.max() - ref.min())
    b = sharpness_bias(v, scale=2.0)
    for k in range(len(v)):
        w = np.exp(-((ys - ys[k]) ** 2 + (xs - xs[k]) ** 2) / (2 * ss**2)
                   - np.sum((c - c[k]) ** 2, axis=1) / (2 * sr**2)) * b
        np.testing.assert_allclose(out[ys[k], xs[k]], np.sum(w * v) / np.sum(w), rtol=1e-12)


def _one_channel_match():
    """Left (0.2, 0.2, 0.8) with BM 1 px, right (0.2, 0.8, 0.2) with BM 5 px: equal red channel."""
    h, w = 40, 40
    ref = np.empty((h, w, 3))
    ref[:, : w // 2] = (0.2, 0.2, 0.8)
    ref[:, w // 2:] = (0.2, 0.8, 0.2)
    bm = np.full((h, w), np.nan)
    bm[::3, : w // 2: 3] = 1.0
    bm[::3, w // 2::3] = 5.0
    left = np.isfinite(bm) & (np.arange(w) < w // 2)[None, :]
    return bm, ref, left, np.isfinite(bm) & ~left


@pytest.mark.parametrize("method", ["grid", "brute_force"])
def test_product_kernel_does_not_leak_through_one_matching_channel(method):
    """Sum kernel: 1/3 of the range weight crosses (red matches), so each side is pulled toward the
    other's measures (measured max leak 0.75 px, left mean 1.16 px, right mean 4.84 px); the product
    kernel keeps both sides exactly (round-off, measured 3e-15)."""
    bm, ref, left, right = _one_channel_match()
    kw = dict(sharpness_bias=False, method=method)
    summed = biased_cross_bilateral(bm, ref, range_kernel="sum", **kw)
    joint = biased_cross_bilateral(bm, ref, range_kernel="product", **kw)
    assert np.max(summed[left]) - 1.0 >= BILATERAL_SUM_LEAK_MIN_PX
    assert 5.0 - np.min(summed[right]) >= BILATERAL_SUM_LEAK_MIN_PX
    assert summed[left].mean() > 1.0 and summed[right].mean() < 5.0
    np.testing.assert_allclose(joint[left], 1.0, rtol=0, atol=BILATERAL_CONSTANT_ATOL)
    np.testing.assert_allclose(joint[right], 5.0, rtol=0, atol=BILATERAL_CONSTANT_ATOL)


@pytest.mark.parametrize("method", ["grid", "brute_force"])
@pytest.mark.parametrize("kernel", ["sum", "product"])
def test_robust_iterations_zero_is_the_plain_filter(rng, method, kernel):
    bm, ref = _case(rng, 40, 48)
    plain = biased_cross_bilateral(bm, ref, method=method, range_kernel=kernel)
    zero = biased_cross_bilateral(bm, ref, method=method, range_kernel=kernel, robust_iterations=0,
                                  robust_scale=0.1)
    np.testing.assert_array_equal(zero, plain)
    one = biased_cross_bilateral(bm, ref, method=method, range_kernel=kernel, robust_iterations=1)
    assert not np.array_equal(one, plain, equal_nan=True)


@pytest.mark.parametrize("method", ["grid", "brute_force"])
@pytest.mark.parametrize("kernel", ["sum", "product"])
def test_robust_iterations_reject_an_outlier(method, kernel):
    """One 10-px measure among 2-px ones: one pass leaves it at 2.59 px (grid, sum), two re-weighted
    passes at 2.016 px, and the neighbours it disturbed (max 0.47 px off) come back (0.012 px)."""
    h = w = 60
    ref = np.full((h, w, 3), 0.5)
    bm = np.full((h, w), np.nan)
    bm[::4, ::4] = 2.0
    bm[28, 28] = 10.0
    kw = dict(sharpness_bias=False, method=method, range_kernel=kernel)
    plain = biased_cross_bilateral(bm, ref, **kw)
    robust = biased_cross_bilateral(bm, ref, robust_iterations=2, **kw)
    one = biased_cross_bilateral(bm, ref, robust_iterations=1, **kw)
    inlier = bm == 2.0
    assert abs(plain[28, 28] - 2.0) > 0.3  # the outlier does move the plain filter
    assert abs(robust[28, 28] - 2.0) <= BILATERAL_ROBUST_RESIDUAL_FRACTION * abs(plain[28, 28] - 2.0)
    assert abs(robust[28, 28] - 2.0) < abs(one[28, 28] - 2.0) < abs(plain[28, 28] - 2.0)
    assert np.max(np.abs(robust[inlier] - 2.0)) <= BILATERAL_ROBUST_RESIDUAL_FRACTION * np.max(
        np.abs(plain[inlier] - 2.0))


@pytest.mark.parametrize("bad", [
    dict(range_kernel="max"), dict(range_kernel="Product"), dict(robust_iterations=-1),
    dict(robust_iterations=1.5), dict(robust_iterations=True), dict(robust_scale=0),
    dict(robust_scale=-1.0), dict(robust_scale=np.inf), dict(robust_scale=np.nan)])
def test_bad_robust_and_kernel_options_raise(rng, bad):
    bm, ref = _case(rng, 20, 20)
    with pytest.raises(ValueError, match=next(iter(bad))):
        biased_cross_bilateral(bm, ref, **bad)


# --- the product grid's fast kernels against scipy (their oracle) ---------------------------------
from scipy import ndimage  # noqa: E402

import method.refine.cross_bilateral as cbf  # noqa: E402


def _sparse_grid(rng, dims, fill=0.03):
    g = np.zeros(int(np.prod(dims)))
    idx = rng.choice(g.size, max(1, int(fill * g.size)), replace=False)
    g[idx] = rng.random(len(idx))
    return g


@pytest.mark.parametrize("dims, sigmas", [((9, 11, 7), (1.2, 0.8, 1.5)), ((6, 7, 5, 6, 5), (1.2,) * 5),
                                          ((300,), (2.0,)), ((5, 600), (1.0, 1.3))])
def test_blur_pair_is_scipy_gaussian_filter(rng, dims, sigmas):
    gn, gd = _sparse_grid(rng, dims), _sparse_grid(rng, dims)
    keep_n, keep_d = gn.copy(), gd.copy()
    got_n, got_d = cbf._gaussian_blur_pair(gn, gd, dims, sigmas, truncate=3.0)
    for got, src in ((got_n, gn), (got_d, gd)):
        want = ndimage.gaussian_filter(src.reshape(dims), sigmas, mode="constant", truncate=3.0)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * want.max())
    assert np.array_equal(gn, keep_n) and np.array_equal(gd, keep_d)  # inputs untouched


@pytest.mark.parametrize("dims", [(9, 11, 7), (6, 7, 5, 6, 5), (5, 600), (3, 4, 700)])
def test_blur_axis_pass_is_each_outputs_ascending_sum_bit_for_bit(rng, dims):
    """One pass of the separable blur: every output Σ_j taps[j − i + r]·src[j] added from 0 in
    ascending j (the kernel's fixed order, any thread count), the same bytes as this slow loop;
    chunks wider than one work item and all-zero chunks included."""
    import numba

    taps = cbf.gaussian_taps(1.3, 3.0)
    r = (len(taps) - 1) // 2
    for axis in range(len(dims)):
        outer, n, inner = int(np.prod(dims[:axis])), dims[axis], int(np.prod(dims[axis + 1:]))
        src_n, src_d = _sparse_grid(rng, dims, fill=0.1), _sparse_grid(rng, dims, fill=0.1)
        sn, sd = src_n.reshape(outer, n, inner), src_d.reshape(outer, n, inner)
        want_n, want_d = np.zeros_like(sn), np.zeros_like(sd)
        for i in range(n):
            for j in range(max(0, i - r), min(n - 1, i + r) + 1):
                want_n[:, i] += taps[j - i + r] * sn[:, j]
                want_d[:, i] += taps[j - i + r] * sd[:, j]
        threads = numba.get_num_threads()
        for nt in (threads, 1):
            numba.set_num_threads(nt)
            try:
                dst_n, dst_d = np.full_like(src_n, np.nan), np.full_like(src_d, np.nan)
                cbf._blur_axis_pair(src_n, src_d, dst_n, dst_d, outer, n, inner, taps)
            finally:
                numba.set_num_threads(threads)
            assert np.array_equal(dst_n.reshape(want_n.shape), want_n)
            assert np.array_equal(dst_d.reshape(want_d.shape), want_d)


def test_blur_pair_sigma_zero_skips_that_axis(rng):
    dims, sig = (8, 9, 10), (1.1, 0.0, 1.4)
    g = _sparse_grid(rng, dims)
    got, _ = cbf._gaussian_blur_pair(g, g, dims, sig, truncate=3.0)
    want = ndimage.gaussian_filter1d(ndimage.gaussian_filter1d(g.reshape(dims), 1.4, axis=2, mode="constant",
                                                               truncate=3.0), 1.1, axis=0, mode="constant", truncate=3.0)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * want.max())


def test_splat_blurred_last_is_splat_then_blur(rng):
    """One scatter = the multilinear splat followed by the last axis's Gaussian pass (zero outside)."""
    m, dims = 300, np.array([7, 8, 6, 12], dtype=np.int64)
    coords = rng.random((4, m)) * (dims[:, None] - 1.0001)
    coords[3, :5] = [0.0, 0.2, 10.9, 10.99, 5.5]  # points at both ends of the blurred axis
    base = np.floor(coords).astype(np.int64)
    frac = np.ascontiguousarray(coords - base)
    wv, bias = rng.random(m), rng.random(m) + 0.1
    size = int(np.prod(dims))
    n0, d0 = np.zeros(size), np.zeros(size)
    cbf._splat_multilinear(base, frac, dims, wv, bias, n0, d0)
    taps = cbf.gaussian_taps(1.3, 3.0)
    n1, d1 = np.zeros(size), np.zeros(size)
    cbf._splat_blurred_last(base, frac, dims, wv, bias, taps, n1, d1)
    for got, plain in ((n1, n0), (d1, d0)):
        want = ndimage.gaussian_filter1d(plain.reshape(tuple(dims)), 1.3, axis=-1, mode="constant", truncate=3.0)
        np.testing.assert_allclose(got.reshape(tuple(dims)), want, rtol=0, atol=1e-13 * want.max())


def test_gaussian_taps_are_scipys():
    for sigma in (0.6, 1.2, 2.7):
        impulse = np.zeros(41)
        impulse[20] = 1.0
        want = ndimage.gaussian_filter1d(impulse, sigma, mode="constant", truncate=3.0)
        taps = cbf.gaussian_taps(sigma, 3.0)
        r = (len(taps) - 1) // 2
        np.testing.assert_allclose(want[20 - r:21 + r], taps, rtol=1e-12)
        assert np.all(want[:20 - r] == 0) and np.all(want[21 + r:] == 0)


@pytest.mark.parametrize("kernel", ["sum", "product"])
def test_grid_threads_do_not_change_the_result(rng, kernel, monkeypatch):
    """The grids are blurred on GRID_THREADS threads; the result is bit-identical to one thread."""
    img = rng.random((48, 40, 3))
    bm = np.full((48, 40), np.nan)
    mask = rng.random((48, 40)) < 0.2
    bm[mask] = rng.random(mask.sum()) * 4
    monkeypatch.setattr(cbf, "GRID_THREADS", 1)
    one = biased_cross_bilateral(bm, img, range_kernel=kernel)
    monkeypatch.setattr(cbf, "GRID_THREADS", 2)
    two = biased_cross_bilateral(bm, img, range_kernel=kernel)
    assert np.array_equal(one, two, equal_nan=True)
