"""One evaluation per cell of the claims table: every cell names the evaluation it came from, and two
cells of a claim share one only along an axis (preset, scene set) the claim is declared independent of.

Both sides: the quick data passes the check; hand-made claims documents that share an evaluation
where the claim depends on the preset or the scene set, that evaluate a preset-independent claim
twice, or that name another preset's evaluation, fail it. A figure computed for one preset or
without a scene set gives "not evaluated" for the other cells, never a copy of its numbers.
"""

from __future__ import annotations

import copy

import pytest

from experiments.claims import (ALL_PRESETS, ALL_SCENE_SETS, CLAIMS, claim_matrix, claims_document, evaluate_claims,
                                evaluation_problems)

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
def _fig8(psnr=24.0):
    return {"images_vs_d2": {"unchanged_d1": {"psnr_db": 23.0, "ssim": 0.66},
                             "refocused_estimated": {"psnr_db": psnr, "ssim": 0.70}}}


def _fig4_analytic():
    mf = {"model_fit": {"median_ae": 0.05}}
    return {"straight": {"clean": mf, "noisy": mf}, "curved": {"clean": mf}}


def test_a_figure_of_the_paper_preset_only_gives_not_evaluated_for_another_preset():
    m = {"fig8": {"metrics": _fig8()}, "fig10": {"metrics": {"max_rel_err": 0.01, "n_points": 3}}}
    robust = {c.id: v for c, v in evaluate_claims(m, preset="robust")}
    assert robust["refocus"].verdict == "not evaluated" and "paper preset only" in robust["refocus"].evidence
    assert robust["refocus"].evaluation == ""
    assert robust["eq5"].verdict == "reproduced"  # Eq. (5) does not depend on the preset
    paper = {c.id: v for c, v in evaluate_claims(m)}
    assert paper["refocus"].verdict == "reproduced" and paper["refocus"].evaluation.startswith("fig8/paper/")
    assert paper["eq5"].evaluation == robust["eq5"].evaluation == f"fig10/{ALL_PRESETS}/{ALL_SCENE_SETS}/unrecorded-config"


def test_a_figure_without_scene_sets_gives_not_evaluated_for_a_named_set():
    rendered = {"pooled": {"srgb": {"line_spread": {"model_fit": {"mae": 1.0, "median_ae": 0.5},
                                                    "zero_crossing": {"mae": 2.0, "median_ae": 0.8}}}}}
    m = {"fig4": {"mode": "quick", "config": {"a": 1}, "metrics": {"analytic": _fig4_analytic(), "rendered": rendered}}}
    got = {c.id: v for c, v in evaluate_claims(m, scene_set="paper_cameras")}
    assert got["model_fit_real_images"].verdict == "not evaluated"
    assert "without a scene set" in got["model_fit_real_images"].evidence
    # the analytic claim has no scene set: evaluated, and named for all scene sets
    assert got["model_fit_accuracy"].verdict == "reproduced"
    assert got["model_fit_accuracy"].evaluation.startswith(f"fig4/paper/{ALL_SCENE_SETS}/quick-")


def test_the_preset_fit_is_read_under_its_own_name():
    """The robust preset's model fit is model_fit_checked: its numbers, not the paper fit's, are judged."""
    robust = {"fit_estimator": "model_fit_checked",
              "analytic": {"straight": {"clean": {"model_fit_checked": {"median_ae": 0.05}},
                                        "noisy": {"model_fit_checked": {"median_ae": 0.5}}},
                           "curved": {"clean": {"model_fit_checked": {"median_ae": 0.05}}}}}
    m = {"fig4": {"metrics": {"analytic": _fig4_analytic(), "presets": {"robust": robust}}}}
    got = {c.id: v for c, v in evaluate_claims(m, preset="robust")}
    assert got["model_fit_accuracy"].verdict == "partly reproduced"  # noisy 0.5 px > bound
    assert "model_fit_checked" in got["model_fit_accuracy"].evidence
    assert {c.id: v for c, v in evaluate_claims(m)}["model_fit_accuracy"].verdict == "reproduced"


# --- the report shows a repeated evaluation as "=" -----------------------------------------------------
def test_report_cells_say_all_presets_and_scene_sets_then_equals():
    from repro.report import build_markdown, cell_texts, claims_block

    m = {"fig10": {"mode": "quick", "metrics": {"max_rel_err": 0.01, "n_points": 3}},
         "fig8": {"mode": "quick", "metrics": {**_fig8(), "scene_set": "paper_cameras",
                                               "presets": {"robust": _fig8(22.0)},
                                               "scene_sets": {"tabletop_stress": {**_fig8(23.0), "presets": {
                                                   "robust": _fig8(25.0)}}}}}}
    matrix = claim_matrix(m)
    assert list(matrix) == list(COLUMNS)
    texts = cell_texts(matrix)
    eq5 = [texts[(c, "eq5")] for c in COLUMNS]
    assert eq5[0] == ("reproduced", "all presets and scene sets") and eq5[1:] == [(None, "=")] * 3
    refocus = [texts[(c, "refocus")][0] for c in COLUMNS]
    assert refocus == ["reproduced", "not reproduced", "partly reproduced", "reproduced"]
    assert all(texts[(c, "refocus")][1] == "" for c in COLUMNS)
    block = claims_block(matrix, report_link="r.md")
    row = [line for line in block.splitlines() if line.startswith("| " + BY_ID["eq5"].text.replace("|", "\\|"))][0]
    assert row.endswith("| `+` reproduced (all presets and scene sets) | = | = | = |")
    md = build_markdown(m, matrix, figures_rel="figures", bench=None)
    assert "same evaluation as *paper preset, paper_cameras*" in md
    assert "Evaluation: `fig8/robust/tabletop_stress/quick`" in md
    doc = claims_document(matrix)
    assert evaluation_problems(doc) == []
    assert doc[1]["verdicts"]["eq5"]["same_as"] == {"preset": "paper", "scene_set": "paper_cameras"}
    assert doc[1]["verdicts"]["refocus"]["same_as"] is None


# --- the quick data -------------------------------------------------------------------------------------
@pytest.mark.render
def test_every_cell_of_the_quick_claims_table_names_its_own_evaluation():
    from tests.golden import CLAIM_FIGURES, quick_metrics

    metrics = {fig: {"metrics": quick_metrics(fig), "mode": "quick"} for fig in CLAIM_FIGURES}
    matrix = claim_matrix(metrics)
    columns = list(matrix)
    assert columns == list(COLUMNS)
    doc = claims_document(matrix)
    assert evaluation_problems(doc) == []
    ids = {c.id: {entry["verdicts"][c.id]["evaluation"] for entry in doc} for c in CLAIMS}
    for c in CLAIMS:
        assert all(entry["verdicts"][c.id]["verdict"] != "not evaluated" for entry in doc), c.id
        expected = 1 if c.id in INDEPENDENT else 2 if c.id in PRESET_ONLY + SCENE_SET_ONLY else len(columns)
        assert len(ids[c.id]) == expected, (c.id, ids[c.id])
    assert ids["refocus"] == {f"fig8/{p}/{s}/quick" for p, s in COLUMNS}
    assert ids["model_fit_real_images"] == {f"fig4/{p}/{s}/quick" for p, s in COLUMNS}
    # the robust columns really are the robust preset's numbers: its own fit and its own map
    fig4 = metrics["fig4"]["metrics"]
    assert fig4["fit_estimator"] == "model_fit" and fig4["presets"]["robust"]["fit_estimator"] == "model_fit_checked"
    fig8 = metrics["fig8"]["metrics"]
    for node in (fig8, fig8["scene_sets"]["paper_cameras"]):
        paper, robust = node["images_vs_d2"], node["presets"]["robust"]["images_vs_d2"]
        assert paper["unchanged_d1"] == robust["unchanged_d1"]  # the same renders
        assert paper["refocused_estimated"]["psnr_db"] != robust["refocused_estimated"]["psnr_db"]  # other maps
    # a tampered copy (the case) fails the check
    bad = copy.deepcopy(doc)
    bad[1]["verdicts"]["refocus"]["evaluation"] = bad[0]["verdicts"]["refocus"]["evaluation"]
    assert evaluation_problems(bad)
