"""CPU and wall time of the blur-at-edges stage alone, per preset (supplement to ``benchmarks/stage_cpu.py``).

``.venv/bin/python benchmarks/blur_stage_cpu.py [--preset robust] [--size 1024] [--repeat 3] [--tree PATH ...]``

For each ``--tree`` (a checkout, e.g. a ``git worktree`` of an older commit; default this one), in turn
and ``--rounds`` times, a fresh subprocess runs the edge stage once on repro.bench's image (skimage's
astronaut resized) and then the blur stage (``method.pipeline.blur_stage``, plus ``isolation_stage``
where the preset has it) ``--repeat`` times after one warm-up run, and prints the smallest CPU time
(time.process_time, all threads) with its wall time and the 1-min load before and after. Set
``NUMBA_NUM_THREADS=1`` for the algorithmic cost: on a busy machine a parallel kernel's idle
OpenMP thread spins, which counts as CPU.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_WORKER = r"""
import json, sys, time, warnings
sys.path.insert(0, {tree!r})
from experiments.bench.speed import bench_image
import method.pipeline as pl
from method import DefocusParams

params = DefocusParams.preset({preset!r})
image = bench_image({size})
warnings.simplefilter("ignore")
encoding = pl.resolve_encoding(image, "auto")
seen = pl.measure_input(image, params, encoding=encoding).seen
edge_map = pl.edges_stage(seen, params=params, encoding=encoding)

def blur():
    sparse, confidence, edges, _ = pl.blur_stage(seen, edge_map, params=params)
    if params.edge_isolation is not None:
        pl.isolation_stage(seen, edges, sparse, params=params, confidence=confidence)

blur()
best = None
for _ in range({repeat}):
    c, t = time.process_time(), time.perf_counter()
    blur()
    run = (time.process_time() - c, time.perf_counter() - t)
    best = run if best is None or run[0] < best[0] else best
print(json.dumps({{"cpu_s": best[0], "wall_s": best[1], "edge_pixels": int(edge_map.edges.sum())}}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="robust")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--tree", type=Path, nargs="+", default=[ROOT], help="checkouts whose method/ is timed")
    args = ap.parse_args(argv)
    for _ in range(args.rounds):
        for tree in args.tree:
            load0 = os.getloadavg()[0]
            code = _WORKER.format(tree=str(tree), preset=args.preset, size=args.size, repeat=args.repeat)
            proc = subprocess.run([sys.executable, "-c", code], cwd=tree, capture_output=True, text=True)
            if proc.returncode != 0:
                print(proc.stderr[-2000:], file=sys.stderr)
                return 1
            row = json.loads(proc.stdout.strip().splitlines()[-1])
            print(f"{tree}  {args.preset} {args.size}²: blur CPU {row['cpu_s']:.3f} s, wall {row['wall_s']:.3f} s, "
                  f"{row['edge_pixels']} edge px, load {load0:.1f} → {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
