"""Beyond the paper: how much the model's assumptions bias the estimates (from Fig. 4's and Fig. 6's rows)."""

from __future__ import annotations

from ..results_query import Results

__all__ = ["mismatch_findings"]

_LABELS = {"encoding_effect": "input file: 8-bit sRGB − 8-bit linear, declared (mean signed error shift)",
           "convention_effect": "σ convention: line_spread − erf_fit (mean signed error shift)"}


def mismatch_findings(table) -> list[dict]:
    """The model's bias shifts, for the paper preset on each figure's first (default) scene set.

    The method assumes a Gaussian-blurred step in the light it measures in; the renderer blurs with a
    disk in linear light and the camera stores sRGB. The input's encoding is declared to the method,
    so both inputs are measured in the preset's light and the encoding effect is that of where the
    8-bit quantisation falls (the tone curve's own effect is ``measure_light``'s). Returns rows ``{"effect", "estimator", "edges",
    "bias_shift_px"}``: Fig. 4's pooled mean signed error differences (sRGB − linear input, line_spread −
    erf_fit σ convention), and Fig. 6's dense-map bias at α = 0.5 per encoding, mean over the scenes;
    empty when the rows are missing.
    """
    table = table if isinstance(table, Results) else Results(table)
    rows = []
    fig4 = table.where(figure="fig4", preset="paper", variant="pooled", encoding=None)
    sets = [s for s in fig4.distinct("scene_set") if s]
    for est, r in (fig4.where(scene_set=sets[0]).group("estimator").items() if sets else ()):
        for metric, value in r.metrics().items():
            effect, subset, variant = metric.split("/")
            rows.append({"effect": _LABELS.get(effect, effect), "estimator": est, "edges": f"{subset} ({variant})",
                         "bias_shift_px": value})
    fig6 = table.where(figure="fig6", preset="paper")
    sets = [s for s in fig6.distinct("scene_set") if s]
    if sets:
        f6 = fig6.where(scene_set=sets[0])
        for enc in [e for e in f6.distinct("encoding") if e]:
            for region in ("all", "textured"):
                vals = [v["value"] for v in f6.where(encoding=enc, metric=f"alpha=0.5/{region}_bias") if v["value"] is not None]
                if vals:
                    rows.append({"effect": f"dense map bias, {enc} input (α = 0.5)", "estimator": "pipeline",
                                 "edges": f"{region} pixels", "bias_shift_px": sum(vals) / len(vals)})
    return rows
