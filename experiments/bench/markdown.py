"""``accuracy.md``: the Markdown of an accuracy benchmark report.

:func:`accuracy_markdown` renders an :func:`experiments.bench.accuracy.accuracy_report` record: the
overall verdict and notes, one table per analytic dataset (MAE / bias per σ bin with the target row
and the robust verdict), one table per scene set, and the speed rows. The limits quoted in the text
are read from :mod:`experiments.bench.targets` when the text is made.
"""

from __future__ import annotations

from . import targets as _t
from .accuracy import seeds_text
from .lens import lens_markdown
from .mosaics import ANALYTIC_DATASETS, noise_label

__all__ = ["accuracy_markdown"]


def _f(x, fmt=".2f") -> str:
    return "–" if x is None else format(x, fmt)


def _word(ok) -> str:
    return "n/a" if ok is None else ("pass" if ok else "FAIL")


def _bin_cell(v: dict) -> str:
    if v["pass"] is None:
        return "n/a"
    if v["pass"]:
        return "pass"
    why = [k for k, ok in (("MAE", v["mae_ok"]), ("bias", v["bias_ok"])) if ok is False]
    return "FAIL" + (f" ({'+'.join(why)})" if why else " (no pixels)")


def _header(report: dict) -> list[str]:
    cfg, verdict = report["config"], report["verdict"]
    lines = [f"# Accuracy benchmark ({report['date']}, {report['machine']['cpus']} CPUs, "
             f"{report['runtime_s'] / 60:.1f} min)", "",
             "`python -m repro.bench --accuracy`. Targets of the dense-map issue, for the robust preset; "
             "every pass/fail is computed from the numbers below.", "",
             f"**Overall: {_word(verdict['overall'])}** (analytic truth: {_word(verdict['analytic_pass'])}, "
             f"rendered scenes: {_word(verdict['rendered']['pass'])}, speed: {_word(verdict['speed']['pass'])})", ""]
    for note in report["notes"]:
        lines.append(f"- {note}")
    lines.append("")
    lines += ["## 1. Analytic truth (8 bits + Gaussian noise)", "",
              "Dense map over textured valid pixels (`stage_errors` → estimated → `dense_textured`), one bin "
              "per tile σ: cells are MAE / mean signed error (px), pooled over seeds "
              f"{seeds_text(cfg)} (pixel-weighted). `all` = every bin; `oracle` = "
              "the dense MAE when σ_gt itself is fed at the detected edges into Eq. (4) (`oracle_propagate`), "
              "the propagation's own floor; `sparse` = MAE of the edge measures (coverage = share of valid edge "
              "pixels with a measure).",
              f"Targets (robust): MAE ≤ {_t.TARGET_DENSE_MAE_PX:g} px for σ ≤ {_t.TARGET_ABS_MAE_MAX_SIGMA:g}; "
              f"≤ {_t.TARGET_DENSE_REL_MAE:.0%} of σ_gt for {_t.TARGET_ABS_MAE_MAX_SIGMA:g} < σ ≤ "
              f"{_t.TARGET_REL_MAE_MAX_SIGMA:g}; |mean signed error| ≤ max({_t.TARGET_BIAS_PX:g} px, {_t.TARGET_BIAS_REL:.0%} of σ_gt) for σ ≤ "
              f"{_t.TARGET_BIAS_MAX_SIGMA:g} px; no target above. Row `target` gives MAE limit / |bias| limit.", ""]
    return lines


def _target_row(v: dict) -> str:
    cells = [("–" if b["mae_limit"] is None else f"≤{b['mae_limit']:.2f}") + " / "
             + ("–" if b["bias_limit"] is None else f"±{b['bias_limit']:.2f}") for b in v["bins"]]
    return "| | target | " + " | ".join(cells) + " | | | |"


def _dataset_table(report: dict, dataset: str, groups: list[dict], verdicts: dict) -> list[str]:
    """The table of one analytic dataset: one row per (noise, preset), the target and verdict rows."""
    title = ANALYTIC_DATASETS.entry(dataset).summary
    shape = next(r["shape"] for r in report["analytic"]["runs"] if r["dataset"] == dataset)
    lines = [f"### {title}, {shape[0]}×{shape[1]} px", ""]
    bins = groups[0]["dense_textured"]["bins"]
    heads = [f"σ {b['sigma']:g}" + (f" ({b['sigma_gt']:.2f})" if abs(b["sigma_gt"] - b["sigma"]) > 1e-9 else "")
             for b in bins]
    lines += ["| noise | preset | " + " | ".join(heads) + " | all | oracle | sparse (coverage) |",
              "|---|---|" + "---|" * (len(bins) + 3)]
    shown_target = False
    for g in groups:
        v = verdicts.get((dataset, g["noise_std"])) if g["preset"] == "robust" else None
        if v and not shown_target:
            lines.append(_target_row(v))
            shown_target = True
        d, sp = g["dense_textured"], g["sparse"]
        cells = [f"{_f(b['mae'])} / {_f(b['bias'], '+.2f')}" for b in d["bins"]]
        cov = [r["sparse"]["coverage"] for r in report["analytic"]["runs"]
               if (r["dataset"], r["noise_std"], r["preset"]) == (dataset, g["noise_std"], g["preset"])]
        oracle = (g["oracle_propagate_dense_textured"] or {}).get("mae")
        lines.append(f"| {noise_label(g['noise_std'])} | {g['preset']} | " + " | ".join(cells)
                     + f" | {_f(d['mae'])} / {_f(d['bias'], '+.2f')} | {_f(oracle)} | {_f(sp['mae'])} "
                     f"({_f(sum(cov) / len(cov), '.0%') if cov and None not in cov else '–'}) |")
        if v:
            lines.append(f"| {noise_label(g['noise_std'])} | **robust verdict** | "
                         + " | ".join(_bin_cell(b) for b in v["bins"]) + f" | **{_word(v['pass'])}** | | |")
    lines.append("")
    return lines


def _analytic_sections(report: dict) -> list[str]:
    pooled = report["analytic"]["pooled"]
    verdicts = {(v["dataset"], v["noise_std"]): v for v in report["verdict"]["analytic"]}
    lines = []
    for dataset in report["config"]["datasets"]:
        groups = [g for g in pooled if g["dataset"] == dataset]
        if groups:
            lines += _dataset_table(report, dataset, groups, verdicts)
    return lines


def _scene_set_table(name: str, sv: dict, mine: list[dict], by_case: dict, presets: list, ests: list) -> list[str]:
    lines = []
    lines += [f"### Scene set `{name}` — **{_word(sv['pass'])}**", "",
              "| scene | f/N | " + " | ".join(f"dense {p}" for p in presets) + " | robust/paper | verdict | "
              + " | ".join(f"sparse {p}" for p in presets + ests) + " |",
              "|---|---|" + "---|" * (2 * len(presets) + len(ests) + 2)]
    for c in mine:
        v = by_case[(name, c["scene"], c["f_number"])]
        runs = [c["presets"][p] for p in presets] + [c["estimators"][e] for e in ests]
        lines.append(f"| {c['scene']} | {c['f_number']:g} | "
                     + " | ".join(_f(c["presets"][p]["dense_textured"]["mae"]) for p in presets)
                     + f" | {_f(v['ratio'])} | {_word(v['pass'])} | "
                     + " | ".join(f"{_f(r['sparse']['mae'])} ({_f(r['sparse']['coverage'], '.0%')})"
                                  for r in runs)
                     + " |")
    means = [sum(c["presets"][p]["dense_textured"]["mae"] or 0.0 for c in mine) / len(mine) for p in presets]
    m = sv["mean"] or {}
    lines += ["| **mean** | | " + " | ".join(_f(x) for x in means)
              + f" | {_f(m.get('ratio'))} | **{_word(m.get('pass'))}** | "
              + " | ".join("" for _ in presets + ests) + " |", ""]
    return lines


def _rendered_section(report: dict) -> list[str]:
    cfg, cases = report["config"], report["rendered"]["cases"]
    if not cases:
        return []
    rv = report["verdict"]["rendered"]
    presets = list(cases[0]["presets"])
    ests = list(cases[0]["estimators"])
    lines = [f"## 2. Rendered scenes ({cfg['render_preset']} preset, "
             f"{cases[0]['shape'][1]}×{cases[0]['shape'][0]} px, 8-bit sRGB), one table per scene set", "",
             "Dense textured MAE and sparse edge MAE (px) over valid pixels (not occlusion boundaries); "
             "sparse coverage in brackets; estimators run in the paper pipeline. "
             f"Targets: robust dense ≤ {_t.TARGET_RENDER_DENSE_RATIO:g} × paper per case and on each set's mean; "
             f"robust sparse MAE on {_t.TARGET_SPARSE_CASE[0]} f/{_t.TARGET_SPARSE_CASE[1]:g} ≤ min over "
             f"{', '.join(ests) or 'the estimators'}, measured on ≥ {_t.TARGET_MIN_COVERAGE:.0%} of the edge "
             "pixels (a cue that abstains on the hard pixels does not pass).", ""]
    by_case = {(v["scene_set"], v["scene"], v["f_number"]): v for v in rv["cases"]}
    for name, sv in rv.get("sets", {}).items():
        mine = [c for c in cases if c.get("scene_set") == name]
        lines += _scene_set_table(name, sv, mine, by_case, presets, ests)
    s = rv["sparse"]
    if s:
        rob = "no measure" if s["robust_mae"] is None else f"{s['robust_mae']:.3f} px"
        cov = "—" if s.get("robust_coverage") is None else f"{s['robust_coverage']:.0%}"
        lines += [f"Sparse target, {s['scene']} f/{s['f_number']:g}: robust {rob} (coverage {cov}, target ≥ "
                  f"{_t.TARGET_MIN_COVERAGE:.0%}) vs best estimator {s['best_estimator']} {s['best_mae']:.3f} px "
                  f"→ **{_word(s['pass'])}**."]
    lines.append("")
    return lines


def _speed_section(report: dict) -> list[str]:
    rows = report["speed"]["rows"]
    if not rows:
        return []
    sv = report["verdict"]["speed"]
    lines = ["## 3. Speed (whole pipeline, astronaut test image as `python -m repro.bench`)", "",
             "Wall time of `estimate_defocus_map` (no magnification), median of the runs, in this process "
             "after the accuracy runs (numba cache warm); load = 1/5/15-min load average before → after.", "",
             "| preset | size | median (s) | runs (s) | load before | load after |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['preset']} | {r['size']}² | {r['median_s']:.2f} | "
                     + ", ".join(f"{t:.2f}" for t in r["runs_s"])
                     + f" | {' / '.join(f'{x:.2f}' for x in r['load_before'])} | "
                     f"{' / '.join(f'{x:.2f}' for x in r['load_after'])} |")
    lines += ["", f"Target robust ≤ {_t.TARGET_SPEED_RATIO:g} × paper at {sv['size']}²: "
              f"ratio {_f(sv['ratio'])} → "
              f"**{_word(sv['pass'])}**.", ""]
    return lines


def accuracy_markdown(report: dict) -> str:
    """The Markdown of ``accuracy.md``.

    Parameters
    ----------
    report : dict
        An :func:`experiments.bench.accuracy.accuracy_report` record (``config``, ``analytic``,
        ``rendered``, ``speed``, ``verdict``, ``notes``, ``date``, ``machine``, ``runtime_s``; with
        ``lens`` rows also ``lens_verdict``: the lens section, :func:`experiments.bench.lens.lens_markdown`).

    Returns
    -------
    str
        Without a final newline.
    """
    lines = _header(report) + _analytic_sections(report) + _rendered_section(report) + _speed_section(report)
    if report.get("lens"):
        lines += ["", lens_markdown(report["lens"], report["config"]["lens"], report["lens_verdict"])]
    return "\n".join(lines)
