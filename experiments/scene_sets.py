"""The scene sets a figure is computed on: the hand-built sets of :mod:`scenes` and the procedural test split.

A figure's config names its sets in one field, ``scene_sets``: pairs ``(set name, scenes)``, the first
the default (its plot is ``<fig>.png``, the others ``<fig>_<set>.png``). Each set is a case axis: every
(set, scene) is its own case, so the rows of the results table carry the set in their ``scene_set``
column and the claims are judged per set.

* ``paper_cameras`` and ``tabletop_stress``: :data:`scenes.SCENE_SETS` (hand-built; the figures' presets
  were tuned on them).
* ``procedural_test``: the first seeds of the ``test`` split of the procedural family
  (:mod:`scenes.library.procedural`, ``procedural_<seed>``, seeds 100000 and up) — scenes nobody tuned
  on. A claim whose verdict differs between the hand-built sets and this one is fragile (the report
  says so, with both evidences).
"""

from __future__ import annotations

__all__ = ["PROCEDURAL_TEST", "SCENE_SET_CAPTIONS", "check_scene_sets", "procedural_test_scenes", "scene_set_names",
           "set_scene_pairs"]

#: Name of the procedural test split as a scene set.
PROCEDURAL_TEST = "procedural_test"

#: One line per scene set: what it is (under its figures and in the report).
SCENE_SET_CAPTIONS = {
    "paper_cameras": "scene set paper_cameras (default): the paper's cameras at real-world distances "
                     "(subject at 2-6 m, background to 10-30 m)",
    "tabletop_stress": "scene set tabletop_stress (stress test): tabletop macro shots, 50 mm full frame "
                       "focused at 0.2-0.25 m (blur far larger than the paper's)",
    PROCEDURAL_TEST: "scene set procedural_test (held out): the first seeds of the procedural family's test split "
                     "(seeds 100000 and up), scenes nobody tuned on",
}


def procedural_test_scenes(n: int) -> tuple[str, ...]:
    """Names of the first ``n`` scenes of the procedural ``test`` split (``procedural_100000`` …).

    Raises
    ------
    ValueError
        ``n`` ≤ 0 or beyond the split.
    """
    from scenes.library.procedural import SPLITS, check_seed_range, procedural_name

    return tuple(procedural_name(s) for s in check_seed_range("test", SPLITS["test"].start, n))


def scene_set_names() -> tuple[str, ...]:
    """Every scene set a figure may name: :data:`scenes.SCENE_SETS` and :data:`PROCEDURAL_TEST`."""
    from scenes import SCENE_SETS

    return (*SCENE_SETS, PROCEDURAL_TEST)


def _in_set(set_name: str, scene: str) -> bool:
    from scenes import SCENE_SETS
    from scenes.library.procedural import is_procedural_name, seed_of, split_of

    if set_name == PROCEDURAL_TEST:
        return is_procedural_name(scene) and seed_of(scene)[1] is None and split_of(seed_of(scene)[0]) == "test"
    return scene in SCENE_SETS[set_name]


def check_scene_sets(pairs) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """A config's ``scene_sets`` checked: each set named once, known, non-empty, holding its scenes.

    Parameters
    ----------
    pairs : sequence of (str, sequence of str)
        ``(set name, scenes)``.

    Returns
    -------
    tuple of (str, tuple of str)

    Raises
    ------
    ValueError
        An unknown or repeated set, an empty one, or a scene that is not in its set.
    """
    out = []
    for item in pairs:
        try:
            set_name, scenes = item
        except (TypeError, ValueError):
            raise ValueError(f"scene_sets entry {item!r} is invalid; allowed: (set name, (scene, ...))") from None
        if set_name not in scene_set_names():
            raise ValueError(f"scene_set={set_name!r} is invalid; allowed: one of {list(scene_set_names())}")
        if any(set_name == s for s, _ in out):
            raise ValueError(f"scene set {set_name!r} appears twice in the config")
        scenes = tuple(scenes)
        stray = [n for n in scenes if not _in_set(set_name, n)]
        if not scenes or stray:
            raise ValueError(f"scenes {stray or list(scenes)} are invalid for scene set {set_name!r}; allowed: "
                             "a non-empty tuple of its scenes")
        out.append((set_name, scenes))
    return tuple(out)


def set_scene_pairs(config) -> list[tuple[str, str]]:
    """``[(set name, scene)]`` of a config's ``scene_sets`` (checked), sets in order."""
    return [(s, n) for s, names in check_scene_sets(config.scene_sets) for n in names]
