"""Scene definitions: what a scene is, its presets, and geometry helpers shared by the scenes.

Every scene is modelled in *camera space*: the camera of :func:`scenes.mitsuba_camera.thinlens_sensor_dict`
sits at the origin looking down +z with +y up, so world +x appears on the image's **left**.
The helpers below take image-space layouts (``u`` from −1 at the left edge to +1 at the right edge,
``v`` from −1 at the bottom to +1 at the top, for the scene's default field of view) and produce
world geometry, and they map texture arrays so that array row 0 is at the top of the image and
column 0 on the left (``tests/test_scenes.py`` checks this on a render).

Mitsuba is imported lazily inside the builders: the caller selects a variant first
(:func:`scenes.backend.import_mitsuba`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np

from ..camera import CAMERA_PRESETS, ThinLensCamera, camera_preset
from ..mitsuba_camera import thinlens_sensor_dict

__all__ = [
    "DEFAULT_F_NUMBERS",
    "EMISSION_ONLY_INTEGRATOR",
    "PATH_INTEGRATOR",
    "PRESETS",
    "REF_WIDTH_PX",
    "SAMPLER",
    "SceneDefinition",
    "ambient_light",
    "area_light",
    "black_bsdf",
    "emissive",
    "facing_rectangle",
    "image_extent",
    "radiance_texture",
    "reflectance_texture",
    "spp_per_preset",
]

#: Resolution presets (width, height) in pixels: ``small`` for CI, ``full`` for the figures.
PRESETS: Mapping[str, tuple[int, int]] = MappingProxyType({"small": (160, 120), "full": (640, 480)})
#: Image width (px) of the ``full`` preset: the reference width of the procedural scenes' defocus draw
#: and texture scales (:mod:`scenes.library.procedural`).
REF_WIDTH_PX = PRESETS["full"][0]
#: The paper's Fig. 7 pair of apertures: f/8 photograph and f/4 photograph.
DEFAULT_F_NUMBERS = (8.0, 4.0)
#: Mitsuba sampler used for every render. Multi-jittered samples converge much faster than
#: independent ones on the lens/pixel integral (measured here on a defocused photo at 320x240:
#: RMSE 0.0052 vs 0.018 at 64 spp).
SAMPLER = "multijitter"
#: Integrator of emissive-only scenes: camera rays return the emission of the first surface hit and
#: nothing else. Every surface has a black BSDF, so this is exactly what ``direct`` computes (its
#: light-sampling terms are all zero) without the wasted shadow rays: measured 10x faster here
#: (planes, 160x120, 256 spp: 0.3 s vs 4 s). No lighting noise either way.
EMISSION_ONLY_INTEGRATOR: Mapping = MappingProxyType({"type": "path", "max_depth": 1})
#: Integrator of the scenes where lighting is the point (soft shadows, glossy highlights): path
#: tracing with up to three bounces.
PATH_INTEGRATOR: Mapping = MappingProxyType({"type": "path", "max_depth": 4})


def spp_per_preset(spp: int) -> Mapping[str, int]:
    """The same samples per pixel for every resolution preset: ``{"small": spp, "full": spp}``."""
    return MappingProxyType({name: int(spp) for name in PRESETS})


def _check_preset(preset: str) -> tuple[int, int]:
    try:
        return PRESETS[preset]
    except KeyError:
        raise ValueError(f"unknown resolution preset {preset!r}; choose one of {sorted(PRESETS)}") from None


@dataclasses.dataclass(frozen=True)
class SceneDefinition:
    """A procedural scene: metadata, default camera and a Mitsuba scene-dictionary builder.

    Attributes
    ----------
    name : str
        Registry key.
    version : int
        Informational (shown by ``--list`` and in the sidecar). Not part of the render cache key, which
        hashes the scene's content (:func:`scenes.render.scene_content_hash`): no need to bump it.
    description : str
        One line for ``--list``.
    focus_distance_m : float
        Default focus distance D of the scene's camera, metres.
    shapes : callable () -> dict
        Returns the scene's shapes/emitters as Mitsuba dictionary entries (camera space, metres).
        Called after a Mitsuba variant has been selected.
    integrator : mapping
        Mitsuba integrator dictionary. Default :data:`EMISSION_ONLY_INTEGRATOR` for emissive-only
        scenes; ``path`` with real lighting where lighting is the point.
    default_spp : mapping of str to int
        Samples per pixel per resolution preset.
    camera_name : str
        Key of :data:`scenes.camera.CAMERA_PRESETS` the default camera starts from.
    facts : mapping
        Known ground truth the tests check (e.g. exact depths of fronto-parallel planes, metres).
    """

    name: str
    version: int
    description: str
    focus_distance_m: float
    shapes: Callable[[], dict]
    integrator: Mapping = dataclasses.field(default_factory=lambda: EMISSION_ONLY_INTEGRATOR)
    default_spp: Mapping = dataclasses.field(default_factory=lambda: spp_per_preset(256))
    camera_name: str = "full_frame"
    facts: Mapping = dataclasses.field(default_factory=lambda: MappingProxyType({}))

    def camera(
        self,
        preset: str = "small",
        *,
        f_number: float | None = None,
        camera_name: str | None = None,
        resolution: tuple[int, int] | None = None,
        **changes,
    ) -> ThinLensCamera:
        """The scene's default camera.

        Parameters
        ----------
        preset : {"small", "full"}
            Resolution preset (ignored when ``resolution`` is given).
        f_number : float, optional, keyword-only
            N (default 8, the first of :data:`DEFAULT_F_NUMBERS`).
        camera_name : str, optional, keyword-only
            A :data:`scenes.camera.CAMERA_PRESETS` key (default: the scene's, full frame 50 mm).
            All presets share one field of view, so the framing stays the same.
        resolution : (int, int), optional, keyword-only
            (width, height) in pixels, overriding the preset.
        **changes
            Further :class:`~scenes.camera.ThinLensCamera` fields (``focus_distance_m=...``).

        Returns
        -------
        ThinLensCamera
        """
        res = resolution if resolution is not None else _check_preset(preset)
        fields = dict(
            focus_distance_m=self.focus_distance_m,
            f_number=DEFAULT_F_NUMBERS[0] if f_number is None else f_number,
            resolution=tuple(res),
        )
        fields.update(changes)
        return camera_preset(camera_name or self.camera_name, **fields)

    def spp(self, preset: str = "small") -> int:
        """Default samples per pixel for a resolution preset."""
        _check_preset(preset)
        return int(self.default_spp[preset])

    def build(self, camera: ThinLensCamera, *, spp: int, seed: int = 0) -> dict:
        """Mitsuba scene dictionary for ``camera`` (``thinlens`` sensor, ``box`` pixel filter).

        Parameters
        ----------
        camera : ThinLensCamera
        spp : int, keyword-only
            Samples per pixel of the sensor's sampler (> 0).
        seed : int, keyword-only
            Sampler seed.

        Returns
        -------
        dict
            For ``mitsuba.load_dict``.
        """
        sensor = thinlens_sensor_dict(camera, spp=spp, seed=seed, pixel_filter="box")
        sensor["sampler"] = {"type": SAMPLER, "sample_count": int(spp), "seed": int(seed)}
        scene = {"type": "scene", "integrator": dict(self.integrator), "sensor": sensor}
        shapes = self.shapes()
        clash = set(shapes) & set(scene)
        if clash:
            raise ValueError(f"scene {self.name!r} uses reserved keys {sorted(clash)}")
        scene.update(shapes)
        return scene


def image_extent(focus_distance_m: float, *, camera_name: str = "full_frame", aspect: float = 0.75) -> tuple[float, float]:
    """tan of the half field of view (horizontal, vertical) of a scene's default camera.

    The horizontal half-angle is atan(W / (2v)) with v = f·D/(D − f); the vertical one follows
    from the ``aspect`` (height / width) of the presets (square pixels).

    Returns
    -------
    (float, float)
        (tan_half_x, tan_half_y), dimensionless.
    """
    cam = CAMERA_PRESETS[camera_name].replace(focus_distance_m=focus_distance_m)
    tx = math.tan(math.radians(cam.fov_x_deg) / 2.0)
    return tx, tx * aspect


def area_light(to_world, radiance) -> dict:
    """A one-sided rectangular area light (Mitsuba ``rectangle`` with an ``area`` emitter).

    Parameters
    ----------
    to_world : mitsuba.ScalarTransform4f
        Placement of the unit rectangle [-1, 1]² (it emits along its +z normal), metres.
    radiance : sequence of 3 float
        Linear RGB radiance.

    Returns
    -------
    dict
    """
    return {"type": "rectangle", "to_world": to_world,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": list(radiance)}}}


def ambient_light(radiance) -> dict:
    """A constant environment emitter of linear RGB ``radiance`` (3 floats): the fill light."""
    return {"type": "constant", "radiance": {"type": "rgb", "value": list(radiance)}}


def black_bsdf() -> dict:
    """A BSDF reflecting nothing: emissive surfaces then show exactly their emission."""
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}


def _bitmap_texture(texture: np.ndarray, *, repeat=(1.0, 1.0), filter_type="bilinear") -> dict:
    import mitsuba as mi

    tex = np.ascontiguousarray(np.asarray(texture, dtype=np.float32)[::-1])  # row 0 → top of image
    d = {"type": "bitmap", "bitmap": mi.Bitmap(tex), "filter_type": filter_type, "wrap_mode": "repeat"}
    if tuple(repeat) != (1.0, 1.0):
        d["to_uv"] = mi.ScalarTransform3f().scale([float(repeat[0]), float(repeat[1])])
    return d


def radiance_texture(texture: np.ndarray, *, repeat=(1.0, 1.0), scale: float = 1.0) -> dict:
    """Area-emitter radiance from an HxWx3 linear texture (float32 arrays are not gamma-decoded)."""
    t = np.asarray(texture, dtype=np.float32)
    return _bitmap_texture(t * np.float32(scale) if scale != 1.0 else t, repeat=repeat)


def reflectance_texture(texture: np.ndarray, *, repeat=(1.0, 1.0)) -> dict:
    """Diffuse reflectance from an HxWx3 linear texture with values in [0, 1]."""
    return _bitmap_texture(texture, repeat=repeat)


def emissive(shape: dict, texture: np.ndarray, *, repeat=(1.0, 1.0), scale: float = 1.0) -> dict:
    """Make ``shape`` a black surface emitting ``texture`` (radiance = texel value, linear)."""
    out = dict(shape)
    out["bsdf"] = black_bsdf()
    out["emitter"] = {"type": "area", "radiance": radiance_texture(texture, repeat=repeat, scale=scale)}
    return out


def facing_rectangle(z: float, u0: float, u1: float, v0: float, v1: float, *, extent: tuple[float, float]) -> dict:
    """A fronto-parallel rectangle at depth ``z`` covering an image-space box, facing the camera.

    Parameters
    ----------
    z : float
        Camera-space depth of the plane, metres.
    u0, u1 : float
        Left and right edge in the image, −1 (left border) … +1 (right border); may exceed ±1.
    v0, v1 : float
        Bottom and top edge, −1 (bottom border) … +1 (top border).
    extent : (float, float), keyword-only
        :func:`image_extent` of the scene's default camera.

    Returns
    -------
    dict
        A Mitsuba ``rectangle`` whose normal points at the camera (−z) and whose texture
        coordinates put a texture array's column 0 on the image left and row 0 at the top.

    Notes
    -----
    The ``rectangle`` spans [−1, 1]² in its local xy plane with normal +z. Rotating it by 180°
    about y turns the normal to −z (area emitters only emit on the normal's side) and maps local
    +x to world −x, which appears on the image *right* (RENDERING-FACTS), so texture u increases
    to the right. World +y is image up.
    """
    import mitsuba as mi

    if not (u1 > u0 and v1 > v0 and z > 0):
        raise ValueError(f"bad rectangle z={z}, u=({u0}, {u1}), v=({v0}, {v1}); need z > 0, u1 > u0, v1 > v0")
    tx, ty = extent
    cx = -0.5 * (u0 + u1) * tx * z  # image right is world −x
    cy = 0.5 * (v0 + v1) * ty * z
    hw = 0.5 * (u1 - u0) * tx * z
    hh = 0.5 * (v1 - v0) * ty * z
    T = mi.ScalarTransform4f
    return {
        "type": "rectangle",
        "to_world": T().translate([cx, cy, z]) @ T().rotate([0, 1, 0], 180) @ T().scale([hw, hh, 1.0]),
    }
