"""One module per paper figure: ``compute(config) -> dict of arrays + metrics`` (cached) and a thin
plot function in :mod:`experiments.plotting` (the only place matplotlib is imported).

The registry of figures is :data:`experiments.registry.FIGURES`; ``python -m repro.figures`` runs it.
"""
