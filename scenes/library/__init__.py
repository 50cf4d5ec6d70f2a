"""Registry of the procedural test scenes.

``SCENES`` maps a name to a :class:`~scenes.library.base.SceneDefinition`:

* ``planes`` — fronto-parallel textured planes, sharp step edges at several depths;
* ``tilted_plane`` — one textured plane with continuously varying depth;
* ``portrait`` — an in-focus figure with occlusion boundaries before a far textured background;
* ``clutter`` — many objects at many depths;
* ``shadow_gloss`` — path-traced soft shadow and glossy highlight (blur outliers, Sec. 3.3).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from .base import DEFAULT_F_NUMBERS, PRESETS, SceneDefinition
from .catalog import CLUTTER, PLANES, PORTRAIT, SHADOW_GLOSS, TILTED_PLANE

__all__ = ["DEFAULT_F_NUMBERS", "PRESETS", "SCENES", "SceneDefinition", "get_scene"]

#: Every scene by name.
SCENES: Mapping[str, SceneDefinition] = MappingProxyType(
    {s.name: s for s in (PLANES, TILTED_PLANE, PORTRAIT, CLUTTER, SHADOW_GLOSS)}
)


def get_scene(scene) -> SceneDefinition:
    """A :class:`SceneDefinition` from its name (or the definition itself).

    Raises
    ------
    ValueError
        If the name is not in :data:`SCENES`.
    """
    if isinstance(scene, SceneDefinition):
        return scene
    try:
        return SCENES[scene]
    except (KeyError, TypeError):
        raise ValueError(f"unknown scene {scene!r}; choose one of {sorted(SCENES)}") from None
