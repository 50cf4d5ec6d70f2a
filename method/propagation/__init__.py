"""Propagation of the sparse measures to a dense defocus map (Eq. 4), and the fusion of the region cue
into its data term.

Modules: :mod:`.defocus` (:func:`propagate_defocus`, Eq. 4 with Levin et al.'s colorization affinities),
:mod:`.system` (the sparse system), :mod:`.solvers` (direct, AMG-CG), :mod:`.matrix_free` (with the
matrix-free operator of :mod:`.normal_operator`) and :mod:`.galerkin` (the coarse mode's two-level CG),
:mod:`.matting` (the matting-Laplacian variant),
:mod:`.methods` (the registry :data:`PROPAGATION_METHODS`), :mod:`.cue_fusion` (inverse-variance fusion),
:mod:`.data_weights` (the per-edge data weights c_p), :mod:`.params` (:class:`.params.PropagationParams`,
:class:`.params.FusionParams`).
"""

from .cue_fusion import fuse_cues
from .data_weights import edge_confidence, propagation_confidence
from .defocus import PROPAGATION_REFINEMENTS, PROPAGATION_SOLVERS, propagate_defocus
from .methods import PROPAGATION_METHODS, propagate_blur_measures
from .system import colorization_matrix, colorization_weights, normal_equations
from .params import FusionParams, PropagationParams
from .data_weights import ALPHA_CONFIDENCES

__all__ = ["ALPHA_CONFIDENCES", "FusionParams", "PROPAGATION_METHODS", "PropagationParams", "PROPAGATION_REFINEMENTS", "PROPAGATION_SOLVERS", "colorization_matrix",
           "colorization_weights", "edge_confidence", "fuse_cues", "normal_equations", "propagate_blur_measures",
           "propagate_defocus", "propagation_confidence"]
