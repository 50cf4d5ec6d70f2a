"""Physical camera description (sensor, lens, aperture, focus) and its presets.

The camera is pure data; :mod:`scenes.mitsuba_camera` maps it to Mitsuba's ``thinlens`` sensor
exactly as ``RENDERING-FACTS.md`` measured: aperture radius R = f/(2N), horizontal field of view
from the lens–sensor distance v = f·D/(D − f): fov_x = 2·atan(W / (2v)).

Pixels are square: the sensor width W maps to the image width, so the pixel pitch is W / width_px
and the vertical extent follows from the resolution's aspect ratio.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from .thin_lens import circle_of_confusion, lens_sensor_distance

__all__ = [
    "CAMERA_PRESETS",
    "PAPER_CAMERAS",
    "SENSORS",
    "Sensor",
    "ThinLensCamera",
    "camera_preset",
    "same_field_of_view",
]


@dataclasses.dataclass(frozen=True)
class Sensor:
    """A sensor format."""

    width_mm: float   # sensor width X, millimetres
    height_mm: float  # sensor height, millimetres


#: Sensor formats named in the paper (Appendix A, Sec. 5) plus full frame.
SENSORS: Mapping[str, Sensor] = MappingProxyType(
    {
        "full_frame": Sensor(36.0, 24.0),
        "canon_1d_mark_ii": Sensor(28.7, 19.1),
        "aps_c_22": Sensor(22.2, 14.8),           # the large sensor of the paper's Fig. 2
        "nikon_d50": Sensor(23.7, 15.6),
        "canon_powershot_a80": Sensor(7.18, 5.32),
    }
)


def _check_positive(name, value, allowed="> 0"):
    if not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name}={value!r} is invalid; allowed: finite {allowed}")


@dataclasses.dataclass(frozen=True)
class ThinLensCamera:
    """A thin-lens camera; every field validated on construction.

    Raises ``ValueError`` naming the bad value and the allowed range.
    """

    sensor_width_mm: float = 36.0     # sensor width X, millimetres (maps to the image width)
    sensor_height_mm: float = 24.0    # sensor height, millimetres (informational; pixels are square)
    focal_length_mm: float = 50.0     # focal length f, millimetres
    f_number: float = 8.0             # N, dimensionless; aperture diameter A = f / N
    focus_distance_m: float = 1.5     # focus distance D (plane z_cam = D), metres; must exceed f
    resolution: tuple[int, int] = (640, 480)  # (width, height), pixels

    def __post_init__(self):
        _check_positive("sensor_width_mm", self.sensor_width_mm)
        _check_positive("sensor_height_mm", self.sensor_height_mm)
        _check_positive("focal_length_mm", self.focal_length_mm)
        _check_positive("f_number", self.f_number)
        _check_positive("focus_distance_m", self.focus_distance_m)
        if self.focus_distance_m <= self.focal_length_m:
            raise ValueError(
                f"focus_distance_m={self.focus_distance_m!r} is invalid; allowed: "
                f"> focal length ({self.focal_length_m} m)"
            )
        res = tuple(self.resolution)
        if len(res) != 2 or not all(isinstance(r, (int, np.integer)) and r > 0 for r in res):
            raise ValueError(
                f"resolution={self.resolution!r} is invalid; allowed: (width, height) positive integers"
            )
        object.__setattr__(self, "resolution", (int(res[0]), int(res[1])))

    # --- derived quantities -------------------------------------------------------------
    @property
    def focal_length_m(self) -> float:
        """f in metres."""
        return self.focal_length_mm * 1e-3

    @property
    def sensor_width_m(self) -> float:
        """X in metres."""
        return self.sensor_width_mm * 1e-3

    @property
    def aperture_radius_m(self) -> float:
        """R = f / (2N), metres (Mitsuba's ``aperture_radius``)."""
        return self.focal_length_m / (2.0 * self.f_number)

    @property
    def lens_sensor_distance_m(self) -> float:
        """v = f·D / (D − f), metres."""
        return float(lens_sensor_distance(self.focal_length_m, self.focus_distance_m))

    @property
    def fov_x_deg(self) -> float:
        """Horizontal field of view 2·atan(W / (2v)), degrees (Mitsuba's ``fov``, ``fov_axis='x'``)."""
        return math.degrees(2.0 * math.atan(self.sensor_width_m / (2.0 * self.lens_sensor_distance_m)))

    @property
    def pixel_pitch_m(self) -> float:
        """Sensor width of one pixel, metres."""
        return self.sensor_width_m / self.resolution[0]

    @property
    def relative_focal_length(self) -> float:
        """f' = f / X (Eq. 6); equal f' means equal field of view."""
        return self.focal_length_mm / self.sensor_width_mm

    def coc_m(self, depth_m):
        """Circle-of-confusion diameter on the sensor (metres) for camera-space depth z, Eq. (5)."""
        return circle_of_confusion(
            depth_m,
            focal_length=self.focal_length_m,
            f_number=self.f_number,
            focus_distance=self.focus_distance_m,
        )

    def coc_px(self, depth_m):
        """Circle-of-confusion diameter in pixels, Eq. (5) divided by the pixel pitch."""
        return self.coc_m(depth_m) / self.pixel_pitch_m

    def replace(self, **changes) -> "ThinLensCamera":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """JSON-ready description, including derived Mitsuba parameters."""
        d = dataclasses.asdict(self)
        d["resolution"] = list(self.resolution)
        d.update(
            aperture_radius_m=self.aperture_radius_m,
            lens_sensor_distance_m=self.lens_sensor_distance_m,
            fov_x_deg=self.fov_x_deg,
        )
        return d


def same_field_of_view(camera: ThinLensCamera, sensor: Sensor | str) -> ThinLensCamera:
    """The camera with another sensor and the focal length that keeps the field of view.

    Keeps the relative focal length f' = f / X (Eq. 6), the f-number, focus and resolution.

    Parameters
    ----------
    camera : ThinLensCamera
    sensor : Sensor or str
        A :class:`Sensor` or a key of :data:`SENSORS`.
    """
    if isinstance(sensor, str):
        sensor = _lookup_sensor(sensor)
    focal = camera.relative_focal_length * sensor.width_mm
    return camera.replace(
        sensor_width_mm=sensor.width_mm, sensor_height_mm=sensor.height_mm, focal_length_mm=focal
    )


def _lookup_sensor(name: str) -> Sensor:
    try:
        return SENSORS[name]
    except KeyError:
        raise ValueError(f"unknown sensor preset {name!r}; choose one of {sorted(SENSORS)}") from None


#: Relative focal length of the presets: a 50 mm lens on full frame (horizontal FOV ≈ 39.6°).
_DEFAULT_RELATIVE_FOCAL = 50.0 / 36.0

#: Each sensor with a lens giving the full-frame 50 mm field of view, f/8, D = 1.5 m (Eq. 6 comparisons).
_SAME_FOV_PRESETS: Mapping[str, ThinLensCamera] = MappingProxyType(
    {
        name: ThinLensCamera(
            sensor_width_mm=s.width_mm,
            sensor_height_mm=s.height_mm,
            focal_length_mm=_DEFAULT_RELATIVE_FOCAL * s.width_mm,
        )
        for name, s in SENSORS.items()
    }
)


#: The paper's cameras with their lenses (Sec. 6): Figs. 5-7 a Canon 1D Mark II with an 85 mm lens (at
#: f/8 and f/4), Figs. 1, 8 and two rows of Fig. 11 a Canon PowerShot A80 at 7.8 mm (f/2.8), Fig. 11 (a)
#: a Nikon D50 with a 180 mm lens (f/4.8). Unlike :data:`CAMERA_PRESETS`' same-field-of-view presets,
#: each keeps its real focal length, so their fields of view differ (18.4°, 49.3°, 7.3° horizontally
#: at the focus distances below). f-number and focus distance are the paper's; scenes set their own focus.
PAPER_CAMERAS: Mapping[str, ThinLensCamera] = MappingProxyType(
    {
        "canon_1d_mark_ii_85mm": ThinLensCamera(
            sensor_width_mm=SENSORS["canon_1d_mark_ii"].width_mm,
            sensor_height_mm=SENSORS["canon_1d_mark_ii"].height_mm,
            focal_length_mm=85.0, f_number=8.0, focus_distance_m=2.0),
        "powershot_a80_7_8mm": ThinLensCamera(
            sensor_width_mm=SENSORS["canon_powershot_a80"].width_mm,
            sensor_height_mm=SENSORS["canon_powershot_a80"].height_mm,
            focal_length_mm=7.8, f_number=2.8, focus_distance_m=2.0),
        "nikon_d50_180mm": ThinLensCamera(
            sensor_width_mm=SENSORS["nikon_d50"].width_mm,
            sensor_height_mm=SENSORS["nikon_d50"].height_mm,
            focal_length_mm=180.0, f_number=4.8, focus_distance_m=6.0),
    }
)

#: Every named camera: the same-field-of-view sensor presets and the paper's cameras with their lenses.
CAMERA_PRESETS: Mapping[str, ThinLensCamera] = MappingProxyType({**_SAME_FOV_PRESETS, **PAPER_CAMERAS})


def camera_preset(name: str, **changes) -> ThinLensCamera:
    """A camera preset by name, optionally with fields changed (``f_number=4``, ``resolution=...``)."""
    try:
        cam = CAMERA_PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown camera preset {name!r}; choose one of {sorted(CAMERA_PRESETS)}") from None
    return cam.replace(**changes) if changes else cam
