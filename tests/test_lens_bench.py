"""The lens benchmark (experiments.bench.lens): its rows, its verdict rules on both sides, its CLI flags."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from experiments.bench import lens
from tests.cli_run import run_in_process

TINY = dict(lens.LENS_CONFIG, psfs=("disk",), families=("step_edges", "checker"), noises=("iso100",),
            sigmas=(1.0, 4.0), tile=48, cols=2, variants={"robust": ("robust", {})},
            regions={"gated": lens.LENS_CONFIG["regions"]["disk + adequacy gate"]})


@pytest.fixture(scope="module")
def rows():
    return lens.measure_lens(TINY, progress=False)


def test_rows_cover_the_grid_and_cues(rows):
    keys = {(r["family"], r["variant"], r["cue"]) for r in rows}
    assert keys == {("step_edges", "robust", "dense_textured"), ("step_edges", "robust", "sparse"),
                    ("checker", "robust", "dense_textured"), ("checker", "robust", "sparse"),
                    ("checker", "region: gated", "region")}
    assert sorted({r["sigma"] for r in rows}) == [1.0, 4.0]
    steps = [r for r in rows if r["family"] == "step_edges" and r["cue"] == "sparse"]
    # the robust fit reads lens-blurred steps in linear light: measures at most edge pixels, small bias
    for r in steps:
        assert r["coverage"] > 0.9 and abs(r["median"]) < 0.05 * r["sigma_gt"]


def _row(**kw):
    base = {"psf": "disk", "noise": "iso100", "jpeg": None, "family": "dead_leaves", "seed": 0, "variant": "robust",
            "cue": "dense_textured", "sigma": 2.0, "sigma_gt": 2.0, "n": 100, "mae": 0.1, "bias": 0.0,
            "median": 0.0, "coverage": 1.0}
    return {**base, **kw}


def test_verdict_rules_both_sides():
    good = [_row(), _row(cue="sparse", family="step_edges", median=0.05, coverage=0.95),
            _row(cue="region", variant="region: gated", median=0.05, coverage=0.5),
            # no blur information in smooth shading: abstaining there is right, not judged
            _row(cue="region", variant="region: gated", family="shading", median=None, coverage=0.0),
            _row(cue="region", variant="region: other", median=3.0, coverage=0.5)]  # not the judged setting
    v = lens.judge_lens(good)
    assert v["pass"] is True and v["edges"]["pass"] and v["region"]["pass"] and v["dense"]["pass"]
    assert v["region"]["exempt"] == list(lens.REGION_NO_INFORMATION) and "shading" in v["region"]["exempt"]
    # each rule fails on its own
    for bad, part, reason in (
            (_row(mae=0.31), "dense", "error"),  # σ ≤ 4: 0.3 px
            (_row(sigma=6.0, sigma_gt=6.0, mae=0.61), "dense", "error"),  # σ > 4: 10 % of σ
            (_row(coverage=0.4, mae=0.1), "dense", "coverage"),  # accurate, but a map with holes
            (_row(cue="sparse", family="step_edges", coverage=0.89), "edges", "coverage"),
            (_row(cue="sparse", family="step_edges", median=0.11), "edges", "error"),
            (_row(cue="region", variant="region: gated", median=-0.11, coverage=0.5), "region", "error"),
            # a family with blur information where the cue abstains fails, however accurate its few measures
            (_row(cue="region", variant="region: gated", family="photo", median=0.0, coverage=0.3), "region",
             "coverage"),
            (_row(cue="region", variant="region: gated", family="photo", median=None, coverage=0.0), "region",
             "coverage"),
            # where there is no information, a measure it does give is still judged
            (_row(cue="region", variant="region: gated", family="shading", median=3.0, coverage=0.06), "region",
             "error")):
        v = lens.judge_lens(good + [bad])
        assert v[part]["pass"] is False and v["pass"] is False, bad
        assert [f["reason"] for f in v[part]["fails"]] == [reason], bad
    # the coverage target on its boundary: measuring on exactly the target share and accurate passes; just
    # below it fails; enough coverage and a wrong median fails
    at = lens.LENS_TARGETS["region_min_coverage"]
    assert at == lens.TARGET_MIN_COVERAGE == 0.5
    ok = _row(cue="region", variant="region: gated", family="photo", median=0.02, coverage=at)
    assert lens.judge_lens(good + [ok])["pass"] is True
    assert lens.judge_lens(good + [{**ok, "coverage": at - 0.01}])["region"]["pass"] is False
    assert lens.judge_lens(good + [{**ok, "median": 0.2}])["region"]["pass"] is False
    # only abstaining region rows: the region part is judged (and fails), not "n/a"
    v = lens.judge_lens([_row(cue="region", variant="region: gated", median=None, coverage=0.0)])
    assert v["region"]["pass"] is False and v["pass"] is False
    # outside σ 1–8 and at other noise levels the dense target does not apply
    assert lens.judge_lens(good + [_row(sigma=0.5, sigma_gt=0.5, mae=2.0), _row(noise="iso800", mae=2.0)])["pass"]
    # a tile with no textured pixel is not a dense cell to judge
    assert lens.judge_lens(good + [_row(n=0, mae=None, coverage=None)])["pass"] is True
    assert lens.judge_lens([])["pass"] is None


def test_markdown_says_which_cells_fail_for_coverage():
    rows = [_row(), _row(cue="region", variant="region: gated", median=None, coverage=0.0)]
    md = lens.lens_markdown(rows, TINY, lens.judge_lens(rows))
    assert "region cue FAIL (1 cell, 1 below the coverage target)" in md
    assert "cannot pass by abstaining" in md and "shading" in md


def test_markdown_names_every_section(rows):
    v = lens.judge_lens(rows)
    md = lens.lens_markdown(rows, TINY, v)
    for text in ("### PSF disk, noise iso100", "Worst texture family", "Edge measures on the straight steps",
                 "Region cue alone", "| checker | gated |", "Dense map over textured pixels", "| checker | robust |"):
        assert text in md
    assert ("PASS" in md) == bool(v["pass"])


def test_lens_config_and_bad_psf():
    assert lens.lens_config()["psfs"] == lens.LENS_CONFIG["psfs"]
    assert lens.lens_config(psfs=["hexagon", "hexagon"])["psfs"] == ("hexagon",)
    full = lens.lens_config(full=True)
    assert set(full["psfs"]) == {"gaussian", "disk", "soft_disk", "hexagon"} and 85 in full["jpeg_qualities"]
    with pytest.raises(ValueError, match="unknown PSF"):
        lens.lens_config(psfs=["square"])


def test_cli_bad_psf_and_flags():
    r = run_in_process("repro.bench", ["--accuracy", "--psf", "square"])
    assert r.returncode == 2 and "unknown PSF" in r.stderr and r.stderr.count("\n") == 1
    r = run_in_process("repro.bench", ["--psf", "disk"])
    assert r.returncode == 2 and "--psf, --full and --tone-curves go with --accuracy" in r.stderr


def test_region_rows_measure_only_where_the_cue_measures():
    cfg = copy.deepcopy(TINY)
    case = lens.lens_case("shading", "disk", "iso100", None, 0, cfg)
    from method import DefocusParams

    params = DefocusParams.preset("robust", **cfg["regions"]["gated"])
    rr = lens._region_rows(case["image"], case, params, (0.0, 2.5, np.inf), family="shading", variant="region: gated",
                           cue="region")
    # smooth shading carries no blur information: the gated cue gives (almost) no measure
    assert all((r["coverage"] or 0.0) < 0.05 for r in rr)


def test_periodic_cells_judged_only_above_the_contrast_threshold():
    at = lens.LENS_TARGETS["periodic_min_snr"]
    bad = _row(family="checker", mae=2.0, tone="srgb")
    v = lens.judge_lens([_row(), {**bad, "snr": at - 0.1}])  # contrast lost in the noise: not judged
    assert v["pass"] is True and v["dense"]["not_judged"][0]["family"] == "checker"
    assert lens.judge_lens([_row(), {**bad, "snr": at + 0.1}])["dense"]["pass"] is False
    assert lens.judge_lens([_row(), {**bad, "snr": None}])["dense"]["pass"] is False  # unknown: judged
    # a non-periodic family is judged whatever its contrast
    assert lens.judge_lens([_row(), _row(family="shading", mae=2.0, snr=0.5)])["dense"]["pass"] is False


def test_tone_rule_both_sides():
    light = lens.LENS_TARGETS["tone_light_variants"]
    limit = 1.0 + lens.LENS_TARGETS["tone_max_excess"]

    def cell(mae_robust, tone="filmic"):
        return [_row(tone=tone, mae=mae_robust), _row(tone=tone, variant=light[0], mae=0.25),
                _row(tone=tone, variant=light[1], mae=0.2)]

    ok = lens.judge_lens(cell(0.2 * limit - 1e-6))
    assert ok["tone"]["pass"] is True
    v = lens.judge_lens(cell(0.2 * limit + 1e-3))
    assert v["tone"]["pass"] is False and v["pass"] is False and v["tone"]["fails"][0]["tone"] == "filmic"
    assert lens.judge_lens([_row(tone="filmic")])["tone"]["pass"] is None  # the lights not run: not judged
    # σ beyond the old range is judged now (σ 1–16)
    assert lens.judge_lens([_row(sigma=12.0, sigma_gt=12.0, mae=1.3)])["dense"]["pass"] is False
    assert lens.judge_lens([_row(sigma=12.0, sigma_gt=12.0, mae=1.1)])["dense"]["pass"] is True


def test_tone_grid_config():
    cfg = lens.lens_config(tones=True)
    assert cfg["tones"] == lens.LENS_TONES and ("srgb", "display") in cfg["tones"]
    assert set(lens.LENS_TARGETS["tone_light_variants"]) <= set(cfg["variants"])
    assert lens.LENS_CONFIG["tones"] == (("srgb", "linear"),)
    assert lens.lens_config(full=True)["tones"] == lens.LENS_TONES


def test_tone_axis_rows_name_their_curve_and_contrast():
    cfg = dict(TINY, families=("checker",), sigmas=(1.0,), tones=(("gamma1.8", "linear"),),
               variants={"robust": ("robust", {}), "auto": ("robust", {}, "auto")}, regions={})
    rows = lens.measure_lens(cfg, progress=False)
    assert {r["tone"] for r in rows} == {"gamma1.8"} and {r["variant"] for r in rows} == {"robust", "auto"}
    assert all(r["snr"] > 3.0 for r in rows)  # a sharp checker: contrast far above the noise
    assert lens.tone_label("srgb", "display") == "srgb, display blur"


def test_periodic_contrast_is_lost_at_large_blur():
    """The bench's contrast / noise per tile: far above 3 for a sharp checker, below it once a disk of σ 8
    has averaged the checker out (so that cell is not judged)."""
    cfg = dict(lens.LENS_CONFIG, sigmas=(1.0, 8.0), tile=96, cols=2)
    snr = lens.lens_case("checker", "disk", "iso100", None, 0, cfg)["snr"]
    assert snr[1.0] > 5 * lens.LENS_TARGETS["periodic_min_snr"] and snr[8.0] < lens.LENS_TARGETS["periodic_min_snr"]
    flat = lens.lens_case("checker", "disk", "none", None, 0, cfg)["snr"]  # no noise: only the 8-bit step
    assert flat[1.0] > snr[1.0]
