"""The magnification targets' report (experiments.bench.magnify_targets) on made-up numbers."""

from experiments.bench import magnify_targets as M


def _report(meets):
    psnr = {"unchanged": {"all": 33.5, "in_focus": 44.5, "defocused": 33.8},
            "default": {"all": 39.3, "in_focus": 43.4, "defocused": 40.4}}
    return {"preset": "robust", "default": {"renderer": "scatter", "floor": "auto"},
            "renders": [{"scene": "portrait_garden", "psnr_db": psnr,
                         "targets": {"in_focus_kept": meets, "defocused_gained": True, "default_renderer_best": True}}],
            "photos": [{"photo": "chelsea", "defocused_sigma_px_input": 3.95,
                        "magnified": {"default": {"in_focus_psnr_db": 31.3, "defocused_sigma_px": 8.57,
                                                  "blur_ratio": 2.17}},
                        "targets": {"in_focus_kept": meets, "defocused_gained": True}}],
            "speed_12mp": {"renderer": "scatter", "shape": [2828, 4243], "magnify_s": 10.7, "meets_target": True,
                           "load1": [4.0, 4.5]}}


def test_markdown_marks_each_target():
    md = M.magnify_markdown(_report(True))
    assert "| portrait_garden | targets | best renderer: pass | pass | pass |" in md
    assert "| chelsea | default | 31.30 | 3.95 → 8.57 | 2.17 |" in md
    assert "10.7 s (pass; 1-min load 4.0 → 4.5" in md
    md = M.magnify_markdown(_report(False))
    assert "| portrait_garden | targets | best renderer: pass | FAIL | pass |" in md
    assert "| chelsea | targets | FAIL | | pass |" in md


def test_variants_put_the_default_first_and_the_literal_row_beside():
    from method import DefocusParams

    robust = M._variants(DefocusParams.preset("robust"))
    assert list(robust) == ["default", "gather, floor auto", "gather, floor clamp"]
    assert robust["default"] == ("scatter", "auto")
    paper = M._variants(DefocusParams.preset("paper"))
    assert paper == {"default": ("gather", "clamp"), "scatter, floor clamp": ("scatter", "clamp")}
