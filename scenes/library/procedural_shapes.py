"""Mitsuba shapes of a procedural scene's layout (:func:`.procedural.draw_layout`): geometry, textures,
materials and lights, in camera space (metres).

Every surface carries a sharp texture of a texture family (:func:`scenes.analytic.families.texture_bitmap`,
decoded from display values to linear), looked up nearest-texel (a texel is a sharp square, no
interpolation blur) and mirrored at each repeat (no seam edge); repeats are chosen so that a texel spans
about 1/``texels_per_px`` px at the ``full`` preset. Emission-only scenes emit the texture (black BSDF);
lit scenes reflect it (diffuse, or GGX rough plastic for glossy surfaces) under a key area light and an
ambient fill. The background wall emits its texture in both. Mitsuba is imported inside the functions
(the caller selects a variant first).
"""

from __future__ import annotations

import functools
import math
from types import MappingProxyType

import numpy as np

from .base import REF_WIDTH_PX, image_extent

__all__ = ["layout_shapes"]

#: Texture side (texels) per family (flat patches are slow to draw: a smaller tile, repeated).
_TEXTURE_SIZE = MappingProxyType({"flat_patches": 256})
_DEFAULT_TEXTURE_SIZE = 512


@functools.lru_cache(maxsize=32)
def _texture(family: str, seed: int, key: tuple, *, scale: float) -> np.ndarray:
    """A sharp texture of ``family`` as linear float32 values in [0, scale] (decoded from display values);
    cached (read-only): a scene's shapes are built for its hash and again for its render."""
    from ..analytic.families import texture_bitmap
    from ..display import srgb_to_linear

    size = _TEXTURE_SIZE.get(family, _DEFAULT_TEXTURE_SIZE)
    out = (srgb_to_linear(texture_bitmap(family, size, seed=seed, key=key)) * scale).astype(np.float32)
    out.setflags(write=False)
    return out


def _bitmap(texture: np.ndarray, repeat: float) -> dict:
    """A Mitsuba bitmap texture with nearest-texel lookup (each texel a sharp square: no interpolation
    blur) repeated ``repeat`` times along u and v, mirrored at each repeat (no seam edge)."""
    import mitsuba as mi

    tex = np.ascontiguousarray(np.asarray(texture, dtype=np.float32)[::-1])  # row 0 → top of the image
    out = {"type": "bitmap", "bitmap": mi.Bitmap(tex), "filter_type": "nearest", "wrap_mode": "mirror"}
    if repeat != 1.0:
        out["to_uv"] = mi.ScalarTransform3f().scale([float(repeat), float(repeat)])
    return out


def _repeat(extent_px: float, texels_per_px: float, family: str) -> float:
    """Whole repeats of the texture so that a texel spans about 1/texels_per_px px at the full preset."""
    size = _TEXTURE_SIZE.get(family, _DEFAULT_TEXTURE_SIZE)
    return float(max(1, round(extent_px * texels_per_px / size)))


def _material(shape: dict, obj: dict, *, seed: int, key: tuple, extent_px: float, lighting: str) -> dict:
    """``shape`` with the object's texture: emitted (emission-only scenes) or reflected (lit scenes)."""
    rep = _repeat(extent_px, obj["texels_per_px"], obj["family"])
    out = dict(shape)
    if lighting == "emission":
        out["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
        out["emitter"] = {"type": "area", "radiance": _bitmap(_texture(obj["family"], seed, key, scale=0.9), rep)}
    elif obj.get("glossy"):
        out["bsdf"] = {"type": "roughplastic", "distribution": "ggx", "alpha": obj["roughness"],
                       "diffuse_reflectance": _bitmap(_texture(obj["family"], seed, key, scale=0.8), rep)}
    else:
        out["bsdf"] = {"type": "diffuse", "reflectance": _bitmap(_texture(obj["family"], seed, key, scale=0.85), rep)}
    return out


def _geometry(obj: dict, ext) -> tuple[dict, float]:
    """Mitsuba shape dict (no material) of an object and its extent in full-preset px."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    z, tx, ty = obj["depth_m"], ext[0], ext[1]
    x, y = -obj["u"] * tx * z, obj["v"] * ty * z  # image right is world −x
    half = obj["size_frac"] * tx * z  # half-size, metres
    px_per_m = REF_WIDTH_PX / (2.0 * tx * z)
    kind = obj["kind"]
    if kind == "plane":
        hw, hh = half * math.sqrt(obj["aspect"]), half / math.sqrt(obj["aspect"])
        to_world = (T().translate([x, y, z]) @ T().rotate([1, 0, 0], obj["tilt_x_deg"])
                    @ T().rotate([0, 1, 0], obj["tilt_y_deg"]) @ T().rotate([0, 0, 1], obj["roll_deg"])
                    @ T().rotate([0, 1, 0], 180) @ T().scale([hw, hh, 1.0]))
        return {"type": "rectangle", "to_world": to_world}, 2.0 * max(hw, hh) * px_per_m
    if kind == "box":
        s = [half * c for c in obj["scale"]]
        to_world = (T().translate([x, y, z + max(s)]) @ T().rotate(obj["axis"], obj["angle_deg"]) @ T().scale(s))
        return {"type": "cube", "to_world": to_world}, 2.0 * max(s) * px_per_m
    if kind == "sphere":
        to_world = T().translate([x, y, z + half]) @ T().rotate([1, 0, 0], -90) @ T().scale([half] * 3)
        return {"type": "sphere", "to_world": to_world}, math.pi * 2.0 * half * px_per_m
    r = half * obj["radius_frac"]
    a, t = math.radians(obj["angle_deg"]), math.radians(obj["tilt_deg"])
    d = np.array([math.cos(a) * math.cos(t), math.sin(a) * math.cos(t), math.sin(t)]) * half
    c = np.array([x, y, z + r])
    return ({"type": "cylinder", "p0": [float(v) for v in c - d], "p1": [float(v) for v in c + d], "radius": r},
            2.0 * half * px_per_m)


def _background(layout: dict, ext) -> dict:
    """The wall (and floor) of a layout as Mitsuba shapes with their textures (emitted in every scene:
    a bright backdrop, lit by nothing, keeps the exposure of lit scenes)."""
    import mitsuba as mi

    from .base import facing_rectangle

    T = mi.ScalarTransform4f
    bg, seed = layout["background"], layout["seed"]
    z = bg["depth_m"]
    out = {}
    wall = facing_rectangle(z, -1.5, 1.5, -1.5, 1.5, extent=ext)
    emit = {**bg, "glossy": False}
    out["background"] = _material(wall, emit, seed=seed, key=(1000,), extent_px=1.5 * REF_WIDTH_PX, lighting="emission")
    floor = bg["floor"]
    if floor is not None:
        y = -floor["below_frac"] * ext[1] * layout["focus_distance_m"]
        z0 = min([layout["focus_distance_m"] * 0.3, *(o["depth_m"] * 0.9 for o in layout["objects"])])
        half_w = 1.6 * ext[0] * z
        shape = {"type": "rectangle",
                 "to_world": T().translate([0.0, y, 0.5 * (z0 + z)]) @ T().rotate([1, 0, 0], -90)
                 @ T().scale([half_w, 0.5 * (z - z0), 1.0])}
        obj = {**floor, "glossy": False, "roughness": 0.1}
        depth_px = REF_WIDTH_PX * (z - z0) / (2.0 * ext[0] * layout["focus_distance_m"])
        out["floor"] = _material(shape, obj, seed=seed, key=(1001,), extent_px=min(depth_px, 4 * REF_WIDTH_PX),
                                 lighting=layout["lighting"])
    return out


def _light(layout: dict, ext) -> dict:
    """Key area light (soft shadows) above one side of the subject, aimed at it, and a dim ambient fill."""
    import mitsuba as mi

    from .base import ambient_light, area_light

    light, d = layout["light"], layout["focus_distance_m"]
    size = light["size_frac"] * ext[0] * d
    pos = np.array([light["side"] * ext[0] * d, light["height_frac"] * ext[1] * d * 2.0, 0.5 * d])
    target = np.array([-layout["subject"]["u"] * ext[0] * d, layout["subject"]["v"] * ext[1] * d, d])
    dist = float(np.linalg.norm(target - pos))
    # irradiance ≈ L·A/dist² at the subject; aim for E ≈ π·0.9 (a white diffuse surface at 0.9)
    radiance = math.pi * 0.9 * dist * dist / (4.0 * size * size)
    T = mi.ScalarTransform4f
    to_world = T().look_at(origin=[float(v) for v in pos], target=[float(v) for v in target], up=[0, 0, 1]) \
        @ T().scale([size, size, 1.0])
    return {"key_light": area_light(to_world, [radiance, radiance * 0.97, radiance * 0.92]),
            "ambient": ambient_light([light["ambient"]] * 3)}


def layout_shapes(layout: dict) -> dict:
    """The Mitsuba shapes, materials and lights of a :func:`.procedural.draw_layout` (camera space, metres)."""
    ext = image_extent(layout["focus_distance_m"], camera_name=layout["camera_name"])
    out = _background(layout, ext)
    seed, lighting = layout["seed"], layout["lighting"]
    for i, obj in enumerate([layout["subject"], *layout["objects"]]):
        shape, extent_px = _geometry(obj, ext)
        name = "subject" if i == 0 else f"object_{i:02d}_{obj['kind']}"
        out[name] = _material(shape, obj, seed=seed, key=(i,), extent_px=extent_px, lighting=lighting)
    if lighting == "lit":
        out.update(_light(layout, ext))
    return out
