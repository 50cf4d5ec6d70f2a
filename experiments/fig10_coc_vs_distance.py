"""Fig. 10: circle-of-confusion diameter vs object distance (Appendix A, Eq. 5).

Curves: Eq. (5) for N ∈ {2, 4, 8}, D = 200 cm, f = 8.5 cm, S ∈ [100, 300] cm (the paper's values).
Points: the same camera rendered by Mitsuba (a geometric step edge at each distance, see
:mod:`scenes.calibration`); the fitted disk diameter in pixels is converted to centimetres on the
sensor with the pixel pitch (sensor width / film width).

Notes
-----
1. Evaluate Eq. (5) on a dense grid of S for each N (curves).
2. For each N and each measured S, render the step edge with the thin-lens camera
   (``canon_1d_mark_ii`` sensor, 28.7 mm, by default — the paper's camera with an 85 mm lens),
   fit the exact disk ⊗ box edge profile, and convert c_px → c_cm = c_px · pitch.
3. Metrics: relative error of every measured point vs Eq. (5); the maximum is the headline.
4. On the procedural test split (``scene_sets``): per held-out scene its own camera (one of the paper's,
   focused at the scene's drawn distance, f/``procedural_f_number``, film ``width_px`` wide) and its own
   depths (the first ``procedural_points`` surfaces whose CoC on that film lies in
   [``procedural_min_coc_px``, ``crop_width`` − 40] px), measured and scored the same way: Eq. (5) with
   cameras and distances nobody chose for it.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "Fig10Config", "camera", "cases", "compute_case", "edge_renderer", "procedural_depths"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig10Config:
    """Every parameter of Fig. 10."""

    focal_length_cm: float = 8.5
    # f, centimetres (paper, Appendix A).
    focus_distance_cm: float = 200.0
    # D, centimetres (paper).
    f_numbers: tuple[float, ...] = (2.0, 4.0, 8.0)
    # N, dimensionless (paper's three curves).
    curve_range_cm: tuple[float, float] = (100.0, 300.0)
    # S range of the Eq. (5) curves, centimetres (paper's x axis).
    curve_points: int = 401
    # number of S samples per curve.
    measured_distances_cm: tuple[float, ...] = (100.0, 125.0, 150.0, 175.0, 190.0, 210.0, 225.0, 250.0,
                                                275.0, 300.0)
    # S of the rendered points, centimetres (S = D has c = 0 and is skipped by construction).
    sensor: str = "canon_1d_mark_ii"
    # key of scenes.camera.SENSORS; sets the pixel pitch only (c in cm does not depend on it).
    width_px: int = 4096
    # film width, px; pitch = sensor width / width_px (7.0 µm for 28.7 mm), so c spans 3.5–270 px.
    crop_width: int = 320
    # rendered crop around the edge, px; must exceed the largest c (≈ 269 px at f/2, 100 cm) + 16.
    rows: int = 8
    # film height, px (averaged into one profile).
    spp: int = 4096
    # samples per pixel.
    seed: int = 0
    # sampler seed.
    scene_sets: tuple = (("procedural_test", ("procedural_100000", "procedural_100001", "procedural_100002",
                                              "procedural_100003")),)
    # held-out scenes whose camera and depths are measured too (experiments.scene_sets); () for none.
    procedural_f_number: float = 4.0
    # N of the procedural scenes' cameras.
    procedural_points: int = 4
    # at most this many depths per procedural scene.
    procedural_min_coc_px: float = 3.0
    # smallest CoC on the film measured, px (the disk fit needs a few pixels of blur).


FULL = Fig10Config()
QUICK = Fig10Config(measured_distances_cm=(100.0, 150.0, 250.0, 300.0), spp=1024, curve_points=201,
                    scene_sets=(("procedural_test", ("procedural_100000", "procedural_100001")),))


def camera(config: Fig10Config, f_number: float):
    """The thin-lens camera of the rendered points at ``f_number`` (film ``width_px`` × ``rows``).

    Parameters
    ----------
    config : Fig10Config
    f_number : float
        N, dimensionless.

    Returns
    -------
    scenes.camera.ThinLensCamera
    """
    from scenes.camera import SENSORS, ThinLensCamera

    sensor = SENSORS[config.sensor]
    return ThinLensCamera(sensor_width_mm=sensor.width_mm, sensor_height_mm=sensor.height_mm,
                          focal_length_mm=config.focal_length_cm * 10.0, f_number=float(f_number),
                          focus_distance_m=config.focus_distance_cm / 100.0,
                          resolution=(config.width_px, config.rows))


def edge_renderer(config: Fig10Config):
    """The step-edge renderer of the measured points (:class:`scenes.calibration.StepEdgeRenderer`)."""
    from scenes.calibration import StepEdgeRenderer

    return StepEdgeRenderer(spp=config.spp, rows=config.rows, crop_width=config.crop_width, seed=config.seed)


def _paper_case(config: Fig10Config) -> dict:
    """Eq. (5) curves and rendered points of Fig. 10.

    Parameters
    ----------
    config : Fig10Config

    Returns
    -------
    dict
        ``f_numbers`` (k,), ``curve_s_cm`` (n,), ``curve_c_cm`` (k, n) — Eq. (5), cm;
        ``points_s_cm`` (m,), ``points_c_cm`` (k, m) — measured, cm; ``points_eq5_cm`` (k, m);
        ``points_c_px`` / ``points_eq5_px`` (k, m); ``points_rel_err`` (k, m);
        ``points_edge_offset_px`` (k, m): fitted edge − optical axis, px;
        ``points_sigma_2nd_px`` (k, m): second-moment σ of the edge's line spread, px;
        ``metrics``: ``max_rel_err``, ``rms_rel_err``, per-N maxima, pixel pitch, timings.
    """
    from scenes.calibration import measure_edge_grid
    from scenes.thin_lens import circle_of_confusion

    t0 = time.perf_counter()
    f_m, d_m = config.focal_length_cm / 100.0, config.focus_distance_cm / 100.0
    s_curve = np.linspace(*config.curve_range_cm, config.curve_points)
    ns = np.asarray(config.f_numbers, dtype=np.float64)
    curves = np.stack([
        circle_of_confusion(s_curve / 100.0, focal_length=f_m, f_number=float(n), focus_distance=d_m) * 100.0
        for n in ns
    ])
    renderer = edge_renderer(config)
    s_pts = np.asarray(config.measured_distances_cm, dtype=np.float64)
    cameras = [camera(config, n) for n in ns]
    pitch_cm = cameras[-1].pixel_pitch_m * 100.0
    grid = measure_edge_grid(renderer, cameras, s_pts / 100.0, label=config.sensor)
    c_px, eq5_px = grid["coc_fit_px"], grid["coc_eq5_px"]
    rel = c_px / eq5_px - 1.0
    metrics = {
        "max_rel_err": float(np.nanmax(np.abs(rel))),
        "rms_rel_err": float(np.sqrt(np.nanmean(rel**2))),
        "max_rel_err_by_f_number": {f"N={n:g}": float(np.nanmax(np.abs(r))) for n, r in zip(ns, rel)},
        "n_points": int(np.isfinite(rel).sum()),
        "pixel_pitch_um": pitch_cm * 1e4,
        "coc_px_range": [float(np.nanmin(eq5_px)), float(np.nanmax(eq5_px))],
    }
    info = {"render_seconds": renderer.render_seconds, "compute_seconds": time.perf_counter() - t0,
            "variant": renderer.variant, "measurement": _MEASUREMENT, **metrics}
    return {"metrics": metrics, "info": info, "arrays": {
        "f_numbers": ns,
        "curve_s_cm": s_curve,
        "curve_c_cm": curves,
        "points_s_cm": s_pts,
        "points_c_cm": c_px * pitch_cm,
        "points_eq5_cm": eq5_px * pitch_cm,
        "points_c_px": c_px,
        "points_eq5_px": eq5_px,
        "points_rel_err": rel,
        "points_edge_offset_px": grid["edge_offset_px"],
        "points_sigma_2nd_px": grid["sigma_2nd_px"],
    }}


_MEASUREMENT = ("disk (diameter c) convolved with the box pixel footprint, least-squares fit to a rendered step edge; "
                "c_cm = c_px * pixel pitch")


def procedural_depths(config: Fig10Config, scene: str) -> tuple:
    """(camera, depths in m) of a procedural scene: its camera on a ``width_px`` × ``rows`` film at
    f/``procedural_f_number``, and the depths of its first ``procedural_points`` surfaces (objects, then the
    background) whose CoC on that film lies in [``procedural_min_coc_px``, ``crop_width`` − 40] px."""
    from scenes.library.procedural import draw_layout, procedural_scene, seed_of
    from scenes.thin_lens import circle_of_confusion

    seed, _ = seed_of(scene)
    cam = procedural_scene(seed).camera("full", f_number=config.procedural_f_number,
                                        resolution=(config.width_px, config.rows))
    layout = draw_layout(seed)
    depths = []
    for z in [o["depth_m"] for o in layout["objects"]] + [layout["background"]["depth_m"]]:
        c = circle_of_confusion(z, focal_length=cam.focal_length_m, f_number=cam.f_number,
                                focus_distance=cam.focus_distance_m) / cam.pixel_pitch_m
        if config.procedural_min_coc_px <= c <= config.crop_width - 40 and len(depths) < config.procedural_points:
            depths.append(float(z))
    return cam, tuple(depths)


def _procedural_case(config: Fig10Config, case) -> dict:
    from scenes.calibration import measure_edge_grid

    cam, depths = procedural_depths(config, case.scene)
    if not depths:
        raise ValueError(f"{case.scene}: no surface with a measurable CoC; allowed: scenes with a depth whose CoC "
                         f"is in [{config.procedural_min_coc_px}, {config.crop_width - 40}] px")
    renderer = edge_renderer(config)
    grid = measure_edge_grid(renderer, [cam], np.asarray(depths), label=case.scene)
    c_px, eq5_px = grid["coc_fit_px"][0], grid["coc_eq5_px"][0]
    rel = c_px / eq5_px - 1.0
    metrics = {"max_rel_err": float(np.nanmax(np.abs(rel))), "rms_rel_err": float(np.sqrt(np.nanmean(rel**2))),
               "n_points": int(np.isfinite(rel).sum()), "pixel_pitch_um": cam.pixel_pitch_m * 1e6,
               "focal_length_mm": cam.focal_length_m * 1e3, "focus_distance_m": cam.focus_distance_m,
               "coc_px_range": [float(np.nanmin(eq5_px)), float(np.nanmax(eq5_px))]}
    return {"metrics": metrics, "info": {"variant": renderer.variant, "measurement": _MEASUREMENT},
            "arrays": {"depths_m": np.asarray(depths), "coc_fit_px": c_px, "coc_eq5_px": eq5_px, "rel_err": rel}}


def cases(config: Fig10Config) -> tuple:
    """The paper's camera at the config's distances (``variant="paper"``) and each procedural scene's camera
    at its own depths (one case per scene of ``scene_sets``)."""
    from .cases import Case
    from .scene_sets import set_scene_pairs

    return (Case("fig10", variant="paper"),
            *(Case("fig10", scene_set=s, scene=n, aperture=float(config.procedural_f_number))
              for s, n in set_scene_pairs(config)))


def compute_case(config: Fig10Config, case, inputs) -> dict:
    """One case of :func:`cases`: curves and points of the paper's camera (arrays ``f_numbers`` (k,),
    ``curve_s_cm`` (n,), ``curve_c_cm`` (k, n) — Eq. (5), cm; ``points_s_cm`` (m,), ``points_c_cm`` (k, m),
    ``points_eq5_cm``, ``points_c_px`` / ``points_eq5_px``, ``points_rel_err``, ``points_edge_offset_px``,
    ``points_sigma_2nd_px`` (k, m)), or one procedural scene's points (``depths_m``, ``coc_fit_px``,
    ``coc_eq5_px``, ``rel_err``); metrics ``max_rel_err``, ``rms_rel_err``, ``n_points`` and the camera's."""
    return _paper_case(config) if case.variant == "paper" else _procedural_case(config, case)


FIGURE = Figure(
    name="fig10",
    title="CoC diameter vs object distance (Eq. 5) with Mitsuba-measured points",
    plot="experiments.plotting.fig10:plot",
    configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=4,
    sigma_convention="none: the figure reports the CoC diameter c itself (disk fit), not a Gaussian sigma",
)
