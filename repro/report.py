"""Build the report: ``report/index.html`` and ``report/README.md`` from the results table of the figures.

``python -m repro.report [--figures report/figures] [--out DIR] [--readme FILE] [--external NAME=MAPDIR ...]
[--dataset DIR] [--evaluations DIR] [-q]``

Reads the long results table that ``python -m repro.figures`` wrote (``<figures>/results.parquet`` or
``results.csv``, :mod:`experiments.results_table`) and the figures' ``<fig>.metrics.json`` (config,
mode, σ convention, image files), checks each of the paper's claims on it (:mod:`experiments.claims`:
one verdict per method preset × scene set) and writes, atomically, an HTML page (images by relative
path, :mod:`repro._report_html`), a Markdown page (:mod:`repro._report_markdown`) and ``claims.json``
with the verdict table, the evidence numbers, the fragile verdicts — those that differ between the
hand-built scene sets and the procedural test split, shown with both evidences — and the key figures.
Nothing in the report is typed by hand: rerun the figures and this command to refresh it; the same
results give the same files (no timestamp), so a rerun on unchanged results leaves ``git status`` clean.

``python -m repro.report`` writes the committed report (``report/``, and the claims block of the
project's ``README.md``) from ``report/figures`` and ``report/evaluations``. With ``--figures`` in the
git-ignored ``report/quick/`` (``repro.figures --quick`` writes ``report/quick/figures``), ``--out``
defaults to ``report/quick`` and ``--evaluations`` to ``report/quick/evaluations`` (where
``repro.evaluate --procedural`` writes by default), and ``README.md`` is left alone.
The committed report is built from full-mode figures only: a figure whose metrics file or results rows
say another mode (``quick``; :func:`figure_modes`) is refused there (one line, exit status 2).

``--external NAME=MAPDIR`` (repeatable) adds a leaderboard (:mod:`experiments.leaderboard`): every
method preset and every external map folder, one row each, per scene set and protocol, on the images
of ``--dataset DIR`` (a ``repro.dataset export`` folder; no renderer needed) or, without it, on the
harness's renders named by the maps; its rows are long-table rows (``leaderboard.json``). A map that
cannot be scored is one line on stderr naming the entry and the file.

Generalisation: the newest evaluation of each split of the procedural scene family under
``--evaluations`` (the committed ``report/evaluations`` is written only on purpose: ``python -m
repro.evaluate --procedural N --split dev|test|fresh --out report/evaluations``) gives, per preset and
aperture, the dev and test errors side by side with 95 % bootstrap intervals and test − dev
(:mod:`repro._report_gap`); also written to ``<out>/generalisation.json``. Without both a dev and a
test evaluation the section is left out.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from repro._cli import ArgumentParser, CLIError, run_cli

from ._report_html import build_html
from ._report_markdown import build_markdown, md_verdict_cell
from ._report_paths import EVALUATIONS, FIGURES, QUICK, QUICK_EVALUATIONS, QUICK_FIGURES, REPORT
from ._report_text import MARKS, SELF_CHECK_LEGEND, cell_texts, column_label, mark, md_cell

__all__ = ["README_END", "README_START", "build_html", "build_markdown", "check_full_mode", "claims_block",
           "figure_modes", "load_figures", "main", "parse_external", "update_readme_block"]

PROG = "python -m repro.report"
_PROJECT_ROOT = Path(__file__).resolve().parents[1]


def load_figures(folder: Path):
    """``({figure: parsed <fig>.metrics.json}, results table)`` of a ``repro.figures`` output folder.

    Raises
    ------
    ValueError
        The folder, its metrics files or its results table are missing or unreadable.
    """
    from experiments.results_query import read_table

    if not folder.is_dir():
        raise ValueError(f"figures folder {folder} does not exist; run python -m repro.figures first")
    infos = {}
    for path in sorted(folder.glob("*.metrics.json")):
        try:
            infos[path.name.split(".")[0]] = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ValueError(f"cannot read {path}: {exc}") from None
    if not infos:
        raise ValueError(f"no *.metrics.json in {folder}; run python -m repro.figures first")
    return infos, read_table(folder)


def figure_modes(infos: dict, table) -> dict[str, set]:
    """The run modes (``full``, ``quick``, …) of every figure of a ``repro.figures`` output folder.

    A figure's modes are its metrics file's ``mode`` (None when it has none) and the mode named by the
    ``evaluation_id`` of each of its results rows (``<figure>-<mode>-<hash>``, None for another shape;
    :func:`experiments.figure_data.evaluation_mode`), so a table whose rows were merged from runs of
    different modes shows both.

    Parameters
    ----------
    infos : dict
        ``{figure: parsed <figure>.metrics.json}`` (:func:`load_figures`).
    table : experiments.results_query.Results
        The folder's results table.
    """
    from experiments.figure_data import evaluation_mode

    modes = {name: {info.get("mode")} for name, info in infos.items()}
    for row in table:
        if row.get("figure"):
            modes.setdefault(row["figure"], set()).add(evaluation_mode(row.get("evaluation_id", ""), row["figure"]))
    return modes


def _quick(args) -> bool:
    """Whether ``--figures`` lies in the git-ignored folder of exploratory runs (:data:`QUICK`)."""
    return args.figures.resolve().is_relative_to(QUICK.resolve())


def _committed_target(out: Path, readme: Path | None) -> bool:
    """Whether the report goes to the project's committed ``report/`` or its ``README.md``."""
    return (out.resolve() == (_PROJECT_ROOT / "report").resolve()
            or readme is not None and readme.resolve() == (_PROJECT_ROOT / "README.md").resolve())


def check_full_mode(infos: dict, table, *, figures: Path) -> None:
    """Refuse figures run in another mode than ``full`` for the committed report.

    Raises
    ------
    ValueError
        Naming the figures and their modes, and the way to a quick report.
    """
    other = {name: sorted(map(str, m)) for name, m in figure_modes(infos, table).items() if m != {"full"}}
    if other:
        listed = ", ".join(f"{name} ({'/'.join(m)})" for name, m in sorted(other.items()))
        raise ValueError(f"{figures} holds results of a run that is not full-mode: {listed}; allowed for the committed "
                         "report (report/, README.md): full-mode figures (python -m repro.figures without --quick); "
                         "a quick run's report: python -m repro.report --figures report/quick/figures")


def _bench_summary(out: Path, name: str = "bench.md") -> str | None:
    path = out / "bench" / name
    return path.read_text() if path.exists() else None


#: Markers of the block in the project README that ``repro.report`` keeps current.
README_START = "<!-- claims:start (generated by python -m repro.report; do not edit) -->"
README_END = "<!-- claims:end -->"


def claims_block(matrix: dict, *, report_link: str, fragile: list | None = None) -> str:
    """Short verdict table for the project README (between :data:`README_START` and :data:`README_END`).

    ``matrix``: :func:`experiments.claims.claim_matrix` (one column per preset and scene set). Marks are
    ASCII text (:data:`MARKS`), readable in any font.
    """
    columns = list(matrix)
    rows = ["| claim | where | " + " | ".join(column_label(*c) for c in columns) + " |",
            "|---|---|" + "---|" * len(columns)]
    if columns:
        texts = cell_texts(matrix, fragile or ())
        for c, _ in matrix[columns[0]]:
            rows.append(f"| {md_cell(c.text)} | {c.section} | "
                        + " | ".join(md_verdict_cell(texts[(k, c.id)]) for k in columns) + " |")
    legend = ("Marks: " + ", ".join(f"`{m}` {v}" for v, m in MARKS.items()) + "; " + SELF_CHECK_LEGEND
              + ". `=`: the same evaluation as "
              "the cell it names (or, alone, as the claim's first cell: a claim independent of presets and scene "
              "sets is computed once). `fragile`: the procedural test split's verdict differs from a hand-built set's.")
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
    """:func:`experiments.leaderboard.build_leaderboard` on ``dataset`` (or the renders the maps name).

    The folders and the dataset are checked first (a bad one is the user's error: one line, exit 2);
    a failure while scoring them is a bug and shows its traceback.
    """
    from experiments.external_maps import DatasetTruth, RenderTruth
    from experiments.leaderboard import build_leaderboard, check_external

    from repro._cli import user_input

    with user_input():  # --external names and folders, --dataset
        check_external(external)
        if dataset is not None:
            truth = DatasetTruth(dataset)
        else:
            from repro._cli import require_extras

            require_extras("render", command="repro.report --external without --dataset")
            truth = RenderTruth.named_by(external.values())
    return build_leaderboard(truth, external=external)


def _generalisation(args) -> dict | None:
    """The generalisation section from ``--evaluations`` (None when it lacks a dev or a test evaluation)."""
    from ._report_gap import load_generalisation

    root = args.evaluations if args.evaluations is not None else QUICK_EVALUATIONS if _quick(args) else EVALUATIONS
    if args.evaluations is not None and not root.is_dir():
        raise CLIError(f"--evaluations {str(root)!r} is not a folder; allowed: a folder of repro.evaluate "
                         "--procedural evaluations")
    return load_generalisation(root)


def _parser():
    from repro._cli import add_quiet_option

    parser = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--figures", type=Path, default=FIGURES, metavar="DIR",
                        help=f"folder with results.parquet|csv and <fig>.png/.pdf/.metrics.json (default: {FIGURES}, "
                             f"full-mode figures; a quick run's: {QUICK_FIGURES})")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help=f"output folder (default: {REPORT}; {QUICK} when --figures is in it); the committed "
                             f"{REPORT}/ takes full-mode figures only")
    parser.add_argument("--readme", type=Path, default=None, metavar="FILE",
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
                             f"generalisation section (default: {EVALUATIONS}, written only on purpose with "
                             f"repro.evaluate --procedural ... --out {EVALUATIONS}; {QUICK_EVALUATIONS} when "
                             f"--figures is in {QUICK})")
    add_quiet_option(parser, what="no verdict listing on the terminal")
    return parser


def _write_json(path: Path, doc) -> None:
    from defocus_cache import atomic_write_text
    from experiments.cache_keys import to_jsonable

    atomic_write_text(path, json.dumps(to_jsonable(doc), indent=1, sort_keys=True, ensure_ascii=False) + "\n")


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    from repro._cli import user_input

    with user_input():  # the flags and the figures folder
        external = parse_external(args.external)
        if args.dataset is not None and not external:
            raise ValueError("--dataset is invalid without --external; allowed: with --external NAME=MAPDIR")
        infos, table = load_figures(args.figures)
        if args.out is None:
            args.out = QUICK if _quick(args) else REPORT
        readme = args.readme
        if readme is None and args.out.resolve() == (_PROJECT_ROOT / "report").resolve():
            readme = _PROJECT_ROOT / "README.md"
        if _committed_target(args.out, readme):
            check_full_mode(infos, table, figures=args.figures)
    from defocus_cache import atomic_write_text
    from experiments.claims import claim_matrix, claims_document, fragile_claims, is_self_check

    args.out.mkdir(parents=True, exist_ok=True)
    matrix = claim_matrix(table)
    fragile = fragile_claims(matrix)
    try:
        rel = args.figures.resolve().relative_to(args.out.resolve()).as_posix()
    except ValueError:
        rel = args.figures.resolve().as_posix()
    board = None
    if external:
        board = external_leaderboard(external, args.dataset)
        for line in board["problems"]:
            print(f"{PROG}: skipped {line}", file=sys.stderr)
        _write_json(args.out / "leaderboard.json", board)
    generalisation = _generalisation(args)
    if generalisation is not None:
        _write_json(args.out / "generalisation.json", {k: v for k, v in generalisation.items() if k != "tables"})
    pages = dict(figures_rel=rel, bench=_bench_summary(args.out), figures_dir=args.figures, leaderboard=board,
                 generalisation=generalisation, fragile=fragile, doubling=_bench_summary(args.out, "doubling.md"))
    atomic_write_text(args.out / "README.md", build_markdown(infos, table, matrix, **pages))
    atomic_write_text(args.out / "index.html", build_html(infos, table, matrix, **pages))
    first = next(iter(matrix), None)
    summary = {"claims": [{"id": c.id, "section": c.section, "figure": c.figure, "claim": c.text, "rule": c.rule,
                           "varies_with": list(c.varies_with), "test_split": c.test_split, "verdict": v.verdict,
                           "evidence": v.evidence, "evaluation": v.evaluation}
                          for c, v in (matrix[first] if first is not None else [])],
               "matrix": claims_document(matrix), "fragile": fragile}
    atomic_write_text(args.out / "claims.json", json.dumps(summary, indent=1, ensure_ascii=False))
    if readme is not None and readme.is_file():
        try:
            link = (args.out / "README.md").resolve().relative_to(readme.resolve().parent).as_posix()
        except ValueError:
            link = (args.out / "README.md").resolve().as_posix()
        if update_readme_block(readme, claims_block(matrix, report_link=link, fragile=fragile)):
            print(f"refreshed the claims table in {readme}")
    if not args.quiet:
        for (p, sset), rows in matrix.items():
            print(f"{column_label(p, sset)}:")
            for c, v in rows:
                own = is_self_check(c, sset, v)
                print(f"  [{mark(v.verdict, self_check=own)}] {v.verdict:17s} {c.id}"
                      + (" (harness self-check)" if own else ""))
        for f in fragile:
            print(f"fragile: {f['claim']} ({f['preset']}): procedural_test {f['test']['verdict']}, hand-built "
                  + ", ".join(f"{h['scene_set'] or 'hand-built'} {h['verdict']}" for h in f["hand_built"]))
    print(f"wrote {args.out / 'README.md'}, {args.out / 'index.html'}, {args.out / 'claims.json'}"
          + (f", {args.out / 'leaderboard.json'}" if board is not None else ""))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog=PROG))
