"""Parameter presets (method.presets.PRESETS) and the robust preset's switches.

* ``"paper"`` is ``DefocusParams()`` and reproduces the pre-preset pipeline bit for bit;
* presets, names and the new fields are validated;
* every robust switch is its own field, and the one-switch-off ablation on a texture mosaic shows
  which switches help the dense map (and, honestly, which do not);
* the model-fit plausibility rules (:func:`method.blur.model_fit.apply_fit_rules`) do what they say
  and keep the analytic step-edge accuracy.

Run with ``pytest -s`` to see the measured ablation table.
"""

import dataclasses
import math
import warnings

import numpy as np
import pytest

from experiments.metrics import region_masks
from experiments.stage_attribution import ablation_params
from method import NoEdgesWarning, estimate_defocus_map
from method.blur.estimators import estimate_blur
from method.blur.model_fit import model_fit_diagnostics, apply_fit_rules, estimate_blur_model_fit
from method.edges.elder_zucker import detect_edges
from method import PRESETS, DefocusParams
from method.presets import ROBUST_CHANGES, ZHUO_SIM_CHANGES
from method.pipeline import luminance
from method.propagation.defocus import propagate_defocus
from method.propagation.methods import PROPAGATION_METHODS, propagate_blur_measures
from scenes.analytic import step_edge, texture_mosaic
from tests.tolerances import (MOSAIC_ABLATION_MARGIN_PX, MOSAIC_ABLATION_MIN_GAIN_PX,
                              MOSAIC_ROBUST_VS_PAPER_MIN_GAIN_PX, MOSAIC_SPARSE_MIN_GAIN_PX, ROBUST_FIT_STEP_RTOL)

PAPER = DefocusParams()
ROBUST = DefocusParams.preset("robust")
#: The mosaic of the ablation below blurs display values (a Gaussian after the tone curve), so its
#: switches are measured with the edge fit in display light; measure_light itself is judged on blur in
#: each light (test_measure_light_reads_the_blur_in_the_light_it_acted_in).
ROBUST_DISPLAY = ROBUST.replace(measure_light="display")
#: The magnification's switches leave the map as it is (judged on magnified images: tests/test_map_floor.py).
MAGNIFICATION = ("map_floor", "magnify_renderer")
MOSAIC_CHANGES = {k: v for k, v in ROBUST_CHANGES.items() if k != "measure_light" and k not in MAGNIFICATION}

# --- the paper preset is the literal reproduction ------------------------------------

def test_paper_preset_is_the_default():
    assert DefocusParams.preset("paper") == DefocusParams()
    assert PRESETS["paper"] == DefocusParams()
    assert DefocusParams.preset("paper").changes_from(DefocusParams()) == {}


#: The paper preset's maps of the astronaut are stored as arrays (tests/golden/paper_astronaut.npz) and
#: compared at the tolerance measured across CPU code paths (tests/golden_arrays.py, the README in
#: tests/golden/): a hash of float64 bytes differs between CPUs of one library stack. The arrays were
#: written on the current code; on that machine the code *before* the presets and the beyond-the-paper
#: switches were added (e1ae76b) gives the same sparse and refined maps bit for bit and a dense map
#: within 2.5e-14 px (docs/testing.md), far inside the tolerance.


@pytest.fixture(scope="module")
def paper_astronaut():
    pytest.importorskip("skimage.data")
    from tests import golden_arrays

    return golden_arrays.compute_paper_astronaut(), golden_arrays.load_golden(), golden_arrays.load_tolerance()


def test_paper_pipeline_matches_the_pre_preset_golden_arrays(paper_astronaut):
    from tests.golden_arrays import compare

    got, golden, atol = paper_astronaut
    assert compare(got, golden, atol) == []
    assert np.isfinite(golden["sparse_sigma"]).sum() > 500  # the golden has edges to compare


@pytest.mark.parametrize("name", ["sparse_sigma", "refined_sigma", "defocus_map"])
def test_golden_arrays_comparison_fails_beyond_tolerance(paper_astronaut, name):
    """The paper output moved by 10 × the tolerance at one pixel, by a NaN at a finite pixel, or by a
    relative 1e-4 everywhere fails the golden comparison; the golden moved by half the tolerance passes."""
    from tests.golden_arrays import compare

    got, golden, atol = paper_astronaut
    assert 0 < atol < 1e-5  # measured: ~1.6e-7 px (round-off, far below any change of the method)
    finite = np.flatnonzero(np.isfinite(got[name]))
    i = finite[len(finite) // 2]
    moved = {k: v.copy() for k, v in got.items()}
    moved[name].flat[i] += 10 * atol
    problems = compare(moved, golden, atol)
    assert len(problems) == 1 and problems[0].startswith(name) and "atol" in problems[0], problems
    moved[name].flat[i] = np.nan
    problems = compare(moved, golden, atol)
    assert len(problems) == 1 and "NaN" in problems[0], problems
    assert compare({**got, name: got[name] * (1 + 1e-4)}, golden, atol) != []
    within = {k: v.copy() for k, v in golden.items()}
    within[name].flat[i] += 0.5 * atol
    assert compare(within, golden, atol) == []


# --- presets, names, validation -------------------------------------------------------------------

def test_presets_registered():
    assert set(PRESETS) == {"paper", "robust", "zhuo_sim"}
    assert all(isinstance(p, DefocusParams) for p in PRESETS.values())


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_round_trips(name):
    p = DefocusParams.preset(name)
    assert p == PRESETS[name]
    # a copy rebuilt from its fields is equal (and validates)
    assert DefocusParams(**{f.name: getattr(p, f.name) for f in dataclasses.fields(p)}) == p
    # paper + its recorded changes gives the preset back
    assert DefocusParams().replace(**{k: v for k, (v, _) in p.changes_from(DefocusParams()).items()}) == p
    # overrides are applied and validated
    assert DefocusParams.preset(name, alpha=0.25).alpha == 0.25
    assert DefocusParams.preset(name, alpha=0.25).replace(alpha=p.alpha) == p
    with pytest.raises(ValueError, match="alpha"):
        DefocusParams.preset(name, alpha=-1.0)


def test_preset_changes_are_the_documented_ones():
    assert {k: v for k, (v, _) in ROBUST.changes_from(PAPER).items()} == ROBUST_CHANGES
    assert set(ROBUST.changes_from(PAPER)) == set(ROBUST_CHANGES)
    for k, (mine, theirs) in ROBUST.changes_from(PAPER).items():
        assert mine == ROBUST_CHANGES[k] and theirs == getattr(PAPER, k)
    zs = DefocusParams.preset("zhuo_sim")
    assert {k: v for k, (v, _) in zs.changes_from(PAPER).items()} == ZHUO_SIM_CHANGES


@pytest.mark.parametrize("bad", ["nope", "Paper", "", None, 3])
def test_unknown_preset_lists_allowed(bad):
    with pytest.raises(ValueError) as info:
        DefocusParams.preset(bad)
    msg = str(info.value)
    assert all(repr(n) in msg for n in PRESETS), msg


def test_propagation_registry_and_unknown_name():
    assert set(PROPAGATION_METHODS) == {"colorization", "matting_laplacian"}
    for name in PROPAGATION_METHODS:
        assert DefocusParams(propagation=name).propagation == name
    with pytest.raises(ValueError, match="propagation") as info:
        DefocusParams(propagation="poisson")
    assert all(repr(n) in str(info.value) for n in PROPAGATION_METHODS), str(info.value)


def test_propagation_registry_calls_the_method(rng):
    h, w = 24, 28
    ref = rng.random((h, w, 3))
    bm = np.where(rng.random((h, w)) < 0.15, 1.0 + 3.0 * rng.random((h, w)), np.nan)
    p = PAPER.replace(propagation_downsample=1)
    got = propagate_blur_measures(bm, ref, params=p)
    want = propagate_defocus(bm, ref, alpha=p.alpha, window=p.propagation_window,
                             neighborhood=p.propagation_neighborhood, tol=p.propagation_tol,
                             solver=p.propagation_solver, downsample=1, refinement=p.propagation_refinement)
    np.testing.assert_array_equal(got, want)
    # the matting propagation has no per-edge confidence: refused, not silently ignored
    with pytest.raises(ValueError, match="confidence"):
        propagate_blur_measures(bm, ref, params=p.replace(propagation="matting_laplacian"),
                                confidence=np.ones((h, w)))


@pytest.mark.parametrize("field, values", [
    ("fit_max_scale", [0.0, -1.0, math.nan]),
    ("fit_min_samples", [2, 0, 4.0, 5.5]),
    ("fit_max_width_ratio", [0.0, -0.5, math.nan]),
    ("fit_below_scale", ["NaN", "none", ""]),
    ("bilateral_range_kernel", ["max", "Product", ""]),
    ("bias_reference", ["mm", "fraction"]),
    ("refinement_robust_iterations", [-1, 1.5]),
    ("refinement_robust_scale", [0.0, -0.5, math.nan]),
    ("propagation", ["poisson", ""]),
    ("alpha_confidence", ["always", "agree"]),
    ("matting_lambda", [0.0, -1e-3, math.nan]),
    ("matting_epsilon", [0.0, -1e-5]),
    ("matting_tol", [0.0, 1.0, -1e-3, math.nan]),
    ("matting_step_tol", [0.0, 1.0, -1e-4, math.nan, True, "1e-4"]),
    ("fit_residual_noise", [-1.0, math.inf]),
    ("fit_scale_ratio", [0.0, 1.5]),
    ("relaxed_fit_weight", [0.0, 1.5]),
    ("measure_weighting", ["Uncertainty", "", None]),
    ("bias_weighting", ["uncertain", "", None]),
    ("fit_psf", ["Disk", "", "pillbox", None]),
])
def test_new_fields_reject_bad_values(field, values):
    for v in values:
        with pytest.raises(ValueError, match=field):
            DefocusParams(**{field: v})
        with pytest.raises(ValueError, match=field):
            DefocusParams.preset("robust", **{field: v})


@pytest.mark.parametrize("field, value", [
    ("fit_max_scale", 4.0), ("fit_max_scale", None), ("fit_min_samples", 7), ("fit_max_width_ratio", 1.0),
    ("fit_below_scale", "nan"), ("bilateral_range_kernel", "product"), ("bias_reference", "image_fraction"),
    ("refinement_robust_iterations", 0), ("refinement_robust_scale", 2.0), ("alpha_confidence", "agreement"),
    ("matting_lambda", 0.1), ("matting_epsilon", 1e-3), ("matting_tol", 1e-3), ("matting_step_tol", 1e-3), ("matting_step_tol", None),
    ("fit_residual_noise", 2.0),
    ("fit_scale_ratio", 0.5),
    ("relaxed_fit_weight", 0.1), ("measure_weighting", "hand"), ("bias_weighting", "uniform"), ("fit_psf", "disk"), ("fit_psf", "best"), ("fit_psf", "gaussian")])
def test_new_fields_accept_good_values(field, value):
    p = DefocusParams(**{field: value})
    assert getattr(p, field) == value
    # changes_from reports exactly this field (or nothing when it is the paper's value)
    want = {} if value == getattr(PAPER, field) else {field: (value, getattr(PAPER, field))}
    assert p.changes_from(PAPER) == want
    assert PAPER.changes_from(p) == {k: (b, a) for k, (a, b) in want.items()}


# --- every robust switch is its own field ---------------------------------------------------------

def test_every_robust_switch_is_its_own_ablation_row():
    rows = ablation_params(ROBUST, ROBUST_CHANGES)
    assert len(rows) == len(ROBUST_CHANGES) + 1
    assert rows["all"] == ROBUST
    assert len(set(rows.values())) == len(ROBUST_CHANGES) + 1  # all distinct
    for field in ROBUST_CHANGES:
        row = rows[f"no {field}"]
        assert set(row.changes_from(ROBUST)) == {field}
        assert getattr(row, field) == getattr(PAPER, field)
    # turning every switch off gives the paper back
    paper = ROBUST.replace(**{f: getattr(PAPER, f) for f in ROBUST_CHANGES})
    assert paper == PAPER


# --- the ablation on a texture mosaic --------------------------------------------------------------
#: 48×192 dead-leaves mosaics: one row of four 48-px tiles, σ = 0.5, 1, 2, 4 px, 8-bit + noise 1/255.
MOSAIC = dict(tile=48, sigmas=(0.5, 1.0, 2.0, 4.0), cols=4, noise_std=1.0 / 255, quantize_bits=8)
MOSAIC_SEEDS = (0, 1, 2)

#: Switches of Eq. (3), the cross-bilateral refinement (they cannot change the sparse stage).
REFINEMENT_FIELDS = ("bilateral_sigma_spatial", "bilateral_sigma_range", "bilateral_range_kernel",
                     "sharpness_bias", "bias_scale", "bias_reference", "refinement_robust_iterations",
                     "refinement_robust_scale")

#: What each robust switch was measured to do on the mosaic (seed-mean dense textured MAE over seeds
#: 0–2; gain = MAE with the switch off − MAE with all on, px; 2026-12-06 with the uncertainty weights and the
#: guarded scale following: robust 0.160, paper 0.526; printed by the ``mosaic_ablation`` fixture with -s):
#:
#: * helps the dense map: estimator="model_fit_checked" +0.229, noise_model="signal_dependent" +0.103
#:   (sparse +0.115), measure_weighting="uncertainty" +0.048 (sparse unchanged: it only weighs the
#:   measures, in Eq. (3) and Eq. (4); the hand-set relaxed_fit_weight it replaced gave +0.017);
DENSE_HELPS = ("estimator", "noise_model", "measure_weighting")
#: * neutral on this σ ≤ 4 mosaic: sharpness_bias=False +0.003; fit_max_scale −0.008 (kept for its gain
#:   on the lens bench's blurry tiles and the renders, docs/presets.md); bilateral_sigma_spatial (5 %)
#:   +0.005; fit_psf +0.001 (its "auto" selection picks Eq. (2c) on this Gaussian-blurred mosaic; the
#:   disk fit's accuracy on disk blur: tests/test_disk_edge_response.py); fit_follow_max_residual
#:   −0.001 (with the guard off the unguarded re-fit; its cost on dead leaves σ 3–4 and its guard:
#:   tests/test_blur_scale_follow.py, docs/presets.md);
DENSE_NEUTRAL = ("sharpness_bias", "fit_max_scale", "bilateral_sigma_spatial", "fit_psf", "fit_follow_max_residual")
#: * the region (spectral) cue and its fusion, measured on the accuracy bench's 96-px mosaics and the
#:   photos (docs/cue-fusion.md): region_estimator +0.012 px here (σ ≤ 4; its gain is on σ 5–8 tiles
#:   and real photos: coffee AUC 0.653 → 0.825), fusion_edge_error_rel −0.001, fusion_island_weight
#:   −0.007, fusion_straddle_weight −0.001 — within the margin on this mosaic; the island and straddle
#:   factors keep the region terms from out-voting exact edge measures (step mosaic dense MAE 0.21 px
#:   with them, 0.54 / 0.77 px without each);
REGION_CUE = ("region_estimator", "fusion_edge_error_rel", "fusion_island_weight", "fusion_straddle_weight")
#: * neutral on this σ ≤ 4 mosaic, helps blurry texture (σ 5–8): fit_residual_noise (k = 2),
#:   dense −0.004, sparse −0.044 px (it adds measures, ~25 % more here, of poorer fits); its gain is
#:   on σ ≥ 5 tiles (tests/test_relaxed_fit_confidence.py: σ 6 tile 1.40 → 1.09 px; 1.53 → 1.45 px with the noise model and the plateau gate) with the
#:   relaxed measures at relaxed_fit_weight;
DENSE_NEUTRAL_BLURRY_HELPS = ("fit_residual_noise",)
#: * no effect on the dense map but helps the sparse stage (fewer, better measures): fit_below_scale
#:   dense +0.019, sparse +0.024 (with the paper's σb = 0); fit_max_residual (0.03 instead of 0.05) dense
#:   +0.010, sparse +0.037; fit_max_width_ratio dense +0.000, sparse +0.223 (its dense gain, +0.151 with the
#:   hand-set weights, is now taken by the uncertainty weights, which give its too-wide fits little
#:   weight); fit_step_gate ("plateau", reach 0.5) dense +0.015, sparse +0.045 (the mosaic's blurred texture
#:   bands that turn back before their plateaus were read as edges of the wrong width);
DENSE_NEUTRAL_SPARSE_HELPS = ("fit_below_scale", "fit_max_residual", "fit_max_width_ratio", "fit_step_gate")
#: * HURTS the dense map on the mosaic: bilateral_range_kernel −0.032 (0.160 → 0.128 px with the sum
#:   kernel): with the estimated (noisy, sparse) measures a colour-blind average wins on this mosaic,
#:   whose tiles share one colour distribution. It does lower the error the refinement adds to *perfect*
#:   measures (oracle_refine; asserted in
#:   tests/test_stage_attribution.py::test_oracle_refine_credits_the_refinement_switches).
DENSE_HURTS = ("bilateral_range_kernel",)
#: * identical on this σ ≤ 4 mosaic: fit_follow_scale (the guard, fit_follow_max_residual 0.01, re-fits no
#:   edge of it); its gain is on σ ≥ 8 (isolated steps and the lens bench's large grid, docs/presets.md).
FOLLOW_IDENTICAL = ("fit_follow_scale",)
#: * identical on this σ ≤ 4 mosaic (no edge of it needs σ1 > 16 or σ2 > 8), and a faster detector
#:   (no 64-px FFT padding level): the coarse-scale caps sigma1_scales ≤ 16, sigma2_scales ≤ 8
#:   (their accuracy on σ 5–8 tiles and renders: docs/presets.md, the accuracy bench).
SCALE_CAPS_IDENTICAL = ("sigma1_scales", "sigma2_scales")
#: * identical on this 48×192 mosaic (too few blocks to measure the noise's spectrum: white is assumed):
#:   noise_spectrum; judged on correlated noise, the resized 1-MP image and the photos
#:   (tests/test_noise_spectrum.py, docs/noise.md).
NOISE_SPECTRUM_IDENTICAL = ("noise_spectrum",)
#: * the light of the edge stage: linear (a lens blurs linear radiance): judged on steps blurred in each
#:   light (below) and on the lens bench, the renders and the photos (docs/presets.md).
LIGHT = ("measure_light",)


def test_every_robust_switch_has_a_measured_claim():
    """A switch added to ROBUST_CHANGES must be measured and put in one of the groups above."""
    groups = (DENSE_HELPS + DENSE_NEUTRAL_SPARSE_HELPS + DENSE_NEUTRAL_BLURRY_HELPS + DENSE_HURTS + FOLLOW_IDENTICAL
              + SCALE_CAPS_IDENTICAL + REGION_CUE + LIGHT + MAGNIFICATION + DENSE_NEUTRAL
              + NOISE_SPECTRUM_IDENTICAL)
    assert len(set(groups)) == len(groups)
    assert set(ROBUST_CHANGES) <= set(groups), sorted(set(ROBUST_CHANGES) - set(groups))


@pytest.fixture(scope="module")
def mosaic_ablation():
    """{row: {"dense": [MAE per seed], "sparse": [...], "n_sparse": [...]}} over paper + ablation rows."""
    rows = {"paper": PAPER, **ablation_params(ROBUST_DISPLAY, MOSAIC_CHANGES)}
    out = {name: {"dense": [], "sparse": [], "n_sparse": []} for name in rows}
    for seed in MOSAIC_SEEDS:
        m = texture_mosaic(**MOSAIC, rng=seed)
        for name, p in rows.items():
            with warnings.catch_warnings():
                warnings.simplefilter("error", NoEdgesWarning)
                r = estimate_defocus_map(m.image, p)
            reg = region_masks(m.image, m.sigma, edges=r.edges, exclude=m.boundary)
            tx = reg["textured"]
            at = reg["edges"] & np.isfinite(r.sparse_sigma)
            out[name]["dense"].append(float(np.mean(np.abs(r.defocus_map[tx] - m.sigma[tx]))))
            out[name]["sparse"].append(float(np.mean(np.abs(r.sparse_sigma[at] - m.sigma[at]))))
            out[name]["n_sparse"].append(int(np.isfinite(r.sparse_sigma).sum()))
    print("\nmosaic ablation: dense textured MAE per seed | seed mean (gain), sparse MAE seed mean (gain), px")
    for name, v in out.items():
        dg = np.mean(v["dense"]) - np.mean(out["all"]["dense"])
        sg = np.mean(v["sparse"]) - np.mean(out["all"]["sparse"])
        print(f"  {name:30s} dense {' '.join(f'{x:.3f}' for x in v['dense'])} | {np.mean(v['dense']):.3f} "
              f"({dg:+.3f})   sparse {np.mean(v['sparse']):.3f} ({sg:+.3f})  n {v['n_sparse']}")
    return out


def _gain(ab, field, key="dense"):
    """Seed-mean MAE with ``field`` reset to the paper's value minus the robust preset's, px."""
    return float(np.mean(ab[f"no {field}"][key]) - np.mean(ab["all"][key]))


def _in_preset(field):
    if field not in MOSAIC_CHANGES:
        pytest.skip(f"{field} is no longer a switch of the robust preset")


def test_robust_beats_paper_on_mosaic(mosaic_ablation):
    ab = mosaic_ablation
    gain = np.mean(ab["paper"]["dense"]) - np.mean(ab["all"]["dense"])
    assert gain >= MOSAIC_ROBUST_VS_PAPER_MIN_GAIN_PX, gain
    assert all(r < p for r, p in zip(ab["all"]["dense"], ab["paper"]["dense"]))  # on every seed
    assert np.mean(ab["all"]["sparse"]) < np.mean(ab["paper"]["sparse"])


@pytest.mark.parametrize("field", FOLLOW_IDENTICAL + SCALE_CAPS_IDENTICAL + NOISE_SPECTRUM_IDENTICAL)
def test_switch_identical_on_the_sharp_mosaic(mosaic_ablation, field):
    """The guarded scale following re-fits no edge of this σ ≤ 4 mosaic, the coarse-scale caps
    remove no edge of this σ ≤ 4 mosaic, and its noise spectrum cannot be measured (white): the same
    maps on every seed."""
    _in_preset(field)
    ab = mosaic_ablation
    assert ab[f"no {field}"] == ab["all"]


@pytest.mark.parametrize("field", sorted(set(MOSAIC_CHANGES) - set(DENSE_HURTS)))
def test_switch_off_does_not_improve_the_dense_map(mosaic_ablation, field):
    """Turning one switch off (others on) does not improve the dense map by more than a small margin
    (every switch of the preset except the recorded DENSE_HURTS)."""
    assert _gain(mosaic_ablation, field) >= -MOSAIC_ABLATION_MARGIN_PX, (field, _gain(mosaic_ablation, field))


@pytest.mark.parametrize("field", DENSE_HELPS)
def test_switch_helps_the_dense_map(mosaic_ablation, field):
    _in_preset(field)
    assert _gain(mosaic_ablation, field) >= MOSAIC_ABLATION_MIN_GAIN_PX, (field, _gain(mosaic_ablation, field))


@pytest.mark.parametrize("field", DENSE_NEUTRAL)
def test_switch_neutral_on_the_mosaic(mosaic_ablation, field):
    _in_preset(field)
    assert abs(_gain(mosaic_ablation, field)) <= MOSAIC_ABLATION_MARGIN_PX, (field, _gain(mosaic_ablation, field))


@pytest.mark.parametrize("field", DENSE_NEUTRAL_SPARSE_HELPS)
def test_switch_helps_the_sparse_stage_only(mosaic_ablation, field):
    _in_preset(field)
    ab = mosaic_ablation
    assert abs(_gain(ab, field)) <= MOSAIC_ABLATION_MARGIN_PX, (field, _gain(ab, field))
    assert _gain(ab, field, "sparse") >= MOSAIC_SPARSE_MIN_GAIN_PX, (field, _gain(ab, field, "sparse"))
    # it acts by rejecting measures, on every seed
    assert all(n_all < n_off for n_all, n_off in zip(ab["all"]["n_sparse"], ab[f"no {field}"]["n_sparse"]))


@pytest.mark.parametrize("field", DENSE_NEUTRAL_BLURRY_HELPS)
def test_switch_neutral_on_the_sharp_mosaic_adds_measures(mosaic_ablation, field):
    """No dense effect beyond the margin on this σ ≤ 4 mosaic; it acts by adding measures, on every seed
    (its dense gain on blurry tiles: tests/test_relaxed_fit_confidence.py)."""
    _in_preset(field)
    ab = mosaic_ablation
    assert abs(_gain(ab, field)) <= MOSAIC_ABLATION_MARGIN_PX, (field, _gain(ab, field))
    assert all(n_all > n_off for n_all, n_off in zip(ab["all"]["n_sparse"], ab[f"no {field}"]["n_sparse"]))


@pytest.mark.parametrize("field", DENSE_HURTS)
def test_switch_does_not_help_the_dense_map_on_the_mosaic(mosaic_ablation, field):
    """A recorded negative finding (see DENSE_HURTS): turning the switch off IMPROVES the mosaic's dense
    map beyond the margin. If this starts failing, re-measure and re-classify the switch."""
    _in_preset(field)
    assert _gain(mosaic_ablation, field) <= -MOSAIC_ABLATION_MARGIN_PX, (field, _gain(mosaic_ablation, field))


@pytest.mark.parametrize("blur_light", ["linear", "display"])
def test_measure_light_reads_the_blur_in_the_light_it_acted_in(blur_light):
    """A disk-blurred step (σ 4 px, ISO 100 noise, 8 bits): the robust fit in the light the blur acted in
    measures it (≥ 90 % of the edge pixels, median within 5 %); in the other light the tone curve makes
    the profile asymmetric and the checked fit declines it (measured: 0 %). A lens blurs linear light."""
    from method.luma import measure_luminance
    from method.pipeline import blur_stage, edges_stage
    from scenes.analytic.lens import lens_step_edge

    e = lens_step_edge((128, 128), sigma=4.0, psf="disk", angle=0.4, light=blur_light, noise="iso100",
                       quantize_bits=8, rng=0)
    near = np.abs(e.edge_distance) < 4.0
    near[:30], near[-30:], near[:, :30], near[:, -30:] = False, False, False, False
    coverage = {}
    for light in ("linear", "display"):
        p = ROBUST.replace(measure_light=light)
        gray = measure_luminance(e.image, light)
        edges = edges_stage(gray, params=p)
        sparse = blur_stage(gray, edges, params=p)[0][near & edges.edges]
        ok = np.isfinite(sparse)
        coverage[light] = ok.mean()
        if light == blur_light:
            assert ok.mean() >= 0.9 and abs(np.median(sparse[ok]) - 4.0) <= 0.2
    other = "display" if blur_light == "linear" else "linear"
    assert coverage[other] < 0.1, coverage


def test_refinement_switches_leave_the_sparse_stage_alone(mosaic_ablation):
    ab = mosaic_ablation
    fields = [f for f in ROBUST_CHANGES if f in REFINEMENT_FIELDS]
    assert fields
    for field in fields:
        assert ab[f"no {field}"]["sparse"] == ab["all"]["sparse"]
        assert ab[f"no {field}"]["dense"] != ab["all"]["dense"]


# --- model-fit plausibility rules (apply_fit_rules) ------------------------------------------------

def _synthetic_diagnostics():
    """One row per case: (σb, window samples, fitted width s px, σ2 px)."""
    cases = [
        (1.0, 3, 1.2, 0.5),    # 0: 3 samples (half-window 1 px)
        (1.0, 4, 1.2, 0.5),    # 1: 4 samples (half-window 1.5 px)
        (1.0, 5, 1.2, 0.5),    # 2: 5 samples (half-window 2 px): s/half-window = 0.6
        (2.0, 9, 3.1, 1.0),    # 3: half-window 4 px: s/half-window = 0.775
        (2.0, 9, 2.9, 1.0),    # 4: s/half-window = 0.725
        (0.0, 9, 0.5, 0.5),    # 5: s ≤ σ2 at the finest σ2 (0.5): sharp edge, kept at 0
        (0.0, 9, 0.9, 1.0),    # 6: s ≤ σ2 at σ2 = 1 > finest: no measure under "nan"
        (0.0, 15, 1.5, 2.0),   # 7: same at σ2 = 2
        (np.nan, 0, np.nan, np.nan),  # 8: off edges / failed fit stays NaN
    ]
    sb, win, width, s2 = (np.array(c) for c in zip(*cases))
    return {"sigma_b": sb[None], "window": win.astype(np.int64)[None], "width": width[None],
            "sigma2": s2[None], "residual": np.zeros((1, len(cases)))}


def _nan_cols(a):
    return set(np.flatnonzero(np.isnan(a[0])).tolist())


def test_fit_rules_paper_defaults_change_nothing():
    d = _synthetic_diagnostics()
    out = apply_fit_rules(d, params=PAPER)
    np.testing.assert_array_equal(out, d["sigma_b"])
    assert out is not d["sigma_b"]


def test_fit_rule_min_samples():
    d = _synthetic_diagnostics()
    assert _nan_cols(apply_fit_rules(d, params=PAPER.replace(fit_min_samples=4))) == {0, 8}
    assert _nan_cols(apply_fit_rules(d, params=PAPER.replace(fit_min_samples=5))) == {0, 1, 8}
    assert _nan_cols(apply_fit_rules(d, params=PAPER.replace(fit_min_samples=10))) == {0, 1, 2, 3, 4, 5, 6, 8}


def test_fit_rule_max_width_ratio():
    d = _synthetic_diagnostics()
    # width > ratio · (window − 1)/2 at 0.75: cases 0 (1.2 > 0.75), 1 (1.2 > 1.125), 3 (3.1 > 3.0);
    # kept: 2 (1.2 ≤ 1.5), 4 (2.9 ≤ 3.0), 5–7
    assert _nan_cols(apply_fit_rules(d, params=PAPER.replace(fit_max_width_ratio=0.75))) == {0, 1, 3, 8}
    # at ratio 0.5: case 0 (1.2 > 0.5), 1 (1.2 > 0.75), 2 (1.2 > 1.0), 3, 4 (2.9 > 2.0)
    assert _nan_cols(apply_fit_rules(d, params=PAPER.replace(fit_max_width_ratio=0.5))) == {0, 1, 2, 3, 4, 8}


def test_fit_rule_below_scale_nan_only_above_finest_scale():
    d = _synthetic_diagnostics()
    out = apply_fit_rules(d, params=PAPER.replace(fit_below_scale="nan"))
    assert _nan_cols(out) == {6, 7, 8}
    assert out[0, 5] == 0.0  # the sharp edge at the finest σ2 keeps σb = 0
    # "finest" is params.sigma2_scales' minimum: with σ2 from 1 px up, case 6 is at the finest scale
    coarse = PAPER.replace(fit_below_scale="nan", sigma2_scales=(1.0, 2.0, 4.0, 8.0, 16.0, 32.0))
    assert _nan_cols(apply_fit_rules(d, params=coarse)) == {7, 8}


def test_fit_rules_untouched_values_are_unchanged():
    d = _synthetic_diagnostics()
    out = apply_fit_rules(d, params=ROBUST)
    keep = np.isfinite(out)
    np.testing.assert_array_equal(out[keep], d["sigma_b"][keep])
    assert _nan_cols(out) == {0, 1, 3, 6, 7, 8}


@pytest.fixture(scope="module")
def mosaic_diagnostics():
    m = texture_mosaic(**MOSAIC, rng=0)
    gray = luminance(m.image)
    em = detect_edges(gray, keep_hessians=True)
    return gray, em, model_fit_diagnostics(gray, em, params=PAPER)


def test_fit_rules_default_params_bit_identical_to_model_fit(mosaic_diagnostics):
    gray, em, d = mosaic_diagnostics
    ref = estimate_blur_model_fit(gray, em, params=PAPER)
    np.testing.assert_array_equal(apply_fit_rules(d, params=PAPER), ref)
    np.testing.assert_array_equal(d["sigma_b"], ref)
    assert np.isfinite(ref).sum() > 500


def test_fit_rules_on_real_diagnostics(mosaic_diagnostics):
    gray, em, d = mosaic_diagnostics
    fin = np.isfinite(d["sigma_b"])
    win, width, s2 = d["window"], d["width"], d["sigma2"]
    # min samples: exactly the windows below the limit go (and there are some: 4-sample windows)
    out = apply_fit_rules(d, params=PAPER.replace(fit_min_samples=5))
    assert (fin & (win < 5)).sum() > 0
    np.testing.assert_array_equal(np.isnan(out), ~fin | (win < 5))
    # width ratio
    out = apply_fit_rules(d, params=PAPER.replace(fit_max_width_ratio=0.75))
    too_wide = fin & (width > 0.75 * 0.5 * (win - 1))
    assert too_wide.sum() > 0
    np.testing.assert_array_equal(np.isnan(out), ~fin | too_wide)
    # below scale: the paper's σb = 0 at σ2 above the finest scale becomes NaN; nothing else changes
    out = apply_fit_rules(d, params=PAPER.replace(fit_below_scale="nan"))
    below = fin & (width <= s2)
    assert below.sum() > 0 and np.all(d["sigma_b"][below] == 0.0)
    np.testing.assert_array_equal(np.isnan(out), ~fin | (below & (s2 > min(PAPER.sigma2_scales))))
    np.testing.assert_array_equal(out[np.isfinite(out)], d["sigma_b"][np.isfinite(out)])


def test_estimator_applies_the_rules_of_its_params(mosaic_diagnostics):
    """estimate_blur_model_fit with robust params = apply_fit_rules on the robust diagnostics."""
    gray, em, _ = mosaic_diagnostics
    d = model_fit_diagnostics(gray, em, params=ROBUST)
    got = estimate_blur_model_fit(gray, em, params=ROBUST)
    np.testing.assert_array_equal(got, apply_fit_rules(d, params=ROBUST))
    # fit_max_scale: the responses fitted are at min(σ2, 2 px)
    edge = np.isfinite(em.sigma2) & em.edges
    np.testing.assert_array_equal(d["sigma2"][edge & np.isfinite(d["sigma2"])],
                                  np.minimum(em.sigma2, 2.0)[edge & np.isfinite(d["sigma2"])])
    assert np.any(em.sigma2[edge] > 2.0)


# --- fit_max_scale keeps the analytic-edge accuracy ------------------------------------------------

@pytest.mark.parametrize("sigma", [1.0, 3.0, 6.0])
def test_robust_model_fit_on_step_edges(sigma):
    errs, used_s2, detector_s2 = [], [], []
    for i, a in enumerate(math.radians(x) for x in (0, 33, 71, 128)):
        sc = step_edge((80, 80), sigma=sigma, angle=a, offset=0.21, noise_std=1.0 / 255, quantize_bits=8,
                       rng=100 + i)
        em = detect_edges(sc.image)
        inner = np.zeros(sc.image.shape, dtype=bool)
        inner[12:-12, 12:-12] = True
        sel = em.edges & inner & (np.abs(sc.edge_distance) < 1.5)
        est = estimate_blur(sc.image, em, params=ROBUST)
        errs.append(est[sel] - sigma)
        detector_s2.append(em.sigma2[sel])
        used_s2.append(model_fit_diagnostics(sc.image, em, params=ROBUST)["sigma2"][sel])
    e = np.concatenate(errs)
    assert e.size > 100
    assert np.mean(np.isnan(e)) <= 0.05  # the rules reject (almost) nothing on clean edges
    med = float(np.median(np.abs(e[np.isfinite(e)])))
    print(f"\nσ = {sigma}: robust model fit median |error| {med:.4f} px, "
          f"σ2 used {np.unique(np.concatenate(used_s2))}")
    assert med <= ROBUST_FIT_STEP_RTOL * sigma
    assert np.all(np.concatenate(used_s2) <= ROBUST.fit_max_scale)
    if sigma == 6.0:  # here the detector's σ2 (4 px) is above fit_max_scale: the switch acts
        assert np.all(np.concatenate(detector_s2) > ROBUST.fit_max_scale)


# --- the coarse-scale caps drop only the edges found at σ1 > 16 or σ2 > 8 ------------------------

@pytest.mark.parametrize("sigma, contrast, dropped", [(3.0, 0.6, False), (8.0, 0.6, False), (8.0, 0.08, True)])
def test_scale_caps_drop_only_the_coarse_scale_edges(sigma, contrast, dropped):
    """Robust's detector (σ1 ≤ 16, σ2 ≤ 8 px) finds exactly the paper detector's edges whose minimum
    reliable scales are within the caps, with the same θ and σ2 there, and none of the others."""
    sc = step_edge((128, 128), sigma=sigma, angle=0.4, low=0.5 - contrast / 2, high=0.5 + contrast / 2,
                   noise_std=2.0 / 255, quantize_bits=8, rng=7)
    full = detect_edges(sc.image, sigma1_scales=PAPER.sigma1_scales, sigma2_scales=PAPER.sigma2_scales)
    capped = detect_edges(sc.image, sigma1_scales=ROBUST.sigma1_scales, sigma2_scales=ROBUST.sigma2_scales)
    within = full.edges & (full.sigma2 <= max(ROBUST.sigma2_scales)) & (full.sigma1 <= max(ROBUST.sigma1_scales))
    np.testing.assert_array_equal(capped.edges, within)
    np.testing.assert_array_equal(capped.sigma2[within], full.sigma2[within])
    np.testing.assert_allclose(capped.theta[within], full.theta[within], rtol=0, atol=1e-6)
    # a high-contrast σ 8 step is reliable by σ2 = 8 (kept whole); a faint one only at σ2 16–32 (all dropped)
    assert (full.edges & ~within).sum() > 50 if dropped else (capped.edges.sum() > 100 and np.array_equal(capped.edges, full.edges))
