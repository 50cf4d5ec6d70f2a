"""Propagation of the sparse blur measure to a dense defocus map, Eq. (4) (Sec. 4, after Levin et al. 2004).

Energy (Eq. 4a–4c)::

    E(B) = Σ_p (B(p) − Σ_{q∈N(p)} w_pq B(q))²  +  Σ_p α_p (B(p) − BM(p))²
    w_pq ∝ Σ_{i∈RGB} exp(−(C_i(p) − C_i(q))² / (2 σ_ip²)),   Σ_q w_pq = 1

with ``α_p = alpha`` at edge pixels (finite BM) and 0 elsewhere. Its minimiser solves the sparse
symmetric positive (semi-)definite system ``(LᵀL + diag α) B = diag(α) BM`` with ``L = I − W``.

Reading of the paper's "window size 7×7" (also in docs/choices.md)
-----------------------------------------------------------------
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
* :mod:`method.propagation.system` — the equation: affinities of Eq. (4c)
  (:func:`~method.propagation.system.colorization_weights`), L = I − W
  (:func:`~method.propagation.system.colorization_matrix`), the normal equations
  (:func:`~method.propagation.system.normal_equations`);
* :mod:`method.propagation.solvers` — solvers of the assembled system (:data:`PROPAGATION_SOLVERS`:
  AMG-PCG, direct) and the coarse level of the coarse mode (AMG hierarchy + V-cycle, or LU);
* :mod:`method.propagation.matrix_free` — the matrix-free preconditioned CGs at full resolution and
  their numba kernels (two-level: Jacobi + coarse-grid correction);
* this module — the driver :func:`propagate_defocus` (validation, exact or coarse mode, refinement).

Solving (see :func:`propagate_defocus`, Notes)
----------------------------------------------
Images up to 2¹⁵ px (≈ 181²; the small renders) are solved exactly (pyamg smoothed-aggregation
multigrid + CG). Larger ones are solved on a grid coarsened by a power of two, at least 4× (4× up to
≈ 362², 8× at 512², 1 MP and the photo tools' 1.5 MP, 16× at 4 MP), with the *Galerkin* coarse operator PᵀAP of the
exact full-resolution system (:mod:`method.propagation.galerkin`); the interpolated coarse solution
starts a CG on the exact full-resolution system, preconditioned by Jacobi plus a coarse-grid
correction through the same coarse hierarchy (two-level, matrix-free fine level), max(⌈2.5·s⌉, 20)
iterations. On the astronaut photo the default is 0.016 px RMS / 0.069 px p99 (512², 8×) and 0.019 px
RMS / 0.082 px p99 (1024², 8×) from the exact solve with the paper's measures (:func:`propagate_defocus`,
Notes). The measurements behind each constant below and the history of the default are in
docs/performance.md ("Propagation solver history").
"""

from __future__ import annotations

import dataclasses
import math
import numpy as np

from .galerkin import galerkin_coarse_operator, prolong, restrict
from .matrix_free import two_level_pcg
from .solvers import COARSE_SETUPS, PROPAGATION_SOLVERS
from .system import (
    assemble_system,
    data_term,
    padded_weights,
    validate_options,
    colorization_matrix,
    colorization_weights,
    normal_equations,
)
from ..validation import check_positive, validate_propagation_inputs
from ..registry import Entry, Registry

__all__ = [
    "PROPAGATION_REFINEMENTS",
    "PROPAGATION_SOLVERS",
    "colorization_matrix",
    "colorization_weights",
    "normal_equations",
    "propagate_defocus",
]


#: Largest number of pixels solved exactly at full resolution by ``downsample="auto"`` (2¹⁵, ≈ 181²:
#: the small renders, 160×120, and the 128² hash test stay exact); bigger images take the coarse mode,
#: which is an order of magnitude faster at 256² (docs/performance.md).
AUTO_MAX_EXACT_PIXELS = 2 ** 15

#: Largest coarse grid of ``downsample="auto"``'s coarse mode, px: the smallest power of two
#: ≥ 8 bringing the grid under it once 4× is too big (:data:`AUTO_MAX_COARSE_PIXELS_AT_4X`): 8× from
#: ≈ 362² to 1448² (512², 1 MP and the photo tools' 1.5 MP), 16× at 4 MP. Why 2¹⁵: at 1 MP the 8×
#: grid's V-cycle is cheap and strong enough, 4× is slower per iteration and no closer, and at 16× the
#: Jacobi part cannot cover the wider band of frequencies (several times farther from the exact solve;
#: docs/performance.md).
AUTO_MAX_COARSE_PIXELS = 2 ** 15

#: Largest coarse grid at the smallest factor, 4×, px (2¹³: up to ≈ 362²); beyond it "auto" starts at
#: 8×. At 4× the coarse grid grows with the image, and so do its V-cycle's cost and its weakness as
#: the coarse inverse: at 512² the 8× grid is both faster and, for robust's sparser,
#: confidence-weighted data term, closer to the exact solve; at 256² 4× is closer at the same cost
#: (measurements in docs/performance.md).
AUTO_MAX_COARSE_PIXELS_AT_4X = 2 ** 13

#: Smallest coarsening factor of ``downsample="auto"``'s coarse mode: 2× has a 4× costlier V-cycle,
#: needs no fewer iterations and ends farther from the exact solve (docs/performance.md).
AUTO_MIN_COARSENING = 4

#: Relative residual of the coarse solve of the coarse mode when ``coarse_tol`` is None (or ``tol``
#: if that is looser). The refinement removes what the looser coarse solve leaves (the distance from
#: the exact solve grows by < 0.001 px RMS against 1e-5) and most of the coarse AMG-CG iterations are
#: saved (docs/performance.md).
DEFAULT_COARSE_TOL = 1e-3

#: Default number of full-resolution CG iterations after a coarse solve, per refinement (keys of
#: :data:`PROPAGATION_REFINEMENTS`): max(⌈k·s⌉, floor) for the coarsening factor s. The two-level
#: preconditioner's condition number grows with s (the band of frequencies between the coarse grid
#: and the Jacobi smoother widens), so CG needs ∝ s iterations for the same accuracy; the floor
#: covers small s. Galerkin: max(⌈2.5·s⌉, 20) — 20 at 4× and 8× (256² to 1.5 MP), 40 at 16×. On the
#: astronaut photo (``benchmarks/propagation_accuracy.py``; RMS / p99 px from the exact solve) at 512²
#: (8×) paper 0.016 / 0.069, robust 0.032 / 0.15; at 1024² (8×) paper 0.019 / 0.082, robust 0.026 /
#: 0.092 (the targets: ≤ 0.03 px RMS, ≤ 0.15 px p99). Earlier refinements and their distances:
#: docs/performance.md.
DEFAULT_REFINE_ITERATIONS = {"galerkin": (2.5, 20)}


def _default_refine_iterations(refinement: str, s: int) -> int:
    per_factor, floor = DEFAULT_REFINE_ITERATIONS[refinement]
    return max(int(math.ceil(per_factor * s)), floor)


@dataclasses.dataclass(frozen=True)
class _FineSystem:
    """The full-resolution Eq. (4) system in matrix-free form, and the problem it came from."""

    sparse_sigma: np.ndarray   # H×W, px, NaN off edges
    ref: np.ndarray            # H×W×C guide
    weights: np.ndarray        # (K, H+2r, W+2r) float32 affinities (zero padding)
    offs: np.ndarray           # (K, 2) offsets
    a_diag: np.ndarray         # H×W data term α_p + λ
    rhs: np.ndarray            # H×W right-hand side α·BM + λ·mean(BM)
    fill: float                # mean of the measures (start value)


def _galerkin_start(fine, s, *, solver, coarse_tol, **_):
    """Galerkin coarse operator PᵀAP of the fine system; x0 = P (PᵀAP)⁻¹ Pᵀ rhs (to ``coarse_tol``)."""
    h, w = fine.a_diag.shape
    coarse_shape = (-(-h // s), -(-w // s))
    level = COARSE_SETUPS[solver](galerkin_coarse_operator(
        fine.weights, fine.offs, fine.a_diag, s=s, coarse_shape=coarse_shape))
    rhs_c = restrict(fine.rhs, s=s, coarse_shape=coarse_shape)
    coarse = level.solve(rhs_c.ravel(), np.full(rhs_c.size, fine.fill), coarse_tol).reshape(coarse_shape)
    return prolong(coarse, s=s, shape=(h, w)), level, 1.0


#: Storage of the Galerkin refinement's CG vectors (scalars and per-row sums stay float64). float32
#: halves their memory traffic (the fine iterations are memory-bound) and moves the default map by
#: ≤ 1.2e-5 px against float64 vectors; round-off sets a floor near 5e-4 px RMS (docs/performance.md).
REFINE_VECTOR_DTYPE = np.float32


def _refine_galerkin(fine, x0, *, coarse, scale, s, coarse_shape, maxiter, tol):
    return two_level_pcg(fine.weights, fine.offs, fine.a_diag, fine.rhs, x0, coarse=coarse, s=s,
                         coarse_shape=coarse_shape, maxiter=maxiter, tol=tol, coarse_scale=scale,
                         vector_dtype=REFINE_VECTOR_DTYPE)


#: Coarse mode of :func:`propagate_defocus` (``downsample`` > 1), chosen with ``refinement="..."``:
#: name -> (start: coarse level + start map, refine: full-resolution CG).
#:
#: * ``"galerkin"`` (default): the coarse level is the Galerkin operator PᵀAP of the exact fine
#:   system (:func:`method.propagation.galerkin.galerkin_coarse_operator`), its solution
#:   interpolated starts a CG preconditioned by Jacobi + that coarse-grid correction
#:   (:func:`method.propagation.matrix_free.two_level_pcg`, c = 1).
#: Each entry's value refines the fine solution; its ``"start"`` hook builds the coarse start.
PROPAGATION_REFINEMENTS = Registry("propagation refinement", {
    "galerkin": Entry(_refine_galerkin, "Galerkin coarse operator, two-level PCG (default)",
                      hooks={"start": _galerkin_start}),
})


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------
def _auto_downsample(h, w, max_pixels, min_factor=AUTO_MIN_COARSENING, max_exact=AUTO_MAX_EXACT_PIXELS,
                     max_at_min=AUTO_MAX_COARSE_PIXELS_AT_4X):
    """1 when H·W ≤ ``max_exact``; else ``min_factor`` while that coarse grid has ≤ ``max_at_min`` px,
    else the smallest power of two ≥ 2·``min_factor`` bringing the coarse grid under ``max_pixels``
    (at most min(H, W)/2, so the coarse grid keeps ≥ 2 px per side)."""
    if h * w <= max_exact or min(h, w) < 4:
        return 1

    def cells(f):
        return (-(-h // f)) * (-(-w // f))

    s = min_factor
    if cells(s) > max_at_min:
        s *= 2
    while cells(s) > max_pixels:
        s *= 2
    while s > min(h, w) // 2:
        s //= 2
    return s


def propagate_defocus(sparse_sigma, reference, *, alpha=0.5, window=7, neighborhood=3, eps=1e-6,
                      regularization=1e-6, tol=1e-6, solver="amg_pcg", downsample="auto",
                      refinement="galerkin", refine_iterations=None,
                      max_coarse_pixels=AUTO_MAX_COARSE_PIXELS, confidence=None, coarse_tol=None,
                      max_confidence=1.0) -> np.ndarray:
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
        H·W ≤ :data:`AUTO_MAX_EXACT_PIXELS` (2¹⁵), else :data:`AUTO_MIN_COARSENING` (4) while
        that coarse grid has ≤ :data:`AUTO_MAX_COARSE_PIXELS_AT_4X` (2¹³) px, else the smallest power
        of two ≥ 8 that brings the coarse grid under ``max_coarse_pixels`` (4× at 256², 8× at 512²,
        1024² and the photo tools' 1.5 MP, 16× at 2048²).
    refinement : str, keyword-only
        Key of :data:`PROPAGATION_REFINEMENTS` (used when s > 1): ``"galerkin"`` (default; CG
        preconditioned by Jacobi + the Galerkin coarse-grid correction).
    refine_iterations : int or None, keyword-only
        Full-resolution CG iterations after a coarse solve (≥ 0; they stop earlier once the relative
        residual reaches ``tol``). None: :data:`DEFAULT_REFINE_ITERATIONS` of ``refinement``
        (max(⌈2.5·s⌉, 20) for ``"galerkin"``).
    max_coarse_pixels : int, keyword-only
        Pixel budget of the ``"auto"`` coarse grid (default :data:`AUTO_MAX_COARSE_PIXELS`, 2¹⁵).
    coarse_tol : float or None, keyword-only
        Relative residual at which the coarse solve of the coarse mode (s > 1) stops; None:
        max(``tol``, :data:`DEFAULT_COARSE_TOL` = 1e-3). The refinement removes most of what the
        looser coarse solve leaves (see Notes).
    confidence : ndarray, HxW, float in [0, 1], or None, keyword-only
        Beyond the paper: per-edge confidence c_p, so α_p = alpha·c_p at edge pixels (None: the
        paper's α_p = alpha). Ignored off edges.
    max_confidence : float, keyword-only
        Largest accepted c_p (default 1). Fused region measures (:mod:`method.propagation.cue_fusion`) stand for a
        window of pixels and may weigh more than one edge pixel; the pipeline raises it for them.

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
       box (:func:`method.propagation.system.colorization_weights`); L = I − W.
    2. α_p = alpha where BM is finite; system (LᵀL + diag α + λI) B = α·BM + λ·mean(BM), λ = regularization·alpha.
    3. Exact mode (``downsample=1``; ``"auto"`` up to :data:`AUTO_MAX_EXACT_PIXELS`): assemble and
       solve with ``solver`` (AMG-PCG to ``tol``).
    4. Coarse mode (s > 1), ``refinement="galerkin"`` (default): the coarse operator is the Galerkin
       projection A_c = PᵀAP of the exact full-resolution system with the bilinear interpolation P
       (:func:`method.propagation.galerkin.galerkin_coarse_operator`, formed matrix-free from the
       affinities, ~0.1 s at 1 MP). Build its solver once (AMG hierarchy or LU), solve
       A_c B_c = Pᵀ rhs to ``coarse_tol`` (1e-3 by default) and interpolate (P B_c) to get the
       start map.
    5. Refinement: ``refine_iterations`` iterations of CG on the exact full-resolution system
       (matrix-free, numba; affinities and vectors stored in float32 —
       scalars and sums in float64; the map moves by ≤ 1.2e-5 px against float64 vectors,
       :data:`REFINE_VECTOR_DTYPE`), preconditioned by M⁻¹ = D⁻¹ + c·P Ã_c⁻¹ Pᵀ — Jacobi for the
       oscillatory error plus a coarse-grid correction (restriction Pᵀ, one V-cycle of the coarse
       hierarchy, prolongation P) for the smooth error (c = 1 for the Galerkin operator;
       :func:`method.propagation.matrix_free.two_level_pcg`). Cost O(H·W) per
       iteration plus one V-cycle on the coarse grid; max(⌈2.5·s⌉, 20) iterations by default. The 3×3
       neighbourhood has unrolled kernels (bit-identical to the generic ones, ~5–8× faster).
       Error of the default against the exact solve on the astronaut photo
       (``benchmarks/propagation_accuracy.py`` records it; RMS / p99 px, 8× and 20 iterations at
       both sizes): paper's measures 0.016 / 0.069 at 512², 0.019 / 0.082 at 1024²; robust's
       (with their confidence) 0.032 / 0.15 and 0.026 / 0.092 (:data:`DEFAULT_REFINE_ITERATIONS`,
       :data:`AUTO_MAX_COARSE_PIXELS_AT_4X`; the other refinements' distances are in
       docs/performance.md). ``tests/test_propagation.py`` bounds the error on a 320² synthetic image.
    6. Determinism: the AMG setup draws no random numbers (:data:`AMG_PROLONGATION_SMOOTHER`) and
       runs with single-threaded BLAS; the numba kernels are row-parallel without shared writes and
       add per-row partial sums in row order; the coarse-grid correction is single-threaded. Same
       inputs give the same bytes in any process and for any thread count; NumPy's global RNG is
       neither used nor reseeded.
    """
    sparse_sigma, ref = validate_propagation_inputs(sparse_sigma, reference, min_side=2)
    window, neighborhood, eps, alpha, regularization = validate_options(
        window, neighborhood, eps, alpha, regularization)
    PROPAGATION_SOLVERS.check(solver, what="solver")
    tol = check_positive("tol", tol)
    if not tol < 1:
        raise ValueError(f"tol={tol!r} is invalid; allowed: 0 < tol < 1")
    coarse_tol = max(tol, DEFAULT_COARSE_TOL) if coarse_tol is None else check_positive("coarse_tol", coarse_tol)
    if not coarse_tol < 1:
        raise ValueError(f"coarse_tol={coarse_tol!r} is invalid; allowed: None or 0 < coarse_tol < 1")
    PROPAGATION_REFINEMENTS.check(refinement, what="refinement")
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
        if not np.all(np.isfinite(cf)) or (cf.size and (cf.min() < 0 or cf.max() > max_confidence)):
            raise ValueError(f"confidence must be finite and in [0, {max_confidence:g}] at edge pixels")
    edge = np.isfinite(sparse_sigma)
    if not edge.any():
        return np.zeros((h, w))
    fill = float(np.mean(sparse_sigma[edge]))
    if np.ptp(sparse_sigma[edge]) == 0:
        return np.full((h, w), fill)  # constant data: B = const solves Eq. (4) exactly (L·1 = 0)

    solve = PROPAGATION_SOLVERS[solver]
    if s == 1:
        L = colorization_matrix(ref, window=window, neighborhood=neighborhood, eps=eps)
        a, rhs, lam, _ = data_term(sparse_sigma, alpha, regularization, confidence)
        A = assemble_system(L, a, lam)
        x0 = np.full(h * w, fill)
        return solve(A, rhs, x0=x0, tol=tol).reshape(h, w)

    # --- coarse solve + full-resolution refinement --------------------------------------------
    start, refine = PROPAGATION_REFINEMENTS.hook(refinement, "start"), PROPAGATION_REFINEMENTS[refinement]
    weights, offs = padded_weights(ref, window, neighborhood, eps)
    a, rhs, lam, _ = data_term(sparse_sigma, alpha, regularization, confidence)
    fine = _FineSystem(sparse_sigma, ref, weights, offs, (a + lam).reshape(h, w), rhs.reshape(h, w), fill)
    x0, coarse_level, scale = start(fine, s, alpha=alpha, regularization=regularization,
                                    confidence=confidence, window=window, neighborhood=neighborhood,
                                    eps=eps, solver=solver, coarse_tol=coarse_tol)
    if refine_iterations == 0:
        return x0
    x, _res = refine(fine, x0, coarse=coarse_level, scale=scale, s=s, coarse_shape=(-(-h // s), -(-w // s)),
                     maxiter=int(refine_iterations), tol=tol)
    return x

