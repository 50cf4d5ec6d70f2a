"""Steerable Gaussian derivatives (Eq. 7, 8) and noise thresholds (Eq. 9) against closed forms."""

import math

import numpy as np
import pytest
import scipy.fft
import scipy.ndimage as ndi
from scipy.special import erfinv

from method.edges.gaussian_derivatives import (
    GaussianDerivativeBank,
    gaussian_derivative,
    sampled_kernel,
    steer_first,
    steer_second,
    steer_third,
)
from method.edges.noise_thresholds import (
    first_derivative_threshold,
    per_pixel_false_positive_rate,
    second_derivative_threshold,
)
from tests import tolerances as tol

# Gaussian blobs (centre row, centre col, std b, amplitude): I ∗ g_σ is again a sum of blobs.
_BLOBS = ((30.0, 27.0, 3.0, 0.6), (44.3, 52.1, 2.5, -0.4), (52.0, 30.5, 4.0, 0.3))
_SHAPE = (80, 84)


def _blobs(y, x, sigma=0.0):
    out = np.zeros(np.broadcast(y, x).shape)
    for cy, cx, b, a in _BLOBS:
        v = b * b + sigma * sigma
        out = out + a * (b * b / v) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * v))
    return out


def _blob_image():
    y, x = np.mgrid[0:_SHAPE[0], 0:_SHAPE[1]].astype(float)
    return _blobs(y, x)


@pytest.mark.parametrize("sigma", [1.5, 2.0, 3.0])
def test_matches_direct_convolution_with_sampled_kernels(sigma):
    img = ndi.gaussian_filter(np.random.default_rng(1).random((48, 56)), 2.0)
    bank = GaussianDerivativeBank(img, sigma)
    for a, b in ((1, 0), (0, 1), (2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2), (0, 3)):
        ref = ndi.convolve(img, sampled_kernel(sigma, order_x=a, order_y=b), mode="mirror")
        got = bank.response(sigma, a, b)
        assert np.abs(got - ref).max() <= tol.DERIV_VS_SAMPLED_RTOL * np.abs(ref).max(), (a, b)


def test_matches_sampled_kernels_at_sigma_one_loosely():
    img = ndi.gaussian_filter(np.random.default_rng(2).random((40, 40)), 2.0)
    bank = GaussianDerivativeBank(img, 1.0)
    for a, b in ((1, 0), (0, 1), (2, 0), (1, 1), (0, 2)):
        ref = ndi.convolve(img, sampled_kernel(1.0, order_x=a, order_y=b), mode="mirror")
        assert np.abs(bank.response(1.0, a, b) - ref).max() <= tol.DERIV_VS_SAMPLED_SIGMA1_RTOL * np.abs(ref).max()


def test_sampled_second_derivative_kernel_aliases_at_half_pixel_but_bank_has_zero_dc():
    # Why the bank uses the analytic transfer function: the sampled Eq. (8a) kernel at σ = 0.5
    # does not sum to zero, so it would respond to a constant image.
    assert sampled_kernel(0.5, order_x=2, order_y=0).sum() < -0.5
    const = np.full((20, 24), 0.7)
    bank = GaussianDerivativeBank(const, 0.5)
    for a, b in ((1, 0), (2, 0), (1, 1), (0, 2), (0, 3)):
        assert np.abs(bank.response(0.5, a, b)).max() < 1e-12
    assert np.allclose(bank.response(0.5, 0, 0), 0.7, atol=1e-12)


def _directional_fd(f, y, x, theta, order):
    """Central finite differences of f along u = (cos θ, sin θ) in (x, y) with y = row (down)."""
    ux, uy = math.cos(theta), math.sin(theta)

    def g(t):
        return f(y + t * uy, x + t * ux)

    if order == 1:
        h = 1e-3
        return (g(h) - g(-h)) / (2 * h)
    if order == 2:
        h = 1e-3
        return (g(h) - 2 * g(0.0) + g(-h)) / h ** 2
    h = 5e-3
    return (g(2 * h) - 2 * g(h) + 2 * g(-h) - g(-2 * h)) / (2 * h ** 3)


@pytest.mark.parametrize("sigma", [1.0, 2.5])
def test_steered_derivatives_equal_numerical_directional_derivatives(sigma):
    img = _blob_image()
    bank = GaussianDerivativeBank(img, sigma)
    ix, iy = bank.gradient(sigma)
    ixx, ixy, iyy = bank.hessian(sigma)
    t3 = bank.third(sigma)
    y, x = np.mgrid[16:64:3, 16:68:3].astype(float)
    yi, xi = y.astype(int), x.astype(int)

    def blurred(yy, xx):
        return _blobs(yy, xx, sigma)

    for deg in range(0, 360, 15):
        th = math.radians(deg)
        for order, got in (
            (1, steer_first(ix, iy, th)),
            (2, steer_second(ixx, ixy, iyy, th)),
            (3, steer_third(*t3, th)),
        ):
            ref = _directional_fd(blurred, y, x, th, order)
            err = np.abs(got[yi, xi] - ref).max()
            assert err <= tol.STEERED_VS_ANALYTIC_RTOL * np.abs(ref).max() + 1e-9, (deg, order, err)


def test_paper_minus_sign_is_the_y_up_convention():
    # With y down the cross term is +2cs·I_xy; the paper's −2cs equals steering by −θ (y up).
    img = _blob_image()
    ixx, ixy, iyy = GaussianDerivativeBank(img, 2.0).hessian(2.0)
    th = 0.7
    c, s = math.cos(th), math.sin(th)
    paper = c * c * ixx - 2 * c * s * ixy + s * s * iyy
    assert np.allclose(paper, steer_second(ixx, ixy, iyy, -th), atol=1e-15)
    assert not np.allclose(paper, steer_second(ixx, ixy, iyy, th), atol=1e-6)


def test_single_precision_bank_is_far_below_the_thresholds():
    img = np.clip(_blob_image() + 0.5, 0, 1)
    ap = per_pixel_false_positive_rate(1e-6, img.size)
    dbl = GaussianDerivativeBank(img, 32.0)
    sgl = GaussianDerivativeBank(img, 32.0, precision="single")
    for s in (0.5, 4.0, 32.0):
        c2 = second_derivative_threshold(s, noise_std=2.5 / 255, alpha_p=ap)
        diff = np.abs(sgl.response(s, 2, 0).astype(float) - dbl.response(s, 2, 0)).max()
        assert diff <= tol.SINGLE_PRECISION_VS_THRESHOLD * c2


@pytest.mark.parametrize("precision", ["single", "double"])
def test_fused_transfer_is_numpys_two_products_byte_for_byte(precision, rng):
    """The numba transfer kernel gives the values of ``spectrum * hx[None]`` then ``*= hy[:, None]``.

    Every order the bank serves (0 … 3, odd orders with their zeroed Nyquist bin), scales on every
    padding level, even and odd FFT sizes; the inverse FFTs of both then agree byte for byte too.
    """
    from method.edges.gaussian_derivatives import _apply_transfer

    for shape in ((80, 84), (81, 77)):
        img = np.clip(0.5 + 0.2 * rng.standard_normal(shape), 0, 1)
        bank = GaussianDerivativeBank(img, 64.0, precision=precision)
        for s in (0.5, 3.0, 12.0, 64.0):
            _, (p, fft_shape, spectrum, wy, wx, nyq_y, nyq_x) = bank._level(s)
            for a in range(4):
                for b in range(4 - a):
                    hy = bank._axis_transfer(wy, s, b, nyq_y)
                    hx = bank._axis_transfer(wx, s, a, nyq_x)
                    want = spectrum * hx[None, :]
                    want *= hy[:, None]
                    got = np.empty_like(spectrum)
                    _apply_transfer(spectrum, hx, hy, got)
                    # equal values (only the sign of a zero may differ, where the Gaussian
                    # underflowed to 0) and the same bytes after the inverse FFT
                    assert np.array_equal(got, want), (shape, s, a, b)
                    inv_got = scipy.fft.irfft2(got, s=fft_shape)
                    assert inv_got.tobytes() == scipy.fft.irfft2(want, s=fft_shape).tobytes(), (shape, s, a, b)
        # a product that is not one rounded real product per component would differ: the kernel is
        # not just returning its input
        assert not np.array_equal(got, spectrum)


@pytest.mark.parametrize("precision", ["single", "double"])
def test_response_is_the_plain_irfft2_of_the_product_byte_for_byte(precision, rng):
    """The bank's response equals the obvious ``irfft2`` of the whole product, cropped, byte for byte.

    The bank skips the columns where the Gaussian underflowed and the rows the crop discards
    (``_cropped_irfft2``); the oracle runs NumPy's two products and the full ``irfft2``. Every
    order, scales on every padding level (σ = 16 and 64 have underflowed columns), even and odd
    FFT sizes; only the sign of an exact 0 may differ, so the values are compared with +0 for −0.
    """
    for shape in ((80, 84), (81, 77), (150, 203)):
        img = np.clip(0.5 + 0.2 * rng.standard_normal(shape), 0, 1)
        bank = GaussianDerivativeBank(img, 64.0, precision=precision)
        skipped = 0
        for s in (0.5, 3.0, 12.0, 16.0, 64.0):
            _, (p, fft_shape, spectrum, wy, wx, nyq_y, nyq_x) = bank._level(s)
            for a in range(4):
                for b in range(4 - a):
                    hy = bank._axis_transfer(wy, s, b, nyq_y)
                    hx = bank._axis_transfer(wx, s, a, nyq_x)
                    skipped += int(hx[-1] == 0 and hx[len(hx) // 2] == 0)
                    prod = spectrum * hx[None, :]
                    prod *= hy[:, None]
                    want = scipy.fft.irfft2(prod, s=fft_shape)[p:p + shape[0], p:p + shape[1]]
                    if a == 0 and b == 0:
                        want = want + want.dtype.type(bank.mean)
                    got = bank.response(s, a, b)
                    assert got.dtype == want.dtype and got.flags.c_contiguous
                    assert (got + 0.0).tobytes() == (want + 0.0).tobytes(), (shape, s, a, b)
        assert skipped > 0  # the column skip was exercised


def test_large_scale_is_cheap_and_matches_wrapper():
    img = _blob_image()
    a = gaussian_derivative(img, 64.0, order_x=1, order_y=0)
    b = GaussianDerivativeBank(img, 64.0).response(64.0, 1, 0)
    assert a.shape == img.shape and np.allclose(a, b)


@pytest.mark.parametrize("bad", [np.zeros((4, 4, 3)), np.zeros((1, 5)), np.full((5, 5), np.nan),
                                 np.zeros((5, 5), dtype=np.uint8)])
def test_bank_rejects_bad_images(bad):
    with pytest.raises(ValueError):
        GaussianDerivativeBank(bad, 1.0)


def test_bank_rejects_bad_orders_and_scales():
    bank = GaussianDerivativeBank(np.zeros((8, 8)), 2.0)
    with pytest.raises(ValueError, match="orders"):
        bank.response(1.0, 2, 2)
    with pytest.raises(ValueError, match="max_sigma"):
        bank.response(4.0, 1, 0)
    with pytest.raises(ValueError, match="sigma"):
        bank.response(-1.0, 1, 0)


# --- Eq. (9) ---------------------------------------------------------------------------------

def test_alpha_p_solves_its_definition_without_cancellation():
    for a_i, n in ((1e-6, 1_000_000), (1e-6, 4096), (0.05, 10), (1e-3, 1)):
        ap = per_pixel_false_positive_rate(a_i, n)
        assert 0 < ap < 1
        # (1 − α_p)^n = 1 − α_I, checked in log space
        assert math.isclose(n * math.log1p(-ap), math.log1p(-a_i), rel_tol=tol.THRESHOLD_RTOL)
    assert math.isclose(per_pixel_false_positive_rate(1e-6, 1_000_000), 1e-12, rel_tol=1e-6)


def test_thresholds_equal_closed_forms():
    sn = 2.5 / 255
    for ap in (1e-3, 0.2):  # moderate α_p: 1 − α_p is exact enough for the naive erf⁻¹ form
        for s in (0.5, 1.0, 4.0, 64.0):
            c1 = sn * math.sqrt(-2 * math.log(ap)) / (2 * math.sqrt(2 * math.pi) * s ** 2)
            c2 = sn * math.sqrt(2) * erfinv(1 - ap) / (4 * math.sqrt(math.pi / 3) * s ** 3)
            assert math.isclose(first_derivative_threshold(s, noise_std=sn, alpha_p=ap), c1, rel_tol=tol.THRESHOLD_RTOL)
            assert math.isclose(second_derivative_threshold(s, noise_std=sn, alpha_p=ap), c2, rel_tol=1e-10)
    scales = np.array([0.5, 1.0, 2.0])
    c = first_derivative_threshold(scales, noise_std=sn, alpha_p=1e-3)
    assert c.shape == (3,) and np.allclose(c[0] / c, (scales / 0.5) ** 2)


def test_second_threshold_positive_with_paper_alpha():
    ap = per_pixel_false_positive_rate(1e-6, 1024 * 1024)
    c2 = second_derivative_threshold(1.0, noise_std=2.5 / 255, alpha_p=ap)
    # erf⁻¹(1 − α_p) reading: ≈ 7.1 noise standard deviations; the erf⁻¹(α_p) reading would be ~0.
    std = (2.5 / 255) / (4 * math.sqrt(math.pi / 3))
    assert 6.5 < c2 / std < 7.5
    assert c2 > 0


def test_threshold_inputs_validated():
    with pytest.raises(ValueError, match="false_positive_rate"):
        per_pixel_false_positive_rate(1.5, 10)
    with pytest.raises(ValueError, match="n_pixels"):
        per_pixel_false_positive_rate(1e-6, 0)
    with pytest.raises(ValueError, match="sigma1"):
        first_derivative_threshold(0.0, noise_std=0.01, alpha_p=1e-6)
    with pytest.raises(ValueError, match="noise_std"):
        second_derivative_threshold(1.0, noise_std=-1.0, alpha_p=1e-6)
    with pytest.raises(ValueError, match="alpha_p"):
        second_derivative_threshold(1.0, noise_std=0.01, alpha_p=0.0)


def test_steering_weights_written_once():
    """The steering arithmetic (cos/sin products of the 2nd and 3rd derivative) lives in
    method.edges.gaussian_derivatives only; the kernels call its helpers."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "method"
    pattern = re.compile(r"2\.0 \* c \* s|3\.0 \* c \* c \* s|abs\(c\) >= abs\(s\)")
    where = sorted(p.relative_to(root).as_posix() for p in root.rglob("*.py") if pattern.search(p.read_text()))
    assert where == ["edges/gaussian_derivatives.py"]


def test_steering_weights_match_the_closed_form_bit_for_bit():
    from method.edges.gaussian_derivatives import nearest_axis_step, second_steering_weights, third_steering_weights

    th = np.linspace(-np.pi, np.pi, 37)
    c, s = np.cos(th), np.sin(th)
    for got, want in zip(second_steering_weights(c, s), (c * c, 2.0 * c * s, s * s)):
        np.testing.assert_array_equal(got, want)
    for got, want in zip(third_steering_weights(c, s), (c * c * c, 3.0 * c * c * s, 3.0 * c * s * s, s * s * s)):
        np.testing.assert_array_equal(got, want)
    assert nearest_axis_step(0.9, -0.3) == (0, 1, 0.9)
    assert nearest_axis_step(-0.2, -0.8) == (-1, 0, 0.8)


def test_responses_on_threads_are_response_byte_for_byte(rng):
    """The responses computed ahead on threads are :meth:`response`'s, in request order; close() stops early."""
    img = np.clip(0.5 + 0.2 * rng.standard_normal((61, 70)), 0, 1)
    bank = GaussianDerivativeBank(img, 16.0, precision="single", workers=1)
    requests = [(s, a, b) for s in (0.5, 2.0, 16.0) for a, b in ((1, 0), (0, 1), (2, 0), (1, 1), (0, 2))]
    want = [GaussianDerivativeBank(img, 16.0, precision="single", workers=1).response(*r) for r in requests]
    for threads, ahead in ((1, 6), (2, 1), (2, 6), (3, 100)):
        got = list(bank.responses(requests, threads=threads, ahead=ahead))
        assert [g.tobytes() for g in got] == [w.tobytes() for w in want], (threads, ahead)
    # responses of different requests differ: the order is tested, not just the values
    assert want[0].tobytes() != want[1].tobytes()
    stream = bank.responses(requests, threads=2, ahead=4)
    assert next(stream).tobytes() == want[0].tobytes()
    stream.close()
    with pytest.raises(StopIteration):
        next(stream)


def test_bank_fft_threads_follow_numbas_thread_count():
    """Without ``workers`` the bank's FFTs use numba's thread count (1 inside the runner's single_threaded)."""
    import numba

    from experiments.threads import single_threaded

    img = np.zeros((20, 20))
    assert GaussianDerivativeBank(img, 1.0).workers == numba.get_num_threads()
    with single_threaded():
        assert GaussianDerivativeBank(img, 1.0).workers == 1
    assert GaussianDerivativeBank(img, 1.0, workers=3).workers == 3
    with pytest.raises(ValueError, match="workers"):
        GaussianDerivativeBank(img, 1.0, workers=0)
