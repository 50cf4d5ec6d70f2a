"""Steerable Gaussian derivative filters, Eq. (7) and (8) (Appendix B, after Elder & Zucker 1998).

Angle convention used everywhere in ``method``
-----------------------------------------------
Pixel ``(row, col)``; **x = column index, increasing to the right; y = row index, increasing
downward**. An angle θ names the unit vector u = (cos θ, sin θ) in (x, y), so θ = 0 points right and
θ = +π/2 points *down*. The gradient direction is θ = atan2(∂I/∂y, ∂I/∂x); intensity increases
along u.

With this convention the directional derivatives along u are

* 1st: ∂_u I = cos θ · I_x + sin θ · I_y
* 2nd: ∂²_u I = cos²θ · I_xx + 2 cos θ sin θ · I_xy + sin²θ · I_yy
* 3rd: ∂³_u I = cos³θ · I_xxx + 3 cos²θ sin θ · I_xxy + 3 cos θ sin²θ · I_xyy + sin³θ · I_yyy

The paper's Eq. (8e) writes the cross term of the 2nd derivative with a minus sign; that is the
same operator with y pointing *up* (θ measured counter-clockwise on screen). The tests check the
``+`` sign against numerical directional derivatives with y down.

Implementation
--------------
The responses are ``I ∗ ∂^{a+b} g_σ / ∂x^a ∂y^b`` with g_σ the 2-D Gaussian of Eq. (1), i.e. the
convolution with the kernels of Eq. (7a/b) (a+b = 1) and Eq. (8a–c) (a+b = 2). They are evaluated in
the Fourier domain: one real FFT of the reflect-padded image, then per (σ, a, b) a multiplication
by the analytic transfer function (iω_x)^a (iω_y)^b exp(−σ²(ω_x² + ω_y²)/2) and one inverse real
FFT. The cost per response is independent of σ, so σ1 = 64 px costs the same as σ1 = 0.5 px.

For σ ≳ 1 px this equals direct convolution with the sampled kernels of Eq. (7/8) (tested). At
σ = 0.5 px the sampled kernels alias badly — e.g. the sampled Eq. (8a) kernel sums to ≈ −0.58
instead of 0, so it responds to a constant image — while the analytic transfer function is exactly
zero at DC; we therefore use the transfer function (the continuous Gaussian derivative of the
band-limited image) at every scale.
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
import scipy.fft

from ..validation import validate_image

__all__ = [
    "GaussianDerivativeBank",
    "gaussian_derivative",
    "sampled_kernel",
    "nearest_axis_step",
    "second_steering_weights",
    "steer_first",
    "steer_second",
    "steer_third",
    "third_steering_weights",
]

#: Reflect padding added on every side, in multiples of the largest σ requested (px).
PAD_SIGMAS = 4.0
#: Width, px, of the raised-cosine taper added outside the reflect padding (see Notes of the bank).
TAPER_PX = 8
#: Highest derivative order supported (the zero-crossing estimator needs 3).
MAX_ORDER = 3


def check_gray_image(image, name="image", min_size=2):
    # a grey HxW float image, any finite values (derivatives are linear): method.validation's rules
    return validate_image(np.asarray(image), name=name, min_side=min_size, channels=(), check_range=False)


def _validate_sigma(sigma, name="sigma"):
    s = float(sigma)
    if not (s > 0 and math.isfinite(s)):
        raise ValueError(f"{name}={sigma!r} is invalid; allowed: finite σ > 0 px")
    return s


class GaussianDerivativeBank:
    """Gaussian derivative responses of one image at any scale, Eq. (7), (8).

    The image is reflect-padded and Fourier-transformed once per *padding level* (lazily); each
    call of :meth:`response` then costs one complex multiplication and one inverse real FFT.

    Parameters
    ----------
    image : ndarray, shape (H, W), float
        Real image (any units; the method uses [0, 1]).
    max_sigma : float
        Largest σ (px) that will be requested.
    pad_sigmas : float, keyword-only
        Reflect padding per side in units of σ (default :data:`PAD_SIGMAS` = 4).
    precision : {"double", "single"}, keyword-only
        FFT precision. "single" (complex64) is ≈ 2× faster; its round-off on a [0, 1] image is
        < 1e−3 of the Eq. (9) thresholds at every paper scale (measured), so the edge detector uses
        it. Responses are float64 for "double", float32 for "single".
    workers : int or None, keyword-only
        FFT threads; None (default): numba's thread count (:func:`numba.get_num_threads`), so a
        caller that limits numba to one thread (the runner's cases do) gets one-thread FFTs too.

    Notes
    -----
    1. Subtract the image mean (improves round-off; derivatives ignore it, order 0 adds it back).
    2. Padding levels: a request at σ uses the smallest level 4^k ≥ σ (k ≥ 1, capped at
       max_sigma) and pads ``ceil(pad_sigmas · level) + 1`` px per side (``numpy.pad``
       ``mode="reflect"``), plus :data:`TAPER_PX` more reflected px that a raised cosine takes down
       to 0 (the mean) — so the FFT's periodic wrap is continuous — then zeros up to a fast FFT
       length. Small scales use small FFTs.
    3. ``rfft2`` once per level. Per request: multiply by (iω_x)^a (iω_y)^b exp(−σ²|ω|²/2) (the
       Nyquist bin of an odd order is set to 0), ``irfft2``, crop the padding. The inverse is
       computed as ``irfft2`` computes it (see :func:`_cropped_irfft2`) but skips the frequency
       columns where the Gaussian has underflowed to 0 and the rows the crop discards: the same
       bytes for 29–66 % less transform work at σ ≥ 8 px.
    """

    def __init__(self, image, max_sigma, *, pad_sigmas=PAD_SIGMAS, precision="double", workers=None):
        img = check_gray_image(image)
        max_sigma = _validate_sigma(max_sigma, "max_sigma")
        if not pad_sigmas > 0:
            raise ValueError(f"pad_sigmas={pad_sigmas!r} is invalid; allowed: > 0")
        if precision not in ("double", "single"):
            raise ValueError(f"precision={precision!r} is invalid; allowed: 'double', 'single'")
        self.shape = img.shape
        self.mean = float(img.mean())
        self.max_sigma = max_sigma
        self.pad_sigmas = float(pad_sigmas)
        self.precision = precision
        self.workers = numba.get_num_threads() if workers is None else int(workers)
        if self.workers < 1:
            raise ValueError(f"workers={workers!r} is invalid; allowed: None or an integer >= 1")
        self._rdtype = np.float64 if precision == "double" else np.float32
        self._cdtype = np.complex128 if precision == "double" else np.complex64
        self._centered = (img - self.mean).astype(self._rdtype)
        self._levels = {}
        self._lock = threading.Lock()  # one transform per padding level when responses run on threads

    def _level(self, sigma):
        lev = 4.0
        while lev < sigma:
            lev *= 4.0
        lev = min(lev, self.max_sigma)
        with self._lock:
            return lev, self._level_entry(lev)

    def _level_entry(self, lev):
        entry = self._levels.get(lev)
        if entry is None:
            h, w = self.shape
            p = int(math.ceil(self.pad_sigmas * lev)) + 1
            fft_shape = (scipy.fft.next_fast_len(h + 2 * (p + TAPER_PX), real=True),
                         scipy.fft.next_fast_len(w + 2 * (p + TAPER_PX), real=True))
            padded = np.pad(self._centered, p + TAPER_PX, mode="reflect")
            # Taper the outer TAPER_PX of the padding to 0 (the image mean): the periodic wrap of
            # the FFT is then continuous, so the band-limited kernels (whose spatial tails are long
            # at σ = 0.5 px) see no artificial step at the wrap.
            ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(TAPER_PX) + 0.5) / TAPER_PX)
            taper_y = np.ones(padded.shape[0], dtype=self._rdtype)
            taper_y[:TAPER_PX], taper_y[-TAPER_PX:] = ramp, ramp[::-1]
            taper_x = np.ones(padded.shape[1], dtype=self._rdtype)
            taper_x[:TAPER_PX], taper_x[-TAPER_PX:] = ramp, ramp[::-1]
            padded *= taper_y[:, None]
            padded *= taper_x[None, :]
            padded = np.pad(padded, ((0, fft_shape[0] - padded.shape[0]), (0, fft_shape[1] - padded.shape[1])))
            p += TAPER_PX
            spectrum = scipy.fft.rfft2(padded, workers=self.workers)
            ny, nx = fft_shape
            wy = 2.0 * np.pi * scipy.fft.fftfreq(ny)
            wx = 2.0 * np.pi * scipy.fft.rfftfreq(nx)
            entry = (p, fft_shape, spectrum, wy, wx, ny // 2 if ny % 2 == 0 else None,
                     nx // 2 if nx % 2 == 0 else None)
            self._levels[lev] = entry
        return entry

    def _axis_transfer(self, w, sigma, order, nyq):
        h = np.exp(-0.5 * (sigma * w) ** 2).astype(np.complex128)
        if order:
            h *= (1j * w) ** order
            if order % 2 == 1 and nyq is not None:
                h[nyq] = 0.0
        return h.astype(self._cdtype)

    def response(self, sigma, order_x, order_y):
        """``I ∗ ∂^{a+b} g_σ / ∂x^a ∂y^b`` with a = order_x, b = order_y.

        Parameters
        ----------
        sigma : float
            Gaussian scale σ, px, ``0 < sigma <= max_sigma``.
        order_x, order_y : int
            Derivative orders along x (columns) and y (rows), ``0 <= a + b <= 3``.

        Returns
        -------
        ndarray, shape (H, W), float64 (float32 for ``precision="single"``)
            Response in image units per px^(a+b).
        """
        sigma = _validate_sigma(sigma)
        if sigma > self.max_sigma * (1 + 1e-12):
            raise ValueError(f"sigma={sigma} exceeds the bank's max_sigma={self.max_sigma}")
        a, b = int(order_x), int(order_y)
        if a < 0 or b < 0 or a + b > MAX_ORDER:
            raise ValueError(f"orders (x={order_x}, y={order_y}) invalid; allowed: a, b >= 0, a + b <= {MAX_ORDER}")
        _, (p, fft_shape, spectrum, wy, wx, nyq_y, nyq_x) = self._level(sigma)
        hy = self._axis_transfer(wy, sigma, b, nyq_y)
        hx = self._axis_transfer(wx, sigma, a, nyq_x)
        out = _cropped_irfft2(spectrum, hx, hy, fft_shape, p, self.shape, self.workers)
        if a == 0 and b == 0:
            out += self._rdtype(self.mean)
        return out

    def gradient(self, sigma):
        """(I_x, I_y) at scale σ (Eq. 7a, 7b); each (H, W), image units / px."""
        return self.response(sigma, 1, 0), self.response(sigma, 0, 1)

    def hessian(self, sigma):
        """(I_xx, I_xy, I_yy) at scale σ (Eq. 8a, 8c, 8b); each (H, W), image units / px²."""
        return self.response(sigma, 2, 0), self.response(sigma, 1, 1), self.response(sigma, 0, 2)

    def third(self, sigma):
        """(I_xxx, I_xxy, I_xyy, I_yyy) at scale σ; each (H, W), image units / px³."""
        return (self.response(sigma, 3, 0), self.response(sigma, 2, 1),
                self.response(sigma, 1, 2), self.response(sigma, 0, 3))

    def responses(self, requests, *, threads=1, ahead=6):
        """:meth:`response` of each ``(sigma, order_x, order_y)`` of ``requests``, in order, as an iterator.

        Parameters
        ----------
        requests : sequence of (float, int, int)
            σ (px) and the orders along x and y, as :meth:`response` takes them.
        threads : int, keyword-only
            With more than 1, up to ``ahead`` requests are computed ahead of the consumer on that many
            threads from this call on (the FFTs and the transfer product release the GIL), so the
            consumer's own work on one response overlaps the transforms of the next. Each response is
            computed as :meth:`response` computes it: the values do not depend on ``threads``.
        ahead : int, keyword-only
            Most requests in flight (≥ 1).

        Returns
        -------
        iterator of ndarray, shape (H, W)
            The responses in the order of ``requests``; also a context manager whose exit (or
            ``close()``) cancels the requests not started and waits for the running ones.
        """
        return _ResponseStream(self, list(requests), int(threads), max(1, int(ahead)))


class _ResponseStream:
    """Iterator of :meth:`GaussianDerivativeBank.responses`: up to ``ahead`` requests computed ahead on a pool."""

    def __init__(self, bank, requests, threads, ahead):
        self._bank, self._requests, self._ahead, self._next = bank, requests, ahead, 0
        self._pool = ThreadPoolExecutor(max_workers=threads) if threads > 1 else None
        self._pending = {i: self._pool.submit(bank.response, *requests[i])
                         for i in range(min(ahead, len(requests)))} if self._pool else {}

    def __iter__(self):
        return self

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __next__(self):
        i = self._next
        if i >= len(self._requests):
            self.close()
            raise StopIteration
        self._next += 1
        if self._pool is None:
            return self._bank.response(*self._requests[i])
        if i + self._ahead < len(self._requests):
            self._pending[i + self._ahead] = self._pool.submit(self._bank.response, *self._requests[i + self._ahead])
        return self._pending.pop(i).result()

    def close(self):
        """Cancel the requests not started, wait for the running ones; the iterator is then exhausted."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool, self._pending = None, {}
        self._next = len(self._requests)


def _cropped_irfft2(spectrum, hx, hy, fft_shape, pad, shape, workers):
    """``irfft2(spectrum · hx[None, :] · hy[:, None], s=fft_shape)[pad:pad + H, pad:pad + W]``, byte for byte.

    pocketfft's ``irfft2`` is an unscaled complex inverse along the rows' axis (0), then a real
    inverse along axis 1 whose output it multiplies by ``1 / (ny · nx)`` (rounded to the FFT's
    precision). This runs the same two 1-D transforms, but the first only on the leading columns
    where ``hx`` is not 0 (beyond them the Gaussian has underflowed: the columns are 0, and so is
    their transform) and the second only on the H rows the crop keeps, then applies the same scale
    factor as the same rounded product. The values are ``irfft2``'s (only the sign of an exact 0
    may differ); tested against ``irfft2`` on every order, precision and padding level.

    Parameters
    ----------
    spectrum : ndarray, shape (ny, nx // 2 + 1), complex
        ``rfft2`` of the padded image.
    hx, hy : ndarray, shapes (nx // 2 + 1,) and (ny,), the spectrum's dtype
        Transfer function along x (columns) and y (rows); ``hx`` must be 0 beyond its last non-zero.
    fft_shape : (int, int)
        (ny, nx), the real FFT's shape.
    pad : int
        Padding on every side, px.
    shape : (int, int)
        (H, W) kept after the crop.
    workers : int
        FFT threads.

    Returns
    -------
    ndarray, shape (H, W), float (the spectrum's real precision), C-contiguous
    """
    ny, nx = fft_shape
    h, w = shape
    nz = np.flatnonzero(hx)
    k = int(nz[-1]) + 1 if nz.size else 1
    spec = np.empty((ny, k), dtype=spectrum.dtype)
    _apply_transfer(spectrum, hx, hy, spec)
    cols = scipy.fft.ifft(spec, axis=0, norm="forward", workers=workers, overwrite_x=True)
    if k == spectrum.shape[1]:
        half = cols[pad:pad + h]  # a C-contiguous block of rows: no copy
    else:
        half = np.zeros((h, spectrum.shape[1]), dtype=spectrum.dtype)
        half[:, :k] = cols[pad:pad + h]
    rows = scipy.fft.irfft(half, n=nx, axis=1, norm="forward", workers=workers, overwrite_x=True)
    real = rows.dtype.type
    # pocketfft's scale: 1 / (ny · nx) in long double, rounded once to the transform's precision
    return np.multiply(rows[:, pad:pad + w], real(1 / np.longdouble(ny * nx)))


@numba.njit(cache=True, nogil=True)
def _apply_transfer(spectrum, hx, hy, out):
    """out = (spectrum · hx[None, :]) · hy[:, None] on out's leading columns; NumPy's values.

    The same two complex products per bin, in the same order, as the NumPy expression
    ``spectrum * hx[None, :]`` then ``*= hy[:, None]``: one pass over the spectrum instead of two
    (0.8 ms instead of 1.8 ms of CPU per response at 1 MP). One thread: the memory-bound pass gains
    little from more, and an OpenMP team left spinning after it slows the FFT threads that follow;
    :meth:`GaussianDerivativeBank.responses` runs whole responses on threads instead (``nogil``). Each factor is real or imaginary (i^a times a
    real Gaussian), so every product component is one rounded real product whichever way NumPy fuses
    its multiply: the values are NumPy's (only the sign of a zero may differ, where the Gaussian has
    underflowed to 0), and the inverse FFTs are byte-identical (tested on every order and precision).
    """
    ny, nx = out.shape  # the leading nx columns of the spectrum (all of them when out has its shape)
    for y in range(ny):
        br = hy[y].real
        bi = hy[y].imag
        srow = spectrum[y]
        orow = out[y]
        for x in range(nx):
            s = srow[x]
            h = hx[x]
            tr = s.real * h.real - s.imag * h.imag
            ti = s.real * h.imag + s.imag * h.real
            orow[x] = complex(tr * br - ti * bi, tr * bi + ti * br)


def gaussian_derivative(image, sigma, *, order_x, order_y):
    """One Gaussian derivative response ``I ∗ ∂^{a+b} g_σ/∂x^a ∂y^b`` (Eq. 7, 8).

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Real image.
    sigma : float
        Scale σ, px (> 0).
    order_x, order_y : int, keyword-only
        Derivative orders along x (columns, right) and y (rows, down); a + b <= 3.

    Returns
    -------
    ndarray, shape (H, W), float64

    Notes
    -----
    Builds a :class:`GaussianDerivativeBank` (one FFT) and evaluates one response; use the bank
    directly for many responses of the same image.
    """
    return GaussianDerivativeBank(image, sigma).response(sigma, order_x, order_y)


def steer_first(ix, iy, theta):
    """Steered 1st derivative along θ: cos θ·I_x + sin θ·I_y (Eq. 7, x right, y down)."""
    return np.cos(theta) * ix + np.sin(theta) * iy


@numba.njit(cache=True, inline="always")
def nearest_axis_step(c, s):
    """The one-pixel step along the image axis closest to the direction (cos θ, sin θ) = (c, s).

    Returns
    -------
    di, dj : int
        Row and column step (one of them 0, the other ±1; x right, y down).
    proj : float
        max(|c|, |s|): a straight edge normal to θ is crossed every 1/proj steps.
    """
    if abs(c) >= abs(s):
        return 0, (1 if c >= 0 else -1), abs(c)
    return (1 if s >= 0 else -1), 0, abs(s)


@numba.njit(cache=True, inline="always")
def second_steering_weights(c, s):
    """Weights (cos²θ, 2 cos θ sin θ, sin²θ) of I_xx, I_xy, I_yy in the steered 2nd derivative.

    The one definition of the steering arithmetic: :func:`steer_second` and the numba kernels that
    steer per pixel (edge detection, model fit) use it, so all give bit-identical values.

    Parameters
    ----------
    c, s : float or ndarray
        cos θ and sin θ (θ in radians).

    Returns
    -------
    tuple of float or ndarray
        (c·c, 2·c·s, s·s), dimensionless.
    """
    return c * c, 2.0 * c * s, s * s


@numba.njit(cache=True, inline="always")
def third_steering_weights(c, s):
    """(c·c·c, 3·c·c·s, 3·c·s·s, s·s·s): the weights of I_xxx, I_xxy, I_xyy, I_yyy in the steered 3rd
    derivative, c = cos θ and s = sin θ as in :func:`second_steering_weights` (used by
    :func:`steer_third` and the zero-crossing kernel)."""
    return c * c * c, 3.0 * c * c * s, 3.0 * c * s * s, s * s * s


def steer_second(ixx, ixy, iyy, theta):
    """Steered 2nd derivative along θ, Eq. (8d/e) with y down.

    cos²θ·I_xx + 2 cos θ sin θ·I_xy + sin²θ·I_yy (the paper's −2 is for y up).

    Parameters
    ----------
    ixx, ixy, iyy : ndarray, same shape
        Responses to Eq. (8a), (8c), (8b), image units / px².
    theta : float or ndarray
        Direction θ, radians.

    Returns
    -------
    ndarray
    """
    cc, cs2, ss = second_steering_weights(np.cos(theta), np.sin(theta))
    return cc * ixx + cs2 * ixy + ss * iyy


def steer_third(ixxx, ixxy, ixyy, iyyy, theta):
    """Steered 3rd derivative along θ (x right, y down).

    cos³θ·I_xxx + 3cos²θ sin θ·I_xxy + 3cos θ sin²θ·I_xyy + sin³θ·I_yyy; used by the
    zero-crossing blur estimator (the 3rd derivative is separable-steerable with 4 basis filters).
    """
    c3, c2s, cs2, s3 = third_steering_weights(np.cos(theta), np.sin(theta))
    return c3 * ixxx + c2s * ixxy + cs2 * ixyy + s3 * iyyy


def sampled_kernel(sigma, *, order_x, order_y, radius=None):
    """The sampled spatial kernel ∂^{a+b} g_σ / ∂x^a ∂y^b of Eq. (7) / (8) (reference / tests).

    Parameters
    ----------
    sigma : float
        σ, px.
    order_x, order_y : int, keyword-only
        a, b with a + b <= 3. E.g. (1, 0) is Eq. (7a) −x/(2πσ⁴)·exp(−(x²+y²)/(2σ²)),
        (2, 0) is Eq. (8a), (1, 1) is Eq. (8c).
    radius : int, optional, keyword-only
        Half-size in px; default ``ceil(6σ)``.

    Returns
    -------
    ndarray, shape (2·radius + 1, 2·radius + 1)
        Kernel with rows = y (down), columns = x (right), centre at [radius, radius]; to be used
        with *convolution* (``scipy.ndimage.convolve``).
    """
    sigma = _validate_sigma(sigma)
    r = int(math.ceil(6 * sigma)) if radius is None else int(radius)
    t = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (t / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma)
    # 1-D derivatives of the Gaussian: g' = −t/σ² g, g'' = (t²/σ² − 1)/σ² g, g''' = (3t/σ² − t³/σ⁴)/σ² g
    polys = {
        0: np.ones_like(t),
        1: -t / sigma ** 2,
        2: (t ** 2 / sigma ** 2 - 1) / sigma ** 2,
        3: (3 * t / sigma ** 2 - t ** 3 / sigma ** 4) / sigma ** 2,
    }
    a, b = int(order_x), int(order_y)
    if a < 0 or b < 0 or a + b > MAX_ORDER:
        raise ValueError(f"orders (x={order_x}, y={order_y}) invalid; allowed: a, b >= 0, a + b <= {MAX_ORDER}")
    kx = polys[a] * g
    ky = polys[b] * g
    return ky[:, None] * kx[None, :]
