"""Benchmarks of the method: speed and memory (:mod:`.speed`), accuracy against analytic and rendered
truth (:mod:`.accuracy`, images in :mod:`.mosaics`, targets and verdicts in :mod:`.targets`, the
report's Markdown in :mod:`.markdown`), lens blur in linear light (:mod:`.lens`) and the robust
preset's ablation on three sets (:mod:`.ablation`). ``python -m repro.bench`` runs them and writes the files.
"""

from .ablation import ABLATION_ROWS, ablation_markdown, ablation_report
from .accuracy import ACCURACY_CONFIG, accuracy_report, measure_accuracy
from .lens import LENS_CONFIG, LENS_FULL_CONFIG, judge_lens, lens_config, lens_markdown, measure_lens
from .markdown import accuracy_markdown
from .mosaics import ANALYTIC_DATASETS, analytic_case, sigma_bins, step_mosaic
from .speed import BENCH_PRESETS, bench_image, speed_markdown, speed_report, speed_summary, time_pipeline
from .targets import judge_accuracy

__all__ = ["ABLATION_ROWS", "ACCURACY_CONFIG", "ANALYTIC_DATASETS", "BENCH_PRESETS", "LENS_CONFIG",
           "LENS_FULL_CONFIG", "ablation_markdown", "ablation_report", "accuracy_markdown", "accuracy_report",
           "analytic_case", "bench_image", "judge_accuracy", "judge_lens", "lens_config", "lens_markdown",
           "measure_accuracy", "measure_lens", "sigma_bins", "speed_markdown", "speed_report", "speed_summary",
           "step_mosaic", "time_pipeline"]
