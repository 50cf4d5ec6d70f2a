"""Propagation of sparse defocus to a dense map with the closed-form matting Laplacian (Zhuo & Sim 2011).

The propagation step of S. Zhuo and T. Sim, "Defocus map estimation from a single image", Pattern
Recognition 44(9):1852–1858, 2011, an alternative to Bae & Durand's Eq. (4) (:mod:`method.propagation.defocus`).
The dense map d minimises::

    E(d) = dᵀ L d + λ (d − d̂)ᵀ D (d − d̂)

with L the matting Laplacian of the RGB guide image (Levin, Lischinski & Weiss, "A closed-form
solution to natural image matting", TPAMI 30(2), 2008; built by :func:`pymatting.cf_laplacian`),
D = diag(1 at pixels with a sparse estimate — finite values of the sparse map —, 0 elsewhere) and d̂
the sparse map. The minimiser solves the sparse symmetric positive definite system::

    (L + λ D) d = λ D d̂

Matting Laplacian
-----------------
L = Σ_k L_k over every (2r+1)² window w_k lying fully inside the image, with
``L_k[i, j] = δ_ij − (1 + (I_i − μ_k)ᵀ (Σ_k + ε/|w_k| I₃)⁻¹ (I_j − μ_k)) / |w_k|``
(μ_k, Σ_k: mean and 3×3 colour covariance of w_k, |w_k| = (2r+1)²). L is positive semi-definite and,
for ε > 0, its null space is the constant maps (L·1 = 0): a map costs nothing only if it is
constant, and little if it is locally an affine function of the colour (the colour-line model), so
the map can jump across colour edges. Hence L + λD is positive definite as soon as one pixel has an
estimate (every pixel lies in a window once H, W ≥ 2r+1, and overlapping windows connect the
image): **no extra regulariser is needed** and none is added. A grey guide is repeated to three
channels; its Laplacian is then the grey one with ε/3 (the covariance is rank one).

Parameter values and where they come from
-----------------------------------------
The paper's text was not available to this reproduction (stored pages, documentation and code were
searched), so **none of the defaults is taken from the paper**:

* ``lam`` λ = 0.005 and ``epsilon`` ε = 1e-5: fallback values chosen for this harness (pymatting's
  own default ε is 1e-7). The authors' public MATLAB release (``demo.m`` / ``defocusEstimation.m``,
  "Shaojie Zhuo @ 2011") calls the propagation with ``lambda = 0.001``, and its ``getLaplacian``
  adds ``1e-7·I₃`` to Σ_k, i.e. ε = 9e-7 in Levin's (and pymatting's) convention ε/|w_k| with
  |w_k| = 9; pass ``lam=0.001, epsilon=9e-7`` to follow that code. (That release also marks only
  σ > 1e-4 as known, after clipping σ to a maximum and a sparse bilateral filter — steps outside
  this module; here every finite σ, 0 included, is a constraint.)
* ``radius`` r = 1 (3×3 windows): the same in the authors' release (``getLaplacian(I, 1)``) and in
  Levin et al.'s default.

Solver (measured; see :data:`MATTING_SOLVERS`)
----------------------------------------------
Default ``"cg_amg"`` (:mod:`method.propagation.matting_amg`): CG preconditioned by a V-cycle of pyamg
smoothed aggregation whose candidate vectors are 1, R, G, B of the guide (the near-null space of L: maps
locally affine in the colour cost ~ε; with Zhuo & Sim's ε = 9e-7 and data term λ·d̂ ≈ 1e-3 that space is
what a geometric V-cycle fails to reduce), held in float32 with forward/backward Gauss–Seidel, CG in
float64; optionally also stopped once a step moves no pixel by more than ``step_tol`` px. Plain smoothed
aggregation (constant candidate only) needed 710 iterations at tol 1e-6 on portrait f/8 and was slower
than the V-cycle. On the stages figure's ``zhuo_sim`` systems (640×480 renders, λ = 0.001, ε = 9e-7,
D = d̂) CG stopped when a step first moved no pixel by more than 1e-4 px left ≤ 2.0e-3 px (20× that
step; past the 10th iteration the error was at most 40× the last step) from the tol-1e-6 ``"cg_vcycle"``
solution, after 63–182 iterations; the relative residual at which the error first fell below 0.01 px
ranged over 2e-2 … 2e-4, so the residual does not bound the error in px (``"cg_amg"`` at tol 1e-4 was
once 9.5e-3 px away, at 1e-3 0.0104 px). ``benchmarks/matting_solve.py`` measures the solvers on those
cases (docs/figures.md).
The earlier measurements of ``"cg_vcycle"`` and ``"cg_ichol"`` (Zhuo & Sim's options not used):
Conjugate gradients (:func:`pymatting.cg`, BLAS limited to one thread) started from the mean of the
sparse values (exact when they are all equal, since L·1 = 0), preconditioned by pymatting's
geometric multigrid V-cycle (:func:`pymatting.vcycle`: 1 pre-/post-Jacobi sweep, ω = 0.8) or by its
thresholded incomplete Cholesky factor (:func:`pymatting.ichol`: discard threshold 1e-4). Wall
time of :func:`propagate_defocus_matting` (Laplacian included) on the astronaut photo with
canny-edge sparse values (8–11 % of pixels), ``tol=1e-6``, on this 2-core machine while other jobs
ran (load 3–4); CG iterations and max |error| against ``"direct"`` (where run) from the same
photo with slightly noisier sparse values:

=========  ===============================  ===============================  ============
size       ``"cg_vcycle"``                  ``"cg_ichol"``                   ``"direct"``
=========  ===============================  ===============================  ============
256²       2.5–3.0 s, 206 it, 3.6e-6 px     2.0–2.3 s, 19 it, 3.7e-6 px      10 s
512²       10.1 s, 212 it, 1.1e-5 px        16.5–20 s, 31 it, 4.8e-6 px      70 s
1024²      35–55 s (34 s CPU), 168 it,      128 s (88 s CPU), 63 it,         refused
           peak RSS 1.0 GB                  peak RSS 2.5 GB                  (> 512² px)
=========  ===============================  ===============================  ============

At 256² incomplete Cholesky is ~15 % faster and as accurate (both a few 1e-6 px from the exact solve),
but its factor has ~3× the non-zeros of L + λD, its set-up and sequential triangular solves grow
faster than linearly, and its iteration count grows with the image (19 → 31 → 63) while the
V-cycle's stays ~150–330 over the photos tried (astronaut, coffee, chelsea, rocket, noise; odd sizes
included). On coffee at 1024² the thresholded factorisation also broke down twice before a
diagonal shift of 1e-3 made it succeed (113 s vs 50 s CPU for the V-cycle). Hence the V-cycle was
preferred to incomplete Cholesky: 2× faster at 512², 2.3–3.7× at 1024², and less than half the memory. ``tol=1e-8``
costs ~1.3× the iterations of ``tol=1e-6`` with either and reaches ~1e-7 px. Jacobi-preconditioned
CG (not offered) needed 2000–2900 iterations and was 2.5–5× slower than either.
"""

from __future__ import annotations

import contextlib
import io
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..validation import check_positive, validate_propagation_inputs
from ..registry import Entry, Registry

__all__ = [
    "MATTING_DATA_WEIGHTS",
    "MATTING_SOLVERS",
    "matting_system",
    "propagate_defocus_matting",
]

#: λ of the data term (not from the paper; see the module docstring).
DEFAULT_LAMBDA = 0.005
#: ε of the matting Laplacian, Levin's convention (Σ_k + ε/|w_k| I₃) (not from the paper).
DEFAULT_EPSILON = 1e-5
#: name -> what D of the data term holds at a measure d̂ (0 elsewhere).
MATTING_DATA_WEIGHTS = Registry("matting data weight", {
    "constant": "1 (Zhuo & Sim's equation)",
    "sigma": "d̂ (the public Zhuo & Sim code: D = diag(sparse map))",
})
#: Largest image (pixels) accepted by ``solver="direct"`` (sparse LU took ~70 s at 512² here).
DIRECT_MAX_PIXELS = 512 * 512


def _pymatting():
    """pymatting, imported on first use.

    ``import pymatting`` costs ≈ 3 s of CPU here (it imports numba and loads ~30 compiled kernels,
    KNN/foreground ones included), which ``import method`` should not pay when this module is
    registered but not used.
    """
    import pymatting

    return pymatting


# --------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------
def _check_int(name, value, minimum) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}={value!r} is invalid; allowed: integer >= {minimum}")
    return int(value)


def _validate(sparse_sigma, reference, lam, epsilon, radius):
    """The same input rules as :mod:`method.propagation.defocus` (:func:`validate_propagation_inputs`); the
    guide as an HxWx3 float64 C-contiguous array (a grey / HxWx1 guide repeated to 3 channels)."""
    sparse_sigma, ref = validate_propagation_inputs(sparse_sigma, reference)
    if ref.shape[2] == 1:
        ref = np.repeat(ref, 3, axis=2)
    ref = np.ascontiguousarray(ref)
    lam = check_positive("lam", lam)
    epsilon = check_positive("epsilon", epsilon)
    radius = _check_int("radius", radius, 1)
    side = 2 * radius + 1
    if min(ref.shape[:2]) < side:
        raise ValueError(f"image is {ref.shape[0]}x{ref.shape[1]} px; allowed: H, W >= 2*radius+1 = {side}")
    return sparse_sigma, ref, lam, epsilon, radius


# --------------------------------------------------------------------------------------------
# the linear system
# --------------------------------------------------------------------------------------------
def _data_diagonal(sparse_sigma, data_weight):
    """The diagonal of D: 0 off the measures, 1 (``"constant"``) or d̂ (``"sigma"``) at them."""
    known = np.isfinite(sparse_sigma).ravel()
    if data_weight == "sigma":
        return np.where(known, np.nan_to_num(sparse_sigma.ravel()), 0.0)
    return known.astype(np.float64)


def _assemble(ref, sparse_sigma, lam, epsilon, radius, data_weight="constant"):
    """A = L + λD (canonical CSR, explicit zeros removed) and b = λ D d̂."""
    known = np.isfinite(sparse_sigma).ravel()
    L = _pymatting().cf_laplacian(ref, epsilon=epsilon, radius=radius)
    data = lam * _data_diagonal(sparse_sigma, data_weight)
    A = (L + sp.diags(data, format="csr")).tocsr()
    del L
    A.sum_duplicates()
    A.eliminate_zeros()
    b = data * np.where(known, sparse_sigma.ravel(), 0.0)
    return A, b


def _check_data_weight(data_weight):
    MATTING_DATA_WEIGHTS.check(data_weight, what="data_weight")
    return data_weight


def matting_system(sparse_sigma, reference, *, lam=DEFAULT_LAMBDA, epsilon=DEFAULT_EPSILON, radius=1,
                   data_weight="constant"):
    """The system (L + λD) d = λ D d̂ that :func:`propagate_defocus_matting` solves.

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at pixels with an estimate (d̂); NaN elsewhere.
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image of the matting Laplacian.
    lam : float, keyword-only
        λ, weight of the data term (> 0).
    epsilon : float, keyword-only
        ε of the matting Laplacian, image units², Levin's convention (> 0).
    radius : int, keyword-only
        Window radius r, px (windows of (2r+1)² px; ≥ 1).
    data_weight : str, keyword-only
        Key of :data:`MATTING_DATA_WEIGHTS`: D's diagonal at the measures.

    Returns
    -------
    A : scipy.sparse.csr_matrix, (H·W) x (H·W), float64
        L + λD, pixels in raster (row-major) order; symmetric positive semi-definite, definite
        when some pixel has an estimate.
    b : ndarray, H·W, float64
        λ D d̂, σ px (0 where there is no estimate).

    Raises
    ------
    ValueError
        Same conditions as :func:`propagate_defocus_matting`.

    Notes
    -----
    1. L = :func:`pymatting.cf_laplacian` (reference, ε, r) — Levin et al. 2008, windows fully
       inside the image.
    2. D = diag(1, or d̂ with ``data_weight="sigma"``, where ``sparse_sigma`` is finite, else 0);
       A = L + λD with duplicates summed and explicit zeros removed; b = λ D d̂.
    """
    sparse_sigma, ref, lam, epsilon, radius = _validate(sparse_sigma, reference, lam, epsilon, radius)
    return _assemble(ref, sparse_sigma, lam, epsilon, radius, _check_data_weight(data_weight))


# --------------------------------------------------------------------------------------------
# solvers of the assembled system
# --------------------------------------------------------------------------------------------
def _pcg(A, b, x0, tol, max_iterations, M):
    """pymatting's CG with BLAS limited to one thread (its dot products and norms are BLAS calls).

    Measured on the 256² astronaut case with other jobs on this 2-core machine: 2.5–2.9 s with one
    BLAS thread against 7.8–9.5 s with OpenBLAS's default threads (the worker thread competes for
    the second core and the main thread waits on it); one thread also makes the reductions, hence
    the result, independent of the thread count. Only the BLAS API is limited (as in
    :mod:`method.propagation.defocus`), not numba's.
    """
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(limits=1, user_api="blas"):
            return _pymatting().cg(A, b, x0=x0, rtol=tol, maxiter=max_iterations, M=M)
    except ValueError as exc:  # pymatting signals non-convergence with ValueError
        raise RuntimeError(
            f"conjugate gradients did not reach tol={tol:g} within max_iterations={max_iterations} "
            f"({exc}); raise max_iterations or tol") from None


def _solve_cg_amg(A, b, *, shape, x0, tol, max_iterations, guide, step_tol=None):
    """CG preconditioned by a float32 pyamg smoothed-aggregation V-cycle fitted to the matting Laplacian
    (default; :mod:`method.propagation.matting_amg`): candidate vectors 1, R, G, B of the guide, BLAS on one
    thread, an optional stop on the iterate's change (``step_tol`` px)."""
    from .matting_amg import amg_hierarchy, pcg, vcycle_preconditioner

    precondition = vcycle_preconditioner(amg_hierarchy(A, guide))
    x, _ = pcg(A, b, x0, precondition, tol=tol, max_iterations=max_iterations, step_tol=step_tol)
    return x


def _solve_cg_vcycle(A, b, *, shape, x0, tol, max_iterations, guide=None):
    """CG preconditioned by pymatting's geometric-multigrid V-cycle (default; fastest at ≥ 512²)."""
    return _pcg(A, b, x0, tol, max_iterations, _pymatting().vcycle(A, shape))


def _solve_cg_ichol(A, b, *, shape, x0, tol, max_iterations, guide=None):
    """CG preconditioned by pymatting's thresholded incomplete Cholesky factor of A.

    When the thresholded factorisation breaks down, :func:`pymatting.ichol` retries with a growing
    diagonal shift (a shifted factor is still a valid SPD preconditioner; CG still solves A d = b)
    and prints a "PERFORMANCE WARNING" to stdout; that text is captured and dropped so the
    numerics print nothing (``contextlib.redirect_stdout`` swaps ``sys.stdout`` process-wide for
    the duration of the factorisation).
    """
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            M = _pymatting().ichol(A.tocsc())
    except ValueError as exc:  # every shift failed, or the factor outgrew pymatting's max_nnz
        raise RuntimeError(f"incomplete Cholesky factorisation failed ({exc}); try solver='cg_vcycle'") from None
    return _pcg(A, b, x0, tol, max_iterations, M)


def _solve_direct(A, b, *, shape, x0, tol, max_iterations, guide=None):
    """Sparse LU (SuperLU) of the same system; tests and small images (≤ DIRECT_MAX_PIXELS)."""
    if A.shape[0] > DIRECT_MAX_PIXELS:
        raise ValueError(f"solver='direct' is for small images; got {A.shape[0]} px, allowed <= {DIRECT_MAX_PIXELS}")
    return spla.spsolve(A.tocsc(), b)


#: Solvers of (L + λD) d = λ D d̂, chosen with ``solver="..."``. Each is called as
#: ``solve(A, b, *, shape, x0, tol, max_iterations, guide) -> d`` (``guide``: the HxWx3 guide image);
#: the iterative ones stop at relative residual ``tol`` and raise RuntimeError after ``max_iterations``;
#: ``"direct"`` ignores both. Those whose function has a ``step_tol`` parameter (``"cg_amg"``) also take it
#: (px or None: :func:`_reads_step_tol`).
MATTING_SOLVERS = Registry("matting solver", {
    "cg_amg": Entry(_solve_cg_amg, "CG preconditioned by pyamg smoothed aggregation (colour candidates)"),
    "cg_vcycle": Entry(_solve_cg_vcycle, "CG preconditioned by pymatting's multigrid V-cycle"),
    "cg_ichol": Entry(_solve_cg_ichol, "CG preconditioned by pymatting's incomplete Cholesky"),
    "direct": Entry(_solve_direct, "sparse LU (scipy)"),
})


def _reads_step_tol(solver) -> bool:
    """Whether the solver ``solver`` (a key of :data:`MATTING_SOLVERS`) can also stop on the iterate's change."""
    import inspect

    return "step_tol" in inspect.signature(MATTING_SOLVERS[solver]).parameters


# --------------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------------
def propagate_defocus_matting(sparse_sigma, reference, *, lam=DEFAULT_LAMBDA, epsilon=DEFAULT_EPSILON,
                              radius=1, tol=1e-6, solver="cg_amg", max_iterations=2000,
                              data_weight="constant", step_tol=None) -> np.ndarray:
    """Dense defocus map from sparse blur σ by matting-Laplacian propagation (Zhuo & Sim 2011).

    Minimises E(d) = dᵀ L d + λ (d − d̂)ᵀ D (d − d̂) (see the module docstring).

    Parameters
    ----------
    sparse_sigma : ndarray, HxW, float
        Blur σ, px, at edge pixels (d̂; finite values must be ≥ 0); NaN at every other pixel.
    reference : ndarray, HxWx3 or HxW, float in [0, 1]
        Guide image (the RGB input photo); a grey (HxW or HxWx1) guide is repeated to three
        channels. Must be finite; the range is not checked, but ε is in these units.
    lam : float, keyword-only
        λ, weight of the data term relative to the smoothness term (> 0; default 0.005, not from
        the paper — the authors' MATLAB release uses 0.001). Larger λ follows d̂ more closely.
    epsilon : float, keyword-only
        ε of the matting Laplacian, image units², in Levin's convention (Σ_k + ε/|w_k| I₃)⁻¹
        (> 0; default 1e-5, not from the paper — the authors' release corresponds to 9e-7).
        Larger ε smooths the map across colour edges.
    radius : int, keyword-only
        Window radius r, px: windows of (2r+1)² px (≥ 1; default 1, i.e. 3×3, as the authors'
        release). H and W must be ≥ 2r+1. L has (4r+1)² non-zeros per row.
    tol : float, keyword-only
        Relative residual ‖λDd̂ − (L + λD) d‖ / ‖λDd̂‖ at which CG stops (0 < tol < 1). 1e-6 leaves
        ~1e-5 px from the exact solve on photos up to 512²; ignored by ``"direct"``.
    solver : str, keyword-only
        Key of :data:`MATTING_SOLVERS`: ``"cg_amg"`` (default; CG + pyamg smoothed aggregation
        with the guide's colours as candidates), ``"cg_vcycle"`` (CG + pymatting's multigrid
        V-cycle, the earlier default), ``"cg_ichol"`` (CG + incomplete Cholesky; ~15 % faster at 256², 2–4× slower and
        2.5× the memory at 1024²) or ``"direct"`` (sparse LU; ≤ 512² px, for tests and small images).
    max_iterations : int, keyword-only
        Most CG iterations (≥ 1; default 2000, ~10× what the V-cycle needed up to 1024²).
    data_weight : str, keyword-only
        Key of :data:`MATTING_DATA_WEIGHTS`: ``"constant"`` (default; D = 1 at every measure, Zhuo &
        Sim's equation) or ``"sigma"`` (D = d̂, as the public Zhuo & Sim code builds it, so larger
        measures weigh more and a measure of 0 px weighs nothing; docs/zhuo-sim.md).
    step_tol : float or None, keyword-only
        px (> 0): CG also stops once an iteration changed no pixel of d by more than ``step_tol``
        (``"cg_amg"`` only; default None: the relative residual alone). On the stages figure's
        ``zhuo_sim`` systems the error left was at most ~20× the last step (docs/figures.md).

    Returns
    -------
    ndarray, HxW, float64
        Dense blur σ, px. Not clipped: L has positive off-diagonal entries, so nothing guarantees
        the range of the sparse σ (no value outside it was seen on the photos tried).
        All zeros when ``sparse_sigma`` has no finite value; the constant map when all its finite
        values are equal.

    Raises
    ------
    ValueError
        Shapes disagree, non-float input, NaN/Inf in the reference, Inf or negative σ, image
        smaller than 2r+1 px, unknown ``solver``, bad option value, ``"direct"`` on a too-large image,
        ``step_tol`` with a solver other than ``"cg_amg"``.
    RuntimeError
        CG did not reach ``tol`` within ``max_iterations``, or (``"cg_ichol"``) the incomplete
        Cholesky factorisation failed.

    Notes
    -----
    1. Validate; if no σ is finite return zeros; if all finite σ are equal return that constant
       (it solves the system exactly: L·1 = 0 and D(1·c − d̂) = 0).
    2. L = :func:`pymatting.cf_laplacian` of the guide with ε and r (Levin et al. 2008).
    3. D = diag(1 at finite σ); A = L + λD, b = λ D d̂ (:func:`matting_system`). A is symmetric
       positive definite (one estimate suffices, see the module docstring), so no regulariser
       is added.
    4. Solve A d = b with ``solver``: CG to relative residual ``tol`` from d₀ = mean of the
       sparse σ, preconditioned by smoothed aggregation (``"cg_amg"``), a V-cycle
       (``"cg_vcycle"``) or an incomplete Cholesky factor
       (``"cg_ichol"``), or sparse LU (``"direct"``).
    5. Reshape to HxW. Deterministic: no random numbers are drawn and CG's BLAS reductions run
       on one thread.
    """
    sparse_sigma, ref, lam, epsilon, radius = _validate(sparse_sigma, reference, lam, epsilon, radius)
    MATTING_SOLVERS.check(solver, what="solver")
    tol = check_positive("tol", tol)
    if not tol < 1:
        raise ValueError(f"tol={tol!r} is invalid; allowed: 0 < tol < 1")
    max_iterations = _check_int("max_iterations", max_iterations, 1)
    data_weight = _check_data_weight(data_weight)
    if step_tol is not None:
        step_tol = check_positive("step_tol", step_tol)
        if not _reads_step_tol(solver):
            readers = [name for name in MATTING_SOLVERS if _reads_step_tol(name)]
            raise ValueError(f"step_tol={step_tol!r} with solver={solver!r} is invalid; allowed: step_tol=None, "
                             f"or a solver of {readers}")
    h, w = sparse_sigma.shape
    if solver == "direct" and h * w > DIRECT_MAX_PIXELS:
        raise ValueError(f"solver='direct' is for small images; got {h * w} px, allowed <= {DIRECT_MAX_PIXELS}")

    known = np.isfinite(sparse_sigma)
    if not known.any():
        return np.zeros((h, w))
    values = sparse_sigma[known]
    fill = float(np.mean(values))
    if np.ptp(values) == 0:
        return np.full((h, w), float(values[0]))

    if not _data_diagonal(sparse_sigma, data_weight).any():  # every weight 0: no constraint
        return np.zeros((h, w))
    A, b = _assemble(ref, sparse_sigma, lam, epsilon, radius, data_weight)
    x0 = np.full(h * w, fill)
    extra = {} if step_tol is None else {"step_tol": step_tol}
    d = MATTING_SOLVERS[solver](A, b, shape=(h, w), x0=x0, tol=tol, max_iterations=max_iterations, guide=ref,
                                **extra)
    return np.asarray(d, dtype=np.float64).reshape(h, w)
