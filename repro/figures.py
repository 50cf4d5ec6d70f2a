"""Reproduce the paper's figures: compute (cached), plot, and write metrics.

``python -m repro.figures [NAMES...] [--list] [--quick] [--jobs N] [--out DIR] [--force] [--preset NAME ...] [-q]``

For each figure (default: all registered in :data:`experiments.registry.FIGURES`) this renders
whatever is missing (render and compute results are cached under ``$DEFOCUS_CACHE_DIR``), runs the
experiment, and writes ``<out>/<name>.png``, ``<name>.pdf`` and ``<name>.metrics.json`` (metrics,
the config, the σ convention, library versions). ``--jobs N`` runs independent figures in N
parallel processes. ``--preset robust zhuo_sim`` sets the ``presets`` field (method parameter
presets of :data:`method.PRESETS`) of every selected figure whose config has one, to
``("paper", "robust", "zhuo_sim")`` — ``"paper"``, the reproduction, always first; ``--preset paper``
runs the paper alone; figures without that field ignore it. Unknown names or bad values: one line
on stderr, exit status 2. A figure
whose computation fails is reported (traceback, then one summary line) and the others still run;
the exit status is then 1.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

PROG = "python -m repro.figures"
DEFAULT_OUT = Path("report") / "figures"


def _parser() -> argparse.ArgumentParser:
    from experiments.registry import FIGURES
    from method import PRESETS
    from repro._cli import ArgumentParser, add_force_option, add_quiet_option, add_variant_option, int_type

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_variant_option(p)
    p.add_argument("names", nargs="*", metavar="NAME",
                   help=f"figures to make (default: all registered: {', '.join(FIGURES)})")
    p.add_argument("--list", action="store_true", help="list the registered figures and exit")
    p.add_argument("--quick", action="store_true", help="quick mode: fewer points, fewer samples per pixel")
    p.add_argument("--jobs", type=int_type("--jobs"), default=1, metavar="N", help="figures computed in parallel (processes)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, metavar="DIR",
                   help=f"output folder (default: {DEFAULT_OUT})")
    add_force_option(p)
    add_quiet_option(p, what="no progress display")
    p.add_argument("--preset", nargs="+", default=None, metavar="NAME",
                   help=f"method parameter presets (method.PRESETS: {', '.join(PRESETS)}) for the figures whose "
                        "config has a 'presets' field (fig6, fig7, fig11, stages); 'paper' is always kept first "
                        "(--preset paper: the paper alone); default: each config's own; figures without the "
                        "field ignore it")
    return p


def preset_names(names) -> tuple[str, ...]:
    """The ``presets`` tuple of ``--preset NAMES``: ``"paper"`` first, then the others in order, without repeats.

    Raises
    ------
    ValueError
        A name not in :data:`method.PRESETS` (the message lists the allowed names).
    """
    from method import PRESETS

    return tuple(dict.fromkeys(["paper", *PRESETS.check_all(names or ["paper"], what="preset")]))


def figure_config(fig, mode: str, presets=None):
    """``fig``'s config of ``mode``, with its ``presets`` field set to ``presets`` when it has one (else unchanged)."""
    import dataclasses

    config = fig.config(mode)
    if presets is not None and any(f.name == "presets" for f in dataclasses.fields(config)):
        config = dataclasses.replace(config, presets=tuple(presets))
    return config


def make_figure(name: str, mode: str, out_dir: str, force: bool, presets=None) -> dict:
    """Compute (cached), plot and write the metrics of one figure; returns a summary dict.

    ``presets`` (tuple of str or None) replaces the config's ``presets`` field if it has one
    (see :func:`figure_config`). Top-level so that worker processes can run it.
    """
    from experiments.registry import FIGURES, compute_cached, library_versions, to_jsonable
    from defocus_cache import atomic_write_text

    t0 = time.perf_counter()
    fig = FIGURES[name]
    config = figure_config(fig, mode, presets)
    result = compute_cached(fig, config, force=force)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / fig.name
    paths = fig.plot_function()(result.as_data(), config, stem)
    info = {
        "figure": fig.name,
        "title": fig.title,
        "mode": mode,
        "metrics": result.metrics,
        "config_type": type(config).__qualname__,
        "config": to_jsonable(config),
        "code_version": fig.version,
        "sigma_convention": fig.sigma_convention,
        "versions": library_versions(),
        "cache": {"hit": result.cached, "entry": result.folder.name},
        "outputs": [p.name for p in paths],
    }
    metrics_path = out / f"{fig.name}.metrics.json"
    atomic_write_text(metrics_path, json.dumps(to_jsonable(info), indent=1, sort_keys=True) + "\n")
    return {"name": name, "cached": result.cached, "seconds": time.perf_counter() - t0,
            "files": [str(p) for p in [*paths, metrics_path]], "metrics": result.metrics}


def _make_figure_safe(name: str, mode: str, out_dir: str, force: bool, presets=None) -> dict:
    # One failing figure must not stop the others: report it and carry on.
    try:
        return make_figure(name, mode, out_dir, force, presets)
    except Exception as exc:  # noqa: BLE001 - reported to the user, exit status 1
        import traceback

        return {"name": name, "error": f"{type(exc).__name__}: {exc}",
                "traceback": "".join(traceback.format_exception(exc))}


def _headline(metrics: dict) -> str:
    keys = [k for k in metrics if k.startswith("max_rel_err") or k.endswith("_ratio_rel_err")]
    parts = [f"{k}={metrics[k]:.4g}" for k in keys if isinstance(metrics[k], (int, float))]
    return ", ".join(parts)


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    from experiments.registry import FIGURES

    if args.list:
        for name, fig in FIGURES.items():
            print(f"{name:<8} {fig.title}")
        return 0
    from repro._cli import user_input

    with user_input():  # the figure and preset names
        names = list(dict.fromkeys(args.names)) or list(FIGURES)
        unknown = [n for n in names if n not in FIGURES]
        if unknown:
            raise ValueError(f"unknown figure(s) {', '.join(map(repr, unknown))}; choose from {', '.join(FIGURES)}")
        mode = "quick" if args.quick else "full"
        presets = preset_names(args.preset) if args.preset is not None else None
    if args.variant:
        import os

        from scenes.backend import VARIANT_ENV, select_variant

        select_variant(args.variant)  # fails early (one line, exit 2) if it does not work here
        os.environ[VARIANT_ENV] = args.variant  # inherited by worker processes
    args.out.mkdir(parents=True, exist_ok=True)

    from tqdm import tqdm

    summaries = []
    bar = tqdm(total=len(names), desc=f"figures ({mode})", unit="fig", file=sys.stderr, disable=args.quiet)
    if args.jobs == 1 or len(names) == 1:
        for name in names:
            bar.set_postfix_str(name)
            summaries.append(_make_figure_safe(name, mode, str(args.out), args.force, presets))
            bar.update()
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        # spawn, not fork: Dr.Jit/LLVM state does not survive a fork safely.
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(args.jobs, len(names)), mp_context=ctx) as pool:
            futures = {pool.submit(_make_figure_safe, n, mode, str(args.out), args.force, presets): n
                       for n in names}
            for fut in as_completed(futures):
                summaries.append(fut.result())
                bar.set_postfix_str(futures[fut])
                bar.update()
    bar.close()
    failed = []
    for s in sorted(summaries, key=lambda s: names.index(s["name"])):
        if "error" in s:
            failed.append(s)
            print(s["traceback"], file=sys.stderr)
            continue
        how = "cached" if s["cached"] else "computed"
        print(f"{s['name']}: {how}, {s['seconds']:.1f} s; {_headline(s['metrics'])}")
        for f in s["files"]:
            print(f"  {f}")
    for s in failed:
        print(f"{PROG}: {s['name']} failed: {s['error']}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
