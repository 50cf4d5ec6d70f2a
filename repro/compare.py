"""Rank two variants with paired confidence: ``python -m repro.compare A B``.

``python -m repro.compare A B (--procedural N --split dev|test|fresh [--scene-seed-start S] | --scenes NAME ...)
[--fnumber N ...] [--scene-size small|full] [--metric NAME] [--workers W | --scheduler ADDR] [--out DIR]
[--judgement-log FILE] [--force] [-q]``

A and B are method presets (:data:`method.PRESETS`) or trivial baselines (:mod:`experiments.baselines`:
``const_median_gt``, ``const_floor``). Both are scored on the same scenes — N procedural scenes of a
split (the evaluation of ``repro.evaluate --procedural``, cached and resumable per scene), or the named
scenes (``repro.evaluate``'s cases) — and :func:`experiments.compare.compare_rows` gives, per metric and
aperture, the mean paired difference B − A with a paired bootstrap 95 % interval, a verdict (better /
worse / no difference detected), the scenes for 80 % power and the scenes for a ±0.15 px interval.
Printed (the headline metrics) and written to ``DIR/compare.csv``, ``DIR/compare.json`` (every metric,
the command, seeds and commit) and ``DIR/compare.png`` (per-scene scatter of ``--metric``).

``--split fresh`` draws unseen seeds at run time; each such run is a judgement and is appended to the
committed log (``--judgement-log``, default ``report/judgements.jsonl`` and its ``.md`` view).

Bad input (A = B, an unknown name, fewer than 2 scenes, no scene source): one line on stderr, exit 2.
"""

from __future__ import annotations

import datetime
import shlex
import sys
import time
from pathlib import Path

from ._report_paths import QUICK_COMPARE

PROG = "python -m repro.compare"
#: Default output folder (git-ignored: exploratory runs never touch the committed report).
DEFAULT_OUT = QUICK_COMPARE


def _parser():
    from experiments.baselines import BASELINES
    from method import PRESETS
    from repro._cli import (ArgumentParser, add_force_option, add_plugin_options, add_quiet_option,
                            add_scene_size_option, add_variant_option, float_type, int_type)
    from repro._runner import add_engine_options

    names = ", ".join([*PRESETS, *BASELINES])
    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    p.add_argument("a", metavar="A", help=f"the reference variant: a preset or baseline ({names})")
    p.add_argument("b", metavar="B", help="the variant judged against A (differences are B − A)")
    p.add_argument("--procedural", type=int_type("--procedural"), default=None, metavar="N",
                   help="compare on N scenes (N ≥ 2) of the procedural family (needs --split)")
    p.add_argument("--split", default=None, metavar="dev|test|fresh",
                   help="with --procedural: tune on dev; test is held out but seen; fresh draws unseen seeds "
                        "at run time and logs the judgement")
    p.add_argument("--scene-seed-start", type=int_type("--scene-seed-start", minimum=0), default=None, metavar="S",
                   help="with --procedural: first seed (default: the split's first; fresh: drawn)")
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help="compare on these named scenes (at least 2) instead of procedural ones")
    p.add_argument("--fnumber", nargs="+", type=float_type("--fnumber"), default=None, metavar="N",
                   help="apertures (default: 8 4 2 with --procedural, 8 4 with --scenes)")
    add_scene_size_option(p)
    add_variant_option(p)
    add_engine_options(p, what="scenes")
    p.add_argument("--metric", default="dense_textured_mae", metavar="NAME",
                   help="metric of the scatter plot (default dense_textured_mae; every metric is in the tables)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR", help=f"output folder (default: {DEFAULT_OUT})")
    p.add_argument("--judgement-log", type=Path, default=None, metavar="FILE",
                   help="with --split fresh: the committed log the judgement is appended to "
                        "(default: report/judgements.jsonl)")
    add_force_option(p)
    add_plugin_options(p)
    add_quiet_option(p, what="no progress display")
    return p


def validate(args):
    """``(a, b, presets, source)``: ``source`` a :class:`experiments.procedural_eval.ProceduralPlan` or
    ``(scenes, f_numbers)``. Raises ValueError (one line naming what is allowed)."""
    from experiments.baselines import BASELINES
    from experiments.compare import check_pair
    from method import PRESETS

    a, b = check_pair(args.a, args.b, presets=PRESETS, baselines=BASELINES)
    from ._evaluate_table import METRIC_COLUMNS

    plotted = [m for m in METRIC_COLUMNS if m != "seconds_total"]
    if args.metric not in plotted:
        raise ValueError(f"--metric {args.metric!r} is invalid; allowed: {', '.join(plotted)}")
    presets = tuple(n for n in (a, b) if n in PRESETS) or ("paper",)  # two baselines: paper carries the renders
    if (args.procedural is None) == (args.scenes is None):
        raise ValueError("give one scene source; allowed: --procedural N --split dev|test|fresh, or --scenes NAME ...")
    if args.procedural is not None:
        from experiments.procedural_eval import plan_evaluation

        if args.split is None:
            raise ValueError("--procedural needs --split; allowed: dev, test, fresh")
        if args.procedural < 2:
            raise ValueError(f"--procedural {args.procedural} is invalid (a paired interval needs two scenes); "
                             "allowed: N ≥ 2")
        plan = plan_evaluation(args.procedural, split=args.split, start=args.scene_seed_start, presets=presets,
                               f_numbers=args.fnumber, scene_size=args.scene_size, variant=args.variant)
        return a, b, presets, plan
    if args.split is not None or args.scene_seed_start is not None:
        raise ValueError("--split and --scene-seed-start are invalid with --scenes; allowed: with --procedural N")
    from method.registry import Registry
    from scenes import SCENES

    names = Registry("scene", list(SCENES)).check_all(dict.fromkeys(args.scenes), what="scene")
    if len(names) < 2:
        raise ValueError(f"--scenes {' '.join(names)} is invalid (a paired interval needs two scenes); "
                         "allowed: at least 2 scenes")
    return a, b, presets, (names, [float(n) for n in dict.fromkeys(args.fnumber or [8.0, 4.0])])


def _rows(args, presets, source, out: Path, workers, scheduler) -> tuple[list[dict], dict]:
    """The long results rows of both variants and what identifies the scenes (seeds or names)."""
    from experiments.procedural_eval import ProceduralPlan

    if isinstance(source, ProceduralPlan):
        from ._evaluate_procedural import run_evaluation

        run = run_evaluation(source, out / "evaluations", workers=workers, scheduler=scheduler, force=args.force,
                             progress=not args.quiet, command=list(sys.argv))
        return run.rows, {"seeds": [source.start, source.start + source.n - 1], "split": source.split,
                          "evaluation": str(run.folder), "failures": run.failures}
    from experiments.units import EvaluateConfig

    from .evaluate import evaluate_named

    scenes, f_numbers = source
    config = EvaluateConfig(presets=presets, scenes=tuple(scenes), f_numbers=tuple(f_numbers),
                            scene_size=args.scene_size, variant=args.variant)
    data = evaluate_named(config, workers=workers, scheduler=scheduler, force=args.force, progress=not args.quiet)
    # the case runner's rows name nested metrics with "/" (dense/textured/mae); the tables use "_"
    return ([{**r, "source": "scenes", "metric": r["metric"].replace("/", "_")} for r in data.rows()],
            {"scenes": list(scenes)})


def _scatter(records, rows, a, b, metric, out_stem):
    """The per-scene scatter of ``metric`` (one panel per aperture of the first encoding and noise)."""
    from experiments.compare import paired_values
    from experiments.plotting.compare import plot_scatter

    shown = {(r["aperture"], r["encoding"], r["noise"]): r for r in records if r["metric"] == metric}
    pairs = paired_values(rows, a, b)
    panels = []
    for (ap, enc, noise), r in shown.items():
        if r["ci_low"] is None:
            continue
        _, va, vb = pairs[(ap, enc, noise, metric)]
        panels.append((f"f/{ap:g}: {b} − {a} = {r['mean_diff']:+.3f}\n95 % [{r['ci_low']:+.3f}, {r['ci_high']:+.3f}]",
                       va, vb))
    if not panels:
        return []
    return plot_scatter(panels, out_stem, a=a, b=b, metric=metric, unit=next(iter(shown.values()))["unit"])


def _baseline_means(rows, plan_apertures) -> dict:
    """Mean dense textured MAE of every baseline per aperture over the rows' scenes (for the log)."""
    from experiments.baselines import BASELINES

    out: dict = {}
    for name in BASELINES:
        for ap in plan_apertures:
            v = [r["value"] for r in rows if r.get("preset") == name and r["metric"] == "dense_textured_mae"
                 and r.get("aperture") == ap and r.get("value") is not None]
            if v:
                out.setdefault(name, {})[f"{ap:g}"] = sum(v) / len(v)
    return out


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    from repro._cli import CLIError, require_extras, user_input

    args = _parser().parse_args(argv)
    with user_input():
        a, b, presets, source = validate(args)
    out = args.out if args.out is not None else DEFAULT_OUT
    if out.exists() and not out.is_dir():
        raise CLIError(f"--out {str(out)!r} is a file; allowed: a folder")
    require_extras("render", command="repro.compare")
    if args.variant:
        from scenes.backend import select_variant

        select_variant(args.variant)
    from ._runner import engine_choice

    workers, scheduler = engine_choice(args.workers, args.scheduler, command="repro.compare")
    split = getattr(source, "split", None)
    if split == "fresh" and args.scene_seed_start is None:
        print(f"fresh seeds drawn: {source.start}..{source.start + source.n - 1}", file=sys.stderr)
    from experiments.dataset import git_commit

    t0, commit = time.perf_counter(), git_commit()  # the code that runs (before any file changes meanwhile)
    rows, where = _rows(args, presets, source, out, workers, scheduler)
    from experiments.compare import compare_rows, format_comparison
    from experiments.cache_keys import to_jsonable

    records = compare_rows(rows, a, b, n_resamples=10_000, seed=0)
    wall = time.perf_counter() - t0
    command = " ".join(["python -m repro.compare", *map(shlex.quote, sys.argv[1:] if argv is None else argv)])
    meta = {"a": a, "b": b, "command": command, "commit": commit,
            "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "scene_size": args.scene_size, "wall_s": wall, **where}
    from experiments.results_table import write_results

    from ._evaluate_table import write_csv_json

    paths = write_csv_json(out, "compare", records, list(records[0]) if records else ["metric"],
                           {**meta, "records": records})
    paths += _scatter(records, rows, a, b, args.metric, out / "compare")
    print(format_comparison(records, a, b))
    if split == "fresh":
        from experiments.compare import HEADLINE_METRICS
        from experiments.judgements import DEFAULT_LOG, append_judgement

        verdicts = [r for r in records if r["metric"] == HEADLINE_METRICS[0] and r["ci_low"] is not None]
        n_scenes = max((r["n_scenes"] for r in records), default=0)
        rec = to_jsonable({**{k: meta[k] for k in ("a", "b", "command", "commit", "date_utc", "scene_size", "seeds")},
                           "n_scenes": n_scenes, "verdicts": verdicts,
                           "baselines": _baseline_means(rows, source.f_numbers)})
        log = args.judgement_log or DEFAULT_LOG
        count = append_judgement(rec, log)
        print(f"judgement {count} on fresh scenes logged in {log}")
    paths += write_results(out, rows, to_jsonable(meta), stem="rows")
    print(f"{wall:.0f} s wall; per aperture ({HEADLINE}): " + "; ".join(
        f"f/{r['aperture']:g} ±{r['half_width']:.3f} px, {r['n_for_half_width']} scenes for ±0.15 px"
        for r in records if r["metric"] == HEADLINE and r["half_width"] is not None))
    for p in paths:
        print(f"  {p}")
    return 0


#: The metric of the closing line (per aperture: the interval's half-width and the scenes for ±0.15 px).
HEADLINE = "dense_textured_mae"


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
