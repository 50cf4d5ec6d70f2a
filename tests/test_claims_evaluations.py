"""One evaluation per cell of the claims table: every cell names the evaluation it came from, and two
cells of a claim share one only along an axis (preset, scene set) the claim is declared independent of.

Both sides: the quick table passes the check; hand-made claims documents that share an evaluation
where the claim depends on the preset or the scene set, that evaluate a preset-independent claim
twice, or that name another preset's evaluation, fail it. A figure without rows for a preset or a
scene set gives "not evaluated" for those cells, never a copy of other numbers. The procedural test
split is its own evaluation of the claims computed on it, and a verdict it does not confirm is fragile.
"""

from __future__ import annotations

import copy

import pytest

from experiments.claims import (ALL_PRESETS, ALL_SCENE_SETS, CLAIMS, claim_matrix, claims_document, evaluate_claims,
                                evaluation_problems, fragile_claims)
from tests.claims_tables import SET, fig4, fig7, fig7_scene, fig8, fig10, fig10_procedural

BY_ID = {c.id: c for c in CLAIMS}
#: Claims computed once for every preset and scene set (properties of the thin-lens optics).
INDEPENDENT = ("eq5", "eq6")
#: Claims on fig4's analytic images: one evaluation per preset, none per scene set (no scenes in them).
PRESET_ONLY = ("model_fit_accuracy", "neighbouring_edges")
#: Claims on the paper's Eq. (3) filter with and without its bias (fig5): one evaluation per scene set.
SCENE_SET_ONLY = ("bias_removes_outliers", "refinement_small_change")


def _doc(cells: dict) -> list[dict]:
    """A claims document from ``{(preset, scene set): {claim id: evaluation id}}`` (verdicts made up)."""
    return [{"preset": p, "scene_set": s,
             "verdicts": {cid: {"verdict": "reproduced", "evidence": "", "evaluation": ev} for cid, ev in row.items()}}
            for (p, s), row in cells.items()]


COLUMNS = (("paper", "paper_cameras"), ("robust", "paper_cameras"), ("paper", "tabletop_stress"),
           ("robust", "tabletop_stress"))


def _good_cells() -> dict:
    out = {}
    for p, s in COLUMNS:
        out[(p, s)] = {"eq5": f"fig10/{ALL_PRESETS}/{ALL_SCENE_SETS}/quick",
                       "model_fit_accuracy": f"fig4/{p}/{ALL_SCENE_SETS}/quick",
                       "refocus": f"fig8/{p}/{s}/quick"}
    return out


def test_the_declarations():
    assert {c.id for c in CLAIMS if not c.varies_with} == set(INDEPENDENT)
    assert {c.id for c in CLAIMS if c.varies_with == ("preset",)} == set(PRESET_ONLY)
    assert {c.id for c in CLAIMS if c.varies_with == ("scene_set",)} == set(SCENE_SET_ONLY)
    assert all(c.varies_with == ("preset", "scene_set") for c in CLAIMS
               if c.id not in INDEPENDENT + PRESET_ONLY + SCENE_SET_ONLY)
    with pytest.raises(ValueError, match="varies_with"):
        type(CLAIMS[0])("x", "s", "fig10", "t", "r", lambda m: None, varies_with=("camera",))


def test_a_document_with_one_evaluation_per_cell_passes():
    assert evaluation_problems(_doc(_good_cells())) == []


def test_a_shared_evaluation_of_a_claim_that_depends_on_the_preset_fails():
    cells = _good_cells()
    # the case: the paper preset's fig8 numbers copied into the robust column
    cells[("robust", "paper_cameras")]["refocus"] = "fig8/paper/paper_cameras/quick"
    problems = evaluation_problems(_doc(cells))
    assert any("refocus" in p and "not of preset 'robust'" in p for p in problems), problems
    # the same copy with an id that names the robust preset, but shared with the paper cell: still caught
    cells = _good_cells()
    for col in COLUMNS:
        cells[col]["refocus"] = "fig8/paper/paper_cameras/quick"
    problems = evaluation_problems(_doc(cells))
    assert any("share evaluation" in p and "preset" in p for p in problems), problems


def test_a_shared_evaluation_across_scene_sets_fails_unless_the_claim_has_no_scene_set():
    cells = _good_cells()
    # fig4's rendered comparison on tabletop scenes filled into the paper_cameras column
    for p in ("paper", "robust"):
        cells[(p, "paper_cameras")]["refocus"] = f"fig8/{p}/tabletop_stress/quick"
    problems = evaluation_problems(_doc(cells))
    assert any("share evaluation" in p and "scene_set" in p for p in problems), problems
    # an analytic claim shares its per-preset evaluation across scene sets: fine (declared)
    assert evaluation_problems(_doc(_good_cells())) == []
    # ... but not across presets
    cells = _good_cells()
    for col in COLUMNS:
        cells[col]["model_fit_accuracy"] = f"fig4/paper/{ALL_SCENE_SETS}/quick"
    assert any("model_fit_accuracy" in p for p in evaluation_problems(_doc(cells)))


def test_an_independent_claim_is_computed_once():
    cells = _good_cells()
    cells[("robust", "tabletop_stress")]["eq5"] = f"fig10/{ALL_PRESETS}/{ALL_SCENE_SETS}/full"
    problems = evaluation_problems(_doc(cells))
    assert any("eq5" in p and "2 evaluations" in p for p in problems), problems
    cells = _good_cells()
    cells[("robust", "tabletop_stress")]["eq5"] = f"fig10/robust/{ALL_SCENE_SETS}/quick"
    assert any("eq5" in p and "names a preset" in p for p in evaluation_problems(_doc(cells)))


def test_a_judged_cell_without_an_evaluation_fails():
    cells = _good_cells()
    cells[("paper", "paper_cameras")]["refocus"] = ""
    doc = _doc(cells)
    assert any("names no evaluation" in p for p in evaluation_problems(doc))
    doc[0]["verdicts"]["refocus"]["verdict"] = "not evaluated"  # nothing evaluated: nothing to name
    assert evaluation_problems(doc) == []
    doc[0]["verdicts"]["refocus"].update(verdict="reproduced", evaluation="fig7/paper/paper_cameras/quick")
    assert any("not 'fig8/" in p for p in evaluation_problems(doc))


# --- figures computed for one preset / without a scene set are not copied ------------------------------
def test_a_figure_of_the_paper_preset_only_gives_not_evaluated_for_another_preset():
    table = fig8() + fig10()
    robust = {c.id: v for c, v in evaluate_claims(table, preset="robust", scene_set=SET)}
    assert robust["refocus"].verdict == "not evaluated" and "no rows of preset 'robust'" in robust["refocus"].evidence
    assert robust["refocus"].evaluation == ""
    assert robust["eq5"].verdict == "reproduced"  # Eq. (5) does not depend on the preset
    paper = {c.id: v for c, v in evaluate_claims(table, scene_set=SET)}
    assert paper["refocus"].verdict == "reproduced" and paper["refocus"].evaluation == f"fig8/paper/{SET}/quick-0000abcd"
    assert paper["eq5"].evaluation == robust["eq5"].evaluation == f"fig10/{ALL_PRESETS}/{ALL_SCENE_SETS}/quick-0000abcd"


def test_a_figure_without_rows_of_a_scene_set_gives_not_evaluated_for_it():
    table = fig4()  # the pooled comparison of paper_cameras only; the analytic steps have no scene set
    got = {c.id: v for c, v in evaluate_claims(table, scene_set="tabletop_stress")}
    assert got["model_fit_real_images"].verdict == "not evaluated"
    assert "no rows of scene set 'tabletop_stress'" in got["model_fit_real_images"].evidence
    # the analytic claim has no scene set: evaluated, and named for all scene sets
    assert got["model_fit_accuracy"].verdict == "reproduced"
    assert got["model_fit_accuracy"].evaluation == f"fig4/paper/{ALL_SCENE_SETS}/quick-0000abcd"


def test_the_test_split_is_its_own_evaluation_and_only_of_the_claims_computed_there():
    table = (fig10(0.01) + fig10_procedural(0.02) + fig8() + fig8(scene_set="procedural_test")
             + fig7() + fig7(scene_set="procedural_test"))
    mat = claim_matrix(table)
    assert list(mat)[-1] == ("paper", "procedural_test")
    got = {c.id: v for c, v in mat[("paper", "procedural_test")]}
    assert got["eq5"].evaluation.startswith("fig10/all-presets/procedural_test/")
    assert got["doubled_map"].evaluation.startswith("fig7/paper/procedural_test/")
    # refocus is not computed on the test split: not evaluated, whatever rows there are
    assert got["refocus"].verdict == "not evaluated" and "not computed on the procedural test split" in got["refocus"].evidence
    doc = claims_document(mat)
    assert evaluation_problems(doc) == []
    # the test split's eq5 shares nothing with the hand-built cells
    bad = copy.deepcopy(doc)
    bad[-1]["verdicts"]["eq5"]["evaluation"] = bad[0]["verdicts"]["eq5"]["evaluation"]
    assert any("not of scene set 'procedural_test'" in p for p in evaluation_problems(bad))


# --- fragile verdicts: the test split disagrees with a hand-built set ----------------------------------------
def _fragility(test_mag, hand_mags):
    table = fig7(fig7_scene(base=(30.0, 0.80), mag=test_mag), scene_set="procedural_test")
    for s, mag in hand_mags.items():
        table += fig7(fig7_scene(base=(30.0, 0.80), mag=mag), scene_set=s)
    return fragile_claims(claim_matrix(table))


def test_a_verdict_that_differs_on_the_test_split_is_fragile_with_both_evidences():
    closer, same = (31.0, 0.85), (30.0, 0.80)
    fragile = _fragility(same, {"paper_cameras": closer, "tabletop_stress": closer})
    (f,) = [x for x in fragile if x["claim"] == "magnified_close"]
    assert f["preset"] == "paper" and f["test"]["verdict"] == "not reproduced"
    assert [h["verdict"] for h in f["hand_built"]] == ["reproduced", "reproduced"]
    assert "30.0 → 30.0 dB" in f["test"]["evidence"] and "30.0 → 31.0 dB" in f["hand_built"][0]["evidence"]
    assert f["test"]["evaluation"].startswith("fig7/paper/procedural_test/")
    # one hand-built set agreeing is not enough: any disagreement makes the verdict fragile
    assert [x["claim"] for x in _fragility(same, {"paper_cameras": same, "tabletop_stress": closer})
            if x["claim"] == "magnified_close"] == ["magnified_close"]


def test_a_verdict_the_test_split_confirms_is_not_fragile():
    closer = (31.0, 0.85)
    assert not [x for x in _fragility(closer, {"paper_cameras": closer, "tabletop_stress": closer})
                if x["claim"] == "magnified_close"]
    # without a judged verdict on the test split there is nothing to compare
    table = fig7(fig7_scene(mag=(31.0, 0.85)))
    assert fragile_claims(claim_matrix(table)) == []


# --- the report shows a repeated evaluation as "=" -----------------------------------------------------
def test_report_cells_say_all_presets_and_scene_sets_then_equals():
    from experiments.results_query import Results
    from repro._report_text import cell_texts
    from repro.report import build_markdown, claims_block

    table = (fig10() + fig8() + fig8((23.0, 0.66), (22.0, 0.70), preset="robust")
             + fig8((23.0, 0.66), (23.0, 0.70), scene_set="tabletop_stress")
             + fig8((23.0, 0.66), (25.0, 0.70), preset="robust", scene_set="tabletop_stress"))
    table = [r for i, r in enumerate(table) if r not in table[:i]]  # rows once
    matrix = claim_matrix(table)
    assert list(matrix) == list(COLUMNS)
    texts = cell_texts(matrix)
    eq5 = [texts[(c, "eq5")] for c in COLUMNS]
    # Eq. (5) is computed once for the hand-built sets (the test split would be its own evaluation)
    # (Eq. (5) against a thin-lens renderer is a harness self-check: its note says so)
    assert eq5[0] == ("reproduced", "all presets and hand-built scene sets; harness self-check, not held-out evidence",
                      True) and eq5[1:] == [(None, "=", True)] * 3
    refocus = [texts[(c, "refocus")][0] for c in COLUMNS]
    assert refocus == ["reproduced", "not reproduced", "partly reproduced", "reproduced"]
    assert all(texts[(c, "refocus")][1:] == ("", False) for c in COLUMNS)
    block = claims_block(matrix, report_link="r.md")
    row = [line for line in block.splitlines() if line.startswith("| " + BY_ID["eq5"].text.replace("|", "\\|"))][0]
    assert row.endswith("| `(+)` reproduced (all presets and hand-built scene sets; harness self-check, not held-out "
                        "evidence) | = | = | = |")
    md = build_markdown({"fig8": {"mode": "quick"}}, Results(table), matrix, figures_rel="figures", bench=None)
    assert "same evaluation as *paper preset, paper_cameras*" in md
    assert "Evaluation: `fig8/robust/tabletop_stress/quick-0000abcd`" in md
    doc = claims_document(matrix)
    assert evaluation_problems(doc) == []
    assert doc[1]["verdicts"]["eq5"]["same_as"] == {"preset": "paper", "scene_set": "paper_cameras"}
    assert doc[1]["verdicts"]["refocus"]["same_as"] is None


# --- harness self-checks are labelled, held-out evidence is not ---------------------------------------------
def _self_check_table():
    """Analytic steps on the hand-built side (reproduced) and on the test split (not reproduced), Eq. (5)."""
    hand = fig4()
    test = [dict(r, scene_set="procedural_test") for r in fig4(clean=0.5, curved=0.5, noisy=0.9)
            if str(r["variant"]).startswith("analytic")]
    return hand + test + fig10() + fig10_procedural(0.01) + fig8()


def test_the_self_check_declarations():
    from experiments.claims import is_self_check

    assert {c.id for c in CLAIMS if c.self_check} == {"eq5", "eq6", "model_fit_accuracy"}
    assert is_self_check(BY_ID["eq5"], "paper_cameras") and is_self_check(BY_ID["eq5"], "procedural_test")
    assert is_self_check(BY_ID["eq6"], None)
    # the analytic steps are the claim's own evidence on their own, a self-check only as "held-out" evidence
    assert not is_self_check(BY_ID["model_fit_accuracy"], "paper_cameras")
    assert is_self_check(BY_ID["model_fit_accuracy"], "procedural_test")
    assert not any(is_self_check(BY_ID[c], s) for c in ("refocus", "dense_map", "magnified_close")
                   for s in ("paper_cameras", "procedural_test"))
    make = type(CLAIMS[0])
    with pytest.raises(ValueError, match="self_check_scope"):
        make("x", "s", "fig10", "t", "r", lambda m: None, self_check="why", self_check_scope="sometimes")
    with pytest.raises(ValueError, match="not computed on the test split"):
        make("x", "s", "fig10", "t", "r", lambda m: None, self_check="why", self_check_scope="test_split")


def test_a_self_check_is_labelled_in_every_output_and_a_real_claim_is_not():
    from experiments.claims import SELF_CHECK_NOTE
    from experiments.results_query import Results
    from repro._report_html import build_html
    from repro.report import build_markdown, claims_block

    table = _self_check_table()
    matrix = claim_matrix(table)
    assert list(matrix) == [("paper", "paper_cameras"), ("paper", "procedural_test")]
    doc = {e["scene_set"]: e["verdicts"] for e in claims_document(matrix)}
    assert doc["procedural_test"]["model_fit_accuracy"]["self_check"] == BY_ID["model_fit_accuracy"].self_check
    assert doc["paper_cameras"]["model_fit_accuracy"]["self_check"] is None
    assert doc["paper_cameras"]["eq5"]["self_check"] and doc["procedural_test"]["eq5"]["self_check"]
    assert doc["paper_cameras"]["refocus"]["self_check"] is None
    assert doc["paper_cameras"]["eq6"]["self_check"] is None  # no rows of fig2: not evaluated, no evidence to label
    block = claims_block(matrix, report_link="r.md")
    row = {c: [line for line in block.splitlines() if line.startswith("| " + BY_ID[c].text.replace("|", "\\|"))][0]
           for c in ("model_fit_accuracy", "refocus", "eq5")}
    # the test split's cell of the analytic steps: bracketed mark and the note; the hand-built one: neither
    assert row["model_fit_accuracy"].endswith(f"| `+` reproduced | `(-)` not reproduced ({SELF_CHECK_NOTE}) |")
    assert row["refocus"].endswith("| `+` reproduced | `?` not evaluated |") and "self-check" not in row["refocus"]
    assert f"`(+)` reproduced ({SELF_CHECK_NOTE})" in row["eq5"]
    assert "`(+)`, `(-)`: a harness self-check" in block
    md = build_markdown({"fig4": {"mode": "quick"}}, Results(table), matrix, figures_rel="figures", bench=None)
    assert md.count("*Harness self-check, not held-out evidence: ") == 3  # eq5 twice, model fit on the test split
    assert "(of these, harness self-checks: 2)" in md and "(of these, harness self-checks: 1)" in md
    page = build_html({"fig4": {"mode": "quick"}}, Results(table), matrix, figures_rel="figures", bench=None)
    assert page.count("self-check'>") == 3 and "not-reproduced self-check" in page


def test_a_self_check_is_never_fragile_and_the_same_disagreement_on_a_real_claim_is(monkeypatch):
    import dataclasses

    from experiments.claims import matrix as matrix_module

    table = _self_check_table()
    assert [f["claim"] for f in fragile_claims(claim_matrix(table))] == []  # the test split differs, but only
    # as a self-check; declared as held-out evidence, the same disagreement is fragile
    real = tuple(dataclasses.replace(c, self_check="") if c.id == "model_fit_accuracy" else c for c in CLAIMS)
    monkeypatch.setattr(matrix_module, "CLAIMS", real)
    assert [f["claim"] for f in fragile_claims(claim_matrix(table))] == ["model_fit_accuracy"]


# --- the quick table ---------------------------------------------------------------------------------------
@pytest.mark.render
def test_every_cell_of_the_quick_claims_table_names_its_own_evaluation(quick_table):
    matrix = claim_matrix(quick_table)
    columns = list(matrix)
    assert columns == [*COLUMNS, ("paper", "procedural_test"), ("robust", "procedural_test")]
    doc = claims_document(matrix)
    assert evaluation_problems(doc) == []
    hand = [e for e in doc if e["scene_set"] != "procedural_test"]
    ids = {c.id: {entry["verdicts"][c.id]["evaluation"] for entry in hand} for c in CLAIMS}
    for c in CLAIMS:
        assert all(entry["verdicts"][c.id]["verdict"] != "not evaluated" for entry in hand), c.id
        expected = 1 if c.id in INDEPENDENT else 2 if c.id in PRESET_ONLY + SCENE_SET_ONLY else len(COLUMNS)
        assert len(ids[c.id]) == expected, (c.id, ids[c.id])
    assert {i.rsplit("/", 1)[0] for i in ids["refocus"]} == {f"fig8/{p}/{s}" for p, s in COLUMNS}
    test = [e for e in doc if e["scene_set"] == "procedural_test"]
    for c in CLAIMS:
        judged = {e["verdicts"][c.id]["verdict"] != "not evaluated" for e in test}
        assert judged == {c.test_split}, c.id
    # the robust columns really are the robust preset's numbers: its own fit and its own map
    fig4 = quick_table.where(figure="fig4", variant="analytic:straight")
    assert set(fig4.where(preset="paper").distinct("estimator")) >= {"model_fit"}
    assert "model_fit_checked" in fig4.where(preset="robust").distinct("estimator")
    fig8 = quick_table.where(figure="fig8")
    for s in ("tabletop_stress", "paper_cameras"):
        est = [fig8.value("images_vs_d2/refocused_estimated/psnr_db", scene_set=s, preset=p) for p in ("paper", "robust")]
        assert est[0] != est[1]  # other maps; the unchanged input is one preset-independent row
        assert len(fig8.where(scene_set=s, metric="images_vs_d2/unchanged_d1/psnr_db")) == 1
    # a tampered copy (the case) fails the check
    bad = copy.deepcopy(doc)
    bad[1]["verdicts"]["refocus"]["evaluation"] = bad[0]["verdicts"]["refocus"]["evaluation"]
    assert evaluation_problems(bad)
