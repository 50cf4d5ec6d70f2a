"""The report's HTML page (``report/index.html``): the same sections as the Markdown page, inline SVG marks."""

from __future__ import annotations

import html
import time
from pathlib import Path

from ._report_text import (GENERALISATION_HEADING, MARKS, cell_texts, column_label, fig_order, figure_files, mark_svg,
                           modes, preset_tables, scene_set_lines)

__all__ = ["build_html"]


def build_html(infos: dict, table, matrix: dict, *, figures_rel: str, bench: str | None,
               figures_dir: Path | None = None, leaderboard: dict | None = None,
               generalisation: dict | None = None, fragile: list | None = None) -> str:
    """A self-contained HTML page (images by relative path); the arguments as in
    :func:`repro._report_markdown.build_markdown`."""
    from experiments.claims import SELF_CHECK_NOTE, fragile_claims

    e = html.escape
    fragile = fragile_claims(matrix) if fragile is None else fragile
    rows = _html_claims_table(matrix, fragile) + _html_fragile(fragile)
    details_html = _html_evidence(matrix)
    legend = (" ".join(f"{mark_svg(v)} {e(v)}" for v in MARKS)
              + f"; a dashed cell ({e(SELF_CHECK_NOTE)}): the harness agreeing with itself (a renderer that implements "
              "the formula checked, or analytic steps that draw nothing from the scenes they are shown under)")
    sets_html = "<h2>Scene sets</h2><p>The figures are computed on the hand-built scene sets and, where the claim " \
                "can be computed on it, on the procedural test split; the first image of each figure is its default " \
                "set, the further images the other sets.</p><ul>" + "".join(
                    f"<li><b>{e(n)}</b> ({e(w)})<ul>" + "".join(f"<li>{e(x)}</li>" for x in sc) + "</ul></li>"
                    for n, w, sc in scene_set_lines()) + "</ul>"
    figs = _html_figures(infos, figures_rel=figures_rel, figures_dir=figures_dir)
    bench_html = f"<h2>Speed</h2><pre>{e(bench)}</pre>" if bench else ""
    preset_html = _html_tables(preset_tables(table), "presets")
    if preset_html:
        preset_html = ("<h2>Presets side by side</h2><p><code>paper</code> is the reproduction, <code>robust</code> "
                       "goes beyond the paper, <code>zhuo_sim</code> is the Zhuo &amp; Sim 2011 baseline. Errors "
                       "against σ_gt in px (edge MAE; dense MAE over textured pixels, bias in brackets).</p>" + preset_html)
    board_html = ""
    if leaderboard:
        from experiments.leaderboard import leaderboard_intro, leaderboard_tables

        board_html = (f"<h2>Leaderboard</h2><p>{e(leaderboard_intro(leaderboard))}</p>"
                      + _html_tables(leaderboard_tables(leaderboard), "leaderboard"))
    if generalisation:
        from ._report_gap import generalisation_intro

        board_html += (f"<h2>{e(GENERALISATION_HEADING)}</h2><p>{e(generalisation_intro(generalisation))}</p>"
                       + _html_tables(generalisation["tables"], "generalisation"))
    mismatch_html = _html_mismatch(table)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>Defocus Magnification — reproduction report</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; padding: 0 1em; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #ccc; padding: 4px 8px; vertical-align: top; }}
td.reproduced, tr.reproduced td:nth-child(3) {{ color: #1a7f37; }}
td.not-reproduced, tr.not-reproduced td:nth-child(3) {{ color: #cf222e; }}
td.partly-reproduced, tr.partly-reproduced td:nth-child(3) {{ color: #9a6700; }}
td.self-check {{ border: 2px dashed #6e7781; font-style: italic; }}
svg.mark {{ vertical-align: -3px; }} figure {{ margin: 0 0 1em 0; }} figcaption {{ font-style: italic; }}
details {{ margin: 0.5em 0; }} summary {{ cursor: pointer; font-weight: bold; }}
img {{ max-width: 100%; border: 1px solid #eee; }}
</style></head><body>
<h1>Defocus Magnification (Bae &amp; Durand 2007): reproduction report</h1>
<p>Generated {e(time.strftime('%Y-%m-%d %H:%M'))} by <code>python -m repro.report</code> from the results table of
<code>python -m repro.figures</code> (mode: {e(modes(infos))}).</p>
<h2>The paper's claims, checked</h2>
<p>One column per method preset and scene set. Marks: {legend}</p>
{rows}
{details_html}
{sets_html}
{mismatch_html}
{preset_html}
{board_html}
<h2>Figures</h2>
{figs}
{bench_html}
</body></html>
"""


def _html_claims_table(matrix: dict, fragile) -> str:
    """The claims × (preset, scene set) verdict table of the HTML page ('' without columns)."""
    e = html.escape
    columns = list(matrix)
    if not columns:
        return ""
    head = "".join(f"<th>{e(column_label(*c))}</th>" for c in columns)
    texts = cell_texts(matrix, fragile)

    def td(c, claim):
        verdict, note, self_check = texts[(c, claim.id)]
        if verdict is None:
            return f"<td class='same'>{e(note)}</td>"
        cls = verdict.replace(" ", "-") + (" self-check" if self_check else "")
        return (f"<td class='{e(cls)}'>{mark_svg(verdict)} {e(verdict)}"
                + (f" <small>({e(note)})</small>" if note else "") + "</td>")

    body = []
    for claim, _ in matrix[columns[0]]:
        cells = "".join(td(c, claim) for c in columns)
        body.append(f"<tr><td>{e(claim.text)}</td><td>{e(claim.section)} ({e(claim.figure)})</td>{cells}</tr>")
    return (f"<table id='claims' class='claims'><tr><th>claim</th><th>where</th>{head}</tr>\n"
            + "\n".join(body) + "\n</table><p>Every cell is its own evaluation; a claim that does not depend "
            "on the preset or the scene set is computed once and its further cells say “=” (the same "
            "evaluation; <code>claims.json</code> names each cell's).</p>")


def _html_evidence(matrix: dict) -> str:
    """One collapsible evidence table per column (the first open)."""
    e = html.escape
    from experiments.claims import SELF_CHECK_NOTE, cell_sources, is_self_check

    sources = cell_sources(matrix)

    def evidence_row(col, c, v):
        src = sources.get((col, c.id))
        if src is not None:
            return (f"<tr class='same'><td>{mark_svg(v.verdict)}</td><td>{e(c.text)}</td><td>=</td>"
                    f"<td>same evaluation as <i>{e(column_label(*src))}</i> (<code>{e(v.evaluation)}</code>)</td></tr>")
        ev = f"<br>Evaluation: <code>{e(v.evaluation)}</code>." if v.evaluation else ""
        own = (f"<i>{e(SELF_CHECK_NOTE.capitalize())}: {e(c.self_check)}.</i><br>"
               if is_self_check(c, col[1], v) else "")
        return (f"<tr class='{e(v.verdict.replace(' ', '-'))}'><td>{mark_svg(v.verdict)}</td><td>{e(c.text)}</td>"
                f"<td><b>{e(v.verdict)}</b></td><td>{own}{e(v.evidence)}{ev}<br><i>Rule: {e(c.rule)}.</i></td></tr>")

    details = []
    for j, col in enumerate(matrix):
        trs = "\n".join(evidence_row(col, c, v) for c, v in matrix[col])
        details.append(f"<details{' open' if j == 0 else ''}><summary>Evidence: {e(column_label(*col))}</summary>"
                       f"<table class='evidence'><tr><th></th><th>claim</th><th>verdict</th><th>evidence</th></tr>"
                       f"{trs}</table></details>")
    return "\n".join(details)


def _html_figures(infos: dict, *, figures_rel: str, figures_dir: Path | None) -> str:
    """One section per figure: its images (linked to the PDF), captions, σ convention and metrics link."""
    e = html.escape
    return "\n".join(
        f"<section id='{e(n)}'><h3>{e(n)}: {e(infos[n].get('title', ''))}</h3>"
        + "".join(f"<figure><a href='{figures_rel}/{e(stem)}.pdf'><img src='{figures_rel}/{e(stem)}.png' "
                  f"alt='{e(stem)}'></a>" + (f"<figcaption>{e(cap)}</figcaption>" if cap else "") + "</figure>"
                  for stem, cap in figure_files(n, infos[n], figures_dir))
        + f"<p>σ convention: {e(str(infos[n].get('sigma_convention', 'n/a')))}. "
        f"<a href='{figures_rel}/{e(n)}.metrics.json'>metrics</a></p></section>"
        for n in fig_order(infos))


def _html_tables(tables: list[dict], css_class: str) -> str:
    """Titled HTML tables (``{"title", "header", "rows"}`` each) of class ``css_class``."""
    e = html.escape
    return "".join(
        f"<h3>{e(t['title'])}</h3><table class='{css_class}'><tr>" + "".join(f"<th>{e(h)}</th>" for h in t["header"])
        + "</tr>" + "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in t["rows"]) + "</table>"
        for t in tables)


def _html_mismatch(table) -> str:
    """The model-mismatch section of the HTML page ('' when nothing was measured)."""
    from experiments.claims import mismatch_findings

    e = html.escape
    findings = mismatch_findings(table)
    if not findings:
        return ""
    return ("<h2>Beyond the paper: model mismatch</h2><p>The method assumes a Gaussian-blurred step in "
            "the pixel values; a thin lens blurs with a disk in linear light and a camera stores sRGB. "
            "Measured bias shifts (px):</p><table><tr><th>effect</th><th>estimator</th><th>pixels</th>"
            "<th>value (px)</th></tr>" + "".join(
                f"<tr><td>{e(r['effect'])}</td><td>{e(r['estimator'])}</td><td>{e(r['edges'])}</td>"
                f"<td>{r['bias_shift_px']:+.3f}</td></tr>" for r in findings) + "</table>")


def _html_fragile(fragile: list[dict]) -> str:
    """The fragile verdicts with both evidences ('' when none)."""
    e = html.escape
    if not fragile:
        return ""
    items = []
    for f in fragile:
        t = f["test"]
        hand = "".join(f"<li>{e(h['scene_set'] or 'hand-built')}: {mark_svg(h['verdict'])} <b>{e(h['verdict'])}</b>: {e(h['evidence'])} "
                       f"(<code>{e(h['evaluation'])}</code>)</li>" for h in f["hand_built"])
        items.append(f"<li><b>{e(f['claim'])}</b>, {e(f['preset'])} preset<ul><li>procedural_test: "
                     f"{mark_svg(t['verdict'])} <b>{e(t['verdict'])}</b>: {e(t['evidence'])} "
                     f"(<code>{e(t['evaluation'])}</code>)</li>{hand}</ul></li>")
    return ("<h2 id='fragile'>Fragile verdicts</h2><p>A verdict is fragile when it differs between the hand-built "
            "scene sets (the scenes every preset was tuned on) and the procedural test split (scenes nobody tuned "
            "on). Both evidences:</p><ul>" + "".join(items) + "</ul>")
