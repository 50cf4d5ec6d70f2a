"""The metric columns of a scored render, in table order: the flattened keys
(:func:`experiments.evaluation.flatten_metrics`) of :func:`experiments.evaluation.evaluate_result`, then the
wall time.

A leaf module (it imports nothing), read by every table of scored renders: ``repro.evaluate``'s, the
sweep's, and the sweep's ``--metric`` choices.
"""

__all__ = ["METRIC_COLUMNS"]

#: Metric columns (px for the σ errors, fractions for the outlier shares, s for ``seconds_total``).
METRIC_COLUMNS = (
    "sparse_n", "sparse_mae", "sparse_median_ae", "sparse_rmse", "sparse_bias", "sparse_median_rel_error",
    "sparse_outlier_fraction",
    "refined_mae", "refined_median_ae", "refined_bias", "refined_outlier_fraction",
    "dense_all_mae", "dense_all_rmse", "dense_all_bias", "dense_all_outlier_fraction",
    "dense_edges_mae", "dense_edges_rmse", "dense_textured_n", "dense_textured_mae", "dense_textured_rmse",
    "rtf_nmse", "rtf_nmae",
    "in_focus_outliers_sparse_fraction", "in_focus_outliers_refined_fraction",
    "seconds_total",
)
