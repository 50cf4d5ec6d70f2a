"""What a claim is, what a verdict is, the thresholds of the rules and the helpers the rules share."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from ..results_query import MissingData

__all__ = ["ALL_PRESETS", "ALL_SCENE_SETS", "AXES", "DEFAULT_PRESET", "SELF_CHECK_NOTE", "SELF_CHECK_SCOPES", "VERDICTS",
           "Claim", "MissingData", "Verdict"]

VERDICTS = ("reproduced", "partly reproduced", "not reproduced", "not evaluated", "error")

#: The preset of a claim that does not vary with the preset.
DEFAULT_PRESET = "paper"
#: The axes of the claim matrix a claim can vary with (:attr:`Claim.varies_with`).
AXES = ("preset", "scene_set")
#: Evaluation-id parts along an axis the claim does not vary with.
ALL_PRESETS = "all-presets"
ALL_SCENE_SETS = "all-scene-sets"
#: Where a claim's evidence is a harness self-check (:attr:`Claim.self_check_scope`): in every cell, or
#: on the procedural test split only.
SELF_CHECK_SCOPES = ("everywhere", "test_split")
#: How the report labels a cell whose evidence is a harness self-check.
SELF_CHECK_NOTE = "harness self-check, not held-out evidence"


@dataclasses.dataclass(frozen=True)
class Verdict:
    """Outcome of checking one claim."""

    verdict: str     # one of VERDICTS
    evidence: str    # one or two sentences with the measured numbers
    numbers: dict    # the numbers the verdict rests on (JSON-able)
    evaluation: str = ""  # id of the evaluation the verdict rests on ("" when none: "not evaluated")


@dataclasses.dataclass(frozen=True)
class Claim:
    """One claim of Bae & Durand 2007 and how the harness checks it.

    ``check(rows)`` takes the claim's figure's rows of the results table for one cell
    (:class:`experiments.results_query.Results`, see :func:`experiments.claims.matrix.cell_rows`) and
    returns a :class:`Verdict`; a value it needs that is not there raises
    :class:`~experiments.results_query.MissingData` ("not evaluated").
    """

    id: str
    section: str     # where the paper makes it
    figure: str      # the figure whose rows test it
    text: str        # the claim, paraphrased
    rule: str        # how numbers become a verdict
    check: Callable
    varies_with: tuple[str, ...] = ("preset", "scene_set")
    # the axes of AXES the claim's numbers depend on: () for a property of the optics (Eq. 5, Eq. 6),
    # ("preset",) for the method on analytic images (no scene set), ("scene_set",) for the paper's
    # Eq. (3) filter with and without its bias (Fig. 5 fixes the filter's parameters: a claim about
    # the filter, not a preset; the robust preset turns the bias off), both for a preset's method on
    # rendered scenes.
    test_split: bool = False
    # whether the claim is also computed on the procedural test split (scene set "procedural_test"):
    # then that column is its own evaluation even when the claim does not vary with the scene set.
    self_check: str = ""
    # non-empty: why the claim's evidence (in the cells of ``self_check_scope``) is a check of the
    # harness against itself — it agrees by construction (a renderer that implements the formula
    # checked) or draws nothing from the scenes it is shown under — rather than held-out evidence for
    # the paper. The verdict is still computed (a failing self-check is a harness bug); the report
    # labels those cells (SELF_CHECK_NOTE) and they never count as a fragile verdict.
    self_check_scope: str = "everywhere"
    # one of SELF_CHECK_SCOPES: "everywhere" or "test_split" (the procedural test split's cells only).

    def __post_init__(self):
        bad = [a for a in self.varies_with if a not in AXES]
        if bad or len(set(self.varies_with)) != len(self.varies_with):
            raise ValueError(f"claim {self.id!r}: varies_with={self.varies_with!r} is invalid; allowed: "
                             f"distinct names of {AXES}")
        if self.self_check_scope not in SELF_CHECK_SCOPES:
            raise ValueError(f"claim {self.id!r}: self_check_scope={self.self_check_scope!r} is invalid; allowed: "
                             f"{', '.join(SELF_CHECK_SCOPES)}")
        if self.self_check_scope == "test_split" and self.self_check and not self.test_split:
            raise ValueError(f"claim {self.id!r}: self_check_scope='test_split' is invalid for a claim not computed "
                             "on the test split; allowed: test_split=True, or self_check_scope='everywhere'")


# --- thresholds of the rules (named so the rule texts, the tests and the report agree) --------------
#: Eq. (5) / Eq. (6): largest relative error of a rendered point that still reproduces the formula.
EQ_MAX_REL_ERR = 0.03
#: Model fit on analytic steps: median |error| bounds, px (clean straight and curved; noise + 8 bit).
FIT_CLEAN_MAX_MEDIAN_AE_PX = 0.15
FIT_NOISY_MAX_MEDIAN_AE_PX = 0.3
#: Neighbouring edges: a case where both estimators' median relative error exceeds this is no
#: evidence for either (both fail) and is excluded.
NEIGHBOUR_BOTH_FAIL_REL = 0.5
#: Fraction of the judged neighbouring-edge cases the model fit must win: reproduced / partly.
NEIGHBOUR_REPRODUCED_FRACTION = 0.8
NEIGHBOUR_PARTLY_FRACTION = 0.5
#: fig5 cases with fewer in-focus outliers than this before the filter are no evidence of a correction.
BIAS_MIN_OUTLIERS_BEFORE = 0.02
#: "Corrects the outliers": the in-focus outlier fraction falls by at least this fraction of its value.
BIAS_MIN_RELATIVE_DROP = 0.25
#: "Does not generate much change": |ΔMAE| / MAE_before at edges at most this.
SMALL_CHANGE_MAX_REL = 0.25
#: "Refines": the mean MAE over the cases falls by at least this fraction.
REFINE_MIN_RELATIVE_GAIN = 0.01
#: α visibly changes the map: mean |B(α_max) − B(α_min)| over textured pixels at least this, px
#: (a quarter pixel of σ: ≈ 5 % of the 0–5 px range the paper's maps are shown over).
ALPHA_VISIBLE_CHANGE_PX = 0.25
#: Dense map recovered on a scene: |mean signed error| and MAE over textured pixels at most these, px.
DENSE_MAX_ABS_BIAS_PX = 0.5
DENSE_MAX_MAE_PX = 1.0
#: Doubling: median |2·map(f/8) − map(f/4)| / map(f/4) at most this for the two maps to be "similar".
DOUBLING_MAX_MEDIAN_REL_DIFF = 0.2
#: Doubling: median |map − σ_gt(f/4)| / σ_gt(f/4) at most this for a map to match the f/4 truth.
DOUBLING_MAX_MEDIAN_REL_ERR = 0.25
#: An image is closer to a reference when PSNR rises by at least this (dB) / SSIM by at least this;
#: a fall by more than the same margin is worse (smaller changes are no change).
PSNR_MARGIN_DB = 0.1
SSIM_MARGIN = 0.002
#: Sharp regions count as kept when the magnified photo's in-focus PSNR against the f/4 render is at
#: least min(unchanged − SHARP_MAX_DROP_DB, SHARP_MIN_PSNR_DB) (in-focus pixels of the f/8 and f/4
#: renders are nearly identical, ~100 dB, so a drop alone would demand bit-exact pixels).
SHARP_MAX_DROP_DB = 3.0
SHARP_MIN_PSNR_DB = 35.0

#: How "closer" is decided (part of several rule texts).
CLOSER = (f"a measure is “closer” when PSNR rises by ≥ {PSNR_MARGIN_DB:g} dB (SSIM by ≥ {SSIM_MARGIN:g}) and "
          "“worse” when it falls by more than that margin")


def num(x) -> float:
    """A value of the table as float (empty → NaN)."""
    return math.nan if x is None else float(x)


def fmt(x, nd=3) -> str:
    """A number for the evidence text (``n/a`` for a missing one)."""
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}g}"


def err_or_inf(x) -> float:
    """An error metric as float; an empty one (the estimator gave no estimate) as +inf (a failure)."""
    return math.inf if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


def compare(before: float, after: float, margin: float) -> int:
    """+1 when ``after`` is higher by ≥ margin, −1 when lower by more than margin, else 0."""
    d = after - before
    return 1 if d >= margin else (-1 if d < -margin else 0)


def closer(base: dict, test: dict) -> tuple[int, int]:
    """(PSNR, SSIM) comparison of ``test`` with ``base`` against the same reference (+1/0/−1 each)."""
    return (compare(num(base["psnr_db"]), num(test["psnr_db"]), PSNR_MARGIN_DB),
            compare(num(base["ssim"]), num(test["ssim"]), SSIM_MARGIN))


def image_verdict(pairs: list[tuple[int, int]]) -> str:
    """Reproduced: both measures closer on every case; partly: on every case one is closer and the
    other no worse; else not reproduced."""
    if pairs and all(p == 1 and s == 1 for p, s in pairs):
        return "reproduced"
    if pairs and all(max(p, s) == 1 and min(p, s) >= 0 for p, s in pairs):
        return "partly reproduced"
    return "not reproduced"
