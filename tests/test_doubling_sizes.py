"""The doubling claim at both render sizes and the f/4 stage attribution (experiments/doubling_sizes.py)."""

import numpy as np
import pytest

from experiments.claims.core import DOUBLING_MAX_MEDIAN_REL_DIFF, DOUBLING_MAX_MEDIAN_REL_ERR
from experiments.claims.rules import doubling_verdict
from experiments.doubling_sizes import (LOSS_MIN_PX, STAGES, attribute_stage, doubling_markdown, size_verdict,
                                        summarise)


def _errors(est, o_ref, o_prop, sparse=-1.0, refined=-2.0):
    return {"estimated": {"sparse": {"bias": sparse}, "refined": {"bias": refined}, "dense_textured": {"bias": est}},
            "oracle_refine": {"dense_textured": {"bias": o_ref}}, "oracle_propagate": {"dense_textured": {"bias": o_prop}}}


def test_attribution_shares_telescope_and_name_the_losing_stage():
    # Eq. (3) pulls perfect measures down by 3 px, Eq. (4) alone by 0.5, the edge fit adds −0.2
    a = attribute_stage(_errors(est=-3.7, o_ref=-3.5, o_prop=-0.5))
    assert a["stage"] == "Eq. (3) refinement"
    assert sum(a["shares"].values()) == pytest.approx(-3.7)
    assert a["shares"]["Eq. (4) propagation"] == pytest.approx(-0.5)
    assert a["shares"]["edge fit (Sec. 3.2)"] == pytest.approx(-0.2)
    # the edge fit's measures too small, Eq. (3) and (4) faithful
    assert attribute_stage(_errors(est=-2.1, o_ref=-0.1, o_prop=0.0))["stage"] == "edge fit (Sec. 3.2)"
    assert attribute_stage(_errors(est=-1.0, o_ref=-1.0, o_prop=-1.0))["stage"] == "Eq. (4) propagation"
    # nothing loses more than LOSS_MIN_PX: no stage named
    small = -0.5 * LOSS_MIN_PX
    assert attribute_stage(_errors(est=3 * small, o_ref=2 * small, o_prop=small))["stage"] is None


def test_attribution_needs_the_oracles():
    e = _errors(-1, -1, -1)
    e["oracle_refine"] = {}
    with pytest.raises(ValueError, match="oracles=True"):
        attribute_stage(e)


@pytest.mark.parametrize("small,full,key", [
    ("reproduced", "reproduced", "holds"),
    ("reproduced", "not reproduced", "pixel_units"),
    ("partly reproduced", "not reproduced", "pixel_units"),
    ("not reproduced", "not reproduced", "claim_fails"),
    ("not reproduced", "reproduced", "full_only"),
    ("partly reproduced", "partly reproduced", "same"),
])
def test_size_verdict_separates_the_claim_from_the_pixel_units(small, full, key):
    v = size_verdict({"small": small, "full": full})
    assert v["key"] == key and v["text"]


def test_size_verdict_bad_input():
    with pytest.raises(ValueError, match="allowed: reproduced"):
        size_verdict({"small": "reproduced", "full": "maybe"})
    with pytest.raises(ValueError, match="'full'"):
        size_verdict({"small": "reproduced"})


def _numbers(apart, err):
    return {"doubled_f8_vs_map_f4_median_rel": apart, "doubled_f8_vs_map_f4_mae": 0.1,
            "doubled_f8_vs_gt_median_rel": err, "map_f4_vs_gt_median_rel": err,
            "doubled_f8_vs_gt_mae": 0.2, "map_f4_vs_gt_mae": 0.3}


def test_doubling_verdict_is_the_claims_rule():
    ok_apart, bad_apart = 0.5 * DOUBLING_MAX_MEDIAN_REL_DIFF, 2 * DOUBLING_MAX_MEDIAN_REL_DIFF
    ok_err, bad_err = 0.5 * DOUBLING_MAX_MEDIAN_REL_ERR, 2 * DOUBLING_MAX_MEDIAN_REL_ERR
    assert doubling_verdict({"a": _numbers(ok_apart, ok_err)})[0] == "reproduced"
    assert doubling_verdict({"a": _numbers(ok_apart, bad_err)})[0] == "partly reproduced"
    assert doubling_verdict({"a": _numbers(ok_apart, ok_err), "b": _numbers(bad_apart, ok_err)})[0] == "not reproduced"


def _case(scene, size, apart, err, est):
    return {"scene": scene, "size": size, "preset": "paper", "doubling": _numbers(apart, err),
            "median_sigma_gt_f4": 2.0, "seconds": 1.0,
            "attribution": attribute_stage(_errors(est=est, o_ref=est + 0.1, o_prop=-0.1))}


def test_summary_and_markdown():
    cfg = {"scenes": ("a", "b"), "sizes": ("small", "full"), "preset": "paper", "f_numbers": (8.0, 4.0)}
    cases = [_case(s, "small", 0.1, 0.1, -0.2) for s in ("a", "b")] + [_case(s, "full", 0.5, 0.6, -4.0)
                                                                      for s in ("a", "b")]
    rep = summarise(cases, cfg)
    assert rep["sizes"]["small"]["verdict"] == "reproduced" and rep["sizes"]["full"]["verdict"] == "not reproduced"
    assert rep["sizes"]["full"]["stage"] == "Eq. (3) refinement" and rep["sizes"]["small"]["stage"] is None
    assert rep["verdict"]["key"] == "pixel_units"
    md = doubling_markdown(rep)
    assert md.startswith("# The doubling claim at both render sizes")
    assert "pixel units fail at this resolution" in md and md.count("\n| a |") == 2
    assert all(f"share: {s}" in md for s in STAGES)
    assert np.isfinite(rep["cases"][0]["attribution"]["bias"])


def test_report_shows_the_doubling_section():
    from experiments.results_query import Results
    from repro._report_html import build_html
    from repro._report_markdown import build_markdown

    cfg = {"scenes": ("a",), "sizes": ("small", "full"), "preset": "paper", "f_numbers": (8.0, 4.0)}
    text = doubling_markdown(summarise([_case("a", "small", 0.1, 0.1, -0.2), _case("a", "full", 0.5, 0.6, -4.0)], cfg))
    md = build_markdown({}, Results([]), {}, figures_rel="f", bench=None, doubling=text)
    assert "## The doubling claim at both render sizes (paper preset)" in md and "pixel units fail" in md
    assert "doubling claim at both render sizes" not in build_markdown({}, Results([]), {}, figures_rel="f", bench=None)
    page = build_html({}, Results([]), {}, figures_rel="f", bench=None, doubling=text)
    assert "<h2>The doubling claim at both render sizes (paper preset)</h2>" in page and "pixel units fail" in page
