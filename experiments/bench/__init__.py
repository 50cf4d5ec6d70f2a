"""Benchmarks of the method: speed and memory (:mod:`.speed`), accuracy against analytic and rendered
truth (:mod:`.accuracy`, images in :mod:`.mosaics`, targets and verdicts in :mod:`.targets`, the
report's Markdown in :mod:`.markdown`). ``python -m repro.bench`` runs them and writes the files.
"""

from .accuracy import ACCURACY_CONFIG, accuracy_report, measure_accuracy
from .markdown import accuracy_markdown
from .mosaics import ANALYTIC_DATASETS, analytic_case, sigma_bins, step_mosaic
from .speed import BENCH_PRESETS, bench_image, speed_markdown, speed_report, speed_summary, time_pipeline
from .targets import judge_accuracy

__all__ = ["ACCURACY_CONFIG", "ANALYTIC_DATASETS", "BENCH_PRESETS", "accuracy_markdown", "accuracy_report",
           "analytic_case", "bench_image", "judge_accuracy", "measure_accuracy", "sigma_bins", "speed_markdown",
           "speed_report", "speed_summary", "step_mosaic", "time_pipeline"]
