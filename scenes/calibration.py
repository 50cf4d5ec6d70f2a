"""Calibration: measure the blur Mitsuba's ``thinlens`` renders and compare it with Eq. (5)/(6).

A geometric step edge — an emissive half-plane with a straight vertical edge on the optical axis,
fronto-parallel at camera-space depth S — is rendered with the ``direct`` integrator (no lighting
noise: a camera ray either hits the emitter or misses), Mitsuba's ``box`` pixel filter and a
wide-and-short film (by default 4096 px wide, of which only a centred crop of 256 × 8 px is
rendered). The rows are averaged into one edge profile, and the profile is fitted with the exact
image of a step blurred by a uniform disk of diameter c and integrated over the box pixel
footprint (:func:`disk_edge_profile`; the edge model and its fits are :mod:`scenes.edge_fits`, imported
here). The fitted c (pixels) is compared with Eq. (5)
(:meth:`scenes.camera.ThinLensCamera.coc_px`), and the ratio of two sensors' relative blur
with Eq. (6).

For reporting, each profile is also fitted with a Gaussian edge (erf, σ at pixel centres) and
its line-spread second moment is measured (:func:`second_moment_sigma`); these are the two
"σ" conventions of :data:`scenes.thin_lens.SIGMA_CONVENTIONS`.

Units: distances in metres, positions and blur in pixels of the full film.

Notes
-----
Algorithm of :func:`measure_edge` (:func:`measure_edge_grid` over cameras × distances; the
experiments ``fig10`` (Eq. 5) and ``fig2`` (Eq. 6) run it):

1. For the camera and object distance S, set ``aperture_radius``, ``focus_distance``, ``x_fov`` and the
   half-plane's ``to_world`` through ``mi.traverse`` (one scene load per film size) and render.
2. Average the film rows → profile p[i], i = 0 … crop_width − 1, pixel i covering [i, i + 1].
3. Least-squares fit p ≈ B + A·G(x; x0, c), G the box-averaged disk edge-spread function.
4. Compare c with Eq. (5); two sensors at equal (S, N) and field of view give c'_1 / c'_2 to
   compare with Eq. (6).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from .camera import ThinLensCamera
from .edge_fits import disk_edge_profile, fit_disk_edge, fit_erf_edge, second_moment_sigma
from .thin_lens import BOX_FILTER_SIGMA_PX, coc_to_sigma

__all__ = [
    "FOV_MAPPINGS",
    "GRID_FIELDS",
    "StepEdgeRenderer",
    "disk_edge_profile",
    "fit_disk_edge",
    "fit_erf_edge",
    "measure_edge",
    "measure_edge_grid",
    "second_moment_sigma",
]

#: Ways of turning a physical camera into Mitsuba's horizontal field of view.
#: ``"thin_lens"`` (the project's): 2·atan(W / (2v)), v = f·D/(D − f);
#: ``"naive"``: 2·atan(W / (2f)), which renders the blur (D − f)/D too small.
FOV_MAPPINGS = ("thin_lens", "naive")


# --------------------------------------------------------------------------------------------
# Renderer
# --------------------------------------------------------------------------------------------
def _fov_deg(camera: ThinLensCamera, mapping: str) -> float:
    if mapping == "thin_lens":
        return camera.fov_x_deg
    if mapping == "naive":
        return math.degrees(2.0 * math.atan(camera.sensor_width_m / (2.0 * camera.focal_length_m)))
    raise ValueError(f"fov_mapping={mapping!r} is invalid; allowed: {FOV_MAPPINGS}")


class StepEdgeRenderer:
    """Renders a fronto-parallel emissive half-plane (vertical edge on the optical axis).

    One Mitsuba scene per film width is loaded once; camera and object changes go through
    ``mi.traverse``. Profiles are memoised in the instance (same camera + depth → no re-render).

    Parameters
    ----------
    spp : int, keyword-only
        Samples per pixel (> 0).
    rows : int, keyword-only
        Film height, px (rows averaged into the profile).
    crop_width : int, keyword-only
        Width of the rendered centred crop, px (even); must exceed c + 16 px of every case.
    seed : int, keyword-only
        Sampler seed.
    sampler : str, keyword-only
        Mitsuba sampler type. ``"multijitter"`` (default, as the scene library uses) measured
        ~2× smaller fit scatter than ``"independent"`` on 3-px edges.
    variant : str, optional, keyword-only
        Mitsuba variant (default: :func:`scenes.backend.select_variant`).

    Notes
    -----
    The film is the camera's full width (``camera.resolution[0]``, which sets the pixel pitch);
    only the crop [W/2 − crop/2, W/2 + crop/2) × rows is rendered, so the edge lies at
    crop_width/2 in profile coordinates. The camera's ``resolution[1]`` is ignored.
    """

    def __init__(self, *, spp=4096, rows=8, crop_width=256, seed=0, sampler="multijitter", variant=None):
        if not (isinstance(spp, int) and spp > 0):
            raise ValueError(f"spp={spp!r} is invalid; allowed: integer > 0")
        if not (isinstance(rows, int) and rows > 0):
            raise ValueError(f"rows={rows!r} is invalid; allowed: integer > 0")
        if not (isinstance(crop_width, int) and crop_width >= 16 and crop_width % 2 == 0):
            raise ValueError(f"crop_width={crop_width!r} is invalid; allowed: even integer >= 16")
        if sampler not in ("independent", "multijitter", "stratified", "ldsampler"):
            raise ValueError(f"sampler={sampler!r} is invalid; allowed: independent, multijitter, stratified, ldsampler")
        self.spp, self.rows, self.crop_width, self.seed = spp, rows, crop_width, int(seed)
        self.sampler = sampler
        self._variant = variant
        self._scenes: dict[int, tuple] = {}
        self._profiles: dict[tuple, np.ndarray] = {}
        self.render_seconds = 0.0
        self.render_count = 0

    @property
    def variant(self) -> str:
        """The Mitsuba variant used."""
        from .backend import select_variant

        return select_variant(self._variant)

    def _scene(self, camera: ThinLensCamera):
        from .backend import import_mitsuba
        from .mitsuba_camera import thinlens_sensor_dict

        width = camera.resolution[0]
        if width in self._scenes:
            return self._scenes[width]
        if width % 2 or width < self.crop_width:
            raise ValueError(
                f"camera.resolution[0]={width} is invalid; allowed: even and >= crop_width={self.crop_width}"
            )
        mi, _ = import_mitsuba(self._variant)
        sensor = thinlens_sensor_dict(
            camera.replace(resolution=(width, self.rows)), spp=self.spp, seed=self.seed, pixel_filter="box"
        )
        sensor["sampler"]["type"] = self.sampler
        sensor["film"].update(
            crop_offset_x=width // 2 - self.crop_width // 2, crop_offset_y=0,
            crop_width=self.crop_width, crop_height=self.rows,
        )
        scene = mi.load_dict({
            "type": "scene",
            "integrator": {"type": "direct"},
            "sensor": sensor,
            "edge": {
                "type": "rectangle",
                "flip_normals": True,  # emit towards the camera (−z)
                "to_world": self._edge_transform(mi, 1.0),
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}},
            },
        })
        entry = (mi, scene, mi.traverse(scene))
        self._scenes[width] = entry
        return entry

    @staticmethod
    def _edge_transform(mi, depth_m):
        # Unit rectangle [-1, 1]² → x ∈ [0, 2L], y ∈ [−L, L] at z = S: edge on the optical axis,
        # extent far beyond the field of view and the blur footprint.
        half = max(10.0 * depth_m, 10.0)
        return mi.ScalarTransform4f().translate([half, 0.0, depth_m]) @ mi.ScalarTransform4f().scale(
            [half, half, 1.0]
        )

    def render_profile(self, camera: ThinLensCamera, depth_m: float, *, fov_mapping="thin_lens"):
        """Render the edge at camera-space depth ``depth_m`` and return its row-averaged profile.

        Parameters
        ----------
        camera : ThinLensCamera
            Camera (focal length, f-number, focus, sensor width; ``resolution[0]`` = film width).
        depth_m : float
            Object distance S, metres (> near clip 0.01 m).
        fov_mapping : {"thin_lens", "naive"}, keyword-only
            How the field of view is derived (see :data:`FOV_MAPPINGS`).

        Returns
        -------
        ndarray, shape (crop_width,)
            Linear radiance (emitter radiance 1), bright on the image left.
        """
        if not (math.isfinite(depth_m) and depth_m > 0.01):
            raise ValueError(f"depth_m={depth_m!r} is invalid; allowed: finite > 0.01 m")
        fov = _fov_deg(camera, fov_mapping)
        key = (camera.replace(resolution=(camera.resolution[0], self.rows)), float(depth_m), fov_mapping)
        if key in self._profiles:
            return self._profiles[key].copy()
        mi, scene, params = self._scene(camera)
        params["sensor.aperture_radius"] = camera.aperture_radius_m
        params["sensor.focus_distance"] = camera.focus_distance_m
        params["sensor.x_fov"] = fov
        params["edge.to_world"] = self._edge_transform(mi, float(depth_m))
        params.update()
        t0 = time.perf_counter()
        img = np.asarray(mi.render(scene, params, spp=self.spp, seed=self.seed), dtype=np.float64)
        self.render_seconds += time.perf_counter() - t0
        self.render_count += 1
        profile = img[..., 0].mean(axis=0)
        self._profiles[key] = profile
        return profile.copy()


# --------------------------------------------------------------------------------------------
# Measurement
# --------------------------------------------------------------------------------------------
def measure_edge(renderer: StepEdgeRenderer, camera: ThinLensCamera, depth_m: float, *,
                 fov_mapping="thin_lens", label=""):
    """Render one step edge and measure its blur three ways; one table row.

    Parameters
    ----------
    renderer : StepEdgeRenderer
    camera : ThinLensCamera
    depth_m : float
        Object distance S, metres.
    fov_mapping : {"thin_lens", "naive"}, keyword-only
    label : str, keyword-only
        Name of the camera in the row (e.g. the sensor key).

    Returns
    -------
    dict
        ``coc_eq5_px`` (Eq. 5, px), ``coc_fit_px`` (disk fit, px), ``rel_err`` (fit/Eq5 − 1),
        ``sigma_erf_px`` / ``sigma_erf_pred_px`` (erf fit vs √((0.273c)² + 1/12)),
        ``sigma_2nd_px`` / ``sigma_2nd_pred_px`` (LSF second moment vs √(c²/16 + 1/12)),
        ``edge_offset_px`` (fitted edge − expected position), ``rms_residual``, and the camera.
    """
    coc_eq5 = float(camera.coc_px(depth_m))
    if coc_eq5 + 16 > renderer.crop_width:
        raise ValueError(
            f"Eq. (5) blur {coc_eq5:.1f} px does not fit the crop of {renderer.crop_width} px; "
            "allowed: c + 16 <= crop_width"
        )
    profile = renderer.render_profile(camera, depth_m, fov_mapping=fov_mapping)
    disk = fit_disk_edge(profile)
    erf = fit_erf_edge(profile)
    c = disk["coc_px"]
    return {
        "label": label,
        "sensor_width_mm": camera.sensor_width_mm,
        "focal_length_mm": round(camera.focal_length_mm, 6),
        "f_number": camera.f_number,
        "focus_distance_m": camera.focus_distance_m,
        "depth_m": float(depth_m),
        "width_px": camera.resolution[0],
        "fov_mapping": fov_mapping,
        "fov_x_deg": _fov_deg(camera, fov_mapping),
        "coc_eq5_px": coc_eq5,
        "coc_fit_px": c,
        "rel_err": c / coc_eq5 - 1.0 if coc_eq5 > 0 else float("nan"),
        "coc_eq5_mm": coc_eq5 * camera.pixel_pitch_m * 1e3,
        "coc_fit_mm": c * camera.pixel_pitch_m * 1e3,
        "sigma_erf_px": erf["sigma_px"],
        "sigma_erf_pred_px": float(coc_to_sigma(coc_eq5, convention="erf_fit")),
        "sigma_2nd_px": second_moment_sigma(profile, edge_px=disk["edge_px"], half_window_px=c / 2 + 4),
        "sigma_2nd_pred_px": float(coc_to_sigma(coc_eq5, convention="line_spread")),
        "filter_sigma_px": BOX_FILTER_SIGMA_PX,
        "edge_offset_px": disk["edge_px"] - renderer.crop_width / 2,
        "rms_residual": disk["rms_residual"],
    }


#: Numeric fields of a :func:`measure_edge` row that :func:`measure_edge_grid` collects.
GRID_FIELDS = ("coc_eq5_px", "coc_fit_px", "rel_err", "sigma_erf_px", "sigma_erf_pred_px", "sigma_2nd_px",
               "sigma_2nd_pred_px", "edge_offset_px", "rms_residual")


def measure_edge_grid(renderer: StepEdgeRenderer, cameras: Sequence[ThinLensCamera], depths_m, *,
                      fov_mapping="thin_lens", label=""):
    """:func:`measure_edge` for every camera at every object distance.

    Parameters
    ----------
    renderer : StepEdgeRenderer
    cameras : sequence of ThinLensCamera, length k
    depths_m : array_like, shape (m,)
        Object distances S, metres.
    fov_mapping : {"thin_lens", "naive"}, keyword-only
    label : str, keyword-only
        Name of the cameras in the rows.

    Returns
    -------
    dict
        ``field -> ndarray (k, m)`` of float64 for every field of :data:`GRID_FIELDS` (px, or
        dimensionless for ``rel_err``; camera i, distance j).
    """
    depths = [float(s) for s in np.asarray(depths_m, dtype=np.float64).ravel()]
    out = {name: np.full((len(cameras), len(depths)), np.nan) for name in GRID_FIELDS}
    for i, cam in enumerate(cameras):
        for j, s in enumerate(depths):
            row = measure_edge(renderer, cam, s, fov_mapping=fov_mapping, label=label)
            for name in GRID_FIELDS:
                out[name][i, j] = row[name]
    return out
