"""Fig. 11: results gallery — input, defocus map, magnified result, for renders and real photos.

Rendered scenes have ground truth, so their dense maps are scored (MAE / bias vs σ_gt, occlusion
bands excluded). The real photographs are the ones shipped inside scikit-image
(``skimage.data``: no download); they have no ground truth, so the figure reports their map
statistics (percentiles of σ, fraction of edge pixels) and the estimator's runtime.

Notes
-----
1. Renders: ``render_scene(name, preset, f_number)``, input ``render.image(encoding="srgb",
   quantize_bits=8)``.
2. Photos: ``skimage.data.<name>()`` (8-bit sRGB) → float in [0, 1]; when its longer side exceeds
   ``photo_max_side`` it is downscaled with :func:`method.magnify.upsampling.downscale_image` (Gaussian
   anti-aliasing prefilter) — every σ of a photo is then in px of the *downscaled* image.
3. :func:`method.estimate_defocus_map` (paper defaults), timed per stage (wall time on a shared
   2-core machine: indicative only).
4. :func:`method.magnify_defocus` with ``factor`` (Sec. 5 preprocessing, Gaussian kernel).
5. Method presets (``config.presets``; the first is always ``"paper"`` = ``DefocusParams()``, the
   reproduction, whose metrics are the top-level ones): steps 3–4 again with every further preset
   of :data:`method.PRESETS` (e.g. ``"robust"``, beyond the paper; Sec. 5 preprocessing with its
   ``map_clip_percent`` / ``map_smoothing``) on the same inputs, scored the same way, under
   ``metrics["presets"][name]`` = {``items``, ``summary``} with the paper's keys.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .scene_sets import scene_set_figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig11Config", "compute", "compute_set", "load_photo"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig11Config:
    """Every parameter of Fig. 11."""

    scenes: tuple[str, ...] = ("portrait_garden", "street_figures", "patio_table", "heron_at_the_lake")
    # rendered scenes (scenes.SCENES), scored against σ_gt.
    scene_set: str = "paper_cameras"
    # name of the scenes.SCENE_SETS entry ``scenes`` is drawn from (the flat metrics describe it).
    other_scene_sets: tuple = (("tabletop_stress", (("scenes", ("planes", "tilted_plane", "portrait", "clutter",
                                                               "shadow_gloss")), ("photos", ()))),)
    # further scene sets computed the same way (the photos only once, with the default set):
    # (set name, ((config field, value), ...)) overrides; their metrics go to
    # metrics["scene_sets"][name], arrays to "<name>__<key>" (experiments.scene_sets).
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_number: float = 8.0
    # N of the renders (the "photo as taken"; magnification then simulates a wider aperture).
    photos: tuple[str, ...] = ("astronaut", "coffee", "chelsea", "rocket")
    # names of skimage.data RGB photos (bundled with scikit-image, no download).
    photo_max_side: int = 640
    # longer side of the processed photo, px; larger photos are downscaled (0 = never downscale).
    factor: float = 2.0
    # defocus magnification k (total blur k·B; 2 = doubling the aperture diameter).
    kernel: str = "gaussian"
    # magnification kernel (method.MAGNIFICATION_KERNELS).
    quantize_bits: int = 8
    # bits per channel of the rendered inputs (8 = JPEG-like).
    texture_threshold: float = 0.02
    # local luminance std above which a rendered pixel is "textured", image units.
    render_seed: int = 0
    # Mitsuba sampler seed.
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS); the first is "paper" (the reproduction, top-level
    # metrics), the others go to metrics["presets"][name] (not to be confused with the render `preset`).


FULL = Fig11Config()
QUICK = Fig11Config(preset="small", photos=("astronaut", "coffee", "chelsea"), photo_max_side=160,
                    other_scene_sets=(("tabletop_stress", (("scenes", ("planes", "portrait", "shadow_gloss")),
                                                            ("photos", ()))),))


def load_photo(name: str, max_side: int = 0) -> tuple[np.ndarray, float]:
    """An RGB photo bundled with scikit-image, as float in [0, 1], optionally downscaled.

    Parameters
    ----------
    name : str
        Function name in ``skimage.data`` returning an HxWx3 uint8 image (e.g. ``"astronaut"``).
    max_side : int
        Longer side after downscaling, px (0: keep the original size).

    Returns
    -------
    (ndarray, float)
        The image, hxwx3 float64 in [0, 1], and the linear scale s = h / H (1 if not downscaled).

    Raises
    ------
    ValueError
        Unknown name, a non-RGB image, or ``max_side`` < 0.
    """
    import skimage.data

    from method.magnify.upsampling import downscale_image

    loader = getattr(skimage.data, name, None)
    if loader is None or name.startswith("_"):
        raise ValueError(f"photo {name!r} is unknown; allowed: an RGB image function of skimage.data")
    if max_side < 0:
        raise ValueError(f"max_side={max_side!r} is invalid; allowed: integer >= 0")
    img = np.asarray(loader())
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.dtype != np.uint8:
        raise ValueError(f"photo {name!r} is not an 8-bit RGB image (shape {img.shape}, {img.dtype})")
    img = img[..., :3].astype(np.float64) / 255.0
    H, W = img.shape[:2]
    if max_side and max(H, W) > max_side:
        s = max_side / max(H, W)
        shape = (max(8, round(H * s)), max(8, round(W * s)))
        return downscale_image(img, shape), shape[0] / H
    return img, 1.0


def _run(image, config, params=None):
    from method import DefocusParams, estimate_defocus_map, magnify_defocus

    params = DefocusParams() if params is None else params
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = estimate_defocus_map(image, params)
    t_est = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = magnify_defocus(image, res.defocus_map, factor=config.factor, kernel=config.kernel,
                          clip_percent=params.map_clip_percent, smoothing=params.map_smoothing)
    t_mag = time.perf_counter() - t0
    timings = {f"estimate_{k}_s": float(v) for k, v in res.timings.items()}
    timings.update(estimate_wall_s=t_est, magnify_wall_s=t_mag)
    return res, out, timings


def _map_stats(res):
    m = res.defocus_map
    p = np.percentile(m, [5, 50, 95])
    return {"map_mean_px": float(m.mean()), "map_p5_px": float(p[0]), "map_median_px": float(p[1]),
            "map_p95_px": float(p[2]), "map_max_px": float(m.max()),
            "edge_fraction": float(res.edges.mean()),
            "sparse_median_px": float(np.nanmedian(res.sparse_sigma)) if res.edges.any() else float("nan")}


def compute_set(config: Fig11Config) -> dict:
    """Gallery of rendered scenes and bundled photos: maps, magnified results, metrics (one scene set).

    Parameters
    ----------
    config : Fig11Config

    Returns
    -------
    dict
        ``items`` (n,) names in drawing order (``"scene:<name>"`` / ``"photo:<name>"``); per item
        ``<item>__input`` (H, W, 3), ``<item>__map`` (H, W) σ px, ``<item>__magnified`` (H, W, 3),
        ``<item>__sparse`` (H, W) σ px at edges (NaN elsewhere); for scenes also ``<item>__gt``
        (H, W) σ_gt px and ``<item>__occlusion`` (H, W) bool; ``metrics``: per item map statistics
        and timings, for scenes dense MAE / bias per region vs σ_gt, and means over scenes — all for
        the ``"paper"`` preset. Every further preset P of ``config.presets``: ``<item>__<P>__map``
        (H, W) σ px, ``<item>__<P>__magnified`` (H, W, 3), ``<item>__<P>__sparse`` (H, W) σ px, and
        ``metrics.presets.<P>`` = {``items``, ``summary`` (the paper's keys), ``compute_seconds``}.
    """
    from scenes import render_scene

    from .fig6_alpha_sweep import method_presets
    from .metrics import dense_metrics, region_masks, rtf_normalized_errors

    presets = method_presets(config.presets)
    t_start = time.perf_counter()
    data, items = {}, []
    per_preset = {p: {} for p in presets}  # preset -> item -> metrics
    seconds = dict.fromkeys(presets, 0.0)

    def store(item, pname, res, out):
        tag = "" if pname == "paper" else f"__{pname}"
        data.update({f"{item}{tag}__map": res.defocus_map.astype(np.float32),
                     f"{item}{tag}__magnified": out.astype(np.float32),
                     f"{item}{tag}__sparse": res.sparse_sigma.astype(np.float32)})

    for name in config.scenes:
        render = render_scene(name, preset=config.preset, f_number=config.f_number, seed=config.render_seed,
                              progress=False)
        image = render.image(encoding="srgb", quantize_bits=config.quantize_bits)
        gt = np.asarray(render.sigma_px, dtype=np.float64)
        item = f"scene:{name}"
        items.append(item)
        data.update({f"{item}__gt": gt.astype(np.float32), f"{item}__occlusion": render.occlusion_boundary,
                     f"{item}__input": image.astype(np.float32)})
        for pname, params in presets.items():
            t0 = time.perf_counter()
            res, out, timings = _run(image, config, params)
            regions = region_masks(image, gt, edges=res.edges, exclude=render.occlusion_boundary,
                                   texture_threshold=config.texture_threshold)
            dm = dense_metrics(res.defocus_map, gt, regions=regions)
            per_preset[pname][item] = {
                **{f"{r}_{k}": dm[r][k] for r in dm for k in ("mae", "bias")},
                **{f"rtf_{k}": v for k, v in rtf_normalized_errors(res.defocus_map, gt, mask=regions["all"]).items()
                   if k != "n"},
                **_map_stats(res), "timings": timings, "shape": list(image.shape[:2]),
                "sigma_gt_range_px": [float(np.nanmin(gt)), float(np.nanmax(gt))],
            }
            store(item, pname, res, out)
            seconds[pname] += time.perf_counter() - t0
    for name in config.photos:
        image, scale = load_photo(name, config.photo_max_side)
        item = f"photo:{name}"
        items.append(item)
        data[f"{item}__input"] = image.astype(np.float32)
        for pname, params in presets.items():
            t0 = time.perf_counter()
            res, out, timings = _run(image, config, params)
            per_preset[pname][item] = {**_map_stats(res), "timings": timings, "shape": list(image.shape[:2]),
                                       "scale_from_original": scale,
                                       "megapixels": image.shape[0] * image.shape[1] / 1e6}
            store(item, pname, res, out)
            seconds[pname] += time.perf_counter() - t0
    scene_items = [f"scene:{n}" for n in config.scenes]

    def summarise(per_item):
        summary = {}
        if scene_items:
            for key in ("all_mae", "all_bias", "textured_mae", "edges_mae", "rtf_nmae", "rtf_nmse"):
                summary[f"scenes_mean_{key}"] = float(np.mean([per_item[i][key] for i in scene_items]))
        return summary

    names = list(presets)
    per_item, summary = per_preset[names[0]], summarise(per_preset[names[0]])
    extra = {p: {"items": per_preset[p], "summary": summarise(per_preset[p]), "compute_seconds": seconds[p]}
             for p in names[1:]}
    data["items"] = np.asarray(items)
    data["metrics"] = {"items": per_item, "summary": summary, "presets": extra, "factor": config.factor,
                       "compute_seconds": time.perf_counter() - t_start,
                       "regions_note": "scene metrics exclude occlusion-boundary pixels; photos have no "
                                       "ground truth (map statistics in px of the processed image)"}
    return data


FIGURE = scene_set_figure(
    compute_set, name="fig11", quick=QUICK, full=FULL, version=3,
    title="Results gallery: input, defocus map, magnified result (renders with MAE; skimage.data photos)",
)
#: :func:`compute_set` on the default scene set and on each of ``config.other_scene_sets``
#: (:func:`experiments.scene_sets.compute_scene_sets`); the photos only with the default set.
compute = FIGURE.compute
