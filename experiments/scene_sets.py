"""Run a figure's compute on its default scene set and on every further named scene set.

Figs. 5, 6, 7 and 11 compute on the scenes in the paper's regime (``scenes.SCENE_SETS["paper_cameras"]``)
and, as a named stress set, on the tabletop macro scenes (``"tabletop_stress"``). Their configs carry
``scene_set`` (the set ``scenes`` is drawn from) and ``other_scene_sets``: pairs
``(set name, ((field, value), ...))`` of config overrides (usually ``scenes``) for each further set.

The result keeps the default set's arrays and metrics where they were (the flat keys) and adds, per
the project contract: ``metrics["scene_set"]`` (the default set's name) and
``metrics["scene_sets"][name]`` (the other set's metrics, same shape, with its own ``"presets"``);
arrays of the other set are stored as ``<name>__<key>``.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

from .registry import Figure

__all__ = ["SCENE_SET_CAPTIONS", "SET_SEPARATOR", "check_scene_sets", "compute_scene_sets", "scene_set_configs",
           "scene_set_figure", "set_arrays"]

#: One line per scene set: what it is (under its figures and in the report).
SCENE_SET_CAPTIONS = {
    "paper_cameras": "scene set paper_cameras (default): the paper's cameras at real-world distances "
                     "(subject at 2-6 m, background to 10-30 m)",
    "tabletop_stress": "scene set tabletop_stress (stress test): tabletop macro shots, 50 mm full frame "
                       "focused at 0.2-0.25 m (blur far larger than the paper's)",
}

#: Separator between a scene set's name and an array key of that set.
SET_SEPARATOR = "__"


def scene_set_configs(config) -> list[tuple[str, object]]:
    """``[(set name, config of that set)]``: the default set first, then each of ``other_scene_sets``.

    A further set's config is ``config`` with that set's overrides, ``scene_set`` = its name and no
    ``other_scene_sets``.

    Parameters
    ----------
    config : frozen dataclass
        With ``scene_set`` (str), ``other_scene_sets`` (see module docs) and the scenes drawn from
        the set: ``scenes`` (tuple of str) or, for a one-scene figure, ``scene`` (str).

    Returns
    -------
    list of (str, dataclass)

    Raises
    ------
    ValueError
        Unless each set is named once, is a set of ``scenes.SCENE_SETS`` and holds its config's scenes.
    """
    from scenes import SCENE_SETS

    out = [(config.scene_set, config)]
    for set_name, overrides in config.other_scene_sets:
        out.append((set_name, dataclasses.replace(config, scene_set=set_name, other_scene_sets=(),
                                                  **dict(overrides))))
    seen = set()
    for set_name, cfg in out:
        if set_name in seen:
            raise ValueError(f"scene set {set_name!r} appears twice in the config")
        seen.add(set_name)
        if set_name not in SCENE_SETS:
            raise ValueError(f"scene_set={set_name!r} is invalid; allowed: one of {sorted(SCENE_SETS)}")
        names = cfg.scenes if hasattr(cfg, "scenes") else (cfg.scene,)
        stray = [n for n in names if n not in SCENE_SETS[set_name]]
        if stray:
            raise ValueError(f"scenes {stray} are not in scene set {set_name!r}; allowed: {list(SCENE_SETS[set_name])}")
    return out


def check_scene_sets(config) -> None:
    """Raise ``ValueError`` unless every scene of each set of ``config`` belongs to that named set.

    Parameters
    ----------
    config : frozen dataclass
        See :func:`scene_set_configs`.
    """
    scene_set_configs(config)


def compute_scene_sets(compute_one: Callable[[object], dict], config) -> dict:
    """``compute_one`` on the default set, then on each of ``config.other_scene_sets``, merged.

    Parameters
    ----------
    compute_one : callable
        ``compute_one(config) -> dict`` of arrays plus ``"metrics"`` for one scene set.
    config : frozen dataclass
        See :func:`check_scene_sets`.

    Returns
    -------
    dict
        The default set's arrays and metrics; ``metrics["scene_set"]``,
        ``metrics["scene_sets"][name]`` (each with ``"scene_set": name``), arrays ``<name>__<key>``.
    """
    sets = scene_set_configs(config)
    data = compute_one(config)
    metrics = data["metrics"]
    metrics["scene_set"] = config.scene_set
    nested = {}
    for set_name, sub_config in sets[1:]:
        sub = compute_one(sub_config)
        sub_metrics = sub.pop("metrics")
        sub_metrics["scene_set"] = set_name
        nested[set_name] = sub_metrics
        for key, value in sub.items():
            data[f"{set_name}{SET_SEPARATOR}{key}"] = value
    metrics["scene_sets"] = nested
    return data


def scene_set_figure(compute_set: Callable[[object], dict], *, name: str, title: str, quick, full,
                     version: int, **fields) -> Figure:
    """The :class:`~experiments.registry.Figure` of a figure computed on every scene set of its config.

    Parameters
    ----------
    compute_set : callable
        ``compute_set(config) -> dict`` for one scene set; the figure's compute is
        :func:`compute_scene_sets` over it.
    name, title : str, keyword-only
        Figure name (its plot is ``experiments.plotting.<name>:plot``) and one-line title.
    quick, full : frozen dataclass, keyword-only
        The configs of the two modes.
    version : int, keyword-only
        Code version of the compute (part of the cache key).
    **fields
        Further :class:`~experiments.registry.Figure` fields (``sigma_convention``, ``renders``).

    Returns
    -------
    Figure
    """
    return Figure(name=name, title=title, compute=functools.partial(compute_scene_sets, compute_set),
                  plot=f"experiments.plotting.{name}:plot", configs={"quick": quick, "full": full},
                  version=version, **fields)


def set_arrays(data: dict, set_name: str | None) -> dict:
    """The arrays and metrics of one scene set as a compute dict (``None``: the default set).

    Parameters
    ----------
    data : dict
        A :func:`compute_scene_sets` result (arrays plus ``"metrics"``).
    set_name : str or None
        A name of ``data["metrics"]["scene_sets"]``, or ``None`` / the default set's name.

    Returns
    -------
    dict
        Arrays without the set prefix plus that set's ``"metrics"``, as the plot functions take it.
    """
    metrics = data.get("metrics", {})
    if set_name is None or set_name == metrics.get("scene_set"):
        return {k: v for k, v in data.items()
                if not any(k.startswith(f"{s}{SET_SEPARATOR}") for s in metrics.get("scene_sets", {}))}
    if set_name not in metrics.get("scene_sets", {}):
        raise ValueError(f"no scene set {set_name!r} in the figure data; has {sorted(metrics.get('scene_sets', {}))}")
    prefix = f"{set_name}{SET_SEPARATOR}"
    out = {k[len(prefix):]: v for k, v in data.items() if k.startswith(prefix)}
    out["metrics"] = metrics["scene_sets"][set_name]
    return out
