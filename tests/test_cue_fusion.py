"""Fusion of edge and region blur measures in Eq. (4) (method.propagation.cue_fusion, method.pipeline).

* inverse-variance fusion: analytic cases of :func:`fuse_measures` and of the region weights;
* a wide smooth ramp (in-focus soft shading) beside sharp edges of the same surface cannot out-vote
  them once the blur-island factor is on, and does without it (both sides);
* oracle region measures (σ_gt + noise, constant information) on a blurry texture mosaic lower the
  dense error of the edge-only map;
* with both new cues off, paper's and robust's maps equal those of the code before the fusion (arrays
  stored from it, tests/references/cue_fusion_off.npz, compared at the paper golden's measured
  cross-CPU tolerance; on the machine that stored them they were bit-identical).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from method import DefocusParams, estimate_defocus_map
from method.propagation.cue_fusion import ERROR_FLOOR_PX, blur_islands, fuse_measures, region_data_term
from method.pipeline import STAGES, luminance, propagate_stage

REFERENCE = Path(__file__).parent / "references" / "cue_fusion_off.npz"
#: Cross-CPU tolerance of stored σ maps, px: the paper golden's (tests/golden/paper_astronaut_tolerance.json,
#: 10 × the largest deviation over numba/OpenBLAS/numpy-SIMD/thread configurations).
ATOL_PX = 1.6e-7
#: The region estimator's grid these unit tests place measures on: stride 16 px (the blocks of the
#: 16×16 example below), windows clip(12·σ, 16, 96) px.
GRID = {"stride": 16, "window": (12.0, 16, 96)}
_FIELDS = ("edges", "sparse_sigma", "refined_sigma", "defocus_map", "measure_confidence")


# --- inverse-variance fusion, analytic ------------------------------------------------------------
def test_two_terms_become_their_weighted_mean_with_summed_weight():
    e = np.array([[2.0, np.nan, 1.0]])
    we = np.array([[1.0, np.nan, 0.5]])
    r = np.array([[4.0, 3.0, np.nan]])
    wr = np.array([[3.0, 2.0, 0.0]])
    s, w = fuse_measures(e, we, r, wr)
    np.testing.assert_allclose(s, [[(2 + 12) / 4.0, 3.0, 1.0]])
    np.testing.assert_allclose(w, [[4.0, 2.0, 0.5]])
    # the quadratic identity the swap relies on: same minimiser, same curvature
    b = np.linspace(0, 6, 61)
    two = 1.0 * (b - 2.0) ** 2 + 3.0 * (b - 4.0) ** 2
    one = 4.0 * (b - s[0, 0]) ** 2
    np.testing.assert_allclose(two - one, (two - one)[0], atol=1e-12)


def test_no_term_stays_nan_and_edge_only_pixels_are_unchanged():
    e = np.array([[np.nan, 1.5]])
    s, w = fuse_measures(e, None, np.full((1, 2), np.nan), np.zeros((1, 2)))
    assert np.isnan(s[0, 0]) and np.isnan(w[0, 0])
    assert s[0, 1] == 1.5 and w[0, 1] == 1.0


def test_region_weight_is_relative_inverse_variance():
    sig = np.array([[2.0, 4.0]])
    info = np.array([[1.0 / 0.04, np.inf]])  # variance 0.04 px², then exact
    s, w = region_data_term(sig, info, edge_error_rel=0.5, region_error_rel=0.25, region_weight=2.0,
                            placement="blocks", **GRID)
    d2 = ERROR_FLOOR_PX ** 2
    v_r = np.array([0.04 + (0.25 * 2) ** 2 + d2, (0.25 * 4) ** 2 + d2])
    v_e = (0.5 * sig[0] + ERROR_FLOOR_PX) ** 2
    np.testing.assert_allclose(w[0], 2.0 * v_e / v_r)
    np.testing.assert_array_equal(s, sig)
    # more information → more weight; no information → no term
    _, w_lo = region_data_term(sig, info / 100, edge_error_rel=0.5, region_error_rel=0.25, region_weight=2.0,
                               placement="blocks", **GRID)
    assert w_lo[0, 0] < w[0, 0] / 2.0 and w_lo[0, 1] == w[0, 1]
    s0, w0 = region_data_term(sig, np.zeros_like(sig), placement="blocks", **GRID)
    assert np.all(np.isnan(s0)) and np.all(w0 == 0)


def test_block_placement_spreads_a_measure_and_shares_its_weight():
    sig = np.full((16, 16), np.nan)
    info = np.zeros((16, 16))
    sig[4::8, 4::8] = [[1.0, 2.0], [3.0, 4.0]]
    info[4::8, 4::8] = 1e6
    s_c, w_c = region_data_term(sig, info, placement="centres", **GRID)  # sparse input: as given
    s_b, w_b = region_data_term(sig, info, placement="blocks", **GRID)
    assert np.isfinite(s_c).sum() == 4 and np.all(np.isfinite(s_b))
    assert s_b[0, 0] == 1.0 and s_b[15, 15] == 4.0 and s_b[2, 13] == 2.0
    for v in (1.0, 2.0, 3.0, 4.0):  # each measure's total weight is kept
        np.testing.assert_allclose(w_b[s_b == v].sum(), w_c[s_c == v].sum())


def test_bad_options_are_refused_naming_the_allowed_values():
    sig, info = np.ones((4, 4)), np.ones((4, 4))
    with pytest.raises(ValueError, match="allowed"):
        region_data_term(sig, info, placement="everywhere", **GRID)
    with pytest.raises(ValueError, match="allowed"):
        region_data_term(sig, info, island_weight=-0.1, **GRID)
    with pytest.raises(ValueError, match="allowed"):
        DefocusParams(fusion_region_weight=0.0)
    with pytest.raises(ValueError, match="allowed"):
        DefocusParams(fusion_region_placement="nowhere")


# --- a smooth ramp beside sharp edges -------------------------------------------------------------
def _ramp_with_sharp_edges():
    """64×256 grey image, one in-focus surface: a wide smooth ramp (soft shading, no fine detail)
    crossed by three sharp 2-px dark lines. Edge measures σ 0.5 on the lines' edges; a region
    estimator fooled by the ramp reports σ 6 with high information in the blocks between them."""
    h, w = 64, 256
    x = np.arange(w)[None, :] * np.ones((h, 1))
    img = 0.3 + 0.4 * x / w
    lines = (np.abs(x - 64) < 1) | (np.abs(x - 128) < 1) | (np.abs(x - 192) < 1)
    img = np.where(lines, 0.1, img)
    rng = np.random.default_rng(0)
    img = np.clip(img + rng.normal(0, 1 / 255, img.shape), 0, 1)
    edges = np.full((h, w), np.nan)
    for c in (64, 128, 192):
        edges[:, [c - 2, c + 1]] = 0.5
    region = np.full((h, w), np.nan)
    info = np.zeros((h, w))
    cols = [c for c in range(24, 232, 16) if min(abs(c - 64), abs(c - 128), abs(c - 192)) > 12]
    region[8::16, cols] = 6.0  # blocks of ramp only (a window on a line would read it sharp), away
    info[8::16, cols] = 100.0  # from the borders (a filter's edge extension kinks the ramp)
    return img, edges, region, info


@pytest.mark.parametrize("island_weight, ramp_sharp", [(1.0, False), (0.0, True)])
def test_ramp_without_texture_cannot_out_vote_the_sharp_edges(island_weight, ramp_sharp):
    img, edges, region, info = _ramp_with_sharp_edges()
    rgb = np.repeat(img[..., None], 3, axis=2)
    islands = blur_islands(img, noise_std=2.5 / 255, radius=24.0, sigma=region)
    assert islands[np.isfinite(region)].all()
    p = DefocusParams(fusion_region_weight=10.0, fusion_island_weight=island_weight, fusion_island_radius=24.0)
    dense = propagate_stage(edges, rgb, params=p, region_sigma=region, region_information=info)
    ramp = dense[:, 70:186][:, np.abs(np.arange(70, 186) - 128) > 4].mean()  # between the lines
    if ramp_sharp:
        assert ramp < 1.0, ramp  # the sharp edges hold the surface in focus
    else:
        assert ramp > 3.0, ramp  # without the island factor the ramp's blocks out-vote them


def test_blurred_texture_is_not_an_island():
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(sigmas=(5.0,), tile=96, cols=1, noise_std=1 / 255, quantize_bits=8, rng=0)
    gray = luminance(m.image)
    sig = np.full(gray.shape, np.nan)
    sig[8::16, 8::16] = 5.0
    islands = blur_islands(gray, noise_std=2.5 / 255, radius=24.0, sigma=sig)
    assert islands[np.isfinite(sig)].mean() < 0.1, islands[np.isfinite(sig)].mean()


# --- oracle region measures on blurry texture -----------------------------------------------------
def test_oracle_region_measures_lower_the_blurry_texture_error():
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(sigmas=(1.0, 5.0), tile=64, cols=2, noise_std=1 / 255, quantize_bits=8, rng=0)
    robust = DefocusParams.preset("robust")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = estimate_defocus_map(m.image, robust)
    rng = np.random.default_rng(1)
    region = np.full(m.sigma.shape, np.nan)
    region[8::16, 8::16] = m.sigma[8::16, 8::16] * (1 + 0.05 * rng.standard_normal(m.sigma[8::16, 8::16].shape))
    info = np.where(np.isfinite(region), 25.0, 0.0)
    fused = propagate_stage(r.refined_sigma, m.image, params=robust.replace(fusion_region_weight=10.0),
                            sparse_sigma=r.sparse_sigma, confidence=r.measure_confidence,
                            region_sigma=region, region_information=info, gray=luminance(m.image))
    ok = ~m.boundary
    blurry = ok & (m.sigma > 3)
    edge_only = np.mean(np.abs(r.defocus_map[blurry] - m.sigma[blurry]))
    with_region = np.mean(np.abs(fused[blurry] - m.sigma[blurry]))
    # measured: edge-only 0.47 px, with the oracle region terms 0.34 px
    assert with_region < edge_only - 0.08 and with_region < 0.4, (edge_only, with_region)


# --- cues off: bit-identical maps -----------------------------------------------------------------
def _cases():
    import skimage.data
    from scenes.analytic import texture_mosaic

    m = texture_mosaic(sigmas=(0.5, 2.0, 4.0, 6.0), tile=48, cols=4, noise_std=1 / 255, quantize_bits=8, rng=0)
    yield "dead_leaves_48x192", m.image
    yield "astronaut_crop_96", skimage.data.astronaut()[100:196, 150:246].astype(np.float64) / 255.0


def _cues_off_result(img, preset):
    # the edge fit in display light, with the constant noise and no plateau gate, as the reference was
    # stored (robust's linear light, noise model and gate are judged in tests/test_presets.py)
    params = DefocusParams.preset(preset).replace(edge_isolation=None, region_estimator=None, measure_light="display",
                                                  noise_model="constant", fit_step_gate="none")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return estimate_defocus_map(img, params)


def test_cues_off_maps_equal_those_before_the_fusion():
    ref = np.load(REFERENCE)
    for name, img in _cases():
        for preset in ("paper", "robust"):
            r = _cues_off_result(img, preset)
            assert r.region_sigma is None and r.region_information is None
            assert r.timings["region_blur"] == 0.0 and set(STAGES) <= set(r.timings)
            for field in _FIELDS:
                key = f"{name}/{preset}/{field}"
                a = getattr(r, field)
                if key not in ref.files:
                    assert a is None, key
                    continue
                want = ref[key]
                if want.dtype == bool:
                    np.testing.assert_array_equal(a, want, err_msg=key)
                else:
                    np.testing.assert_array_equal(np.isnan(a), np.isnan(want), err_msg=key)
                    np.testing.assert_allclose(a, want, rtol=0, atol=ATOL_PX, equal_nan=True, err_msg=key)


def _store_reference():  # python -c "import tests.test_cue_fusion as t; t._store_reference()"
    from defocus_cache import atomic_write_bytes

    arrays = {}
    for name, img in _cases():
        for preset in ("paper", "robust"):
            r = _cues_off_result(img, preset)
            arrays.update({f"{name}/{preset}/{f}": getattr(r, f) for f in _FIELDS if getattr(r, f) is not None})
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(REFERENCE, buf.getvalue())
