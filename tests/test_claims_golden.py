"""Every claim's verdict on the quick results table, for every preset and scene set, is what it was.

The verdicts of ``experiments.claims.claim_matrix`` on the quick table CI computes (the session's
``quick_table``: every claim figure's quick cases, through the case runner's cache) are stored in
``tests/golden/claims_quick.json`` (``"<preset>/<scene set>.<claim id>": verdict``) and compared
exactly: a change of the science (a rule, the method, a scene) shows up as a failing test and is
taken in deliberately by regenerating the goldens (``python -m tests.golden --regenerate``).
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.render


def test_claim_verdicts_match_the_golden(goldens, quick_table):
    from experiments.claims import CLAIMS, VERDICTS, claim_matrix
    from experiments.scene_sets import PROCEDURAL_TEST
    from tests.golden import claims_values

    values = claims_values(quick_table)
    for combo, verdicts in values.items():
        assert list(verdicts) == [c.id for c in CLAIMS], combo
        assert all(v in VERDICTS for v in verdicts.values()), (combo, verdicts)
        # on the quick table every claim has its numbers (on the test split: every claim computed there)
        expected = {c.id for c in CLAIMS if c.test_split or not combo.endswith(PROCEDURAL_TEST)}
        assert not {k: v for k, v in verdicts.items() if k in expected and v in ("error", "not evaluated")}, \
            (combo, verdicts)
    assert {k.split("/")[1] for k in values} == {"paper_cameras", "tabletop_stress", PROCEDURAL_TEST}
    assert len(claim_matrix(quick_table)) == len(values)
    goldens.check("claims_quick", values)
