"""Benchmark suite: per-stage and whole-pipeline wall time and peak memory of the method.

``python -m repro.bench [--sizes 256 512 1024] [--preset paper robust] [--repeat 3] [--out report/bench]``

Each (preset, size) runs in a fresh subprocess (so its peak resident memory, ``ru_maxrss``, is its
own) on a textured photo-like image (``skimage.data.astronaut`` resized, shipped with scikit-image),
with the 1-min load average before and after. Writes ``bench.json`` and ``bench.md`` and prints the
table; the run it replaces (the previous ``bench.json`` in ``--out``) is kept in the output as
"before". Targets (:mod:`experiments.bench.speed`, this 2-core machine kind), for every preset: whole
pipeline at 1 MP ≤ 1.0 s and ≤ 1.5 GiB, at 512² ≤ 1.0 s; 512² → 1024² cost growth ≤ 4.5×. The machine
is shared, so each row says how loaded it was; the fastest of ``--repeat`` runs counts. Then, for each
renderer of ``--magnify-renderers`` (default ``scatter``; none to skip), the magnification step alone on
a 12-MP photo (``skimage.data.coffee`` upscaled) with its map given, as ``repro.magnify --map`` runs it,
in a fresh process (:func:`experiments.bench.speed.time_magnification`); target for the scatter ≤ 20 s.

``python -m repro.bench --accuracy [--out report/bench]`` instead records the targets of the
dense-map issue (:func:`experiments.bench.accuracy.accuracy_report`, configuration
:data:`experiments.bench.accuracy.ACCURACY_CONFIG`): dense-map and sparse
edge errors per σ bin on analytic truth (dead-leaves / photo mosaics, step-edge mosaics; 8 bits +
noise), on the rendered scenes, and the whole-pipeline speed of the presets, with pass/fail per
target. Writes ``accuracy.json`` and ``accuracy.md`` (``--sizes`` / ``--repeat`` do not apply). Its
analytic and rendered cases run on the case runner (:mod:`repro._runner`): ``--workers N`` (alias
``--jobs``) Dask workers, default one per core, or ``--scheduler ADDRESS``; the speed runs follow alone.

``--psf NAME…`` chooses the PSFs of its lens part (:mod:`experiments.bench.lens`: texture families and
steps blurred by a lens PSF in linear light, then a camera's noise and tone curve) and ``--full`` its
full grid; ``--grid large`` runs its large-blur grid instead (σ 8–16 px on 224-px tiles, its own variants).
``python -m repro.bench --doubling`` runs the doubling claim of Fig. 7 at both render sizes of the same
scenes with the f/4 stage attribution for each ``--preset`` (:mod:`experiments.doubling_sizes`; ``doubling.md``, which
``repro.report`` shows). ``python -m repro.bench --ablation`` runs the robust preset's ablation on the lens bench, the
paper_cameras renders and the real photos (:mod:`experiments.bench.ablation`; ``ablation.md``).

``python -m repro.bench --magnify [--out report/bench]`` records the targets of the magnification as
the robust preset does it by default (:mod:`experiments.bench.magnify_targets`: the paper_cameras full
renders against the real f/4 render, the photos' drawn regions, the 12-MP scatter in a fresh process).
Writes ``magnify.json`` and ``magnify.md``.

``python -m repro.bench --figures [--out report/bench]`` benchmarks the case runner
(:func:`repro._figures_bench.run_figures_bench`): ``repro.figures --quick`` with every case recomputed
(renders cached), 1 and 2 workers, the two tables compared row for row; ``figures_speed.json`` and
``figures_speed.md`` (target: ≥ 1.3× with 2 workers on a 2-core machine).

``python -m repro.bench --first-photo [--out report/bench]`` times the first ``repro.estimate`` of a new
install (:func:`first_photo_bench`): ``skimage.data.chelsea`` (451×300) in a fresh process with an empty
numba cache (``NUMBA_CACHE_DIR`` a new temporary folder) and an empty map cache, once as installed and
once after ``python -m repro.warmup``; ``first_photo.json`` and ``first_photo.md`` (target ≤ 10 s).

``python -m repro.bench --sweep [--out report/bench]`` benchmarks the sweep engine
(:func:`repro._sweep_bench.run_sweep_bench`): cells per minute for 1 and 2 workers on the small preset and the
engine's overhead per cell. Writes ``sweep.json`` and ``sweep.md``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

PROG = "python -m repro.bench"


def _run_size(size: int, repeat: int, preset: str = "paper") -> dict:
    """One (preset, size) timed in a fresh process (its own peak memory): ``--worker``'s JSON line
    (the process registers the same plugins: entry points and ``--estimator-module`` / ``--preset-module``)."""
    from repro._plugins import plugin_argv

    cmd = [sys.executable, "-m", "repro.bench", "--worker", str(size), "--repeat", str(repeat),
           "--worker-preset", preset, *plugin_argv()]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark of {preset} at {size}² failed:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _run_magnify(renderer: str) -> dict:
    """The 12-MP magnification of ``renderer`` timed in a fresh process: ``--worker-magnify``'s JSON line."""
    cmd = [sys.executable, "-m", "repro.bench", "--worker-magnify", renderer]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"magnification benchmark of {renderer} failed:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _previous_run(path: Path) -> dict | None:
    """The run a new ``bench.json`` replaces (date, rows, summary), or None."""
    try:
        before = json.loads(path.read_text(encoding="utf-8"))
        return {"date": before["date"], "rows": before["rows"], "summary": before["summary"]}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def run_accuracy(config: dict | None = None, *, out: Path, progress: bool = True, workers: int | None = 1,
                 scheduler: str | None = None) -> dict:
    """Measure and judge (:func:`experiments.bench.accuracy.accuracy_report`), then write
    ``accuracy.json`` and ``accuracy.md`` to ``out`` (created; files written atomically).

    The analytic and rendered cases run on the case runner (:mod:`repro._runner`: ``workers`` Dask
    workers, ``scheduler``, or in this process for one worker); the speed runs afterwards, alone."""
    from defocus_cache import atomic_write_text
    from experiments.bench import accuracy_markdown, accuracy_report

    from ._runner import FigureJob, run_figures

    def run_cases(unit, cfg):
        (run,) = run_figures([FigureJob(unit, cfg, "accuracy")], workers=workers, scheduler=scheduler,
                             progress=progress, desc="accuracy")
        if run.error is not None:
            raise RuntimeError(f"an accuracy case failed: {run.error}\n{run.traceback}")
        return run.data.outputs

    report = accuracy_report(config, progress=progress, run_cases=run_cases)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "accuracy.json", json.dumps(report, allow_nan=False, separators=(",", ":")))
    atomic_write_text(out / "accuracy.md", accuracy_markdown(report) + "\n")
    return report


#: The first photo's wall-time target after ``repro.warmup``, s.
FIRST_PHOTO_TARGET_S = 10.0


def _timed(cmd, env) -> dict:
    """Run ``cmd`` with ``env``; its wall time and its CPU (user + system of the child), s."""
    import os
    import resource
    import time

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env={**os.environ, **env})
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}


def first_photo_bench(out: Path) -> dict:
    """The first ``repro.estimate`` of a new install, without and with ``repro.warmup`` first.

    Each case gets a new empty numba cache (``NUMBA_CACHE_DIR``) and map cache (``DEFOCUS_CACHE_DIR``);
    ``repro.estimate`` (default preset) runs on ``skimage.data.chelsea`` written as a PNG, in a fresh
    process. Writes ``first_photo.json`` and ``first_photo.md`` to ``out`` (atomically).

    Returns
    -------
    dict
        ``cold`` and ``warm`` (``wall_s``, ``cpu_s`` of the first estimate), ``warmup`` (of
        ``repro.warmup``), ``target_s``, ``ok``, ``load_before`` / ``load_after`` (1-min load average),
        ``date``, ``machine``.
    """
    import datetime
    import os
    import tempfile

    from PIL import Image
    from skimage import data

    from defocus_cache import atomic_write_text
    from experiments.bench.speed import machine_info

    report = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
              "machine": machine_info(), "load_before": round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory(prefix="defocus-first-photo-") as tmp:
        photo = Path(tmp) / "chelsea.png"
        Image.fromarray(data.chelsea()).save(photo)
        for case in ("cold", "warm"):
            env = {"NUMBA_CACHE_DIR": str(Path(tmp) / f"numba-{case}"), "DEFOCUS_CACHE_DIR": str(Path(tmp) / case)}
            if case == "warm":
                report["warmup"] = _timed([sys.executable, "-m", "repro.warmup", "--quiet"], env)
            report[case] = _timed([sys.executable, "-m", "repro.estimate", str(photo), "-o",
                                   str(Path(tmp) / f"{case}.npy"), "--quiet"], env)
    report["load_after"] = round(os.getloadavg()[0], 2)
    report["target_s"] = FIRST_PHOTO_TARGET_S
    report["ok"] = bool(report["warm"]["wall_s"] <= FIRST_PHOTO_TARGET_S)
    md = ["# The first photo of a new install", "",
          f"`python -m repro.bench --first-photo`, {report['date']}, 1-min load {report['load_before']} before, "
          f"{report['load_after']} after. `repro.estimate` (default preset) on chelsea (451×300) in a fresh "
          "process with empty numba and map caches.", "",
          "| run | wall (s) | CPU (s) |", "|---|---|---|",
          f"| first estimate, no warm-up | {report['cold']['wall_s']} | {report['cold']['cpu_s']} |",
          f"| `python -m repro.warmup` | {report['warmup']['wall_s']} | {report['warmup']['cpu_s']} |",
          f"| first estimate after the warm-up | {report['warm']['wall_s']} | {report['warm']['cpu_s']} |", "",
          f"Target: first estimate after the warm-up ≤ {FIRST_PHOTO_TARGET_S:g} s: "
          f"{'met' if report['ok'] else 'not met'}."]
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "first_photo.json", json.dumps(report, indent=1))
    atomic_write_text(out / "first_photo.md", "\n".join(md) + "\n")
    return report


def _speed_bench(args) -> None:
    """The plain speed bench: each (preset, size) in a subprocess, then ``bench.json`` / ``bench.md``."""
    from tqdm import tqdm

    from defocus_cache import atomic_write_text
    from experiments.bench import speed_markdown, speed_report
    from method import PRESETS
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    from repro._cli import user_input

    with user_input():  # --preset, --magnify-renderers
        PRESETS.check_all(args.preset)
        renderers = [] if args.magnify_renderers == ["none"] else args.magnify_renderers
        for r in renderers:
            MAGNIFICATION_RENDERERS.check(r, what="--magnify-renderers")
    before = _previous_run(args.out / "bench.json")
    jobs = [(p, s) for p in args.preset for s in args.sizes]
    rows = [_run_size(s, args.repeat, p) for p, s in tqdm(jobs, desc="bench runs", unit="run", disable=args.quiet)]
    magnify_rows = [_run_magnify(r) for r in tqdm(renderers, desc="12-MP magnification", unit="run",
                                                   disable=args.quiet)]
    report = speed_report(rows, before=before, magnify_rows=magnify_rows)
    md = speed_markdown(report, repeat=args.repeat)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "bench.json", json.dumps(report, indent=1))
    atomic_write_text(args.out / "bench.md", md)
    print(md)


def _write_report(out: Path, stem: str, json_text: str, markdown: str) -> None:
    """Write ``<stem>.json`` and ``<stem>.md`` into ``out`` (atomically) and print the Markdown."""
    from defocus_cache import atomic_write_text

    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / f"{stem}.json", json_text)
    atomic_write_text(out / f"{stem}.md", markdown)
    print(markdown, end="" if markdown.endswith("\n") else "\n")


def _parser():
    from experiments.bench import BENCH_PRESETS, LENS_CONFIG
    from experiments.bench.speed import MAGNIFY_BENCH_RENDERERS
    from scenes.analytic.psfs import PSFS
    from repro._cli import (ArgumentParser, add_plugin_options, add_preset_option, add_quiet_option, hidden_alias,
                            int_type)

    parser = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int_type("--sizes", minimum=16), nargs="+", default=[256, 512, 1024],
                        help="image sides, px (>= 16)")
    parser.add_argument("--repeat", type=int_type("--repeat"), default=3, help="runs per size; the fastest counts")
    add_quiet_option(parser, what="no progress display")
    parser.add_argument("--out", type=Path, default=Path("report") / "bench", metavar="DIR",
                        help="output folder (default: report/bench)")
    parser.add_argument("--accuracy", action="store_true",
                        help="record the dense-map accuracy targets (accuracy.md / accuracy.json) instead")
    parser.add_argument("--psf", nargs="+", metavar="NAME",
                        help=f"with --accuracy: the lens PSFs of the lens benchmark ({', '.join(PSFS)}; default: "
                             f"{' '.join(LENS_CONFIG['psfs'])})")
    parser.add_argument("--full", action="store_true",
                        help="with --accuracy: the full lens grid (every PSF and noise level, JPEG 85, two seeds, "
                             "every tone curve)")
    parser.add_argument("--tone-curves", action="store_true",
                        help="with --accuracy: the lens tone grid (ISO 100, every tone curve and display-value blur; "
                             "robust in both lights and with its curve fitted)")
    parser.add_argument("--grid", default=None, metavar="NAME",
                        help="with --accuracy: the lens grid by name (default, full, tones, large: σ 8–16 px on 224-px "
                             "tiles, the fit's scale following off, on and guarded)")
    parser.add_argument("--doubling", action="store_true",
                        help="run the doubling claim (Fig. 7) at both render sizes of the same scenes with the f/4 "
                             "stage attribution instead, per --preset (doubling.md / doubling.json)")
    from ._runner import add_engine_options

    add_engine_options(parser, what="with --accuracy: the analytic and rendered cases")
    parser.add_argument("--ablation", action="store_true",
                        help="run the robust preset's ablation on the lens bench, the paper_cameras renders (full "
                             "preset, f/8 f/4 f/2) and the real photos instead (ablation.md / ablation.json)")
    parser.add_argument("--magnify", action="store_true",
                        help="record the magnification targets (robust's default renderer and floor): "
                             "magnify.json / magnify.md")
    parser.add_argument("--figures", action="store_true",
                        help="benchmark the case runner instead: repro.figures --quick (every case recomputed) with 1 "
                             "and 2 workers, tables compared (figures_speed.md / figures_speed.json)")
    parser.add_argument("--first-photo", action="store_true",
                        help="time the first repro.estimate of a new install (empty numba cache) without and with "
                             "repro.warmup instead (first_photo.md / first_photo.json)")
    parser.add_argument("--sweep", action="store_true",
                        help="benchmark the sweep engine instead (cells/minute for 1 and 2 workers, engine overhead "
                             "per cell; sweep.md / sweep.json)")
    add_preset_option(parser, default=tuple(BENCH_PRESETS), many=True, extra="the presets timed")
    hidden_alias(parser, "--presets", dest="preset", nargs="+", metavar="NAME")
    parser.add_argument("--magnify-renderers", nargs="+", default=list(MAGNIFY_BENCH_RENDERERS), metavar="NAME",
                        help="renderers whose magnification step alone is timed on a 12-MP photo with its map "
                             f"given (default: {' '.join(MAGNIFY_BENCH_RENDERERS)}; 'none' to skip)")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--worker-magnify", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--worker-preset", default="paper", help=argparse.SUPPRESS)
    add_plugin_options(parser)
    return parser


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    from repro._cli import CLIError, require_extras, user_input

    args = _parser().parse_args(argv)
    if args.worker_magnify is not None:
        from experiments.bench.speed import time_magnification

        print(json.dumps(time_magnification(args.worker_magnify)))
        return 0
    if args.worker is not None:
        from experiments.bench import time_pipeline

        print(json.dumps(time_pipeline(args.worker, args.repeat, args.worker_preset)))
        return 0
    if (args.psf or args.full or args.tone_curves) and not args.accuracy:
        raise CLIError("--psf, --full and --tone-curves go with --accuracy")
    if args.grid and not args.accuracy:
        raise CLIError("--grid goes with --accuracy; allowed: --accuracy --grid NAME")
    if args.full and args.grid:
        raise CLIError("--full and --grid exclude each other; allowed: --full or --grid NAME")
    if (args.workers is not None or args.scheduler is not None) and not args.accuracy:
        raise CLIError("--workers and --scheduler go with --accuracy; allowed: --accuracy --workers N")
    if args.accuracy:
        require_extras("render", command="repro.bench --accuracy")
        from experiments.bench import accuracy, lens_config

        config = dict(accuracy.ACCURACY_CONFIG)
        if config.get("lens") is not None and args.tone_curves:
            with user_input():  # --psf names
                config["lens"] = lens_config(psfs=args.psf, full=args.full, tones=True)
        elif config.get("lens") is not None and (args.psf or args.full or args.grid):
            with user_input():  # --psf and --grid names
                cfg = lens_config(psfs=args.psf, full=args.full, grid=args.grid)
                config["lens"] = cfg if args.grid else {**cfg, "variants": config["lens"]["variants"]}
        from ._runner import engine_choice

        workers, scheduler = engine_choice(args.workers, args.scheduler, command=f"{PROG} --accuracy")
        run_accuracy(config, out=args.out, progress=not args.quiet, workers=workers, scheduler=scheduler)
        print((args.out / "accuracy.md").read_text(encoding="utf-8"))
        return 0
    if args.ablation:
        require_extras("render", command="repro.bench --ablation")
        from experiments.bench import ablation_markdown, ablation_report

        report = ablation_report(progress=not args.quiet)
        _write_report(args.out, "ablation", json.dumps(report, indent=1, allow_nan=False, default=str),
                      ablation_markdown(report) + "\n")
        return 0
    if args.magnify:
        require_extras("render", command="repro.bench --magnify")
        from experiments.bench.magnify_targets import magnify_markdown, magnify_report
        from method import DefocusParams

        report = magnify_report("robust", speed_row=_run_magnify(DefocusParams.preset("robust").magnify_renderer))
        _write_report(args.out, "magnify", json.dumps(report, indent=1, default=str), magnify_markdown(report) + "\n")
        return 0
    if args.doubling:
        require_extras("render", command="repro.bench --doubling")
        from experiments.cache_keys import to_jsonable
        from experiments.doubling_sizes import DOUBLING_SIZES_CONFIG, doubling_markdown, doubling_report
        from method import PRESETS
        from repro._cli import user_input

        with user_input():
            PRESETS.check_all(args.preset)
        reports = {p: doubling_report({**DOUBLING_SIZES_CONFIG, "preset": p}, progress=not args.quiet)
                   for p in args.preset}
        _write_report(args.out, "doubling", json.dumps(to_jsonable(reports), indent=1, allow_nan=False),
                      "\n".join(doubling_markdown(r) for r in reports.values()))
        return 0
    if args.figures:
        require_extras("sweep", "render", command="repro.bench --figures")
        from repro._figures_bench import run_figures_bench

        run_figures_bench(args.out, progress=not args.quiet)
        print((args.out / "figures_speed.md").read_text(encoding="utf-8"))
        return 0
    if args.first_photo:
        first_photo_bench(args.out)
        print((args.out / "first_photo.md").read_text(encoding="utf-8"))
        return 0
    if args.sweep:
        require_extras("sweep", "render", command="repro.bench --sweep")
        from repro._sweep_bench import run_sweep_bench

        run_sweep_bench(args.out)
        print((args.out / "sweep.md").read_text(encoding="utf-8"))
        return 0
    _speed_bench(args)
    return 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
