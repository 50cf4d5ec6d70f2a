"""Propagation of the sparse blur measure to a dense defocus map, Eq. (4) (Sec. 4, after Levin et al. 2004).

Energy (Eq. 4a–4c)::

    E(B) = Σ_p (B(p) − Σ_{q∈N(p)} w_pq B(q))²  +  Σ_p α_p (B(p) − BM(p))²
    w_pq ∝ Σ_{i∈RGB} exp(−(C_i(p) − C_i(q))² / (2 σ_ip²)),   Σ_q w_pq = 1

with ``α_p = alpha`` at edge pixels (finite BM) and 0 elsewhere. Its minimiser solves the sparse
symmetric positive (semi-)definite system ``(LᵀL + diag α) B = diag(α) BM`` with ``L = I − W``.

Reading of the paper's "window size 7×7" (the README paragraph says the same)
---------------------------------------------------------------------------
The paper attaches "window" to σ_ip: "σ_p is the standard deviation of the intensities and colors of
neighboring pixels in a window around p. The window size used is 7×7." It never gives the size of
the affinity neighbourhood N(p); the method it follows (Levin et al. 2004) uses the 8 neighbours of a
3×3 window. We therefore expose two parameters:

* ``window`` (default 7): side of the square window, centred on p and clipped to the image, over
  which the per-channel standard deviation σ_ip is computed (p itself included);
* ``neighborhood`` (default 3): side of the square N(p) (p excluded, clipped to the image).

``neighborhood=7`` is the other reading ("one 7×7 window defines both"); it is supported by every
solver, but LᵀL then has a 13×13 stencil (169 non-zeros per row, ≈ 2 GB at 1 MP), so the exact
solver is only feasible on small images; the fast solver stays matrix-free at the fine level.

Where each part lives (as pymatting splits laplacian / solver / preconditioner)
------------------------------------------------------------------------------
* :mod:`method.propagation_system` — the equation: affinities of Eq. (4c)
  (:func:`~method.propagation_system.colorization_weights`), L = I − W
  (:func:`~method.propagation_system.colorization_matrix`), the normal equations
  (:func:`~method.propagation_system.normal_equations`) and the coarse re-discretisation;
* :mod:`method.propagation_solvers` — solvers of the assembled system (:data:`PROPAGATION_SOLVERS`:
  AMG-PCG, direct) and the coarse level of the coarse mode (AMG hierarchy + V-cycle, or LU);
* :mod:`method.propagation_matrix_free` — the matrix-free preconditioned CGs at full resolution and
  their numba kernels (two-level: Jacobi + coarse-grid correction; Jacobi alone);
* this module — the driver :func:`propagate_defocus` (validation, exact or coarse mode, refinement).

Solving (see :func:`propagate_defocus`, Notes)
----------------------------------------------
Images up to 256² px are solved exactly (pyamg smoothed-aggregation multigrid + CG). Larger ones are
solved on a grid coarsened by a power of two, at least 4× (4× at 512² and 1 MP, 8× at the photo
tools' 1.5 MP), to a relative residual of 1e-3; its bilinearly interpolated solution starts a CG on
the exact full-resolution system, preconditioned by Jacobi plus a coarse-grid correction through the
same coarse hierarchy (two-level, matrix-free fine level), 20·s iterations. On the astronaut photo
the default is 0.0024 px RMS / 0.012 px p99 (512²) and 0.015 px RMS / 0.07 px p99 (1024²) from the
exact solve (:func:`propagate_defocus`, Notes).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import ndimage

from .propagation_matrix_free import jacobi_pcg, two_level_pcg
from .propagation_solvers import COARSE_SETUPS, PROPAGATION_SOLVERS
from .propagation_system import (
    _assemble,
    _coarse_problem,
    _data_term,
    _padded_weights,
    _validate_options,
    colorization_matrix,
    colorization_weights,
    normal_equations,
)
from .validation import check_positive, validate_propagation_inputs

__all__ = [
    "PROPAGATION_REFINEMENTS",
    "PROPAGATION_SOLVERS",
    "colorization_matrix",
    "colorization_weights",
    "normal_equations",
    "propagate_defocus",
]


#: Largest number of pixels solved at full resolution by ``downsample="auto"``; bigger images are
#: solved on a grid coarsened by a power of two (at least :data:`AUTO_MIN_COARSENING`) to at most
#: this many pixels, then refined.
AUTO_MAX_COARSE_PIXELS = 256 * 256

#: Smallest coarsening factor of ``downsample="auto"``'s coarse mode. With the unrolled 3×3 kernels
#: a full-resolution CG iteration costs less than a V-cycle on a 256² coarse grid, so at 512² the
#: 4× grid with 80 iterations is both faster and closer to the exact solve than the 2× grid with 40
#: (astronaut, paper preset: 0.0024 vs 0.0117 px RMS, about half the CPU time; 1 MP keeps 4×).
AUTO_MIN_COARSENING = 4

#: Relative residual of the coarse solve of the coarse mode when ``coarse_tol`` is None (or ``tol``
#: if that is looser). The refinement removes what it leaves: on the astronaut photo (paper preset)
#: 1e-3 instead of 1e-6 moves the default by 0.0149 vs 0.0140 px RMS from the exact solve at 1024²
#: and saves ~37 of the ~40 AMG-CG iterations on the 256² coarse grid.
DEFAULT_COARSE_TOL = 1e-3

#: Default number of full-resolution CG iterations after a coarse solve, per refinement (keys of
#: :data:`PROPAGATION_REFINEMENTS`), per unit of the coarsening factor s: the two-level
#: preconditioner's condition number grows like s² (the band of frequencies between the coarse grid
#: and the Jacobi smoother widens), so CG needs ∝ s iterations for the same accuracy. Two-level:
#: 20·s, i.e. 80 at 512² and 1024² (s = 4), which leave the astronaut photo ≈ 0.002 / 0.015 px
#: RMS and 0.01 / 0.07 px p99 from the exact solve (see :func:`propagate_defocus`, Notes). Jacobi:
#: the earlier fixed 60 iterations (0.08 / 0.15 px RMS).
DEFAULT_REFINE_ITERATIONS = {"two_level": (20, "per_factor"), "jacobi": (60, "fixed")}


def _default_refine_iterations(refinement: str, s: int) -> int:
    n, kind = DEFAULT_REFINE_ITERATIONS[refinement]
    return n * s if kind == "per_factor" else n


def _refine_two_level(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol):
    return two_level_pcg(weights, offs, a_diag, rhs, x0, coarse=coarse, s=s,
                                      coarse_shape=coarse_shape, maxiter=maxiter, tol=tol)


def _refine_jacobi(weights, offs, a_diag, rhs, x0, *, coarse, s, coarse_shape, maxiter, tol):
    return jacobi_pcg(weights, offs, a_diag, rhs, x0, maxiter=maxiter, tol=tol)


#: Full-resolution refinements after a coarse solve (``downsample`` > 1), chosen with
#: ``refinement="..."``: ``"two_level"`` (default) = CG preconditioned by Jacobi + the coarse-grid
#: correction (:func:`method.propagation_matrix_free.two_level_pcg`); ``"jacobi"`` = the earlier, cheaper Jacobi-only
#: CG (:func:`method.propagation_matrix_free.jacobi_pcg`), which leaves the coarse grid's smooth error almost intact.
PROPAGATION_REFINEMENTS: dict[str, Callable] = {
    "two_level": _refine_two_level,
    "jacobi": _refine_jacobi,
}


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------
def _auto_downsample(h, w, max_pixels, min_factor=AUTO_MIN_COARSENING):
    """1 when H·W ≤ ``max_pixels``, else the smallest power of two ≥ ``min_factor`` bringing the coarse
    grid under ``max_pixels`` (at most min(H, W)/2, so the coarse grid keeps ≥ 2 px per side)."""
    if h * w <= max_pixels or min(h, w) < 4:
        return 1
    s = min_factor
    while (-(-h // s)) * (-(-w // s)) > max_pixels:
        s *= 2
    while s > min(h, w) // 2:
        s //= 2
    return s


def _upsample(coarse, s, shape):
    """Bilinear interpolation of a block-centred coarse map onto the fine pixel centres."""
    h, w = shape
    ys = (np.arange(h) + 0.5) / s - 0.5
    xs = (np.arange(w) + 0.5) / s - 0.5
    return ndimage.map_coordinates(coarse, np.meshgrid(ys, xs, indexing="ij"), order=1, mode="nearest")


def propagate_defocus(sparse_sigma, reference, *, alpha=0.5, window=7, neighborhood=3, eps=1e-6,
                      regularization=1e-6, tol=1e-6, solver="amg_pcg", downsample="auto",
                      refinement="two_level", refine_iterations=None,
                      max_coarse_pixels=AUTO_MAX_COARSE_PIXELS, confidence=None, coarse_tol=None) -> np.ndarray:
    """Dense defocus map B minimising Eq. (4), from sparse blur σ at edge pixels.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels (BM, e.g. after Eq. 3); NaN at every other pixel.
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image C of Eq. (4c) (the RGB input photo).
    alpha : float, keyword-only
        Data weight α_p at edge pixels (paper: 0.5; 0 elsewhere). > 0.
    window : int, keyword-only
        Odd side, px, of the σ_ip window (paper: "7×7"; see the module docstring).
    neighborhood : int, keyword-only
        Odd side, px, of N(p) (default 3 as Levin et al.; 7 = "7×7 defines both").
    eps : float, keyword-only
        Floor on σ_ip², image units².
    regularization : float, keyword-only
        λ/α of the guard term λ·Σ_p (B(p) − mean BM)² that makes the system positive definite when a
        region has no edge pixel and is cut off by strong colour edges (default 1e-6: it moves a
        well-determined map by ~1e-6 relative). 0 disables it.
    tol : float, keyword-only
        Relative residual ‖A B − rhs‖ / ‖rhs‖ at which the iterative solves stop.
    solver : str, keyword-only
        Key of :data:`PROPAGATION_SOLVERS`: ``"amg_pcg"`` (pyamg smoothed aggregation + CG) or
        ``"direct"`` (sparse LU; small images). With ``downsample`` > 1 it solves the coarse system
        and provides the coarse-grid correction of the two-level refinement (one V-cycle / LU solve).
    downsample : int or "auto", keyword-only
        1 = exact: solve the full-resolution system with ``solver`` to ``tol``. s > 1 (power of two or
        any integer): solve the problem on an s-times coarser grid with ``solver``, interpolate
        bilinearly and refine with ``refine_iterations`` iterations of preconditioned CG on the exact
        full-resolution system (approximate; see Notes). ``"auto"`` (default): 1 when
        H·W ≤ ``max_coarse_pixels``, else the smallest power of two ≥ :data:`AUTO_MIN_COARSENING` (4)
        that brings the coarse grid under it (4× at 512² and 1024², 8× at the photo tools' 1.5 MP).
    refinement : str, keyword-only
        Key of :data:`PROPAGATION_REFINEMENTS` (used when s > 1): ``"two_level"`` (default; CG
        preconditioned by Jacobi + the coarse-grid correction) or ``"jacobi"`` (the earlier, cheaper
        Jacobi-only CG, ≈ 20× further from the exact solve on photos).
    refine_iterations : int or None, keyword-only
        Full-resolution CG iterations after a coarse solve (≥ 0; they stop earlier once the relative
        residual reaches ``tol``). None: :data:`DEFAULT_REFINE_ITERATIONS` of ``refinement``
        (20·s for ``"two_level"`` — 40 at s = 2, 80 at s = 4 —, 60 for ``"jacobi"``).
    max_coarse_pixels : int, keyword-only
        Pixel budget of the ``"auto"`` coarse grid.
    coarse_tol : float or None, keyword-only
        Relative residual at which the coarse solve of the coarse mode (s > 1) stops; None:
        max(``tol``, :data:`DEFAULT_COARSE_TOL` = 1e-3). The refinement removes most of what the
        looser coarse solve leaves (see Notes).
    confidence : ndarray, HxW, float in [0, 1], or None, keyword-only
        Beyond the paper: per-edge confidence c_p, so α_p = alpha·c_p at edge pixels (None: the
        paper's α_p = alpha). Ignored off edges.

    Returns
    -------
    ndarray, HxW, float64
        Dense blur σ, px. Not clipped (the quadratic smoothness can overshoot slightly; the pipeline
        clips to [0, max_sigma]). All zeros when no pixel is finite in ``sparse_sigma``.

    Raises
    ------
    ValueError
        Shapes disagree, NaN/Inf in the reference, Inf or negative σ, bad options.

    Notes
    -----
    1. Affinities w_pq (Eq. 4c) with σ_ip from a ``window``-side box and N(p) a ``neighborhood``-side
       box (:func:`method.propagation_system.colorization_weights`); L = I − W.
    2. α_p = alpha where BM is finite; system (LᵀL + diag α + λI) B = α·BM + λ·mean(BM), λ = regularization·alpha.
    3. Exact mode (``downsample=1``; ``"auto"`` up to ``max_coarse_pixels``): assemble and solve with
       ``solver`` (AMG-PCG to ``tol``).
    4. Coarse mode (s > 1): guide block-averaged over s×s blocks; BM_c = mean of the block's edge
       values; α_c = s²·Σ_block α_p — for a smooth map, (L_c B)² is s⁴ times (L B)² on s⁻² as many
       pixels, so the smoothness energy grows by s² and α is scaled alike to keep their ratio.
       Build the coarse solver once (AMG hierarchy or LU), solve the coarse Eq. (4) to ``coarse_tol``
       (1e-3 by default) and interpolate bilinearly (P) to get the start map.
    5. Refinement (``refinement="two_level"``): ``refine_iterations`` iterations of CG on the exact
       full-resolution system (matrix-free, numba, float64 vectors and scalars, affinities stored in
       float32: the map moves by < 1e-6 px against float64), preconditioned by
       M⁻¹ = D⁻¹ + s²·P Ã_c⁻¹ Pᵀ — Jacobi for the oscillatory error plus a coarse-grid correction
       (restriction Pᵀ, one V-cycle of the coarse hierarchy, prolongation P) for the smooth error
       the Jacobi-only CG could not remove (:func:`method.propagation_matrix_free.two_level_pcg`). Cost O(H·W) per
       iteration plus one V-cycle on the (fixed-size) coarse grid; 20·s iterations by default.
       The 3×3 neighbourhood has unrolled kernels (bit-identical to the generic ones, ~5–8× faster).
       Error of the default against the exact solve on the astronaut photo (paper preset's
       measures; ``repro.bench`` records it): 0.0024 px RMS / 0.012 px p99 / 0.039 px max at 512²
       (coarse 4×, 80 iterations) and 0.0149 / 0.070 / 0.19 px at 1024² (coarse 4×, 80
       iterations); before (2× at 512², coarse solve to ``tol``) 0.0117 / 0.070 / 0.13 and
       0.0140 / 0.066 / 0.16 px. The Jacobi-only refinement (``refinement="jacobi"``, 60
       iterations) leaves 0.083 / 0.49 / 0.88 and 0.152 / 0.73 / 1.18 px.
       ``tests/test_propagation.py`` bounds the error on a 320² synthetic image.
    6. Determinism: the AMG setup draws no random numbers (:data:`AMG_PROLONGATION_SMOOTHER`) and
       runs with single-threaded BLAS; the numba kernels are row-parallel without shared writes and
       add per-row partial sums in row order; the coarse-grid correction is single-threaded. Same
       inputs give the same bytes in any process and for any thread count; NumPy's global RNG is
       neither used nor reseeded.
    """
    sparse_sigma, ref = validate_propagation_inputs(sparse_sigma, reference, min_side=2)
    window, neighborhood, eps, alpha, regularization = _validate_options(
        window, neighborhood, eps, alpha, regularization)
    if solver not in PROPAGATION_SOLVERS:
        raise ValueError(f"solver={solver!r} is unknown; allowed: {sorted(PROPAGATION_SOLVERS)}")
    tol = check_positive("tol", tol)
    if not tol < 1:
        raise ValueError(f"tol={tol!r} is invalid; allowed: 0 < tol < 1")
    coarse_tol = max(tol, DEFAULT_COARSE_TOL) if coarse_tol is None else check_positive("coarse_tol", coarse_tol)
    if not coarse_tol < 1:
        raise ValueError(f"coarse_tol={coarse_tol!r} is invalid; allowed: None or 0 < coarse_tol < 1")
    if not isinstance(refinement, str) or refinement not in PROPAGATION_REFINEMENTS:
        raise ValueError(f"refinement={refinement!r} is unknown; allowed: {sorted(PROPAGATION_REFINEMENTS)}")
    if refine_iterations is not None and (
            isinstance(refine_iterations, bool) or not isinstance(refine_iterations, (int, np.integer)) or refine_iterations < 0):
        raise ValueError(f"refine_iterations={refine_iterations!r} is invalid; allowed: None or integer >= 0")
    if isinstance(max_coarse_pixels, bool) or not isinstance(max_coarse_pixels, (int, np.integer)) or max_coarse_pixels < 16:
        raise ValueError(f"max_coarse_pixels={max_coarse_pixels!r} is invalid; allowed: integer >= 16")
    h, w = sparse_sigma.shape
    if downsample == "auto":
        s = _auto_downsample(h, w, int(max_coarse_pixels))
    elif (isinstance(downsample, (int, np.integer)) and not isinstance(downsample, bool)
          and (downsample == 1 or 2 <= downsample <= min(h, w) // 2)):
        s = int(downsample)
    else:
        raise ValueError(f"downsample={downsample!r} is invalid; allowed: 'auto' or integer in [1, min(H, W)/2]")

    if refine_iterations is None:
        refine_iterations = _default_refine_iterations(refinement, s)

    if confidence is not None:
        confidence = np.asarray(confidence, dtype=np.float64)
        if confidence.shape != (h, w):
            raise ValueError(f"confidence has shape {confidence.shape}, expected {(h, w)}")
        cf = confidence[np.isfinite(sparse_sigma)]
        if not np.all(np.isfinite(cf)) or (cf.size and (cf.min() < 0 or cf.max() > 1)):
            raise ValueError("confidence must be finite and in [0, 1] at edge pixels")
    edge = np.isfinite(sparse_sigma)
    if not edge.any():
        return np.zeros((h, w))
    fill = float(np.mean(sparse_sigma[edge]))
    if np.ptp(sparse_sigma[edge]) == 0:
        return np.full((h, w), fill)  # constant data: B = const solves Eq. (4) exactly (L·1 = 0)

    solve = PROPAGATION_SOLVERS[solver]
    if s == 1:
        L = colorization_matrix(ref, window=window, neighborhood=neighborhood, eps=eps)
        a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization, confidence)
        A = _assemble(L, a, lam)
        x0 = np.full(h * w, fill)
        return solve(A, rhs, x0=x0, tol=tol).reshape(h, w)

    # --- coarse solve + full-resolution refinement --------------------------------------------
    ref_c, bm_c, a_c = _coarse_problem(sparse_sigma, ref, s, alpha, confidence)
    hc, wc = bm_c.shape
    L_c = colorization_matrix(ref_c, window=window, neighborhood=neighborhood, eps=eps)
    lam_c = regularization * alpha * s * s
    target = float(np.sum(a_c * bm_c) / np.sum(a_c))
    A_c = _assemble(L_c, a_c.ravel(), lam_c)
    del L_c
    rhs_c = (a_c * bm_c).ravel() + lam_c * target
    coarse_level = COARSE_SETUPS[solver](A_c)
    coarse = coarse_level.solve(rhs_c, np.full(hc * wc, target), coarse_tol).reshape(hc, wc)
    x0 = _upsample_crop(coarse, s, (h, w))
    if refine_iterations == 0:
        return x0
    weights, offs = _padded_weights(ref, window, neighborhood, eps)
    a, rhs, lam, _ = _data_term(sparse_sigma, alpha, regularization, confidence)
    a_diag = (a + lam).reshape(h, w)
    x, _res = PROPAGATION_REFINEMENTS[refinement](
        weights, offs, a_diag, rhs.reshape(h, w), x0, coarse=coarse_level, s=s, coarse_shape=(hc, wc),
        maxiter=int(refine_iterations), tol=tol)
    return x


def _upsample_crop(coarse, s, shape):
    h, w = shape
    hp, wp = coarse.shape[0] * s, coarse.shape[1] * s
    return _upsample(coarse, s, (hp, wp))[:h, :w]
