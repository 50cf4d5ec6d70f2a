"""Build the report: ``report/index.html`` and ``report/README.md`` from the figures' metrics.

``python -m repro.report [--figures report/figures] [--out report] [--external NAME=MAPDIR ...] [--dataset DIR]
[--evaluations report/evaluations]``

Reads every ``<fig>.metrics.json`` that ``python -m repro.figures`` wrote, checks each of the paper's
claims (:mod:`experiments.claims`) and writes, atomically, an HTML page (images by relative path)
and a Markdown page with the verdict table, the evidence numbers and the key figures. Nothing in
the report is typed by hand: rerun the figures and this command to refresh it.

``--external NAME=MAPDIR`` (repeatable) adds a leaderboard (:mod:`experiments.leaderboard`): every
method preset and every external map folder, one row each, per scene set and protocol, on the images
of ``--dataset DIR`` (a ``repro.dataset export`` folder; no renderer needed) or, without it, on the
harness's renders named by the maps. Also written to ``<out>/leaderboard.json``. A map that cannot be
scored is one line on stderr naming the entry and the file.

Generalisation: the newest evaluation of each split of the procedural scene family under
``--evaluations`` (``python -m repro.evaluate --procedural N --split dev|test|fresh`` writes there)
gives, per preset and aperture, the dev and test errors side by side with 95 % bootstrap intervals and
test − dev (:mod:`repro._report_gap`); also written to ``<out>/generalisation.json``. Without both a
dev and a test evaluation the section is left out.
"""

from __future__ import annotations

import html
import json
import sys
import time
from pathlib import Path

from repro._cli import ArgumentParser, run_cli

#: Text mark of each verdict (Markdown, README, terminal): ASCII, so it reads in any font.
MARKS = {"reproduced": "+", "partly reproduced": "~", "not reproduced": "-", "not evaluated": "?", "error": "!"}
_COLOURS = {"reproduced": "#1a7f37", "partly reproduced": "#9a6700", "not reproduced": "#cf222e",
            "not evaluated": "#6e7781", "error": "#000000"}
#: Inline SVG path(s) drawn inside a 16x16 circle for each verdict (HTML; no font needed).
_SVG_GLYPH = {
    "reproduced": "<path d='M4.5 8.5l2.5 2.5 4.5-5' fill='none' stroke='#fff' stroke-width='2'/>",
    "partly reproduced": "<path d='M8 2a6 6 0 0 1 0 12z' fill='#fff'/>",
    "not reproduced": "<path d='M5 5l6 6M11 5l-6 6' stroke='#fff' stroke-width='2'/>",
    "not evaluated": "<path d='M5 8h6' stroke='#fff' stroke-width='2'/>",
    "error": "<path d='M8 4v5M8 11v1.5' stroke='#fff' stroke-width='2'/>",
}
_PROJECT_ROOT = Path(__file__).resolve().parents[1]

#: Figures shown in the Markdown report, in this order (all of them appear in the HTML page).
KEY_FIGURES = ("fig4", "fig5", "fig6", "fig7", "fig11", "fig2", "fig10")


def mark_svg(verdict: str) -> str:
    """An inline SVG mark (16 px circle in the verdict's colour with a white glyph) with a text title."""
    colour = _COLOURS.get(verdict, "#000000")
    glyph = _SVG_GLYPH.get(verdict, "")
    return (f"<svg class='mark' width='16' height='16' viewBox='0 0 16 16' role='img' aria-label='{html.escape(verdict)}'>"
            f"<title>{html.escape(verdict)}</title><circle cx='8' cy='8' r='7' fill='{colour}'/>{glyph}</svg>")


def _mark(verdict: str) -> str:
    return MARKS.get(verdict, "!")


def _as_matrix(verdicts) -> dict:
    """A :func:`experiments.claims.claim_matrix` dict; a plain verdict list becomes ``{("paper", None): list}``."""
    if isinstance(verdicts, dict):
        return verdicts
    return {("paper", None): list(verdicts)}


def column_label(preset: str, scene_set) -> str:
    """Heading of one (preset, scene set) column."""
    return f"{preset} preset" if scene_set is None else f"{preset} preset, {scene_set}"


def scene_set_lines() -> list[tuple[str, str, list[str]]]:
    """``(set name, what it is, ["scene: description"])`` for each scene set (from :mod:`scenes`)."""
    from scenes import SCENE_SETS, SCENES

    what = {"paper_cameras": "default: the paper's cameras (Canon 1D Mark II 85 mm, Nikon D50 180 mm) at real-world "
                             "distances, σ_gt from the pixel-filter floor to about 4 px at f/8 and 8 px at f/4 (full preset)",
            "tabletop_stress": "stress test: tabletop macro shots (50 mm full frame focused at 0.2-0.25 m), σ_gt up "
                               "to 12-17 px at f/4 (full preset), far beyond the paper's photos"}
    return [(name, what.get(name, ""), [f"{n}: {SCENES[n].description}" for n in names])
            for name, names in SCENE_SETS.items()]


def cell_texts(matrix: dict) -> dict:
    """``{(column, claim id): (verdict or None, note)}`` of the claims table.

    A cell with its own evaluation shows its verdict, with the claim's :func:`experiments.claims.scope_note`
    (e.g. "all presets and scene sets") when later cells repeat its evaluation; a cell that repeats
    an earlier column's evaluation shows no verdict and the note ``"="`` (claims that vary with nothing)
    or ``"= <column>"``.
    """
    from experiments.claims import cell_sources, scope_note

    sources = cell_sources(matrix)
    repeated = {(src, cid) for (_, cid), src in sources.items() if src is not None}
    out = {}
    for col, rows in matrix.items():
        for claim, v in rows:
            src = sources.get((col, claim.id))
            if src is None:
                out[(col, claim.id)] = (v.verdict, scope_note(claim) if (col, claim.id) in repeated else "")
            else:
                out[(col, claim.id)] = (None, "=" if not claim.varies_with else f"= {column_label(*src)}")
    return out


def _md_verdict_cell(text) -> str:
    verdict, note = text
    if verdict is None:
        return note
    return f"`{_mark(verdict)}` {verdict}" + (f" ({note})" if note else "")


def _md_cell(text: str) -> str:
    """Text safe inside a Markdown table cell (pipes escaped)."""
    return str(text).replace("|", "\\|")


def load_metrics(folder: Path) -> dict:
    """``{figure name: parsed metrics file}`` for every ``*.metrics.json`` in ``folder``."""
    out = {}
    for path in sorted(folder.glob("*.metrics.json")):
        try:
            out[path.name.split(".")[0]] = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ValueError(f"cannot read {path}: {exc}") from None
    return out


def _fig_order(names):
    def key(n):
        digits = "".join(ch for ch in n if ch.isdigit())
        return (int(digits) if digits else 999, n)
    return sorted(names, key=key)


def _modes(metrics: dict) -> str:
    modes = sorted({m.get("mode", "?") for m in metrics.values()})
    return ", ".join(modes)


def _bench_summary(out: Path) -> str | None:
    path = out / "bench" / "bench.md"
    return path.read_text() if path.exists() else None


def preset_tables(metrics: dict) -> list[dict]:
    """Presets side by side, one table per scene set, from the ``stages`` figure's metrics.

    Returns
    -------
    list of dict
        ``{"title", "header", "rows"}`` per scene set (analytic mosaics; rendered scenes): one row per
        case with, per preset, the sparse edge MAE and the dense textured MAE (bias) in px. Empty
        when the ``stages`` figure has not been computed.
    """
    m = metrics.get("stages", {}).get("metrics")
    if not m:
        return []
    presets = m["presets"]
    sets = {"mosaic": ("Analytic texture mosaics (8-bit + noise; σ_gt exact)", []),
            "render": (f"Rendered scenes ({metrics['stages'].get('mode', '?')} mode)", [])}
    for label, case in m["cases"].items():
        row = [label]
        for pname in presets:
            est = case[pname]["estimated"]
            sp, dt = est["sparse"], est["dense_textured"]
            row.append("–" if sp["mae"] is None else f"{sp['mae']:.2f}")
            row.append("–" if dt["mae"] is None else f"{dt['mae']:.2f} ({dt['bias']:+.2f})")
        sets[case["kind"]][1].append(row)
    header = ["case"] + [f"{p}: {what}" for p in presets for what in ("edge MAE", "dense MAE (bias)")]
    return [{"title": t, "header": header, "rows": rows} for t, rows in sets.values() if rows]


def leaderboard_tables(board: dict) -> list[dict]:
    """:func:`experiments.leaderboard.leaderboard_tables` (one table per protocol)."""
    from experiments.leaderboard import leaderboard_tables as tables

    return tables(board)


def leaderboard_intro(board: dict) -> str:
    """One paragraph: what the leaderboard's rows are and where the ground truth comes from."""
    return ("One row per method preset and external map folder, per scene set and protocol: the mean over the "
            f"images of the per-image metric. Ground truth: {board['ground_truth']}; occlusion bands excluded. "
            "Presets: the method on each image's 8-bit sRGB input (as `repro.estimate --preset NAME` on the "
            "exported PNG). Protocols: docs/dataset.md."
            + (f" Not scored: {len(board['problems'])} map(s) (listed in leaderboard.json)." if board["problems"] else ""))


def build_markdown(metrics: dict, verdicts, *, figures_rel: str, bench: str | None,
                   figures_dir: Path | None = None, leaderboard: dict | None = None,
                   generalisation: dict | None = None) -> str:
    """The Markdown report (GitHub renders it next to the figures).

    Parameters
    ----------
    metrics : dict
        ``{figure: metrics file}`` (:func:`load_metrics`).
    verdicts : dict or list
        :func:`experiments.claims.claim_matrix` (``{(preset, scene set): [(Claim, Verdict)]}``), or
        one list of (Claim, Verdict) (shown as the ``paper`` preset).
    figures_rel : str
        Path of the figures folder relative to the report.
    bench : str or None
        The speed summary (Markdown), if any.
    figures_dir : Path, optional, keyword-only
        The figures folder on disk, to find the per-scene-set figure files ``<fig>_<set>.png``.
    leaderboard : dict, optional, keyword-only
        :func:`experiments.leaderboard.build_leaderboard`'s result, shown as one table per protocol.
    generalisation : dict, optional, keyword-only
        :func:`repro._report_gap.load_generalisation`'s result: dev and test side by side, test − dev.
    """
    matrix = _as_matrix(verdicts)
    lines = [
        "# Defocus Magnification (Bae & Durand 2007): reproduction report",
        "",
        f"Generated {time.strftime('%Y-%m-%d %H:%M')} by `python -m repro.report` from the metrics of "
        f"`python -m repro.figures` (mode: {_modes(metrics)}). Do not edit by hand.",
        "",
        "## The paper's claims, checked",
        "",
        "Verdict marks: " + ", ".join(f"`{m}` {v}" for v, m in MARKS.items()) + ". One column per method "
        "preset and scene set; the evidence and the rule of every cell follow.",
        "",
    ]
    lines += _md_claims_table(matrix)
    lines += _md_scene_sets()
    lines += _md_evidence(matrix)
    lines += _md_mismatch(metrics)
    tables = preset_tables(metrics)
    if tables:
        lines += _md_tables("Presets side by side", PRESET_TABLES_INTRO, tables)
    if leaderboard:
        lines += _md_tables("Leaderboard", _md_cell(leaderboard_intro(leaderboard)), leaderboard_tables(leaderboard),
                            escape_titles=True)
    if generalisation:
        from ._report_gap import generalisation_intro

        lines += _md_tables(GENERALISATION_HEADING, generalisation_intro(generalisation), generalisation["tables"],
                            escape_titles=True)
    lines += _md_figures(metrics, figures_rel=figures_rel, figures_dir=figures_dir)
    if bench:
        lines += ["## Speed", "", bench.replace("# Benchmark", "Benchmark", 1), ""]
    return "\n".join(lines) + "\n"


#: Heading of the generalisation section (Markdown and HTML).
GENERALISATION_HEADING = "Generalisation: dev and test scenes"
#: The paragraph under "Presets side by side" (Markdown and HTML).
PRESET_TABLES_INTRO = (
    "`paper` is the reproduction (`DefocusParams()`), `robust` goes beyond the paper ("
    "`docs/presets.md`), `zhuo_sim` is the Zhuo & Sim 2011 baseline. Errors against σ_gt in px: sparse blur "
    "at the edge pixels, dense map over textured pixels (mean signed error in brackets); occlusion "
    "boundaries and tile seams excluded. From the `stages` figure.")


def _md_claims_table(matrix: dict) -> list[str]:
    """The claims × (preset, scene set) verdict table and the note on shared evaluations."""
    columns = list(matrix)
    if not columns:
        return []
    lines = ["| claim | where | " + " | ".join(column_label(*c) for c in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    texts = cell_texts(matrix)
    for claim, _ in matrix[columns[0]]:
        cells = [_md_verdict_cell(texts[(c, claim.id)]) for c in columns]
        lines.append(f"| {_md_cell(claim.text)} | {claim.section} ({claim.figure}) | " + " | ".join(cells) + " |")
    return lines + ["", "Every cell is its own evaluation (its figure computed with that preset's parameters on that "
                    "scene set). A claim that does not depend on the preset or the scene set is computed once per value "
                    "it does depend on, and its further cells say `=` (the same evaluation): Eq. (5) and Eq. (6) are "
                    "optics (once in all); Fig. 4's analytic edges have no scene set (once per preset); Fig. 5 tests "
                    "the paper's Eq. (3) filter with and without its bias (once per scene set). The evaluation of "
                    "every cell is named in `claims.json`.", ""]


def _md_evidence(matrix: dict) -> list[str]:
    """One evidence table per (preset, scene set) column: verdict, evidence and rule of each claim."""
    lines = []
    sources = cell_sources_of(matrix)
    for col, rows in matrix.items():
        lines += [f"### Evidence: {column_label(*col)}", "",
                  "| | claim | verdict | evidence |", "|---|---|---|---|"]
        for claim, v in rows:
            src = sources.get((col, claim.id))
            if src is not None:
                lines.append(f"| `{_mark(v.verdict)}` | {_md_cell(claim.text)} | = | same evaluation as "
                             f"*{column_label(*src)}* (`{v.evaluation}`) |")
                continue
            ev = f" <br>Evaluation: `{v.evaluation}`." if v.evaluation else ""
            lines.append(f"| `{_mark(v.verdict)}` | {_md_cell(claim.text)} | **{v.verdict}** | {_md_cell(v.evidence)} "
                         f"{ev}<br>*Rule: {_md_cell(claim.rule)}.* |")
        counts = {k: sum(1 for _, v in rows if v.verdict == k) for k in MARKS}
        lines += ["", "Totals: " + ", ".join(f"{k}: {n}" for k, n in counts.items() if n), ""]
    return lines


def _md_mismatch(metrics: dict) -> list[str]:
    """The model-mismatch section (bias shifts of the Gaussian-step model), if any were measured."""
    from experiments.claims import mismatch_findings

    findings = mismatch_findings(metrics)
    if not findings:
        return []
    lines = ["## Beyond the paper: model mismatch", "",
             "The method assumes a Gaussian-blurred step in the pixel values; a thin lens blurs with a "
             "disk in linear light and a camera stores sRGB. Bias shifts below are measured, in px.", "",
             "| effect | estimator | pixels | value (px) |", "|---|---|---|---|"]
    lines += [f"| {r['effect']} | {r['estimator']} | {r['edges']} | {r['bias_shift_px']:+.3f} |" for r in findings]
    return lines + [""]


def _md_tables(heading: str, intro: str, tables: list[dict], *, escape_titles: bool = False) -> list[str]:
    """A section of titled tables (``{"title", "header", "rows"}`` each) under ``heading``."""
    lines = [f"## {heading}", "", intro, ""]
    for t in tables:
        title = _md_cell(t["title"]) if escape_titles else t["title"]
        lines += [f"**{title}**", "", "| " + " | ".join(t["header"]) + " |", "|" + "---|" * len(t["header"])]
        lines += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in t["rows"]]
        lines.append("")
    return lines


def _md_figures(metrics: dict, *, figures_rel: str, figures_dir: Path | None) -> list[str]:
    """The figures, key figures first, each with its captions and links to its metrics and PDF."""
    lines = ["## Figures", ""]
    for name in [n for n in KEY_FIGURES if n in metrics] + [n for n in _fig_order(metrics) if n not in KEY_FIGURES]:
        m = metrics[name]
        lines += [f"### {name}: {m.get('title', '')}", ""]
        for stem, caption in figure_files(name, m, figures_dir):
            if caption:
                lines += [f"*{caption}*", ""]
            lines += [f"![{stem}]({figures_rel}/{stem}.png)", ""]
        lines += [f"σ convention: {m.get('sigma_convention', 'n/a')}. "
                  f"Metrics: [`{name}.metrics.json`]({figures_rel}/{name}.metrics.json), "
                  f"vector: [`{name}.pdf`]({figures_rel}/{name}.pdf).", ""]
    return lines


def cell_sources_of(matrix: dict) -> dict:
    """:func:`experiments.claims.cell_sources` of a claim matrix (or of a plain verdict list)."""
    from experiments.claims import cell_sources

    return cell_sources(_as_matrix(matrix))


def _md_scene_sets() -> list[str]:
    lines = ["## Scene sets", "",
             "Figures 4, 5, 6, 7, 8 and 11 are computed on two sets of rendered scenes; the flat metrics and the "
             "first figure of each are the figure's default set, the second figure (`<fig>_<set>.png`) the other "
             "set.", ""]
    for name, what, scenes in scene_set_lines():
        lines += [f"- **{name}** ({what}):"] + [f"  - {_md_cell(x)}" for x in scenes]
    return lines + [""]


def figure_files(name: str, metrics_file: dict, figures_dir: Path | None) -> list[tuple[str, str]]:
    """``(file stem, caption)`` of a figure's images: the default scene set's, then each further set's.

    A figure without scene sets has one image and no caption. Further sets' images
    (``<name>_<set>.png``) are listed when ``figures_dir`` is None or the file exists.
    """
    from experiments.scene_sets import SCENE_SET_CAPTIONS

    inner = metrics_file.get("metrics") if isinstance(metrics_file, dict) else None
    inner = inner if isinstance(inner, dict) else {}
    default = inner.get("scene_set")
    if default is None:
        return [(name, "")]
    out = [(name, SCENE_SET_CAPTIONS.get(default, f"scene set {default}"))]
    for other in inner.get("scene_sets", {}) or {}:
        stem = f"{name}_{other}"
        if figures_dir is None or (Path(figures_dir) / f"{stem}.png").exists():
            out.append((stem, SCENE_SET_CAPTIONS.get(other, f"scene set {other}")))
    return out


def build_html(metrics: dict, verdicts, *, figures_rel: str, bench: str | None,
               figures_dir: Path | None = None, leaderboard: dict | None = None,
               generalisation: dict | None = None) -> str:
    """A self-contained HTML page (images by relative path); ``leaderboard`` and ``generalisation`` as in
    :func:`build_markdown`."""
    e = html.escape
    matrix = _as_matrix(verdicts)
    rows = _html_claims_table(matrix)
    details_html = _html_evidence(matrix)
    legend = " ".join(f"{mark_svg(v)} {e(v)}" for v in MARKS)
    sets_html = "<h2>Scene sets</h2><p>Figures 4, 5, 6, 7, 8 and 11 are computed on two sets of rendered scenes; " \
                "the first image of each is the figure's default set, the second the other set.</p><ul>" + "".join(
                    f"<li><b>{e(n)}</b> ({e(w)})<ul>" + "".join(f"<li>{e(x)}</li>" for x in sc) + "</ul></li>"
                    for n, w, sc in scene_set_lines()) + "</ul>"
    figs = _html_figures(metrics, figures_rel=figures_rel, figures_dir=figures_dir)
    bench_html = f"<h2>Speed</h2><pre>{e(bench)}</pre>" if bench else ""
    preset_html = _html_tables(preset_tables(metrics), "presets")
    if preset_html:
        preset_html = ("<h2>Presets side by side</h2><p><code>paper</code> is the reproduction, <code>robust</code> "
                       "goes beyond the paper, <code>zhuo_sim</code> is the Zhuo &amp; Sim 2011 baseline. Errors "
                       "against σ_gt in px (edge MAE; dense MAE over textured pixels, bias in brackets).</p>" + preset_html)
    board_html = ""
    if leaderboard:
        board_html = (f"<h2>Leaderboard</h2><p>{e(leaderboard_intro(leaderboard))}</p>"
                      + _html_tables(leaderboard_tables(leaderboard), "leaderboard"))
    if generalisation:
        from ._report_gap import generalisation_intro

        board_html += (f"<h2>{e(GENERALISATION_HEADING)}</h2><p>{e(generalisation_intro(generalisation))}</p>"
                       + _html_tables(generalisation["tables"], "generalisation"))
    mismatch_html = _html_mismatch(metrics)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>Defocus Magnification — reproduction report</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; padding: 0 1em; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #ccc; padding: 4px 8px; vertical-align: top; }}
td.reproduced, tr.reproduced td:nth-child(3) {{ color: #1a7f37; }}
td.not-reproduced, tr.not-reproduced td:nth-child(3) {{ color: #cf222e; }}
td.partly-reproduced, tr.partly-reproduced td:nth-child(3) {{ color: #9a6700; }}
svg.mark {{ vertical-align: -3px; }} figure {{ margin: 0 0 1em 0; }} figcaption {{ font-style: italic; }}
details {{ margin: 0.5em 0; }} summary {{ cursor: pointer; font-weight: bold; }}
img {{ max-width: 100%; border: 1px solid #eee; }}
</style></head><body>
<h1>Defocus Magnification (Bae &amp; Durand 2007): reproduction report</h1>
<p>Generated {e(time.strftime('%Y-%m-%d %H:%M'))} by <code>python -m repro.report</code> from the metrics of
<code>python -m repro.figures</code> (mode: {e(_modes(metrics))}).</p>
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


def _html_claims_table(matrix: dict) -> str:
    """The claims × (preset, scene set) verdict table of the HTML page ('' without columns)."""
    e = html.escape
    columns = list(matrix)
    if not columns:
        return ""
    head = "".join(f"<th>{e(column_label(*c))}</th>" for c in columns)
    texts = cell_texts(matrix)

    def td(c, claim):
        verdict, note = texts[(c, claim.id)]
        if verdict is None:
            return f"<td class='same'>{e(note)}</td>"
        return (f"<td class='{e(verdict.replace(' ', '-'))}'>{mark_svg(verdict)} {e(verdict)}"
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
    sources = cell_sources_of(matrix)

    def evidence_row(col, c, v):
        src = sources.get((col, c.id))
        if src is not None:
            return (f"<tr class='same'><td>{mark_svg(v.verdict)}</td><td>{e(c.text)}</td><td>=</td>"
                    f"<td>same evaluation as <i>{e(column_label(*src))}</i> (<code>{e(v.evaluation)}</code>)</td></tr>")
        ev = f"<br>Evaluation: <code>{e(v.evaluation)}</code>." if v.evaluation else ""
        return (f"<tr class='{e(v.verdict.replace(' ', '-'))}'><td>{mark_svg(v.verdict)}</td><td>{e(c.text)}</td>"
                f"<td><b>{e(v.verdict)}</b></td><td>{e(v.evidence)}{ev}<br><i>Rule: {e(c.rule)}.</i></td></tr>")

    details = []
    for j, col in enumerate(matrix):
        trs = "\n".join(evidence_row(col, c, v) for c, v in matrix[col])
        details.append(f"<details{' open' if j == 0 else ''}><summary>Evidence: {e(column_label(*col))}</summary>"
                       f"<table class='evidence'><tr><th></th><th>claim</th><th>verdict</th><th>evidence</th></tr>"
                       f"{trs}</table></details>")
    return "\n".join(details)


def _html_figures(metrics: dict, *, figures_rel: str, figures_dir: Path | None) -> str:
    """One section per figure: its images (linked to the PDF), captions, σ convention and metrics link."""
    e = html.escape
    return "\n".join(
        f"<section id='{e(n)}'><h3>{e(n)}: {e(metrics[n].get('title', ''))}</h3>"
        + "".join(f"<figure><a href='{figures_rel}/{e(stem)}.pdf'><img src='{figures_rel}/{e(stem)}.png' "
                  f"alt='{e(stem)}'></a>" + (f"<figcaption>{e(cap)}</figcaption>" if cap else "") + "</figure>"
                  for stem, cap in figure_files(n, metrics[n], figures_dir))
        + f"<p>σ convention: {e(str(metrics[n].get('sigma_convention', 'n/a')))}. "
        f"<a href='{figures_rel}/{e(n)}.metrics.json'>metrics</a></p></section>"
        for n in _fig_order(metrics))


def _html_tables(tables: list[dict], css_class: str) -> str:
    """Titled HTML tables (``{"title", "header", "rows"}`` each) of class ``css_class``."""
    e = html.escape
    return "".join(
        f"<h3>{e(t['title'])}</h3><table class='{css_class}'><tr>" + "".join(f"<th>{e(h)}</th>" for h in t["header"])
        + "</tr>" + "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in t["rows"]) + "</table>"
        for t in tables)


def _html_mismatch(metrics: dict) -> str:
    """The model-mismatch section of the HTML page ('' when nothing was measured)."""
    from experiments.claims import mismatch_findings

    e = html.escape
    findings = mismatch_findings(metrics)
    if not findings:
        return ""
    return ("<h2>Beyond the paper: model mismatch</h2><p>The method assumes a Gaussian-blurred step in "
            "the pixel values; a thin lens blurs with a disk in linear light and a camera stores sRGB. "
            "Measured bias shifts (px):</p><table><tr><th>effect</th><th>estimator</th><th>pixels</th>"
            "<th>value (px)</th></tr>" + "".join(
                f"<tr><td>{e(r['effect'])}</td><td>{e(r['estimator'])}</td><td>{e(r['edges'])}</td>"
                f"<td>{r['bias_shift_px']:+.3f}</td></tr>" for r in findings) + "</table>")


#: Markers of the block in the project README that ``repro.report`` keeps current.
README_START = "<!-- claims:start (generated by python -m repro.report; do not edit) -->"
README_END = "<!-- claims:end -->"


def claims_block(verdicts, *, report_link: str) -> str:
    """Short verdict table for the project README (between :data:`README_START` and :data:`README_END`).

    ``verdicts``: a :func:`experiments.claims.claim_matrix` dict (one column per preset and scene set)
    or one list of (Claim, Verdict). Marks are ASCII text (:data:`MARKS`), readable in any font.
    """
    matrix = _as_matrix(verdicts)
    columns = list(matrix)
    rows = ["| claim | where | " + " | ".join(column_label(*c) for c in columns) + " |",
            "|---|---|" + "---|" * len(columns)]
    if columns:
        texts = cell_texts(matrix)
        for c, _ in matrix[columns[0]]:
            rows.append(f"| {_md_cell(c.text)} | {c.section} | "
                        + " | ".join(_md_verdict_cell(texts[(k, c.id)]) for k in columns) + " |")
    legend = ("Marks: " + ", ".join(f"`{m}` {v}" for v, m in MARKS.items()) + ". `=`: the same evaluation as "
              "the cell it names (or, alone, as the claim's first cell: a claim independent of presets and scene "
              "sets is computed once).")
    return "\n".join([README_START, "", *rows, "", legend + f" Evidence and numbers for every cell: "
                      f"[{report_link}]({report_link}).", "", README_END])


def update_readme_block(readme: Path, block: str) -> bool:
    """Replace the marked block in ``readme`` (atomically); False when the file has no markers."""
    from defocus_cache import atomic_write_text

    text = readme.read_text(encoding="utf-8")
    start, end = text.find(README_START), text.find(README_END)
    if start < 0 or end < start:
        return False
    new = text[:start] + block + text[end + len(README_END):]
    if new != text:
        atomic_write_text(readme, new)
    return True


def parse_external(values) -> dict:
    """``["NAME=MAPDIR", ...]`` -> ``{NAME: Path(MAPDIR)}``; ValueError (one line) on a bad or repeated NAME."""
    out = {}
    for text in values:
        name, sep, folder = str(text).partition("=")
        if not sep or not name.strip() or not folder:
            raise ValueError(f"--external {text!r} is invalid; allowed: NAME=MAPDIR")
        if name in out:
            raise ValueError(f"--external {text!r} is invalid (NAME {name!r} given twice); allowed: one folder per NAME")
        out[name.strip()] = Path(folder)
    return out


def external_leaderboard(external: dict, dataset: Path | None) -> dict:
    """:func:`experiments.leaderboard.build_leaderboard` on ``dataset`` (or the renders the maps name)."""
    from experiments.external_maps import DatasetTruth, RenderTruth
    from experiments.leaderboard import build_leaderboard

    if dataset is not None:
        truth = DatasetTruth(dataset)
    else:
        from repro._cli import require_extras

        require_extras("render", command="repro.report --external without --dataset")
        truth = RenderTruth.named_by(external.values())
    return build_leaderboard(truth, external=external)


def _generalisation(args) -> dict | None:
    """The generalisation section from ``--evaluations`` (None when it lacks a dev or a test evaluation)."""
    from ._report_gap import DEFAULT_EVALUATIONS, load_generalisation

    root = args.evaluations if args.evaluations is not None else DEFAULT_EVALUATIONS
    if args.evaluations is not None and not root.is_dir():
        raise ValueError(f"--evaluations {str(root)!r} is not a folder; allowed: a folder of repro.evaluate "
                         "--procedural evaluations")
    return load_generalisation(root)


def main(argv=None) -> int:
    parser = ArgumentParser(prog="python -m repro.report", description=__doc__.splitlines()[0])
    parser.add_argument("--figures", type=Path, default=Path("report") / "figures",
                        help="folder with <fig>.png/.pdf/.metrics.json (default: report/figures)")
    parser.add_argument("--out", type=Path, default=Path("report"), help="output folder (default: report)")
    parser.add_argument("--readme", type=Path, default=None,
                        help="README whose marked claims block is refreshed (default: the project's "
                             "README.md, and only when --out is the project's report/ folder)")
    parser.add_argument("--external", action="append", default=[], metavar="NAME=MAPDIR",
                        help="add a leaderboard row set for the defocus maps in MAPDIR (NAME.npy|npz|exr|png, σ in "
                             "px) under NAME; repeatable. The presets are scored alongside")
    parser.add_argument("--dataset", type=Path, default=None, metavar="DIR",
                        help="with --external: the ground truth of a repro.dataset export folder (default: the "
                             "harness's renders named by the maps)")
    parser.add_argument("--evaluations", type=Path, default=None, metavar="DIR",
                        help="folder of repro.evaluate --procedural evaluations; the newest dev and test ones give the "
                             "generalisation section (default: report/evaluations)")
    args = parser.parse_args(argv)
    from repro._cli import user_input

    with user_input():  # the flags and the figures folder
        external = parse_external(args.external)
        if args.dataset is not None and not external:
            raise ValueError("--dataset is invalid without --external; allowed: with --external NAME=MAPDIR")
        if not args.figures.is_dir():
            raise ValueError(f"figures folder {args.figures} does not exist; run python -m repro.figures first")
        metrics = load_metrics(args.figures)
        if not metrics:
            raise ValueError(f"no *.metrics.json in {args.figures}; run python -m repro.figures first")
    from experiments.claims import claim_matrix, claims_document, evaluate_claims
    from defocus_cache import atomic_write_text

    args.out.mkdir(parents=True, exist_ok=True)
    verdicts = evaluate_claims(metrics)
    matrix = claim_matrix(metrics)
    try:
        rel = args.figures.resolve().relative_to(args.out.resolve()).as_posix()
    except ValueError:
        rel = args.figures.resolve().as_posix()
    bench = _bench_summary(args.out)
    board = None
    if external:
        with user_input():  # --external names and folders, --dataset (too broad: also the scoring)
            board = external_leaderboard(external, args.dataset)
        for line in board["problems"]:
            print(f"python -m repro.report: skipped {line}", file=sys.stderr)
        from experiments.registry import to_jsonable

        atomic_write_text(args.out / "leaderboard.json",
                          json.dumps(to_jsonable(board), indent=1, sort_keys=True, ensure_ascii=False) + "\n")
    with user_input():  # --evaluations (too broad: also reading the evaluations)
        generalisation = _generalisation(args)
    if generalisation is not None:
        from experiments.registry import to_jsonable

        atomic_write_text(args.out / "generalisation.json", json.dumps(
            to_jsonable({k: v for k, v in generalisation.items() if k != "tables"}), indent=1, sort_keys=True,
            ensure_ascii=False) + "\n")
    atomic_write_text(args.out / "README.md", build_markdown(metrics, matrix, figures_rel=rel, bench=bench,
                                                             figures_dir=args.figures, leaderboard=board,
                                                             generalisation=generalisation))
    atomic_write_text(args.out / "index.html", build_html(metrics, matrix, figures_rel=rel, bench=bench,
                                                          figures_dir=args.figures, leaderboard=board,
                                                          generalisation=generalisation))
    summary = {"claims": [{"id": c.id, "section": c.section, "figure": c.figure, "claim": c.text,
                           "rule": c.rule, "varies_with": list(c.varies_with), "verdict": v.verdict,
                           "evidence": v.evidence, "evaluation": v.evaluation}
                          for c, v in verdicts],
               "matrix": claims_document(matrix)}
    atomic_write_text(args.out / "claims.json", json.dumps(summary, indent=1, ensure_ascii=False))
    readme = args.readme
    if readme is None and args.out.resolve() == (_PROJECT_ROOT / "report").resolve():
        readme = _PROJECT_ROOT / "README.md"
    if readme is not None and readme.is_file():
        try:
            link = (args.out / "README.md").resolve().relative_to(readme.resolve().parent).as_posix()
        except ValueError:
            link = (args.out / "README.md").resolve().as_posix()
        if update_readme_block(readme, claims_block(matrix, report_link=link)):
            print(f"refreshed the claims table in {readme}")
    for (p, sset), rows in matrix.items():
        print(f"{column_label(p, sset)}:")
        for c, v in rows:
            print(f"  [{_mark(v.verdict)}] {v.verdict:17s} {c.id}")
    print(f"wrote {args.out / 'README.md'}, {args.out / 'index.html'}, {args.out / 'claims.json'}"
          + (f", {args.out / 'leaderboard.json'}" if board is not None else ""))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="python -m repro.report"))
