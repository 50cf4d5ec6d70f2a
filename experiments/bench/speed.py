"""Speed benchmark of the method: per-stage and whole-pipeline wall time and peak memory.

One run is :func:`time_pipeline` (the pipeline ``repeat`` times on :func:`bench_image`, the fastest
counts); ``python -m repro.bench`` runs each (preset, size) in a fresh process, so its peak resident
memory is its own, then :func:`speed_summary` judges the rows against the targets below (this 2-core
machine kind) and :func:`speed_markdown` writes the table. :func:`time_magnification` times the
magnification step alone on a 12-MP photo with its map given (what ``repro.magnify --map`` runs after
reading the files), one fresh process per renderer. Measurements: ``docs/performance.md``.
"""

from __future__ import annotations

import os
import platform
import resource
import time
import warnings

__all__ = ["BENCH_PRESETS", "MAGNIFY_BENCH_PIXELS", "MAGNIFY_BENCH_RENDERERS", "TARGET_GROWTH_512_TO_1024",
           "TARGET_MAGNIFY_SECONDS_12MP", "TARGET_PEAK_GIB_1MP", "TARGET_SECONDS_1MP",
           "TARGET_SECONDS_512", "bench_image", "machine_info", "magnify_bench_inputs", "magnify_table",
           "speed_markdown", "speed_report", "speed_summary", "speed_table", "time_magnification", "time_pipeline"]

#: Whole pipeline at 1 MP (1024² px), s, for every preset of :data:`BENCH_PRESETS`.
TARGET_SECONDS_1MP = 1.0
#: Whole pipeline at 512² px, s.
TARGET_SECONDS_512 = 1.0
#: Peak resident memory of the run at 1 MP, GiB.
TARGET_PEAK_GIB_1MP = 1.5
#: Presets timed by default (every one must meet the targets).
BENCH_PRESETS = ("paper", "robust")
#: Cost growth from 512² to 1024² px (4 × the pixels), ratio of totals.
TARGET_GROWTH_512_TO_1024 = 4.5
#: The scatter renderer's magnification step alone (map given, factor 2) on a 12-MP photo, s.
TARGET_MAGNIFY_SECONDS_12MP = 20.0
#: Pixels of the magnification benchmark's photo.
MAGNIFY_BENCH_PIXELS = 12_000_000
#: Renderers whose 12-MP magnification is timed by default (the target is the scatter's).
MAGNIFY_BENCH_RENDERERS = ("scatter",)


def bench_image(size: int):
    """The benchmark image: ``skimage.data.astronaut`` resized to ``size``² px.

    Parameters
    ----------
    size : int
        Side, px.

    Returns
    -------
    ndarray, (size, size, 3), float64 in [0, 1]
    """
    import numpy as np
    from skimage import data, transform

    img = data.astronaut().astype(np.float64) / 255.0
    return np.clip(transform.resize(img, (size, size), order=1, anti_aliasing=True), 0.0, 1.0)


def time_pipeline(size: int, repeat: int, preset: str = "paper") -> dict:
    """Run the whole pipeline and a 2× magnification ``repeat`` times at ``size``² px.

    Parameters
    ----------
    size : int
        Image side, px.
    repeat : int
        Runs; the fastest (by ``total``) counts.
    preset : str
        Key of :data:`method.PRESETS`.

    Returns
    -------
    dict
        ``preset``, ``size``, ``pixels``, ``edge_pixels``, ``timings_s`` (stage → s of the fastest run,
        plus ``magnification``), ``peak_rss_gib`` (this process's ``ru_maxrss``) and ``load1`` (1-min
        load average before and after).
    """
    from method import DefocusParams, estimate_defocus_map, magnify_defocus

    image = bench_image(size)
    params = DefocusParams.preset(preset)
    load_before = os.getloadavg()[0]
    best = None
    for _ in range(repeat):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = estimate_defocus_map(image, params)
            t = time.perf_counter()
            magnify_defocus(image, result.defocus_map, factor=2.0)
            t_mag = time.perf_counter() - t
        timings = dict(result.timings)
        timings["magnification"] = t_mag
        if best is None or timings["total"] < best["total"]:
            best = timings
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "preset": preset,
        "load1": [load_before, os.getloadavg()[0]],
        "size": size,
        "pixels": size * size,
        "edge_pixels": int(result.edges.sum()),
        "timings_s": best,
        "peak_rss_gib": peak_kib / 2**20,
    }


def magnify_bench_inputs(pixels: int = MAGNIFY_BENCH_PIXELS, *, preset: str = "robust"):
    """The magnification benchmark's photo and map: ``skimage.data.coffee`` upscaled to ≈ ``pixels`` (8-bit values).

    The map is the ``preset`` map estimated on the photo at its shipped 400×600 px, brought to the
    big photo's size as ``repro.magnify --map`` does with a map of the photo's aspect ratio
    (bilinear, σ × the width ratio).

    Returns
    -------
    (ndarray, (H, W, 3) float64 in [0, 1]; ndarray, (H, W) σ px)
    """
    import numpy as np
    from skimage import data, transform

    from method import DefocusParams, estimate_defocus_map

    small = data.coffee().astype(np.float64) / 255.0
    s = (pixels / (small.shape[0] * small.shape[1])) ** 0.5
    shape = (int(round(small.shape[0] * s)), int(round(small.shape[1] * s)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sigma = estimate_defocus_map(small, DefocusParams.preset(preset)).defocus_map
    photo = np.rint(np.clip(transform.resize(small, shape, order=1), 0.0, 1.0) * 255.0) / 255.0  # an 8-bit photo
    scaled = transform.resize(sigma, shape, order=1, mode="edge", preserve_range=True) * (shape[1] / small.shape[1])
    return photo, np.maximum(scaled, 0.0)


def time_magnification(renderer: str = "scatter", pixels: int = MAGNIFY_BENCH_PIXELS, *,
                       preset: str = "robust") -> dict:
    """Time the magnification step alone (×2, map given) as ``repro.magnify --map`` runs it.

    Parameters
    ----------
    renderer : str
        Key of :data:`method.magnify.magnification.MAGNIFICATION_RENDERERS`.
    pixels : int
        Size of the photo (:func:`magnify_bench_inputs`).
    preset : str
        Map and Sec. 5 preprocessing parameters (``repro.magnify``'s default: robust).

    Returns
    -------
    dict
        ``renderer``, ``shape``, ``pixels``, ``sigma_px`` (median / 99th percentile / max of the given
        map), ``magnify_s`` (Sec. 5 preprocessing + tiled magnification with ``repro.magnify``'s
        default tile size; numba kernels warmed up on a small image first), ``peak_rss_gib``,
        ``load1`` (before, after).
    """
    import numpy as np

    from method import DefocusParams, magnify_defocus
    from method.magnify.magnification import preprocess_defocus_map
    from method.magnify.upsampling import DEFAULT_TILE_PIXELS, magnify_defocus_tiled

    photo, sigma = magnify_bench_inputs(pixels, preset=preset)
    params = DefocusParams.preset(preset)
    magnify_defocus(photo[:64, :64], sigma[:64, :64] / 8.0, factor=2.0, renderer=renderer)  # JIT load
    load_before = os.getloadavg()[0]
    t = time.perf_counter()
    processed = preprocess_defocus_map(sigma, clip_percent=params.map_clip_percent, smoothing=params.map_smoothing,
                                       floor=params.map_floor)
    magnify_defocus_tiled(photo, processed, factor=2.0, renderer=renderer, preprocess=False,
                          tile_pixels=DEFAULT_TILE_PIXELS)
    seconds = time.perf_counter() - t
    return {
        "renderer": renderer,
        "shape": list(photo.shape[:2]),
        "pixels": int(photo.shape[0] * photo.shape[1]),
        "sigma_px": {"median": float(np.median(sigma)), "p99": float(np.percentile(sigma, 99)),
                     "max": float(sigma.max())},
        "magnify_s": seconds,
        "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "load1": [load_before, os.getloadavg()[0]],
    }


def magnify_table(rows: list[dict]) -> str:
    """Markdown table of :func:`time_magnification` rows."""
    lines = ["| renderer | photo (px) | map σ median / p99 / max (px) | magnify (s) | peak RSS (GiB) | load 1-min |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        s = r["sigma_px"]
        lines.append(f"| {r['renderer']} | {r['shape'][1]}×{r['shape'][0]} | {s['median']:.2f} / {s['p99']:.2f} / "
                     f"{s['max']:.2f} | {r['magnify_s']:.1f} | {r['peak_rss_gib']:.2f} | "
                     f"{r['load1'][0]:.1f} → {r['load1'][1]:.1f} |")
    return "\n".join(lines)


def speed_table(rows: list[dict]) -> str:
    """Markdown table of :func:`time_pipeline` rows: one per (preset, size), one column per stage."""
    stages = list(rows[0]["timings_s"].keys())
    head = ("| preset | size | edge px | " + " | ".join(f"{s} (s)" for s in stages)
            + " | peak RSS (GiB) | load 1-min (before → after) |")
    sep = "|" + "---|" * (len(stages) + 5)
    lines = [head, sep]
    for r in rows:
        cells = " | ".join(f"{r['timings_s'][s]:.3f}" if s in r["timings_s"] else "" for s in stages)
        load = r.get("load1")
        load = f"{load[0]:.1f} → {load[1]:.1f}" if load else "not recorded"
        lines.append(f"| {r.get('preset', 'paper')} | {r['size']}² | {r['edge_pixels']} | {cells} | "
                     f"{r['peak_rss_gib']:.2f} | {load} |")
    return "\n".join(lines)


def speed_summary(rows: list[dict], magnify_rows: list[dict] = ()) -> dict:
    """Per preset: 1 MP / 512² totals and peak memory against the targets, and the 512² → 1024² growth;
    per renderer timed: the 12-MP magnification against :data:`TARGET_MAGNIFY_SECONDS_12MP`.

    Parameters
    ----------
    rows : list of dict
        :func:`time_pipeline` results.
    magnify_rows : list of dict
        :func:`time_magnification` results.

    Returns
    -------
    dict
        ``"{preset}: total_1mp_s"``, ``"{preset}: meets_time_target_1mp"``, … (only for sizes run).
    """
    summary = {}
    for preset in dict.fromkeys(r.get("preset", "paper") for r in rows):
        by_size = {r["size"]: r for r in rows if r.get("preset", "paper") == preset}
        if 1024 in by_size:
            r = by_size[1024]
            summary[f"{preset}: total_1mp_s"] = r["timings_s"]["total"]
            summary[f"{preset}: peak_1mp_gib"] = r["peak_rss_gib"]
            summary[f"{preset}: meets_time_target_1mp"] = r["timings_s"]["total"] <= TARGET_SECONDS_1MP
            summary[f"{preset}: meets_memory_target"] = r["peak_rss_gib"] <= TARGET_PEAK_GIB_1MP
        if 512 in by_size:
            summary[f"{preset}: total_512_s"] = by_size[512]["timings_s"]["total"]
            summary[f"{preset}: meets_time_target_512"] = by_size[512]["timings_s"]["total"] <= TARGET_SECONDS_512
        if 512 in by_size and 1024 in by_size:
            g = by_size[1024]["timings_s"]["total"] / by_size[512]["timings_s"]["total"]
            summary[f"{preset}: growth_512_to_1024"] = g
            summary[f"{preset}: meets_growth_target"] = g <= TARGET_GROWTH_512_TO_1024
    for r in magnify_rows:
        mp = r["pixels"] / 1e6
        summary[f"magnify {r['renderer']}: seconds_{mp:.0f}mp"] = r["magnify_s"]
        if r["renderer"] == "scatter":
            summary[f"magnify {r['renderer']}: meets_time_target_{mp:.0f}mp"] = r["magnify_s"] <= TARGET_MAGNIFY_SECONDS_12MP
    return summary


def machine_info() -> dict:
    """CPU count, Python version and platform of this machine."""
    return {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()}


def speed_report(rows: list[dict], *, before: dict | None, magnify_rows: list[dict] = ()) -> dict:
    """The ``bench.json`` record: rows, magnification rows, :func:`speed_summary`, the run it replaces,
    targets, machine, date."""
    return {
        "rows": rows,
        "magnify_rows": list(magnify_rows),
        "summary": speed_summary(rows, magnify_rows),
        "before": before,
        "targets": {"total_1mp_s": TARGET_SECONDS_1MP, "total_512_s": TARGET_SECONDS_512,
                    "peak_1mp_gib": TARGET_PEAK_GIB_1MP, "growth_512_to_1024": TARGET_GROWTH_512_TO_1024,
                    "magnify_scatter_12mp_s": TARGET_MAGNIFY_SECONDS_12MP},
        "machine": machine_info(),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }


def _summary_lines(summary: dict) -> str:
    return "\n".join(f"- {k}: {v:.3f}" if isinstance(v, float) else f"- {k}: {v}" for k, v in summary.items())


def speed_markdown(report: dict, *, repeat: int) -> str:
    """``bench.md`` of a :func:`speed_report` (with the previous run as "Before" when it has one)."""
    md = (f"# Benchmark ({report['date']}, {report['machine']['cpus']} CPUs)\n\n"
          "Whole-pipeline `total` excludes magnification (timed separately); fastest of "
          f"{repeat} runs; peak RSS of the whole worker process.\n\n{speed_table(report['rows'])}\n\n")
    if report.get("magnify_rows"):
        md += ("Magnification step alone (×2, map given as with `repro.magnify --map`; one run in a fresh process): "
               f"\n\n{magnify_table(report['magnify_rows'])}\n\n")
    md += _summary_lines(report["summary"]) + "\n"
    before = report.get("before")
    if before:
        md += (f"\n## Before: the previous run ({before['date']})\n\n{speed_table(before['rows'])}\n\n"
               + _summary_lines(before["summary"]) + "\n")
    return md
