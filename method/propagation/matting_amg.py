"""The ``"cg_amg"`` solver of the matting system (L + λD) d = λ D d̂ (:mod:`method.propagation.matting`).

Conjugate gradients in float64, preconditioned by one V-cycle of a pyamg smoothed-aggregation hierarchy
held in float32:

* the hierarchy: candidate vectors 1, R, G, B of the guide (the near-null space of the matting Laplacian:
  maps locally affine in the colour cost ~ε), no candidate improvement, deterministic prolongation smoother
  (:data:`method.propagation.solvers.AMG_PROLONGATION_SMOOTHER`), forward Gauss–Seidel before the coarse
  correction and backward after it (the cycle stays a symmetric operator, as CG needs);
* float32 matrices and vectors inside the cycle: the products are memory-bound, so half the bytes is
  close to half the time, and the preconditioner needs no more digits than it has (CG's own products,
  residual and iterate stay float64, so the solution's accuracy is not float32's);
* the cycle driven here (:func:`vcycle_preconditioner`) rather than by ``MultilevelSolver.aspreconditioner``,
  which computes two extra residual norms on the finest level per application;
* a stop on the iterate's change: CG also stops once its last step moved no pixel by more than
  ``step_tol`` px (:func:`pcg`).

Measured on the stages figure's ``zhuo_sim`` systems in docs/figures.md.
"""

from __future__ import annotations

import numpy as np

__all__ = ["amg_hierarchy", "pcg", "vcycle_preconditioner"]


def amg_hierarchy(A, guide):
    """Float32 smoothed-aggregation hierarchy of the matting system, colour candidates.

    Parameters
    ----------
    A : scipy.sparse.csr_matrix, N x N, float64
        L + λD (symmetric positive definite), pixels in raster order.
    guide : ndarray, HxWx3, float
        The guide image (H·W = N) whose 1, R, G, B (centred) are the aggregation's candidates.

    Returns
    -------
    pyamg.MultilevelSolver
        Its levels' ``A``, ``P``, ``R`` are float32; smoothers: forward Gauss–Seidel before, backward after.
    """
    import pyamg
    from threadpoolctl import threadpool_limits

    from .solvers import AMG_PROLONGATION_SMOOTHER

    rgb = guide.reshape(-1, guide.shape[-1])
    candidates = np.column_stack([np.ones(len(rgb)), rgb - rgb.mean(axis=0)]).astype(np.float32)
    with threadpool_limits(limits=1):
        return pyamg.smoothed_aggregation_solver(
            A.astype(np.float32), B=candidates, symmetry="symmetric", max_coarse=500,
            smooth=AMG_PROLONGATION_SMOOTHER, improve_candidates=None,
            presmoother=("gauss_seidel", {"sweep": "forward"}), postsmoother=("gauss_seidel", {"sweep": "backward"}))


def vcycle_preconditioner(ml):
    """z = M r: one V-cycle of ``ml`` from z = 0, computed in the hierarchy's precision.

    Parameters
    ----------
    ml : pyamg.MultilevelSolver
        A hierarchy with at least two levels (:func:`amg_hierarchy`).

    Returns
    -------
    callable
        ``apply(r)`` with r an (N,) float64 residual; returns the (N,) float64 correction. The same as
        pyamg's ``ml.aspreconditioner(cycle="V")`` up to the rounding of the hierarchy's precision.
    """
    levels = ml.levels
    dtype = levels[0].A.dtype

    def cycle(i, b):
        level = levels[i]
        if i == len(levels) - 1:
            return np.asarray(ml.coarse_solver(level.A, b), dtype=dtype).reshape(b.shape)
        x = np.zeros_like(b)
        level.presmoother(level.A, x, b)
        x += level.P @ cycle(i + 1, level.R @ (b - level.A @ x))
        level.postsmoother(level.A, x, b)
        return x

    def apply(r):
        return cycle(0, r.astype(dtype)).astype(np.float64)

    return apply


def pcg(A, b, x0, precondition, *, tol, max_iterations, step_tol=None):
    """Preconditioned conjugate gradients (Hestenes–Stiefel) with two stopping rules.

    Parameters
    ----------
    A : scipy.sparse matrix, N x N, float64
        Symmetric positive definite.
    b : ndarray, N, float64
        Right-hand side (σ px times the data weight).
    x0 : ndarray, N, float64
        Start, σ px.
    precondition : callable
        r (N,) -> M r (N,), M symmetric positive definite.
    tol : float
        Stop when ‖b − A x‖ ≤ tol ‖b‖ (relative residual).
    max_iterations : int
        Most iterations; RuntimeError beyond.
    step_tol : float or None
        px; if given, also stop when an iteration changed no entry of x by more than ``step_tol``.

    Returns
    -------
    x : ndarray, N, float64
        The iterate where a rule held, σ px.
    iterations : int
        Iterations made.

    Raises
    ------
    RuntimeError
        Neither rule held within ``max_iterations``.
    """
    from threadpoolctl import threadpool_limits

    x = np.array(x0, dtype=np.float64)
    stop = tol * np.linalg.norm(b)
    with threadpool_limits(limits=1, user_api="blas"):
        r = b - A @ x
        if np.linalg.norm(r) <= stop:
            return x, 0
        z = precondition(r)
        p = z.copy()
        rz = r @ z
        for k in range(1, max_iterations + 1):
            Ap = A @ p
            alpha = rz / (p @ Ap)
            x += alpha * p
            r -= alpha * Ap
            if np.linalg.norm(r) <= stop or (step_tol is not None and abs(alpha) * np.max(np.abs(p)) <= step_tol):
                return x, k
            z = precondition(r)
            rz, rz_old = r @ z, rz
            p *= rz / rz_old
            p += z
    raise RuntimeError(f"conjugate gradients did not reach tol={tol:g} within max_iterations={max_iterations}; "
                       "raise max_iterations or tol")
