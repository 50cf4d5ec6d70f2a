"""``python -m repro.evaluate --procedural N``: the procedural scene family scored at scale, on Dask.

One case per scene (:func:`experiments.procedural_eval.score_scene`: its renders at every aperture
through the render cache, every preset on every input, scored against σ_gt by
:func:`experiments.scoring.score_render`), run by the case runner (:mod:`repro._runner`) on a Dask
LocalCluster of single-threaded workers (``--workers``, default one per core), an existing scheduler
(``--scheduler``) or in this process (``--workers 1``). Each finished scene is stored at once in the one
case store (:func:`experiments.cases.run_case`, ``<cache>/figures``), so the same command after Ctrl-C, a
crash or a killed worker reads finished scenes back. The outputs go to ``DIR/<evaluation id>/`` (``DIR``: ``--out``,
default the git-ignored ``report/quick/evaluations``; the committed report shows those of ``report/evaluations``). Then the long results table (:mod:`experiments.results_table`:
``results.parquet`` + ``results.csv``), the summary per preset and aperture with 95 % bootstrap
intervals over scenes (``summary.csv``, ``summary.json``), the timings per scene and lighting kind
(``timings.json``) and ``run.json`` (the plan, the seeds and the command that reruns them; written
first, so a ``fresh`` evaluation's drawn seeds are on disk before anything is rendered).
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import sys
import time
from pathlib import Path

from ._report_paths import QUICK_EVALUATIONS

PROG = "python -m repro.evaluate"
#: Default output root of ``--procedural`` (one folder per evaluation id), git-ignored: an exploratory run never
#: changes the committed report, which shows the newest evaluations of ``report/evaluations`` (written there only
#: with ``--out report/evaluations``; :mod:`repro._report_paths`).
DEFAULT_ROOT = QUICK_EVALUATIONS
#: Options only ``--procedural`` takes (flag, attribute, argparse default).
PROCEDURAL_ONLY = (("--split", "split", None), ("--scene-seed-start", "scene_seed_start", None), ("--spp", "spp", None))
#: Options of the named-scene evaluation that ``--procedural`` does not take.
NOT_PROCEDURAL = (("--scenes", "scenes", None), ("--stages", "stages", False),
                  ("--photos", "photos", None), ("--maps", "maps", None))


def noises(names) -> list[str]:
    """``--noise`` names (default ``["none"]``), duplicates dropped; ValueError naming the levels on a bad one."""
    from scenes.display import NOISE_LEVELS

    out = list(dict.fromkeys(names or ["none"]))
    for level in out:
        if level not in NOISE_LEVELS:
            raise ValueError(f"--noise {level!r} is invalid (unknown noise level); allowed: {', '.join(NOISE_LEVELS)}")
    return out


def add_options(p) -> None:
    """``--noise`` and the ``--procedural`` flags of ``repro.evaluate``'s parser."""
    from repro._cli import int_type
    from scenes.display import NOISE_LEVELS

    p.add_argument("--noise", nargs="+", default=None, metavar="LEVEL",
                   help=f"sensor noise level(s) of the input, an axis ({', '.join(NOISE_LEVELS)}; default: none)")

    p.add_argument("--procedural", type=int_type("--procedural"), default=None, metavar="N",
                   help="score the presets on N scenes of the procedural family (docs/procedural.md) instead of "
                        "the named scenes")
    p.add_argument("--split", default=None, metavar="dev|test|fresh",
                   help="with --procedural: the seed split (tune on dev; report test and fresh)")
    p.add_argument("--scene-seed-start", type=int_type("--scene-seed-start", minimum=0), default=None, metavar="S",
                   help="with --procedural: first scene seed (default: the split's first; fresh: drawn at run time "
                        "and recorded). Not --seed: that one is a render's sampler seed")
    from ._runner import add_engine_options

    add_engine_options(p, what="cases (scenes, photos, procedural scenes)")
    p.add_argument("--spp", type=int_type("--spp"), default=None, metavar="N",
                   help="with --procedural: samples per pixel of every render (default: each scene's own)")


def validate(args):
    """The :class:`experiments.procedural_eval.ProceduralPlan` of the flags and the output root (ValueError)."""
    from experiments.procedural_eval import plan_evaluation

    used = [flag for flag, attr, default in NOT_PROCEDURAL if getattr(args, attr, default) != default]
    if used:
        raise ValueError(f"--procedural does not take {', '.join(used)}; allowed with --procedural: --split, "
                         "--scene-seed-start, --preset, --estimator, --fnumber, --scene-size, --noise, --encoding, --spp, "
                         "--workers | --scheduler, --variant, --out, --force, -q")
    if args.split is None:
        raise ValueError("--procedural needs --split; allowed: dev, test, fresh (tune on dev; report test and fresh)")
    plan = plan_evaluation(args.procedural, split=args.split, start=args.scene_seed_start, presets=args.preset,
                           f_numbers=args.fnumber, scene_size=args.scene_size, noises=args.noise or ["none"],
                           encodings=args.encoding, spp=args.spp, variant=args.variant, estimators=args.estimator)
    root = args.out if args.out is not None else DEFAULT_ROOT
    if root.exists() and not root.is_dir():
        raise ValueError(f"--out {str(root)!r} is a file; allowed: a folder")
    if args.scheduler is not None:
        from ._runner import check_scheduler

        check_scheduler(args.scheduler)
    return plan, root


@dataclasses.dataclass
class EvaluationRun:
    """What :func:`run_evaluation` did."""

    folder: Path
    rows: list
    summary: list
    timings: dict
    n_resumed: int
    wall_s: float
    paths: list
    failures: dict  # seed -> lines of the method runs that raised
    traceback: str | None = None  # of the first run that raised


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _timing_summary(records: dict) -> dict:
    """Per lighting kind: scenes, mean seconds of a render when it was made, mean seconds of scoring one
    render per preset (all encodings and noise levels)."""
    out: dict[str, dict] = {}
    for rec in records.values():
        t = rec["result"]["timings"]
        kind = out.setdefault(t["lighting"], {"scenes": 0, "render": [], "score": {}})
        kind["scenes"] += 1
        kind["render"] += list(t["render_built_s"].values())
        for per in t["score_s"].values():
            for preset, s in per.items():
                kind["score"].setdefault(preset, []).append(s)
    for kind in out.values():
        r = kind.pop("render")
        kind["mean_render_built_s_per_aperture"] = sum(r) / len(r) if r else None
        kind["mean_score_s_per_aperture"] = {p: sum(v) / len(v) for p, v in kind.pop("score").items()}
    return out


def run_evaluation(plan, root, *, workers=None, scheduler=None, force=False, progress=True, log=None,
                   command=None) -> EvaluationRun:
    """Run (or resume) an evaluation and write its tables into ``root / plan.evaluation_id``.

    Parameters
    ----------
    plan : experiments.procedural_eval.ProceduralPlan
    root : path
        Output root; the evaluation's folder is created in it.
    workers : int, optional, keyword-only
        LocalCluster size (default: one per core); 1 runs the scenes in this process.
    scheduler : str, optional, keyword-only
        Address of an existing Dask scheduler.
    force : bool, keyword-only
        Recompute every scene (stored results are replaced).
    progress : bool, keyword-only
        tqdm bar of scenes done / total with an ETA.
    log : callable, optional, keyword-only
        One-line messages (default: stderr).
    command : list of str, optional, keyword-only
        The command line recorded in ``run.json``.

    Returns
    -------
    EvaluationRun

    Notes
    -----
    1. ``run.json`` (plan, seeds, the command that reruns them) is written before anything runs.
    2. One case per scene (:data:`experiments.units.PROCEDURAL`) in the one case store
       (:func:`experiments.cases.run_case`); scenes the store holds are read back here.
    3. The others run on the case runner (:func:`repro._runner.run_figures`); each is stored as it finishes.
    4. Rows in seed order; the results table, the summary and the timings, atomically.
    """
    from defocus_cache import atomic_write_text
    from experiments.cases import run_case, stored_case
    from experiments.procedural_eval import summary_rows
    from experiments.cache_keys import code_fingerprint, to_jsonable
    from experiments.registry import library_versions
    from experiments.results_table import write_results
    from experiments.units import PROCEDURAL
    from scenes.library.procedural import seed_of

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    t0, eid = time.perf_counter(), plan.evaluation_id
    out = Path(root) / eid
    out.mkdir(parents=True, exist_ok=True)
    rerun = ["python", "-m", "repro.evaluate", *plan.command(), "--out", str(root)]
    run_info = {"evaluation_id": eid, "plan": plan.to_dict(), "seeds": [plan.start, plan.start + plan.n - 1],
                "rerun": " ".join(rerun), "command": command, "started_utc": _now()}
    atomic_write_text(out / "run.json", json.dumps(run_info, indent=1, sort_keys=True) + "\n")
    log(f"evaluation {eid}: {plan.n} {plan.split} scene(s), seeds {plan.start}..{plan.start + plan.n - 1} -> {out}")
    code, versions = code_fingerprint(), library_versions()
    cases = {seed_of(c.scene)[0]: c for c in PROCEDURAL.cases(plan)}
    records = {} if force else {s: {"result": run_case(PROCEDURAL, plan, c).info} for s, c in cases.items()
                                if stored_case(PROCEDURAL, plan, c) is not None}
    resumed = set(records)
    if resumed:
        log(f"resuming: {len(resumed)} of {plan.n} scenes read back from the case store")
    todo = [s for s in plan.seeds if s not in records]
    if todo:
        from ._runner import FigureJob, run_figures

        job = FigureJob(PROCEDURAL, plan, cases=tuple(cases[s] for s in todo))

        def store(_job, output):
            records[seed_of(output.case.scene)[0]] = {"result": output.info}

        (run,) = run_figures([job], workers=workers, scheduler=scheduler, force=force, progress=progress,
                             on_case=store, log=log, desc="evaluate")
        if run.error is not None:
            raise RuntimeError(f"a scene's task failed: {run.error}\n{run.traceback}")
    rows = [r for s in plan.seeds for r in records[s]["result"]["rows"]]
    summary = summary_rows(rows)
    timings = {"per_lighting": _timing_summary(records),
               "scenes": {str(s): {**records[s]["result"]["timings"], "resumed": s in resumed} for s in plan.seeds}}
    meta = {**run_info, "finished_utc": _now(), "code": code, "versions": versions, "n_resumed": len(resumed),
            "failures": [line for s in plan.seeds for line in records[s]["result"].get("failures", [])],
            "mitsuba_variants": sorted({str(records[s]["result"]["variant"]) for s in plan.seeds}),
            "wall_s": time.perf_counter() - t0}
    paths = write_results(out, rows, meta)
    atomic_write_text(out / "summary.json", json.dumps(to_jsonable({**meta, "summary": summary}), indent=1,
                                                       sort_keys=True) + "\n")
    paths.append(out / "summary.json")
    atomic_write_text(out / "timings.json", json.dumps(to_jsonable(timings), indent=1, sort_keys=True) + "\n")
    paths.append(out / "timings.json")
    return EvaluationRun(folder=out, rows=rows, summary=summary, timings=timings, n_resumed=len(resumed),
                         wall_s=meta["wall_s"], paths=paths,
                         failures={s: records[s]["result"].get("failures", []) for s in plan.seeds},
                         traceback=next((tb for s in plan.seeds if (tb := records[s]["result"].get("traceback"))), None))


def _ci(row) -> str:
    if row["mean"] is None:
        return "–"
    if row["ci_low"] is None:
        return f"{row['mean']:.3f}"
    return f"{row['mean']:.3f} [{row['ci_low']:.3f}, {row['ci_high']:.3f}]"


def format_summary(summary, *, metrics=("dense_textured_mae", "sparse_mae", "dense_all_mae")) -> str:
    """Terminal table: per preset × estimator × aperture (× encoding × noise) the mean over scenes [95 % interval]."""
    ids = ("preset", "estimator", "aperture", "encoding", "noise")
    keys = list(dict.fromkeys(tuple(r.get(c) for c in ids) for r in summary))
    by = {(*(r.get(c) for c in ids), r["metric"]): r for r in summary}
    head = ["preset", "estimator", "f/N", "encoding", "noise", "scenes",
            *(f"{m} (px)" if "fraction" not in m else m for m in metrics)]
    body = []
    for k in keys:
        cells = [by.get((*k, m)) for m in metrics]
        n = next((c["n_scenes"] for c in cells if c), 0)
        body.append([str(k[0]), str(k[1]), f"{k[2]:g}", str(k[3]), str(k[4]), str(n),
                     *(_ci(c) if c else "–" for c in cells)])
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]
    lines = ["mean over scenes [95 % bootstrap interval]", "  ".join(h.ljust(w) for h, w in zip(head, widths))]
    return "\n".join(lines + ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body])


def main_procedural(args) -> int:
    """``--procedural``: plan, run (or resume) and write one evaluation; exit status."""
    from repro._cli import require_extras, user_input

    with user_input():
        plan, root = validate(args)
    require_extras("sweep", command="repro.evaluate --procedural")
    if plan.split == "fresh" and args.scene_seed_start is None:
        print(f"fresh seeds drawn: {plan.start}..{plan.start + plan.n - 1} (rerun or resume with "
              f"--scene-seed-start {plan.start})", file=sys.stderr)
    if args.variant:
        from scenes.backend import select_variant

        select_variant(args.variant)
    from ._runner import engine_choice

    workers, scheduler = engine_choice(args.workers, args.scheduler, command="repro.evaluate --procedural")
    run = run_evaluation(plan, root, workers=workers, scheduler=scheduler, force=args.force,
                         progress=not args.quiet, command=list(sys.argv))
    print(format_summary(run.summary))
    kinds = "; ".join(f"{k}: {v['scenes']} scene(s), {v['mean_render_built_s_per_aperture']:.1f} s per render, "
                      "scoring " + ", ".join(f"{p} {t:.1f} s" for p, t in v["mean_score_s_per_aperture"].items())
                      for k, v in run.timings["per_lighting"].items())
    print(f"scenes: {plan.n} ({run.n_resumed} read back); {kinds}; {run.wall_s:.1f} s")
    failures = [line for s in plan.seeds for line in run.failures.get(s, [])]
    if failures:
        print(f"{PROG}: the method raised on {len(failures)} input(s) (recorded as pipeline_failed = 1):",
              file=sys.stderr)
        for line in failures:
            print(f"  {line}", file=sys.stderr)
        if run.traceback:
            print(f"the first one's traceback:\n{run.traceback.rstrip()}", file=sys.stderr)
    for p in run.paths:
        print(f"  {p}")
    return 0
