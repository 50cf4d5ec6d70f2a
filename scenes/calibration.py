"""Calibration: measure the blur Mitsuba's ``thinlens`` renders and compare it with Eq. (5)/(6).

A geometric step edge — an emissive half-plane with a straight vertical edge on the optical axis,
fronto-parallel at camera-space depth S — is rendered with the ``direct`` integrator (no lighting
noise: a camera ray either hits the emitter or misses), Mitsuba's ``box`` pixel filter and a
wide-and-short film (by default 4096 px wide, of which only a centred crop of 256 × 8 px is
rendered). The rows are averaged into one edge profile, and the profile is fitted with the exact
image of a step blurred by a uniform disk of diameter c and integrated over the box pixel
footprint (:func:`disk_edge_profile`). The fitted c (pixels) is compared with Eq. (5)
(:meth:`scenes.camera.ThinLensCamera.coc_px`), and the ratio of two sensors' relative blur
with Eq. (6).

For reporting, each profile is also fitted with a Gaussian edge (erf, σ at pixel centres) and
its line-spread second moment is measured (:func:`second_moment_sigma`); these are the two
"σ" conventions of :data:`scenes.thin_lens.SIGMA_CONVENTIONS`.

Units: distances in metres, positions and blur in pixels of the full film.

Notes
-----
Algorithm of :func:`run_calibration`:

1. For each camera (two sensors with the same relative focal length, Eq. 6) and f-number, and
   each object distance S, set ``aperture_radius``, ``focus_distance``, ``x_fov`` and the
   half-plane's ``to_world`` through ``mi.traverse`` (one scene load per film size) and render.
2. Average the film rows → profile p[i], i = 0 … crop_width − 1, pixel i covering [i, i + 1].
3. Least-squares fit p ≈ B + A·G(x; x0, c), G the box-averaged disk edge-spread function.
4. Compare c with Eq. (5); pair the sensors at equal (S, N) and compare c'_1 / c'_2 with Eq. (6).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
from collections.abc import Sequence

import numpy as np

from .camera import SENSORS, ThinLensCamera, same_field_of_view
from .thin_lens import BOX_FILTER_SIGMA_PX, coc_to_sigma, relative_circle_of_confusion

__all__ = [
    "CALIBRATION_DEFAULTS",
    "FOV_MAPPINGS",
    "CalibrationConfig",
    "StepEdgeRenderer",
    "calibration_cases",
    "default_renderer",
    "disk_edge_profile",
    "fit_disk_edge",
    "fit_erf_edge",
    "format_table",
    "measure_edge",
    "run_calibration",
    "second_moment_sigma",
    "sensor_ratio_table",
    "write_calibration_log",
]

#: Ways of turning a physical camera into Mitsuba's horizontal field of view.
#: ``"thin_lens"`` (the project's): 2·atan(W / (2v)), v = f·D/(D − f);
#: ``"naive"``: 2·atan(W / (2f)), which renders the blur (D − f)/D too small.
FOV_MAPPINGS = ("thin_lens", "naive")


# --------------------------------------------------------------------------------------------
# Edge model and fits
# --------------------------------------------------------------------------------------------
def _disk_esf_antiderivative(t):
    """∫ F(t) dt of the unit-radius disk's edge-spread function F, with H(t) = 0 for t ≤ −1.

    F(t) = 1/2 + (t·√(1 − t²) + asin t)/π on [−1, 1] (fraction of the disk left of t), so
    H(t) = t/2 + (t·asin t + √(1 − t²) − (1 − t²)^{3/2}/3)/π, and H(t) = t for t ≥ 1.
    """
    t = np.asarray(t, dtype=np.float64)
    u = np.clip(t, -1.0, 1.0)
    s = np.sqrt(np.maximum(1.0 - u * u, 0.0))
    inside = u / 2.0 + (u * np.arcsin(u) + s - s**3 / 3.0) / np.pi
    return np.where(t <= -1.0, 0.0, np.where(t >= 1.0, t, inside))


def _disk_esf_correction(t):
    # h(t) = H(t) − max(t, 0): bounded, zero outside (−1, 1); avoids cancellation of large H.
    t = np.asarray(t, dtype=np.float64)
    return np.where(np.abs(t) < 1.0, _disk_esf_antiderivative(t) - np.maximum(t, 0.0), 0.0)


def _disk_edge_profile(x, edge, coc):
    # Box-averaged disk ESF: (1/1px)·∫_{x−½}^{x+½} F((u − x0)/r) du = r·[H(b) − H(a)],
    # split as [max(u, 0)] over the pixel (a ramp in px, exact) + r·[h(b) − h(a)].
    r = max(float(coc) / 2.0, 1e-9)
    lo, hi = x - 0.5 - edge, x + 0.5 - edge
    ramp = np.maximum(hi, 0.0) - np.maximum(lo, 0.0)
    return ramp + r * (_disk_esf_correction(hi / r) - _disk_esf_correction(lo / r))


def disk_edge_profile(x_px, *, edge_px, coc_px):
    """Image of a unit step blurred by a uniform disk and integrated over a 1-px box pixel.

    Exact model of a defocused straight edge rendered with a ``box`` reconstruction filter:
    the disk's edge-spread function (the fraction of a disk of diameter ``coc_px`` lying on the
    bright side) averaged over the pixel footprint [x − ½, x + ½]. Dark (0) for x ≪ edge,
    bright (1) for x ≫ edge.

    Parameters
    ----------
    x_px : ndarray, shape (n,)
        Pixel-centre positions, px.
    edge_px : float, keyword-only
        Position of the sharp edge, px.
    coc_px : float, keyword-only
        Circle-of-confusion diameter c, px (≥ 0; 0 gives the box-averaged step).

    Returns
    -------
    ndarray, shape (n,)
        Profile values in [0, 1].
    """
    if not (math.isfinite(coc_px) and coc_px >= 0):
        raise ValueError(f"coc_px={coc_px!r} is invalid; allowed: finite >= 0")
    return _disk_edge_profile(np.asarray(x_px, dtype=np.float64), float(edge_px), float(coc_px))


def _check_profile(profile):
    p = np.asarray(profile, dtype=np.float64)
    if p.ndim != 1 or p.size < 8 or not np.all(np.isfinite(p)):
        raise ValueError(f"profile must be a finite 1-D array with >= 8 samples, got shape {p.shape}")
    return p


def _initial_guess(p):
    """Edge position, a width estimate (px), low and high levels of a monotone-ish edge profile."""
    n = p.size
    k = max(2, n // 16)
    left, right = float(np.median(p[:k])), float(np.median(p[-k:]))
    lo, hi = min(left, right), max(left, right)
    q = (p - lo) / (hi - lo if hi > lo else 1.0)
    if left > right:
        q = 1.0 - q
    x = np.arange(n) + 0.5
    # 10 % and 90 % crossings of the rising profile (counted, robust to noise).
    x10 = float(np.sum(q < 0.1))
    x90 = float(np.sum(q < 0.9))
    x50 = float(np.interp(0.5, np.sort(q), x)) if np.all(np.diff(q) >= 0) else float(np.sum(q < 0.5))
    return x50, max(x90 - x10, 0.5), left, right


def fit_disk_edge(profile):
    """Fit the disk-blurred, box-integrated step (:func:`disk_edge_profile`) to an edge profile.

    Model: p(x) ≈ B + A·G(x; x0, c), with pixel i centred at x = i + ½. A may be negative
    (bright side on the left, as Mitsuba's camera frame puts world +x on the image left).

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Edge profile (row average of a rendered edge), any linear intensity unit; n ≥ 8.

    Returns
    -------
    dict
        ``coc_px`` (fitted c, px), ``edge_px`` (x0, px), ``amplitude`` A, ``offset`` B,
        ``rms_residual`` (same unit as the profile).

    Notes
    -----
    1. Initial edge and width from the 10/50/90 % crossings (the disk's 10–90 % width ≈ 0.61·c).
    2. Levenberg–Marquardt (``scipy.optimize.least_squares``) over (x0, c, A, B), c ≥ 0.
    """
    from scipy.optimize import least_squares

    p = _check_profile(profile)
    x = np.arange(p.size) + 0.5
    x50, width, left, right = _initial_guess(p)
    a0, b0 = right - left, left  # G runs 0 → 1 left → right; A < 0 when the bright side is left

    def resid(theta):
        x0, c, a, b = theta
        return b + a * _disk_edge_profile(x, x0, abs(c)) - p

    best = None
    for c_start in (width / 0.61, width / 0.61 * 0.5, width / 0.61 * 1.5, 0.5):
        sol = least_squares(resid, [x50, max(c_start, 0.05), a0, b0], method="lm", x_scale="jac")
        if best is None or sol.cost < best.cost:
            best = sol
    x0, c, a, b = best.x
    return {
        "coc_px": float(abs(c)),
        "edge_px": float(x0),
        "amplitude": float(a),
        "offset": float(b),
        "rms_residual": float(np.sqrt(np.mean(best.fun**2))),
    }


def fit_erf_edge(profile):
    """Least-squares fit of a Gaussian-blurred step (erf) sampled at pixel centres.

    p(x) ≈ B + A·Φ((x − x0)/σ), Φ the standard normal CDF. The fitted σ includes the pixel
    footprint (≈ √(σ_blur² + 1/12) for a box filter); for a disk edge σ_blur ≈ 0.273·c
    (``coc_to_sigma(convention="erf_fit")``).

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Edge profile.

    Returns
    -------
    dict
        ``sigma_px`` (σ, px), ``edge_px``, ``amplitude``, ``offset``, ``rms_residual``.
    """
    from scipy.optimize import least_squares
    from scipy.special import ndtr

    p = _check_profile(profile)
    x = np.arange(p.size) + 0.5
    x50, width, left, right = _initial_guess(p)

    def resid(theta):
        x0, s, a, b = theta
        return b + a * ndtr((x - x0) / max(abs(s), 1e-6)) - p

    sol = least_squares(resid, [x50, max(width / 2.563, 0.3), right - left, left], method="lm",
                        x_scale="jac")
    x0, s, a, b = sol.x
    return {
        "sigma_px": float(abs(s)),
        "edge_px": float(x0),
        "amplitude": float(a),
        "offset": float(b),
        "rms_residual": float(np.sqrt(np.mean(sol.fun**2))),
    }


def second_moment_sigma(profile, *, edge_px, half_window_px):
    """Standard deviation of the edge's line-spread function (second moment), px.

    The LSF is estimated by differencing adjacent pixels, which samples LSF ⊗ pixel-box ⊗ box
    at the pixel boundaries; the extra differencing box (variance 1/12 px²) is subtracted, so
    the result estimates √(c²/16 + 1/12) for a disk of diameter c rendered with a box filter
    (``coc_to_sigma(c, convention="line_spread")``).

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Edge profile.
    edge_px : float, keyword-only
        Edge position (px) — the window centre, e.g. from :func:`fit_disk_edge`.
    half_window_px : float, keyword-only
        Half-width of the window the moment is taken over, px (> 0); e.g. c/2 + 4.

    Returns
    -------
    float
        σ in px (NaN when the windowed LSF has no mass).
    """
    p = _check_profile(profile)
    if not half_window_px > 0:
        raise ValueError(f"half_window_px={half_window_px!r} is invalid; allowed: > 0")
    d = np.diff(p)
    xb = np.arange(1, p.size, dtype=np.float64)  # boundary between pixel i−1 and i
    keep = np.abs(xb - edge_px) <= half_window_px
    w = d[keep]
    w = w * np.sign(w.sum()) if w.sum() != 0 else w
    total = w.sum()
    if not total > 0:
        return float("nan")
    mu = float(np.sum(w * xb[keep]) / total)
    var = float(np.sum(w * (xb[keep] - mu) ** 2) / total) - 1.0 / 12.0
    return float(np.sqrt(max(var, 0.0)))


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


def default_renderer(*, spp=4096, rows=8, crop_width=256, seed=0) -> StepEdgeRenderer:
    """A process-wide :class:`StepEdgeRenderer` per setting, so renders are shared within a run."""
    return _shared_renderer(int(spp), int(rows), int(crop_width), int(seed))


@functools.lru_cache(maxsize=8)
def _shared_renderer(spp, rows, crop_width, seed):
    return StepEdgeRenderer(spp=spp, rows=rows, crop_width=crop_width, seed=seed)


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


@dataclasses.dataclass(frozen=True, kw_only=True)
class CalibrationConfig:
    """Every parameter of the calibration run (issue part 7)."""

    width_px: int = 4096
    # film width, px; sets the pixel pitch (sensor width / width_px). Only a crop is rendered.
    crop_width: int = 256
    # rendered crop around the optical axis, px; must exceed the largest c + 16 px.
    rows: int = 8
    # film height, px; rows are averaged into one profile.
    spp: int = 4096
    # samples per pixel; per-pixel std of the averaged profile ≤ 0.5/√(rows·spp) ≈ 0.003.
    seed: int = 0
    # sampler seed.
    focus_distance_m: float = 1.0
    # D, metres. Close focus makes (D − f)/D (the naive-FOV error) 5 % for the 50 mm lens.
    depths_m: tuple[float, ...] = (0.45, 0.7, 1.6, 5.0)
    # object distances S, metres: two in front of and two behind focus.
    f_numbers: tuple[float, ...] = (4.0, 8.0)
    # N, dimensionless.
    sensors: tuple[str, ...] = ("full_frame", "canon_powershot_a80")
    # keys of scenes.camera.SENSORS; the first has f = 50 mm, the others the same f' = f/X (Eq. 6).
    reference_focal_length_mm: float = 50.0
    # focal length on the first sensor, mm.


#: The calibration the test suite runs: 2 sensors × 2 f-numbers × 4 depths = 16 cases, all ≥ 2.6 px.
CALIBRATION_DEFAULTS = CalibrationConfig()


def calibration_cases(config: CalibrationConfig = CALIBRATION_DEFAULTS):
    """The (label, camera, depth) cases of a calibration config.

    Returns
    -------
    list of (str, ThinLensCamera, float)
        Sensor key, camera (same field of view across sensors via
        :func:`scenes.camera.same_field_of_view`), object distance S in metres.
    """
    first = SENSORS[config.sensors[0]]
    base = ThinLensCamera(
        sensor_width_mm=first.width_mm, sensor_height_mm=first.height_mm,
        focal_length_mm=config.reference_focal_length_mm, f_number=config.f_numbers[0],
        focus_distance_m=config.focus_distance_m, resolution=(config.width_px, config.rows),
    )
    cases = []
    for name in config.sensors:
        cam_s = same_field_of_view(base, name)
        for n in config.f_numbers:
            cam = cam_s.replace(f_number=float(n))
            for s in config.depths_m:
                cases.append((name, cam, float(s)))
    return cases


def run_calibration(config: CalibrationConfig = CALIBRATION_DEFAULTS, *, renderer=None, progress=None):
    """Render and measure every case of ``config``.

    Parameters
    ----------
    config : CalibrationConfig
    renderer : StepEdgeRenderer, optional, keyword-only
        Defaults to :func:`default_renderer` with the config's sampling settings (shared in-process).
    progress : callable, optional, keyword-only
        Called with each finished row (e.g. to print it).

    Returns
    -------
    list of dict
        One row per case (see :func:`measure_edge`).
    """
    if renderer is None:
        renderer = default_renderer(spp=config.spp, rows=config.rows, crop_width=config.crop_width,
                                    seed=config.seed)
    rows = []
    for label, cam, depth in calibration_cases(config):
        row = measure_edge(renderer, cam, depth, label=label)
        rows.append(row)
        if progress is not None:
            progress(row)
    return rows


def sensor_ratio_table(rows: Sequence[dict], *, reference=None):
    """Pair rows of different sensors at equal (S, N, D, width) and compare blur ratios with Eq. (6).

    The measured ratio is of the relative blur c' = c / X (equal pixel counts make it the ratio
    of c in pixels); the prediction is the ratio of :func:`scenes.thin_lens.relative_circle_of_confusion`.

    Parameters
    ----------
    rows : sequence of dict
        Rows from :func:`measure_edge` (``fov_mapping == "thin_lens"`` only are used).
    reference : str, optional, keyword-only
        Sensor label in the numerator (default: the first label seen).

    Returns
    -------
    list of dict
        ``ratio_measured``, ``ratio_eq6``, ``rel_err``, ``min_coc_px`` (the smaller Eq. 5 c of the pair).
    """
    rows = [r for r in rows if r["fov_mapping"] == "thin_lens"]
    if not rows:
        return []
    reference = reference or rows[0]["label"]
    by_key = {}
    for r in rows:
        by_key.setdefault((r["depth_m"], r["f_number"], r["focus_distance_m"], r["width_px"]), {})[r["label"]] = r
    out = []
    for (s, n, d, w), group in by_key.items():
        if reference not in group:
            continue
        a = group[reference]
        for label, b in group.items():
            if label == reference:
                continue
            def rel(r):
                x = r["sensor_width_mm"] * 1e-3
                return float(relative_circle_of_confusion(
                    s, relative_focal_length=r["focal_length_mm"] / r["sensor_width_mm"],
                    sensor_width=x, f_number=n, focus_distance=d))
            measured = (a["coc_fit_px"] / a["width_px"]) / (b["coc_fit_px"] / b["width_px"])
            predicted = rel(a) / rel(b)
            out.append({
                "pair": f"{reference}/{label}", "depth_m": s, "f_number": n, "focus_distance_m": d,
                "ratio_measured": measured, "ratio_eq6": predicted, "rel_err": measured / predicted - 1.0,
                "sensor_width_ratio": a["sensor_width_mm"] / b["sensor_width_mm"],
                "min_coc_px": min(a["coc_eq5_px"], b["coc_eq5_px"]),
            })
    return out


def format_table(rows: Sequence[dict], ratios: Sequence[dict] = ()) -> str:
    """Human-readable table of calibration rows (and optional Eq. 6 ratios)."""
    lines = [
        f"{'sensor':<20} {'f/mm':>6} {'N':>3} {'D/m':>5} {'S/m':>5} {'fov':>9} {'c_eq5':>8} {'c_fit':>8} "
        f"{'err%':>6} {'σ2nd':>6} {'pred':>6} {'σerf':>6} {'pred':>6} {'edge':>6}",
    ]
    for r in rows:
        lines.append(
            f"{r['label']:<20} {r['focal_length_mm']:6.2f} {r['f_number']:3.0f} {r['focus_distance_m']:5.2f} "
            f"{r['depth_m']:5.2f} {r['fov_mapping']:>9} {r['coc_eq5_px']:8.3f} {r['coc_fit_px']:8.3f} "
            f"{100 * r['rel_err']:+6.2f} {r['sigma_2nd_px']:6.2f} {r['sigma_2nd_pred_px']:6.2f} "
            f"{r['sigma_erf_px']:6.2f} {r['sigma_erf_pred_px']:6.2f} {r['edge_offset_px']:+6.3f}"
        )
    if ratios:
        lines.append("")
        lines.append(f"{'pair':<36} {'S/m':>5} {'N':>3} {'measured':>9} {'Eq.6':>8} {'err%':>6} {'X ratio':>8}")
        for q in ratios:
            lines.append(
                f"{q['pair']:<36} {q['depth_m']:5.2f} {q['f_number']:3.0f} {q['ratio_measured']:9.4f} "
                f"{q['ratio_eq6']:8.4f} {100 * q['rel_err']:+6.2f} {q['sensor_width_ratio']:8.4f}"
            )
    return "\n".join(lines)


def write_calibration_log(rows, ratios=(), *, folder=None, extra=None):
    """Write the table as ``calibration.json`` and ``calibration.txt`` (atomically).

    Parameters
    ----------
    rows, ratios : sequences of dict
        From :func:`run_calibration` / :func:`sensor_ratio_table`.
    folder : path, optional, keyword-only
        Default ``<cache>/calibration``.
    extra : dict, optional, keyword-only
        Additional JSON-able metadata (timings, config).

    Returns
    -------
    pathlib.Path
        The JSON file.
    """
    from pathlib import Path

    from .backend import cache_root
    from defocus_cache import atomic_write_text

    folder = Path(folder) if folder is not None else cache_root() / "calibration"
    folder.mkdir(parents=True, exist_ok=True)
    payload = {"rows": list(rows), "ratios": list(ratios), **(extra or {})}
    path = folder / "calibration.json"
    atomic_write_text(path, json.dumps(payload, indent=1, default=str))
    atomic_write_text(folder / "calibration.txt", format_table(rows, ratios) + "\n")
    return path
