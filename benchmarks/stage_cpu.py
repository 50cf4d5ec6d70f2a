"""Per-stage wall *and* CPU time of ``estimate_defocus_map`` (supplement to ``python -m repro.bench``).

``.venv/bin/python benchmarks/stage_cpu.py [--sizes 512 1024] [--repeat 3] [--tree PATH] [--label L]``

Each size runs in a fresh subprocess (numba cache warm) on the same test image as repro.bench
(skimage's astronaut, resized). For every stage it records the wall time (time.perf_counter) and
the process CPU time (time.process_time: all threads, i.e. the algorithmic cost, less sensitive to
other users' load than wall time) of the run with the smallest total wall time, the peak RSS and the
1-minute load average before and after. ``--tree`` times another checkout (e.g. a ``git worktree``
of an older commit) for before/after comparisons. Results go to stage_cpu.json (appended by label).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1] / "report" / "bench"  # where results go
ROOT = HERE.parents[1]

_WORKER = r"""
import json, resource, sys, time, warnings
sys.path.insert(0, {tree!r})
import numpy as np
from skimage import data, transform
import method.pipeline as pl
from method import estimate_defocus_map

size, repeat = {size}, {repeat}
img = data.astronaut().astype(np.float64) / 255.0
img = np.clip(transform.resize(img, (size, size), order=1, anti_aliasing=True), 0.0, 1.0)
cpu = {{}}
if not hasattr(pl.DefocusResult, "__dataclass_fields__") or "cpu_timings" not in pl.DefocusResult.__dataclass_fields__:
    # older checkouts: measure CPU per stage by wrapping the stage functions
    def wrap(name, fn):
        def f(*a, **k):
            c = time.process_time(); r = fn(*a, **k); cpu[name] = time.process_time() - c; return r
        return f
    pl.detect_edges = wrap("edges", pl.detect_edges)
    pl.estimate_blur = wrap("blur_at_edges", pl.estimate_blur)
    pl.biased_cross_bilateral = wrap("cross_bilateral", pl.biased_cross_bilateral)
    pl.propagate_defocus = wrap("propagation", pl.propagate_defocus)
best = None
for _ in range(repeat):
    c0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = estimate_defocus_map(img)
    c = dict(getattr(r, "cpu_timings", None) or cpu)
    c["total"] = time.process_time() - c0
    if best is None or r.timings["total"] < best[0]["total"]:
        best = (dict(r.timings), c)
print(json.dumps({{"size": size, "wall_s": best[0], "cpu_s": best[1],
                  "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--tree", type=Path, default=ROOT, help="checkout whose method/ is timed")
    ap.add_argument("--label", default="current")
    args = ap.parse_args(argv)
    rows = []
    for size in args.sizes:
        load0 = os.getloadavg()[0]
        code = _WORKER.format(tree=str(args.tree), size=size, repeat=args.repeat)
        proc = subprocess.run([sys.executable, "-c", code], cwd=args.tree, capture_output=True, text=True)
        if proc.returncode != 0:
            print(proc.stderr[-2000:], file=sys.stderr)
            return 1
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        row["load_1min_before_after"] = [round(load0, 2), round(os.getloadavg()[0], 2)]
        rows.append(row)
        stages = list(row["wall_s"])
        print(f"{args.label} {size}²: " + ", ".join(
            f"{k} {row['wall_s'][k]:.3f}/{row['cpu_s'].get(k, float('nan')):.3f}" for k in stages)
            + f" (wall/CPU s), peak {row['peak_rss_gib']:.2f} GiB, load {row['load_1min_before_after']}")
    out = HERE / "stage_cpu.json"
    data = json.loads(out.read_text()) if out.exists() else {}
    data[args.label] = {"date": time.strftime("%Y-%m-%d %H:%M:%S"), "cpus": os.cpu_count(), "rows": rows}
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
