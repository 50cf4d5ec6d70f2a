"""The paper's claims, each a query on the long results table and a rule that turns its numbers into a verdict.

Every claim is a :class:`Claim` (:mod:`.catalogue`): what the paper says (with its section), which
figure's rows test it, the rule stated in words (``rule``, printed by the report) and a check
(:mod:`.rules`) that reads one cell's rows of the results table that ``python -m repro.figures``
writes (:mod:`experiments.results_table`, read with :mod:`experiments.results_query`) and returns a
:class:`Verdict`; nothing here is hard-coded.

Verdict labels: ``"reproduced"``, ``"partly reproduced"`` (a weaker form of the claim, stated in the
rule, holds), ``"not reproduced"``, ``"not evaluated"`` (the rows or a number are missing) and
``"error"`` (the check raised anything else: a failure of the harness, shown as such, never hidden as
missing data). The matrix of cells, one per method preset × scene set, the evaluation each cell rests
on and the claims that are fragile (a different verdict on the procedural test split than on a
hand-built set) are in :mod:`.matrix`. A claim whose evidence is a check of the harness against itself
(:attr:`Claim.self_check`: Eq. (5) and Eq. (6) against a renderer that implements them; analytic steps
on the test split) is labelled as such in every cell it concerns and is never a fragile verdict.
"""

from .catalogue import CLAIMS
from .core import ALL_PRESETS, ALL_SCENE_SETS, AXES, DEFAULT_PRESET, SELF_CHECK_NOTE, VERDICTS, Claim, Verdict
from .findings import mismatch_findings
from .matrix import (JUDGED, cell_rows, cell_sources, claim_matrix, claims_document, columns, evaluate_claims,
                     evaluation_id, evaluation_problems, fragile_claims, is_self_check, scope_note)

__all__ = ["ALL_PRESETS", "ALL_SCENE_SETS", "AXES", "CLAIMS", "DEFAULT_PRESET", "JUDGED", "SELF_CHECK_NOTE", "VERDICTS",
           "Claim", "Verdict", "cell_rows", "cell_sources", "claim_matrix", "claims_document", "columns",
           "evaluate_claims", "evaluation_id", "evaluation_problems", "fragile_claims", "is_self_check",
           "mismatch_findings", "scope_note"]
