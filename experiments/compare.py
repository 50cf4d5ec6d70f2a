"""Two variants on the same scenes: paired differences, bootstrap intervals, verdicts and the scenes needed.

``repro.compare A B`` scores two method presets (or trivial baselines, :mod:`experiments.baselines`) on
the same scenes and hands the long results rows (:mod:`experiments.results_table`) to
:func:`compare_rows`. For every metric and aperture (× encoding × noise), over the scenes where both
have a value:

* the per-scene difference d = B − A and its mean, with a paired percentile-bootstrap 95 % interval
  (:func:`experiments.results_table.paired_difference`, seeded, 10 000 resamples);
* a verdict on B relative to A (:func:`verdict`): ``better`` / ``worse`` when the interval excludes 0 in
  the metric's good / bad direction (:func:`direction`), else ``no difference detected`` (for a metric
  without a good direction, a count: ``higher`` / ``lower``);
* the scenes that would give 80 % power at α = 0.05 for the observed mean difference
  (:func:`scenes_for_power`, the paired t approximation n = ((z₁₋α/₂ + z₀.₈)·sd/|mean d|)²);
* the interval's half-width and the scenes that would bring it to ±0.15 px
  (:func:`scenes_for_half_width`: the half-width shrinks as 1/√n).

A bias metric (signed) is compared as |bias| (closer to 0 is better): its rows are named ``|<metric>|``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = ["GROUP", "HEADLINE_METRICS", "TARGET_HALF_WIDTH_PX", "check_pair", "compare_rows", "direction",
           "format_comparison", "paired_values", "scenes_for_half_width", "scenes_for_power", "verdict"]

#: Columns that split a comparison into groups (besides the metric).
GROUP = ("aperture", "encoding", "noise")
#: Metrics of the terminal table (every metric is in the written table).
HEADLINE_METRICS = ("dense_textured_mae", "dense_all_mae", "rtf_nmae", "sparse_mae")
#: Half-width (px) the scene count of :func:`scenes_for_half_width` aims at.
TARGET_HALF_WIDTH_PX = 0.15
#: Metrics that describe the input or the scene, not the map: not compared.
_NOT_COMPARED = ("baseline_sigma_px", "n_occlusion_excluded")


def direction(metric: str) -> str | None:
    """Which way ``metric`` is good: ``"lower"`` (errors, outlier fractions, failures), ``"closer to 0"``
    (a signed bias, compared as its absolute value) or None (counts such as ``sparse_n``: no good way)."""
    from .results_table import metric_unit

    unit = metric_unit(metric)
    if unit == "pixels" or metric.endswith("_n") or metric.startswith("n_"):
        return None
    if metric.endswith("_bias"):
        return "closer to 0"
    return "lower"


def verdict(ci_low, ci_high, way: str | None) -> str:
    """B against A from the interval of mean(B − A): ``better`` / ``worse`` / ``no difference detected``
    (``higher`` / ``lower`` for a metric without a good direction; ``too few scenes`` without an interval)."""
    if ci_low is None or ci_high is None:
        return "too few scenes"
    if ci_low <= 0.0 <= ci_high:
        return "no difference detected"
    up = ci_low > 0.0
    if way is None:
        return "higher" if up else "lower"
    return "worse" if up else "better"


def scenes_for_power(mean_diff, sd, *, alpha: float = 0.05, power: float = 0.8) -> int | None:
    """Scenes a paired comparison needs to detect ``mean_diff`` with ``power`` at two-sided level ``alpha``.

    Parameters
    ----------
    mean_diff : float
        Observed mean paired difference (the metric's unit).
    sd : float
        Standard deviation of the paired differences (ddof 1, same unit).
    alpha, power : float, keyword-only

    Returns
    -------
    int or None
        ⌈((z₁₋α/₂ + z_power) · sd / |mean_diff|)²⌉ (normal approximation of the paired t test), at least 2;
        None when the difference is 0 or undefined (no number of scenes detects it).
    """
    from scipy.stats import norm

    if mean_diff is None or sd is None or not math.isfinite(mean_diff) or mean_diff == 0.0:
        return None
    z = norm.ppf(1.0 - alpha / 2.0) + norm.ppf(power)
    return max(2, math.ceil((z * sd / abs(mean_diff)) ** 2))


def scenes_for_half_width(n: int, half_width, *, target: float = TARGET_HALF_WIDTH_PX) -> int | None:
    """Scenes that would bring an interval of ``half_width`` measured on ``n`` scenes to ``± target``:
    ⌈n · (half_width / target)²⌉ (the half-width shrinks as 1/√n), at least 2; None without an interval."""
    if half_width is None or not math.isfinite(half_width):
        return None
    return max(2, math.ceil(n * (half_width / target) ** 2))


def check_pair(a: str, b: str, *, presets: Iterable[str], baselines: Iterable[str]) -> tuple[str, str]:
    """``(a, b)`` if both name a preset or a baseline and they differ.

    Raises
    ------
    ValueError
        A = B, or an unknown name (naming the presets and baselines allowed).
    """
    allowed = [*presets, *baselines]
    for name in (a, b):
        if name not in allowed:
            raise ValueError(f"{name!r} is invalid (unknown preset or baseline); allowed: {', '.join(allowed)}")
    if a == b:
        raise ValueError(f"A = B = {a!r} is invalid; allowed: two different presets or baselines")
    return a, b


def paired_values(rows: Iterable[dict], a: str, b: str) -> dict:
    """Per group (:data:`GROUP` + ``metric``) the scenes where both variants have a value.

    Returns
    -------
    dict
        ``{(aperture, encoding, noise, metric): (scenes, values of a, values of b)}``: lists in the rows'
        scene order; bias metrics as absolute values under the name ``|metric|``; groups where no scene has
        both values are left out.
    """
    per: dict[tuple, dict] = {}
    for r in rows:
        if r.get("preset") not in (a, b) or r.get("value") is None or r["metric"] in _NOT_COMPARED:
            continue
        metric, value = r["metric"], float(r["value"])
        if direction(metric) == "closer to 0":
            metric, value = f"|{metric}|", abs(value)
        key = (*(r.get(c) for c in GROUP), metric)
        per.setdefault(key, {}).setdefault(r["scene"], {})[r["preset"]] = value
    out = {}
    for key, scenes in per.items():
        both = [s for s, v in scenes.items() if a in v and b in v]
        if both:  # a metric only one of them has (a baseline's missing sparse metrics) is not compared
            out[key] = (both, [scenes[s][a] for s in both], [scenes[s][b] for s in both])
    return out


def compare_rows(rows: Iterable[dict], a: str, b: str, *, alpha: float = 0.05, power: float = 0.8,
                 target_half_width: float = TARGET_HALF_WIDTH_PX, n_resamples: int = 10_000,
                 seed: int = 0) -> list[dict]:
    """The comparison of B against A, one record per aperture × encoding × noise × metric.

    Parameters
    ----------
    rows : iterable of dict
        Long results rows holding both variants (``preset`` = their names) on the same scenes.
    a, b : str
        The variants (B − A is the difference).
    alpha, power : float, keyword-only
        Interval level (1 − α) and the power of :func:`scenes_for_power`.
    target_half_width : float, keyword-only
        Half-width (px) of :func:`scenes_for_half_width`, given for the metrics in px only.
    n_resamples, seed : int, keyword-only
        Paired bootstrap resamples and seed (the same rows give the same intervals).

    Returns
    -------
    list of dict
        ``aperture``, ``encoding``, ``noise``, ``metric``, ``unit``, ``direction``, ``n_scenes``, ``mean_a``,
        ``mean_b``, ``mean_diff`` (B − A), ``sd_diff``, ``ci_low``, ``ci_high``, ``half_width``, ``verdict``,
        ``n_for_power``, ``n_for_half_width`` (None for a metric not in px); sorted by aperture (descending f-number) then metric.
    """
    from .results_table import metric_unit, paired_difference

    out = []
    for (aperture, encoding, noise, metric), (scenes, va, vb) in paired_values(rows, a, b).items():
        d = paired_difference(va, vb, confidence=1.0 - alpha, n_resamples=n_resamples, seed=seed)
        way, unit = direction(metric.strip("|")), metric_unit(metric.strip("|"))
        hw = None if d["ci_low"] is None else (d["ci_high"] - d["ci_low"]) / 2.0
        out.append({"aperture": aperture, "encoding": encoding, "noise": noise, "metric": metric,
                    "unit": unit, "direction": way, "n_scenes": len(scenes),
                    "mean_a": float(np.mean(va)) if va else None, "mean_b": float(np.mean(vb)) if vb else None,
                    "mean_diff": d["value"], "sd_diff": d["sd"], "ci_low": d["ci_low"], "ci_high": d["ci_high"],
                    "half_width": hw, "verdict": verdict(d["ci_low"], d["ci_high"], way),
                    "n_for_power": scenes_for_power(d["value"], d["sd"], alpha=alpha, power=power),
                    "n_for_half_width": scenes_for_half_width(len(scenes), hw, target=target_half_width)
                    if unit == "px (σ)" else None})
    return sorted(out, key=lambda r: (-(r["aperture"] or 0.0), str(r["encoding"]), str(r["noise"]), r["metric"]))


def _num(v, fmt="{:.3f}") -> str:
    return "–" if v is None else fmt.format(v)


def format_comparison(records, a: str, b: str, *, metrics=HEADLINE_METRICS) -> str:
    """Terminal table of the ``metrics`` records: means, B − A [95 % interval], verdict, scenes needed."""
    head = ["metric", "f/N", "enc", "noise", "n", a, b, f"{b} − {a} [95 %]", "±", "verdict", "n@80%", "n@±0.15"]
    body = [[r["metric"], _num(r["aperture"], "{:g}"), str(r["encoding"]), str(r["noise"]), str(r["n_scenes"]),
             _num(r["mean_a"]), _num(r["mean_b"]),
             f"{_num(r['mean_diff'], '{:+.3f}')} [{_num(r['ci_low'], '{:+.3f}')}, {_num(r['ci_high'], '{:+.3f}')}]",
             _num(r["half_width"]), r["verdict"], _num(r["n_for_power"], "{:d}"), _num(r["n_for_half_width"], "{:d}")]
            for m in metrics for r in records if r["metric"] == m]
    widths = [max(len(h), *(len(x[i]) for x in body)) if body else len(h) for i, h in enumerate(head)]
    lines = [f"{b} against {a}: per-scene paired differences B − A (lower is better for every metric shown); "
             "n@80%: scenes for 80 % power at α = 0.05; n@±0.15: scenes for a ±0.15 interval",
             "  ".join(h.ljust(w) for h, w in zip(head, widths))]
    return "\n".join(lines + ["  ".join(c.ljust(w) for c, w in zip(x, widths)) for x in body])
