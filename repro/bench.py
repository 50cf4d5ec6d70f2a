"""Benchmark suite: per-stage and whole-pipeline wall time and peak memory of the method.

``python -m repro.bench [--sizes 256 512 1024] [--repeat 3] [--out report/bench]``

Each size runs in a fresh subprocess (so its peak resident memory, ``ru_maxrss``, is its own) on a
textured photo-like image (``skimage.data.astronaut`` resized, shipped with scikit-image). Writes
``bench.json`` and ``bench.md`` and prints the table. Targets (this 2-core machine kind):
whole pipeline at 1 MP ≤ 5 s and ≤ 3 GiB; 512² → 1024² cost growth ≤ 4.5×.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

TARGET_SECONDS_1MP = 5.0
TARGET_PEAK_GIB_1MP = 3.0
TARGET_GROWTH_512_TO_1024 = 4.5


def _test_image(size: int):
    import numpy as np
    from skimage import data, transform

    img = data.astronaut().astype(np.float64) / 255.0
    return np.clip(transform.resize(img, (size, size), order=1, anti_aliasing=True), 0.0, 1.0)


def _worker(size: int, repeat: int) -> dict:
    """Run the pipeline ``repeat`` times at ``size``²; return the best timings and peak RSS."""
    import warnings

    from method import DefocusParams, estimate_defocus_map, magnify_defocus

    image = _test_image(size)
    params = DefocusParams()
    best = None
    for _ in range(repeat):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = estimate_defocus_map(image, params)
            t = time.perf_counter()
            magnify_defocus(image, result.defocus_map, factor=2.0)
            t_mag = time.perf_counter() - t
        timings = dict(result.timings)
        timings["magnification"] = t_mag
        if best is None or timings["total"] < best["total"]:
            best = timings
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "size": size,
        "pixels": size * size,
        "edge_pixels": int(result.edges.sum()),
        "timings_s": best,
        "peak_rss_gib": peak_kib / 2**20,
    }


def _run_size(size: int, repeat: int) -> dict:
    cmd = [sys.executable, "-m", "repro.bench", "--worker", str(size), "--repeat", str(repeat)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmark at {size}² failed:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _table(rows: list[dict]) -> str:
    stages = list(rows[0]["timings_s"].keys())
    head = "| size | edge px | " + " | ".join(f"{s} (s)" for s in stages) + " | peak RSS (GiB) |"
    sep = "|" + "---|" * (len(stages) + 3)
    lines = [head, sep]
    for r in rows:
        cells = " | ".join(f"{r['timings_s'][s]:.3f}" for s in stages)
        lines.append(f"| {r['size']}² | {r['edge_pixels']} | {cells} | {r['peak_rss_gib']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m repro.bench", description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024], help="image sides, px")
    parser.add_argument("--repeat", type=int, default=3, help="runs per size; the fastest counts")
    parser.add_argument("--out", type=Path, default=Path("report") / "bench", help="output folder")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker is not None:
        print(json.dumps(_worker(args.worker, args.repeat)))
        return 0
    if any(s < 16 for s in args.sizes) or args.repeat < 1:
        print("error: --sizes must be >= 16 px and --repeat >= 1", file=sys.stderr)
        return 2
    from tqdm import tqdm

    from scenes.storage import atomic_write_text

    rows = [_run_size(s, args.repeat) for s in tqdm(args.sizes, desc="bench sizes", unit="size")]
    by_size = {r["size"]: r for r in rows}
    summary = {}
    if 1024 in by_size:
        r = by_size[1024]
        summary["total_1mp_s"] = r["timings_s"]["total"]
        summary["peak_1mp_gib"] = r["peak_rss_gib"]
        summary["meets_time_target"] = r["timings_s"]["total"] <= TARGET_SECONDS_1MP
        summary["meets_memory_target"] = r["peak_rss_gib"] <= TARGET_PEAK_GIB_1MP
    if 512 in by_size and 1024 in by_size:
        g = by_size[1024]["timings_s"]["total"] / by_size[512]["timings_s"]["total"]
        summary["growth_512_to_1024"] = g
        summary["meets_growth_target"] = g <= TARGET_GROWTH_512_TO_1024
    report = {
        "rows": rows,
        "summary": summary,
        "targets": {"total_1mp_s": TARGET_SECONDS_1MP, "peak_1mp_gib": TARGET_PEAK_GIB_1MP,
                    "growth_512_to_1024": TARGET_GROWTH_512_TO_1024},
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    table = _table(rows)
    md = (f"# Benchmark ({report['date']}, {os.cpu_count()} CPUs)\n\n"
          "Whole-pipeline `total` excludes magnification (timed separately); fastest of "
          f"{args.repeat} runs; peak RSS of the whole worker process.\n\n{table}\n\n"
          + "\n".join(f"- {k}: {v:.3f}" if isinstance(v, float) else f"- {k}: {v}" for k, v in summary.items())
          + "\n")
    atomic_write_text(args.out / "bench.json", json.dumps(report, indent=1))
    atomic_write_text(args.out / "bench.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
