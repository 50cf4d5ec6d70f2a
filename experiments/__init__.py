"""One module per paper figure: its cases (scene set × scene × preset × aperture, or its own unit) and
``compute_case(config, case, inputs) -> arrays + metrics`` (:mod:`experiments.cases`, each case cached),
and a thin plot function in :mod:`experiments.plotting` (the only place matplotlib is imported).

The registry of figures is :data:`experiments.registry.FIGURES`; ``python -m repro.figures`` runs their
cases (:mod:`repro._runner`) and writes the long results table (:mod:`experiments.results_table`) the
claims (:mod:`experiments.claims`) and the report read.
"""
