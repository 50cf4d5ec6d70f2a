"""Scenes in the paper's regime: the paper's cameras and lenses at real-world distances.

The paper's photographs (Sec. 6) are portraits and outdoor scenes: a Canon 1D Mark II with an 85 mm
lens at f/8 and f/4 (Figs. 5-7), a Nikon D50 with a 180 mm lens (Fig. 11 a). These scenes put a
people-scale subject in focus at 2 m (the telephoto one at 6 m), a mid-ground at 3-5 m and a far
background at 8-30 m, with occlusion boundaries (heads, poles, reeds against the background) and,
unlike the tabletop stress scenes of :mod:`.catalog`, lit diffuse surfaces.

σ_gt at the ``full`` preset (640×480) spans the box-filter floor (0.29 px) up to about 4 px at f/8
and 8 px at f/4 (``python -m repro.render --list`` prints the ranges measured on the rendered
ground truth). At 640 px width the 85 mm lens focused at 2 m blurs a background at infinity to at
most σ ≈ 2.6 px at f/8 (Eq. 5: c∞ = f²/(N(D − f)) = 10.5 px), so the portrait scenes reach the upper
end with a foreground element at 0.8 m (σ ≈ 3.9 px at f/8), as a photographer shooting past a
branch or a pole does; the telephoto scene reaches it with its far shore.

Lighting: ``portrait_garden``, ``street_figures`` and ``heron_at_the_lake`` are lit by one
``directional`` sun under the ``direct`` integrator — a single emitter, so no light-selection or
lighting noise, only the pixel/lens integral (hard, unlit shadows where visible; the sun is kept
near the camera's direction so they are small). ``patio_table`` is path traced with an area light
(soft shadows) and a glossy globe: the paper's Sec. 3.3 outliers at the focus distance.
"""

from __future__ import annotations

import math
from types import MappingProxyType

import numpy as np

from . import textures as tx
from .base import (
    PATH_INTEGRATOR, SceneDefinition, ambient_light, area_light, facing_rectangle, image_extent, reflectance_texture,
    spp_per_preset,
)

__all__ = ["HERON_AT_THE_LAKE", "PATIO_TABLE", "PORTRAIT_GARDEN", "STREET_FIGURES"]

_CANON = "canon_1d_mark_ii_85mm"
_NIKON = "nikon_d50_180mm"
#: The sun-lit scenes' integrator: camera ray → first hit → one shadow ray to the sun.
_SUNLIT_INTEGRATOR = MappingProxyType({"type": "direct", "emitter_samples": 1, "bsdf_samples": 0})


def _T():
    import mitsuba as mi

    return mi.ScalarTransform4f


def _diffuse(shape: dict, texture: np.ndarray, *, repeat=(1.0, 1.0)) -> dict:
    """Make ``shape`` (a Mitsuba dict or an :func:`_ellipsoid`) a diffuse surface with an HxWx3 linear
    reflectance texture in [0, 1]."""
    bsdf = {"type": "diffuse", "reflectance": reflectance_texture(texture, repeat=repeat)}
    if "_ellipsoid" in shape:
        return _ellipsoid_mesh(*shape["_ellipsoid"], bsdf)
    out = dict(shape)
    out["bsdf"] = bsdf
    return out


def _sun(direction, irradiance: float = 3.0) -> dict:
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    return {"type": "directional", "direction": [float(v) for v in d],
            "irradiance": {"type": "rgb", "value": [irradiance, irradiance * 0.97, irradiance * 0.9]}}


def _ellipsoid(centre, radii, *, n_lat: int = 48, n_lon: int = 96) -> dict:
    """An ellipsoid as a smooth triangle mesh (Mitsuba's ``sphere`` takes no non-uniform scaling: it
    warns and returns NaN radiance on scaled spheres). Texture u runs around world y, v from top to
    bottom. A marker dict that :func:`_diffuse` turns into the mesh."""
    return {"_ellipsoid": (tuple(float(c) for c in centre), tuple(float(r) for r in radii), n_lat, n_lon)}


def _ellipsoid_mesh(centre, radii, n_lat, n_lon, bsdf: dict):
    import mitsuba as mi

    th = np.linspace(0.0, np.pi, n_lat + 1)
    ph = np.linspace(0.0, 2.0 * np.pi, n_lon + 1)
    t, p = np.meshgrid(th, ph, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], axis=-1)
    pos = unit * np.asarray(radii) + np.asarray(centre)
    nrm = unit / np.asarray(radii)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    uv = np.stack([p / (2.0 * np.pi), t / np.pi], axis=-1)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh("ellipsoid", pos.shape[0] * pos.shape[1], faces.shape[0], props=props,
                   has_vertex_normals=True, has_vertex_texcoords=True)
    params = mi.traverse(mesh)
    # the buffers' own array types: mi.Float is a Python float in the scalar variants
    for key, values, dtype in (("vertex_positions", pos, np.float32), ("vertex_normals", nrm, np.float32),
                               ("vertex_texcoords", uv, np.float32), ("faces", faces, np.uint32)):
        params[key] = type(params[key])(values.reshape(-1).astype(dtype))
    params.update()
    return mesh


def _person(prefix: str, *, x: float, z: float, head_y: float, skin: np.ndarray, cloth: np.ndarray,
            scale: float = 1.0) -> dict:
    """A standing figure facing the camera: head, neck and torso (metres, camera space).

    ``z`` is the depth of the front of the face; ``head_y`` the height of the head's centre.
    """
    r = 0.095 * scale
    return {
        f"{prefix}_head": _diffuse(_ellipsoid((x, head_y, z + r), (r * 0.85, r, r)), skin, repeat=(3.0, 2.0)),
        f"{prefix}_neck": _diffuse({"type": "cylinder", "p0": [x, head_y - 1.9 * r, z + 1.2 * r],
                                    "p1": [x, head_y - 0.6 * r, z + 1.2 * r], "radius": 0.45 * r}, skin),
        f"{prefix}_torso": _diffuse(_ellipsoid((x, head_y - 5.0 * r, z + 1.6 * r), (2.3 * r, 3.4 * r, 1.2 * r)),
                                    cloth, repeat=(6.0, 2.0)),
    }


def _foliage(seed: int, size: int = 512, *, r_max: float = 40.0) -> np.ndarray:
    return tx.dead_leaves(size, seed=seed, r_min=1.5, r_max=r_max, palette=((0.03, 0.3), (0.12, 0.6), (0.02, 0.2)))


# --- portrait_garden ---------------------------------------------------------------------------
_PG_D = 2.0


def _portrait_garden_shapes() -> dict:
    ext = image_extent(_PG_D, camera_name=_CANON)
    skin = tx.dead_leaves(512, seed=61, r_min=1.5, r_max=20.0, palette=((0.45, 0.8), (0.28, 0.5), (0.18, 0.35)))
    shirt = tx.stripes(256, period=24, colours=((0.15, 0.2, 0.55), (0.8, 0.78, 0.7)))
    out = {
        "sun": _sun((-0.35, -0.45, 1.0)),
        # far background: a sun-lit brick house front 10 m away
        "house": _diffuse(facing_rectangle(10.0, -1.5, 1.5, -1.5, 1.5, extent=ext), tx.photo("brick", lo=0.1, hi=0.7),
                          repeat=(3.0, 2.0)),
        # mid-ground hedge at 4.5 m across the lower half
        "hedge": _diffuse(facing_rectangle(4.5, -1.5, 1.5, -1.5, -0.05, extent=ext), _foliage(62), repeat=(3.0, 1.5)),
        # a tree trunk at 3.2 m on the left: an occlusion boundary in the mid-ground
        "trunk": _diffuse({"type": "cylinder", "p0": [0.45, -1.5, 3.2], "p1": [0.45, 1.5, 3.2], "radius": 0.09},
                          tx.dead_leaves(256, seed=63, r_max=12.0, palette=((0.15, 0.4), (0.1, 0.3), (0.05, 0.2))),
                          repeat=(2.0, 6.0)),
        # foreground leaves at 0.8 m in the lower right corner (shot past a branch)
        "branch": _diffuse(facing_rectangle(0.8, 0.55, 1.5, -1.5, -0.45, extent=ext), _foliage(64, r_max=60.0)),
    }
    out.update(_person("person", x=0.0, z=_PG_D, head_y=0.07, skin=skin, cloth=shirt))
    return out


PORTRAIT_GARDEN = SceneDefinition(
    name="portrait_garden",
    version=1,
    description="sun-lit head-and-shoulders portrait at 2 m, tree trunk at 3.2 m, hedge at 4.5 m, brick house "
    "at 10 m, leaves at 0.8 m in a corner (Canon 1D Mark II, 85 mm)",
    focus_distance_m=_PG_D,
    shapes=_portrait_garden_shapes,
    integrator=_SUNLIT_INTEGRATOR,
    camera_name=_CANON,
    facts=MappingProxyType({"subject_depth_m": _PG_D, "foreground_depth_m": 0.8, "background_depth_m": 10.0}),
)


# --- street_figures ------------------------------------------------------------------------------
_SF_D = 2.0


def _street_figures_shapes() -> dict:
    T = _T()
    ext = image_extent(_SF_D, camera_name=_CANON)
    out = {
        "sun": _sun((-0.3, -0.5, 1.0)),
        "facade": _diffuse(facing_rectangle(10.0, -1.5, 1.5, -1.5, 1.5, extent=ext), tx.photo("coffee", lo=0.05, hi=0.8),
                           repeat=(2.0, 2.0)),
        # shop fronts along the right side of the street, receding from 2.5 m to 10 m (continuous depth)
        "shopfront": {
            "type": "rectangle",
            # local xy → world (z, y); normal → +x (towards the street centre and the camera's axis)
            "to_world": T().translate([-0.42, 0.2, 6.25]) @ T().rotate([0, 1, 0], 90) @ T().scale([3.75, 1.8, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(tx.photo("brick", lo=0.1, hi=0.7),
                                                                           repeat=(4.0, 1.0))},
        },
        # a café-umbrella pole 0.85 m away on the left: strongly blurred occluder
        "pole": _diffuse({"type": "cylinder", "p0": [0.12, -1.0, 0.85], "p1": [0.12, 1.0, 0.85], "radius": 0.025},
                         tx.stripes(128, period=16, colours=((0.7, 0.7, 0.68), (0.1, 0.1, 0.1)), vertical=False),
                         repeat=(1.0, 8.0)),
    }
    people = (  # (image u of the centre, face depth m, head centre height m, seed); eye-level camera
        (-0.3, _SF_D, 0.03, 71),
        (0.4, 3.5, 0.1, 72),
        (0.05, 6.0, -0.02, 73),
        (-0.65, 8.0, 0.08, 74),
    )
    for i, (u, z, hy, seed) in enumerate(people):
        x = -u * ext[0] * z
        rng = np.random.default_rng(seed)
        skin = tx.dead_leaves(256, seed=seed, r_min=1.5, r_max=18.0,
                              palette=((0.3, 0.75), (0.2, 0.5), (0.12, 0.35)))
        cloth = tx.dead_leaves(256, seed=seed + 100, r_min=2.0, r_max=30.0,
                               palette=tuple(tuple(sorted(rng.uniform(0.03, 0.8, 2))) for _ in range(3)))
        out.update(_person(f"person{i}", x=x, z=z, head_y=hy, skin=skin, cloth=cloth))
    return out


STREET_FIGURES = SceneDefinition(
    name="street_figures",
    version=1,
    description="sun-lit street: people at 2 (in focus), 3.5, 6 and 8 m, shop fronts receding 2.5-10 m, "
    "facade at 10 m, a pole at 0.85 m (Canon 1D Mark II, 85 mm)",
    focus_distance_m=_SF_D,
    shapes=_street_figures_shapes,
    integrator=_SUNLIT_INTEGRATOR,
    camera_name=_CANON,
    facts=MappingProxyType({"subject_depth_m": _SF_D, "people_depths_m": (2.0, 3.5, 6.0, 8.0)}),
)


# --- heron_at_the_lake ---------------------------------------------------------------------------
_HL_D = 6.0


def _heron_shapes() -> dict:
    T = _T()
    ext = image_extent(_HL_D, camera_name=_NIKON)
    feathers = tx.dead_leaves(512, seed=81, r_min=1.0, r_max=14.0, palette=((0.4, 0.8), (0.42, 0.8), (0.45, 0.85)))
    out = {
        "sun": _sun((-0.4, -0.35, 1.0)),
        # far shore: trees 30 m away
        "shore": _diffuse(facing_rectangle(30.0, -1.5, 1.5, -0.5, 1.5, extent=ext), _foliage(82, r_max=50.0),
                          repeat=(2.0, 2.0)),
        # the lake: a horizontal plane 0.35 m below the lens from 5 m to 40 m (continuous depth)
        "water": {
            "type": "rectangle",
            "to_world": T().translate([0.0, -0.35, 22.5]) @ T().rotate([1, 0, 0], -90) @ T().scale([4.0, 17.5, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(
                tx.dead_leaves(512, seed=83, r_min=1.0, r_max=25.0, palette=((0.05, 0.2), (0.1, 0.3), (0.15, 0.4))),
                repeat=(4.0, 16.0))},
        },
        # the heron at 6 m: body, neck, head, beak
        "body": _diffuse(_ellipsoid((0.02, -0.12, _HL_D + 0.09), (0.16, 0.09, 0.09)), feathers, repeat=(3.0, 2.0)),
        "neck": _diffuse({"type": "cylinder", "p0": [-0.08, -0.08, _HL_D + 0.06], "p1": [-0.12, 0.12, _HL_D + 0.04],
                          "radius": 0.025}, feathers, repeat=(2.0, 2.0)),
        "head": _diffuse(_ellipsoid((-0.12, 0.15, _HL_D + 0.04), (0.035, 0.035, 0.035), n_lat=24, n_lon=48), feathers),
        "beak": _diffuse({"type": "cylinder", "p0": [-0.15, 0.15, _HL_D + 0.04], "p1": [-0.26, 0.13, _HL_D + 0.04],
                          "radius": 0.009}, tx.checker(64, cells=2, colours=((0.6, 0.45, 0.1), (0.55, 0.4, 0.08)))),
    }
    # reeds: thin stalks at 4.2-4.8 m (in front) and 8-12 m (behind)
    rng = np.random.default_rng(84)
    stalk = tx.stripes(64, period=8, colours=((0.35, 0.3, 0.1), (0.15, 0.18, 0.05)), vertical=False)
    for i in range(14):
        z = float(rng.uniform(4.2, 4.8)) if i < 6 else float(rng.uniform(8.0, 12.0))
        u = float(rng.uniform(-1.1, 1.1))
        x = -u * ext[0] * z
        top = float(rng.uniform(0.0, 0.9)) * ext[1] * z
        out[f"reed_{i:02d}"] = _diffuse({"type": "cylinder", "p0": [x, -0.35, z], "p1": [x + 0.02, top, z],
                                         "radius": 0.006 * math.sqrt(z / 4.0)}, stalk, repeat=(1.0, 20.0))
    return out


HERON_AT_THE_LAKE = SceneDefinition(
    name="heron_at_the_lake",
    version=1,
    description="sun-lit heron at 6 m among reeds at 4.2-4.8 m and 8-12 m, lake surface receding 7-30 m, "
    "far shore at 30 m (Nikon D50, 180 mm)",
    focus_distance_m=_HL_D,
    shapes=_heron_shapes,
    integrator=_SUNLIT_INTEGRATOR,
    camera_name=_NIKON,
    facts=MappingProxyType({"subject_depth_m": _HL_D, "background_depth_m": 30.0}),
)


# --- patio_table -------------------------------------------------------------------------------
_PT_D = 2.0
_PT_TABLE_Y = -0.2


def _patio_table_shapes() -> dict:
    T = _T()
    ext = image_extent(_PT_D, camera_name=_CANON)
    cloth = tx.dead_leaves(512, seed=91, r_min=2.0, r_max=30.0, palette=((0.5, 0.85), (0.45, 0.8), (0.35, 0.7)))
    return {
        # table top: horizontal plane from 1.5 m to 3 m (visible from about 1.65 m: continuous depth)
        "table": {
            "type": "rectangle",
            "to_world": T().translate([0.0, _PT_TABLE_Y, 2.25]) @ T().rotate([1, 0, 0], -90) @ T().scale([0.6, 0.75, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(cloth, repeat=(2.0, 3.0))},
        },
        # wall 3.2 m away on the left two thirds, the garden 9 m away through the opening on the right
        "wall": {**facing_rectangle(3.2, -1.5, 0.35, -1.5, 1.5, extent=ext),
                 "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(tx.photo("brick", lo=0.1, hi=0.7),
                                                                                repeat=(2.0, 2.0))}},
        "garden": {**facing_rectangle(9.0, -1.5, 1.5, -1.5, 1.5, extent=ext),
                   "bsdf": {"type": "diffuse", "reflectance": reflectance_texture(_foliage(92), repeat=(3.0, 3.0))}},
        # at the focus distance: a glossy garden globe (highlight) and a box casting a soft shadow
        "globe": {
            "type": "sphere", "center": [-0.08, _PT_TABLE_Y + 0.07, _PT_D + 0.07], "radius": 0.07,
            "bsdf": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.05,
                     "diffuse_reflectance": {"type": "rgb", "value": [0.08, 0.25, 0.55]}},
        },
        "box": {
            "type": "cube",
            "to_world": T().translate([0.12, _PT_TABLE_Y + 0.09, _PT_D + 0.05]) @ T().rotate([0, 1, 0], 25)
            @ T().scale([0.04, 0.09, 0.04]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.6, 0.35, 0.15]}},
        },
        # a sky-light panel above and to the left (world +x is image left), facing down: soft shadows
        "skylight": area_light(T().translate([0.6, 0.9, 1.7]) @ T().rotate([1, 0, 0], 90) @ T().scale([0.3, 0.3, 1.0]),
                               [14.0, 13.5, 12.5]),
        "ambient": ambient_light([0.05, 0.055, 0.06]),
    }


PATIO_TABLE = SceneDefinition(
    name="patio_table",
    version=1,
    description="path-traced patio: a glossy globe and a box with a soft shadow on a table at 2 m, table "
    "receding 1.65-3 m, wall at 3.2 m, garden at 9 m (Canon 1D Mark II, 85 mm)",
    focus_distance_m=_PT_D,
    shapes=_patio_table_shapes,
    integrator=PATH_INTEGRATOR,
    default_spp=spp_per_preset(512),
    camera_name=_CANON,
    facts=MappingProxyType({"subject_depth_m": _PT_D, "background_depth_m": 9.0}),
)
