"""Calibration (issue part 7): Mitsuba's thin-lens blur equals Eq. (5); sensor ratios equal Eq. (6).

Renders a geometric step edge for 2 sensors (same field of view) × f/4, f/8 × 4 distances and
fits the exact disk ⊗ box edge profile. Run with ``pytest -s`` to see the measured table; it is
also written to ``<cache>/calibration/calibration.{json,txt}``.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests import tolerances as tol



# --- model and fitters (no rendering) -----------------------------------------------------------
def test_disk_profile_limits_and_slope():
    from scenes.calibration import disk_edge_profile

    x = np.arange(200) + 0.5
    p = disk_edge_profile(x, edge_px=100.0, coc_px=20.0)
    assert p[0] == 0 and p[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(p) >= -1e-15)
    # symmetric about the edge: p(x0 + u) + p(x0 − u) = 1
    np.testing.assert_allclose(p[100:] + p[:100][::-1], 1.0, atol=1e-12)
    # the centre slope of a disk ESF is 2/(π r) per px (LSF peak = 2·chord/(π r²) at r)
    r = 10.0
    slope = (disk_edge_profile(np.array([100.5]), edge_px=100.0, coc_px=20.0)
             - disk_edge_profile(np.array([99.5]), edge_px=100.0, coc_px=20.0))[0]
    assert slope == pytest.approx(2.0 / (np.pi * r), rel=2e-3)
    # c → 0: a box-averaged step (linear ramp across one pixel)
    q = disk_edge_profile(np.array([99.75, 100.0, 100.25]), edge_px=100.0, coc_px=0.0)
    np.testing.assert_allclose(q, [0.25, 0.5, 0.75], atol=1e-9)


def test_disk_profile_matches_brute_force():
    from scenes.calibration import disk_edge_profile

    # Brute force: fraction of a disk's area on the bright side, averaged over a pixel.
    c, x0 = 7.3, 20.2
    rng = np.random.default_rng(1)
    u = rng.uniform(-1, 1, (400_000, 2))
    u = u[(u**2).sum(1) <= 1] * c / 2
    for xc in (16.5, 18.5, 20.5, 22.5):
        shifts = rng.uniform(-0.5, 0.5, len(u))
        want = np.mean(xc + shifts + u[:, 0] > x0)
        got = disk_edge_profile(np.array([xc]), edge_px=x0, coc_px=c)[0]
        assert got == pytest.approx(want, abs=3e-3)


@pytest.mark.parametrize("c", [1.0, 3.0, 12.5, 60.0])
def test_fitters_recover_synthetic_edges(c, rng):
    from scenes.calibration import disk_edge_profile, fit_disk_edge, fit_erf_edge, second_moment_sigma
    from scenes.thin_lens import coc_to_sigma

    x = np.arange(256) + 0.5
    p = 0.9 - 0.8 * disk_edge_profile(x, edge_px=128.3, coc_px=c) + rng.normal(0, 1e-4, x.size)
    fit = fit_disk_edge(p)
    assert fit["coc_px"] == pytest.approx(c, rel=2e-3)
    assert fit["edge_px"] == pytest.approx(128.3, abs=2e-3)
    s2 = second_moment_sigma(p, edge_px=fit["edge_px"], half_window_px=c / 2 + 4)
    if c >= 3:  # a ~1-px LSF is too narrow for a moment of unit-spaced samples
        assert s2 == pytest.approx(float(coc_to_sigma(c)), rel=0.02)
    if c >= 12:
        # an erf fit of a disk edge gives ≈ 0.273·c (plus the pixel footprint in quadrature)
        s_erf = fit_erf_edge(p)["sigma_px"]
        assert s_erf == pytest.approx(float(coc_to_sigma(c, convention="erf_fit")), rel=0.02)


def test_bad_inputs_raise():
    from scenes.calibration import StepEdgeRenderer, disk_edge_profile, fit_disk_edge

    with pytest.raises(ValueError, match="coc_px"):
        disk_edge_profile(np.arange(4.0), edge_px=1.0, coc_px=-1.0)
    with pytest.raises(ValueError, match="profile"):
        fit_disk_edge(np.ones((3, 3)))
    with pytest.raises(ValueError, match="crop_width"):
        StepEdgeRenderer(crop_width=15)


# --- the rendered calibration ------------------------------------------------------------------
@pytest.fixture(scope="module")
def calibration():
    """Render the 16 cases once per test module; return rows, ratios and the wall time."""
    from scenes.calibration import (
        CALIBRATION_DEFAULTS, format_table, run_calibration, sensor_ratio_table, write_calibration_log,
    )

    t0 = time.perf_counter()
    rows = run_calibration(CALIBRATION_DEFAULTS)
    ratios = sensor_ratio_table(rows)
    elapsed = time.perf_counter() - t0
    print("\n" + format_table(rows, ratios))
    print(f"calibration: {len(rows)} cases in {elapsed:.1f} s")
    import dataclasses

    path = write_calibration_log(rows, ratios, extra={
        "seconds": elapsed, "config": dataclasses.asdict(CALIBRATION_DEFAULTS)})
    print(f"written: {path}")
    return {"rows": rows, "ratios": ratios, "seconds": elapsed}


@pytest.mark.render
def test_sixteen_cases_span_both_sides_of_focus(calibration):
    rows = calibration["rows"]
    assert len(rows) == 16
    assert {r["label"] for r in rows} == {"full_frame", "canon_powershot_a80"}
    assert {r["f_number"] for r in rows} == {4.0, 8.0}
    near = [r for r in rows if r["depth_m"] < r["focus_distance_m"]]
    far = [r for r in rows if r["depth_m"] > r["focus_distance_m"]]
    assert len({r["depth_m"] for r in near}) >= 2 and len({r["depth_m"] for r in far}) >= 2
    assert sum(r["coc_eq5_px"] >= tol.CALIB_MIN_COC_PX for r in rows) >= 8


@pytest.mark.render
def test_fitted_coc_matches_eq5(calibration):
    bad = [
        (r["label"], r["f_number"], r["depth_m"], round(r["coc_eq5_px"], 3), round(r["coc_fit_px"], 3))
        for r in calibration["rows"]
        if r["coc_eq5_px"] >= tol.CALIB_MIN_COC_PX and abs(r["rel_err"]) > tol.CALIB_COC_RTOL
    ]
    assert not bad, f"rendered blur differs from Eq. (5) by > {tol.CALIB_COC_RTOL:.0%}: {bad}"


@pytest.mark.render
def test_edge_on_optical_axis(calibration):
    for r in calibration["rows"]:
        assert abs(r["edge_offset_px"]) <= tol.CALIB_EDGE_POSITION_PX, r


@pytest.mark.render
def test_second_moment_sigma_is_c_over_4(calibration):
    for r in calibration["rows"]:
        if r["coc_eq5_px"] >= 4.0:
            assert r["sigma_2nd_px"] == pytest.approx(r["sigma_2nd_pred_px"], rel=tol.CALIB_SIGMA_2ND_RTOL), r


@pytest.mark.render
def test_sensor_ratio_matches_eq6(calibration):
    ratios = calibration["ratios"]
    assert len(ratios) == 8
    checked = [q for q in ratios if q["min_coc_px"] >= tol.CALIB_MIN_COC_PX]
    assert len(checked) >= 4
    for q in checked:
        assert q["ratio_measured"] == pytest.approx(q["ratio_eq6"], rel=tol.CALIB_RATIO_RTOL), q
    # to first order the ratio is the sensor-width ratio (Eq. 6): ~5× here
    assert 4.5 < np.median([q["ratio_measured"] for q in checked]) < 5.8


@pytest.mark.render
def test_naive_fov_mapping_fails_and_project_mapping_passes(calibration):
    """fov = 2·atan(W/2f) renders the blur (D − f)/D too small; the project's v-based mapping does not."""
    from scenes.calibration import CALIBRATION_DEFAULTS, calibration_cases, default_renderer, measure_edge

    cfg = CALIBRATION_DEFAULTS
    renderer = default_renderer(spp=cfg.spp, rows=cfg.rows, crop_width=cfg.crop_width, seed=cfg.seed)
    cases = [(lab, cam, s) for lab, cam, s in calibration_cases(cfg)
             if lab == "full_frame" and cam.f_number == 4.0 and s in (0.45, 5.0)]
    assert len(cases) == 2
    for label, cam, s in cases:
        naive = measure_edge(renderer, cam, s, fov_mapping="naive", label=label)
        proper = measure_edge(renderer, cam, s, fov_mapping="thin_lens", label=label)
        factor = (cam.focus_distance_m - cam.focal_length_m) / cam.focus_distance_m  # 0.95
        print(f"S={s} m: Eq.5 {proper['coc_eq5_px']:.3f} px, thin_lens fov {proper['coc_fit_px']:.3f} px, "
              f"naive fov {naive['coc_fit_px']:.3f} px (ratio {naive['coc_fit_px'] / proper['coc_eq5_px']:.4f}, "
              f"(D-f)/D = {factor:.4f})")
        assert abs(proper["rel_err"]) <= tol.CALIB_COC_RTOL
        assert abs(naive["rel_err"]) > tol.CALIB_COC_RTOL
        assert naive["coc_fit_px"] / naive["coc_eq5_px"] == pytest.approx(factor, rel=tol.CALIB_NAIVE_FACTOR_RTOL)

