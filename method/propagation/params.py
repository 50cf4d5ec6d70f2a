"""Parameters of the propagation to a dense map, Eq. (4) (Sec. 4), and of the fusion of the region cue
into its data term (beyond the paper).

Blur in px of the input image. Measurements behind the values beyond the paper: docs/presets.md
("Per-field measurements"), docs/cue-fusion.md, docs/performance.md (the solver).
"""

from __future__ import annotations

import dataclasses

from ..validation import check_field_choice, invalid_field, is_integer, require_field
from .cue_fusion import REGION_PLACEMENTS
from .data_weights import ALPHA_CONFIDENCES
from .defocus import PROPAGATION_REFINEMENTS, PROPAGATION_SOLVERS
from .matting import MATTING_DATA_WEIGHTS
from .methods import PROPAGATION_METHODS

__all__ = ["FusionParams", "PropagationParams"]

_INF = float("inf")


@dataclasses.dataclass(frozen=True, kw_only=True)
class PropagationParams:
    """The propagation of the refined measures to every pixel, Eq. (4), its solver and the
    matting-Laplacian alternative (Zhuo & Sim 2011).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``).
    """

    propagation: str = "colorization"
    # key of method.propagation.methods.PROPAGATION_METHODS: "colorization" (paper, Eq. 4: Levin et al.
    # 2004 affinities) or "matting_laplacian" (Zhuo & Sim 2011: the closed-form matting Laplacian of
    # Levin et al. 2008).
    alpha_confidence: str = "none"
    # per-edge data weight α_p (key of method.propagation.data_weights.ALPHA_CONFIDENCES; Sec. 4.1 sets
    # α_p = α at every edge): "none" (paper) or "agreement" (beyond the paper:
    # α_p = α·exp(−(BM_p − bCBF_p)² / (2 (0.25·bCBF_p + 0.5 px)²)), the raw measure's agreement with its
    # refined value).
    matting_lambda: float = 0.005
    # λ of Zhuo & Sim's (L + λD) d = λ D d̂ (propagation="matting_laplacian"), dimensionless.
    matting_epsilon: float = 1e-5
    # ε of the matting Laplacian (Levin et al. 2008), image units², for propagation="matting_laplacian".
    matting_data_weight: str = "constant"
    # D of (L + λD) d = λ D d̂ (key of method.propagation.matting.MATTING_DATA_WEIGHTS): "constant" (1 at
    # every measure, Zhuo & Sim's equation) or "sigma" (D = diag(d̂), as their public code builds it).
    matting_tol: float = 1e-6
    # relative residual ‖λDd̂ − (L + λD) d‖ / ‖λDd̂‖ at which the CG solve of the matting system stops
    # (propagation="matting_laplacian"; Eq. 4's own solve stops at propagation_tol). Measured distance of
    # the dense σ from the tol-1e-6 solve per value: docs/figures.md.
    matting_step_tol: float | None = None
    # px: the matting system's CG also stops once an iteration changed no pixel by more than this
    # (propagation="matting_laplacian"); None: the relative residual matting_tol alone. Measured error
    # left per value on the stages figure's renders: docs/figures.md.
    alpha: float = 0.5
    # data-term weight α_p at edge pixels, dimensionless; 0 elsewhere (Sec. 4.1; Fig. 6 sweeps 0.1–1).
    propagation_window: int = 7
    # side of the square window, px, over which σ_ip (per-channel std) is computed (Sec. 4.1: "7×7").
    propagation_neighborhood: int = 3
    # side of the square neighbourhood N(p), px (not given by the paper; 3 = Levin et al. 2004; 7 = the
    # "one 7×7 window defines both" reading; docs/choices.md).
    propagation_tol: float = 1e-6
    # relative residual at which the preconditioned CG solve of the normal equations stops.
    propagation_solver: str = "amg_pcg"
    # key of method.propagation.defocus.PROPAGATION_SOLVERS: "amg_pcg" (multigrid-preconditioned CG) or
    # "direct" (sparse LU; small images and tests).
    propagation_downsample: int | str = "auto"
    # coarsening of the solve: "auto" (exact up to method.propagation.defocus.AUTO_MAX_EXACT_PIXELS, else
    # a coarse grid with the Galerkin operator, interpolated and refined on the exact full-resolution
    # system; method.propagation.defocus.propagate_defocus), 1 (exact full-resolution solve) or a power
    # of two (that factor). Distances from the exact solve: docs/performance.md.
    propagation_refinement: str = "galerkin"
    # refinement of the upsampled coarse solution (key of
    # method.propagation.defocus.PROPAGATION_REFINEMENTS; docs/performance.md).

    def __post_init__(self):
        check_field_choice(self, "alpha_confidence", ALPHA_CONFIDENCES)
        for name in ("matting_lambda", "matting_epsilon", "alpha"):
            require_field(self, name, getattr(self, name) > 0, "> 0")
        check_field_choice(self, "matting_data_weight", MATTING_DATA_WEIGHTS)
        check_field_choice(self, "propagation", PROPAGATION_METHODS)
        if self.propagation == "matting_laplacian" and self.alpha_confidence != "none":
            raise invalid_field("alpha_confidence", self.alpha_confidence,
                                "'none' with propagation='matting_laplacian' (its data term has no per-edge weight)")
        for name in ("propagation_window", "propagation_neighborhood"):
            value = getattr(self, name)
            require_field(self, name, is_integer(value, 3) and value % 2 == 1, "odd integer >= 3")
        for name in ("propagation_tol", "matting_tol"):
            require_field(self, name, 0 < getattr(self, name) < 1, "0 < tol < 1")
        step = self.matting_step_tol
        require_field(self, "matting_step_tol",
                      step is None or (not isinstance(step, bool) and isinstance(step, (int, float)) and 0 < step < 1),
                      "None or a number of px in (0, 1)")
        ds = self.propagation_downsample
        require_field(self, "propagation_downsample", ds == "auto" or (is_integer(ds, 1) and (ds & (ds - 1)) == 0),
                      "'auto' or a power of two >= 1")
        check_field_choice(self, "propagation_refinement", PROPAGATION_REFINEMENTS)
        check_field_choice(self, "propagation_solver", PROPAGATION_SOLVERS)


@dataclasses.dataclass(frozen=True, kw_only=True)
class FusionParams:
    """The inverse-variance fusion of edge and region measures into the data term of Eq. (4), beyond the
    paper (method.propagation.cue_fusion; used only when a region estimator is set).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``).
    """

    fusion_edge_error_rel: float = 0.5
    # relative error ε_e (dimensionless) of an edge measure σ_e in the fusion's error model: variance
    # (ε_e·σ_e + 0.1 px)² / c_e.
    fusion_region_error_rel: float = 0.3
    # relative model error ε_r (dimensionless) of a region measure σ_r, added to its Fisher variance:
    # variance 1/I + (ε_r·σ_r)² + (0.1 px)².
    fusion_region_weight: float = 1.0
    # scale W_r (dimensionless, > 0) of the region measures' data weight in Eq. (4) against an edge
    # measure of the same σ: α_r = α·W_r·v_e(σ_r)/v_r (a region term stands for a window of pixels).
    fusion_region_placement: str = "centres"
    # where a region measure enters Eq. (4) (key of method.propagation.cue_fusion.REGION_PLACEMENTS):
    # "centres" (the region estimator's window centres) or "blocks" (spread over its block of the grid,
    # its weight shared among the pixels).
    fusion_island_weight: float = 1.0
    # factor in [0, 1] on the weight of a region measure in a "blur island"
    # (method.propagation.cue_fusion.blur_islands): a block without high-frequency texture beside
    # texture within fusion_island_radius px, or without texture at its own blur scale. Far from an
    # edge the smoothness of Eq. (4) is soft, so even a weak data term decides there. 1: off; 0: such
    # measures are dropped.
    fusion_island_radius: float = 24.0
    # radius, px, of the neighbourhood searched for high-frequency texture by the island test.
    fusion_straddle_weight: float = 1.0
    # factor in [0, 1] on the weight of a region measure whose window holds an isolated edge
    # (method.propagation.cue_fusion.straddled_windows): the edge fit measures that window's blur
    # better. 1: off.

    def __post_init__(self):
        for name in ("fusion_edge_error_rel", "fusion_region_error_rel"):
            require_field(self, name, 0 <= getattr(self, name) < _INF,
                          "finite and >= 0 (dimensionless relative error)")
        require_field(self, "fusion_region_weight", 0 < self.fusion_region_weight < _INF,
                      "finite and > 0 (dimensionless)")
        check_field_choice(self, "fusion_region_placement", REGION_PLACEMENTS)
        require_field(self, "fusion_island_weight", 0 <= self.fusion_island_weight <= 1,
                      "0 <= factor <= 1 (1: off; 0: island measures dropped)")
        require_field(self, "fusion_straddle_weight", 0 <= self.fusion_straddle_weight <= 1, "0 <= factor <= 1 (1: off)")
        require_field(self, "fusion_island_radius", 0 < self.fusion_island_radius < _INF, "finite and > 0 (px)")
