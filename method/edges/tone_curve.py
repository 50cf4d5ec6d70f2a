"""The tone curve not assumed: choose an image's display curve from its edges.

A lens blurs linear radiance with a point-symmetric PSF, so across a straight step the linear
profile p(t) along the edge normal is point-symmetric about the edge's centre c:
p(c + t) + p(c − t) = p(+∞) + p(−∞) for every t, whatever the PSF's shape (disk, polygon,
Gaussian) and size. Decoding a display image with the wrong tone curve g bends that profile by
g⁻¹∘g_true, which breaks the symmetry in proportion to the edge's contrast. :func:`fit_encoding`
decodes the strongest edges' profiles with each candidate curve (the display-light entries of
:data:`method.luma.ENCODINGS`), fits the best point-symmetric profile to each (centre and mid level
free) and keeps the curve of the smallest median residual, normalised by each edge's contrast.

:data:`INPUT_ENCODINGS` is what :func:`method.pipeline.estimate_defocus_map` accepts: every encoding
of :data:`method.luma.ENCODINGS`, plus ``"auto"`` (a display image of unknown curve: fitted).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..luma import ENCODINGS, LUMA_WEIGHTS, decode, luminance
from ..registry import Entry, Registry

__all__ = ["AUTO_ENCODING", "INPUT_ENCODINGS", "ToneCurveFit", "fit_encoding", "resolve_encoding"]

#: The ``encoding`` that asks for the curve to be fitted per image (:func:`fit_encoding`).
AUTO_ENCODING = "auto"

#: The encodings an input may declare: ``"auto"`` and every key of :data:`method.luma.ENCODINGS`.
INPUT_ENCODINGS = Registry("encoding", {
    AUTO_ENCODING: Entry(None, "display values of unknown tone curve: the curve is fitted per image from its "
                               "strongest edges (method.edges.tone_curve.fit_encoding)"),
    **{name: ENCODINGS.entry(name) for name in ENCODINGS},
})

#: Fewer usable edges than this: no fit, the sRGB curve is assumed (the camera default).
MIN_FIT_EDGES = 20
#: Another curve replaces sRGB (the camera default) only if its residual is below (1 − this) × sRGB's:
#: on sharp edges (σ ≲ 1 px) the curves' residuals differ by less than their noise.
SRGB_MARGIN = 0.2
#: Sample spacing along the edge normal, px.
_STEP = 0.25
#: Half-length of the sampled profile along the normal, px.
_REACH = 18.0
#: Profile half-widths R (px) an edge's window is rounded up to: about 2.5× its display spread + 1 px.
_WINDOWS = (2.0, 3.0, 4.5, 6.5, 9.0, 12.0)
#: Candidate centres: shifts of the display profile's centroid along the normal, ±6 px in steps of
#: _STEP (a tone curve moves the display profile off the linear profile's centre).
_SHIFTS = 24
#: Edge pixels sampled: at most this many × max_edges, those of largest display gradient.
_PRESELECT = 8

@dataclasses.dataclass(frozen=True)
class ToneCurveFit:
    """What :func:`fit_encoding` chose and why.

    Attributes
    ----------
    encoding : str
        The chosen key of :data:`method.luma.ENCODINGS`.
    residuals : dict str -> float
        Per candidate curve, the median over the edges of the point-symmetric fit's mean squared
        residual / contrast² (dimensionless); empty when too few edges were found.
    n_edges : int
        Edges the fit used.
    """

    encoding: str
    residuals: dict
    n_edges: int


def _edge_samples(gray, *, max_edges):
    """Strongest-contrast edges: (K, N) sample rows/columns along their normals, offsets u (px), windows (K,), centres (K,)."""
    from scipy import ndimage
    from skimage.feature import canny

    gy = ndimage.gaussian_filter(gray, 1.0, order=(1, 0))
    gx = ndimage.gaussian_filter(gray, 1.0, order=(0, 1))
    mag = np.hypot(gx, gy)
    edges = canny(gray, sigma=1.0) & (mag > 0)
    u = np.arange(-round(_REACH / _STEP), round(_REACH / _STEP) + 1) * _STEP
    ys, xs = np.nonzero(edges)
    if ys.size > _PRESELECT * max_edges:  # the strongest gradients first: bounds the cost on large images
        top = np.argsort(-mag[ys, xs], kind="stable")[:_PRESELECT * max_edges]
        ys, xs = ys[top], xs[top]
    ny, nx = gy[ys, xs] / mag[ys, xs], gx[ys, xs] / mag[ys, xs]
    py = ys[:, None] + u[None, :] * ny[:, None]
    px = xs[:, None] + u[None, :] * nx[:, None]
    inside = np.all((py >= 0) & (py <= gray.shape[0] - 1) & (px >= 0) & (px <= gray.shape[1] - 1), axis=1)
    py, px = py[inside], px[inside]
    prof = ndimage.map_coordinates(gray, [py.ravel(), px.ravel()], order=1).reshape(py.shape)
    # the display profile's spread: centroid and std of |p'| within ±_WINDOWS[-1] of the edge pixel
    near = np.abs(u[1:] - _STEP / 2) <= _WINDOWS[-1]
    d = np.abs(np.diff(prof, axis=1))[:, near]
    um = (u[1:] - _STEP / 2)[near]
    tot = np.maximum(d.sum(axis=1), 1e-12)
    centre = (d * um).sum(axis=1) / tot
    spread = np.sqrt(np.maximum((d * (um - centre[:, None]) ** 2).sum(axis=1) / tot, 0.0))
    usable = 2.5 * spread + 1.0 <= _WINDOWS[-1]  # wider edges: the window would not reach the plateaus
    py, px, prof, centre, spread = py[usable], px[usable], prof[usable], centre[usable], spread[usable]
    window = np.asarray(_WINDOWS)[np.searchsorted(_WINDOWS, 2.5 * spread + 1.0)]
    j = np.clip(np.round((centre[:, None] + np.stack([-window, window], 1)) / _STEP).astype(int) + u.size // 2,
                0, u.size - 1)
    contrast = np.abs(np.take_along_axis(prof, j, axis=1) @ np.array([-1.0, 1.0]))
    keep = np.argsort(-contrast, kind="stable")[:max_edges]
    return py[keep], px[keep], u, window[keep], centre[keep]


def _bilinear_linear_luminance(rgb, py, px, encoding):
    """Rec. 709 luminance of ``rgb`` decoded by ``encoding``, bilinearly interpolated at (py, px): (K, N)."""
    h, w = rgb.shape[:2]
    y0 = np.clip(np.floor(py).astype(np.int64), 0, h - 2)
    x0 = np.clip(np.floor(px).astype(np.int64), 0, w - 2)
    fy, fx = py - y0, px - x0
    out = np.zeros(py.shape)
    weights = np.asarray(LUMA_WEIGHTS)
    for dy, dx, wgt in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        out += wgt * (decode(rgb[y0 + dy, x0 + dx], encoding) @ weights)
    return out


def _symmetry_residual(profiles, u, window, centre):
    """Per profile: min over centres c of mean((p(c+t) + p(c−t) − 2m)²) / (p(c+R) − p(c−R))², t in (0, R]."""
    best = np.full(profiles.shape[0], np.inf)
    j_centre = np.round(centre / _STEP).astype(int) + u.size // 2
    for r in np.unique(window):
        rows = np.nonzero(window == r)[0]
        k = np.arange(1, int(round(r / _STEP)) + 1)
        p = profiles[rows]
        for s in range(-_SHIFTS, _SHIFTS + 1):
            j = np.clip(j_centre[rows] + s, k[-1], u.size - 1 - k[-1])[:, None]
            hi, lo = np.take_along_axis(p, j + k, axis=1), np.take_along_axis(p, j - k, axis=1)
            sums = hi + lo
            contrast = (hi[:, -1] - lo[:, -1]) ** 2
            res = np.mean((sums - sums.mean(axis=1, keepdims=True)) ** 2, axis=1) / np.maximum(contrast, 1e-12)
            best[rows] = np.minimum(best[rows], res)
    return best


def fit_encoding(image, *, candidates=None, max_edges: int = 400) -> ToneCurveFit:
    """The display tone curve under which the image's strongest edges are most point-symmetric.

    Parameters
    ----------
    image : ndarray, HxWx3 or HxW, float in [0, 1]
        Display values of unknown tone curve. Sides ≥ 8 px.
    candidates : sequence of str, optional, keyword-only
        Keys of :data:`method.luma.ENCODINGS` to choose among; default every display-light one
        ("srgb", "gamma1.8", "gamma2.2", "filmic").
    max_edges : int, keyword-only
        Edges used: those of largest display contrast across their window (≥ 1).

    Returns
    -------
    ToneCurveFit
        ``encoding`` "srgb" (the camera default) when fewer than :data:`MIN_FIT_EDGES` usable edges exist.

    Raises
    ------
    ValueError
        A bad image, an unknown candidate or ``max_edges`` < 1.

    Notes
    -----
    1. Canny edges (scikit-image, σ 1 px) of the display luma; normals from Gaussian derivatives
       (σ 1 px); at most 8 × ``max_edges`` of them, those of largest gradient. Per edge, the display profile along the normal (±18 px) gives a centre (centroid
       of |p′|) and a window R ≈ 2.5× the spread of |p′| + 1 px (2–12 px; wider edges are not
       used); keep the ``max_edges`` of largest display contrast between the window's ends.
    2. Per candidate g: the profile of the linear luminance (each pixel's RGB decoded by g, Rec. 709
       weights), bilinearly interpolated at 0.25 px steps along the normal.
    3. Per profile: the point-symmetric fit p(c + t) + p(c − t) = 2m for t in (0, R], with the mean
       m and centre c (±6 px around the display centre) free; its mean squared residual over the
       squared contrast p(c + R) − p(c − R).
    4. The candidate of the smallest median residual wins, except that sRGB is kept unless the
       winner's residual is below (1 − :data:`SRGB_MARGIN`) × sRGB's.
    """
    from ..validation import validate_image

    image = validate_image(image)
    names = [n for n in ENCODINGS if ENCODINGS[n] == "display"] if candidates is None else \
        ENCODINGS.check_all(candidates, what="candidate encoding")
    if isinstance(max_edges, bool) or not isinstance(max_edges, (int, np.integer)) or max_edges < 1:
        raise ValueError(f"max_edges={max_edges!r} is invalid; allowed: an int >= 1")
    rgb = image if image.ndim == 3 else np.repeat(image[..., None], 3, axis=2)
    py, px, u, window, centre = _edge_samples(luminance(rgb), max_edges=int(max_edges))
    if py.shape[0] < MIN_FIT_EDGES:
        return ToneCurveFit(encoding="srgb", residuals={}, n_edges=int(py.shape[0]))
    residuals = {n: float(np.median(_symmetry_residual(_bilinear_linear_luminance(rgb, py, px, n), u, window, centre)))
                 for n in names}
    best = min(residuals, key=residuals.get)
    if "srgb" in residuals and residuals[best] > (1.0 - SRGB_MARGIN) * residuals["srgb"]:
        best = "srgb"
    return ToneCurveFit(encoding=best, residuals=residuals, n_edges=int(py.shape[0]))


def resolve_encoding(image, encoding: str) -> str:
    """``encoding`` itself, or for ``"auto"`` the curve :func:`fit_encoding` chooses for ``image``.

    Raises
    ------
    ValueError
        ``encoding`` not a key of :data:`INPUT_ENCODINGS` (the message lists them).
    """
    INPUT_ENCODINGS.check(encoding, what="encoding")
    return fit_encoding(image).encoding if encoding == AUTO_ENCODING else encoding
