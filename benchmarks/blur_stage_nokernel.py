"""Robust's blur stage at 1 MP with and without the Eq. (2c) fit kernel's time (the NumPy around it).

``NUMBA_NUM_THREADS=1 PYTHONPATH=TREE .venv/bin/python benchmarks/blur_stage_nokernel.py TREE [REPEAT]``

Runs ``method.pipeline.blur_stage`` of checkout TREE on repro.bench's image (skimage's astronaut
resized to 1024²) REPEAT times (default 8) after a warm-up and prints, as JSON, the smallest CPU
(time.process_time) and wall time of the stage and of the stage less the time spent in
``method.blur.model_fit.run_fit_kernel``. Alternate two trees, a few rounds, and give the load.
"""

import json
import sys
import time
import warnings

tree = sys.argv[1]
sys.path.insert(0, tree)

from experiments.bench.speed import bench_image  # noqa: E402
import method.blur.model_fit as mf  # noqa: E402
import method.pipeline as pl  # noqa: E402
from method import DefocusParams  # noqa: E402

params = DefocusParams.preset("robust")
image = bench_image(1024)
warnings.simplefilter("ignore")
encoding = pl.resolve_encoding(image, "auto")
seen = pl.measure_input(image, params, encoding=encoding).seen
em = pl.edges_stage(seen, params=params, encoding=encoding)
spent = [0.0, 0.0]
kernel = mf.run_fit_kernel


def timed_kernel(*args):
    c, t = time.process_time(), time.perf_counter()
    out = kernel(*args)
    spent[0] += time.process_time() - c
    spent[1] += time.perf_counter() - t
    return out


mf.run_fit_kernel = timed_kernel
runs = []
for i in range(int(sys.argv[2]) + 1 if len(sys.argv) > 2 else 9):
    spent[:] = [0.0, 0.0]
    c, t = time.process_time(), time.perf_counter()
    pl.blur_stage(seen, em, params=params)
    c, t = time.process_time() - c, time.perf_counter() - t
    if i:
        runs.append((c, t, c - spent[0], t - spent[1]))
print(json.dumps({name: round(min(r[j] for r in runs), 4)
                  for j, name in enumerate(("cpu_s", "wall_s", "cpu_without_kernel_s", "wall_without_kernel_s"))}))
