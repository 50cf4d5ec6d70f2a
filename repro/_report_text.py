"""What the report's Markdown and HTML pages share: verdict marks, column labels, cell texts, scene sets,
the figures' image files, the presets table and the section texts."""

from __future__ import annotations

import html
from pathlib import Path

__all__ = ["GENERALISATION_HEADING", "KEY_FIGURES", "MARKS", "PRESET_TABLES_INTRO", "SELF_CHECK_LEGEND", "cell_texts",
           "column_label",
           "figure_files", "fig_order", "fragile_cells", "mark", "mark_svg", "md_cell", "modes", "preset_tables",
           "scene_set_lines"]

#: Text mark of each verdict (Markdown, README, terminal): ASCII, so it reads in any font.
MARKS = {"reproduced": "+", "partly reproduced": "~", "not reproduced": "-", "not evaluated": "?", "error": "!"}
#: The legend of a harness self-check's mark (the verdict's mark in brackets, :func:`mark`).
SELF_CHECK_LEGEND = ("`(+)`, `(-)`: a harness self-check (the harness agreeing with itself: a renderer that "
                     "implements the formula checked, or analytic steps that draw nothing from the scenes they are "
                     "shown under), not held-out evidence for the paper")
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
#: Figures shown in the Markdown report, in this order (all of them appear in the HTML page).
KEY_FIGURES = ("fig4", "fig5", "fig6", "fig7", "fig11", "fig2", "fig10")
#: Heading of the generalisation section (Markdown and HTML).
GENERALISATION_HEADING = "Generalisation: dev and test scenes"
#: The paragraph under "Presets side by side" (Markdown and HTML).
PRESET_TABLES_INTRO = (
    "`paper` is the reproduction (`DefocusParams()`), `robust` goes beyond the paper ("
    "`docs/presets.md`), `zhuo_sim` is the Zhuo & Sim 2011 baseline. Errors against σ_gt in px: sparse blur "
    "at the edge pixels, dense map over textured pixels (mean signed error in brackets); occlusion "
    "boundaries and tile seams excluded. From the `stages` figure.")


def mark_svg(verdict: str) -> str:
    """An inline SVG mark (16 px circle in the verdict's colour with a white glyph) with a text title."""
    colour = _COLOURS.get(verdict, "#000000")
    glyph = _SVG_GLYPH.get(verdict, "")
    return (f"<svg class='mark' width='16' height='16' viewBox='0 0 16 16' role='img' aria-label='{html.escape(verdict)}'>"
            f"<title>{html.escape(verdict)}</title><circle cx='8' cy='8' r='7' fill='{colour}'/>{glyph}</svg>")


def mark(verdict: str, *, self_check: bool = False) -> str:
    """The ASCII mark of a verdict; in brackets for a harness self-check (:data:`SELF_CHECK_LEGEND`)."""
    m = MARKS.get(verdict, "!")
    return f"({m})" if self_check else m


def md_cell(text) -> str:
    """Text safe inside a Markdown table cell (pipes escaped)."""
    return str(text).replace("|", "\\|")


def column_label(preset: str, scene_set) -> str:
    """Heading of one (preset, scene set) column."""
    return f"{preset} preset" if scene_set is None else f"{preset} preset, {scene_set}"


def fragile_cells(fragile: list[dict]) -> set:
    """``{(preset, claim id)}`` of :func:`experiments.claims.fragile_claims`."""
    return {(f["preset"], f["claim"]) for f in fragile}


def cell_texts(matrix: dict, fragile: list[dict] = ()) -> dict:
    """``{(column, claim id): (verdict or None, note, self check)}`` of the claims table.

    A cell with its own evaluation shows its verdict, with the claim's :func:`experiments.claims.scope_note`
    when later cells repeat its evaluation; a cell that repeats an earlier column's evaluation shows no
    verdict and the note ``"="`` (claims that vary with nothing) or ``"= <column>"``; a test-split cell
    of a fragile claim (:func:`experiments.claims.fragile_claims`) says ``fragile``. ``self check`` is
    True for a harness self-check (:func:`experiments.claims.is_self_check`), whose note then also says
    :data:`experiments.claims.SELF_CHECK_NOTE`.
    """
    from experiments.claims import SELF_CHECK_NOTE, cell_sources, is_self_check, scope_note
    from experiments.scene_sets import PROCEDURAL_TEST

    sources = cell_sources(matrix)
    repeated = {(src, cid) for (_, cid), src in sources.items() if src is not None}
    weak = fragile_cells(list(fragile))
    out = {}
    for col, rows in matrix.items():
        for claim, v in rows:
            src = sources.get((col, claim.id))
            own = is_self_check(claim, col[1], v)
            if src is not None:
                out[(col, claim.id)] = (None, "=" if not claim.varies_with else f"= {column_label(*src)}", own)
                continue
            note = scope_note(claim, test_split=col[1] == PROCEDURAL_TEST) if (col, claim.id) in repeated else ""
            if col[1] == PROCEDURAL_TEST and any((p, claim.id) in weak for p in (col[0], "paper")):
                note = "fragile: differs from a hand-built set"
            if own:
                note = "; ".join(n for n in (note, SELF_CHECK_NOTE) if n)
            out[(col, claim.id)] = (v.verdict, note, own)
    return out


def scene_set_lines() -> list[tuple[str, str, list[str]]]:
    """``(set name, what it is, ["scene: description"])`` for each scene set (from :mod:`scenes`)."""
    from experiments.scene_sets import PROCEDURAL_TEST
    from scenes import SCENE_SETS, SCENES

    what = {"paper_cameras": "default: the paper's cameras (Canon 1D Mark II 85 mm, Nikon D50 180 mm) at real-world "
                             "distances, σ_gt from the pixel-filter floor to about 4 px at f/8 and 8 px at f/4 (full preset)",
            "tabletop_stress": "stress test: tabletop macro shots (50 mm full frame focused at 0.2-0.25 m), σ_gt up "
                               "to 12-17 px at f/4 (full preset), far beyond the paper's photos"}
    out = [(name, what.get(name, ""), [f"{n}: {SCENES[n].description}" for n in names])
           for name, names in SCENE_SETS.items()]
    out.append((PROCEDURAL_TEST, "held out: the first seeds of the procedural family's test split (docs/procedural.md), "
                                 "scenes nobody tuned on; a verdict that differs here from a hand-built set is fragile",
                ["procedural_<seed>: a seeded scene (paper camera, 3-12 textured objects, emission-only or lit)"]))
    return out


def fig_order(names):
    """Figure names in numeric order (``fig2`` before ``fig10``), the others last."""
    def key(n):
        digits = "".join(ch for ch in n if ch.isdigit())
        return (int(digits) if digits else 999, n)
    return sorted(names, key=key)


def modes(infos: dict) -> str:
    """The figures' modes (``quick``, ``full``), comma-separated."""
    return ", ".join(sorted({m.get("mode", "?") for m in infos.values()}))


def figure_files(name: str, info: dict, figures_dir: Path | None) -> list[tuple[str, str]]:
    """``(file stem, caption)`` of a figure's images, in the order its plot wrote them.

    The images are the ``.png`` files named in the figure's metrics file (``outputs``; ``<name>.png``
    when it names none); an image of a further scene set (``<name>_<set>.png``) is captioned with the
    set. When ``figures_dir`` is given, the further images are listed only when they exist there (the
    first always: a missing one is a broken image of the report).
    """
    from experiments.scene_sets import SCENE_SET_CAPTIONS

    stems = [Path(o).stem for o in info.get("outputs", []) if str(o).endswith(".png")] or [name]
    sets = [s for s, *_ in info.get("config", {}).get("scene_sets", [])] if isinstance(info.get("config"), dict) else []
    out = []
    for i, stem in enumerate(stems):
        if i and figures_dir is not None and not (Path(figures_dir) / f"{stem}.png").exists():
            continue
        tail = stem[len(name) + 1:] if stem.startswith(f"{name}_") else None
        set_name = tail if tail else (sets[0] if sets and i == 0 else None)
        out.append((stem, SCENE_SET_CAPTIONS.get(set_name, f"scene set {set_name}") if set_name else ""))
    return out


def preset_tables(table) -> list[dict]:
    """Presets side by side, one table per kind of image, from the ``stages`` figure's rows.

    Returns
    -------
    list of dict
        ``{"title", "header", "rows"}`` per kind (analytic mosaics; rendered scenes): one row per image
        with, per preset, the sparse edge MAE and the dense textured MAE (bias) in px. Empty without rows.
    """
    rows = table.where(figure="stages", variant=("mosaic", "render"))
    presets = [p for p in rows.distinct("preset") if p]
    if not presets:
        return []
    titles = {"mosaic": "Analytic texture mosaics (8-bit + noise; σ_gt exact)", "render": "Rendered scenes"}
    out = []
    for kind, title in titles.items():
        body = []
        for (scene, aperture), r in rows.where(variant=kind).group("scene", "aperture").items():
            label = f"mosaic:{scene}" if kind == "mosaic" else f"{scene} f/{aperture:g}"
            row = [label]
            for p in presets:
                m = r.where(preset=p).metrics()
                sp, dt, db = (m.get(k) for k in ("estimated/sparse/mae", "estimated/dense_textured/mae",
                                                 "estimated/dense_textured/bias"))
                row.append("–" if sp is None else f"{sp:.2f}")
                row.append("–" if dt is None else f"{dt:.2f} ({db:+.2f})")
            body.append(row)
        if body:
            mode = sorted({str(e).split("-")[1] for e in rows.distinct("evaluation_id")})
            out.append({"title": title + (f" ({', '.join(mode)} mode)" if kind == "render" else ""),
                        "header": ["case"] + [f"{p}: {w}" for p in presets for w in ("edge MAE", "dense MAE (bias)")],
                        "rows": body})
    return out
