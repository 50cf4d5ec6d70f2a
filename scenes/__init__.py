"""Ground truth for the defocus-magnification harness: optics, cameras, scenes, renders.

Importing this package does not import Mitsuba; :func:`render_scene` selects a variant when first
called (:mod:`scenes.backend`).

Main entry points
-----------------
SCENES : mapping of str to SceneDefinition
    The procedural test scenes (:mod:`scenes.library`).
SCENE_SETS : mapping of str to tuple of str
    ``paper_cameras`` (the paper's cameras at real-world distances, the figures' default) and
    ``tabletop_stress`` (tabletop macro scenes with far larger blur).
render_scene(scene, camera=None, *, preset="small", f_number=None, ...) -> Render
    Render with per-pixel ground truth (depth, CoC, σ_gt, occlusion mask), cached.
load_render(path) -> Render
    Read a render's EXR + JSON sidecar back.
"""

from .camera import CAMERA_PRESETS, SENSORS, ThinLensCamera, camera_preset, same_field_of_view
from .library import (DEFAULT_F_NUMBERS, DEFAULT_SCENE_SET, PRESETS, SCENE_SETS, SCENES, SceneDefinition,
                      get_scene, get_scene_set)
from .render import Render, load_render, render_scene

__all__ = [
    "CAMERA_PRESETS",
    "DEFAULT_F_NUMBERS",
    "DEFAULT_SCENE_SET",
    "PRESETS",
    "SCENES",
    "SCENE_SETS",
    "SENSORS",
    "Render",
    "SceneDefinition",
    "ThinLensCamera",
    "camera_preset",
    "get_scene",
    "get_scene_set",
    "load_render",
    "render_scene",
    "same_field_of_view",
]
