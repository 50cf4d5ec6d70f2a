"""Fig. 2: sensor size — the same scene, field of view and f/2.8 on a 22.2 mm and a 7.18 mm sensor.

Eq. (6): at equal field of view (equal relative focal length f' = f/X) and f-number, the blur as a
fraction of the image width is, to first order, proportional to the sensor width X; the small
sensor's photograph is nearly all in focus.

Notes
-----
1. Render the library's ``portrait`` scene (:func:`scenes.render.render_scene`) with both cameras
   (the scene's default camera moved to each sensor by :func:`scenes.camera.same_field_of_view`,
   f/2.8, same pixel count) — the side-by-side images, with their ground-truth CoC maps (Eq. 5 on
   the rendered camera-space depth).
2. **Measured** CoC ratio: the calibration machinery (:mod:`scenes.calibration`) renders a
   geometric step edge with the *same two cameras* (same f, N, D; a 4096-px-wide film so that the
   small sensor's blur is several pixels) at object distances spanning the portrait's depth range,
   fits the disk ⊗ box edge profile, and takes the ratio of the relative blur c/X between sensors.
   It is compared with Eq. (6).
3. Also reported (not a measurement, Eq. 5 applied to ground-truth depth): the ratio of the two
   renders' median ground-truth CoC maps over pixels where the large sensor's CoC ≥ 1 px.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "Fig2Config", "compute"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig2Config:
    """Every parameter of Fig. 2."""

    scene: str = "portrait"
    # key of scenes.SCENES rendered side by side.
    sensors: tuple[str, str] = ("aps_c_22", "canon_powershot_a80")
    # keys of scenes.camera.SENSORS: large (22.2 × 14.8 mm) and small (7.18 × 5.32 mm) sensor.
    f_number: float = 2.8
    # N for both cameras, dimensionless (paper's Fig. 2).
    preset: str = "full"
    # resolution preset of the scene renders ("small" 160×120 or "full" 640×480 px).
    spp: int | None = None
    # samples per pixel of the scene renders; None = the scene's default for the preset.
    seed: int = 0
    # sampler seed.
    edge_depth_factors: tuple[float, ...] = (0.5, 0.8, 2.4, 6.0)
    # step-edge object distances as multiples of the scene's focus distance D, dimensionless;
    # for the portrait (D = 0.25 m): 0.125 m foreground card, 0.2 m, 0.6 m shelf, 1.5 m background.
    edge_width_px: int = 4096
    # film width of the step-edge measurement, px (sets the pitch; ratios c/X do not depend on it).
    edge_crop_width: int = 384
    # rendered crop of the step-edge film, px; > largest c + 16.
    edge_rows: int = 8
    # step-edge film height, px.
    edge_spp: int = 4096
    # step-edge samples per pixel.


FULL = Fig2Config()
QUICK = Fig2Config(preset="small", edge_spp=1024, edge_depth_factors=(0.5, 6.0))


def _cameras(config: Fig2Config, scene_def):
    from scenes.camera import same_field_of_view

    big = scene_def.camera(config.preset, f_number=config.f_number)
    big = same_field_of_view(big, config.sensors[0])
    small = same_field_of_view(big, config.sensors[1])
    return big, small


def compute(config: Fig2Config) -> dict:
    """Renders, ground-truth CoC maps and the measured CoC ratio of Fig. 2.

    Parameters
    ----------
    config : Fig2Config

    Returns
    -------
    dict
        ``rgb_large``, ``rgb_small`` (H, W, 3) linear renders; ``coc_px_large``, ``coc_px_small``
        (H, W) ground-truth CoC maps (Eq. 5, px, NaN where no surface); ``edge_depth_m`` (m,);
        ``edge_coc_px_large`` / ``edge_coc_px_small`` (m,) fitted step-edge c (px of the wide film);
        ``edge_eq5_px_large`` / ``_small`` (m,); ``edge_ratio`` (m,) measured c'_L/c'_S;
        ``edge_ratio_eq6`` (m,); ``curve_s_m`` (n,) and ``curve_eq5_px_large`` / ``_small`` (n,):
        Eq. (5) on the wide film, for the plot; ``metrics``.
    """
    from scenes import SCENES
    from scenes.calibration import StepEdgeRenderer, measure_edge_grid
    from scenes.render import render_scene

    t0 = time.perf_counter()
    scene_def = SCENES[config.scene]
    big, small = _cameras(config, scene_def)
    spp = config.spp
    renders = {}
    for key, cam in (("large", big), ("small", small)):
        r = render_scene(config.scene, cam, preset=config.preset, spp=spp, seed=config.seed, progress=False)
        renders[key] = r
    coc_l = np.asarray(renders["large"].coc_px, dtype=np.float64)
    coc_s = np.asarray(renders["small"].coc_px, dtype=np.float64)
    mask = np.isfinite(coc_l) & np.isfinite(coc_s) & (coc_l >= 1.0)
    gt_ratio = float(np.median(coc_l[mask]) / np.median(coc_s[mask])) if mask.any() else float("nan")

    renderer = StepEdgeRenderer(spp=config.edge_spp, rows=config.edge_rows, crop_width=config.edge_crop_width,
                                seed=config.seed)
    depths = np.asarray(config.edge_depth_factors, dtype=np.float64) * big.focus_distance_m
    edge_cameras = [cam.replace(resolution=(config.edge_width_px, config.edge_rows)) for cam in (big, small)]
    grid = measure_edge_grid(renderer, edge_cameras, depths)
    out = {"cl": grid["coc_fit_px"][0], "cs": grid["coc_fit_px"][1],
           "el": grid["coc_eq5_px"][0], "es": grid["coc_eq5_px"][1]}
    curve_s = np.geomspace(0.4 * big.focus_distance_m, 8.0 * big.focus_distance_m, 400)
    wide = config.edge_width_px
    curve_l = big.replace(resolution=(wide, config.edge_rows)).coc_px(curve_s)
    curve_s_px = small.replace(resolution=(wide, config.edge_rows)).coc_px(curve_s)
    # equal film widths: the ratio of c/X equals the ratio of c in pixels
    ratio = out["cl"] / out["cs"]
    ratio_eq6 = out["el"] / out["es"]
    rel = ratio / ratio_eq6 - 1.0
    metrics = {
        "measured_ratio_median": float(np.median(ratio)),
        "eq6_ratio": float(np.median(ratio_eq6)),
        "sensor_width_ratio": big.sensor_width_mm / small.sensor_width_mm,
        "max_ratio_rel_err": float(np.max(np.abs(rel))),
        "max_coc_rel_err_vs_eq5": float(np.nanmax(np.abs(np.concatenate(
            [out["cl"] / out["el"] - 1.0, out["cs"] / out["es"] - 1.0])))),
        "gt_map_ratio_median": gt_ratio,
        "coc_px_max_large": float(np.nanmax(coc_l)),
        "coc_px_max_small": float(np.nanmax(coc_s)),
        "focal_length_mm": [big.focal_length_mm, small.focal_length_mm],
        "fov_x_deg": [big.fov_x_deg, small.fov_x_deg],
        "focus_distance_m": big.focus_distance_m,
        "measurement": "ratio of step-edge disk fits (scenes.calibration) rendered with the same two "
                       "cameras on a wide film; gt_map_ratio is Eq. 5 on rendered depth (not a measurement)",
        "compute_seconds": time.perf_counter() - t0,
    }
    return {
        "rgb_large": np.asarray(renders["large"].rgb, dtype=np.float32),
        "rgb_small": np.asarray(renders["small"].rgb, dtype=np.float32),
        "coc_px_large": coc_l.astype(np.float32),
        "coc_px_small": coc_s.astype(np.float32),
        "edge_depth_m": depths,
        "edge_coc_px_large": out["cl"],
        "edge_coc_px_small": out["cs"],
        "edge_eq5_px_large": out["el"],
        "edge_eq5_px_small": out["es"],
        "edge_ratio": ratio,
        "edge_ratio_eq6": ratio_eq6,
        "curve_s_m": curve_s,
        "curve_eq5_px_large": curve_l,
        "curve_eq5_px_small": curve_s_px,
        "metrics": metrics,
    }


FIGURE = Figure(
    name="fig2",
    title="Sensor size: same scene, FOV and f/2.8 on 22.2 mm vs 7.18 mm sensors (Eq. 6)",
    compute=compute,
    plot="experiments.plotting.fig2:plot",
    configs={"quick": QUICK, "full": FULL},
    version=2,  # 2: Eq. (5) curves for the plot
    sigma_convention="none: CoC diameters c (disk fit and Eq. 5 maps), not Gaussian sigmas",
)
