"""Registry of the procedural test scenes.

``SCENES`` maps a name to a :class:`~scenes.library.base.SceneDefinition`:

* ``planes`` — fronto-parallel textured planes, sharp step edges at several depths;
* ``tilted_plane`` — one textured plane with continuously varying depth;
* ``portrait`` — an in-focus figure with occlusion boundaries before a far textured background;
* ``clutter`` — many objects at many depths;
* ``shadow_gloss`` — path-traced soft shadow and glossy highlight (blur outliers, Sec. 3.3);

the tabletop macro scenes above (50 mm full frame at 0.2-0.25 m, σ_gt up to 12-17 px at f/4 at the
``full`` preset) form the ``tabletop_stress`` set; the scenes in the paper's regime
(:mod:`.paper_regime`: the paper's cameras at real-world distances) form ``paper_cameras``:

* ``portrait_garden`` — sun-lit portrait at 2 m, trunk, hedge, house at 10 m, leaves at 0.8 m (85 mm);
* ``street_figures`` — people at 2-8 m, receding shop fronts, a pole at 0.85 m (85 mm);
* ``patio_table`` — path-traced glossy globe and soft shadow on a table at 2 m (85 mm; Sec. 3.3);
* ``heron_at_the_lake`` — a heron at 6 m, reeds, lake, shore at 30 m (Nikon D50, 180 mm).

``SCENE_SETS`` names both sets; ``paper_cameras`` is the default of Figs. 5, 6, 7 and 11.

Beside the named scenes, a family drawn from a seed (:mod:`.procedural`): :func:`get_scene` also
accepts ``procedural_<seed>`` (and ``procedural_<seed>_<camera>``), returning
:func:`~.procedural.procedural_scene` of that seed; those names are not in :data:`SCENES`.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from .base import DEFAULT_F_NUMBERS, PRESETS, SceneDefinition
from .catalog import CLUTTER, PLANES, PORTRAIT, SHADOW_GLOSS, TILTED_PLANE
from .paper_regime import HERON_AT_THE_LAKE, PATIO_TABLE, PORTRAIT_GARDEN, STREET_FIGURES
from .procedural import is_procedural_name, procedural_scene, seed_of

__all__ = ["DEFAULT_F_NUMBERS", "DEFAULT_SCENE_SET", "PRESETS", "SCENES", "SCENE_SETS", "SceneDefinition",
           "get_scene", "get_scene_set", "procedural_scene"]

_TABLETOP = (PLANES, TILTED_PLANE, PORTRAIT, CLUTTER, SHADOW_GLOSS)
_PAPER = (PORTRAIT_GARDEN, STREET_FIGURES, PATIO_TABLE, HERON_AT_THE_LAKE)

#: Every scene by name.
SCENES: Mapping[str, SceneDefinition] = MappingProxyType({s.name: s for s in (*_TABLETOP, *_PAPER)})

#: Named scene sets: ``paper_cameras`` (the paper's cameras at real-world distances; the default of the
#: figures) and ``tabletop_stress`` (tabletop macro shots whose blur is far larger than the paper's).
SCENE_SETS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "paper_cameras": tuple(s.name for s in _PAPER),
    "tabletop_stress": tuple(s.name for s in _TABLETOP),
})
#: The set the figures' flat metrics describe.
DEFAULT_SCENE_SET = "paper_cameras"


def get_scene_set(name: str) -> tuple[str, ...]:
    """The scene names of a :data:`SCENE_SETS` entry.

    Raises
    ------
    ValueError
        If ``name`` is not a key of :data:`SCENE_SETS`.
    """
    try:
        return SCENE_SETS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown scene set {name!r}; choose one of {sorted(SCENE_SETS)}") from None


def get_scene(scene) -> SceneDefinition:
    """A :class:`SceneDefinition` from its name (or the definition itself).

    A name ``procedural_<seed>[_<camera>]`` gives :func:`~.procedural.procedural_scene` of that seed
    (the same object every time within a process).

    Raises
    ------
    ValueError
        If the name is neither in :data:`SCENES` nor a procedural scene's.
    """
    if isinstance(scene, SceneDefinition):
        return scene
    if is_procedural_name(scene):
        seed, camera = seed_of(scene)
        return procedural_scene(seed, camera=camera)
    try:
        return SCENES[scene]
    except (KeyError, TypeError):
        raise ValueError(f"unknown scene {scene!r}; choose one of {sorted(SCENES)} "
                         "or procedural_<seed>") from None
