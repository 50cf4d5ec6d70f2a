"""A leaderboard of defocus maps: every method preset and every external map folder, one row each, per
scene set and protocol (:mod:`experiments.external_maps`).

The presets' maps are computed here, by :func:`method.estimate_defocus_map` with the preset's
parameters on each image's 8-bit sRGB input (the exported PNG, or the render quantised the same way):
the maps ``repro.estimate --preset NAME`` writes for the exported PNGs and ``repro.evaluate --preset
NAME`` scores. An external folder is scored as ``repro.evaluate --maps`` scores it. Each number of a
row is the mean over the images of the scene set of the per-image metric.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path

from .external_maps import (DETECTION_THRESHOLD_PX, HEADLINE, PNG_SCALE, PROTOCOLS, score_folder, score_maps,
                            summarize)

__all__ = ["ALL_SCENES", "build_leaderboard", "leaderboard_tables", "preset_maps", "scene_set_of"]

#: Scene-set label of the rows over every image (given when the images span more than one set).
ALL_SCENES = "all"


def scene_set_of(scene: str) -> str:
    """The :data:`scenes.SCENE_SETS` name holding ``scene`` (``"other"`` if none does)."""
    from scenes.library import SCENE_SETS

    return next((name for name, members in SCENE_SETS.items() if scene in members), "other")


def preset_maps(truth, preset: str):
    """``name -> (σ map of the preset on the image's 8-bit sRGB input, label)``, for :func:`score_maps`."""
    from method import DefocusParams, NoEdgesWarning, estimate_defocus_map

    params = DefocusParams.preset(preset)

    def get(name):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NoEdgesWarning)
            return estimate_defocus_map(truth.image(name), params).defocus_map, f"preset {preset}: {name}"

    return get


def build_leaderboard(truth, *, presets=None, external: Mapping[str, Path] | None = None, protocols=None,
                      threshold_px: float = DETECTION_THRESHOLD_PX, png_scale: float = PNG_SCALE) -> dict:
    """Score every preset and external folder on the images of ``truth``.

    Parameters
    ----------
    truth : experiments.external_maps.DatasetTruth or RenderTruth
    presets : sequence of str, optional, keyword-only
        Keys of :data:`method.PRESETS` (default: all).
    external : mapping str -> path, optional, keyword-only
        Entry name -> folder of maps ``NAME.npy|npz|exr|png``. A name may not be a preset's.
    protocols : sequence of str, optional, keyword-only
        Keys of :data:`experiments.external_maps.PROTOCOLS` (default: all).
    threshold_px, png_scale : float, keyword-only
        Detection threshold (px); 16-bit PNG value per px of σ.

    Returns
    -------
    dict
        ``rows``: one per entry × scene set × protocol, ``{"entry", "kind" ("preset"|"external"),
        "scene_set", "protocol", "n_images", <HEADLINE metric>: mean}``; ``problems``: one line per map
        that could not be scored, naming the entry and the file; ``ground_truth``, ``protocols``,
        ``detection_threshold_px``, ``png_scale``, ``scene_sets`` (set -> images).
    """
    from method import PRESETS

    presets = PRESETS.check_all(dict.fromkeys(presets if presets is not None else PRESETS), what="preset")
    protocols = PROTOCOLS.check_all(dict.fromkeys(protocols if protocols is not None else PROTOCOLS),
                                    what="protocol")
    external = dict(external or {})
    clash = sorted(set(external) & set(presets))
    if clash:
        raise ValueError(f"external name(s) {', '.join(map(repr, clash))} are invalid (a preset's name); "
                         "allowed: any other name")
    for name, folder in external.items():
        if not Path(folder).is_dir():
            raise ValueError(f"--external {name}={folder}: not a folder; allowed: a folder of NAME.npy|npz|exr|png maps")
    sets: dict[str, list[str]] = {}
    for image in truth.names:
        sets.setdefault(scene_set_of(truth.scene(image)), []).append(image)
    if len(sets) > 1:
        sets[ALL_SCENES] = list(truth.names)
    scored = [(p, "preset", score_maps(preset_maps(truth, p), truth, protocols=protocols, threshold_px=threshold_px))
              for p in presets]
    scored += [(n, "external", score_folder(f, truth, protocols=protocols, threshold_px=threshold_px,
                                            png_scale=png_scale)) for n, f in external.items()]
    rows, problems = [], []
    for entry, kind, result in scored:
        problems += [f"{entry}: {p}" for p in result.problems]
        for scene_set, images in sets.items():
            members = set(images)
            chosen = [r for r in result.rows if r["image"] in members]
            for mean in summarize(chosen):
                keep = {k: mean[k] for k, _ in HEADLINE[mean["protocol"]]}
                rows.append({"entry": entry, "kind": kind, "scene_set": scene_set, "protocol": mean["protocol"],
                             "n_images": mean["n_images"], **keep})
    return {"rows": rows, "problems": problems, "ground_truth": truth.source, "protocols": protocols,
            "detection_threshold_px": float(threshold_px), "png_scale": float(png_scale), "scene_sets": sets}


def _cell(v) -> str:
    return "–" if v is None or v != v else f"{v:.3f}"


def leaderboard_tables(board: dict) -> list[dict]:
    """One table per protocol of :func:`build_leaderboard`'s rows: ``{"title", "header", "rows"}``.

    Rows by scene set, then entries in their order (presets first); cells are strings.
    """
    tables = []
    sets = list(board.get("scene_sets", {}))
    for protocol in board.get("protocols", []):
        cols = HEADLINE[protocol]
        rows = [r for r in board["rows"] if r["protocol"] == protocol]
        rows.sort(key=lambda r: sets.index(r["scene_set"]) if r["scene_set"] in sets else len(sets))
        body = [[r["scene_set"], r["entry"], r["kind"], str(r["n_images"]), *(_cell(r.get(k)) for k, _ in cols)]
                for r in rows]
        title = f"{protocol}: {PROTOCOLS.entry(protocol).summary}"
        if protocol == "detection":
            title += f" (threshold {board['detection_threshold_px']:g} px)"
        tables.append({"title": title, "header": ["scene set", "entry", "kind", "images", *(l for _, l in cols)],
                       "rows": body})
    return tables
