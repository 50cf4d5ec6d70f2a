"""Benchmark of the case runner (``python -m repro.bench --figures``): ``repro.figures`` with 1 and 2 workers.

Each run is ``python -m repro.figures [--quick] --force --workers N --out <tmp>/wN -q`` in a fresh
process (every case recomputed; the renders come from the render cache, made first by an untimed run),
timed with its wall clock and the machine's load average before and after. The tables the runs write
must be equal row for row (the runner's contract: serial and parallel runs give the same numbers);
``figures_speed.json`` / ``figures_speed.md`` record the times, the speedup of every worker count over
one worker and whether the tables agree.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["run_figures_bench"]

#: The speedup of two workers over one this benchmark is held to (2-core machine).
TARGET_SPEEDUP = 1.3


def _run(args: list[str], out: Path, *, workers: int) -> dict:
    cmd = [sys.executable, "-m", "repro.figures", *args, "--force", "--workers", str(workers), "--out", str(out), "-q"]
    load = os.getloadavg()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
    return {"workers": workers, "command": " ".join(cmd[1:]), "wall_s": wall, "load_before": list(load),
            "load_after": list(os.getloadavg())}


def _same_tables(a: Path, b: Path) -> tuple[bool, int, list[str]]:
    """Whether two runs' tables hold the same rows and values, apart from wall-clock times (unit ``s``:
    ``compute_seconds`` and the like differ between any two runs); also the number of rows compared and
    the metrics that differ (at most 10)."""
    from experiments.results_query import read_table

    ra, rb = ([r for r in read_table(p).rows if r.get("unit") != "s"] for p in (a, b))
    key = lambda r: tuple(str(r[k]) for k in r if k != "value")  # noqa: E731
    va, vb = {key(r): r["value"] for r in ra}, {key(r): r["value"] for r in rb}
    metric = list(ra[0]).index("metric") if ra else 0
    differ = sorted({k[metric] for k in set(va) | set(vb) if va.get(k, "missing") != vb.get(k, "missing")})
    return not differ and len(ra) == len(rb), len(ra), differ[:10]


def run_figures_bench(out, *, names=(), quick: bool = True, worker_counts=(1, 2), progress: bool = True) -> dict:
    """Time ``repro.figures`` (every case recomputed) with each worker count; write the record.

    Parameters
    ----------
    out : path
        Folder for ``figures_speed.json`` and ``figures_speed.md`` (e.g. ``report/bench``).
    names : sequence of str, keyword-only
        Figures (default: all).
    quick : bool, keyword-only
        ``--quick`` (the small scene presets).
    worker_counts : sequence of int, keyword-only
        The first is the reference of the speedups.
    progress : bool, keyword-only
        One line per run on stderr.

    Returns
    -------
    dict
        Written to ``figures_speed.json``.
    """
    import platform

    from defocus_cache import atomic_write_text

    out = Path(out)
    args = [*names, *(["--quick"] if quick else [])]
    with tempfile.TemporaryDirectory() as tmp:
        warm = subprocess.run([sys.executable, "-m", "repro.figures", *args, "--workers", "1", "--out",
                               str(Path(tmp) / "warm"), "-q"], capture_output=True, text=True)
        if warm.returncode != 0:  # renders made (cached) before anything is timed
            raise RuntimeError(f"the warm-up run failed: {warm.stderr[-2000:]}")
        runs = []
        for n in worker_counts:
            runs.append(_run(args, Path(tmp) / f"w{n}", workers=n))
            if progress:
                print(f"{n} worker(s): {runs[-1]['wall_s']:.1f} s", file=sys.stderr)
        same, n_rows, differ = zip(*(_same_tables(Path(tmp) / f"w{worker_counts[0]}", Path(tmp) / f"w{n}")
                                     for n in worker_counts[1:]))
    ref = runs[0]["wall_s"]
    for r in runs:
        r["speedup"] = ref / r["wall_s"]
    report = {"date": time.strftime("%Y-%m-%d %H:%M:%S"), "figures": list(names) or "all", "quick": quick,
              "runs": runs, "tables_equal": all(same), "table_rows": n_rows[0] if n_rows else None,
              "metrics_differing": sorted({m for d in differ for m in d}),
              "target_speedup_2_workers": TARGET_SPEEDUP, "cpus": os.cpu_count(), "machine": platform.processor() or
              platform.machine(), "python": platform.python_version()}
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "figures_speed.json", json.dumps(report, indent=1) + "\n")
    lines = [f"# repro.figures with 1 and {worker_counts[-1]} workers", "",
             f"{report['date']}, {report['cpus']} CPUs; `repro.figures {' '.join(args)} --force --workers N` (every "
             "case recomputed, renders cached):", "",
             "| workers | wall (s) | speedup | load before → after |", "|---|---|---|---|"]
    lines += [f"| {r['workers']} | {r['wall_s']:.1f} | {r['speedup']:.2f}× | "
              f"{r['load_before'][0]:.2f} → {r['load_after'][0]:.2f} |" for r in runs]
    lines += ["", f"Tables equal row for row ({report['table_rows']} rows; wall-clock times, unit s, left out): "
              f"{'yes' if report['tables_equal'] else 'NO: ' + ', '.join(report['metrics_differing'])}. "
              f"Target: ≥ {TARGET_SPEEDUP:g}× with 2 workers on a 2-core machine."]
    atomic_write_text(out / "figures_speed.md", "\n".join(lines) + "\n")
    return report
