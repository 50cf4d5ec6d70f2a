"""The report's Markdown page (``report/README.md``): claims table, fragile verdicts, evidence, tables, figures."""

from __future__ import annotations

import time
from pathlib import Path

from ._report_text import (GENERALISATION_HEADING, KEY_FIGURES, MARKS, PRESET_TABLES_INTRO, SELF_CHECK_LEGEND, cell_texts,
                           column_label, fig_order, figure_files, mark, md_cell, modes, preset_tables, scene_set_lines)

__all__ = ["build_markdown", "fragile_lines", "md_tables", "md_verdict_cell"]


def md_verdict_cell(text) -> str:
    """A claims-table cell from :func:`repro._report_text.cell_texts`: the mark (bracketed for a harness
    self-check) and verdict (and its note), or the note alone for a repeated cell."""
    verdict, note, self_check = text
    if verdict is None:
        return note
    return f"`{mark(verdict, self_check=self_check)}` {verdict}" + (f" ({note})" if note else "")


def build_markdown(infos: dict, table, matrix: dict, *, figures_rel: str, bench: str | None,
                   figures_dir: Path | None = None, leaderboard: dict | None = None,
                   generalisation: dict | None = None, fragile: list | None = None) -> str:
    """The Markdown report (GitHub renders it next to the figures).

    Parameters
    ----------
    infos : dict
        ``{figure: its metrics file}`` (mode, config, σ convention, output files).
    table : experiments.results_query.Results
        The results table the figures wrote.
    matrix : dict
        :func:`experiments.claims.claim_matrix` (``{(preset, scene set): [(Claim, Verdict)]}``).
    figures_rel : str
        Path of the figures folder relative to the report.
    bench : str or None
        The speed summary (Markdown), if any.
    figures_dir : Path, optional, keyword-only
        The figures folder on disk (only its existing images are shown).
    leaderboard : dict, optional, keyword-only
        :func:`experiments.leaderboard.build_leaderboard`'s result, shown as one table per protocol.
    generalisation : dict, optional, keyword-only
        :func:`repro._report_gap.load_generalisation`'s result: dev and test side by side, test − dev.
    fragile : list, optional, keyword-only
        :func:`experiments.claims.fragile_claims` (default: computed from ``matrix``).
    """
    from experiments.claims import fragile_claims

    fragile = fragile_claims(matrix) if fragile is None else fragile
    lines = [
        "# Defocus Magnification (Bae & Durand 2007): reproduction report",
        "",
        f"Generated {time.strftime('%Y-%m-%d %H:%M')} by `python -m repro.report` from the results table of "
        f"`python -m repro.figures` (mode: {modes(infos)}). Do not edit by hand.",
        "",
        "## The paper's claims, checked",
        "",
        "Verdict marks: " + ", ".join(f"`{m}` {v}" for v, m in MARKS.items()) + "; " + SELF_CHECK_LEGEND
        + ". One column per method preset and scene set; the evidence and the rule of every cell follow.",
        "",
    ]
    lines += _claims_table(matrix, fragile)
    lines += fragile_lines(fragile)
    lines += _scene_sets()
    lines += _evidence(matrix)
    lines += _mismatch(table)
    tables = preset_tables(table)
    if tables:
        lines += md_tables("Presets side by side", PRESET_TABLES_INTRO, tables)
    if leaderboard:
        from experiments.leaderboard import leaderboard_intro, leaderboard_tables

        lines += md_tables("Leaderboard", md_cell(leaderboard_intro(leaderboard)), leaderboard_tables(leaderboard),
                           escape_titles=True)
    if generalisation:
        from ._report_gap import generalisation_intro

        lines += md_tables(GENERALISATION_HEADING, generalisation_intro(generalisation), generalisation["tables"],
                           escape_titles=True)
    lines += _figures(infos, figures_rel=figures_rel, figures_dir=figures_dir)
    if bench:
        lines += ["## Speed", "", bench.replace("# Benchmark", "Benchmark", 1), ""]
    return "\n".join(lines) + "\n"


def _claims_table(matrix: dict, fragile) -> list[str]:
    """The claims × (preset, scene set) verdict table and the note on shared evaluations."""
    columns = list(matrix)
    if not columns:
        return []
    lines = ["| claim | where | " + " | ".join(column_label(*c) for c in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    texts = cell_texts(matrix, fragile)
    for claim, _ in matrix[columns[0]]:
        cells = [md_verdict_cell(texts[(c, claim.id)]) for c in columns]
        lines.append(f"| {md_cell(claim.text)} | {claim.section} ({claim.figure}) | " + " | ".join(cells) + " |")
    return lines + ["", "Every cell is its own evaluation (its figure's cases for that preset on that scene set). A "
                    "claim that does not depend on the preset or the scene set is computed once per value it does "
                    "depend on, and its further cells say `=` (the same evaluation): Eq. (5) and Eq. (6) are optics "
                    "(once for the hand-built sets); Fig. 4's analytic edges have no scene set (once per preset); "
                    "Fig. 5 tests the paper's Eq. (3) filter with and without its bias (once per scene set). The "
                    "procedural test split is always its own evaluation. The evaluation of every cell is named in "
                    "`claims.json`.", ""]


def fragile_lines(fragile: list[dict]) -> list[str]:
    """The section listing every fragile verdict with the test split's and each hand-built set's evidence."""
    from experiments.claims import CLAIMS

    if not fragile:
        return []
    text = {c.id: c.text for c in CLAIMS}
    lines = ["## Fragile verdicts", "",
             "A verdict is fragile when it differs between the hand-built scene sets (the scenes every preset was "
             "tuned on) and the procedural test split (scenes nobody tuned on): the claim's outcome then hangs on "
             "which few scenes were chosen. Both evidences:", ""]
    for f in fragile:
        t = f["test"]
        lines += [f"- **{f['claim']}** ({md_cell(text.get(f['claim'], ''))}), {f['preset']} preset:",
                  f"  - procedural_test: `{mark(t['verdict'])}` **{t['verdict']}**: {md_cell(t['evidence'])} "
                  f"(`{t['evaluation']}`)"]
        lines += [f"  - {h['scene_set'] or 'hand-built'}: `{mark(h['verdict'])}` **{h['verdict']}**: {md_cell(h['evidence'])} "
                  f"(`{h['evaluation']}`)" for h in f["hand_built"]]
    return lines + [""]


def _evidence(matrix: dict) -> list[str]:
    """One evidence table per (preset, scene set) column: verdict, evidence and rule of each claim."""
    from experiments.claims import SELF_CHECK_NOTE, cell_sources, is_self_check

    lines = []
    sources = cell_sources(matrix)
    for col, rows in matrix.items():
        lines += [f"### Evidence: {column_label(*col)}", "", "| | claim | verdict | evidence |", "|---|---|---|---|"]
        for claim, v in rows:
            src = sources.get((col, claim.id))
            own = is_self_check(claim, col[1], v)
            m = mark(v.verdict, self_check=own)
            if src is not None:
                lines.append(f"| `{m}` | {md_cell(claim.text)} | = | same evaluation as "
                             f"*{column_label(*src)}* (`{v.evaluation}`) |")
                continue
            ev = f" <br>Evaluation: `{v.evaluation}`." if v.evaluation else ""
            own_text = f"*{SELF_CHECK_NOTE.capitalize()}: {md_cell(claim.self_check)}.* <br>" if own else ""
            lines.append(f"| `{m}` | {md_cell(claim.text)} | **{v.verdict}** | {own_text}{md_cell(v.evidence)} "
                         f"{ev}<br>*Rule: {md_cell(claim.rule)}.* |")
        counts = {k: sum(1 for _, v in rows if v.verdict == k) for k in MARKS}
        checks = sum(1 for c, v in rows if is_self_check(c, col[1], v))
        lines += ["", "Totals: " + ", ".join(f"{k}: {n}" for k, n in counts.items() if n)
                  + (f" (of these, harness self-checks: {checks})" if checks else ""), ""]
    return lines


def _mismatch(table) -> list[str]:
    """The model-mismatch section (bias shifts of the Gaussian-step model), if any were measured."""
    from experiments.claims import mismatch_findings

    findings = mismatch_findings(table)
    if not findings:
        return []
    lines = ["## Beyond the paper: model mismatch", "",
             "The method assumes a Gaussian-blurred step in the pixel values; a thin lens blurs with a "
             "disk in linear light and a camera stores sRGB. Bias shifts below are measured, in px.", "",
             "| effect | estimator | pixels | value (px) |", "|---|---|---|---|"]
    lines += [f"| {r['effect']} | {r['estimator']} | {r['edges']} | {r['bias_shift_px']:+.3f} |" for r in findings]
    return lines + [""]


def md_tables(heading: str, intro: str, tables: list[dict], *, escape_titles: bool = False) -> list[str]:
    """A section of titled tables (``{"title", "header", "rows"}`` each) under ``heading``."""
    lines = [f"## {heading}", "", intro, ""]
    for t in tables:
        title = md_cell(t["title"]) if escape_titles else t["title"]
        lines += [f"**{title}**", "", "| " + " | ".join(t["header"]) + " |", "|" + "---|" * len(t["header"])]
        lines += ["| " + " | ".join(md_cell(c) for c in r) + " |" for r in t["rows"]]
        lines.append("")
    return lines


def _scene_sets() -> list[str]:
    lines = ["## Scene sets", "",
             "The figures are computed on the hand-built scene sets and, where the claim can be computed on it, on "
             "the procedural test split; the first image of each figure is its default set, the further images "
             "(`<fig>_<set>.png`) the other sets.", ""]
    for name, what, scenes in scene_set_lines():
        lines += [f"- **{name}** ({what}):"] + [f"  - {md_cell(x)}" for x in scenes]
    return lines + [""]


def _figures(infos: dict, *, figures_rel: str, figures_dir: Path | None) -> list[str]:
    """The figures, key figures first, each with its captions and links to its metrics and PDF."""
    lines = ["## Figures", ""]
    for name in [n for n in KEY_FIGURES if n in infos] + [n for n in fig_order(infos) if n not in KEY_FIGURES]:
        m = infos[name]
        lines += [f"### {name}: {m.get('title', '')}", ""]
        for stem, caption in figure_files(name, m, figures_dir):
            if caption:
                lines += [f"*{caption}*", ""]
            lines += [f"![{stem}]({figures_rel}/{stem}.png)", ""]
        lines += [f"σ convention: {m.get('sigma_convention', 'n/a')}. "
                  f"Metrics: [`{name}.metrics.json`]({figures_rel}/{name}.metrics.json) and the rows with figure = "
                  f"`{name}` of [`results.csv`]({figures_rel}/results.csv), vector: "
                  f"[`{name}.pdf`]({figures_rel}/{name}.pdf).", ""]
    return lines
