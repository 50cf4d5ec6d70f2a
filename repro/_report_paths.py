"""Where the tools write by default: the committed report and the git-ignored folder of exploratory runs.

The committed report — ``report/README.md``, ``index.html``, ``claims.json``, ``report/figures/`` (the
figures and the results table of a full ``python -m repro.figures`` run) and ``report/evaluations/`` (the
procedural evaluations the report shows) — changes only on purpose: full-mode figures, ``python -m
repro.report`` from them, and a procedural evaluation sent there explicitly (``python -m repro.evaluate
--procedural N --split dev|test --out report/evaluations``). Exploratory runs write under :data:`QUICK`
(``report/quick/``, git-ignored): ``repro.figures --quick``, ``repro.evaluate`` (every mode), ``repro.compare``
(its judgements on fresh scenes are logged in the committed ``report/judgements.*``) and the report
of quick figures (``repro.report --figures report/quick/figures``). Paths are relative to the working folder.
"""

from __future__ import annotations

from pathlib import Path

#: The committed report.
REPORT = Path("report")
#: Full-mode figures and their results table (``repro.figures`` default ``--out``).
FIGURES = REPORT / "figures"
#: Procedural evaluations the committed report shows (``repro.report`` default ``--evaluations``).
EVALUATIONS = REPORT / "evaluations"
#: Git-ignored root of exploratory runs.
QUICK = REPORT / "quick"
#: ``repro.figures --quick`` default ``--out``.
QUICK_FIGURES = QUICK / "figures"
#: ``repro.evaluate`` default ``--out`` (named scenes, ``--photos``, ``--maps``).
QUICK_EVALUATE = QUICK / "evaluate"
#: ``repro.evaluate --procedural`` default ``--out`` (one folder per evaluation in it).
QUICK_EVALUATIONS = QUICK / "evaluations"
#: ``repro.compare`` default ``--out``.
QUICK_COMPARE = QUICK / "compare"
