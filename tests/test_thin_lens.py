"""Eq. (5)/(6) closed forms against hand-computed numbers (scenes/thin_lens.py)."""

import math

import numpy as np
import pytest

from scenes.thin_lens import (
    BOX_FILTER_SIGMA_PX,
    GAUSSIAN_FILTER_SIGMA_PX,
    SIGMA_CONVENTIONS,
    circle_of_confusion,
    coc_to_sigma,
    lens_sensor_distance,
    relative_circle_of_confusion,
)
from tolerances import THIN_LENS_RTOL


def test_eq5_hand_computed_scene_camera():
    # f = 50 mm, N = 8, D = 0.2 m, S = 2 m: c = (1.8/2) * 0.0025 / (8 * 0.15) = 0.001875 m.
    c = circle_of_confusion(2.0, focal_length=0.05, f_number=8.0, focus_distance=0.2)
    assert c == pytest.approx(0.001875, rel=THIN_LENS_RTOL)


def test_eq5_hand_computed_paper_fig10():
    # Fig. 10 setting: f = 8.5 cm, D = 200 cm, N = 4, S = 100 cm: c = 1 * 0.085^2 / (4 * 1.915).
    c = circle_of_confusion(1.0, focal_length=0.085, f_number=4.0, focus_distance=2.0)
    assert c == pytest.approx(0.007225 / 7.66, rel=THIN_LENS_RTOL)
    assert c == pytest.approx(9.432114882506527e-4, rel=1e-12)


def test_eq5_in_focus_infinity_and_array_shape():
    kw = dict(focal_length=0.05, f_number=4.0, focus_distance=1.5)
    assert circle_of_confusion(1.5, **kw) == 0.0
    limit = 0.05**2 / (4.0 * 1.45)
    assert circle_of_confusion(np.inf, **kw) == pytest.approx(limit, rel=THIN_LENS_RTOL)
    s = np.array([[0.5, 1.5], [3.0, np.inf]])
    c = circle_of_confusion(s, **kw)
    assert c.shape == (2, 2)
    # Symmetric in 1/S: S = 0.75 (in front) and S = inf are |1/S - 1/D| = 1/1.5 apart from focus.
    assert circle_of_confusion(0.75, **kw) == pytest.approx(limit, rel=THIN_LENS_RTOL)


def test_eq5_inverse_in_f_number():
    kw = dict(focal_length=0.05, focus_distance=0.25)
    c8 = circle_of_confusion(1.0, f_number=8.0, **kw)
    c4 = circle_of_confusion(1.0, f_number=4.0, **kw)
    assert c4 / c8 == pytest.approx(2.0, rel=THIN_LENS_RTOL)


def test_eq6_relative_coc_and_sensor_scaling():
    # Full frame (36 mm, f' = 50/36) and the PowerShot A80's 7.18 mm sensor at the same f'.
    fprime = 50.0 / 36.0
    kw = dict(relative_focal_length=fprime, f_number=2.8, focus_distance=2.0)
    c_ff = relative_circle_of_confusion(1.0, sensor_width=0.036, **kw)
    c_cp = relative_circle_of_confusion(1.0, sensor_width=0.00718, **kw)
    # Hand computed: c' = |S-D|/S * f'^2 X / (N (D - f' X)).
    assert c_ff == pytest.approx(1.0 * fprime**2 * 0.036 / (2.8 * (2.0 - 0.05)), rel=THIN_LENS_RTOL)
    assert c_cp == pytest.approx(fprime**2 * 0.00718 / (2.8 * (2.0 - fprime * 0.00718)), rel=THIN_LENS_RTOL)
    # To first order proportional to the sensor width.
    assert c_ff / c_cp == pytest.approx(0.036 / 0.00718, rel=0.03)


def test_lens_sensor_distance():
    assert lens_sensor_distance(0.05, 0.2) == pytest.approx(0.01 / 0.15, rel=THIN_LENS_RTOL)
    with pytest.raises(ValueError):
        lens_sensor_distance(0.05, 0.05)


def test_coc_to_sigma_conventions():
    assert BOX_FILTER_SIGMA_PX == pytest.approx(1 / math.sqrt(12), rel=THIN_LENS_RTOL)
    assert GAUSSIAN_FILTER_SIGMA_PX == 0.5
    assert set(SIGMA_CONVENTIONS) == {"line_spread", "erf_fit"}
    assert coc_to_sigma(4.0) == pytest.approx(math.sqrt(1.0 + 1 / 12), rel=THIN_LENS_RTOL)
    assert coc_to_sigma(4.0, convention="erf_fit") == pytest.approx(math.sqrt(1.092**2 + 1 / 12), rel=THIN_LENS_RTOL)
    assert coc_to_sigma(0.0) == pytest.approx(BOX_FILTER_SIGMA_PX, rel=THIN_LENS_RTOL)
    assert coc_to_sigma(8.0, filter_sigma_px=0.0) == pytest.approx(2.0, rel=THIN_LENS_RTOL)
    # The filter term does not double when the aperture (CoC) doubles.
    s1, s2 = coc_to_sigma(2.0), coc_to_sigma(4.0)
    assert s2 / s1 < 2.0


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(focal_length=0.05, f_number=0.0, focus_distance=1.0),
        dict(focal_length=0.05, f_number=-2.0, focus_distance=1.0),
        dict(focal_length=0.05, f_number=4.0, focus_distance=0.05),
        dict(focal_length=0.0, f_number=4.0, focus_distance=1.0),
    ],
)
def test_eq5_rejects_bad_parameters(kwargs):
    with pytest.raises(ValueError):
        circle_of_confusion(1.0, **kwargs)


def test_coc_to_sigma_rejects_unknown_convention():
    with pytest.raises(ValueError, match="unknown sigma convention"):
        coc_to_sigma(1.0, convention="fwhm")
    with pytest.raises(ValueError):
        coc_to_sigma(1.0, filter_sigma_px=-1.0)
