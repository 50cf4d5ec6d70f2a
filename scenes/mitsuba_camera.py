"""Map a :class:`~scenes.camera.ThinLensCamera` to Mitsuba's ``thinlens`` sensor.

The mapping follows ``RENDERING-FACTS.md`` (measured with Mitsuba 3.9):

* ``aperture_radius`` R = f / (2N) (a uniform disk),
* ``focus_distance`` = D (the focal surface is the plane z_cam = D),
* ``fov`` = 2·atan(W / (2v)) along x, with v = f·D/(D − f) the lens–sensor distance
  (the naive 2·atan(W/(2f)) under-states the blur by (D − f)/D),
* the camera sits at the origin looking down +z with +y up; no scale in ``to_world``
  (world +x then appears on the image's *left*).

``tests/test_calibration.py`` re-measures that the rendered blur equals Eq. (5).
"""

from __future__ import annotations

__all__ = ["CAMERA_FORWARD", "CAMERA_ORIGIN", "CAMERA_UP", "thinlens_sensor_dict"]

#: Camera pose shared by every scene: scenes are modelled in camera space.
CAMERA_ORIGIN = (0.0, 0.0, 0.0)
CAMERA_FORWARD = (0.0, 0.0, 1.0)
CAMERA_UP = (0.0, 1.0, 0.0)


def thinlens_sensor_dict(camera, *, spp, seed=0, pixel_filter="box", near_clip=0.01, far_clip=1e4):
    """Mitsuba scene-dictionary entry of a ``thinlens`` sensor for ``camera``.

    Parameters
    ----------
    camera : scenes.camera.ThinLensCamera
        Physical camera; distances in metres.
    spp : int, keyword-only
        Samples per pixel (> 0).
    seed : int, keyword-only
        Sampler seed.
    pixel_filter : {"box", "gaussian"}, keyword-only
        Reconstruction filter; its σ (1/√12 px for box, 0.5 px for gaussian) adds to the blur.
    near_clip, far_clip : float, keyword-only
        Clip distances in metres.

    Returns
    -------
    dict
        To be placed under a ``"sensor"`` key of a scene dictionary.
    """
    import mitsuba as mi  # the caller has already selected a variant

    if not (isinstance(spp, int) and spp > 0):
        raise ValueError(f"spp={spp!r} is invalid; allowed: integer > 0")
    if pixel_filter not in ("box", "gaussian"):
        raise ValueError(f"pixel_filter={pixel_filter!r} is invalid; allowed: 'box' or 'gaussian'")
    width, height = camera.resolution
    return {
        "type": "thinlens",
        "aperture_radius": camera.aperture_radius_m,
        "focus_distance": camera.focus_distance_m,
        "fov": camera.fov_x_deg,
        "fov_axis": "x",
        "near_clip": near_clip,
        "far_clip": far_clip,
        "to_world": mi.ScalarTransform4f().look_at(
            origin=list(CAMERA_ORIGIN), target=list(CAMERA_FORWARD), up=list(CAMERA_UP)
        ),
        "sampler": {"type": "independent", "sample_count": spp, "seed": int(seed)},
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": height,
            "rfilter": {"type": pixel_filter},
            "pixel_format": "rgb",
            "component_format": "float32",
        },
    }
