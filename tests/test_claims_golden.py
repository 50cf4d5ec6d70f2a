"""Every claim's verdict on the quick figures, for every preset and scene set, is what it was.

The verdicts of ``experiments.claims.claim_matrix`` on the quick data CI computes are stored in
``tests/golden/claims_quick.json`` (``"<preset>/<scene set>.<claim id>": verdict``) and compared
exactly: a change of the science (a rule, the method, a scene) shows up as a failing test and is
taken in deliberately by regenerating the goldens (``python -m tests.golden --regenerate``).
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.render


def test_claim_verdicts_match_the_golden(goldens):
    from experiments.claims import CLAIMS, VERDICTS
    from tests.golden import CLAIM_FIGURES, claims_values, quick_metrics

    metrics = {fig: {"metrics": quick_metrics(fig)} for fig in CLAIM_FIGURES}
    values = claims_values(metrics)
    for combo, verdicts in values.items():
        assert list(verdicts) == [c.id for c in CLAIMS], combo
        assert all(v in VERDICTS for v in verdicts.values()), (combo, verdicts)
        # on the quick data every claim has its numbers: none may be missing or raise
        assert not {k: v for k, v in verdicts.items() if v in ("error", "not evaluated")}, (combo, verdicts)
    goldens.check("claims_quick", values)
