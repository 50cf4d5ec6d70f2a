"""A leaderboard of defocus maps: every method preset, every trivial baseline (:mod:`experiments.baselines`:
constant maps at the image's median σ_gt and at the pixel filter's floor) and every external map folder,
one row each, per scene set and protocol (:mod:`experiments.external_maps`).

The presets' maps are computed here, by :func:`method.estimate_defocus_map` with the preset's
parameters on each image's 8-bit sRGB input (the exported PNG, or the render quantised the same way):
the maps ``repro.estimate --preset NAME`` writes for the exported PNGs and ``repro.evaluate --preset
NAME`` scores. An external folder is scored as ``repro.evaluate --maps`` scores it. Each number of a
row is the mean over the images of the scene set of the per-image metric.

Beside it, the generalisation gap (:func:`generalisation_gap`, :func:`generalisation_tables`): per
preset, the mean error over the ``dev`` seeds of the procedural scene family (the ones to tune on)
and over the ``test`` seeds (held out), each with a 95 % bootstrap interval over scenes, and
test − dev: a preset tuned to the dev scenes shows a positive gap.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .external_maps import DETECTION_THRESHOLD_PX, HEADLINE, PNG_SCALE, PROTOCOLS, score_folder, score_maps

__all__ = ["ALL_APERTURES", "ALL_SCENES", "GAP_METRICS", "build_leaderboard", "check_external", "generalisation_gap", "generalisation_tables",
           "leaderboard_intro", "leaderboard_rows", "leaderboard_tables", "preset_maps", "scene_set_of"]

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


def check_external(external: dict, *, presets=None) -> None:
    """ValueError (one line) unless every entry of ``external`` is a folder under a name no preset or
    baseline has.

    Parameters
    ----------
    external : mapping str -> path
        Entry name -> folder of maps.
    presets : sequence of str, optional, keyword-only
        The preset rows' names (default: every key of :data:`method.PRESETS`).
    """
    from method import PRESETS

    from .baselines import BASELINES

    clash = sorted(set(external) & {*(presets if presets is not None else PRESETS), *BASELINES})
    if clash:
        raise ValueError(f"external name(s) {', '.join(map(repr, clash))} are invalid (a preset's or baseline's name); "
                         "allowed: any other name")
    for name, folder in external.items():
        if not Path(folder).is_dir():
            raise ValueError(f"--external {name}={folder}: not a folder; allowed: a folder of NAME.npy|npz|exr|png maps")


def build_leaderboard(truth, *, presets=None, baselines=None, external: Mapping[str, Path] | None = None, protocols=None,
                      threshold_px: float = DETECTION_THRESHOLD_PX, png_scale: float = PNG_SCALE) -> dict:
    """Score every preset and external folder on the images of ``truth``.

    Parameters
    ----------
    truth : experiments.external_maps.DatasetTruth or RenderTruth
    presets : sequence of str, optional, keyword-only
        Keys of :data:`method.PRESETS` (default: all).
    baselines : sequence of str, optional, keyword-only
        Keys of :data:`experiments.baselines.BASELINES` (default: all; ``()`` for none).
    external : mapping str -> path, optional, keyword-only
        Entry name -> folder of maps ``NAME.npy|npz|exr|png``. A name may not be a preset's.
    protocols : sequence of str, optional, keyword-only
        Keys of :data:`experiments.external_maps.PROTOCOLS` (default: all).
    threshold_px, png_scale : float, keyword-only
        Detection threshold (px); 16-bit PNG value per px of σ.

    Returns
    -------
    dict
        ``table``: the per-image scores as rows of the long results table (:func:`_long_rows`);
        ``rows``: from them (:func:`leaderboard_rows`), one per entry × scene set × protocol, ``{"entry",
        "kind" ("preset"|"baseline"|"external"), "scene_set", "protocol", "n_images", <HEADLINE metric>: mean}``; ``problems``: one line per map
        that could not be scored, naming the entry and the file; ``ground_truth``, ``protocols``,
        ``detection_threshold_px``, ``png_scale``, ``scene_sets`` (set -> images).
    """
    from method import PRESETS

    from .baselines import BASELINES, baseline_maps

    presets = PRESETS.check_all(dict.fromkeys(presets if presets is not None else PRESETS), what="preset")
    baselines = list(BASELINES) if baselines is None else (BASELINES.check_all(baselines) if baselines else [])
    protocols = PROTOCOLS.check_all(dict.fromkeys(protocols if protocols is not None else PROTOCOLS),
                                    what="protocol")
    external = dict(external or {})
    check_external(external, presets=presets)
    sets: dict[str, list[str]] = {}
    for image in truth.names:
        sets.setdefault(scene_set_of(truth.scene(image)), []).append(image)
    if len(sets) > 1:
        sets[ALL_SCENES] = list(truth.names)
    scored = [(p, "preset", score_maps(preset_maps(truth, p), truth, protocols=protocols, threshold_px=threshold_px))
              for p in presets]
    scored += [(b, "baseline", score_maps(baseline_maps(truth, b), truth, protocols=protocols,
                                          threshold_px=threshold_px)) for b in baselines]
    scored += [(n, "external", score_folder(f, truth, protocols=protocols, threshold_px=threshold_px,
                                            png_scale=png_scale)) for n, f in external.items()]
    problems, table = [], []
    for entry, kind, result in scored:
        problems += [f"{entry}: {p}" for p in result.problems]
        table += _long_rows(entry, kind, result.rows)
    return {"rows": leaderboard_rows(table, sets, protocols), "table": table, "problems": problems,
            "ground_truth": truth.source, "protocols": protocols, "detection_threshold_px": float(threshold_px),
            "png_scale": float(png_scale), "scene_sets": sets}


def _long_rows(entry: str, kind: str, rows) -> list[dict]:
    """Per-image scores of one entry as rows of the long results table (:mod:`experiments.results_table`):
    ``source`` ``leaderboard``, ``variant`` ``<kind>:<entry>``, ``preset`` the entry's when a preset or baseline,
    ``scene`` the image, ``metric`` ``<protocol>/<name>``."""
    from .results_table import metric_rows

    out = []
    for r in rows:
        ids = {"evaluation_id": "leaderboard", "source": "leaderboard", "scene_set": scene_set_of(r["scene"]),
               "scene": r["image"], "variant": f"{kind}:{entry}", "preset": entry if kind != "external" else None}
        nums = {f"{r['protocol']}/{k}": v for k, v in r.items() if k not in ("image", "scene", "protocol", "map")
                and isinstance(v, (int, float)) and not isinstance(v, bool)}
        out += metric_rows(ids, nums)
    return out


def leaderboard_rows(table, sets: dict, protocols) -> list[dict]:
    """The leaderboard's rows from its long-table rows: per entry × scene set × protocol the mean over the set's
    images of each headline metric (a non-finite value left out), in entry order, presets first.

    Returns
    -------
    list of dict
        ``{"entry", "kind", "scene_set", "protocol", "n_images", <HEADLINE metric>: mean}``.
    """
    from .results_query import Results

    table = Results(table)
    out = []
    for variant, rows in table.group("variant").items():
        kind, entry = variant.split(":", 1)
        for scene_set, images in sets.items():
            chosen = rows.where(scene=tuple(images))
            for protocol in protocols:
                per = chosen.where(metric=tuple(f"{protocol}/{k}" for k, _ in HEADLINE[protocol]))
                n = len(set(per.distinct("scene")))
                if not n:
                    continue
                keep = {}
                for k, _ in HEADLINE[protocol]:
                    vals = [r["value"] for r in per.where(metric=f"{protocol}/{k}")
                            if r["value"] is not None and np.isfinite(r["value"])]
                    keep[k] = float(np.mean(vals)) if vals else float("nan")
                out.append({"entry": entry, "kind": kind, "scene_set": scene_set, "protocol": protocol,
                            "n_images": n, **keep})
    return out


def leaderboard_intro(board: dict) -> str:
    """One paragraph: what the leaderboard's rows are and where the ground truth comes from."""
    return ("One row per method preset, trivial baseline and external map folder, per scene set and protocol: the "
            f"mean over the images of the per-image metric. Ground truth: {board['ground_truth']}; occlusion bands "
            "excluded. Presets: the method on each image's 8-bit sRGB input (as `repro.estimate --preset NAME` on the "
            "exported PNG). Baselines: a constant map at the image's median σ_gt (const_median_gt, an oracle) and at "
            "the pixel filter's floor 0.289 px (const_floor); a method should beat both. Protocols: docs/dataset.md."
            + (f" Not scored: {len(board['problems'])} map(s) (listed in leaderboard.json)." if board["problems"] else ""))


def _cell(v) -> str:
    return "–" if v is None or v != v else f"{v:.3f}"


def leaderboard_tables(board: dict) -> list[dict]:
    """One table per protocol of :func:`build_leaderboard`'s result, rendered from its long-table rows
    (``table``, :func:`leaderboard_rows`): ``{"title", "header", "rows"}``.

    Rows by scene set, then entries in their order (presets first); cells are strings.
    """
    tables = []
    sets = list(board.get("scene_sets", {}))
    means = leaderboard_rows(board["table"], board.get("scene_sets", {}), board.get("protocols", [])) \
        if "table" in board else board["rows"]
    for protocol in board.get("protocols", []):
        cols = HEADLINE[protocol]
        rows = [r for r in means if r["protocol"] == protocol]
        rows.sort(key=lambda r: sets.index(r["scene_set"]) if r["scene_set"] in sets else len(sets))
        body = [[r["scene_set"], r["entry"], r["kind"], str(r["n_images"]), *(_cell(r.get(k)) for k, _ in cols)]
                for r in rows]
        title = f"{protocol}: {PROTOCOLS.entry(protocol).summary}"
        if protocol == "detection":
            title += f" (threshold {board['detection_threshold_px']:g} px)"
        tables.append({"title": title, "header": ["scene set", "entry", "kind", "images", *(l for _, l in cols)],
                       "rows": body})
    return tables


# --- generalisation: the same presets on the dev and the test seeds of the procedural family ---------
#: Metrics of the generalisation tables (results-table metric names).
GAP_METRICS = ("dense_textured_mae", "sparse_mae")
#: Label of the row that averages a scene's apertures.
ALL_APERTURES = "all"


def _per_scene(rows, metric: str, by: tuple) -> dict:
    """``{group: {scene: value}}`` of one metric; the ``aperture`` of ``by`` also gets an :data:`ALL_APERTURES`
    group holding each scene's mean over the apertures it has a value at."""
    groups: dict[tuple, dict] = {}
    pooled: dict[tuple, dict] = {}
    for r in rows:
        if r["metric"] != metric or r.get("value") is None or r.get("preset") is None:
            continue
        key = tuple(r.get(c) for c in by)
        groups.setdefault(key, {})[r["scene"]] = float(r["value"])
        all_key = tuple(ALL_APERTURES if c == "aperture" else r.get(c) for c in by)
        pooled.setdefault(all_key, {}).setdefault(r["scene"], []).append(float(r["value"]))
    for key, per in pooled.items():
        if any(len(v) > 1 for v in per.values()):  # more than one aperture to pool
            groups[key] = {s: sum(v) / len(v) for s, v in per.items()}
    return groups


def generalisation_gap(dev_rows, test_rows, *, metrics=GAP_METRICS, fresh_rows=None,
                       by=("scene_size", "preset", "aperture", "encoding", "noise")) -> list[dict]:
    """Per preset (and aperture, …) the dev and test means over scenes side by side, and test − dev.

    Parameters
    ----------
    dev_rows, test_rows : iterable of dict
        Results rows (:mod:`experiments.results_table`) of an evaluation on the dev and on the test seeds.
    metrics : tuple of str, keyword-only
        Metrics compared.
    fresh_rows : iterable of dict, optional, keyword-only
        Rows of a ``fresh`` evaluation, shown beside test.
    by : tuple of str, keyword-only
        Columns that must match between the splits; ``aperture`` also gets the pooled
        :data:`ALL_APERTURES` group (each scene's mean over its apertures).

    Returns
    -------
    list of dict
        One per group present in both splits, in the dev table's order: the ``by`` columns, ``metric``,
        ``unit``, ``dev`` / ``test`` / ``fresh`` (each :func:`experiments.results_table.summarise`-like
        ``{"n_scenes", "mean", "ci_low", "ci_high"}`` or None) and ``gap`` (test − dev,
        :func:`experiments.results_table.difference`: resampling dev and test scenes independently).
    """
    from .results_table import difference, mean_interval, metric_unit

    def stats(per):
        return mean_interval(per.values()) if per else None

    out = []
    for metric in metrics:
        dev, test = _per_scene(dev_rows, metric, by), _per_scene(test_rows, metric, by)
        fresh = _per_scene(fresh_rows, metric, by) if fresh_rows is not None else {}
        for key, per_dev in dev.items():
            if key not in test:
                continue
            gap = difference(list(per_dev.values()), list(test[key].values()))
            out.append({**dict(zip(by, key)), "metric": metric, "unit": metric_unit(metric), "dev": stats(per_dev),
                        "test": stats(test[key]), "fresh": stats(fresh.get(key)),
                        "gap": {k: gap[k] for k in ("value", "ci_low", "ci_high")}})
    return out


def _ci_text(s) -> str:
    if not s or s.get("mean", s.get("value")) is None:
        return "–"
    m = s.get("mean", s.get("value"))
    sign = "+" if "value" in s else ""
    if s.get("ci_low") is None:
        return f"{m:{sign}.3f}"
    return f"{m:{sign}.3f} [{s['ci_low']:{sign}.3f}, {s['ci_high']:{sign}.3f}]"


def generalisation_tables(gap_rows) -> list[dict]:
    """One table per metric, scene size, encoding and noise of :func:`generalisation_gap`'s rows:
    ``{"title", "header", "rows"}``, a row per preset × aperture (cells are strings)."""
    tables: dict[tuple, dict] = {}
    has_fresh = any(r.get("fresh") for r in gap_rows)
    for r in gap_rows:
        key = (r["metric"], r.get("scene_size"), r.get("encoding"), r.get("noise"))
        if key not in tables:
            head = ["preset", "f/N", "dev scenes", "dev mean [95 % CI]", "test scenes", "test mean [95 % CI]",
                    "test − dev [95 % CI]"]
            tables[key] = {"title": f"{r['metric']} ({r['unit']}), {r.get('scene_size')} renders, "
                                    f"{r.get('encoding')} input, noise {r.get('noise')}",
                           "header": head + (["fresh scenes", "fresh mean [95 % CI]"] if has_fresh else []),
                           "rows": []}
        ap = r.get("aperture")
        row = [str(r.get("preset")), ap if isinstance(ap, str) else f"{ap:g}", str(r["dev"]["n_scenes"]),
               _ci_text(r["dev"]), str(r["test"]["n_scenes"]), _ci_text(r["test"]), _ci_text(r["gap"])]
        if has_fresh:
            row += [str(r["fresh"]["n_scenes"]) if r.get("fresh") else "0", _ci_text(r.get("fresh"))]
        tables[key]["rows"].append(row)
    return list(tables.values())
