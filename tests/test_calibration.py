"""Calibration: Mitsuba's thin-lens blur equals Eq. (5); sensor ratios equal Eq. (6).

The rendered checks read the figures' own data (the quick configs through the figure cache, shared
with the claims golden): fig10's step edges (one sensor, f/2, f/4, f/8, both sides of focus) against
Eq. (5), fig2's step edges (two sensors at the same field of view) against Eq. (6). The model and
the fitters are checked on synthetic profiles. Run with ``pytest -s`` to see the measured table.
"""

from __future__ import annotations

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


# --- the rendered calibration: fig10 (Eq. 5) and fig2 (Eq. 6) data ---------------------------------
#: Figure mode whose data the rendered checks read.
MODE = "quick"


def _figure_config(name):
    from experiments.registry import FIGURES

    return FIGURES[name].config(MODE)


def _figure_data(name):
    """The quick arrays and metrics of fig10's paper-camera case or of fig2's one case."""
    from tests.golden import quick_data

    fd = quick_data(name)
    if name == "fig10":
        out = fd.one(variant="paper")
        return {**out.arrays(), "metrics": out.info}
    return fd.single()


@pytest.fixture(scope="module")
def fig10():
    """fig10's data with one row per rendered point (sensor, N, S, Eq. 5 c, fitted c, σ, edge)."""
    from scenes.thin_lens import coc_to_sigma

    data = _figure_data("fig10")
    cfg = _figure_config("fig10")
    rows = []
    for i, n in enumerate(data["f_numbers"]):
        for j, s_cm in enumerate(data["points_s_cm"]):
            eq5 = float(data["points_eq5_px"][i, j])
            rows.append({
                "f_number": float(n), "depth_m": float(s_cm) / 100.0,
                "focus_distance_m": cfg.focus_distance_cm / 100.0, "coc_eq5_px": eq5,
                "coc_fit_px": float(data["points_c_px"][i, j]), "rel_err": float(data["points_rel_err"][i, j]),
                "sigma_2nd_px": float(data["points_sigma_2nd_px"][i, j]),
                "sigma_2nd_pred_px": float(coc_to_sigma(eq5, convention="line_spread")),
                "edge_offset_px": float(data["points_edge_offset_px"][i, j]),
            })
    print(f"\nfig10 ({MODE}, {cfg.sensor}, {cfg.spp} spp):")
    print(f"{'N':>3} {'S/m':>5} {'c_eq5':>8} {'c_fit':>8} {'err%':>6} {'σ2nd':>6} {'pred':>6} {'edge':>6}")
    for r in rows:
        print(f"{r['f_number']:3.0f} {r['depth_m']:5.2f} {r['coc_eq5_px']:8.3f} {r['coc_fit_px']:8.3f} "
              f"{100 * r['rel_err']:+6.2f} {r['sigma_2nd_px']:6.2f} {r['sigma_2nd_pred_px']:6.2f} "
              f"{r['edge_offset_px']:+6.3f}")
    return {"rows": rows, "data": data, "config": cfg}


@pytest.fixture(scope="module")
def fig2():
    """fig2's step-edge pairs (large / small sensor at equal S, N and field of view)."""
    data = _figure_data("fig2")
    pairs = [{"depth_m": float(s), "ratio_measured": float(m), "ratio_eq6": float(p),
              "min_coc_px": float(min(el, es)), "coc_fit_px": (float(cl), float(cs)), "coc_eq5_px": (float(el), float(es))}
             for s, m, p, cl, cs, el, es in zip(data["edge_depth_m"], data["edge_ratio"], data["edge_ratio_eq6"],
                                                data["edge_coc_px_large"], data["edge_coc_px_small"],
                                                data["edge_eq5_px_large"], data["edge_eq5_px_small"])]
    print(f"\nfig2 ({MODE}): {'S/m':>5} {'measured':>9} {'Eq.6':>8} {'err%':>6}")
    for q in pairs:
        print(f"{'':12}{q['depth_m']:5.2f} {q['ratio_measured']:9.4f} {q['ratio_eq6']:8.4f} "
              f"{100 * (q['ratio_measured'] / q['ratio_eq6'] - 1):+6.2f}")
    return {"pairs": pairs, "metrics": data["metrics"], "config": _figure_config("fig2")}


@pytest.mark.render
def test_cases_span_both_sides_of_focus(fig10, fig2):
    rows = fig10["rows"]
    assert {r["f_number"] for r in rows} == {2.0, 4.0, 8.0}
    near = [r for r in rows if r["depth_m"] < r["focus_distance_m"]]
    far = [r for r in rows if r["depth_m"] > r["focus_distance_m"]]
    assert len({r["depth_m"] for r in near}) >= 2 and len({r["depth_m"] for r in far}) >= 2
    assert sum(r["coc_eq5_px"] >= tol.CALIB_MIN_COC_PX for r in rows) >= 8
    focus = fig2["metrics"]["focus_distance_m"]
    depths = [q["depth_m"] for q in fig2["pairs"]]
    assert min(depths) < focus < max(depths)
    assert len(set(fig2["config"].sensors)) == 2


@pytest.mark.render
def test_fitted_coc_matches_eq5(fig10, fig2):
    cases = [(f"f/{r['f_number']:g}", r["depth_m"], r["coc_eq5_px"], r["coc_fit_px"]) for r in fig10["rows"]]
    for q in fig2["pairs"]:
        for sensor, eq5, fit in zip(fig2["config"].sensors, q["coc_eq5_px"], q["coc_fit_px"]):
            cases.append((sensor, q["depth_m"], eq5, fit))
    bad = [(label, s, round(eq5, 3), round(fit, 3)) for label, s, eq5, fit in cases
           if eq5 >= tol.CALIB_MIN_COC_PX and abs(fit / eq5 - 1.0) > tol.CALIB_COC_RTOL]
    assert not bad, f"rendered blur differs from Eq. (5) by > {tol.CALIB_COC_RTOL:.0%}: {bad}"


@pytest.mark.render
def test_edge_on_optical_axis(fig10):
    for r in fig10["rows"]:
        assert abs(r["edge_offset_px"]) <= tol.CALIB_EDGE_POSITION_PX, r


@pytest.mark.render
def test_second_moment_sigma_is_c_over_4(fig10):
    checked = [r for r in fig10["rows"] if r["coc_eq5_px"] >= 4.0]
    assert checked
    for r in checked:
        assert r["sigma_2nd_px"] == pytest.approx(r["sigma_2nd_pred_px"], rel=tol.CALIB_SIGMA_2ND_RTOL), r


@pytest.mark.render
def test_sensor_ratio_matches_eq6(fig2):
    pairs = fig2["pairs"]
    assert len(pairs) == len(fig2["config"].edge_depth_factors)
    checked = [q for q in pairs if q["min_coc_px"] >= tol.CALIB_MIN_COC_PX]
    assert len(checked) >= 2
    for q in checked:
        assert q["ratio_measured"] == pytest.approx(q["ratio_eq6"], rel=tol.CALIB_RATIO_RTOL), q
    # to first order the ratio is the sensor-width ratio X_L / X_S (Eq. 6): within −10 % / +16 %
    # (the band 4.5-5.8 around 36 / 7.18 mm = 5.01 for full frame vs the PowerShot A80)
    width_ratio = fig2["metrics"]["sensor_width_ratio"]
    median = float(np.median([q["ratio_measured"] for q in checked]))
    assert 4.5 / 5.014 < median / width_ratio < 5.8 / 5.014, (median, width_ratio)


@pytest.mark.render
def test_naive_fov_mapping_fails_and_project_mapping_passes(fig10):
    """fov = 2·atan(W/2f) renders the blur (D − f)/D too small; the project's v-based mapping does not."""
    from experiments.fig10_coc_vs_distance import camera, edge_renderer
    from scenes.calibration import measure_edge

    cfg = fig10["config"]
    cam = camera(cfg, 4.0)
    renderer = edge_renderer(cfg)
    proper_rows = {r["depth_m"]: r for r in fig10["rows"] if r["f_number"] == 4.0}
    depths = (min(proper_rows), max(proper_rows))  # both sides of focus
    assert depths[0] < cam.focus_distance_m < depths[1]
    factor = (cam.focus_distance_m - cam.focal_length_m) / cam.focus_distance_m  # 0.9575
    for s in depths:
        naive = measure_edge(renderer, cam, s, fov_mapping="naive", label=cfg.sensor)
        proper = proper_rows[s]
        print(f"S={s} m: Eq.5 {proper['coc_eq5_px']:.3f} px, thin_lens fov {proper['coc_fit_px']:.3f} px, "
              f"naive fov {naive['coc_fit_px']:.3f} px (ratio {naive['coc_fit_px'] / proper['coc_eq5_px']:.4f}, "
              f"(D-f)/D = {factor:.4f})")
        assert naive["coc_eq5_px"] == pytest.approx(proper["coc_eq5_px"], rel=1e-12)
        assert abs(proper["rel_err"]) <= tol.CALIB_COC_RTOL
        assert abs(naive["rel_err"]) > tol.CALIB_COC_RTOL
        assert naive["coc_fit_px"] / naive["coc_eq5_px"] == pytest.approx(factor, rel=tol.CALIB_NAIVE_FACTOR_RTOL)
