"""The report's generalisation section: the newest dev, test (and fresh) evaluations of the procedural
scene family side by side (:func:`experiments.leaderboard.generalisation_gap`).

``repro.report`` reads the newest ``results.parquet`` of each split under ``--evaluations`` (default
``report/evaluations``, which ``repro.evaluate --procedural ... --out report/evaluations`` writes on
purpose; :mod:`repro._report_paths`) and shows, per preset and aperture,
the mean error over the dev scenes and over the test scenes with 95 % bootstrap intervals and test − dev.
"""

from __future__ import annotations

#: Preset and metric whose pooled gap the section's text states.
HEADLINE = ("robust", "dense_textured_mae")


def load_generalisation(root) -> dict | None:
    """The generalisation section's data, or None without both a dev and a test evaluation under ``root``.

    Returns
    -------
    dict or None
        ``rows`` (:func:`experiments.leaderboard.generalisation_gap`), ``tables``
        (:func:`experiments.leaderboard.generalisation_tables`) and ``sources``: per split and render
        size the evaluation id, its folder, when it finished, its seeds and the command that reruns it.
        Render sizes with both a dev and a test evaluation are compared.
    """
    from experiments.leaderboard import generalisation_gap, generalisation_tables
    from experiments.procedural_eval import latest_evaluations
    from experiments.results_table import read_results_csv

    latest = latest_evaluations(root)
    sizes = sorted(set(latest.get("dev", {})) & set(latest.get("test", {})))
    if not sizes:
        return None
    used = {split: {size: latest[split][size] for size in sizes if size in latest.get(split, {})}
            for split in latest}
    rows = {split: [r for info in per.values() for r in read_results_csv(info["path"])] for split, per in used.items()}
    gap = generalisation_gap(rows["dev"], rows["test"], fresh_rows=rows.get("fresh"))
    sources = [{"split": split, "scene_size": size, "evaluation_id": info["meta"].get("evaluation_id"),
                "folder": str(info["path"].parent), "finished_utc": info["meta"].get("finished_utc"),
                "seeds": info["meta"].get("seeds"), "rerun": info["meta"].get("rerun")}
               for split, per in used.items() for size, info in per.items()]
    return {"rows": gap, "tables": generalisation_tables(gap), "sources": sources}


def _fmt(s) -> str:
    if not s or s.get("value", s.get("mean")) is None:
        return "n/a"
    v = s.get("value", s.get("mean"))
    if s.get("ci_low") is None:
        return f"{v:+.3f}"
    return f"{v:+.3f} px [{s['ci_low']:+.3f}, {s['ci_high']:+.3f}]"


def generalisation_intro(gen: dict) -> str:
    """The section's paragraph: the rule, the evaluations it reads, the headline preset's pooled gap."""
    src = gen["sources"]
    used = "; ".join(f"{s['split']} ({s['scene_size']}): `{s['evaluation_id']}` (seeds {s['seeds'][0]}–{s['seeds'][1]}, "
                     f"finished {s['finished_utc']})" for s in src if s.get("seeds"))
    preset, metric = HEADLINE
    pooled = [r for r in gen["rows"] if r.get("preset") == preset and r["metric"] == metric and r["aperture"] == "all"]
    head = "".join(f" {preset}'s {metric} test − dev over all apertures ({r['scene_size']}, {r['encoding']}, "
                   f"noise {r['noise']}): {_fmt(r['gap'])}." for r in pooled)
    return ("The procedural scene family (docs/procedural.md) has disjoint seed splits: tune on `dev`, report "
            "`test` and `fresh`. Per preset and aperture, the mean over scenes with a 95 % bootstrap interval "
            "(resampling scenes), and test − dev (resampling each split's scenes independently); `all` pools "
            f"each scene's apertures. A preset tuned to the dev scenes shows a positive gap.{head} "
            f"Newest evaluation of each split and render size: {used}.")
