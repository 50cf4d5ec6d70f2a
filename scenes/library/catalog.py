"""The scenes: procedural geometry in camera space (metres), textures from :mod:`.textures`.

Depths and focus distances are chosen so that σ_gt spans from the box-filter floor (0.29 px) to
about 2 px at the ``small`` preset at f/8 and to 12–17 px at the ``full`` preset at f/4: a 50 mm lens
on full frame focused at 0.2–0.25 m ("tabletop" scale), objects from 0.12 m to 2 m.
Blur in pixels grows with resolution (Eq. 5 divided by the pixel pitch) and with 1/N.

Emissive textured surfaces with black BSDFs, rendered with only directly visible emission
(:data:`.base.EMISSION_ONLY_INTEGRATOR`, equivalent to ``direct`` here: nothing is lit, no lighting
noise) everywhere except ``shadow_gloss``, whose point is real lighting (path tracer).
"""

from __future__ import annotations

import math
from types import MappingProxyType

import numpy as np

from . import textures as tx
from .base import (
    PATH_INTEGRATOR, SceneDefinition, ambient_light, area_light, emissive, facing_rectangle, image_extent,
    reflectance_texture, spp_per_preset,
)

__all__ = ["CLUTTER", "PLANES", "PORTRAIT", "SHADOW_GLOSS", "TILTED_PLANE"]


def _T():
    import mitsuba as mi

    return mi.ScalarTransform4f


# --- planes ------------------------------------------------------------------------------------
_PLANES_D = 0.2
#: (depth m, u0, u1, v0, v1, texture name) — nearer planes occlude farther ones: sharp step edges.
_PLANES_LAYOUT = (
    (2.0, -1.4, 1.4, -1.4, 1.4, "coffee"),
    (0.9, 0.05, 0.85, -1.3, -0.1, "leaves_warm"),
    (0.5, 0.15, 1.3, 0.05, 1.3, "gravel"),
    (0.3, -0.5, 0.3, -1.3, 0.45, "leaves_cool"),
    (0.2, -1.3, -0.3, -0.15, 1.3, "astronaut"),
    (0.13, 0.55, 1.3, -0.75, -0.2, "leaves_green"),
)


def _named_texture(name: str) -> np.ndarray:
    if name == "leaves_warm":
        return tx.dead_leaves(512, seed=11, palette=((0.3, 0.9), (0.1, 0.5), (0.02, 0.2)))
    if name == "leaves_cool":
        return tx.dead_leaves(512, seed=12, palette=((0.02, 0.3), (0.1, 0.6), (0.3, 0.9)))
    if name == "leaves_green":
        return tx.dead_leaves(512, seed=13, palette=((0.02, 0.3), (0.2, 0.8), (0.02, 0.3)))
    if name == "leaves_grey":
        return tx.dead_leaves(512, seed=14)
    return tx.photo(name)


def _planes_shapes() -> dict:
    ext = image_extent(_PLANES_D)
    out = {}
    for i, (z, u0, u1, v0, v1, tex) in enumerate(_PLANES_LAYOUT):
        out[f"plane_{i}_{round(z * 1000)}mm"] = emissive(facing_rectangle(z, u0, u1, v0, v1, extent=ext), _named_texture(tex))
    return out


PLANES = SceneDefinition(
    name="planes",
    version=1,
    description="fronto-parallel textured planes at 0.13/0.2/0.3/0.5/0.9/2 m with sharp step edges (focus 0.2 m)",
    focus_distance_m=_PLANES_D,
    shapes=_planes_shapes,
    facts=MappingProxyType(
        {
            "plane_depths_m": tuple(sorted(p[0] for p in _PLANES_LAYOUT)),
            # The in-focus plane shows skimage's astronaut upright; image-space box (u0, u1, v0, v1).
            "upright_texture": ("astronaut", (-1.3, -0.3, -0.15, 1.3)),
        }
    ),
)


# --- tilted_plane -------------------------------------------------------------------------------
_TILT_D = 0.2
_TILT_Z0 = 0.3      # depth of the plane on the optical axis, m
_TILT_SLOPE = 3.5   # dz/dy along the plane: z = z0 + slope · y


def _tilted_shapes() -> dict:
    T = _T()
    phi = math.degrees(math.atan(_TILT_SLOPE))
    s0, s1 = -0.3, 1.6  # extent along the plane from the optical-axis point, m (fills the frame)
    half_w = 0.45
    along = 0.5 * (s0 + s1)
    sin, cos = math.sin(math.radians(phi)), math.cos(math.radians(phi))
    centre = [0.0, along * cos, _TILT_Z0 + along * sin]
    rect = {
        "type": "rectangle",
        # local +y → up the plane and away (0, cos φ, sin φ); normal → (0, sin φ, −cos φ), towards the camera
        "to_world": T().translate(centre) @ T().rotate([1, 0, 0], phi) @ T().rotate([0, 1, 0], 180)
        @ T().scale([half_w, 0.5 * (s1 - s0), 1.0]),
    }
    return {"tilted": emissive(rect, tx.dead_leaves(512, seed=21, r_max=40.0), repeat=(2.0, 4.0))}


TILTED_PLANE = SceneDefinition(
    name="tilted_plane",
    version=1,
    description="one textured plane receding from 0.18 m (bottom) to 1.0 m (top): continuous depth (focus 0.2 m)",
    focus_distance_m=_TILT_D,
    shapes=_tilted_shapes,
    facts=MappingProxyType({"plane": {"z0_m": _TILT_Z0, "slope_dz_dy": _TILT_SLOPE}}),
)


# --- portrait -----------------------------------------------------------------------------------
_PORTRAIT_D = 0.25


def _portrait_shapes() -> dict:
    T = _T()
    ext = image_extent(_PORTRAIT_D)
    skin = tx.dead_leaves(512, seed=31, r_min=1.5, r_max=25.0, palette=((0.45, 0.8), (0.25, 0.5), (0.15, 0.35)))
    shirt = tx.stripes(256, period=32, colours=((0.6, 0.05, 0.05), (0.85, 0.8, 0.65)))
    return {
        "background": emissive(facing_rectangle(1.5, -1.4, 1.4, -1.4, 1.4, extent=ext), tx.photo("chelsea")),
        "shelf": emissive(
            facing_rectangle(0.6, 0.35, 1.4, -1.4, 0.6, extent=ext),
            tx.dead_leaves(512, seed=32, palette=((0.1, 0.6), (0.1, 0.5), (0.1, 0.4))),
        ),
        "head": emissive(
            {"type": "sphere", "to_world": T().translate([0.0, 0.014, 0.266]) @ T().rotate([1, 0, 0], -90)
             @ T().scale([0.019] * 3)},
            skin,
            repeat=(2.0, 1.0),
        ),
        "neck": emissive(
            {"type": "cylinder", "p0": [0.0, -0.045, 0.27], "p1": [0.0, 0.0, 0.27], "radius": 0.008},
            skin,
        ),
        "torso": emissive(
            {"type": "sphere", "to_world": T().translate([0.0, -0.088, 0.3]) @ T().rotate([1, 0, 0], -90)
             @ T().scale([0.052] * 3)},
            shirt,
            repeat=(6.0, 1.0),
        ),
        "foreground": emissive(
            facing_rectangle(0.125, 0.62, 1.4, -1.4, -0.55, extent=ext),
            tx.dead_leaves(512, seed=33, palette=((0.02, 0.25), (0.2, 0.7), (0.02, 0.2))),
        ),
    }


PORTRAIT = SceneDefinition(
    name="portrait",
    version=1,
    description="in-focus figure (sphere head, neck, sphere torso) at 0.25 m against a cat photo at 1.5 m, "
    "shelf at 0.6 m, blurred foreground card at 0.125 m",
    focus_distance_m=_PORTRAIT_D,
    shapes=_portrait_shapes,
    facts=MappingProxyType({"background_depth_m": 1.5}),
)


# --- clutter ------------------------------------------------------------------------------------
_CLUTTER_D = 0.25
_CLUTTER_COUNT = 24


def _clutter_shapes() -> dict:
    T = _T()
    ext = image_extent(_CLUTTER_D)
    rng = np.random.default_rng(41)
    out = {
        "background": emissive(
            facing_rectangle(2.0, -1.4, 1.4, -1.4, 1.4, extent=ext),
            tx.dead_leaves(512, seed=40, r_max=80.0),
            repeat=(2.0, 2.0),
        )
    }
    # Depths log-uniform in [0.12, 1.6] m; sizes proportional to depth so objects look similar.
    depths = np.exp(rng.uniform(math.log(0.12), math.log(1.6), _CLUTTER_COUNT))
    for i, z in enumerate(sorted(depths, reverse=True)):
        u, v = rng.uniform(-1.05, 1.05, 2)
        x, y = -u * ext[0] * z, v * ext[1] * z
        size = z * ext[0] * rng.uniform(0.07, 0.18)
        kind = ("sphere", "cube", "card")[i % 3]
        palette = tuple(tuple(sorted(rng.uniform(0.02, 0.9, 2))) for _ in range(3))
        tex = tx.dead_leaves(256, seed=100 + i, r_min=1.5, r_max=30.0, palette=palette)
        if kind == "sphere":
            shape = {"type": "sphere", "to_world": T().translate([x, y, z + size]) @ T().scale([size] * 3)}
        elif kind == "cube":
            axis = rng.normal(size=3)
            shape = {"type": "cube", "to_world": T().translate([x, y, z + size])
                     @ T().rotate(list(axis / np.linalg.norm(axis)), float(rng.uniform(0, 360))) @ T().scale([size] * 3)}
        else:
            shape = {"type": "rectangle", "to_world": T().translate([x, y, z]) @ T().rotate([0, 0, 1], float(rng.uniform(-40, 40)))
                     @ T().rotate([0, 1, 0], 180) @ T().scale([size * 1.3, size, 1.0])}
        out[f"obj_{i:02d}_{kind}"] = emissive(shape, tex)
    return out


CLUTTER = SceneDefinition(
    name="clutter",
    version=1,
    description=f"{_CLUTTER_COUNT} textured spheres, rotated cubes and cards at 0.12-1.6 m before a plane at 2 m (focus 0.25 m)",
    focus_distance_m=_CLUTTER_D,
    shapes=_clutter_shapes,
)


# --- shadow_gloss -------------------------------------------------------------------------------
_SG_D = 0.25
_SG_FLOOR_Y = -0.045


def _shadow_gloss_shapes() -> dict:
    T = _T()
    floor_tex = tx.dead_leaves(512, seed=51, r_max=50.0, palette=((0.35, 0.75), (0.35, 0.7), (0.3, 0.6)))
    wall_tex = tx.photo("brick", lo=0.1, hi=0.7)
    return {
        "floor": {
            "type": "rectangle",
            # local xy → world xz (normal +y, up), spanning z 0.1 … 2.1 m
            "to_world": T().translate([0.0, _SG_FLOOR_Y, 1.1]) @ T().rotate([1, 0, 0], -90) @ T().scale([0.8, 1.0, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(floor_tex, repeat=(3.0, 4.0))},
        },
        "wall": {
            "type": "rectangle",
            "to_world": T().translate([0.0, 0.3, 1.2]) @ T().rotate([0, 1, 0], 180) @ T().scale([0.8, 0.4, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(wall_tex, repeat=(2.0, 1.0))},
        },
        "glossy_sphere": {
            "type": "sphere",
            "center": [0.022, _SG_FLOOR_Y + 0.024, 0.27],
            "radius": 0.024,
            "bsdf": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.06,
                     "diffuse_reflectance": {"type": "rgb", "value": [0.55, 0.08, 0.05]}},
        },
        "occluder": {
            "type": "cube",
            "to_world": T().translate([-0.035, _SG_FLOOR_Y + 0.03, 0.28]) @ T().rotate([0, 1, 0], 30)
            @ T().scale([0.012, 0.03, 0.012]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.35, 0.6]}},
        },
        # facing down (normal −y), above and to the right (world −x is image right) of the objects
        "light": area_light(T().translate([-0.14, 0.2, 0.2]) @ T().rotate([1, 0, 0], 90) @ T().scale([0.05] * 3),
                            [60.0, 58.0, 54.0]),
        "ambient": ambient_light([0.04, 0.045, 0.05]),
    }


SHADOW_GLOSS = SceneDefinition(
    name="shadow_gloss",
    version=1,
    description="path-traced tabletop: soft shadow of a box and a glossy highlight on a sphere at the "
    "focus distance 0.25 m, textured floor and brick wall at 1.2 m",
    focus_distance_m=_SG_D,
    shapes=_shadow_gloss_shapes,
    integrator=PATH_INTEGRATOR,
    default_spp=spp_per_preset(512),
)
