"""Solvers of the assembled propagation system (Eq. 4) and the coarse level of the coarse mode.

* :data:`PROPAGATION_SOLVERS`: ``"amg_pcg"`` (pyamg smoothed-aggregation multigrid as preconditioner
  of CG, deterministic set-up, single-threaded BLAS) and ``"direct"`` (sparse LU, small images), each
  ``solve(A, rhs, *, x0, tol) -> x``;
* :data:`COARSE_SETUPS`: per solver name, the set-up of the coarse level of
  :func:`method.propagation.defocus.propagate_defocus`'s coarse mode (:class:`CoarseLevel`): the hierarchy or
  factorisation built once serves both the coarse solve and the coarse-grid correction of the
  two-level preconditioner (one V-cycle, :func:`amg_vcycle`, or the LU solve).

The system itself comes from :mod:`method.propagation.system`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from ..registry import Entry, Registry

__all__ = ["AMG_PROLONGATION_SMOOTHER", "COARSE_SETUPS", "PROPAGATION_SOLVERS", "CoarseLevel", "amg_vcycle"]


def _solve_direct(A, rhs, *, x0=None, tol=1e-6):
    """Sparse LU (SuperLU); small images and tests only."""
    if A.shape[0] > 200_000:
        raise ValueError(f"solver='direct' is for small images (<= 200000 px), got {A.shape[0]} px")
    return spla.spsolve(A.tocsc(), rhs)


#: Prolongation smoother of the AMG hierarchy. pyamg's default Jacobi smoother scales by a spectral
#: radius estimated from a random start vector drawn from NumPy's *global* RNG (so results differed
#: ~1e-7 px run to run); ``weighting="local"`` uses each row's Gershgorin bound instead, which is
#: deterministic, touches no RNG and never under-damps.
AMG_PROLONGATION_SMOOTHER = ("jacobi", {"omega": 4.0 / 3.0, "weighting": "local"})


def _amg_hierarchy(A):
    """pyamg smoothed-aggregation hierarchy of ``A`` (deterministic setup, single-threaded BLAS)."""
    import pyamg
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return pyamg.smoothed_aggregation_solver(A, symmetry="symmetric", max_coarse=500,
                                                 smooth=AMG_PROLONGATION_SMOOTHER)


def _amg_solve(ml, rhs, x0, tol):
    """CG preconditioned by V-cycles of the hierarchy ``ml`` to relative residual ``tol``."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        x = ml.solve(rhs, x0=x0, tol=tol, accel="cg", maxiter=500)
    return np.asarray(x, dtype=np.float64)


def _solve_amg_pcg(A, rhs, *, x0=None, tol=1e-6):
    """Smoothed-aggregation multigrid (pyamg) as preconditioner of CG, single-threaded BLAS.

    Deterministic: no random numbers (see :data:`AMG_PROLONGATION_SMOOTHER`) and BLAS limited to one
    thread, so the result is bit-identical across runs, processes and core counts.
    """
    return _amg_solve(_amg_hierarchy(A), rhs, x0, tol)


#: Solvers of the assembled normal equations, chosen with ``solver="..."``.
PROPAGATION_SOLVERS = Registry("propagation solver", {
    "amg_pcg": Entry(_solve_amg_pcg, "CG preconditioned by pyamg smoothed-aggregation multigrid"),
    "direct": Entry(_solve_direct, "sparse LU (scipy SuperLU)"),
})


class CoarseLevel:
    """The coarse Eq. (4) system of the two-level scheme: its solve and an approximate inverse.

    Attributes
    ----------
    solve : callable (rhs (n_c,), x0 (n_c,), tol) -> (n_c,)
        Solution of the coarse system to relative residual ``tol``.
    apply_inverse : callable (r (n_c,)) -> (n_c,)
        Symmetric positive definite approximation of A_c⁻¹ r, the same linear map at every call
        (one multigrid V-cycle from zero, or the exact LU solve).
    """

    def __init__(self, solve, apply_inverse):
        self.solve = solve
        self.apply_inverse = apply_inverse


def amg_vcycle(ml, b):
    """One V-cycle of the hierarchy ``ml`` from a zero start: x ≈ A⁻¹ b (symmetric, linear in b).

    Pre-smoother, restriction of the residual, recursion, prolongation, post-smoother on every level,
    ``ml.coarse_solver`` on the last; with pyamg's default symmetric Gauss–Seidel smoothers this is an
    SPD preconditioner. (``ml.solve(..., maxiter=1)`` would also compute two residual norms per call.)
    """
    levels = ml.levels
    x = np.zeros_like(b)

    def cycle(lvl, x, b):
        lev = levels[lvl]
        if lvl == len(levels) - 1:
            x[:] = ml.coarse_solver(lev.A, b)
            return
        lev.presmoother(lev.A, x, b)
        bc = lev.R @ (b - lev.A @ x)
        xc = np.zeros_like(bc)
        cycle(lvl + 1, xc, bc)
        x += lev.P @ xc
        lev.postsmoother(lev.A, x, b)

    cycle(0, x, b)
    return x


def _coarse_amg(A_c):
    ml = _amg_hierarchy(A_c)
    return CoarseLevel(lambda rhs, x0, tol: _amg_solve(ml, rhs, x0, tol),
                        lambda r: amg_vcycle(ml, r))


def _coarse_direct(A_c):
    lu = spla.splu(A_c.tocsc())
    return CoarseLevel(lambda rhs, x0, tol: lu.solve(rhs), lu.solve)


#: Set-up of the coarse level of ``downsample`` > 1, per ``solver`` name (same keys as
#: :data:`PROPAGATION_SOLVERS`): the hierarchy / factorisation is built once and serves both the
#: coarse solve and the coarse-grid correction of the two-level preconditioner.
COARSE_SETUPS = Registry("coarse set-up", {
    "amg_pcg": Entry(_coarse_amg, "pyamg hierarchy: AMG-PCG solve, one V-cycle as inverse"),
    "direct": Entry(_coarse_direct, "sparse LU factorisation for both"),
})


