"""Camera validation, derived Mitsuba parameters, same_field_of_view (scenes/camera.py)."""

import math

import numpy as np
import pytest

from scenes.camera import CAMERA_PRESETS, SENSORS, ThinLensCamera, camera_preset, same_field_of_view
from scenes.thin_lens import circle_of_confusion
from tolerances import THIN_LENS_RTOL


@pytest.mark.parametrize(
    "changes, name",
    [
        (dict(f_number=0.0), "f_number"),
        (dict(f_number=-4.0), "f_number"),
        (dict(f_number=float("nan")), "f_number"),
        (dict(f_number=float("inf")), "f_number"),
        (dict(focus_distance_m=0.05), "focus_distance_m"),
        (dict(focus_distance_m=0.03), "focus_distance_m"),
        (dict(sensor_width_mm=0.0), "sensor_width_mm"),
        (dict(sensor_height_mm=-1.0), "sensor_height_mm"),
        (dict(focal_length_mm=0.0), "focal_length_mm"),
        (dict(resolution=(0, 10)), "resolution"),
        (dict(resolution=(10,)), "resolution"),
        (dict(resolution=(10.5, 10)), "resolution"),
    ],
)
def test_camera_validation_names_the_field(changes, name):
    with pytest.raises(ValueError, match=name):
        ThinLensCamera(**changes)


def test_camera_derived_quantities():
    cam = ThinLensCamera(focal_length_mm=50.0, f_number=4.0, focus_distance_m=0.25, resolution=(640, 480))
    assert cam.aperture_radius_m == pytest.approx(0.05 / 8.0, rel=THIN_LENS_RTOL)
    v = 0.05 * 0.25 / 0.2
    assert cam.lens_sensor_distance_m == pytest.approx(v, rel=THIN_LENS_RTOL)
    assert cam.fov_x_deg == pytest.approx(math.degrees(2 * math.atan(0.018 / v)), rel=THIN_LENS_RTOL)
    assert cam.pixel_pitch_m == pytest.approx(0.036 / 640, rel=THIN_LENS_RTOL)
    z = np.array([0.125, 0.25, 2.0])
    expect = circle_of_confusion(z, focal_length=0.05, f_number=4.0, focus_distance=0.25) / (0.036 / 640)
    np.testing.assert_allclose(cam.coc_px(z), expect, rtol=THIN_LENS_RTOL)
    # Hand computed: S = 2 m → c = (1.75/2) * 0.0025 / (4 * 0.2) = 2.734375 mm = 48.61 px.
    assert cam.coc_px(2.0) == pytest.approx(0.002734375 / (0.036 / 640), rel=THIN_LENS_RTOL)
    d = cam.to_dict()
    assert d["resolution"] == [640, 480] and d["aperture_radius_m"] == cam.aperture_radius_m


@pytest.mark.parametrize("sensor", sorted(SENSORS))
def test_same_field_of_view_keeps_f_number_and_fov(sensor):
    cam = CAMERA_PRESETS["full_frame"].replace(f_number=5.6, focus_distance_m=2.0, resolution=(320, 240))
    other = same_field_of_view(cam, sensor)
    assert other.f_number == 5.6
    assert other.focus_distance_m == 2.0 and other.resolution == (320, 240)
    assert other.relative_focal_length == pytest.approx(cam.relative_focal_length, rel=THIN_LENS_RTOL)
    assert other.sensor_width_mm == SENSORS[sensor].width_mm
    # Same field of view to first order (exact at infinity focus); within (D - f) effects.
    assert other.fov_x_deg == pytest.approx(cam.fov_x_deg, rel=0.03)


def test_same_field_of_view_blur_scales_with_sensor():
    cam = CAMERA_PRESETS["full_frame"].replace(focus_distance_m=2.0)
    small = same_field_of_view(cam, "canon_powershot_a80")
    ratio = cam.coc_px(8.0) / small.coc_px(8.0)
    assert ratio == pytest.approx(36.0 / 7.18, rel=0.03)


def test_camera_preset_lookup():
    assert camera_preset("full_frame").focal_length_mm == pytest.approx(50.0)
    assert camera_preset("full_frame", f_number=4.0).f_number == 4.0
    with pytest.raises(ValueError, match="unknown camera preset"):
        camera_preset("nikon")
    with pytest.raises(ValueError, match="unknown sensor preset"):
        same_field_of_view(CAMERA_PRESETS["full_frame"], "nope")
