"""Parameters of the defocus map's preprocessing before magnification (Sec. 5).

Read by the callers of :func:`method.magnify.magnification.preprocess_defocus_map` (the magnification
tools and figures), not by the estimation pipeline.
"""

from __future__ import annotations

import dataclasses

from ..validation import check_field_choice, require_field
from .magnification import MAGNIFICATION_RENDERERS, MAP_FLOOR_MODES

__all__ = ["MagnifyParams"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class MagnifyParams:
    """How the estimated map is cleaned up before it is magnified (Sec. 5).

    Validated on construction (ValueError ``DefocusParams.<field>=… is invalid; allowed: …``).
    """

    map_clip_percent: float = 5.0
    # clip the lower and upper percentile of the defocus map before blurring, % (Sec. 5).
    map_smoothing: float = 0.005
    # σ of the Gaussian blur of the map as a fraction of the image size max(H, W), dimensionless (Sec. 5).
    map_floor: str = "clamp"
    # how Sec. 5's "clamp its minimum value to 0" is read (key of
    # method.magnify.magnification.MAP_FLOOR_MODES): "clamp" = max(σ, 0) px, the literal reading (keeps
    # the in-focus floor σ ≈ 0.3–0.7 px, which magnification then enlarges); "subtract" = remove the
    # lower-percentile value p_lo px in quadrature, √(max(σ² − p_lo², 0)); "shift" = max(σ − p_lo, 0);
    # "auto" = the in-focus floor estimated per photo from the smoothed map, no blur added within its
    # uncertainty, growing smoothly above (method.magnify.map_floor.soft_floor), so sharp regions stay sharp.
    magnify_renderer: str = "gather"
    # how the blur is added (key of method.magnify.magnification.MAGNIFICATION_RENDERERS): "gather" (the
    # paper's path) or "scatter" (per-pixel disks in linear light with occlusion); the renderer a tool
    # uses when it is not told one (docs/magnification.md).

    def __post_init__(self):
        require_field(self, "map_clip_percent", 0 <= self.map_clip_percent < 50, "0 <= p < 50")
        require_field(self, "map_smoothing", self.map_smoothing >= 0, ">= 0")
        check_field_choice(self, "map_floor", MAP_FLOOR_MODES)
        check_field_choice(self, "magnify_renderer", MAGNIFICATION_RENDERERS)
